"""Writing an archive: :class:`ArchiveSink`, the observer that streams a run into the file.

How it stays consistent (a kill can land between any two writes; docs/archive.md has the whole
story): the layout is created up front and the file switches to SWMR so that others can read
it while it grows; rows are flushed *before* the ``/progress`` counter that makes them valid;
the state is checkpointed into the slot *not* holding the newest checkpoint (its ``step`` -1,
the data fsynced, then ``step`` and ``current``); every chunk and every piece of metadata is
checksummed (Fletcher-32, HDF5 1.10 formats); a non-finite state is never checkpointed
(:class:`NonFiniteStateError`); free space is checked before each allocating write, and a
write the system refuses abandons the file as its last successful flush left it (resumable,
like a killed run's); a new or rebuilt file is published atomically (:mod:`warpratchet._files`).

A writer holds a shared ``flock`` on the file for its lifetime; :meth:`ArchiveSink.resume` and
``force=True`` need an exclusive one, so they refuse to touch a file that a live run (or an open
reader) is using. The observables written per chunk are those of Eqs. (An) and the FTLE
(:mod:`warpratchet.observables`).
"""

from __future__ import annotations

import contextlib
import datetime
import os
import shutil
import time
from collections.abc import Callable, Iterator
from typing import Any

import h5py
import numpy as np

from .._files import (
    LIBVER,
    abandon_h5,
    check_new_path,
    claim,
    ensure_space,
    publish,
    storage_errors,
    sync_h5,
    temporary_beside,
    try_lock,
)
from ..ensemble import STATE_FIELDS, Ensemble, Observer
from ..errors import check_count, check_optional, check_real
from ..observables import acceleration, lyapunov, summarize
from . import layout
from . import transport as _transport
from .checks import listed, nonfinite
from .chunking import schedule, sink_min_chunk_steps
from .names import (
    COUNTERS,
    FORMAT_VERSION,
    SERIES_FIELDS,
    SLOTS,
    SNAPSHOT_FIELDS,
    ArchiveError,
    NonFiniteStateError,
)
from .reopen import reopen
from .rows import Rows, set_counter

__all__ = ["ArchiveSink", "NonFiniteStateError"]

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
    every dataset, empty); :meth:`begin` records the run's target step; after each chunk it
    appends a series row, a snapshot when one is due and a checkpoint when one is due, flushing
    after each; :meth:`end` writes a final checkpoint when the run reached its target;
    :meth:`close` trims the datasets to their valid rows. Pass ``chunk_steps=sink.chunk_steps``
    to ``Ensemble.run`` (the CLI does) so that chunk ends land on the snapshot and checkpoint
    steps; with other chunkings a snapshot or checkpoint is taken at the first chunk end past
    its step.

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
        See :func:`~warpratchet.archive.chunking.schedule`; the default chunk is long enough
        that a series row costs at most ~1% of the kernel time at this machine's measured
        speed (:func:`~warpratchet.archive.chunking.sink_min_chunk_steps`).
    threshold : float, optional
        FTLE threshold for the chaotic points of the series (default: per step,
        :func:`~warpratchet.observables.default_lyapunov_threshold`).

    Raises
    ------
    ArchiveError
        The path exists (without ``force``), its folder is missing, or it is in use.
    warpratchet._files.StorageError
        The system refused a write (disk full, read-only, permissions): one line naming the
        file; no temporary file is left behind, and a running archive keeps its last checkpoint.
    NonFiniteStateError
        The state to record holds NaN or infinite values (the archive keeps its last checkpoint).
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
        if not path:
            raise ArchiveError("path = '' is not a file name")
        if not isinstance(ensemble, Ensemble):
            raise ValueError(f"ensemble = {ensemble!r} is not an Ensemble")
        snapshot_points = check_count("snapshot_points", snapshot_points, 1)
        threshold = check_optional(check_real, "threshold", threshold, 0.0)
        with _as_archive_error():
            exists = check_new_path(path, force=force, hint=" (use force=True / --force)")
        schedule(ensemble.points, chunk_steps, snapshot_every, checkpoint_every)  # bad values: no work
        if chunk_steps is None:
            min_chunk = sink_min_chunk_steps(ensemble)
            chunk_steps, checkpoint_every = schedule(
                ensemble.points, None, snapshot_every, checkpoint_every, min_chunk_steps=min_chunk
            )
        else:
            chunk_steps, checkpoint_every = schedule(
                ensemble.points, chunk_steps, snapshot_every, checkpoint_every
            )
        initial = {name: ensemble.array(name) for name in STATE_FIELDS}
        bad = nonfinite(initial)
        if bad:
            raise NonFiniteStateError(
                f"{path}: the state at step {ensemble.step} is not finite ({listed(bad)} non-finite)"
            )
        with _as_archive_error():
            old_fd = claim(path, exclusive=True) if exists else None
        try:
            m = min(snapshot_points, ensemble.points) if snapshot_every else 0
            rng = np.random.default_rng([_SNAPSHOT_SALT, ensemble.seed or 0])
            indices = np.sort(rng.choice(ensemble.points, size=m, replace=False)).astype(np.int64)
            settings = layout.run_settings(
                ensemble,
                threshold=threshold,
                chunk_steps=chunk_steps,
                checkpoint_every=checkpoint_every,
                snapshot_every=snapshot_every,
                snapshot_points=m,
            )
            contents = {
                "params": ensemble.params,
                "settings": settings,
                "versions": layout.software_versions(),
                "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                "initial": initial,
                "initial_step": ensemble.step,
                "indices": indices,
            }
            needed = sum(v.nbytes for k, v in initial.items() if np.any(v != layout.FILL[k]))
            self._build(path, contents, ensemble, replace=exists, needed=needed)
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
        needed: int = 0,
    ) -> None:
        """Create the layout under a temporary name, ``fill`` it, bind it, publish it atomically.

        ``needed`` bytes must be free first. A failure (a full disk) leaves no temporary file and
        the old file, if any, untouched.
        """
        with storage_errors(path, "create"):
            ensure_space(path, needed, "the new archive")
        with storage_errors(path, "create"), temporary_beside(path) as tmp:
            if keep_mode:
                with contextlib.suppress(OSError):
                    shutil.copymode(path, tmp)  # a rebuilt archive keeps the user's permissions
            f = h5py.File(tmp, "w", libver=LIBVER)
            try:
                layout.create(f, **contents)
                if _counts_transport(ensemble):
                    _transport.create(f, ensemble.points)
                if fill is not None:
                    fill(f)
                self._start(f, path, ensemble, contents["settings"], contents["indices"], rows, snaps)
                with _as_archive_error():
                    publish(tmp, path, replace=replace)
            except BaseException:
                abandon_h5(f)  # a plain close would retry a failed write (and crash at exit)
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
        self.threshold = settings["threshold"]
        self._indices = indices
        counters = COUNTERS[FORMAT_VERSION]
        self._series = Rows(f["series"], SERIES_FIELDS, f[counters["series"]], rows)
        self._snapshots = Rows(f["snapshots"], ("step", *SNAPSHOT_FIELDS), f[counters["snapshots"]], snaps)
        self._target_counter = f[counters["target"]]
        # The transport rows (feature "transport"), behind their own counter; a rebuilt file
        # (resume) holds the rows its fill put there.
        self._transport = None
        if _counts_transport(ensemble):
            self._transport = _transport.TransportRows(f, int(f["transport"]["rows"][0]))
        self._target = None
        self._row_step = None
        self._lock_fd = None
        self._failed = False
        self._current = int(f["checkpoint"]["current"][0])

    #: Reopen an archive for appending from its newest good checkpoint (:func:`.reopen.reopen`).
    resume = classmethod(reopen)

    # -- the observer -----------------------------------------------------------------------------
    @contextlib.contextmanager
    def _writing(self) -> Iterator[None]:
        """A write of the running archive: a refused write or a non-finite state ends the sink
        (no end checkpoint), leaving the file as its last successful flush left it."""
        hint = (
            f"; the archive keeps its checkpoint at step {self.checkpoint_step}: once there is space, "
            "run the same command again to resume it"
        )
        try:
            with storage_errors(self.path, "write", hint):
                yield
        except BaseException as exc:
            self._failed = True
            if not isinstance(exc, (NonFiniteStateError, KeyboardInterrupt)):
                self._abandon()
            raise

    def _abandon(self) -> None:
        if getattr(self, "_file", None) is not None:
            abandon_h5(self._file)
        self._release()

    def _release(self) -> None:
        if getattr(self, "_lock_fd", None) is not None:
            os.close(self._lock_fd)
            self._lock_fd = None

    def begin(self, ensemble: Ensemble, target_step: int) -> None:
        if ensemble is not self.ensemble:
            raise ValueError("this ArchiveSink records the ensemble it was created with, not another one")
        if self._file is None or not self._file.id.valid:
            raise ValueError(f"{self.path}: the archive sink is closed")
        self._target = int(target_step)
        self._row_step = None  # the step of the last row this run wrote
        with self._writing():
            set_counter(self._target_counter, self._target)
            self._file.flush()

    def after_chunk(self, ensemble: Ensemble, seconds: float) -> None:
        step = ensemble.step
        f = self._file
        live = {name: ensemble.array(name) for name in STATE_FIELDS}  # zero-copy on the CPU
        with self._writing():
            try:
                summary = summarize(live, step, self.threshold).as_dict()
            except FloatingPointError as exc:
                raise NonFiniteStateError(
                    f"{self.path}: the state at step {step} is not finite ({exc}); not archived: "
                    f"the archive keeps its checkpoint at step {self.checkpoint_step}"
                ) from None
            clocks = {"wall_time": seconds, "unix_time": time.time()}
            snap = (
                self.snapshot_every
                and step // self.snapshot_every > self._last_snapshot // self.snapshot_every
            )
            new_bytes = self._series.growth_bytes() + (self._snapshots.growth_bytes() if snap else 0)
            if self._transport is not None:
                new_bytes += self._transport.growth_bytes()
            if new_bytes:
                ensure_space(self.path, new_bytes, "the next rows")
            self._series.put({name: clocks.get(name, summary.get(name)) for name in SERIES_FIELDS})
            if self._transport is not None:
                self._transport.put({"step": step, "counts": ensemble.histograms().counts()})
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
            if self._transport is not None:
                self._transport.commit()
            if snap:
                self._snapshots.commit()
                self._last_snapshot = step
            f.flush()
        self._row_step = step
        if step // self.checkpoint_every > self.checkpoint_step // self.checkpoint_every:
            self.checkpoint()

    def end(self, ensemble: Ensemble) -> None:
        # The state is checkpointed where this run's last row stands: at the target, or where
        # Ctrl-C stopped the run (Ensemble.run stops between chunks, so step and arrays agree).
        # An ensemble left undefined by a failed launch, or a sink whose write failed, writes
        # nothing more.
        if (
            not self._failed
            and self._target is not None
            and ensemble.undefined is None
            and ensemble.step == self._row_step
            and ensemble.step != self.checkpoint_step
        ):
            self.checkpoint()
        self._target = None

    def checkpoint(self) -> None:
        """Write the full state into the free slot, then point ``current`` at it (crash-safe).

        Raises
        ------
        NonFiniteStateError
            The state holds NaN or infinite values; nothing is written, the last checkpoint stays.
        """
        ensemble = self.ensemble
        state = {name: np.ascontiguousarray(ensemble.array(name)) for name in STATE_FIELDS}
        bad = nonfinite(state)
        if bad:
            self._failed = True
            raise NonFiniteStateError(
                f"{self.path}: the state at step {ensemble.step} is not finite ({listed(bad)} non-finite; "
                "b1 or b2 too small for float64?); not checkpointed: the archive keeps its checkpoint "
                f"at step {self.checkpoint_step}"
            )
        f = self._file
        free = 1 - self._current if self._current >= 0 else 0
        slot = f["checkpoint"][SLOTS[free]]
        transport = ensemble.transport_state() if self._transport is not None else None
        with self._writing():
            if slot["x"].id.get_num_chunks() == 0:  # the slot's first use allocates its space
                extra = sum(v.nbytes for v in transport.carry.values()) if transport is not None else 0
                ensure_space(self.path, sum(v.nbytes for v in state.values()) + extra, "the checkpoint")
            set_counter(slot["step"], -1)  # in progress: neither a reader nor a recovery may trust it
            f.flush()
            for name in STATE_FIELDS:
                slot[name].write_direct(state[name])
            if transport is not None:  # the checkpoint is complete only with its transport state
                _transport.write_slot(f, SLOTS[free], transport)
            sync_h5(f)  # the data is durable before anything points at it
            set_counter(slot["step"], ensemble.step)
            set_counter(f["checkpoint"]["current"], free)
            sync_h5(f)
        self._current = free
        self.checkpoint_step = ensemble.step

    def close(self) -> None:
        """Trim the datasets to their valid rows, flush and close (a complete, resumable archive)."""
        f = getattr(self, "_file", None)
        if f is not None and f.id.valid:
            try:
                with storage_errors(self.path, "write"):
                    self._series.trim()
                    self._snapshots.trim()
                    if self._transport is not None:
                        self._transport.trim()
                    f.flush()
                    f.close()
            except BaseException:
                self._abandon()
                raise
        self._release()

    def __enter__(self) -> ArchiveSink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"ArchiveSink({self.path!r}, rows={self._series.count}, checkpoint_step={self.checkpoint_step})"
        )


def _counts_transport(ensemble: Ensemble) -> bool:
    """Whether ``ensemble`` counts return times and flights (a ``TransportEnsemble``)."""
    return callable(getattr(ensemble, "transport_state", None))
