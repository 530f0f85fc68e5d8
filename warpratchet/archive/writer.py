"""Writing an archive: :class:`ArchiveSink`, the observer that streams a run into the file.

How it stays consistent (a kill can land between any two writes):

* the whole layout is created up front (:func:`~warpratchet.archive.layout.create`), then the
  file switches to SWMR (single writer, multiple readers) so that other processes can read it
  while it grows;
* rows (time series, snapshots) are appended and flushed *before* the ``n_valid`` counter that
  makes them visible is bumped and flushed: a reader never sees a row that is not on disk;
* the full state is checkpointed into one of two slots, the one *not* holding the newest
  checkpoint: its ``step`` is set to -1, the state written, flushed and fsynced, then ``step``
  and the ``current`` pointer are written. The previous checkpoint stays intact until a newer
  one is complete;
* every raw chunk carries a Fletcher-32 checksum (:mod:`.layout`) and, with ``libver="latest"``,
  every piece of HDF5 metadata carries its own: flipped bytes give an error, never silently
  wrong numbers;
* a new file is built under a temporary name and published with ``link`` (or ``replace`` for
  ``force=True``), so the path never holds half an archive (:mod:`warpratchet._files`).
  :meth:`ArchiveSink.resume` rebuilds the archive the same way from its newest good checkpoint
  (:mod:`.resume`), which also clears the "open for writing" mark a killed SWMR writer leaves.

A writer holds a shared ``flock`` on the file for its lifetime; :meth:`ArchiveSink.resume` and
``force=True`` need an exclusive one, so they refuse to touch a file that a live run (or an open
reader) is using. The observables written per chunk are those of Eqs. (An) and the FTLE, see
:mod:`warpratchet.observables`.
"""

from __future__ import annotations

import contextlib
import datetime
import math
import os
import shutil
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import h5py
import numpy as np
from h5py import h5s

from .._files import check_new_path, claim, publish, sync_h5, temporary_beside, try_lock
from ..ensemble import STATE_FIELDS, Ensemble, Observer
from ..errors import check_count, check_optional, check_real
from ..observables import acceleration, lyapunov, summarize
from . import layout
from .chunking import schedule
from .layout import ROW_CHUNK, SERIES_FIELDS, SLOTS, SNAPSHOT_FIELDS, ArchiveError
from .resume import salvage

__all__ = ["ArchiveSink"]

#: Salt of the snapshot subsample's generator, so it differs from the sampler's stream.
_SNAPSHOT_SALT = 0x5A4E


@contextlib.contextmanager
def _as_archive_error() -> Iterator[None]:
    """The file-safety refusals of :mod:`warpratchet._files` as :class:`ArchiveError` lines."""
    try:
        yield
    except (FileExistsError, FileNotFoundError, BlockingIOError) as exc:
        raise ArchiveError(str(exc)) from None


class ArchiveSink(Observer):
    """Streams a run into an HDF5 archive: an :class:`~warpratchet.ensemble.Observer`.

    Creating the sink writes the file (parameters, settings, versions, the initial state and
    every dataset, empty); after each chunk it appends a series row, a snapshot when one is due
    and a checkpoint when one is due, flushing after each; :meth:`end` writes a final checkpoint
    when the run reached its target. Pass ``chunk_steps=sink.chunk_steps`` to ``Ensemble.run``
    (the CLI does) so that chunk ends land on the snapshot and checkpoint steps; with other
    chunkings a snapshot or checkpoint is taken at the first chunk end past its step.

    Parameters
    ----------
    path : str or PathLike
        Archive to create. An existing file is refused unless ``force`` (then replaced
        atomically once the new archive is complete, and only if no process is using it).
    ensemble : Ensemble
        The ensemble to record, at any step.
    snapshot_every : int
        Steps between snapshots (0: none).
    snapshot_points : int
        Points ``M`` in the snapshot subsample (at most the ensemble size).
    checkpoint_every, chunk_steps : int, optional
        See :func:`~warpratchet.archive.chunking.schedule`.
    threshold : float, optional
        FTLE threshold for the chaotic points of the series (default: per step,
        :func:`~warpratchet.observables.default_lyapunov_threshold`).
    """

    def __init__(
        self,
        path: str | os.PathLike,
        ensemble: Ensemble,
        *,
        force: bool = False,
        snapshot_every: int = 0,
        snapshot_points: int = 1000,
        checkpoint_every: int | None = None,
        threshold: float | None = None,
        chunk_steps: int | None = None,
    ) -> None:
        path = os.fspath(path)
        if not isinstance(ensemble, Ensemble):
            raise ValueError(f"ensemble = {ensemble!r} is not an Ensemble")
        snapshot_points = check_count("snapshot_points", snapshot_points, 1)
        chunk_steps, checkpoint_every = schedule(
            ensemble.points, chunk_steps, snapshot_every, checkpoint_every
        )
        threshold = check_optional(check_real, "threshold", threshold)
        with _as_archive_error():
            exists = check_new_path(path, force=force, hint=" (use force=True / --force)")
            old_fd = claim(path, exclusive=True) if exists else None
        try:
            m = min(snapshot_points, ensemble.points) if snapshot_every else 0
            rng = np.random.default_rng([_SNAPSHOT_SALT, ensemble.seed or 0])
            indices = np.sort(rng.choice(ensemble.points, size=m, replace=False)).astype(np.int64)
            settings = layout.settings_attrs(
                points=ensemble.points,
                sampler=ensemble.sampler,
                seed=ensemble.seed,
                threads=ensemble.threads,
                device=ensemble.device,
                chunk_steps=chunk_steps,
                checkpoint_every=checkpoint_every,
                snapshot_every=snapshot_every,
                snapshot_points=m,
                threshold=threshold,
            )
            contents = {
                "params": ensemble.params,
                "settings": settings,
                "versions": layout.software_versions(),
                "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                "initial": {name: ensemble.array(name) for name in STATE_FIELDS},
                "initial_step": ensemble.step,
                "indices": indices,
            }
            self._build(path, contents, ensemble, replace=exists)
        finally:
            if old_fd is not None:
                os.close(old_fd)
        self.checkpoint_step = ensemble.step
        self._last_snapshot = ensemble.step

    def _build(
        self,
        path: str,
        contents: dict[str, Any],
        ensemble: Ensemble,
        *,
        replace: bool,
        keep_mode: bool = False,
        fill: Callable[[h5py.File], None] | None = None,
        rows: int = 0,
        snaps: int = 0,
    ) -> None:
        """Create the layout under a temporary name, ``fill`` it, bind it, publish it atomically."""
        with temporary_beside(path) as tmp:
            if keep_mode:
                with contextlib.suppress(OSError):
                    shutil.copymode(path, tmp)  # a rebuilt archive keeps the user's permissions
            f = h5py.File(tmp, "w", libver="latest")
            try:
                layout.create(f, **contents)
                if fill is not None:
                    fill(f)
                self._start(f, path, ensemble, contents["settings"], contents["indices"], rows, snaps)
                with _as_archive_error():
                    publish(tmp, path, replace=replace)
            except BaseException:
                f.close()
                raise
        self._lock_fd = os.open(path, os.O_RDONLY)
        try_lock(self._lock_fd, exclusive=False)

    def _start(self, f, path, ensemble, settings, indices, rows, snaps) -> None:
        """Enter SWMR mode and bind the open file to this sink."""
        f.swmr_mode = True
        sync_h5(f)  # durable before the file gets its name
        self._file = f
        self.path = path
        self.ensemble = ensemble
        self.settings = settings
        self.chunk_steps = int(settings["chunk_steps"])
        self.checkpoint_every = int(settings["checkpoint_every"])
        self.snapshot_every = int(settings["snapshot_every"])
        threshold = float(settings["threshold"])
        self.threshold = None if math.isnan(threshold) else threshold
        self._indices = indices
        self._series = _Rows(f["series"], SERIES_FIELDS, rows)
        self._snapshots = _Rows(f["snapshots"], ("step", *SNAPSHOT_FIELDS), snaps)
        self._target = None
        self._lock_fd = None
        self._current = int(f["checkpoint"]["current"][0])

    # -- resume -----------------------------------------------------------------------------------
    @classmethod
    def resume(
        cls, path: str | os.PathLike, *, threads: int | None = None, device: str | None = None
    ) -> tuple[ArchiveSink, Ensemble]:
        """Reopen an archive for appending, from its newest good checkpoint.

        The archive is rebuilt under a temporary name from what is valid (metadata, initial
        state, series rows and snapshots up to the checkpoint, the checkpoint; see
        :mod:`warpratchet.archive.resume`) and atomically put in place of the old file, so a
        kill during ``resume`` loses nothing either.

        Returns
        -------
        (ArchiveSink, Ensemble)
            The sink and the ensemble restored bit for bit at the checkpoint step; continue with
            ``run_to(ensemble, total, [sink], sink.chunk_steps)``.

        Raises
        ------
        ArchiveError
            Missing, unreadable or incompatible archive (format version, renormalisation
            constants of the kernel), or a file in use by another process.
        """
        path = os.fspath(path)
        if not os.path.exists(path):
            raise ArchiveError(f"{path}: no such archive")
        with _as_archive_error():
            old_fd = claim(path, exclusive=True)
        try:
            old = salvage(path, threads=threads, device=device)
            sink = cls.__new__(cls)
            sink._build(
                path,
                old.layout,
                old.ensemble,
                replace=True,
                keep_mode=True,
                fill=old.write,
                rows=old.rows,
                snaps=len(old.snapshots),
            )
        finally:
            os.close(old_fd)
        sink.checkpoint_step = old.step
        sink._last_snapshot = old.step
        return sink, old.ensemble

    # -- the observer -----------------------------------------------------------------------------
    def begin(self, ensemble: Ensemble, target_step: int) -> None:
        if ensemble is not self.ensemble:
            raise ValueError("this ArchiveSink records the ensemble it was created with, not another one")
        if self._file is None or not self._file.id.valid:
            raise ValueError(f"{self.path}: the archive sink is closed")
        self._target = int(target_step)

    def after_chunk(self, ensemble: Ensemble, seconds: float) -> None:
        step = ensemble.step
        f = self._file
        live = {name: ensemble.array(name) for name in STATE_FIELDS}  # zero-copy on the CPU
        summary = summarize(live, step, self.threshold).as_dict()
        clocks = {"wall_time": seconds, "unix_time": time.time()}
        self._series.put({name: clocks[name] if name in clocks else summary[name] for name in SERIES_FIELDS})
        snap = (
            self.snapshot_every and step // self.snapshot_every > self._last_snapshot // self.snapshot_every
        )
        if snap:
            sub = {name: live[name][self._indices] for name in STATE_FIELDS}
            self._snapshots.put(
                {
                    "step": step,
                    "x": sub["x"],
                    "p": sub["q"],  # p mod 1 is exactly q
                    "ftle": lyapunov(sub, step),
                    "A": acceleration(sub, step),
                }
            )
        f.flush()  # rows on disk before the counters that make them valid
        self._series.commit()
        if snap:
            self._snapshots.commit()
            self._last_snapshot = step
        f.flush()
        if step // self.checkpoint_every > self.checkpoint_step // self.checkpoint_every:
            self.checkpoint()

    def end(self, ensemble: Ensemble) -> None:
        # Only a run that reached its target is known to be between chunks: an interrupted
        # chunk may have advanced the arrays without the step counter.
        if (
            self._target is not None
            and ensemble.step == self._target
            and ensemble.step != self.checkpoint_step
        ):
            self.checkpoint()
        self._target = None

    def checkpoint(self) -> None:
        """Write the full state into the free slot, then point ``current`` at it (crash-safe)."""
        ensemble = self.ensemble
        f = self._file
        free = 1 - self._current if self._current >= 0 else 0
        slot = f["checkpoint"][SLOTS[free]]
        _set_counter(slot["step"], -1)  # in progress: neither a reader nor a recovery may trust it
        f.flush()
        for name in STATE_FIELDS:
            slot[name].write_direct(np.ascontiguousarray(ensemble.array(name)))
        sync_h5(f)  # the data is durable before anything points at it
        _set_counter(slot["step"], ensemble.step)
        _set_counter(f["checkpoint"]["current"], free)
        sync_h5(f)
        self._current = free
        self.checkpoint_step = ensemble.step

    def close(self) -> None:
        """Flush and close the file (it stays a complete archive; resumable)."""
        if getattr(self, "_file", None) is not None and self._file.id.valid:
            self._file.flush()
            self._file.close()
        if getattr(self, "_lock_fd", None) is not None:
            os.close(self._lock_fd)
            self._lock_fd = None

    def __enter__(self) -> ArchiveSink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"ArchiveSink({self.path!r}, rows={self._series.count}, checkpoint_step={self.checkpoint_step})"
        )


def _set_counter(ds: h5py.Dataset, value: int) -> None:
    """Write a ``(1,)`` int64 counter (low-level: no h5py indexing machinery per chunk)."""
    ds.id.write(h5s.ALL, h5s.ALL, np.array([value], dtype=np.int64))


class _Rows:
    """Append-only rows of the datasets of one group plus its ``n_valid`` counter.

    :meth:`put` writes row ``count`` of every dataset (growing them a chunk at a time);
    :meth:`commit` makes it valid. Rows are written with low-level HDF5 calls: h5py's indexing
    costs ~0.2 ms per call, which at small chunks would dominate the kernel time.
    """

    def __init__(self, group: h5py.Group, names: Sequence[str], count: int) -> None:
        self.datasets = {name: group[name] for name in names}
        self.dtypes = {name: ds.dtype for name, ds in self.datasets.items()}
        self.row_shapes = {name: ds.shape[1:] for name, ds in self.datasets.items()}
        self.capacity = min(ds.shape[0] for ds in self.datasets.values())
        self.counter = group["n_valid"]
        self.count = count

    def put(self, row: dict[str, Any]) -> None:
        if self.count >= self.capacity:
            self.capacity = self.count + ROW_CHUNK
            for ds in self.datasets.values():
                ds.resize(self.capacity, axis=0)
        for name, value in row.items():
            shape = (1, *self.row_shapes[name])
            values = np.ascontiguousarray(value, dtype=self.dtypes[name]).reshape(shape)
            ds = self.datasets[name]
            space = ds.id.get_space()
            space.select_hyperslab((self.count,) + (0,) * (len(shape) - 1), shape)
            ds.id.write(h5s.create_simple(shape), space, values)

    def commit(self) -> None:
        self.count += 1
        _set_counter(self.counter, self.count)
