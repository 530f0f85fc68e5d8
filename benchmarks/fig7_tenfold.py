"""Fig. 7 at ten times the paper's numerics, timed on this machine and projected to the figure.

The paper's Fig. 7 averages ``A_n`` over 10^4 initial conditions at n = 120 000 for each of the 33
values of b2 on the maximal path (``warpratchet.paper.FIG7``). Ten times both, 10^5 orbits and
1.2 x 10^6 steps per point, is 33 x 10^5 x 1.2 x 10^6 = 4 x 10^12 point-steps. This script runs
one point of the path (b2 in the middle of the caption's interval, b1 on the maximal path) with
10^5 orbits as a user would, ``warpratchet run --points 100000 --steps S`` (history and verdict
included; in this process, after the kernel is compiled), with S chosen from a short probe so the
run takes about ``--seconds`` (60), and divides the whole figure's point-steps by the measured rate,
and by that rate over the run's CPU use (what the run did per CPU second: the projection for a
machine whose cores are the run's alone, the steadier number on a shared one).

Usage::

    python benchmarks/fig7_tenfold.py                 # one minute on all cores
    python benchmarks/fig7_tenfold.py --json
    python benchmarks/fig7_tenfold.py --quick --json  # smoke test (10^4 orbits, a second or two)
"""

from __future__ import annotations

import argparse
import json
import os
import sys

from end_to_end import run_cli

from warpratchet import Ensemble, paper
from warpratchet.ensemble import default_threads
from warpratchet.sweep import maximal_path

#: The figure at ten times its numerics.
ORBITS = 10 * paper.POINTS
STEPS = 10 * paper.STEPS
FIGURE_POINT_STEPS = paper.FIG7.count * ORBITS * STEPS
#: The point of the path that is timed: b2 in the middle of the caption's interval.
B2 = sum(paper.FIG7.b2_range) / 2


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fig7_tenfold.py", description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="length of the timed run (default 60)")
    parser.add_argument("--quick", action="store_true", help="10^4 orbits, about a second (smoke test)")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = parser.parse_args(argv)
    if not 0.0 < args.seconds <= 3600.0:
        parser.error(f"--seconds {args.seconds} is outside the allowed range 0 < seconds <= 3600")
    orbits, seconds = (ORBITS // 10, 1.0) if args.quick else (ORBITS, args.seconds)
    threads = default_threads()
    (params,) = maximal_path([B2], K=paper.FIG7.K)
    Ensemble.sample(params, 64, threads=1).run(16)  # compile (or load) the kernel outside the timings
    load = os.getloadavg()
    probe_steps = 2000
    _, probe = run_cli(params, orbits, probe_steps, threads)
    steps = max(probe_steps, min(STEPS, int(probe_steps * seconds / probe.seconds)))
    print(f"b2 = {B2:g}: {orbits:,} orbits x {steps:,} steps on {threads} threads", file=sys.stderr)
    report, timing = run_cli(params, orbits, steps, threads)
    rate = orbits * steps / timing.seconds
    cpu_use = timing.cpu_seconds / (timing.seconds * threads)
    result = {
        "figure": paper.FIG7.figure,
        "b1": params.b1,
        "b2": params.b2,
        "orbits": orbits,
        "steps": steps,
        "threads": threads,
        "seconds": timing.seconds,
        "cpu_use": cpu_use,
        "load_average_at_start": list(load),
        "point_steps_per_second": rate,
        "A": report["A"],
        "lyapunov": report["lyapunov"],
        "figure_point_steps": FIGURE_POINT_STEPS,
        "figure_seconds": FIGURE_POINT_STEPS / rate,
        # What the machine would take with its cores to itself: the rate per CPU second.
        "figure_seconds_with_all_cores": FIGURE_POINT_STEPS / rate * cpu_use,
        "goal_seconds": 3600.0,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"{paper.FIG7.figure} at b2 = {params.b2:g}, b1 = {params.b1:.6g}: {orbits:,} orbits x {steps:,} "
            f"steps in {timing.seconds:.1f} s on {threads} threads (CPU use {result['cpu_use']:.2f})"
        )
        print(f"  {rate / 1e6:,.0f} M point-steps/s, A = {report['A']:.5g}, sigma = {report['lyapunov']:.4g}")
        print(
            f"  the whole figure at 10x ({paper.FIG7.count} points x {ORBITS:,} orbits x {STEPS:,} steps "
            f"= {FIGURE_POINT_STEPS:.2g} point-steps): {result['figure_seconds'] / 3600:.2f} h "
            f"(goal: under 1 h); with the cores to itself (at this run's rate per CPU second): "
            f"{result['figure_seconds_with_all_cores'] / 3600:.2f} h"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
