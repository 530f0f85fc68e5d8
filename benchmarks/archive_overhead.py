"""Cost of archiving a run to HDF5: wall time with an ArchiveSink over wall time without.

Each case advances a fresh strip ensemble (Eq. B) at K = 3, b1 = 0.1, b2 = 0.01 (seed 1) by
``steps`` iterations twice per repetition, alternately

* without an archive: ``Ensemble.run(steps)`` with the default chunking, and
* with an archive: ``Ensemble.run(steps, [ArchiveSink(...)], chunk_steps=sink.chunk_steps)``
  with the sink's default schedule (a series row per chunk, a checkpoint every 8 chunks and at
  the end, no snapshots), exactly what ``warpratchet run --out`` does; the time includes
  creating the file (with the initial state), every row and checkpoint (with their fsyncs) and
  closing it,

and reports the ratio of the best wall times (the budget: at most 1.05 at the default
settings, the first case: 10^4 points x 1.2e5 steps), the ratio of the best process CPU times,
and the archive's own share measured directly: the seconds spent inside the sink (creation,
``after_chunk``, ``end``, ``close``) over the kernel seconds of the same run. On a machine
shared with other jobs the direct share is the steadiest of the three. Both runs must end in
bitwise equal states (archiving never changes results); the script exits with status 1 if not.

Usage::

    python benchmarks/archive_overhead.py                 # three cases, ~2-3 s per run (~1 min)
    python benchmarks/archive_overhead.py --json          # one JSON object on stdout
    python benchmarks/archive_overhead.py --quick --json  # smoke test, a few seconds
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

from _sink_overhead import Timed, case_row, columns_for, compare, finish, log, measure_cases, options, warm_up

from warpratchet.archive import ArchiveSink

BUDGET = 1.05
#: (points, steps): the CLI default first, then larger ensembles (1.2e9 - 2.4e9 point-steps).
CASES = [(10_000, 120_000), (100_000, 12_000), (1_000_000, 2_400)]
QUICK_CASES = [(10_000, 20_000), (100_000, 2_000)]
#: The text table: (header, key, format).
OWN_COLUMNS = [("chunk", "chunk_steps", "d"), ("rows", "rows", "d")]
COLUMNS = columns_for(OWN_COLUMNS, ("archived s", "archived"), ("sink/kernel", "sink"))


def measure(points: int, steps: int, repeat: int, folder: Path) -> dict[str, Any]:
    """Best-of-``repeat`` wall and CPU times with and without the archive, alternating."""

    def archived(ens, rep: int) -> dict[str, Any]:
        path = folder / f"run{points}_{rep}.h5"
        start = time.perf_counter()
        sink = ArchiveSink(path, ens)
        created = time.perf_counter() - start
        timed = Timed(sink)
        ens.run(steps, [timed], chunk_steps=sink.chunk_steps)
        start = time.perf_counter()
        sink.close()
        closing = time.perf_counter() - start
        return {
            "path": path,
            "share": (created + timed.seconds + closing) / timed.kernel,
            "rows": sink._series.count,
            "checkpoints": steps // sink.checkpoint_every + (steps % sink.checkpoint_every != 0),
            "chunk_steps": sink.chunk_steps,
        }

    def remove(info: dict[str, Any]) -> None:
        info["file_bytes"] = os.path.getsize(info["path"])
        info.pop("path").unlink()

    t = compare(points, steps, repeat, archived, remove)
    last = t["measured"][-1]
    shares = [info["share"] for info in t["measured"]]
    log(f"  sink {100 * min(shares):.2f}% of the kernel time (best)")
    own = {key: last[key] for key in ("chunk_steps", "rows", "checkpoints", "file_bytes")}
    return case_row(points, steps, own, t, ("archived", "sink"), shares)


def main(argv: list[str] | None = None) -> int:
    args, repeat = options(__doc__, argv, repeat=3)
    warm_up()
    cases = QUICK_CASES if args.quick else CASES
    results = measure_cases(cases, repeat, measure, "warpratchet-archive-bench-")
    default = results[0]
    summary = {
        "default_case": {"points": default["points"], "steps": default["steps"]},
        "within_budget": default["wall_ratio"] <= BUDGET,
        "sink_within_budget": default["sink_share_of_kernel"] <= BUDGET - 1,
    }
    return finish(
        args, BUDGET, summary, results, COLUMNS, f"budget at the default settings: wall ratio <= {BUDGET}"
    )


if __name__ == "__main__":
    sys.exit(main())
