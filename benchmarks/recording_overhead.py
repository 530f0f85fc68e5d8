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
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from warpratchet import Ensemble, MapParams
from warpratchet.ensemble import STATE_FIELDS
from warpratchet.recording import DEFAULT_MAX_POINTS, RecordingSink, frame_every, require_rerun

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
INIT, SEED = "strip", 1
BUDGET = 1.10
#: (points, steps): 1.2e9 point-steps each, from a small to a subsampled large ensemble.
CASES = [(10_000, 120_000), (100_000, 12_000), (1_000_000, 1_200)]
QUICK_CASES = [(10_000, 20_000), (200_000, 1_000)]


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def measure(points: int, steps: int, repeats: int, folder: Path) -> dict[str, Any]:
    """Best-of-``repeats`` wall times with and without recording, alternating."""
    every = frame_every(points, steps)
    plain, recorded, plain_cpu, recorded_cpu = [], [], [], []
    frames = frame_ms = size = 0.0
    identical = True
    for rep in range(repeats):
        ens = Ensemble.sample(PARAMS, points, INIT, SEED)
        start, cpu = time.perf_counter(), time.process_time()
        ens.run(steps)
        plain.append(time.perf_counter() - start)
        plain_cpu.append(time.process_time() - cpu)
        reference = ens.state()
        del ens

        ens = Ensemble.sample(PARAMS, points, INIT, SEED)
        path = folder / f"run_{points}_{rep}.rrd"
        start, cpu = time.perf_counter(), time.process_time()
        sink = RecordingSink(path, every=every)
        ens.run(steps, [sink], chunk_steps=every)
        recorded.append(time.perf_counter() - start)
        recorded_cpu.append(time.process_time() - cpu)
        identical &= all(np.array_equal(reference[k], ens.array(k)) for k in STATE_FIELDS)
        frames = len(sink.frames)
        frame_ms = 1e3 * float(np.mean(sink.frame_seconds))
        size = path.stat().st_size
        path.unlink()
        del ens
    ratio = min(recorded) / min(plain)
    return {
        "points": points,
        "steps": steps,
        "recorded_points": min(points, DEFAULT_MAX_POINTS),
        "every": every,
        "frames": frames,
        "frame_ms": frame_ms,
        "file_mb": size / 1e6,
        "seconds_plain": min(plain),
        "seconds_recorded": min(recorded),
        "ratio": ratio,
        "cpu_seconds_plain": min(plain_cpu),
        "cpu_seconds_recorded": min(recorded_cpu),
        "cpu_ratio": min(recorded_cpu) / min(plain_cpu),
        "within_budget": ratio <= BUDGET,
        "bitwise_identical": identical,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small cases (smoke test)")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    parser.add_argument("--repeats", type=int, default=None, help="repetitions per case (default 5, quick 1)")
    args = parser.parse_args(argv)
    repeats = args.repeats or (1 if args.quick else 5)
    cases = QUICK_CASES if args.quick else CASES

    # Compile the kernel (or load it from the cache) and import rerun outside the timings; the
    # import is a one-off cost of every recorded run, reported on its own.
    Ensemble.sample(PARAMS, 64, INIT, SEED).run(8)
    start = time.perf_counter()
    require_rerun()
    import_seconds = time.perf_counter() - start
    rows = []
    with tempfile.TemporaryDirectory(prefix="warpratchet-rec-") as tmp:
        for points, steps in cases:
            _log(f"{points} points x {steps} steps ...")
            rows.append(measure(points, steps, repeats, Path(tmp)))
    result = {
        "params": PARAMS.as_dict(),
        "init": INIT,
        "seed": SEED,
        "repeats": repeats,
        "budget": BUDGET,
        "rerun_import_seconds": import_seconds,
        "cases": rows,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"{'points':>9} {'steps':>7} {'every':>6} {'frames':>6} {'ms/frame':>8} {'MB':>6} "
            f"{'plain s':>8} {'rec s':>8} {'ratio':>6} {'cpu ratio':>9}"
        )
        for r in rows:
            print(
                f"{r['points']:>9} {r['steps']:>7} {r['every']:>6} {r['frames']:>6} {r['frame_ms']:>8.2f} "
                f"{r['file_mb']:>6.1f} {r['seconds_plain']:>8.3f} {r['seconds_recorded']:>8.3f} "
                f"{r['ratio']:>6.3f} {r['cpu_ratio']:>9.3f}"
            )
        print(f"(one-off, not in the ratios: importing rerun took {import_seconds:.2f} s)")
    if not all(r["bitwise_identical"] for r in rows):
        _log("error: recording changed the results")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
