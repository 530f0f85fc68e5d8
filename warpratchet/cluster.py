"""One ensemble split across the workers of a Dask cluster, with the single machine's numbers.

:func:`run_sharded` splits the ensemble of a :class:`~warpratchet.spec.RunSpec` by global point
index into shards (:func:`shard_bounds`), runs each as a Dask task (:func:`run_shard`, on the
worker's own threads) and merges what they record into a :class:`ShardedRun`: the summary, the
history rows and block gains, and with ``transport`` the return-time and flight counts and the
spread of the momentum. Every one of these numbers is bit for bit what the same run gives on one
machine, for any number of shards:

* **Initial conditions by global index.** A shard samples points ``lo <= i < hi`` of the one
  ensemble (:func:`warpratchet.sampling.sampled_chunks` with ``lo``, ``hi``): the same doubles,
  and each point's orbit and tangent are independent of the others (as they are of the thread
  count).
* **Per-point records, reduced in the single machine's order.** The summary (Eq. An's mean over
  the chaotic points and its standard error) and the history's variances are two-pass
  reductions (means first, then deviations from them) whose order of additions follows the
  ensemble's :data:`~warpratchet.observables.SUMMARY_CHUNK` blocks, not the shards'. Partial
  sums per shard cannot reproduce them: a deviation from the mean depends on the global mean,
  which no shard knows while it runs. So each shard records, at the run's common steps (the
  history's rows, :func:`~warpratchet.history.history_steps`, which hold the transport spread's
  steps), two doubles per point: the gain ``p_n - p_0`` and the stretch ``log|DM^n v0|``
  (:class:`ShardRecord`). The merge runs the single machine's own reductions
  (:func:`~warpratchet.observables.summarize`, :func:`~warpratchet.history.history_row`,
  :func:`~warpratchet.transport.diffusion.spread_moments`) over the records in global order:
  the FTLE is ``stretch / n`` and ``A_n`` is ``gain / n``, the very operations of
  :func:`~warpratchet.observables.lyapunov` and :func:`~warpratchet.observables.acceleration`.
  Counts (return times, flights, runs still open) are int64 sums and merge by addition; block
  gains are per point of a fixed subsample and merge by concatenation.
* **No lockstep.** Shards never wait for each other: each runs to the end and hands back its
  records; the merge starts when all are in.

Cost: a record is 16 bytes per point per row (about 40 rows at n = 120000). Without a workdir
the worker holds them until the merge and Dask moves them to the client; with one (storage every
worker and the client share) each row is a file, written as the shard passes its step and read
by the merge, and a shard's memory is its state and one row. The merge holds one row of every
shard at a time (16 bytes per point of the whole ensemble); ``benchmarks/cluster_scaling.py``
measures its time.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._cluster_archive import shard_paths
from .errors import ParameterError, ResourceError, check_count
from .history import BLOCKS, History, block_steps, block_subsample, history_row, history_steps
from .limits import format_bytes
from .observables import SUMMARY_BYTES_PER_POINT, SUMMARY_CHUNK, Summary, lyapunov, momentum_gain, summarize
from .runloop import Observer
from .spec import RunSpec

__all__ = [
    "check_merge",
    "ShardRecord",
    "ShardedRun",
    "shard_bounds",
    "shard_bytes",
    "shard_paths",
    "run_shard",
    "run_sharded",
]


def shard_bounds(points: int, shards: int) -> list[tuple[int, int]]:
    """``(lo, hi)`` of each of ``shards`` shards of ``points`` points: consecutive, as equal as can be."""
    points = check_count("points", points, 1)
    shards = check_count("shards", shards, 1, points)
    bounds = [points * k // shards for k in range(shards + 1)]
    return list(zip(bounds[:-1], bounds[1:], strict=True))


def _ensemble_size(spec: RunSpec) -> int:
    """Points the ensemble of ``spec`` has: a grid rounds down to a square."""
    return math.isqrt(spec.points) ** 2 if spec.init == "grid" else spec.points


def _kind(transport: bool):
    if transport:
        from .transport import TransportEnsemble

        return TransportEnsemble
    from .ensemble import Ensemble

    return Ensemble


def shard_bytes(spec: RunSpec, points: int, transport: bool = False, on_disk: bool = False) -> int:
    """Memory a shard of ``points`` points needs on its worker: the state (and transport's
    carry), one summary's working memory, and its records: 16 B per point per history row, or
    with ``on_disk`` (records in a workdir) one row of them."""
    rows = 1 if on_disk else len(history_steps(0, spec.steps))
    state = _kind(transport).bytes_per_point()
    return points * (state + 16 * rows) + min(points, SUMMARY_CHUNK) * SUMMARY_BYTES_PER_POINT


@dataclass
class ShardRecord:
    """What one shard hands back: its points ``lo <= i < hi`` at the run's common steps.

    ``gain`` and ``stretch``: shape ``(rows, hi - lo)``, the gain ``p_n - p_0``
    (:func:`~warpratchet.observables.momentum_gain`) and ``log|DM^n v0|`` at each of ``steps``,
    or None when they are in the files of ``folder`` (a shard with a workdir): :meth:`row` reads
    either;
    ``block_*``: the block subsample's points in this shard (History's ``block_gain`` and
    ``block_ftle`` at ``block_steps``); ``counts`` and ``open_counts``: the ``(3, BINS)``
    completed and still-open runs of a transport run (None otherwise).
    """

    lo: int
    hi: int
    steps: np.ndarray
    gain: np.ndarray
    stretch: np.ndarray
    block_steps: np.ndarray
    block_gain: np.ndarray
    block_ftle: np.ndarray
    counts: np.ndarray | None
    open_counts: np.ndarray | None
    seconds: float
    folder: str | None = None

    def row(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(gain, stretch)`` of this shard's points at ``steps[k]``."""
        if self.folder is None:
            return self.gain[k], self.stretch[k]
        with np.load(_step_path(self.folder, int(self.steps[k]))) as saved:
            return saved["gain"], saved["stretch"]


def _step_path(folder: str, step: int) -> str:
    """The file of a shard's records at ``step``."""
    return os.path.join(folder, f"step-{step:012d}.npz")


class _Recorder(Observer):
    """Keeps a shard's :class:`ShardRecord` arrays at the row and block steps (ends chunks there).

    With a ``folder``, each step's records also go to ``step-NNNNNNNNNNNN.npz`` there, written under
    a temporary name and published atomically before the run goes on: a shard retried from its
    archive's checkpoint at step ``c`` finds every record up to ``c`` (:meth:`load`), since the
    records of a step are on disk before the archive's checkpoint of that step is written.
    """

    def __init__(
        self, steps: list[int], blocks: list[int], members: np.ndarray, points: int, folder: str | None = None
    ) -> None:
        self.steps, self.blocks, self.members, self.folder = steps, blocks, members, folder
        # with a folder the rows live on disk only: a shard's memory stays its state's
        self.gain = self.stretch = None
        if folder is None:
            self.gain, self.stretch = np.empty((2, len(steps), points))
        self.block_gain = np.empty((len(blocks), members.size))
        self.block_ftle = np.empty((len(blocks), members.size))

    def next_stop(self, step: int) -> int | None:
        return next((n for n in sorted({*self.steps, *self.blocks}) if n > step), None)

    def after_chunk(self, ensemble: Any, seconds: float) -> None:
        step = ensemble.step
        views = ensemble.views()
        due = {}
        if step in self.steps:
            row = self.steps.index(step)
            gain = momentum_gain(views)
            # lyapunov's numerator: the merge divides it by n, as lyapunov does
            stretch = views["log_stretch"] + np.log(np.hypot(views["dx"], views["dp"]))
            if self.folder is None:
                self.gain[row], self.stretch[row] = gain, stretch
            due.update(gain=gain, stretch=stretch)
        if step in self.blocks:
            row = self.blocks.index(step)
            sub = {name: values[self.members] for name, values in views.items()}
            self.block_gain[row] = momentum_gain(sub)
            self.block_ftle[row] = lyapunov(sub, step)
            due.update(block_gain=self.block_gain[row], block_ftle=self.block_ftle[row])
        if due and self.folder is not None:
            self._save(step, due)

    def _save(self, step: int, arrays: dict[str, np.ndarray]) -> None:
        from ._files import publish, temporary_beside

        path = _step_path(self.folder, step)
        with temporary_beside(path) as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, **arrays)
                f.flush()
                os.fsync(f.fileno())
            publish(tmp, path, replace=True)

    def load(self, step: int) -> None:
        """The block records of every step up to ``step`` from :attr:`folder` (a retried shard's;
        its rows stay there)."""
        for n in self.blocks:
            if n > step:
                break
            with np.load(_step_path(self.folder, n)) as saved:
                if n in self.blocks:
                    row = self.blocks.index(n)
                    self.block_gain[row], self.block_ftle[row] = saved["block_gain"], saved["block_ftle"]


def _sample_shard(spec: RunSpec, lo: int, hi: int, transport: bool):
    """The ensemble of points ``lo <= i < hi`` of ``spec``'s ensemble, at step 0."""
    from .sampling import sampled_chunks

    _, chunks = sampled_chunks(spec.params, spec.init, spec.points, spec.seed, lo, hi)
    return _kind(transport)(
        spec.params, None, None, device=spec.device, threads=spec.threads, sampler=spec.init,
        seed=spec.seed, _chunks=(hi - lo, chunks),
    )  # fmt: skip


def run_shard(
    spec: RunSpec,
    lo: int,
    hi: int,
    transport: bool = False,
    observers=(),
    workdir: str | os.PathLike | None = None,
    index: int = 0,
    checkpoint_every: int | None = None,
) -> ShardRecord:
    """Run points ``lo <= i < hi`` of the ensemble of ``spec`` to ``spec.steps``: what a Dask task does.

    A pure function of its arguments (apart from ``seconds``). ``observers`` are added to the
    shard's run (e.g. a progress report of its own).

    With a ``workdir`` (a folder every worker sees), the shard streams into an archive of its
    own there (:func:`shard_paths`: an ordinary archive of its points, checkpointed every
    ``checkpoint_every`` steps, :class:`~warpratchet.archive.ArchiveSink`) and keeps its records
    beside it; a shard whose archive exists (a retry after its worker died) continues from the
    archive's checkpoint, bit for bit.
    """
    from .ensemble import Ensemble

    n = _ensemble_size(spec)
    indices = block_subsample(n, spec.seed)
    members = indices[(indices >= lo) & (indices < hi)] - lo
    archive, folder = shard_paths(workdir, index) if workdir is not None else (None, None)
    recorder = _Recorder(
        history_steps(0, spec.steps), block_steps(0, spec.steps, BLOCKS), members, hi - lo, folder
    )
    sink = None
    if archive is None:
        ensemble = _sample_shard(spec, lo, hi, transport)
    else:
        from .archive import ArchiveSink

        os.makedirs(folder, exist_ok=True)
        if os.path.exists(archive):
            sink, ensemble = ArchiveSink.resume(archive, threads=spec.threads, device=spec.device)
            recorder.load(ensemble.step)
        else:
            ensemble = _sample_shard(spec, lo, hi, transport)
            sink = ArchiveSink(
                archive, ensemble, chunk_steps=spec.chunk_steps, checkpoint_every=checkpoint_every,
                threshold=spec.threshold, threshold_rule=spec.threshold_rule,
            )  # fmt: skip
    start = time.perf_counter()
    try:
        # Ensemble.run itself (not TransportEnsemble.run): the spread is the merge's, from the
        # records. The recorder comes before the sink: a step's records are kept before its checkpoint.
        watchers = [recorder, *([sink] if sink is not None else []), *observers]
        chunk_steps = spec.chunk_steps if sink is None else sink.chunk_steps
        Ensemble.run(ensemble, spec.steps - ensemble.step, watchers, chunk_steps)
    finally:
        if sink is not None:
            sink.close()
    seconds = time.perf_counter() - start
    counts = open_counts = None
    if transport:
        counts = ensemble.histograms().counts()
        open_counts = ensemble.open_runs().counts()
    return ShardRecord(
        lo, hi, np.array(recorder.steps, dtype=np.int64), recorder.gain, recorder.stretch,
        np.array(recorder.blocks, dtype=np.int64), recorder.block_gain, recorder.block_ftle,
        counts, open_counts, seconds, folder,
    )  # fmt: skip


def _point_state(gain: np.ndarray, stretch: np.ndarray) -> dict[str, np.ndarray]:
    """A state whose :func:`~warpratchet.observables.momentum_gain` is ``gain`` and whose
    :func:`~warpratchet.observables.lyapunov` at ``n`` is ``stretch / n``, bit for bit.

    ``gain + (0.0 - (0.0 - 0.0))`` is ``gain`` and ``stretch + log(hypot(1, 0))`` is ``stretch``;
    the constant fields are broadcast views, no memory.
    """
    zero = np.broadcast_to(0.0, gain.shape)
    one = np.broadcast_to(1.0, gain.shape)
    return {"winding": gain, "q": zero, "p0": zero, "dx": one, "dp": zero, "log_stretch": stretch}


class ShardedRun:
    """The merged result of :func:`run_sharded`: what ``warpratchet run`` reports, bit for bit.

    Attributes
    ----------
    params, points, step, seed, sampler, threads
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
    """

    def __init__(self, spec: RunSpec, records: list[ShardRecord], transport: bool) -> None:
        start = time.perf_counter()
        self.spec = spec
        self.params = spec.params
        self.points = records[-1].hi
        self.step = spec.steps
        self.seed = spec.seed
        self.sampler = spec.init
        self.threads = spec.threads
        self.device = spec.device
        self.shards = len(records)
        self.transport = transport
        self._records = records
        self.shard_seconds = [r.seconds for r in records]
        self._steps = [int(n) for n in records[0].steps]
        self._summaries: dict[tuple, Summary] = {}
        self.history = self._history()
        if transport:
            self._transport = self._merge_transport()
        self.merge_seconds = time.perf_counter() - start
        self.seconds = math.nan

    def _state(self, step: int) -> dict[str, np.ndarray]:
        """Every point's record at ``step``, in global order."""
        k = self._steps.index(step)
        rows = [r.row(k) for r in self._records]
        return _point_state(np.concatenate([g for g, _ in rows]), np.concatenate([s for _, s in rows]))

    def _history(self) -> History:
        spec = self.spec
        rows: dict[str, list] = {}
        for step in self._steps:
            state = self._state(step)
            summary = summarize(state, step, spec.threshold, spec.threshold_rule)
            self._summaries[(step, spec.threshold, spec.threshold_rule)] = summary
            for name, value in history_row(state, summary).items():
                rows.setdefault(name, []).append(value)
        first = self._records[0]
        block_rows = {
            "block_step": first.block_steps,
            "block_gain": list(np.concatenate([r.block_gain for r in self._records], axis=1)),
            "block_ftle": list(np.concatenate([r.block_ftle for r in self._records], axis=1)),
        }
        indices = block_subsample(self.points, self.seed)
        return History.restore(
            rows, block_rows, indices, threshold=spec.threshold, threshold_rule=spec.threshold_rule
        )

    def summary(
        self,
        threshold: float | None = None,
        rule: str = "strict",
        *,
        warn: bool = True,
        step: int | None = None,
    ) -> Summary:
        """The summary at the last step (:meth:`Ensemble.summary <warpratchet.ensemble.Ensemble.summary>`),
        or at ``step``, one of the history's row steps."""
        step = self.step if step is None else step
        if step not in self._steps:
            raise ValueError(f"step = {step} is not one of the steps the shards recorded: {self._steps}")
        key = (step, threshold, rule)
        result = self._summaries.get(key)
        if result is None:
            result = summarize(self._state(step), step, threshold, rule)
            self._summaries[key] = result
        if warn:
            result.warn()
        return result

    def _merge_transport(self) -> dict:
        from .transport.diffusion import spread_moments, spread_steps
        from .transport.fits import GROUPS, diffusion_fit, pooled_variance
        from .transport.histograms import Histograms
        from .transport.report import transport_report

        counts = sum(r.counts for r in self._records)
        still_open = sum(r.open_counts for r in self._records)
        steps = spread_steps(0, self.step)
        spec = self.spec
        moments = np.array(
            [spread_moments(self._state(n), n, spec.threshold, spec.threshold_rule) for n in steps]
        ).reshape(len(steps), GROUPS, 3)
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


def _worker_memory(client: Any) -> dict[str, int]:
    """Each worker's memory: Dask's ``memory_limit``, or where it has none, what its machine has
    available (asked of the worker; 0 where unknown)."""
    from .limits import available_memory

    limits = {}
    unlimited = []
    for address, info in client.scheduler_info()["workers"].items():
        limit = int(info.get("memory_limit") or 0)
        limits[address] = limit
        if not limit:
            unlimited.append(address)
    if unlimited:
        for address, free in client.run(available_memory, workers=unlimited).items():
            limits[address] = int(free or 0)
    return limits


def check_merge(points: int, transport: bool = False) -> None:
    """ResourceError, before any work, if this machine cannot hold the merge: one row of every
    point's records (16 B a point), with ``transport`` the spread's gains and mask (9 B a point,
    :func:`~warpratchet.transport.diffusion.spread_moments`), and one summary's working memory."""
    from .limits import check_memory

    per_point = 16 + (9 if transport else 0)
    summary = min(points, SUMMARY_CHUNK) * SUMMARY_BYTES_PER_POINT
    check_memory(f"points = {points} (the merge of a sharded run)", per_point * points + summary,
                 f"{per_point} B per point and {format_bytes(summary)} to summarise them")  # fmt: skip


def _check_workers(
    client: Any, spec: RunSpec, bounds: list[tuple[int, int]], transport: bool, on_disk: bool
) -> None:
    """ResourceError, before any work, if the largest shard does not fit the smallest worker."""
    limits = _worker_memory(client)
    if not limits:
        raise ResourceError("the Dask cluster has no workers; start some (docs/cluster.md)")
    largest = max(hi - lo for lo, hi in bounds)
    needed = shard_bytes(spec, largest, transport, on_disk)
    address, smallest = min(limits.items(), key=lambda item: item[1])
    if smallest and needed > smallest:
        rows = 1 if on_disk else len(history_steps(0, spec.steps))
        raise ResourceError(
            f"shards = {len(bounds)}: a shard of {largest} points needs {format_bytes(needed)} "
            f"({_kind(transport).bytes_per_point()} B of state and {16 * rows} B of records per point), "
            f"worker {address} has a memory limit of {format_bytes(smallest)}; use more shards "
            f"(at least {math.ceil(len(bounds) * needed / smallest)}) or workers with more memory"
        )


def _claim_workdir(workdir: str | os.PathLike, spec: RunSpec, bounds: list, transport: bool) -> str:
    """``workdir`` as an absolute path, made if missing, with ``run.json`` naming the run its shards
    belong to; ParameterError if it holds the shards of another run (its archives would be resumed)."""
    import json

    workdir = os.path.abspath(os.fspath(workdir))
    run = {k: v for k, v in json.loads(spec.to_json()).items() if k not in ("threads", "device")}
    run.update(transport=transport, shards=[list(b) for b in bounds])
    manifest = os.path.join(workdir, "run.json")
    if os.path.exists(manifest):
        with open(manifest) as f:
            held = json.load(f)
        if held != run:
            differ = sorted(k for k in run.keys() | held.keys() if run.get(k) != held.get(k))
            raise ParameterError(
                f"workdir = {workdir} holds the shards of another run (it differs in {', '.join(differ)}); "
                "choose another folder or remove it"
            )
        return workdir
    os.makedirs(workdir, exist_ok=True)
    with open(manifest, "w") as f:
        json.dump(run, f, indent=1)
    return workdir


def run_sharded(
    spec: RunSpec,
    client: Any,
    shards: int | None = None,
    *,
    transport: bool = False,
    observers=(),
    workdir: str | os.PathLike | None = None,
    checkpoint_every: int | None = None,
    out: str | os.PathLike | None = None,
    progress: bool = False,
) -> ShardedRun:
    """Run the ensemble of ``spec`` as ``shards`` Dask tasks and merge them (module docstring).

    Parameters
    ----------
    spec : RunSpec
        The run; ``threads`` is each shard's (None: every core of its worker process).
    client : dask.distributed.Client or str
        The cluster, or its scheduler's address (connected and closed here).
    shards : int, optional
        Shards, ``1..points``; default one per worker.
    transport : bool
        Count return times and flights too (:class:`~warpratchet.transport.TransportEnsemble`).
    observers : sequence of Observer
        Added to every shard's run (pickled to the workers).
    workdir : path, optional
        A folder on storage every worker shares: each shard keeps an archive of its points and
        its records there (:func:`run_shard`), so that a shard whose worker dies is retried from
        its last checkpoint rather than from step 0. The folder is made if missing.
    checkpoint_every : int, optional
        Steps between the shards' checkpoints (with ``workdir``; default: the archive's).
    out : path, optional
        One archive of the whole run, written when it is merged (a new file; ``workdir``
        defaults to ``out`` + ``".shards"``): the merged series and history, and the shards'
        per-point data as virtual datasets over their archives (:mod:`warpratchet._cluster_archive`).
    progress : bool
        A progress bar over the shards done, on stderr.

    Raises
    ------
    ResourceError
        The largest shard does not fit the smallest worker's memory limit (checked before any work).
    RuntimeError
        A shard failed for good (after Dask's retries of a lost worker): names the shard and why.
    """
    from .sweep.run import _connect

    if not isinstance(spec, RunSpec):
        raise ParameterError(f"spec = {spec!r} is not a RunSpec")
    from .limits import check_kernel_range

    check_kernel_range(spec.params)
    if out is not None:
        out = os.fspath(out)
        if os.path.lexists(out):
            raise ParameterError(f"out = {out} exists; choose a new path (nothing was run)")
        if workdir is None:
            workdir = out + ".shards"
    client, owned = _connect(client)
    try:
        points = _ensemble_size(spec)
        if shards is None:
            shards = max(1, len(client.scheduler_info()["workers"]))
        bounds = shard_bounds(points, min(check_count("shards", shards, 1, points), points))
        _check_workers(client, spec, bounds, transport, workdir is not None)
        check_merge(points, transport)
        if workdir is not None:
            workdir = _claim_workdir(workdir, spec, bounds, transport)
        start = time.perf_counter()
        futures = [
            client.submit(
                run_shard, spec, lo, hi, transport, list(observers), workdir, k, checkpoint_every, pure=False
            )
            for k, (lo, hi) in enumerate(bounds)
        ]
        import distributed

        from .progress import ProgressBar

        records: dict[int, ShardRecord] = {}
        index = {future.key: k for k, future in enumerate(futures)}
        bar = ProgressBar("shards", disable=not progress, unit="shard")
        bar.open(len(bounds))
        try:
            # In the order they finish (a failure is reported at once), merged in shard order.
            for future in distributed.as_completed(futures):
                k = index[future.key]
                try:
                    records[k] = future.result()
                except Exception as exc:
                    lo, hi = bounds[k]
                    why = f"{type(exc).__name__}: {exc}"
                    raise RuntimeError(
                        f"shard {k} of {len(bounds)} (points {lo}..{hi - 1}) failed: {why}"
                    ) from exc
                bar.advance()
        finally:
            bar.close()
            client.cancel(futures)
        records = [records[k] for k in range(len(bounds))]
        merged = ShardedRun(spec, records, transport)
        merged.seconds = time.perf_counter() - start
        if out is not None:
            from ._cluster_archive import write_merged

            write_merged(out, merged, workdir, bounds)
        return merged
    finally:
        if owned:
            client.close()
