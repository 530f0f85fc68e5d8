"""What a run's stops cost on its threads, with no observer work at all.

A run stops at every step an observer asks to see (a history's rows and, for a small ensemble,
its block steps). This benchmark runs the stops of ``warpratchet run --points N --steps S`` (its
History's, through the History's own ``next_stop``, and the run's regular chunk ends) with an
observer that does nothing at them, against the same ensemble advanced in one chunk, in three
ways, alternately (the order turns every round), on each thread count:

* **one chunk**: no stop;
* **stops**: the threads meet at every stop (every thread's launch ends there and the next starts
  when the last shard is done), as for an observer that needs the live ensemble;
* **copies**: the threads go through the chunk's stops on their own and copy the state at each
  (``Observer.takes_state_copies``, as a History's stops are run), meeting at the chunk's end.

The differences are what the stops themselves cost: launches, the hand-over between threads,
shards that end at different times, and the copies.

For each stopped run it also times every shard's launch (``perf_counter`` around each thread's
launch, from an :class:`~warpratchet.ensemble.Ensemble` subclass, which the run always makes meet
at its stops) and prints, per stop:

* ``lag_first_us``, ``lag_rest_us``: from the start of the chunk to the start of the first shard
  (the thread that calls the run) and of the others (the pool's);
* ``spread_us``: how much later the last shard ends than the first one to end;
* ``tail_us``: from the last shard's end to the end of the chunk;
* ``shards_vs_one``: the shards' summed launch times over the one-chunk run's, per thread (above
  1: the launches themselves run slower when cut at the stops).

Usage::

    python benchmarks/stop_cost.py                   # the README's main job, 10^4 x 120 000; 1 and 2 threads
    python benchmarks/stop_cost.py --points 1000000 --steps 6000 --rounds 3
    python benchmarks/stop_cost.py --quick --json    # smoke test
"""

from __future__ import annotations

import argparse
import json
import statistics
import threading
import time
from typing import Any

import warp as wp
from end_to_end import INIT, PARAMS, SEED, median_range, spread_text

from warpratchet import Ensemble, Observer
from warpratchet.ensemble import default_threads
from warpratchet.history import History


class TimedEnsemble(Ensemble):
    """An ensemble that keeps the start and end of every shard's launch and of every chunk."""

    def _launch(self, lo: int, hi: int, step0: int, steps: int) -> None:
        start = time.perf_counter()
        super()._launch(lo, hi, step0, steps)
        self.launches.append((lo, threading.get_ident(), start, time.perf_counter()))

    def _advance(self, steps: int, pool: Any) -> None:
        start = time.perf_counter()
        super()._advance(steps, pool)
        self.chunks.append((start, time.perf_counter()))


class StopsOf(Observer):
    """Stops where ``history`` would (its ``next_stop``) and does nothing there; takes copies of
    the state there if ``copies``."""

    def __init__(self, history: History, copies: bool) -> None:
        self.history = history
        self.takes_state_copies = copies

    def begin(self, ensemble: Any, target_step: int) -> None:
        self.history.begin(ensemble, target_step)

    def next_stop(self, step: int) -> int | None:
        return self.history.next_stop(step)


#: The ways to run (module docstring).
WAYS = ("one chunk", "stops", "copies")


def timed_run(points: int, steps: int, threads: int, way: str) -> tuple[float, Ensemble]:
    """Wall seconds of ``steps`` steps of the CLI's ensemble in one of :data:`WAYS` (stopped where
    the run's History stops it, with the run's default chunking), and the ensemble."""
    kind = Ensemble if way == "copies" else TimedEnsemble  # a TimedEnsemble meets at every stop
    ens = kind.sample(PARAMS, points, init=INIT, seed=SEED, threads=threads)
    ens.launches, ens.chunks = [], []
    start = time.perf_counter()
    if way == "one chunk":
        ens.run(steps, chunk_steps=steps)
    else:
        ens.run(steps, [StopsOf(History(), copies=way == "copies")])
    return time.perf_counter() - start, ens


def anatomy(ens: TimedEnsemble, one_launch_s: float) -> dict[str, float]:
    """Per stop: the shards' start lags, the spread of their ends and the tail (microseconds), and
    the shards' summed launch times over the one-chunk run's."""
    main = threading.get_ident()
    first, rest, spread, tail = [], [], [], []
    by_chunk: list[list] = [[] for _ in ens.chunks]
    for launch in ens.launches:
        index = next(i for i, (a, b) in enumerate(ens.chunks) if a <= launch[2] <= b)
        by_chunk[index].append(launch)
    for (start, end), shards in zip(ens.chunks, by_chunk, strict=True):
        ends = [launch[3] for launch in shards]
        first += [launch[2] - start for launch in shards if launch[1] == main]
        rest += [launch[2] - start for launch in shards if launch[1] != main]
        spread.append(max(ends) - min(ends))
        tail.append(end - max(ends))
    summed = sum(launch[3] - launch[2] for launch in ens.launches) / ens.threads
    return {
        "lag_first_us": 1e6 * statistics.fmean(first),
        "lag_rest_us": 1e6 * statistics.fmean(rest) if rest else 0.0,
        "spread_us": 1e6 * statistics.fmean(spread),
        "tail_us": 1e6 * statistics.fmean(tail),
        "shards_vs_one": summed / one_launch_s,
    }


def measure(points: int, steps: int, threads: int, rounds: int) -> dict[str, Any]:
    """Rounds of the three ways, in turns; medians and ranges."""
    times: dict[str, list[float]] = {way: [] for way in WAYS}
    parts, stops = [], 0
    for r in range(rounds):
        for way in WAYS[r % 3 :] + WAYS[: r % 3]:
            seconds, ens = timed_run(points, steps, threads, way)
            times[way].append(seconds)
            if way == "stops":
                stops, stopped = len(ens.chunks), ens
        parts.append(anatomy(stopped, times["one chunk"][-1]))
    ones = times["one chunk"]
    ratio = {way: [one / run for one, run in zip(ones, times[way], strict=True)] for way in WAYS[1:]}
    cost = [(run - one) / stops for one, run in zip(ones, times["stops"], strict=True)]
    return {
        "threads": threads,
        "chunks": stops,
        "one_chunk_s": statistics.median(ones),
        "stopped_s": statistics.median(times["stops"]),
        "copies_s": statistics.median(times["copies"]),
        "ratio": median_range(ratio["stops"]),
        "copies_ratio": median_range(ratio["copies"]),
        "ms_per_stop": statistics.median(cost) * 1e3,
        **{key: statistics.median(p[key] for p in parts) for key in parts[0]},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10_000)
    parser.add_argument("--steps", type=int, default=120_000)
    parser.add_argument("--rounds", type=int, default=6, help="rounds per thread count (the ways in turns)")
    parser.add_argument("--threads", type=int, nargs="+", default=None, help="default: 1 and every core")
    parser.add_argument("--quick", action="store_true", help="2 000 points x 3 000 steps, 2 rounds (smoke)")
    parser.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = parser.parse_args(argv)
    if args.quick:
        args.points, args.steps, args.rounds = 2_000, 3_000, 2
    threads = args.threads or sorted({1, default_threads()})
    wp.config.quiet = True
    timed_run(1_000, 10, max(threads), "stops")  # compile and warm up before any timing
    rows = [measure(args.points, args.steps, t, args.rounds) for t in threads]
    if args.json:
        print(json.dumps({"points": args.points, "steps": args.steps, "rounds": args.rounds, "rows": rows}))
        return 0
    print(f"{args.points} points x {args.steps} steps, {args.rounds} rounds, the ways in turns (medians)")
    print(
        "| threads | chunks | one chunk (s) | stops (s) | one / stops [range] | copies (s) "
        "| one / copies [range] | ms per stop | lag first (us) | lag others (us) | spread (us) "
        "| tail (us) | shards / one |"
    )
    print("|---:|---:|---:|---:|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['threads']} | {r['chunks']} | {r['one_chunk_s']:.3f} | {r['stopped_s']:.3f} "
            f"| {spread_text(r['ratio'])} | {r['copies_s']:.3f} "
            f"| {spread_text(r['copies_ratio'])} | {r['ms_per_stop']:.2f} "
            f"| {r['lag_first_us']:.0f} | {r['lag_rest_us']:.0f} | {r['spread_us']:.0f} "
            f"| {r['tail_us']:.0f} | {r['shards_vs_one']:.3f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
