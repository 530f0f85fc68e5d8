"""Writing an archive: :class:`ArchiveSink`, the observer that streams a run into the file.

How it stays consistent (a kill can land between any two writes; docs/archive.md has the whole
story): the layout is created up front and the file switches to SWMR so that others can read
it while it grows; rows are flushed *before* the ``/progress`` counter that makes them valid;
the state is checkpointed into the slot *not* holding the newest checkpoint (its ``step`` -1,
the data fsynced, then ``step`` and ``current``); every chunk and every piece of metadata is
checksummed (Fletcher-32, HDF5 1.10 formats); the file space is paged
(:func:`warpratchet._h5.create_h5`), so that a kill never tears the in-place rewrite of a row
chunk, a counter or HDF5's metadata across two pages; a non-finite state is never checkpointed
(:class:`NonFiniteStateError`); free space is checked before each allocating write, and a
write the system refuses abandons the file as its last successful flush left it (resumable,
like a killed run's); a new or rebuilt file is published atomically (:mod:`warpratchet._files`).

A writer holds a shared ``flock`` on the file for its lifetime; :meth:`ArchiveSink.resume` and
``force=True`` need an exclusive one, so they refuse to touch a file that a live run (or an open
reader) is using. The observables written per chunk are those of Eqs. (An) and the FTLE
(:mod:`warpratchet.observables`).

A new archive and a rebuilt one (:meth:`ArchiveSink.resume`) are both built by
:func:`build_file`: the free space is checked first, the layout (:func:`._format.create`) and
any contents are written into ``.NAME.XXXX.tmp`` next to the path, the caller binds the open
file (SWMR mode, fsync), and only then does the file get its name
(:func:`warpratchet._files.publish`). A failure (a full disk) leaves no temporary file and the
old file, if any, untouched.

Reopening an archive for appending (:meth:`ArchiveSink.resume`) rebuilds it from what is valid
in it (:func:`~warpratchet.archive._recovery.salvage`) under a temporary name and puts it in
place of the old file atomically, under an exclusive lock.

The archive of ``Ensemble.run(archive=path)`` (:func:`archive_sink`) is a new one, or this run's
to append to. The run loop knows no sinks; :func:`archive_sink` is registered for the
``archive=`` keyword (:func:`warpratchet.runloop.register_sink`) by the package's public face,
``warpratchet``.
"""

from __future__ import annotations

import contextlib
import datetime
import functools
import os
import shutil
import time
from collections.abc import Callable, Iterator
from typing import Any

import h5py
import numpy as np

from .._files import abandon_h5, check_new_path, claim, publish, sync_h5, temporary_beside, try_lock
from .._h5 import create_h5
from .._storage import ensure_space, h5_bytes, storage_errors
from ..ensemble import STATE_FIELDS, Ensemble, Observer
from ..errors import check_count, check_optional, check_real
from ..history import History
from ..spec import CHECKPOINT_SECONDS, check_checkpoint_seconds, check_setting
from . import _format
from ._chunking import sink_schedule
from ._features import HistoryWriter, TransportWriter, check_history, counts_transport, create_transport
from ._format import (
    COUNTERS,
    FORMAT_VERSION,
    SERIES_FIELDS,
    SNAPSHOT_FIELDS,
    ArchiveError,
    NonFiniteStateError,
)
from ._reader import open_archive
from ._recovery import rebuilt_bytes, salvage
from ._rows import Rows, listed, nonfinite, set_counter, snapshot_indices, snapshot_row, write_slot

__all__ = [
    "ArchiveSink",
    "NonFiniteStateError",
    "as_archive_error",
    "build_file",
    "archive_sink",
]

#: File space of an archive's layout beyond its data (groups, datasets, attributes, counters,
#: a history's 4096 subsample indices): ``scripts/h5_overhead.py`` measures 40576 B for a bare
#: archive of 10000 points, 81536 B with a history, 93824 B with transport counts too.
LAYOUT_BYTES = 96 * 1024


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
    checkpoint_seconds : float
        Checkpoint also at the chunk end after which the next one would come more than this
        many seconds (wall clock) after the last checkpoint, so that a kill loses at most about
        this much work (default :data:`~warpratchet.archive.CHECKPOINT_SECONDS`).
    checkpoint_every, chunk_steps : int, optional
        See :func:`~warpratchet.archive.schedule`; the default chunk is long enough
        that a series row costs at most :data:`~warpratchet.archive._chunking.ROW_SHARE` of the
        kernel time at this machine's measured speed
        (:func:`~warpratchet.archive._chunking.sink_min_chunk_steps`).
    threshold : float, optional
        FTLE threshold for the chaotic points of the series (default: per step, the rule
        ``threshold_rule``, :func:`~warpratchet.observables.lyapunov_threshold`).
    threshold_rule : str
        ``"strict"`` (default, ``10 (1 + ln n)/n``) or ``"positive"`` (``(1 + ln n)/n``).
    history : History, optional
        A :class:`~warpratchet.history.History` (same threshold and rule) to keep in the optional
        group ``/history``: its rows and block gains are written at each chunk end with the series
        row, and a resume continues it (:attr:`history`). Pass it to ``Ensemble.run`` among the
        observers too, so that it records at its own steps (``warpratchet run`` and
        ``Ensemble.run(archive=...)`` do both).
    how_to_continue : str, optional
        What a refused write's message tells the user to do once there is space (the CLI: "run
        the same command again to resume it"; default: how to continue in Python).

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
        checkpoint_seconds: float = CHECKPOINT_SECONDS,
        threshold: float | None = None,
        chunk_steps: int | None = None,
        threshold_rule: str = "strict",
        history: History | None = None,
        how_to_continue: str | None = None,
    ) -> None:
        path = os.fspath(path)
        if not path:
            raise ArchiveError("path = '' is not a file name")
        if not isinstance(ensemble, Ensemble):
            raise ValueError(f"ensemble = {ensemble!r} is not an Ensemble")
        snapshot_points = check_count("snapshot_points", snapshot_points, 1)
        checkpoint_seconds = check_checkpoint_seconds(checkpoint_seconds)
        threshold = check_optional(check_real, "threshold", threshold, 0.0)
        threshold_rule = check_setting("threshold_rule", threshold_rule)
        if history is not None:
            check_history(history, threshold, threshold_rule)
            history.subsample(ensemble)
        with as_archive_error():
            exists = check_new_path(path, force=force, hint=" (use force=True / --force)")
        chunk_steps, checkpoint_every = sink_schedule(ensemble, chunk_steps, snapshot_every, checkpoint_every)
        initial = ensemble.views()
        bad = nonfinite(initial)
        if bad:
            raise NonFiniteStateError(
                f"{path}: the state at step {ensemble.step} is not finite ({listed(bad)} non-finite)"
            )
        with as_archive_error():
            old_fd = claim(path, exclusive=True) if exists else None
        try:
            m = min(snapshot_points, ensemble.points) if snapshot_every else 0
            indices = snapshot_indices(ensemble.points, m, ensemble.seed)
            settings = _format.run_settings(
                ensemble,
                threshold=threshold,
                threshold_rule=threshold_rule,
                chunk_steps=chunk_steps,
                checkpoint_every=checkpoint_every,
                checkpoint_seconds=checkpoint_seconds,
                snapshot_every=snapshot_every,
                snapshot_points=m,
            )
            contents = {
                "params": ensemble.params,
                "settings": settings,
                "versions": _format.software_versions(),
                "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                "initial": initial,
                "initial_step": ensemble.step,
                "indices": indices,
                "history": history,
            }
            # A uniform field stays a fill value (no storage); the others take chunks of STATE_CHUNK.
            needed = sum(
                h5_bytes(v.nbytes, -(-v.size // _format.STATE_CHUNK))
                for k, v in initial.items()
                if np.any(v != _format.FILL[k])
            )
            self._build(path, contents, ensemble, replace=exists, needed=needed)
        finally:
            if old_fd is not None:
                os.close(old_fd)
        self.checkpoint_step = ensemble.step
        self._last_snapshot = ensemble.step
        self.how_to_continue = how_to_continue

    def _build(
        self,
        path: str,
        contents: dict[str, Any],
        ensemble: Ensemble,
        *,
        rows: int = 0,
        snaps: int = 0,
        fill: Callable[[h5py.File], None] | None = None,
        **how,
    ) -> None:
        """Create the file (:func:`.building.build_file`, keywords ``how``), with a ``/transport``
        group for a transport ensemble, ``fill`` it, bind it to this sink holding ``rows`` series
        rows and ``snaps`` snapshots, and take a shared lock on it."""

        def fill_all(f: h5py.File) -> None:
            if counts_transport(ensemble):
                create_transport(f, ensemble.points)
            if fill is not None:
                fill(f)

        start = functools.partial(self._start, path, ensemble, contents, rows, snaps)  # then the file
        build_file(path, contents, start, fill=fill_all, **how)
        self._lock_fd = os.open(path, os.O_RDONLY)
        try_lock(self._lock_fd, exclusive=False)

    def _start(self, path, ensemble, contents, rows, snaps, f) -> None:
        """Enter SWMR mode and bind the open file to this sink."""
        settings, indices, history = contents["settings"], contents["indices"], contents.get("history")
        f.swmr_mode = True
        sync_h5(f)  # durable before the file gets its name
        self._file = f
        self.path = path
        self.ensemble = ensemble
        self.settings = settings
        self.chunk_steps = int(settings["chunk_steps"])
        self.checkpoint_every = int(settings["checkpoint_every"])
        # Archives from before the wall-clock cadence get the default.
        self.checkpoint_seconds = float(settings.get("checkpoint_seconds") or CHECKPOINT_SECONDS)
        self.snapshot_every = int(settings["snapshot_every"])
        self.threshold = settings["threshold"]
        self.threshold_rule = settings.get("threshold_rule") or "strict"
        self._indices = indices
        #: The run's :class:`~warpratchet.history.History` kept in ``/history`` (None without one).
        self.history = history
        # The optional row groups written with each series row: /history, /transport.
        self._groups = []
        if history is not None:
            kept = len(history.rows["step"]), len(history.block_rows["block_step"])
            self._groups.append(HistoryWriter(f, history, *kept))
        self._transport = None
        if counts_transport(ensemble):
            self._transport = TransportWriter(f)
            self._groups.append(self._transport)
        counters = COUNTERS[FORMAT_VERSION]
        self._series = Rows(f["series"], SERIES_FIELDS, f[counters["series"]], rows)
        self._snapshots = Rows(f["snapshots"], ("step", *SNAPSHOT_FIELDS), f[counters["snapshots"]], snaps)
        self._target_counter = f[counters["target"]]
        self._target = None
        self._row_step = None
        self._lock_fd = None
        self._failed = False
        self._current = int(f["checkpoint"]["current"][0])
        #: What a refused write's message tells the user to do once there is space (the CLI: "run
        #: the same command again to resume it"); None: how to continue in Python.
        self.how_to_continue: str | None = None
        self._checkpoint_clock = self._row_clock = time.monotonic()

    @classmethod
    def resume(
        cls,
        path: str | os.PathLike,
        *,
        threads: int | None = None,
        device: str | None = None,
        how_to_continue: str | None = None,
    ) -> tuple[ArchiveSink, Ensemble]:
        """Reopen an archive for appending, from its newest good checkpoint.

        The archive is rebuilt under a temporary name from what is valid (metadata, initial
        state, series rows and snapshots up to the checkpoint, the checkpoint; see
        :mod:`warpratchet.archive._recovery`) and atomically put in place of the old file, so a
        kill during ``resume`` loses nothing either. A damaged checkpoint, snapshot, series row
        or initial state is skipped and named in an :class:`ArchiveWarning`. An archive of an
        earlier format (version 1, or 2 before minor version 2) is rebuilt in today's, with the
        same values under today's names. ``how_to_continue`` as :class:`ArchiveSink` takes it.

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
        try:
            old_fd = claim(path, exclusive=True)
        except (FileNotFoundError, FileExistsError, BlockingIOError) as exc:
            raise ArchiveError(str(exc)) from None
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
                needed=rebuilt_bytes(old),  # beside the old file until it takes its name
            )
        finally:
            os.close(old_fd)
        sink.checkpoint_step = old.step
        sink._last_snapshot = old.step
        sink.how_to_continue = how_to_continue
        return sink, old.ensemble

    # -- the observer -----------------------------------------------------------------------------
    @contextlib.contextmanager
    def _writing(self) -> Iterator[None]:
        """A write of the running archive: a refused write or a non-finite state ends the sink
        (no end checkpoint), leaving the file as its last successful flush left it."""
        how = self.how_to_continue or (
            f"continue from it with open_archive(path).ensemble() (this ensemble is at step "
            f"{self.ensemble.step}, ahead of the archive)"
        )
        hint = (
            f"; the archive keeps its checkpoint at step {self.checkpoint_step}: once there is space, {how}"
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
        # Wall clock of the last checkpoint and of the last row: the checkpoint cadence.
        self._checkpoint_clock = self._row_clock = time.monotonic()
        if self.history is not None:
            self.history.begin(ensemble, self._target)  # idempotent: also an observer of the run
        with self._writing():
            set_counter(self._target_counter, self._target)
            self._file.flush()

    def after_chunk(self, ensemble: Ensemble, seconds: float) -> None:
        step = ensemble.step
        f = self._file
        with self._writing():
            try:
                summary = ensemble.summary(self.threshold, self.threshold_rule, warn=False).as_dict()
            except FloatingPointError as exc:
                raise NonFiniteStateError(
                    f"{self.path}: the state at step {step} is not finite ({exc}); not archived: "
                    f"the archive keeps its checkpoint at step {self.checkpoint_step}"
                ) from None
            for group in self._groups:
                group.record(ensemble)
            clocks = {"wall_time": seconds, "unix_time": time.time()}
            snap = (
                self.snapshot_every
                and step // self.snapshot_every > self._last_snapshot // self.snapshot_every
            )
            new_bytes = self._series.growth_bytes() + (self._snapshots.growth_bytes() if snap else 0)
            new_bytes += sum(group.growth_bytes() for group in self._groups)
            if new_bytes:
                ensure_space(self.path, new_bytes, "the next rows")
            self._series.put({name: clocks.get(name, summary.get(name)) for name in SERIES_FIELDS})
            if snap:
                self._snapshots.put(snapshot_row(ensemble.views(), self._indices, step))
            for group in self._groups:
                group.put()
            f.flush()  # rows on disk before the counters that make them valid
            self._series.commit()
            for group in self._groups:
                group.commit()
            if snap:
                self._snapshots.commit()
                self._last_snapshot = step
            f.flush()
        self._row_step = step
        now = time.monotonic()
        # The last chunk's wall time predicts the next one's: checkpoint now if waiting for the
        # next chunk end would leave more than checkpoint_seconds of work unsaved.
        last_chunk, self._row_clock = now - self._row_clock, now
        due_by_clock = now - self._checkpoint_clock + last_chunk > self.checkpoint_seconds
        if due_by_clock or step // self.checkpoint_every > self.checkpoint_step // self.checkpoint_every:
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
        free = 1 - self._current if self._current >= 0 else 0
        extra, extra_bytes = None, 0
        if self._transport is not None:  # the checkpoint is complete only with its transport state
            extra, extra_bytes = self._transport.slot_extra(ensemble)
        with self._writing():
            write_slot(self.path, self._file, free, state, ensemble.step, extra, extra_bytes)
        self._current = free
        self.checkpoint_step = ensemble.step
        self._checkpoint_clock = self._row_clock = time.monotonic()

    def close(self) -> None:
        """Trim the datasets to their valid rows, flush and close (a complete, resumable archive)."""
        f = getattr(self, "_file", None)
        if f is not None and f.id.valid:
            try:
                with storage_errors(self.path, "write"):
                    self._series.trim()
                    self._snapshots.trim()
                    for group in self._groups:
                        group.trim()
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


# -- building a file, published atomically --------------------------------------------------------
@contextlib.contextmanager
def as_archive_error() -> Iterator[None]:
    """The file-safety refusals of :mod:`warpratchet._files` as :class:`ArchiveError` lines."""
    try:
        yield
    except (FileExistsError, FileNotFoundError, BlockingIOError) as exc:
        raise ArchiveError(str(exc)) from None


def build_file(
    path: str,
    contents: dict[str, Any],
    start: Callable[[h5py.File], None],
    *,
    replace: bool,
    keep_mode: bool = False,
    fill: Callable[[h5py.File], None] | None = None,
    needed: int = 0,
) -> None:
    """Create the layout under a temporary name, ``fill`` it, ``start`` it, publish it atomically.

    ``needed`` bytes (the estimated file space of the data, :func:`~warpratchet._storage.h5_bytes`)
    and the layout's :data:`LAYOUT_BYTES` must be free first; ``contents`` are the keyword
    arguments of :func:`._format.create`; ``start`` binds the open file to its writer (and leaves it open);
    ``keep_mode`` keeps the permissions of the file at ``path`` (a rebuilt archive).
    """
    with storage_errors(path, "create"):
        ensure_space(path, LAYOUT_BYTES + needed, "the new archive")
    with storage_errors(path, "create"), temporary_beside(path) as tmp:
        if keep_mode:
            with contextlib.suppress(OSError):
                shutil.copymode(path, tmp)  # a rebuilt archive keeps the user's permissions
        f = create_h5(tmp)  # paged: a kill never tears a row chunk or a counter
        try:
            _format.create(f, **contents)
            if fill is not None:
                fill(f)
            start(f)
            with as_archive_error():
                publish(tmp, path, replace=replace)
        except BaseException:
            abandon_h5(f)  # a plain close would retry a failed write (and crash at exit)
            raise


# -- the sink of Ensemble.run(archive=) -----------------------------------------------------------
def archive_sink(ensemble: Any, path: str | os.PathLike, chunk_steps: int | None) -> Any:
    """The ArchiveSink of ``Ensemble.run(archive=path)``: a new archive, or this run's to append to.

    A new archive keeps the run's :class:`~warpratchet.history.History` (``sink.history``, an
    observer of the run too).

    An existing file is appended to only if it is an archive whose checkpoint holds exactly this
    ensemble (same step, every state array equal bit for bit): what a previous ``run(...,
    archive=path)`` of this ensemble leaves when it completes. Anything else is refused, so an
    archive never mixes two runs.
    """
    if not os.path.lexists(path):
        return ArchiveSink(path, ensemble, chunk_steps=chunk_steps, threshold=None, history=History())
    with open_archive(path) as arc:
        state, step = arc.checkpoint()
        params = arc.params
    same = (
        params == ensemble.params
        and step == ensemble.step
        and all(np.array_equal(state[name], ensemble.array(name)) for name in state)
    )
    if not same:
        raise ValueError(
            f"{os.fspath(path)} exists and does not hold this ensemble at step {ensemble.step} "
            f"(its checkpoint is at step {step}); choose a new path, or continue that run from "
            "open_archive(path).ensemble()"
        )
    sink, _ = ArchiveSink.resume(path, threads=ensemble.threads, device=ensemble.device)
    if chunk_steps is not None and chunk_steps != sink.chunk_steps:
        sink.close()
        raise ValueError(
            f"chunk_steps = {chunk_steps} differs from the archive's chunk_steps = {sink.chunk_steps}"
        )
    sink.ensemble = ensemble  # the restored twin equals this ensemble bit for bit (checked above)
    return sink
