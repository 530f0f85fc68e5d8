"""Cost of recording a run with rerun: wall time with a RecordingSink over wall time without.

Each case advances a fresh strip ensemble (Eq. B) at K = 3, b1 = 0.1, b2 = 0.01 (seed 1) by
``steps`` iterations twice per repetition, alternately

* without recording: ``Ensemble.run(steps)`` with the default chunking, and
* with recording: ``Ensemble.run(steps, [RecordingSink(path)])`` with the sink's defaults
  (log-spaced frames of at most 20000 points within 10 MB and 5% of the run time, the kernel's
  speed measured by a probe), exactly what ``warpratchet run --rerun`` does; the time includes
  the probe, opening the file, every frame and the final flush,

and reports the ratio of the best wall times (the budget is 1.10) and of the best
process CPU times (all threads, including rerun's writer): on a machine shared with other
jobs the CPU-time ratio is the steadier of the two. Both runs must end in
bitwise equal states (recording never changes results); the script exits with status 1 if not.
Timings on the shared 2-core machine are noisy; the ratio, taken within one run, is the number
to read.

``--speedup S`` emulates a kernel S times faster (the kernel keeps getting faster, and a frame
costs the same CPU time whatever the kernel): the ensemble advances only 1/S of its points per
step, so the run takes 1/S of the time while the recording still draws and summarises all of
them. The budget must hold there too, since frames are sized by the *measured* speed.

Usage::

    python benchmarks/recording_overhead.py            # three cases, ~1.5 s per run (~2 min)
    python benchmarks/recording_overhead.py --speedup 3    # as if the kernel were 3x faster
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

from warpratchet import Ensemble
from warpratchet.recording import DEFAULT_MAX_POINTS, RecordingSink, blueprint, require_rerun

BUDGET = 1.10
#: (points, steps): 1.2e9 point-steps each, from a small to a subsampled large ensemble.
CASES = [(10_000, 120_000), (100_000, 12_000), (1_000_000, 1_200)]
QUICK_CASES = [(10_000, 20_000), (200_000, 1_000)]
#: The text table: (header, key, format).
COLUMNS = [
    ("points", "points", "d"), ("steps", "steps", "d"), ("frames", "frames", "d"),
    ("ms/frame", "frame_ms", ".2f"), ("MB", "file_mb", ".1f"), ("plain s", "seconds_plain", ".3f"),
    ("rec s", "seconds_recorded", ".3f"), ("ratio", "ratio", ".3f"), ("cpu ratio", "cpu_ratio", ".3f"),
]  # fmt: skip


def faster(speedup: int) -> type[Ensemble]:
    """An Ensemble whose kernel seems ``speedup`` times faster: it advances the first 1/speedup of
    its points only (the others stay put), while observers see every point."""
    if speedup == 1:
        return Ensemble

    class Faster(Ensemble):
        def _advance(self, steps, pool):
            everyone = self.points
            self.points = max(1, everyone // speedup)
            try:
                super()._advance(steps, pool)
            finally:
                self.points = everyone

    return Faster


def measure(points: int, steps: int, repeat: int, folder: Path, speedup: int = 1) -> dict[str, Any]:
    """Best-of-``repeat`` wall times with and without recording, alternating."""

    def recorded(ens, rep: int) -> dict[str, Any]:
        path = folder / f"run_{points}_{rep}.rrd"
        sink = RecordingSink(path)
        ens.run(steps, [sink])
        return {
            "path": path,
            "frames": len(sink.frames),
            "planned_frames": len(sink.plan.steps),
            "frame_ms": 1e3 * float(np.mean(sink.frame_seconds)),
        }

    def remove(info: dict[str, Any]) -> None:
        info["file_mb"] = info["path"].stat().st_size / 1e6
        info.pop("path").unlink()

    t = compare(points, steps, repeat, recorded, remove, cls=faster(speedup))
    last = t["measured"][-1]
    ratio = t["sink"] / t["plain"]
    return {
        "points": points,
        "steps": steps,
        "recorded_points": min(points, DEFAULT_MAX_POINTS),
        "speedup": speedup,
        "frames": last["frames"],
        "planned_frames": last["planned_frames"],
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
    def speedup_flag(p) -> None:
        p.add_argument("--speedup", type=int, default=1, help="emulate a kernel this many times faster")

    args, repeat = options(__doc__, argv, repeat=5, extra=speedup_flag)
    if args.speedup < 1:
        log(f"error: --speedup {args.speedup} is outside the allowed range >= 1")
        return 2
    # Compile the kernel and import rerun outside the timings; the import is a one-off cost of
    # every recorded run, reported on its own.
    warm_up()
    start = time.perf_counter()
    require_rerun()
    blueprint()  # its first use imports more of rerun
    import_seconds = time.perf_counter() - start
    cases = QUICK_CASES if args.quick else CASES
    rows = measure_cases(cases, repeat, lambda *a: measure(*a, speedup=args.speedup), "warpratchet-rec-")
    result = {
        "params": PARAMS.as_dict(),
        "init": INIT,
        "seed": SEED,
        "repeats": repeat,
        "budget": BUDGET,
        "speedup": args.speedup,
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
