"""Where a ``warpratchet run`` spends what its kernel does not: every launch and every row timed.

Each round runs ``warpratchet run --K 3 --b1 0.1 --b2 0.01 --points N --steps S --threads T
--json --quiet`` in this process, then the kernel alone (the same sampling and one
``Ensemble.run(S, chunk_steps=S)``), and times, inside both:

* **launches**: each chunk's launches (``Ensemble._advance``, or ``Ensemble._advance_copying``
  where the threads carry pieces of the ensemble through the chunk's stops on their own: then one
  entry for the chunk), against the kernel alone's one; with a pool, per entry, how much later the
  last thread starts than the first (``start lag``) and how much longer the slowest thread runs
  than the fastest (``shard lag``: what the barrier at the end waits for);
* **rows**: each history row's summary (``Ensemble.summary``), their count and median (a row at
  a copy of the state is made while the threads run on);
* **blocks**: the block records made from the history's own copy of its subsample.

Only the ensemble of the run is counted under launches (not the block records' copy). The numbers
explain :mod:`end_to_end`'s ratio; they are not a target.

Usage::

    python benchmarks/run_pieces.py                                  # 10^6 x 6000, 2 rounds, 1 and 2 threads
    python benchmarks/run_pieces.py --points 10000 --steps 120000    # the README's main job
    python benchmarks/run_pieces.py --quick --json                   # smoke test
"""

from __future__ import annotations

import contextlib
import io
import json
import statistics
import sys
import threading
import time
from collections.abc import Iterator

from end_to_end import PARAMS, job_parser, job_size, kernel_alone, run_cli

from warpratchet import Ensemble
from warpratchet.ensemble import default_threads
from warpratchet.history import History


class Probe:
    """Timings of launches, shards, rows and block records while installed (:meth:`installed`)."""

    def __init__(self) -> None:
        self.launches: list[dict] = []  # per _advance of a counted ensemble: steps, seconds, lags
        self.rows: list[float] = []
        self.blocks: list[float] = []
        self._in_blocks = False
        self._shards: list[tuple[float, float]] = []

    @contextlib.contextmanager
    def installed(self) -> Iterator[Probe]:
        probe = self
        launch, advance, copying = Ensemble._launch, Ensemble._advance, Ensemble._advance_copying
        summary, record_block = Ensemble.summary, History._record_block

        def timed_launch(self, lo, hi, step0, steps):
            start = time.perf_counter()
            launch(self, lo, hi, step0, steps)
            probe._shards.append((threading.get_ident(), start, time.perf_counter()))

        def timed_advance(self, steps, pool):
            probe._shards = []
            start = time.perf_counter()
            advance(self, steps, pool)
            if not probe._in_blocks:
                probe._chunk(steps, time.perf_counter() - start)

        def timed_advance_copying(self, stops, end, pool, at_copy):
            # a chunk whose threads carry pieces through its stops on their own: one entry
            probe._shards, steps = [], end - self.step
            start = time.perf_counter()
            copying(self, stops, end, pool, at_copy)
            probe._chunk(steps, time.perf_counter() - start)

        def timed_summary(self, *args, **kwargs):
            start = time.perf_counter()
            result = summary(self, *args, **kwargs)
            probe.rows.append(time.perf_counter() - start)
            return result

        def timed_record_block(self, step):
            probe._in_blocks = True
            start = time.perf_counter()
            try:
                record_block(self, step)
            finally:
                probe._in_blocks = False
                probe.blocks.append(time.perf_counter() - start)

        Ensemble._launch, Ensemble._advance = timed_launch, timed_advance
        Ensemble._advance_copying = timed_advance_copying
        Ensemble.summary, History._record_block = timed_summary, timed_record_block
        try:
            yield self
        finally:
            Ensemble._launch, Ensemble._advance, Ensemble._advance_copying = launch, advance, copying
            Ensemble.summary, History._record_block = summary, record_block

    def _chunk(self, steps: int, seconds: float) -> None:
        """Record a chunk of ``steps`` that took ``seconds``: each thread's first start and its time
        from there to its last launch's end (its launches are its shard's, or its pieces', at every
        stop in the chunk)."""
        shards: dict[int, list[float]] = {}
        for thread, start, end in self._shards:
            first, last = shards.setdefault(thread, [start, end])
            shards[thread] = [min(first, start), max(last, end)]
        starts, durations = [s for s, _ in shards.values()], [e - s for s, e in shards.values()]
        several = len(shards) > 1
        self.launches.append(
            {
                "steps": steps,
                "seconds": seconds,
                "start_lag": max(starts) - min(starts) if several else 0.0,
                "shard_lag": max(durations) - min(durations) if several else 0.0,
            }
        )


def measure(points: int, steps: int, threads: int) -> dict:
    """One round: the run, then the kernel alone, each under its own :class:`Probe`."""
    with Probe().installed() as run:
        _, run_timing = run_cli(PARAMS, points, steps, threads)
    with Probe().installed() as kernel:
        _, kernel_timing = kernel_alone(points, steps, threads)
    launch_s = sum(x["seconds"] for x in run.launches)
    kernel_launch_s = sum(x["seconds"] for x in kernel.launches)
    return {
        "run_s": run_timing.seconds,
        "kernel_s": kernel_timing.seconds,
        "ratio": kernel_timing.seconds / run_timing.seconds,
        "launches": len(run.launches),
        "launch_s": launch_s,
        "kernel_launch_s": kernel_launch_s,
        "launch_s_beyond_kernel": launch_s - kernel_launch_s,
        "start_lag_s": sum(x["start_lag"] for x in run.launches),
        "shard_lag_s": sum(x["shard_lag"] for x in run.launches),
        "shard_lag_ms_median": 1e3 * statistics.median(x["shard_lag"] for x in run.launches),
        "rows": len(run.rows),
        "row_s": sum(run.rows),
        "row_ms_median": 1e3 * statistics.median(run.rows) if run.rows else 0.0,
        "blocks": len(run.blocks),
        "block_s": sum(run.blocks),
    }


def main(argv: list[str] | None = None) -> int:
    args = job_parser("run_pieces.py", __doc__.splitlines()[0], rounds=2).parse_args(argv)
    points, steps, rounds = job_size(args)
    Ensemble.sample(PARAMS, 64, threads=1).run(16)  # compile (or load) the kernel outside the timings
    results = []
    for threads in sorted({1, default_threads()}):
        for r in range(rounds):
            print(f"{threads} thread(s), round {r + 1}", file=sys.stderr, flush=True)
            with contextlib.redirect_stdout(io.StringIO()):
                results.append({"threads": threads, "round": r + 1, **measure(points, steps, threads)})
    report = {"points": points, "steps": steps, "rounds": rounds, "results": results}
    if args.json:
        print(json.dumps(report))
        return 0
    print(f"warpratchet run, piece by piece: {points:,} points x {steps:,} steps (seconds; lags summed)")
    head = ["threads", "run", "kernel", "ratio", "launches", "beyond", "start lag", "shard lag"]
    head += ["rows", "row ms", "blocks"]
    print("".join(f"{h:>10}" for h in head))
    for row in results:
        cells = [row["threads"], f"{row['run_s']:.3f}", f"{row['kernel_s']:.3f}", f"{row['ratio']:.3f}"]
        cells += [row["launches"], f"{row['launch_s_beyond_kernel']:.3f}", f"{row['start_lag_s']:.3f}"]
        cells += [f"{row['shard_lag_s']:.3f}", row["rows"], f"{row['row_ms_median']:.1f}"]
        cells += [f"{row['block_s']:.3f}"]
        print("".join(f"{c:>10}" for c in cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
