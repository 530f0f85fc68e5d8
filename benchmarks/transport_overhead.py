"""What ``--transport`` costs: ``warpratchet run --transport`` end to end against a plain run.

The same ensemble (10^6 points uniform in the strip B of Eq. (B) at K = 3, b1 = 0.1, b2 = 0.01,
seed 1) is run from step 0 by ``steps`` iterations (default 12 000) as ``warpratchet run`` runs
it: with a :class:`~warpratchet.history.History` observer and the default chunking, once as a
:class:`warpratchet.Ensemble` (kernel ``advance_map``) and once as a
:class:`warpratchet.transport.TransportEnsemble` (kernel ``advance_map_transport``: the same orbit
plus the return-time and flight histograms, and the spread rows of mu), alternately
(which goes first alternates too), ``--repeat`` times each (default 4: single pairs scatter by
+-7% on a shared 2-core machine, their median much less), on one thread and on all of them;
each keeps its best time, and each pair (one plain run, one transport run) gives a ratio of its
own.
Both sides pay the history rows and the chunk ends they make (~140 launches per thread at 10^6
points x 12 000 steps), so the ratio ``transport / plain`` of throughputs from the same run is
what a user sees (the target: at least 0.85). Both must end in the same state and history
rows bit for bit.

Each timing is taken twice: wall time, and the CPU time of the process (all its threads). On a
machine shared with other jobs the wall time also counts the time slices the others take (on 2
threads of a 2-core machine, most of the spread), the CPU time only this process's work; the
CPU-time ratio is the cost of ``--transport`` itself, the wall-time ratio what a user waits.

The plain kernel is not touched by the transport variant (its hooks are empty; the step loop of
``advance_map`` is the same object code as before, ``benchmarks/instruction_mix.py``).

Usage::

    python benchmarks/transport_overhead.py            # 10^6 points x 12 000 steps, 1 and all threads
    python benchmarks/transport_overhead.py --json     # one JSON object on stdout
    python benchmarks/transport_overhead.py --quick    # 20 000 points x 500 steps, one repetition
    python benchmarks/transport_overhead.py --kernel --steps 333   # the kernels alone, 1 thread
    python benchmarks/transport_overhead.py --kernel --block-rows 1  # the decoder's row loop alone

``--kernel``: the two kernels alone, one launch of ``steps`` per timing on the same arrays (no
ensemble, no spread rows, no chunking), one thread, CPU time, best of ``--repeat`` (default 5).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from warpratchet import Ensemble, MapParams
from warpratchet.ensemble import default_threads
from warpratchet.history import History
from warpratchet.transport import TransportEnsemble

PARAMS = MapParams(K=3.0, b1=0.1, b2=0.01)
TARGET = 0.85


def _ready(cls: type[Ensemble], points: int, threads: int) -> Ensemble:
    ensemble = cls.sample(PARAMS, points, "strip", seed=1, threads=threads)
    ensemble.run(1024)  # compiles (or loads) the kernel; tangents large enough to renormalise
    return ensemble


def measure(points: int, steps: int, threads: int, repeat: int) -> dict:
    """Best seconds of a run of ``steps`` from step 0 per kind, as ``warpratchet run`` makes it.

    Each timing samples a fresh ensemble (not timed) and runs it with a
    :class:`~warpratchet.history.History` observer and the default chunking, as the CLI does with
    and without ``--transport``: the transport side pays its kernel, its spread rows (``Spread``)
    and its per-launch costs, at the chunk ends the history and the chunking make on both sides.
    """
    for cls in (Ensemble, TransportEnsemble):
        _ready(cls, min(points, 1000), threads)  # compile (or load) outside the timings
    seconds: dict[str, list[float]] = {"plain": [], "transport": []}
    cpu_seconds: dict[str, list[float]] = {"plain": [], "transport": []}
    ends: dict[str, tuple] = {}
    kinds = [("plain", Ensemble), ("transport", TransportEnsemble)]
    for i in range(repeat):
        # alternate which side goes first, so that a drift in the machine's load favours neither
        for name, cls in kinds if i % 2 == 0 else kinds[::-1]:
            ensemble = cls.sample(PARAMS, points, "strip", seed=1, threads=threads)
            history = History()
            start, cpu_start = time.perf_counter(), time.process_time()
            ensemble.run(steps, [history])
            seconds[name].append(time.perf_counter() - start)
            cpu_seconds[name].append(time.process_time() - cpu_start)
            ends[name] = (ensemble.state(), history.as_dict())
            del ensemble
    (a, rows_a), (b, rows_b) = ends["plain"], ends["transport"]
    best = {name: min(values) for name, values in seconds.items()}
    best_cpu = {name: min(values) for name, values in cpu_seconds.items()}
    return {
        "threads": threads,
        "points": points,
        "steps": steps,
        "plain_seconds": best["plain"],
        "transport_seconds": best["transport"],
        "plain_rate": points * steps / best["plain"],
        "transport_rate": points * steps / best["transport"],
        "ratio": best["plain"] / best["transport"],
        "plain_cpu_seconds": best_cpu["plain"],
        "transport_cpu_seconds": best_cpu["transport"],
        "cpu_ratio": best_cpu["plain"] / best_cpu["transport"],
        "pairs": [p / t for p, t in zip(seconds["plain"], seconds["transport"], strict=True)],
        "cpu_pairs": [p / t for p, t in zip(cpu_seconds["plain"], cpu_seconds["transport"], strict=True)],
        # the same orbit and the same history rows, bit for bit (NaN rows compared as bytes)
        "identical": all(np.array_equal(a[k], b[k]) for k in a)
        and all(np.asarray(rows_a[k]).tobytes() == np.asarray(rows_b[k]).tobytes() for k in rows_a),
    }


def measure_kernels(points: int, steps: int, repeat: int, block_rows: int = 8) -> dict:
    """Best CPU seconds of one launch of ``steps`` per kernel on the same arrays, alternating
    (``block_rows``: the transport decoder's 8-row blocks, or 1 for its row loop alone)."""
    import warp as wp

    from warpratchet import kernels
    from warpratchet.transport import BINS

    ensemble = _ready(Ensemble, points, 1)
    state, step0 = ensemble.state(), ensemble.step
    names = ("x", "q", "winding", "dx", "dp", "log_stretch")

    def arrays() -> list:
        return [wp.array(np.ascontiguousarray(state[k]), device="cpu") for k in names]

    plain, transport = arrays(), arrays()
    start = np.full(points, step0, dtype=np.int64)
    extra = [
        wp.array(start),
        wp.zeros(points, dtype=wp.int64),
        wp.array(start),
        wp.zeros(3 * BINS, dtype=wp.int64),
    ]
    kernels.advance_map_transport.load("cpu")
    seconds: dict[str, list[float]] = {"plain": [], "transport": []}
    for _ in range(repeat):
        for name, kernel, state_arrays, extra_arrays, options in (
            ("plain", kernels.advance_map, plain, [], {}),
            ("transport", kernels.advance_map_transport, transport, extra, {"block_rows": block_rows}),
        ):
            begin = time.thread_time()
            kernel.launch("cpu", state_arrays, extra_arrays, step0, steps, PARAMS, **options)
            seconds[name].append(time.thread_time() - begin)
        step0 += steps
    best = {name: min(values) for name, values in seconds.items()}
    return {
        "points": points,
        "steps": steps,
        "plain_rate": points * steps / best["plain"],
        "transport_rate": points * steps / best["transport"],
        "ratio": best["plain"] / best["transport"],
        "pairs": [p / t for p, t in zip(seconds["plain"], seconds["transport"], strict=True)],
        "identical": all(np.array_equal(a.numpy(), b.numpy()) for a, b in zip(plain, transport, strict=True)),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=None, help="points (default 10^6)")
    parser.add_argument(
        "--steps", type=int, default=None, help="steps per timing (default 12000; --kernel: 1000)"
    )
    parser.add_argument(
        "--repeat", type=int, default=None, help="timings per side, best kept (default 4; --kernel: 5)"
    )
    parser.add_argument("--quick", action="store_true", help="20 000 points x 500 steps, once")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    parser.add_argument("--kernel", action="store_true", help="the kernels alone: one launch each, 1 thread")
    parser.add_argument(
        "--block-rows",
        type=int,
        choices=(1, 8),
        default=8,
        help="--kernel: the CPU transport decoder's blocks of 8 rows, or 1 (its row loop alone)",
    )
    args = parser.parse_args(argv)
    if args.kernel:
        r = measure_kernels(args.points or 1_000_000, args.steps or 1000, args.repeat or 5, args.block_rows)
        if args.json:
            print(json.dumps({"target_ratio": TARGET, "kernel": r}))
        else:
            pairs = " ".join(f"{p:.2f}" for p in r["pairs"])
            print(f"kernels, {r['points']} points, launches of {r['steps']} steps, 1 thread, CPU time:")
            print(f"plain {r['plain_rate'] / 1e6:.0f} M/s, transport {r['transport_rate'] / 1e6:.0f} M/s,")
            print(f"ratio {r['ratio']:.2f}  pairs {pairs}{'' if r['identical'] else '  STATES DIFFER'}")
        return 0 if r["identical"] else 1
    points = args.points or (20_000 if args.quick else 1_000_000)
    steps = args.steps or (500 if args.quick else 12_000)
    repeat = args.repeat or (1 if args.quick else 4)
    rows = []
    for threads in sorted({1, default_threads()}):
        print(f"{points} points x {steps} steps on {threads} thread(s) ...", file=sys.stderr, flush=True)
        rows.append(measure(points, steps, threads, repeat))
    if args.json:
        print(json.dumps({"target_ratio": TARGET, "rows": rows}))
        return 0 if all(r["identical"] for r in rows) else 1
    print(
        f"{'threads':>7} {'plain M/s':>10} {'transport M/s':>14} {'ratio':>6} {'cpu ratio':>9}"
        f" {'cpu median':>10}  pairs (CPU time, then wall time)"
    )
    for r in rows:
        cpu_pairs = " ".join(f"{p:.2f}" for p in r["cpu_pairs"])
        pairs = " ".join(f"{p:.2f}" for p in r["pairs"])
        line = f"{r['threads']:>7} {r['plain_rate'] / 1e6:10.0f} {r['transport_rate'] / 1e6:14.0f}"
        line = f"{line} {r['ratio']:6.2f} {r['cpu_ratio']:9.2f} {np.median(r['cpu_pairs']):10.2f}"
        print(f"{line}  {cpu_pairs} | {pairs}{'' if r['identical'] else '  STATES DIFFER'}")
    print(
        "transport / plain throughput: best wall time, best CPU time, median of the CPU-time pairs;"
        f" the target is at least {TARGET}"
    )
    return 0 if all(r["identical"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
