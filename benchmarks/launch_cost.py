"""What one launch boundary costs: CPU time of a launch of a slice of the state, by slice size.

Launches ``advance_map`` on the first ``size`` points of a strip ensemble (K = 3, b1 = 0.1,
b2 = 0.01, seed 0, one thread) for 1 and for 8 steps, repeated, and reports the CPU seconds per
launch and per point. A launch's cost is ``fixed + steps x per-step``; the fixed part per point,
``(t(1) - (t(8) - t(1)) / 7) / size``, is what every stop of a run (a history row, a chunk end)
adds for each point. Comparing slices that fit a core's cache with the whole ensemble says whether
that cost is memory traffic (then smaller in cache) or arithmetic (the same per point).

Two ways to launch: ``AdvanceKernel.launch`` (the arrays and coefficients packed each time) and
the replay of a recorded launch (``AdvanceKernel.recorded`` / ``replay``), which is how
``Ensemble`` launches its shards chunk after chunk; the difference is the Python work of a launch.

Usage::

    python benchmarks/launch_cost.py                 # slices of 16 384, 65 536 and 10^6 points
    python benchmarks/launch_cost.py --json
    python benchmarks/launch_cost.py --quick --json  # smoke test
"""

from __future__ import annotations

import argparse
import json
import time

import warp as wp

from warpratchet import Ensemble, MapParams
from warpratchet.ensemble import _KERNEL_FIELDS

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
SIZES, QUICK_SIZES = (16_384, 65_536, 1_000_000), (1_024, 16_384)
WORK = 20_000_000  # point-steps per measurement


def launch_seconds(ens: Ensemble, size: int, steps: int, work: int, replayed: bool) -> float:
    """CPU seconds of one launch of ``steps`` steps on the first ``size`` points (mean of repeats)."""
    arrays = [ens._arrays[name][:size] for name in _KERNEL_FIELDS]
    recorded = ens._kernel.recorded(ens.device, arrays, [], ens.params)
    repeats = max(3, work // (size * steps))
    start = time.process_time()
    for _ in range(repeats):
        if replayed:
            ens._kernel.replay(recorded, ens.step, steps)
        else:
            ens._kernel.launch(ens.device, arrays, [], ens.step, steps, ens.params)
        wp.synchronize_device(ens.device)
    return (time.process_time() - start) / repeats


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small slices (smoke test)")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = parser.parse_args(argv)
    sizes, work = (QUICK_SIZES, WORK // 20) if args.quick else (SIZES, WORK)
    wp.config.quiet = True
    ens = Ensemble.sample(PARAMS, max(sizes), seed=0, threads=1)
    ens._kernel.load(ens.device, table=ens.params.table)
    rows = []
    for size in sizes:
        for replayed in (False, True):
            one = launch_seconds(ens, size, 1, work, replayed)
            eight = launch_seconds(ens, size, 8, work, replayed)
            per_step = (eight - one) / 7
            rows.append(
                {
                    "points": size,
                    "launch": "replayed" if replayed else "packed",
                    "launch_1_step_s": one,
                    "launch_8_steps_s": eight,
                    "fixed_ns_per_point": 1e9 * (one - per_step) / size,
                    "step_ns_per_point": 1e9 * per_step / size,
                }
            )
    if args.json:
        print(json.dumps({"rows": rows}))
    else:
        print("| points | launch | 1-step launch (ms) | 8-step launch (ms) | fixed ns/point | step ns/pt |")
        print("|---:|---|---:|---:|---:|---:|")
        for r in rows:
            print(
                f"| {r['points']:,} | {r['launch']} | {1e3 * r['launch_1_step_s']:.3f} "
                f"| {1e3 * r['launch_8_steps_s']:.3f} "
                f"| {r['fixed_ns_per_point']:.1f} | {r['step_ns_per_point']:.2f} |"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
