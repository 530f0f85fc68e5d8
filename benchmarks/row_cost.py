"""What a history row costs, part by part, and the best a run with such rows can do against its kernel.

A run's history summarises every point at each row (``Ensemble.summary``: the FTLE, the chaotic
points' ``A_n``, the sums of :func:`~warpratchet.observables.summarize_with_variance`, NumPy's
numbers bit for bit), and the run stops there. This benchmark takes a strip ensemble (K = 3,
b1 = 0.1, b2 = 0.01, seed 0) advanced 1000 steps and times, on 1 and 2 threads:

* **a row**: one step (so that the state is the kernel's, just written, as a run's rows find it),
  then ``summary()`` on the threads that made the step, as a run makes its rows; on one thread
  also split into the row kernels' launches (``hypot``, the row pass, the leaf sums, by kernel
  name) and the rest (NumPy's ``log`` where the kernels' is not NumPy's, and Python);
* **the kernel**: launches of 1 and of 200 steps on those threads, whose difference gives the
  seconds per step, and the rest of the 1-step launches the cost of a stop (a launch boundary).

From these, for ``warpratchet run --points N --steps S`` (default 6000), whose history has
``R = len(history_steps(0, S))`` rows: the kernel's ``S`` steps, and the best ratio kernel / run
that rows and stops of these costs allow, ``kernel / (kernel + R (row + stop))``: what the run
would reach if nothing else cost anything (its block gains, its copies, its threads' meetings).

Usage::

    python benchmarks/row_cost.py                  # 10^6 points, --steps 6000
    python benchmarks/row_cost.py --points 100000 --steps 60000 --json
    python benchmarks/row_cost.py --quick --json   # smoke test
"""

from __future__ import annotations

import argparse
import collections
import json
import statistics
import time
from concurrent.futures import ThreadPoolExecutor

import warp as wp

from warpratchet import Ensemble, MapParams
from warpratchet.cli import positive_int
from warpratchet.history import history_steps

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
#: Steps of the longer of the two timed launches of the kernel.
LONG_RUN = 200


def _timed_launches() -> tuple[dict[str, float], object]:
    """``wp.launch`` timed by kernel name while it is swapped in: the seconds per name, and Warp's own."""
    seconds: dict[str, float] = collections.defaultdict(float)
    launch = wp.launch

    def timed(kernel, *args, **kwargs):
        start = time.perf_counter()
        try:
            return launch(kernel, *args, **kwargs)
        finally:
            seconds[kernel.key] += time.perf_counter() - start

    wp.launch = timed
    return seconds, launch


def row_seconds(ens: Ensemble, repeats: int, split: bool) -> tuple[list[float], dict[str, float]]:
    """``repeats`` rows' wall seconds (each after one step), and with ``split`` the row kernels'
    launches' seconds per row by kernel name."""
    rows, parts = [], {}
    for _ in range(repeats):
        ens._advance(1, ens.run_pool)
        seconds, launch = _timed_launches() if split else ({}, None)
        try:
            start = time.perf_counter()
            ens.summary(warn=False)
            rows.append(time.perf_counter() - start)
        finally:
            if launch is not None:
                wp.launch = launch
        for name, value in seconds.items():
            parts[name] = parts.get(name, 0.0) + value / repeats
    return rows, parts


def kernel_seconds(ens: Ensemble, repeats: int, long_run: int) -> tuple[float, float]:
    """Seconds per step, and of a stop: from launches of 1 and of ``long_run`` steps, medians of
    ``repeats``."""
    one, many = [], []
    for _ in range(repeats):
        for steps, times in ((1, one), (long_run, many)):
            start = time.perf_counter()
            ens._advance(steps, ens.run_pool)
            times.append(time.perf_counter() - start)
    t1, tn = statistics.median(one), statistics.median(many)
    per_step = (tn - t1) / (long_run - 1)
    return per_step, t1 - per_step


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=positive_int, default=None, help="ensemble size (default 10^6)")
    parser.add_argument("--steps", type=positive_int, default=6000, help="the run's steps S (default 6000)")
    parser.add_argument("--repeats", type=positive_int, default=9, help="rows timed per case (default 9)")
    parser.add_argument("--quick", action="store_true", help="70 000 points, 3 repeats (smoke test)")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = parser.parse_args(argv)
    # quick: just enough points for the rows' kernels (4 leaves of TREE_LEAF), as at 10^6
    points = args.points or (70_000 if args.quick else 1_000_000)
    repeats = 3 if args.quick else args.repeats
    long_run = 20 if args.quick else LONG_RUN
    wp.config.quiet = True
    rows_in_run = len(history_steps(0, args.steps))
    cases = []
    for threads in (1, 2):
        ens = Ensemble.sample(PARAMS, points, seed=0, threads=threads)
        ens.run(1000)
        # the rows on the threads of the launches, kept buffers and all, as inside Ensemble.run
        pool = ThreadPoolExecutor(threads) if threads > 1 else None
        ens._run_pool, ens._running = pool, True
        try:
            row_seconds(ens, 1, False)  # its buffers and modules, once
            per_step, stop = kernel_seconds(ens, repeats, long_run)
            rows, parts = row_seconds(ens, repeats, threads == 1)
        finally:
            ens._run_pool, ens._running = None, False
            if pool is not None:
                pool.shutdown()
        row = statistics.median(rows)
        kernel = args.steps * per_step + stop
        case = {
            "threads": threads,
            "row_s": row,
            "row_range_s": [min(rows), max(rows)],
            "row_ns_per_point": 1e9 * row / points,
            "step_s": per_step,
            "stop_s": stop,
            "row_in_steps": row / per_step,
            "kernel_s": kernel,
            "best_ratio": kernel / (kernel + rows_in_run * (row + stop)),
        }
        if parts:
            case["row_launches_s"] = dict(parts)
            case["row_rest_s"] = row - sum(parts.values())
        cases.append(case)
    report = {"points": points, "steps": args.steps, "rows_in_run": rows_in_run, "cases": cases}
    if args.json:
        print(json.dumps(report))
        return 0
    print(f"{points:,} points; a run of {args.steps:,} steps has {rows_in_run} history rows")
    for c in cases:
        low, high = (1e3 * s for s in c["row_range_s"])
        print(
            f"{c['threads']} thread(s): a row {1e3 * c['row_s']:.2f} ms [{low:.2f}, {high:.2f}] "
            f"({c['row_ns_per_point']:.2f} ns per point, {c['row_in_steps']:.1f} steps of the kernel); "
            f"a stop {1e3 * c['stop_s']:.2f} ms; the kernel {c['kernel_s']:.3f} s; "
            f"best kernel / run with these rows {c['best_ratio']:.3f}"
        )
        if "row_launches_s" in c:
            split = ", ".join(f"{name} {1e3 * s:.2f}" for name, s in c["row_launches_s"].items())
            rest = 1e3 * c["row_rest_s"]
            print(f"    the row's launches (ms): {split}; the rest (NumPy, Python) {rest:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
