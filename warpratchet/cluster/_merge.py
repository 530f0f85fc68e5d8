"""The merged result of a sharded run (:class:`ShardedRun`): the single machine's numbers.

The merge starts when every shard is in. Its tasks run where the shards' records are
(:mod:`._passes`, :mod:`._spread`), on a Dask client or here over records (:class:`_Cluster`);
the client adds their partial sums in the single machine's order. Counts (return times,
flights, runs still open) are int64 sums and merge by addition; block gains are per point of a
fixed subsample and merge by concatenation. ``benchmarks/cluster_scaling.py`` measures the
merge's time.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .. import observables as _obs
from ..errors import renamed_attribute, renamed_keyword
from ..history import History, block_subsample, history_row
from ..observables import Summary
from ..spec import RunSpec
from ._passes import _boundary_pass, _raw, _shard_pass
from ._shard import ShardRecord
from ._spread import _spread_link


class _Cluster:
    """Runs the merge's tasks: on a Dask client over the shards' futures, or here over records."""

    def __init__(self, sources: list, client: Any = None) -> None:
        self.sources, self.client = sources, client
        self.gathered_bytes = 0

    def submit(self, fn, *args):
        if self.client is None:
            return fn(*args)
        return self.client.submit(fn, *args, pure=False)

    def gather(self, items: list) -> list:
        import pickle

        results = items if self.client is None else self.client.gather(items)
        self.gathered_bytes += sum(len(pickle.dumps(r, protocol=5)) for r in results)
        return results


class ShardedRun:
    """The merged result of :func:`run_sharded`: what ``warpratchet run`` reports, bit for bit.

    The merge (module docstring) runs as tasks where the shards' records are: its client receives a
    few numbers per row and per :data:`~warpratchet.observables.SUMMARY_CHUNK` block of points, and
    the spread's column sums, never a record of every point.

    Attributes
    ----------
    params, points, step, seed, init, threads
        As an :class:`~warpratchet.ensemble.Ensemble` of the run has them (``threads``: each
        shard's, as given in the spec).
    shards : int
        Number of shards.
    history : History
        The run's history rows and block gains (:class:`~warpratchet.history.History`).
    seconds : float
        Wall time of the run, from the first submission to the end of the merge.
    merge_seconds : float
        The merge's part of it.
    shard_seconds : list of float
        Each shard's time in its run (on its worker).
    gathered_bytes : int
        What the merge's tasks handed to this process (pickled).
    """

    sampler = renamed_attribute("ShardedRun", "sampler", "init")

    def __init__(
        self, spec: RunSpec, records: list[ShardRecord], transport: bool, sources: list | None = None,
        client: Any = None,
    ) -> None:  # fmt: skip
        start = time.perf_counter()
        self.spec = spec
        self.params = spec.params
        self.points = records[-1].hi
        self.step = spec.steps
        self.seed = spec.seed
        self.init = spec.init
        self.threads = spec.threads
        self.device = spec.device
        self.shards = len(records)
        self.transport = transport
        self._records = records
        self.shard_seconds = [r.seconds for r in records]
        self._steps = [int(n) for n in records[0].steps]
        self._summaries: dict[tuple, Summary] = {}
        cluster = _Cluster(records if sources is None else sources, client)
        self.history = self._history(cluster)
        if transport:
            self._transport = self._merge_transport(cluster)
        self.gathered_bytes = cluster.gathered_bytes
        self.merge_seconds = time.perf_counter() - start
        self.seconds = math.nan

    def _limit(self, step: int, threshold: float | None, rule: str) -> float:
        return _obs.lyapunov_threshold(step, rule) if threshold is None else threshold

    def _passes(self, cluster: _Cluster, rows: list, means: dict | None) -> dict:
        """One pass of the summaries and variances over every chunk: per shard, a task over its
        whole chunks; per chunk that shards share, a task over its points' records."""
        tasks = []
        bounds = [(r.lo, r.hi) for r in self._records]
        chunks = _obs.summary_chunks(self.points)
        for c, (lo, hi) in enumerate(chunks):
            inside = [k for k, (a, b) in enumerate(bounds) if a < hi and lo < b]
            if len(inside) > 1:
                pieces = [cluster.submit(_raw, cluster.sources[k], rows, max(lo, bounds[k][0]),
                                         min(hi, bounds[k][1])) for k in inside]  # fmt: skip
                tasks.append(cluster.submit(_boundary_pass, rows, c, means, *pieces))
        for k, (a, b) in enumerate(bounds):
            whole = [(c, lo, hi) for c, (lo, hi) in enumerate(chunks) if a <= lo and hi <= b]
            if whole:
                tasks.append(cluster.submit(_shard_pass, cluster.sources[k], rows, whole, means))
        parts: dict = {}
        for result in cluster.gather(tasks):
            parts.update(result)
        return parts

    def _history(self, cluster: _Cluster) -> History:
        spec = self.spec
        n = self.points
        chunks = range(len(_obs.summary_chunks(n)))
        rows_in = [
            (k, step, self._limit(step, spec.threshold, spec.threshold_rule))
            for k, step in enumerate(self._steps)
        ]
        first = self._passes(cluster, rows_in, None)
        means = {}
        for k, _, _ in rows_in:
            ones = [first[k, c] for c in chunks]
            a_mean, ftle_mean = _obs.summary_means([p[:5] for p in ones])
            means[k] = (a_mean, ftle_mean, math.fsum(p[5] for p in ones) / n)
        second = self._passes(cluster, rows_in, means)
        rows: dict[str, list] = {}
        for k, step, limit in rows_in:
            ones = [first[k, c][:5] for c in chunks]
            twos = [second[k, c][:3] for c in chunks] if _obs.needs_squares(ones) else []
            summary = _obs.summary_from_sums(step, limit, n, ones, twos)
            self._summaries[(step, spec.threshold, spec.threshold_rule)] = summary
            squares = 0.0
            for c in chunks:  # History's var_dp_all: the chunks' squares added in order
                squares += second[k, c][3]
            row = history_row({"p0": np.empty(0)}, summary)
            row["var_dp_all"] = squares / (n - 1) if n >= 2 else math.nan
            for name, value in row.items():
                rows.setdefault(name, []).append(value)
        first_record = self._records[0]
        block_rows = {
            "block_step": first_record.block_steps,
            "block_gain": list(np.concatenate([r.block_gain for r in self._records], axis=1)),
            "block_ftle": list(np.concatenate([r.block_ftle for r in self._records], axis=1)),
        }
        indices = block_subsample(self.points, self.seed)
        return History.restore(
            rows, block_rows, indices, threshold=spec.threshold, threshold_rule=spec.threshold_rule
        )

    @renamed_keyword("rule", "threshold_rule")
    def summary(
        self,
        threshold: float | None = None,
        threshold_rule: str = "strict",
        *,
        warn: bool = True,
        step: int | None = None,
    ) -> Summary:
        """The summary at the last step (:meth:`Ensemble.summary <warpratchet.ensemble.Ensemble.summary>`),
        or at ``step``, one of the history's row steps, with the run's threshold (or threshold rule).
        ``rule=`` is the former spelling of ``threshold_rule=`` (a :class:`DeprecationWarning`)."""
        step = self.step if step is None else step
        if step not in self._steps:
            raise ValueError(f"step = {step} is not one of the steps the shards recorded: {self._steps}")
        key = (step, threshold, threshold_rule)
        result = self._summaries.get(key)
        if result is None:
            raise ValueError(
                f"threshold = {threshold}, threshold_rule = {threshold_rule}: the merge summarised the "
                f"run's own (threshold = {self.spec.threshold}, threshold_rule = {self.spec.threshold_rule})"
            )
        if warn:
            result.warn()
        return result

    def _merge_transport(self, cluster: _Cluster) -> dict:
        from ..transport import Histograms
        from ..transport._diffusion import spread_steps
        from ..transport._fits import GROUPS, diffusion_fit, pooled_variance
        from ..transport._report import transport_report

        counts = sum(r.counts for r in self._records)
        still_open = sum(r.open_counts for r in self._records)
        steps = spread_steps(0, self.step)
        self.counts = counts
        spec = self.spec
        rows = [(self._steps.index(n), n, self._limit(n, spec.threshold, spec.threshold_rule)) for n in steps]
        moments = np.zeros((len(steps), GROUPS, 3))
        if steps:
            totals = None
            for source in cluster.sources:
                totals = cluster.submit(_spread_link, source, rows, totals, self.points, None)
            total, _, count = cluster.gather([totals])[0]
            count = count.astype(np.float64)
            mean = np.divide(total, count, out=np.zeros_like(total), where=count > 0)
            squares = None
            for source in cluster.sources:
                squares = cluster.submit(_spread_link, source, rows, squares, self.points, mean)
            m2 = cluster.gather([squares])[0][0]
            moments = np.stack([count, mean, m2], axis=2)
        # the transport state's counts and spread rows, as a TransportEnsemble's own
        self.spread_steps, self.spread = np.array(steps, dtype=np.int64), moments
        var = np.array([pooled_variance(m) for m in moments], dtype=np.float64)
        fit = diffusion_fit(
            np.array(steps, dtype=np.int64), var, moments.transpose(1, 0, 2) if len(steps) else None
        )
        return transport_report(
            Histograms.from_counts(counts, self.step), Histograms.from_counts(still_open, self.step), fit
        )

    def report(self) -> dict:
        """The ``"transport"`` object of ``run --json`` (a run with ``transport`` only)."""
        if not self.transport:
            raise ValueError("this run did not count return times and flights (run_sharded(transport=True))")
        return self._transport
