"""Cost of the chaos indicators: ``advance_map_indicators`` against ``advance_map``, interleaved.

The target: the indicators kernel (MEGNO and the FLI: one ``fdlog`` per point every 8 steps,
:mod:`warpratchet.kernels._indicators`) run at >= 0.8 of ``advance_map``'s throughput. On a shared
machine a single timing of each says little, so this script times the two kernels alternately,
many short launches each (the order flips every round, so a slow spell hits both), on the state
of ``throughput.py`` (10^6 points of the strip B, Eq. (B), at K = 3, b1 = 0.1, b2 = 0.01, seed 1,
after 1024 steps), on 1 thread and on all cores (one launch per core, as ``Ensemble.run``). Each
round gives a ratio of throughputs, both per wall second and per CPU second of the process (the
latter ignores time the machine gave to other processes); reported are the median and the range
over rounds, and the ratio of the best rounds. The two kernels must leave the orbit bit for bit
the same (the indicators only read it); the script exits with status 1 if not.

The kernels are launched directly (``warpratchet.kernels``), from global step 1024 with the
indicators' accumulators at zero: the work per step is that of a real run.

Usage::

    python benchmarks/indicators_overhead.py                 # 10^6 points, 15 rounds (~1 min)
    python benchmarks/indicators_overhead.py --json          # one JSON object on stdout
    python benchmarks/indicators_overhead.py --quick --json  # smoke test, a few seconds
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import warp as wp
from end_to_end import median_range
from throughput_contenders import Clock

from warpratchet import Ensemble, MapParams, kernels
from warpratchet.cli import positive_int
from warpratchet.ensemble import default_threads

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
#: The target: the indicators kernel at least this fraction of ``advance_map``'s throughput (throughput.py
#: reports it too).
TARGET = 0.8
WARMUP_STEPS = 1024
STATE = ("x", "q", "winding", "dx", "dp", "log_stretch")
QUICK = {"points": 20_000, "steps": 256, "rounds": 3}


def _launcher(kernel: kernels.AdvanceKernel, init: dict, step0: int, extra: int, threads: int):
    """``run(steps) -> (wall s, CPU s, state)``: ``steps`` iterations of a fresh copy of ``init``."""
    n = init["x"].size
    bounds = np.linspace(0, n, threads + 1).astype(int)
    shards = list(zip(bounds[:-1], bounds[1:], strict=True))

    def run(steps: int):
        state = [wp.array(np.array(init[name]), device="cpu") for name in STATE]
        acc = [wp.zeros(n, dtype=wp.float64, device="cpu") for _ in range(extra)]

        def shard(lo_hi):
            lo, hi = lo_hi
            kernel.launch("cpu", [a[lo:hi] for a in state], [a[lo:hi] for a in acc], step0, steps, PARAMS)

        with Clock() as clock, ThreadPoolExecutor(threads) as pool:
            list(pool.map(shard, shards))
        return clock.timing.seconds, clock.timing.cpu_seconds, state

    return run


def measure(init: dict, step0: int, threads: int, steps: int, rounds: int) -> dict[str, Any]:
    """Alternating timings of both kernels; ratios indicators / map per round."""
    runs = {
        "map": _launcher(kernels.advance_map, init, step0, 0, threads),
        "indicators": _launcher(
            kernels.advance_map_indicators, init, step0, len(kernels.INDICATOR_FIELDS), threads
        ),
    }
    same = all(
        np.array_equal(a.numpy().view(np.int64), b.numpy().view(np.int64))
        for a, b in zip(runs["map"](steps)[2], runs["indicators"](steps)[2], strict=True)
    )
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in runs}
    for r in range(rounds):
        for name in runs if r % 2 == 0 else reversed(runs):
            wall, cpu, _ = runs[name](steps)
            times[name].append((wall, cpu))
    # throughput ratio = time(map) / time(indicators)
    wall = [m[0] / i[0] for m, i in zip(times["map"], times["indicators"], strict=True)]
    cpu = [m[1] / i[1] for m, i in zip(times["map"], times["indicators"], strict=True)]
    point_steps = init["x"].size * steps
    best = {name: min(w for w, _ in t) for name, t in times.items()}
    return {
        "threads": threads,
        "bitwise_same_orbit": same,
        "map_point_steps_per_second": point_steps / best["map"],
        "indicators_point_steps_per_second": point_steps / best["indicators"],
        "ratio_of_best": best["map"] / best["indicators"],
        "ratio_per_wall_second": median_range(wall),
        "ratio_per_cpu_second": median_range(cpu),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="indicators_overhead.py", description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=positive_int, default=1_000_000)
    parser.add_argument("--steps", type=positive_int, default=512, help="steps per timed launch")
    parser.add_argument("--rounds", type=positive_int, default=15)
    parser.add_argument("--quick", action="store_true", help="20 000 points, 256 steps, 3 rounds")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = parser.parse_args(argv)
    if args.quick:
        args.points, args.steps, args.rounds = QUICK["points"], QUICK["steps"], QUICK["rounds"]
    kernels.init_warp()
    load = os.getloadavg()
    ens = Ensemble.sample(PARAMS, args.points, init="strip", seed=1).run(WARMUP_STEPS)
    init, step0 = ens.state(), ens.step
    del ens
    kernels.advance_map.load("cpu")
    kernels.advance_map_indicators.load("cpu")
    rows = [measure(init, step0, t, args.steps, args.rounds) for t in sorted({1, default_threads()})]
    report = {
        "benchmark": "indicators_overhead",
        "quick": args.quick,
        "points": args.points,
        "steps_per_launch": args.steps,
        "rounds": args.rounds,
        "load_average_at_start": list(load),
        "target": TARGET,
        "results": rows,
    }
    if args.json:
        print(json.dumps(report))
    else:
        print(
            f"advance_map_indicators / advance_map, {args.points:,} points x {args.steps} steps per launch, "
            f"{args.rounds} rounds (load average at start {load[0]:.2f}); the target is >= {TARGET}"
        )
        print(
            f"{'threads':>7}{'map Mpt/s':>11}{'ind. Mpt/s':>12}{'best':>7}  per wall s (median [range])"
            "   per CPU s (median [range])  orbit"
        )
        for row in rows:
            w, c = row["ratio_per_wall_second"], row["ratio_per_cpu_second"]
            print(
                f"{row['threads']:>7}{row['map_point_steps_per_second'] / 1e6:>11.0f}"
                f"{row['indicators_point_steps_per_second'] / 1e6:>12.0f}{row['ratio_of_best']:>7.3f}"
                f"  {w['median']:.3f} [{w['min']:.3f}, {w['max']:.3f}]"
                f"         {c['median']:.3f} [{c['min']:.3f}, {c['max']:.3f}]"
                f"      {'same' if row['bitwise_same_orbit'] else 'DIFFERS'}"
            )
    return 0 if all(row["bitwise_same_orbit"] for row in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
