"""Reading an archive: :func:`open_archive`, :class:`Archive`, :class:`Snapshots`.

A reader is safe while a run is still writing the file (HDF5 SWMR; :func:`warpratchet._files.open_h5`
opens a file a writer has open in SWMR-read mode): metadata are read on opening, while
``series``, ``snapshots`` and the checkpoint slots are read afresh on every access and only up
to the live counters, which the writer raises after the rows are on disk. A slot's ``step`` is
read before and after its data (a sequence lock), so a checkpoint the writer recycles meanwhile
is never returned. Any HDF5 failure becomes one :class:`~warpratchet.archive.names.ArchiveError`
line; a damaged or non-finite checkpoint is skipped with an
:class:`~warpratchet.archive.names.ArchiveWarning` naming what was recovered instead. Format
versions 1 and 2 are read (:mod:`.names`).
"""

from __future__ import annotations

import os
import warnings
from typing import Any

import h5py
import numpy as np

from .._files import open_h5
from .._h5verify import first_line
from ..ensemble import Ensemble
from ..history import History
from ..spec import SAMPLERS, RunSpec, attr_value, params_of
from . import progress
from . import transport as _transport
from .checks import TEXT_CHECKSUM, check_text, read_counter, reading, valid_rows
from .history_group import history_info, read_history
from .layout import read_settings
from .names import (
    COUNTERS,
    FORMAT,
    READABLE_VERSIONS,
    SERIES_FIELDS,
    ArchiveError,
    ArchiveWarning,
)
from .slots import newest_good, read_state, slot_steps
from .snapshots import Snapshots, read_snapshots

__all__ = ["Snapshots", "Archive", "open_archive"]


class Archive:
    """A read-only view of an archive; see :func:`open_archive`.

    Metadata (``params``, ``settings``, ``versions``, ``created``) are read on opening; ``series``,
    ``snapshots``, ``checkpoint_step`` and ``target_step`` are read afresh on every access, so a
    reader follows a run that is still being written.
    """

    def __init__(self, path: str | os.PathLike, *, locking: bool | None = None) -> None:
        self.path = os.fspath(path)
        if not os.path.exists(self.path):
            raise ArchiveError(f"{self.path}: no such archive")
        if not os.path.isfile(self.path):  # a FIFO or device would block HDF5's open forever
            raise ArchiveError(f"{self.path} is not a regular file (not a warpratchet archive)")
        try:
            self._file = open_h5(self.path, locking=locking)
        except OSError as exc:
            if "unable to lock file" in str(exc):
                raise ArchiveError(f"{self.path} is locked by another process") from None
            if not h5py.is_hdf5(self.path):  # no HDF5 signature anywhere: not a damaged archive either
                raise ArchiveError(f"{self.path} is not an HDF5 file (not a warpratchet archive)") from None
            raise ArchiveError(
                f"{self.path}: not a readable HDF5 archive ({first_line(exc)}); "
                "the file is truncated or corrupted"
            ) from None
        try:
            self._read_metadata()
        except BaseException:
            self._file.close()
            raise

    @property
    def h5(self) -> h5py.File:
        """The open HDF5 file (read-only, SWMR), for what the properties do not read, e.g. ``resume``."""
        return self._file

    def _read_metadata(self) -> None:
        f = self._file
        with reading(self.path, "the root attributes"):
            fmt = attr_value(f.attrs.get("format", b""))
            version = attr_value(f.attrs.get("format_version", -1))
        if fmt != FORMAT:
            raise ArchiveError(
                f"{self.path}: not a warpratchet archive (format = {fmt!r}, expected {FORMAT!r})"
            )
        if version not in READABLE_VERSIONS:
            raise ArchiveError(
                f"{self.path}: archive format version {version} is not supported "
                f"(this warpratchet reads versions {', '.join(map(str, READABLE_VERSIONS))})"
            )
        self.format_version = int(version)
        self._counters = COUNTERS[self.format_version]
        with reading(self.path, "the metadata"):
            texts = ((f, "the root attributes"), (f["settings"], "/settings"), (f["versions"], "/versions"))
        for obj, what in texts:
            check_text(self.path, obj, f"the text attributes of {what}")
        with reading(self.path, "the metadata"):
            self.created = str(attr_value(f.attrs["created"]))
            features = str(attr_value(f.attrs.get("features", b"")))
            self.features = tuple(name for name in features.split(",") if name)
            p = {k: attr_value(v) for k, v in f["params"].attrs.items()}
            self.params = params_of(p["K"], p.get("b1"), p.get("b2"), p.get("knots"), p.get("values"))
            self.settings = read_settings(f["settings"].attrs, self.format_version)
            versions = f["versions"].attrs.items()
            self.versions = {k: str(attr_value(v)) for k, v in versions if k != TEXT_CHECKSUM}
            self.initial_step = int(attr_value(f["initial"].attrs["step"]))
        if self.format_version == 1:
            # Version 1 callers read the sampler as "sampler" (tests/data/archive_v1.h5).
            self.settings["sampler"] = self.settings["init"]
        self.points = int(self.settings["points"])

    # -- live data ------------------------------------------------------------------------------
    def _counter(self, key: str) -> int:
        return read_counter(self.path, self._file, self._counters[key], signed=key == "target")

    @property
    def rows(self) -> int:
        """Number of valid rows of ``series`` (chunks recorded)."""
        return self._counter("series")

    @property
    def snapshot_count(self) -> int:
        """Number of valid snapshots."""
        return self._counter("snapshots")

    @property
    def target_step(self) -> int | None:
        """The step the last run session aims at (None for format v1 or before the first run)."""
        if "target" not in self._counters:
            return None
        target = self._counter("target")
        return target if target >= 0 else None

    @property
    def spec(self) -> RunSpec | None:
        """The run as a :class:`~warpratchet.spec.RunSpec` (``steps``: the target step).

        None for an ensemble built from arrays (no sampler reproduces it) or before a target
        step is known.
        """
        target = self.target_step
        if self.settings["init"] not in SAMPLERS or target is None or self.settings["seed"] is None:
            return None
        stored = {k: v for k, v in self.settings.items() if v is not None}
        return RunSpec.from_attrs({**stored, **self.params.as_dict(), "steps": target})

    @property
    def series(self) -> dict[str, np.ndarray]:
        """One row per chunk, keys :data:`SERIES_FIELDS`, each of shape ``(rows,)``.

        ``A``, ``A_stderr`` are the mean of ``A_n`` (Eq. An) over chaotic points and its standard
        error, ``lyapunov*`` FTLE statistics of the chaotic points (per iteration),
        ``wall_time`` the chunk's kernel seconds, ``unix_time`` when the row was written.
        """
        n = self.rows
        with reading(self.path, "/series"):
            g = self._file["series"]
        return {name: valid_rows(self.path, g, name, n) for name in SERIES_FIELDS}

    @property
    def snapshots(self) -> Snapshots:
        """Snapshots recorded so far (``S`` may be 0); see :class:`Snapshots`."""
        return read_snapshots(self.path, self._file, self.snapshot_count)

    def _slot_steps(self, problems: list[str] | None = None) -> list[tuple[int, str]]:
        """Complete slots as ``(step, name)``, newest first (:func:`.slots.slot_steps`)."""
        return slot_steps(self.path, self._file, problems)

    @property
    def checkpoint_step(self) -> int:
        """Step of the newest complete checkpoint (the initial step if there is none yet).

        Read from metadata only; :meth:`checkpoint` also verifies the data and falls back (with
        an :class:`ArchiveWarning`) if it is damaged.
        """
        slots = self._slot_steps()
        return slots[0][0] if slots else self.initial_step

    def read_state(self, group: str) -> dict[str, np.ndarray]:
        """The per-point state stored in ``group`` (``"initial"``, ``"checkpoint/a"``, ...), unchecked."""
        return read_state(self.path, self._file, group, self.points)

    @property
    def initial(self) -> dict[str, np.ndarray]:
        """The state the archive started from (at step ``initial_step``), keys ``STATE_FIELDS``."""
        return self.read_state("initial")

    def checkpoint(self) -> tuple[dict[str, np.ndarray], int]:
        """The newest checkpoint whose data verify and are finite, as ``(state, step)``.

        Tries the complete slots newest first, then the initial state. A slot whose checksum
        fails, or that holds non-finite values (written by format v1 releases), is skipped with
        an :class:`ArchiveWarning` naming what was recovered instead. A slot the live writer
        recycles while it is read is read again, never reported as damaged.
        """
        state, step, _ = self.checkpoint_with_transport()
        return state, step

    def checkpoint_with_transport(self) -> tuple[dict[str, np.ndarray], int, Any]:
        """:meth:`checkpoint` and, for an archive with the ``transport`` feature, the transport
        state of that checkpoint (None for the initial state: counting starts there; a slot whose
        transport state is unreadable is skipped like a damaged one)."""
        read_extra = None
        if _transport.FEATURE in self.features:

            def read_extra(slot: str) -> Any:
                return _transport.read_slot(self._file, self.path, slot, self.points)

        found, problems = newest_good(self.path, self._file, self.points, read_extra)
        if found is not None:
            self._warn(problems, f"recovered the checkpoint at step {found[1]}")
            return found
        state = self.initial
        if problems:
            self._warn(problems, f"recovered the initial state at step {self.initial_step}")
        return state, self.initial_step, None

    def _warn(self, problems: list[str], outcome: str) -> None:
        if problems:
            warnings.warn(f"{self.path}: {'; '.join(problems)}; {outcome}", ArchiveWarning, stacklevel=3)

    def restore(
        self,
        state: dict[str, np.ndarray],
        step: int,
        threads: int | None = None,
        device: str | None = None,
        transport: Any = None,
    ) -> Ensemble:
        """An :class:`Ensemble` of this archive's run holding ``state`` at ``step`` (with the
        ``transport`` feature: :func:`.transport.restore`, counting from ``transport``)."""
        init, seed = self.settings["init"], self.settings["seed"]
        kwargs = {"device": device, "threads": threads, "init": init, "seed": seed}
        if _transport.FEATURE not in self.features:
            return Ensemble.from_state(self.params, state, step, **kwargs)
        settings = self.settings
        return _transport.restore(
            self.params, state, step, transport, settings["threshold"], settings["threshold_rule"], **kwargs
        )

    def ensemble(self, threads: int | None = None, device: str | None = None) -> Ensemble:
        """An :class:`Ensemble` restored bit for bit at the newest good checkpoint."""
        state, step, transport = self.checkpoint_with_transport()
        return self.restore(state, step, threads, device, transport)

    @property
    def transport(self) -> dict[str, np.ndarray] | None:
        """The ``/transport`` rows (``step`` ``(R,)``, ``counts`` ``(R, 3, BINS)``: completed return
        gaps and flights per log2 bin at each chunk end), or None without the feature."""
        if _transport.FEATURE not in self.features:
            return None
        return _transport.read_rows(self._file, self.path)

    @property
    def history(self) -> History | None:
        """The run's :class:`~warpratchet.history.History` (feature ``history``; None without one).

        Its valid rows and block records, read afresh (a run may still be writing them):
        ``history.as_dict()`` (rows as lists), ``history.convergence()`` (the verdict at the last
        row), ``history.block_rows``.
        """
        if "history" not in self.features:
            return None
        return read_history(self.path, self._file, self.settings)

    def latest(self) -> dict[str, float | int] | None:
        """The last series row as a dict (None before the first chunk)."""
        return _last_row(self.series)

    def info(self) -> dict[str, Any]:
        """Everything ``warpratchet inspect`` shows: metadata, progress (with an ETA), latest summary."""
        series = self.series
        checkpoint_step = self.checkpoint()[1]  # verified: where a resume would start
        return {
            "path": self.path,
            "format": FORMAT,
            "format_version": self.format_version,
            "features": list(self.features),
            "created": self.created,
            "params": self.params.as_dict(),
            "settings": dict(self.settings),
            "versions": dict(self.versions),
            "initial_step": self.initial_step,
            "checkpoint_step": checkpoint_step,
            "rows": int(series["step"].size),
            "snapshots": self.snapshot_count,
            "latest": _last_row(series),
            "history": history_info(self.history),
            **progress.estimate(series, self.target_step, self.initial_step, checkpoint_step),
        }

    # -- exports ----------------------------------------------------------------------------------
    def to_pandas(self, group: str = "series"):
        """``series`` (or the ``history`` rows) as a ``pandas.DataFrame`` indexed by ``step`` (needs
        ``warpratchet[xarray]``)."""
        from .export import series_frame

        return series_frame(self, group)

    def to_xarray(self, group: str = "series"):
        """``series`` (dimension ``step``), ``snapshots`` (``step``, ``indices``; with the derived
        unwrapped momentum ``p_unwrapped``) or ``history`` (``step``; block gains on ``block_step``,
        ``block_indices``) as an ``xarray.Dataset`` with units, long names and the file's global
        attributes, named and decoded as xarray's h5netcdf engine reads the file (needs
        ``warpratchet[xarray]``)."""
        from .export import dataset

        return dataset(self, group)

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> Archive:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        p = self.params
        force = f"b1={p.b1!r}, b2={p.b2!r}" if p.is_paper else f"table={p.table!r}"
        return f"Archive({self.path!r}, K={p.K!r}, {force}, points={self.points})"


def _last_row(series: dict[str, np.ndarray]) -> dict[str, float | int] | None:
    return None if series["step"].size == 0 else {k: v[-1].item() for k, v in series.items()}


def open_archive(path: str | os.PathLike) -> Archive:
    """Open an archive read-only (SWMR: safe while a run is still writing it).

    Returns an :class:`Archive` with ``params``, ``settings``, ``versions``, ``created``,
    ``series``, ``snapshots``, ``checkpoint_step``, ``target_step`` and ``ensemble()``; use it
    as a context manager. Raises :class:`ArchiveError` (a ``ValueError``) with one clear line for
    a missing, truncated, corrupted or incompatible file.
    """
    return Archive(path)
