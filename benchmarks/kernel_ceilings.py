"""The three CPU kernels against the hand-vectorised C of their instruction set, interleaved.

``advance_map``, ``advance_map_indicators`` (MEGNO and FLI) and ``advance_map_transport`` (return
times and flights) each advance an ensemble of their own (10^6 points uniform in the strip B of
Eq. (B) at K = 3, b1 = 0.1, b2 = 0.01, seed 1, first advanced 1024 steps untimed), launch after
launch as ``Ensemble.run`` launches them (one launch per thread, no observers), and the
hand-vectorised C of the kernels' code path (``c/ratchet_map_avx2.c`` or ``_avx512.c``, the
faster of its vector counts, ``throughput_contenders.py``) advances a copy of the map's state by
as many steps. One round times each once, the order reversed every other round, so all see the
same spells of load; each round gives each kernel's ratio to the C of the same round, per wall
second and per CPU second (the rate over the process's CPU time: what a row did with the CPU it
got). The C is the map and tangent only, so it is the ceiling of ``advance_map``; the other two
kernels do more work per step (the targets: 0.8 for ``advance_map``, 0.7 for the others).

Where the time of a kernel's launches goes, per round: each thread's rate per second of its own
CPU (the launches' point-steps over the CPU seconds of the threads that ran them: a kernel whose
threads slow each other down has a lower one on 2 threads than on 1), and the slowest shard's wall
time over the launches' (below 1: time outside the shards, serial work or a pool thread waiting to
run; a shard slower than the other shows here too).

The C's end state after the first round must equal the map kernel's bit for bit, and the three
kernels' orbits each other's (the script exits with status 1 otherwise).

Usage::

    python benchmarks/kernel_ceilings.py                 # 10^6 points, 400 steps a launch, 3 rounds
    python benchmarks/kernel_ceilings.py --rounds 5 --json
    python benchmarks/kernel_ceilings.py --quick --json  # smoke test
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import throughput_contenders as contenders

from warpratchet import Ensemble, MapParams
from warpratchet.ensemble import default_threads
from warpratchet.kernels import CPU_ISA
from warpratchet.sumrule import IndicatorEnsemble
from warpratchet.transport import TransportEnsemble

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
KERNELS = {"map": Ensemble, "indicators": IndicatorEnsemble, "transport": TransportEnsemble}
TARGETS = {"map": 0.8, "indicators": 0.7, "transport": 0.7}


def _ensemble(cls: type[Ensemble], points: int, threads: int, pool) -> Ensemble:
    start = Ensemble.sample(PARAMS, points, contenders.INIT, seed=contenders.SEED, threads=threads)
    ens = start if cls is Ensemble else cls(PARAMS, start.array("x"), start.array("p0"), threads=threads)
    # loaded before the threads launch it: a first load on two threads at once can crash Warp
    ens._kernel.load(ens.device, table=ens.params.table)
    ens._advance(1024, pool)  # tangents large enough to renormalise
    return ens


def _clock_shards(ens: Ensemble, log: list[tuple[int, float, float]]) -> None:
    """Log each launch of ``ens`` (one per shard and thread): its point-steps, wall seconds and
    the CPU seconds of the thread that ran it."""
    launch = ens._launch

    def timed(lo: int, hi: int, step0: int, steps: int) -> None:
        wall, cpu = time.perf_counter(), time.thread_time()
        launch(lo, hi, step0, steps)
        log.append(((hi - lo) * steps, time.perf_counter() - wall, time.thread_time() - cpu))

    ens._launch = timed


def _timed(work) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    work()
    return time.perf_counter() - wall, time.process_time() - cpu


def measure(points: int, steps: int, rounds: int, threads: int, ceiling) -> dict:
    """Rates and per-round ratios to the C of one thread count."""
    pool = ThreadPoolExecutor(threads) if threads > 1 else None
    ensembles = {name: _ensemble(cls, points, threads, pool) for name, cls in KERNELS.items()}
    start = ensembles["map"].state()
    start = {name: start[name] for name in contenders.EVOLVED}
    step0 = ensembles["map"].step
    rates: dict[str, list[tuple[float, float]]] = {name: [] for name in ["c", *KERNELS]}
    shards: dict[str, list[tuple[int, float, float]]] = {name: [] for name in KERNELS}
    thread_rates: dict[str, list[float]] = {name: [] for name in KERNELS}
    balance: dict[str, list[float]] = {name: [] for name in KERNELS}
    for name, ens in ensembles.items():
        _clock_shards(ens, shards[name])
    c_state = None
    for r in range(rounds):
        order = ["c", *KERNELS] if r % 2 == 0 else [*reversed(KERNELS), "c"]
        for name in order:
            if name == "c":
                state, timing = ceiling(start, step0, steps)
                c_state = c_state or state
                wall, cpu = timing.seconds, timing.cpu_seconds
            else:
                shards[name].clear()
                wall, cpu = _timed(lambda e=ensembles[name]: e._advance(steps, pool))
                thread_rates[name].append(sum(s[0] for s in shards[name]) / sum(s[2] for s in shards[name]))
                balance[name].append(max(s[1] for s in shards[name]) / wall)
            rates[name].append((points * steps / wall, points * steps * threads / cpu))
        if r == 0:
            first = ensembles["map"].state()
            same_c = all(np.array_equal(c_state[k], first[k]) for k in contenders.EVOLVED)
    ends = {name: e.state() for name, e in ensembles.items()}
    same_orbit = all(
        np.array_equal(ends["map"][k], ends[name][k]) for name in KERNELS for k in contenders.EVOLVED
    )
    if pool is not None:
        pool.shutdown()
    row = {"threads": threads, "best_rate": {n: max(w for w, _ in v) for n, v in rates.items()}}
    for name in KERNELS:
        pairs = list(zip(rates[name], rates["c"], strict=True))
        row[f"{name}_vs_c_wall"] = [a[0] / b[0] for a, b in pairs]
        row[f"{name}_vs_c_cpu"] = [a[1] / b[1] for a, b in pairs]
        row[f"{name}_thread_rate"] = thread_rates[name]
        row[f"{name}_slowest_shard"] = balance[name]
    row["bitwise_equal"] = bool(same_c and same_orbit)
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=None, help="points (default 10^6)")
    parser.add_argument("--steps", type=int, default=None, help="steps per launch (default 400)")
    parser.add_argument("--rounds", type=int, default=None, help="rounds (default 3)")
    parser.add_argument("--quick", action="store_true", help="20 000 points x 200 steps, 2 rounds")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = parser.parse_args(argv)
    points = args.points or (20_000 if args.quick else 1_000_000)
    steps = args.steps or (200 if args.quick else 400)
    rounds = args.rounds or (2 if args.quick else 3)
    threads = sorted({1, default_threads()})
    with tempfile.TemporaryDirectory(prefix="warpratchet-ceilings-") as workdir:
        rows, build = contenders.c_simd_contenders(CPU_ISA, PARAMS, threads, Path(workdir))
        if rows[0].advance is None:
            print(build, file=sys.stderr)
            return 1
        result = [measure(points, steps, rounds, c.threads, c.advance) for c in rows]
    report = {"isa": CPU_ISA, "points": points, "steps": steps, "rounds": rounds, "targets": TARGETS}
    report["rows"] = result
    if args.json:
        print(json.dumps(report))
    else:
        print(f"{CPU_ISA} path, {points} points, launches of {steps} steps, {rounds} rounds:")
        for row in result:
            best = "  ".join(f"{n} {v / 1e6:.0f}" for n, v in row["best_rate"].items())
            print(f"{row['threads']} thread(s), best M point-steps/s: {best}")
            for name in KERNELS:
                wall, cpu = row[f"{name}_vs_c_wall"], row[f"{name}_vs_c_cpu"]
                print(
                    f"  {name:>10} / C: per wall second {min(wall):.2f}-{max(wall):.2f},"
                    f" per CPU second {min(cpu):.2f}-{max(cpu):.2f} (target {TARGETS[name]})"
                )
            for name in KERNELS:
                rate, slowest = row[f"{name}_thread_rate"], row[f"{name}_slowest_shard"]
                print(
                    f"  {name:>10}: M point-steps per second of each thread's CPU {min(rate) / 1e6:.0f}"
                    f"-{max(rate) / 1e6:.0f}; slowest shard's wall / the launches' {min(slowest):.2f}"
                    f"-{max(slowest):.2f}"
                )
            print(f"  bitwise equal: {'yes' if row['bitwise_equal'] else 'NO'}")
    return 0 if all(row["bitwise_equal"] for row in result) else 1


if __name__ == "__main__":
    sys.exit(main())
