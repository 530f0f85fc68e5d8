"""Cost of recording a run with rerun: wall time with a RecordingSink over wall time without.

Each case advances a fresh strip ensemble (Eq. B) at K = 3, b1 = 0.1, b2 = 0.01 (seed 1) by
``steps`` iterations twice per repetition, alternately

* without recording: ``Ensemble.run(steps)`` with the default chunking, and
* with recording: ``Ensemble.run(steps, [RecordingSink(...)], chunk_steps=every)`` with the
  sink's defaults (subsample of at most 10^5 points, frame interval
  :func:`warpratchet.recording.frame_every`), exactly what ``warpratchet run --rerun`` does;
  the time includes opening the file, every frame and the final flush,

and reports the ratio of the best wall times (the issue's budget is 1.10) and of the best
process CPU times (all threads, including rerun's writer): on a machine shared with other
jobs the CPU-time ratio is the steadier of the two. Both runs must end in
bitwise equal states (recording never changes results); the script exits with status 1 if not.
Timings on the shared 2-core machine are noisy; the ratio, taken within one run, is the number
to read.

Usage::

    python benchmarks/recording_overhead.py            # three cases, ~1.5 s per run (~2 min)
    python benchmarks/recording_overhead.py --json     # one JSON object on stdout
    python benchmarks/recording_overhead.py --quick --json   # smoke test, a few seconds
    python benchmarks/recording_overhead.py --repeat 3       # best of 3 (default 5)
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from _sink_overhead import INIT, PARAMS, SEED, compare, emit, log, measure_cases, options, warm_up

from warpratchet.recording import DEFAULT_MAX_POINTS, RecordingSink, frame_every, require_rerun

BUDGET = 1.10
#: (points, steps): 1.2e9 point-steps each, from a small to a subsampled large ensemble.
CASES = [(10_000, 120_000), (100_000, 12_000), (1_000_000, 1_200)]
QUICK_CASES = [(10_000, 20_000), (200_000, 1_000)]
#: The text table: (header, key, format).
COLUMNS = [
    ("points", "points", "d"), ("steps", "steps", "d"), ("every", "every", "d"), ("frames", "frames", "d"),
    ("ms/frame", "frame_ms", ".2f"), ("MB", "file_mb", ".1f"), ("plain s", "seconds_plain", ".3f"),
    ("rec s", "seconds_recorded", ".3f"), ("ratio", "ratio", ".3f"), ("cpu ratio", "cpu_ratio", ".3f"),
]  # fmt: skip


def measure(points: int, steps: int, repeat: int, folder: Path) -> dict[str, Any]:
    """Best-of-``repeat`` wall times with and without recording, alternating."""
    every = frame_every(points, steps)

    def recorded(ens, rep: int) -> dict[str, Any]:
        path = folder / f"run_{points}_{rep}.rrd"
        sink = RecordingSink(path, every=every)
        ens.run(steps, [sink], chunk_steps=every)
        return {
            "path": path,
            "frames": len(sink.frames),
            "frame_ms": 1e3 * float(np.mean(sink.frame_seconds)),
        }

    def remove(info: dict[str, Any]) -> None:
        info["file_mb"] = info["path"].stat().st_size / 1e6
        info.pop("path").unlink()

    t = compare(points, steps, repeat, recorded, remove)
    last = t["measured"][-1]
    ratio = t["sink"] / t["plain"]
    return {
        "points": points,
        "steps": steps,
        "recorded_points": min(points, DEFAULT_MAX_POINTS),
        "every": every,
        "frames": last["frames"],
        "frame_ms": last["frame_ms"],
        "file_mb": last["file_mb"],
        "seconds_plain": t["plain"],
        "seconds_recorded": t["sink"],
        "ratio": ratio,
        "cpu_seconds_plain": t["plain_cpu"],
        "cpu_seconds_recorded": t["sink_cpu"],
        "cpu_ratio": t["sink_cpu"] / t["plain_cpu"],
        "within_budget": ratio <= BUDGET,
        "bitwise_identical": t["identical"],
    }


def main(argv: list[str] | None = None) -> int:
    args, repeat = options(__doc__, argv, repeat=5)
    # Compile the kernel and import rerun outside the timings; the import is a one-off cost of
    # every recorded run, reported on its own.
    warm_up()
    start = time.perf_counter()
    require_rerun()
    import_seconds = time.perf_counter() - start
    cases = QUICK_CASES if args.quick else CASES
    rows = measure_cases(cases, repeat, measure, "warpratchet-rec-")
    result = {
        "params": PARAMS.as_dict(),
        "init": INIT,
        "seed": SEED,
        "repeats": repeat,
        "budget": BUDGET,
        "rerun_import_seconds": import_seconds,
        "cases": rows,
    }
    emit(
        result,
        args.json,
        COLUMNS,
        f"(one-off, not in the ratios: importing rerun took {import_seconds:.2f} s)",
    )
    if not all(r["bitwise_identical"] for r in rows):
        log("error: recording changed the results")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
