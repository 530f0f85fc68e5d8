"""One shard: what a Dask task of a sharded run does, and the records it hands back.

A shard samples points ``lo <= i < hi`` of the one ensemble
(:func:`warpratchet.sampling.sampled_chunks` with ``lo``, ``hi``): the same doubles, and each
point's orbit and tangent are independent of the others (as they are of the thread count). It
runs to the end without waiting for the other shards (:func:`run_shard`) and records, at the
run's common steps (the history's rows, :func:`~warpratchet.history.history_steps`, which hold
the transport spread's steps), two doubles per point, the gain ``p_n - p_0`` and the stretch
``log|DM^n v0|`` (:class:`ShardRecord`), and keeps them on its worker (or in its workdir), where
the merge reduces them.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import kernels
from .._cluster_archive import shard_paths, snapshot_file, snapshot_steps
from ..archive._format import SNAPSHOT_FIELDS
from ..archive._rows import snapshot_indices, snapshot_row
from ..errors import ParameterError
from ..history import BLOCKS, block_steps, block_subsample, history_steps
from ..observables import _batched, _momentum_gain_into, lyapunov, momentum_gain
from ..runloop import Observer
from ..spec import RunSpec
from ._plan import _ensemble_size, _kind


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


#: Points per piece of a row's records: few calls of the FTLE kernel, a piece's arrays in a
#: core's cache between its two passes (gain, then stretch).
RECORD_PIECE = 1 << 17


def _row_records(
    views: dict[str, np.ndarray], gain: np.ndarray, stretch: np.ndarray, pool: Any, threads: int
) -> None:
    """Every point's gain (:func:`~warpratchet.observables.momentum_gain`) and stretch (the numerator
    of :func:`~warpratchet.observables.lyapunov`, which the merge divides by n as it does) into
    ``gain`` and ``stretch``, shape ``(points,)``: their operations in their order, so their bits
    (the stretch by :func:`warpratchet.kernels.lyapunov_into`: in a kernel where the libm gate
    allows it), in pieces of :data:`RECORD_PIECE` points on ``pool``'s threads (the run's, idle
    between its launches; here without one) and without full-size temporaries."""

    def piece(lo: int, hi: int) -> None:
        # stretch[lo:hi] holds the gain's temporary until the stretch is written over it
        _momentum_gain_into(views, lo, hi, gain[lo:hi], stretch[lo:hi])
        kernels.lyapunov_into(views, 1, lo, hi, stretch[lo:hi])  # divided by n = 1: the numerator itself

    n = gain.size
    jobs = [lambda lo=lo: piece(lo, min(n, lo + RECORD_PIECE)) for lo in range(0, n, RECORD_PIECE)]
    _batched(pool, jobs, threads)


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
            if self.folder is None:
                gain, stretch = self.gain[row], self.stretch[row]
            else:
                gain, stretch = np.empty((2, len(views["p0"])))
            _row_records(views, gain, stretch, ensemble.run_pool, ensemble.threads)
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
