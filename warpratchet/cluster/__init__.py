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
* **Partial sums in the single machine's order.** The summary (Eq. An's mean over the chaotic
  points and its standard error) and the history's variances are two-pass reductions (means
  first, then deviations from them) over the :data:`~warpratchet.observables.SUMMARY_CHUNK`
  blocks of the ensemble: NumPy's pairwise sum within a block, then the blocks' sums in order.
  Each shard records, at the run's common steps (the history's rows,
  :func:`~warpratchet.history.history_steps`, which hold the transport spread's steps), two
  doubles per point, the gain ``p_n - p_0`` and the stretch ``log|DM^n v0|``
  (:class:`ShardRecord`), and keeps them on its worker (or in its workdir). The merge then runs
  two rounds of tasks where the records are: each shard reduces the blocks that lie wholly in
  it (:func:`~warpratchet.observables.chunk_sums`), a block that two shards share is reduced by
  a task handed the records of its points alone; the client adds the blocks' sums in order as
  :func:`~warpratchet.observables.summarize` does, sends the means back, and the second round
  sums the deviations (:func:`~warpratchet.observables.chunk_squares`). The FTLE is
  ``stretch / n`` and ``A_n`` is ``gain / n``, the very operations of
  :func:`~warpratchet.observables.lyapunov` and :func:`~warpratchet.observables.finite_time_acceleration`.
  The spread of the momentum (:func:`~warpratchet.transport._diffusion.spread_moments`) sums
  each group's column row after row: a chain of tasks, shard after shard, carries the column
  sums on (:func:`_fold`), once for the means and once for the squared deviations.
  Counts (return times, flights, runs still open) are int64 sums and merge by addition; block
  gains are per point of a fixed subsample and merge by concatenation.
* **No lockstep.** Shards never wait for each other: each runs to the end and keeps its
  records; the merge starts when all are in.

Cost: a record is 16 bytes per point per row (about 40 rows at n = 120000), on the shard's
worker (with a workdir, storage every worker and the client share: a file per row, and a shard's
memory is its state and one row). The client receives a few numbers per row and per block of
2^20 points (:data:`MERGE_BYTES_PER_BLOCK`) and the spread's column sums: nothing per point.
A block shared by two shards moves its points' records (16 B a point per row) between workers.
``benchmarks/cluster_scaling.py`` measures the merge's time.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import observables as _obs
from .._cluster_archive import shard_paths, shards_folder, snapshot_file, snapshot_steps
from ..archive._format import SNAPSHOT_FIELDS
from ..archive._rows import snapshot_indices, snapshot_row
from ..errors import ParameterError, ResourceError, check_count, renamed_attribute
from ..history import BLOCKS, History, block_steps, block_subsample, history_row, history_steps
from ..limits import format_bytes
from ..observables import SUMMARY_BYTES_PER_POINT, Summary, lyapunov, momentum_gain
from ..runloop import Observer
from ..spec import RunSpec

__all__ = [
    "check_merge",
    "MERGE_BYTES_PER_BLOCK",
    "ShardRecord",
    "ShardedRun",
    "shard_bounds",
    "shard_bytes",
    "shard_paths",
    "shards_folder",
    "snapshot_file",
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
        from ..transport import TransportEnsemble

        return TransportEnsemble
    from ..ensemble import Ensemble

    return Ensemble


def shard_bytes(
    spec: RunSpec,
    points: int,
    transport: bool = False,
    on_disk: bool = False,
    snapshots: tuple[int, int] = (0, 0),
) -> int:
    """Memory a shard of ``points`` points needs on its worker: the state (and transport's
    carry), one summary's working memory, and its records: 16 B per point per history row, or
    with ``on_disk`` (records in a workdir) one row of them; and for the merge, a block of points
    that shards share, whose records at every row one task holds (twice: the pieces and the row
    they make). With ``snapshots`` (``(snapshot_every, snapshot_points)``), the snapshots of at
    most ``min(points, snapshot_points)`` of its points, which it keeps to the end."""
    every = len(history_steps(0, spec.steps))
    rows = 1 if on_disk else every
    state = _kind(transport).bytes_per_point()
    shared = 2 * min(_ensemble_size(spec), _obs.SUMMARY_CHUNK) * 16 * every
    snapped = (
        len(snapshot_steps(spec.steps, snapshots[0])) * len(SNAPSHOT_FIELDS) * 8 * min(points, snapshots[1])
    )
    return (
        points * (state + 16 * rows)
        + min(points, _obs.SUMMARY_CHUNK) * SUMMARY_BYTES_PER_POINT
        + shared
        + snapped
    )


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
        self,
        steps: list[int],
        blocks: list[int],
        members: np.ndarray,
        points: int,
        folder: str | None = None,
        snapshots: tuple[list[int], np.ndarray] = ([], np.empty(0, dtype=np.int64)),
    ) -> None:
        self.steps, self.blocks, self.members, self.folder = steps, blocks, members, folder
        # with a folder the rows live on disk only: a shard's memory stays its state's
        self.gain = self.stretch = None
        if folder is None:
            self.gain, self.stretch = np.empty((2, len(steps), points))
        self.block_gain = np.empty((len(blocks), members.size))
        self.block_ftle = np.empty((len(blocks), members.size))
        # the archive's snapshots of this shard's points of the subsample (local indices)
        self.snapshot_steps, self.snapshot_points = snapshots
        self.snapshots = {name: np.empty((len(self.snapshot_steps), self.snapshot_points.size))
                          for name in SNAPSHOT_FIELDS}  # fmt: skip

    def next_stop(self, step: int) -> int | None:
        stops = sorted({*self.steps, *self.blocks, *self.snapshot_steps})
        return next((n for n in stops if n > step), None)

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
        if step in self.snapshot_steps:
            row = self.snapshot_steps.index(step)
            snapshot = snapshot_row(views, self.snapshot_points, step)
            for name in SNAPSHOT_FIELDS:
                self.snapshots[name][row] = snapshot[name]
                due[f"snapshot_{name}"] = snapshot[name]
        if due and self.folder is not None:
            self._save(step, due)

    def _save(self, step: int, arrays: dict[str, np.ndarray]) -> None:
        from .._files import publish, temporary_beside

        path = _step_path(self.folder, step)
        with temporary_beside(path) as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, **arrays)
                f.flush()
                os.fsync(f.fileno())
            publish(tmp, path, replace=True)

    def load(self, step: int) -> None:
        """The block records and snapshots of every step up to ``step`` from :attr:`folder` (a
        retried shard's; its rows stay there)."""
        for n in self.blocks:
            if n > step:
                break
            with np.load(_step_path(self.folder, n)) as saved:
                row = self.blocks.index(n)
                self.block_gain[row], self.block_ftle[row] = saved["block_gain"], saved["block_ftle"]
        for row, n in enumerate(self.snapshot_steps):
            if n > step:
                break
            with np.load(_step_path(self.folder, n)) as saved:
                for name in SNAPSHOT_FIELDS:
                    self.snapshots[name][row] = saved[f"snapshot_{name}"]

    def write_snapshots(self, path: str) -> None:
        """The snapshots as datasets ``SNAPSHOT_FIELDS`` of shape ``(snapshots, points)`` in a new
        HDF5 file ``path``, published atomically (the merged archive's virtual sources)."""
        import h5py

        from .._files import publish, temporary_beside
        from .._h5 import sync_h5

        with temporary_beside(path) as tmp:
            with h5py.File(tmp, "w") as f:
                for name in SNAPSHOT_FIELDS:
                    f.create_dataset(name, data=self.snapshots[name])
                sync_h5(f)
            publish(tmp, path, replace=True)


def _sample_shard(spec: RunSpec, lo: int, hi: int, transport: bool):
    """The ensemble of points ``lo <= i < hi`` of ``spec``'s ensemble, at step 0."""
    from ..sampling import sampled_chunks

    _, chunks = sampled_chunks(spec.params, spec.init, spec.points, spec.seed, lo, hi)
    return _kind(transport)(
        spec.params, None, None, device=spec.device, threads=spec.threads, init=spec.init,
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
    snapshot_every: int = 0,
    snapshot_points: int = 0,
) -> ShardRecord:
    """Run points ``lo <= i < hi`` of the ensemble of ``spec`` to ``spec.steps``: what a Dask task does.

    A pure function of its arguments (apart from ``seconds``). ``observers`` are added to the
    shard's run (e.g. a progress report of its own).

    With a ``workdir`` (a folder every worker sees), the shard streams into an archive of its
    own there (:func:`shard_paths`: an ordinary archive of its points, checkpointed every
    ``checkpoint_every`` steps, :class:`~warpratchet.archive.ArchiveSink`) and keeps its records
    beside it; a shard whose archive exists (a retry after its worker died) continues from the
    archive's checkpoint, bit for bit. With ``snapshot_every``, it also takes the snapshots a
    single machine's archive takes (:func:`snapshot_steps`) of the points of the archive's
    subsample of ``snapshot_points`` that are its own, and writes them to
    ``snapshots.h5`` in its records folder when it ends (:func:`snapshot_file`).
    """
    from ..ensemble import Ensemble

    n = _ensemble_size(spec)
    indices = block_subsample(n, spec.seed)
    members = indices[(indices >= lo) & (indices < hi)] - lo
    archive, folder = shard_paths(workdir, index) if workdir is not None else (None, None)
    if snapshot_every and folder is None:
        raise ParameterError(f"snapshot_every = {snapshot_every}: a shard's snapshots need a workdir")
    chosen = snapshot_indices(n, min(snapshot_points, n) if snapshot_every else 0, spec.seed)
    snapshots = (snapshot_steps(spec.steps, snapshot_every), chosen[(chosen >= lo) & (chosen < hi)] - lo)
    recorder = _Recorder(
        history_steps(0, spec.steps), block_steps(0, spec.steps, BLOCKS), members, hi - lo, folder, snapshots
    )
    sink = None
    if archive is None:
        ensemble = _sample_shard(spec, lo, hi, transport)
    else:
        from ..archive import ArchiveSink

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
    if snapshot_every:
        recorder.write_snapshots(snapshot_file(folder))
    counts = open_counts = None
    if transport:
        counts = ensemble.histograms().counts()
        open_counts = ensemble.open_runs().counts()
    return ShardRecord(
        lo, hi, np.array(recorder.steps, dtype=np.int64), recorder.gain, recorder.stretch,
        np.array(recorder.blocks, dtype=np.int64), recorder.block_gain, recorder.block_ftle,
        counts, open_counts, seconds, folder,
    )  # fmt: skip


def _without_rows(record: ShardRecord) -> ShardRecord:
    """A Dask task: ``record`` without its rows of every point (what the merge's client keeps)."""
    from dataclasses import replace

    return replace(record, gain=None, stretch=None)


def _point_state(gain: np.ndarray, stretch: np.ndarray) -> dict[str, np.ndarray]:
    """A state whose :func:`~warpratchet.observables.momentum_gain` is ``gain`` and whose
    :func:`~warpratchet.observables.lyapunov` at ``n`` is ``stretch / n``, bit for bit.

    ``gain + (0.0 - (0.0 - 0.0))`` is ``gain`` and ``stretch + log(hypot(1, 0))`` is ``stretch``;
    the constant fields are broadcast views, no memory.
    """
    zero = np.broadcast_to(0.0, gain.shape)
    one = np.broadcast_to(1.0, gain.shape)
    return {"winding": gain, "q": zero, "p0": zero, "dx": one, "dp": zero, "log_stretch": stretch}


def _chunk_values(gain: np.ndarray, stretch: np.ndarray, step: int):
    """FTLE, ``A_n`` and ``p_n - p_0`` of a chunk's points from their records, by the single
    machine's own functions (:func:`_point_state`)."""
    state = _point_state(gain, stretch)
    ftle, acc = _obs._per_point(state, step, 0, len(gain))
    return ftle, acc, momentum_gain(state)


def _chunk_pass(gain, stretch, step: int, limit: float, means) -> tuple:
    """One chunk's part of a row: pass 1 (``means`` None) the summary's :func:`chunk_sums
    <warpratchet.observables.chunk_sums>` and the gains' sum; pass 2 the :func:`chunk_squares
    <warpratchet.observables.chunk_squares>` and the gains' squared deviations (History's
    ``var_dp_all``, :func:`warpratchet.history._variance`)."""
    ftle, acc, dp = _chunk_values(gain, stretch, step)
    if means is None:
        return (*_obs.chunk_sums(ftle, acc, limit), float(np.add.reduce(dp)))
    a_mean, ftle_mean, dp_mean = means
    d = dp - dp_mean
    return (*_obs.chunk_squares(ftle, acc, limit, a_mean, ftle_mean), float(np.add.reduce(d * d)))


def _shard_pass(record: ShardRecord, rows: list, chunks: list, means: dict | None) -> dict:
    """A Dask task: the :func:`_chunk_pass` of every ``(index, lo, hi)`` of ``chunks`` (chunks wholly
    in ``record``'s points) at every ``(k, step, limit)`` of ``rows``; keys ``(k, index)``."""
    parts = {}
    for k, step, limit in rows:
        gain, stretch = record.row(k)
        for c, lo, hi in chunks:
            a, b = lo - record.lo, hi - record.lo
            parts[k, c] = _chunk_pass(
                gain[a:b], stretch[a:b], step, limit, None if means is None else means[k]
            )
    return parts


def _raw(record: ShardRecord, rows: list, lo: int, hi: int) -> list:
    """A Dask task: the records of points ``lo <= i < hi`` (within ``record``) at each of ``rows``."""
    out = []
    for k, _, _ in rows:
        gain, stretch = record.row(k)
        out.append(
            (gain[lo - record.lo : hi - record.lo].copy(), stretch[lo - record.lo : hi - record.lo].copy())
        )
    return out


def _boundary_pass(rows: list, c: int, means: dict | None, *pieces: list) -> dict:
    """A Dask task: :func:`_chunk_pass` of chunk ``c``, whose points lie in several shards
    (``pieces``: their :func:`_raw` records, in order)."""
    parts = {}
    for j, (k, step, limit) in enumerate(rows):
        gain = np.concatenate([p[j][0] for p in pieces])
        stretch = np.concatenate([p[j][1] for p in pieces])
        parts[k, c] = _chunk_pass(gain, stretch, step, limit, None if means is None else means[k])
    return parts


def _fold_into(acc: np.ndarray, started: np.ndarray, columns: slice, values: np.ndarray) -> None:
    """One row of NumPy's column sum: ``acc + values`` where a column has begun, else ``values``."""
    acc[columns] = np.where(started[columns], acc[columns] + values, values)
    started[columns] = True


def _fold(acc: np.ndarray, started: np.ndarray, values: np.ndarray, lo: int, tail: int | None) -> None:
    """Continue the column sums ``acc`` (:func:`~warpratchet.transport._diffusion.spread_moments`'
    ``np.add.reduce(..., axis=0)`` of the points laid out ``(points / G, G)``) with points
    ``lo, lo + 1, ...`` (``values``): NumPy adds row after row there, so the sums of a shard go on
    from those of the shards before it, one elementwise addition per point as on one machine.
    ``tail``: with the last shard, the ensemble's size, whose last row is padded with +0.0."""
    groups = acc.shape[0]
    i = 0
    off = lo % groups
    if off and len(values):
        i = min(groups - off, len(values))
        _fold_into(acc, started, slice(off, off + i), values[:i])
    full = (len(values) - i) // groups
    if full:
        block = values[i : i + full * groups].reshape(full, groups)
        if not started.all():
            _fold_into(acc, started, slice(0, groups), block[0])
            block = block[1:]
        if len(block):
            acc[:] = np.add.reduce(np.concatenate([acc[None], block]), axis=0)
        i += full * groups
    if i < len(values):
        _fold_into(acc, started, slice(0, len(values) - i), values[i:])
    if tail is not None and tail % groups:
        _fold_into(acc, started, slice(tail % groups, groups), np.zeros(groups - tail % groups))


def _spread_link(record: ShardRecord, rows: list, carried: tuple | None, points: int, means) -> tuple:
    """A Dask task, one link of a chain over the shards in order: the spread's column sums at each
    ``(k, step, limit)`` of ``rows`` carried on over ``record``'s points: with ``means`` None the
    chaotic points' counts and gains, else their squared deviations from ``means`` (shape
    ``(rows, G)``), by :func:`~warpratchet.transport._diffusion.spread_moments`' own elementwise code."""
    from ..transport._diffusion import _chaotic_gains
    from ..transport._fits import GROUPS

    if carried is None:
        carried = (np.zeros((len(rows), GROUPS)), np.zeros((len(rows), GROUPS), bool),
                   np.zeros((len(rows), GROUPS), np.int64))  # fmt: skip
    acc, started, counts = (x.copy() for x in carried)
    m = record.hi - record.lo
    columns = (record.lo + np.arange(m)) % GROUPS
    for j, (k, step, limit) in enumerate(rows):
        gain, stretch = record.row(k)
        gains, mask = np.zeros(m), np.zeros(m, dtype=bool)
        _chaotic_gains(_point_state(gain, stretch), step, limit, gains, mask, None, 0, m)
        if means is None:
            counts[j] += np.bincount(columns[mask], minlength=GROUPS)
        else:
            np.copyto(gains, (gains - means[j][columns]) ** 2, where=mask)
        _fold(acc[j], started[j], gains, record.lo, points if record.hi == points else None)
    return acc, started, counts


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

    def summary(
        self,
        threshold: float | None = None,
        rule: str = "strict",
        *,
        warn: bool = True,
        step: int | None = None,
    ) -> Summary:
        """The summary at the last step (:meth:`Ensemble.summary <warpratchet.ensemble.Ensemble.summary>`),
        or at ``step``, one of the history's row steps, with the run's threshold (or rule)."""
        step = self.step if step is None else step
        if step not in self._steps:
            raise ValueError(f"step = {step} is not one of the steps the shards recorded: {self._steps}")
        key = (step, threshold, rule)
        result = self._summaries.get(key)
        if result is None:
            raise ValueError(
                f"threshold = {threshold}, rule = {rule}: the merge summarised the run's own "
                f"(threshold = {self.spec.threshold}, rule = {self.spec.threshold_rule})"
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


def _worker_memory(client: Any) -> dict[str, int]:
    """Each worker's memory: Dask's ``memory_limit``, or where it has none, what its machine has
    available (asked of the worker; 0 where unknown)."""
    from ..limits import available_memory

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


#: What the merge's client holds per history row and per block of points: the two passes' partial
#: sums as Python numbers in dicts, generously.
MERGE_BYTES_PER_BLOCK = 1024


def check_merge(points: int, transport: bool = False, rows: int = 64) -> None:
    """ResourceError, before any work, if this machine cannot hold the merge: the two passes'
    partial sums of every :data:`~warpratchet.observables.SUMMARY_CHUNK` block of points at each
    of ``rows`` rows (:data:`MERGE_BYTES_PER_BLOCK`), and with ``transport`` the spread's column
    sums; nothing per point."""
    from ..limits import check_memory
    from ..transport._fits import GROUPS

    blocks = -(-max(points, 1) // _obs.SUMMARY_CHUNK)  # len(summary_chunks(points)), counted
    needed = rows * (blocks * MERGE_BYTES_PER_BLOCK + (3 * GROUPS * 8 if transport else 0))
    check_memory(f"points = {points} (the merge of a sharded run)", needed,
                 f"{MERGE_BYTES_PER_BLOCK} B per row for each of {blocks} blocks of points")  # fmt: skip


def _check_workers(
    client: Any,
    spec: RunSpec,
    bounds: list[tuple[int, int]],
    transport: bool,
    on_disk: bool,
    snapshots: tuple[int, int] = (0, 0),
) -> None:
    """ResourceError, before any work, if the largest shard does not fit the smallest worker."""
    limits = _worker_memory(client)
    if not limits:
        raise ResourceError("the Dask cluster has no workers; start some (docs/cluster.md)")
    largest = max(hi - lo for lo, hi in bounds)
    needed = shard_bytes(spec, largest, transport, on_disk, snapshots)
    address, smallest = min(limits.items(), key=lambda item: item[1])
    if smallest and needed > smallest:
        rows = 1 if on_disk else len(history_steps(0, spec.steps))
        raise ResourceError(
            f"shards = {len(bounds)}: a shard of {largest} points needs {format_bytes(needed)} "
            f"({_kind(transport).bytes_per_point()} B of state and {16 * rows} B of records per point), "
            f"worker {address} has a memory limit of {format_bytes(smallest)}; use more shards "
            f"(at least {math.ceil(len(bounds) * needed / smallest)}) or workers with more memory"
        )


def _manifest(spec: RunSpec, bounds: list, transport: bool, snapshots: tuple[int, int]) -> dict:
    """What ``run.json`` of a workdir holds: the run its shards belong to."""
    import json

    run = {k: v for k, v in json.loads(spec.to_json()).items() if k not in ("threads", "device")}
    run.update(transport=transport, shards=[list(b) for b in bounds])
    if snapshots[0]:
        run.update(snapshot_every=snapshots[0], snapshot_points=snapshots[1])
    return run


#: The prefix of a run's folder in the shards folder beside ``out`` (:func:`_run_folder`).
RUN_FOLDER = "run-"


def _run_folder(run: dict) -> str:
    """The name of the folder of the run ``run`` (:func:`_manifest`) in ``out + ".shards"``: the
    same for the same run (the same command again continues it), another for another run (so a
    run that replaces ``out`` never writes where the file it replaces reads)."""
    import hashlib
    import json

    return RUN_FOLDER + hashlib.sha256(json.dumps(run, sort_keys=True).encode()).hexdigest()[:16]


def _remove_other_runs(workdir: str) -> None:
    """Remove the other runs' folders beside ``workdir`` (in ``out + ".shards"``), once ``out``
    reads ``workdir``'s: the replaced file's shards, and what runs that never published left."""
    import shutil

    parent = os.path.dirname(workdir)
    for name in os.listdir(parent):
        path = os.path.join(parent, name)
        if name.startswith(RUN_FOLDER) and path != workdir and os.path.isdir(path):
            shutil.rmtree(path)


def _claim_workdir(workdir: str | os.PathLike, run: dict) -> str:
    """``workdir`` as an absolute path, made if missing, with ``run.json`` naming the run its shards
    belong to (:func:`_manifest`); ParameterError if it holds the shards of another run (its
    archives would be resumed)."""
    import json

    workdir = os.path.abspath(os.fspath(workdir))
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
    snapshot_every: int = 0,
    snapshot_points: int = 1000,
    force: bool = False,
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
        defaults to the run's own folder in ``out`` + ``".shards"``, named by the run,
        :func:`_run_folder`): the merged series and history, and the shards' per-point data as
        virtual datasets over their archives (:mod:`warpratchet._cluster_archive`).
    progress : bool
        A progress bar over the shards done, on stderr.
    snapshot_every, snapshot_points : int
        Steps between snapshots (0: none) of a fixed subsample of ``snapshot_points`` points, as
        :class:`~warpratchet.archive.ArchiveSink` takes them: each shard takes those of its points
        (with ``workdir``), and ``out`` exposes them as the single machine's ``/snapshots``.
    force : bool
        Replace an existing ``out``. It stays as it is, reading its own shards, until the new one
        is complete and takes its name in one rename; with the default ``workdir`` the new run's
        shards are in their own folder, and the other runs' folders in ``out`` + ``".shards"``
        are removed after.

    Raises
    ------
    ResourceError
        The largest shard does not fit the smallest worker's memory limit (checked before any work).
    RuntimeError
        A shard failed for good (after Dask's retries of a lost worker): names the shard and why.
    """
    from ..sweep._run import _connect

    if not isinstance(spec, RunSpec):
        raise ParameterError(f"spec = {spec!r} is not a RunSpec")
    from ..limits import check_kernel_range

    check_kernel_range(spec.params)
    from ..archive import schedule

    if snapshot_every:  # chunk ends on the snapshots, as on one machine (ParameterError if not)
        schedule(spec.points, spec.chunk_steps, snapshot_every, checkpoint_every)
    points = _ensemble_size(spec)
    snapshots = (snapshot_every, min(check_count("snapshot_points", snapshot_points, 1), points))
    shared = workdir is None  # the default folder, beside out
    if out is not None:
        out = os.fspath(out)
        if os.path.lexists(out) and not force:
            raise ParameterError(
                f"out = {out} exists; choose a new path or replace it with force=True (nothing was run)"
            )
        if workdir is None:
            workdir = out + ".shards"
    if snapshot_every and workdir is None:
        raise ParameterError(
            f"snapshot_every = {snapshot_every} needs out (or workdir): the snapshots go to files"
        )
    client, owned = _connect(client)
    try:
        if shards is None:
            shards = max(1, len(client.scheduler_info()["workers"]))
        bounds = shard_bounds(points, min(check_count("shards", shards, 1, points), points))
        _check_workers(client, spec, bounds, transport, workdir is not None, snapshots)
        check_merge(points, transport, len(history_steps(0, spec.steps)))
        if workdir is not None:
            run = _manifest(spec, bounds, transport, snapshots)
            if shared:  # each run its own folder: a replaced out reads its own until the new one is out
                workdir = os.path.join(workdir, _run_folder(run))
            workdir = _claim_workdir(workdir, run)
        start = time.perf_counter()
        futures = [
            client.submit(
                run_shard,
                spec,
                lo,
                hi,
                transport,
                list(observers),
                workdir,
                k,
                checkpoint_every,
                snapshot_every,
                snapshots[1],
                pure=False,
            )  # fmt: skip
            for k, (lo, hi) in enumerate(bounds)
        ]
        import distributed

        from ..progress import ProgressBar

        records: dict[int, ShardRecord] = {}
        index = {future.key: k for k, future in enumerate(futures)}
        # the records stay where they are; this process receives each shard's counts and block gains
        bar = ProgressBar("shards", disable=not progress, unit="shard")
        bar.open(len(bounds))
        try:
            # In the order they finish (a failure is reported at once), merged in shard order.
            for future in distributed.as_completed(futures):
                k = index[future.key]
                try:
                    records[k] = client.submit(_without_rows, future, pure=False).result()
                except Exception as exc:
                    lo, hi = bounds[k]
                    why = f"{type(exc).__name__}: {exc}"
                    raise RuntimeError(
                        f"shard {k} of {len(bounds)} (points {lo}..{hi - 1}) failed: {why}"
                    ) from exc
                bar.advance()
            records = [records[k] for k in range(len(bounds))]
            merged = ShardedRun(spec, records, transport, futures, client)
            merged.seconds = time.perf_counter() - start
        finally:
            bar.close()
            client.cancel(futures)
        if out is not None:
            from .._cluster_archive import write_merged

            write_merged(out, merged, workdir, bounds, snapshots, replace=force)
            if shared:
                _remove_other_runs(workdir)
        return merged
    finally:
        if owned:
            client.close()
