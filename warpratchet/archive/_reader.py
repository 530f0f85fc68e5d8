"""Reading an archive: :func:`open_archive`, :class:`Archive`, what ``inspect`` reports, and the
pandas and xarray views.

A reader is safe while a run is still writing the file (HDF5 SWMR; :func:`warpratchet._files.open_h5`
opens a file a writer has open in SWMR-read mode): metadata are read on opening, while
``series``, ``snapshots`` and the checkpoint slots are read afresh on every access and only up
to the live counters, which the writer raises after the rows are on disk. A slot's ``step`` is
read before and after its data (a sequence lock), so a checkpoint the writer recycles meanwhile
is never returned. Any HDF5 failure becomes one :class:`~warpratchet.archive.ArchiveError`
line; a damaged or non-finite checkpoint is skipped with an
:class:`~warpratchet.archive.ArchiveWarning` naming what was recovered instead. Format
versions 1 and 2 are read (:mod:`._format`).

How far an archived run is and when it will be done (:func:`estimate`, for ``inspect``): pure
NumPy on the series of :class:`Archive`. The target step is stored (``/progress/target_step``,
format v2), the speed is measured from the kernel wall times of the most recent rows.

An archive as a ``pandas.DataFrame`` or an ``xarray.Dataset`` (the optional ``xarray`` extra,
:func:`series_frame`, :func:`dataset`). Units and descriptions come from the file's
``units``/``long_name`` attributes (format v2) or, for format v1 files that lack them, from
:mod:`warpratchet.glossary`. The file itself also opens directly: ``xarray.open_dataset(path,
group="series", engine="h5netcdf")`` (format v2). Both routes give the same dimension names (the
names netCDF readers give the file's dimension scales: ``step``, ``indices``, ``block_step``,
``block_indices``) and decode ``unix_time`` alike (``datetime64``, CF time units); a file written
before minor version 2 stores the snapshots' ``finite_time_acceleration`` as ``A``, which the
direct route reads under that name and :func:`dataset` under today's. :func:`dataset` adds one
derived variable to the snapshots, the unwrapped momentum ``p_unwrapped`` (:func:`unwrapped_momentum`).
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
from ..history import HISTORY_FIELDS, History
from ..spec import SAMPLERS, RunSpec, attr_value, params_of
from ._features import (
    TRANSPORT_FEATURE,
    history_info,
    read_history,
    read_transport_rows,
    read_transport_slot,
    restore_transport,
)
from ._format import (
    COUNTERS,
    FORMAT,
    READABLE_VERSIONS,
    SERIES_FIELDS,
    SNAPSHOT_FIELDS,
    TEXT_CHECKSUM,
    ArchiveError,
    ArchiveWarning,
    describe,
    read_settings,
    stored_name,
)
from ._rows import (
    Snapshots,
    check_text,
    newest_good,
    read_counter,
    read_snapshots,
    read_state,
    reading,
    slot_steps,
    valid_rows,
)

__all__ = [
    "Snapshots",
    "Archive",
    "open_archive",
    "RECENT_ROWS",
    "estimate",
    "attributes",
    "series_frame",
    "dataset",
    "unwrapped_momentum",
]


class VirtualSourceError(ArchiveError):
    """A virtual dataset's source file is missing or unreadable (its points would read as fill values)."""


def virtual_source_path(archive: str, name: str) -> str:
    """The file HDF5 reads for a virtual dataset's source file ``name`` in the file ``archive``.

    As HDF5 resolves it: ``"."`` is ``archive`` itself, an absolute path is itself, a relative
    one is looked for under ``$HDF5_VDS_PREFIX`` (its ``${ORIGIN}`` the archive's folder), then
    the archive's folder, then the working directory; the archive's folder when none exists.
    """
    if name == ".":
        return archive
    if os.path.isabs(name):
        return name
    origin = os.path.dirname(os.path.abspath(archive))
    prefix = os.environ.get("HDF5_VDS_PREFIX", "").replace("${ORIGIN}", origin)
    candidates = [os.path.join(origin, name), os.path.abspath(name)]
    if prefix:
        candidates.insert(0, os.path.join(prefix, name))
    return next((c for c in candidates if os.path.exists(c)), candidates[-2])


def missing_virtual_sources(f: h5py.File, archive: str) -> list[str]:
    """One line for each virtual dataset of ``f`` (the file at ``archive``) whose source file is
    missing or unreadable, or lacks its source dataset: HDF5 reads such a dataset's points as
    fill values without an error, so a reader refuses it instead."""
    found: list[tuple[str, str, str]] = []  # (virtual dataset, source file, source dataset)

    def visit(group: h5py.Group) -> None:  # past damaged objects: what else checks reports them
        try:
            names = list(group)
        except (OSError, RuntimeError, KeyError):
            return
        for name in names:
            try:
                obj = group[name]
                if isinstance(obj, h5py.Group):
                    visit(obj)
                elif isinstance(obj, h5py.Dataset) and obj.is_virtual:
                    found.extend((obj.name, src.file_name, src.dset_name) for src in obj.virtual_sources())
            except (OSError, RuntimeError, KeyError, ValueError):
                continue

    visit(f)
    problems: list[str] = []
    opened: dict[str, h5py.File | str] = {}  # each source file, open, or why it does not open
    try:
        for where, name, dataset in found:
            path = virtual_source_path(archive, name)
            if path not in opened:
                try:
                    opened[path] = h5py.File(path, "r", locking=False)
                except OSError as exc:
                    exists = os.path.exists(path)
                    opened[path] = f"unreadable ({first_line(exc)})" if exists else "missing"
            src = opened[path]
            if isinstance(src, str):
                problems.append(f"{where} reads from {path}, which is {src}")
            elif not isinstance(src.get(dataset), h5py.Dataset):
                problems.append(f"{where} reads from {path}, which has no dataset {dataset}")
    finally:
        for src in opened.values():
            if not isinstance(src, str):
                src.close()
    return problems


class Archive:
    """A read-only view of an archive; see :func:`open_archive`.

    Metadata (``params``, ``settings``, ``versions``, ``created``) are read on opening; ``series``,
    ``snapshots``, ``checkpoint_step`` and ``target_step`` are read afresh on every access, so a
    reader follows a run that is still being written.
    """

    def __init__(
        self, path: str | os.PathLike, *, locking: bool | None = None, check_sources: bool = True
    ) -> None:
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
            if check_sources:
                missing = missing_virtual_sources(self._file, self.path)
                if missing:
                    raise VirtualSourceError(
                        f"{self.path}: {missing[0]}; put the file back where it was "
                        "(its points would read as fill values)"
                    )
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
            #: Changes within the version (``/@format_minor``; absent: 0): 2 names each snapshot
            #: point's A_n ``finite_time_acceleration``, which earlier files store as ``A``.
            self.format_minor = int(attr_value(f.attrs.get("format_minor", 0)))
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
        """Complete slots as ``(step, name)``, newest first (:func:`._rows.slot_steps`)."""
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
        if TRANSPORT_FEATURE in self.features:

            def read_extra(slot: str) -> Any:
                return read_transport_slot(self._file, self.path, slot, self.points)

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
        if TRANSPORT_FEATURE not in self.features:
            return Ensemble.from_state(self.params, state, step, **kwargs)
        settings = self.settings
        return restore_transport(
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
        if TRANSPORT_FEATURE not in self.features:
            return None
        return read_transport_rows(self._file, self.path)

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
            "format_minor": self.format_minor,
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
            **estimate(series, self.target_step, self.initial_step, checkpoint_step),
        }

    # -- exports ----------------------------------------------------------------------------------
    def to_pandas(self, group: str = "series"):
        """``series`` (or the ``history`` rows) as a ``pandas.DataFrame`` indexed by ``step`` (needs
        ``warpratchet[xarray]``)."""
        return series_frame(self, group)

    def to_xarray(self, group: str = "series"):
        """``series`` (dimension ``step``), ``snapshots`` (``step``, ``indices``; with the derived
        unwrapped momentum ``p_unwrapped``) or ``history`` (``step``; block gains on ``block_step``,
        ``block_indices``) as an ``xarray.Dataset`` with units, long names and the file's global
        attributes, named and decoded as xarray's h5netcdf engine reads the file (needs
        ``warpratchet[xarray]``)."""
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


# -- how far a run is -----------------------------------------------------------------------------
#: Rows whose wall times give the speed: recent enough to follow a change of machine or load.
RECENT_ROWS = 16


def estimate(
    series: dict[str, np.ndarray], target: int | None, initial_step: int, checkpoint_step: int | None = None
) -> dict[str, Any]:
    """Target step, fraction done (kept, and written), speed and estimated seconds to the target.

    Parameters
    ----------
    series : dict of ndarray
        ``step`` and ``wall_time`` (kernel seconds) of each row, shape ``(rows,)``.
    target : int or None
        The step the run aims at (None: not recorded, as in format v1).
    initial_step : int
        The archive's first step (the step of ``/initial``).
    checkpoint_step : int, optional
        The verified checkpoint's step: where a rerun continues (default: the newest row's).

    Returns
    -------
    dict
        ``target_step``; ``done``, the fraction of the steps from ``initial_step`` to the target
        that the checkpoint keeps (what a rerun does not do again), and ``latest_done``, the
        fraction the newest row has reached (a live run's progress), both in [0, 1];
        ``steps_per_second`` (kernel speed over the last :data:`RECENT_ROWS` rows) and
        ``eta_seconds`` (kernel time from the newest row to the target at that speed; 0 when
        done); None where unknown.
    """
    out: dict[str, Any] = {
        "target_step": target,
        "done": None,
        "latest_done": None,
        "steps_per_second": None,
        "eta_seconds": None,
    }
    steps = np.asarray(series["step"], dtype=np.int64)
    last = int(steps[-1]) if steps.size else initial_step
    kept = last if checkpoint_step is None else checkpoint_step
    if steps.size:
        gained = np.diff(steps, prepend=initial_step)[-RECENT_ROWS:]
        seconds = float(np.sum(series["wall_time"][-RECENT_ROWS:]))
        if seconds > 0 and np.all(gained > 0):
            out["steps_per_second"] = float(np.sum(gained)) / seconds
    if target is None or target <= initial_step:
        return out

    def fraction(step: int) -> float:
        return min(1.0, max(0.0, (step - initial_step) / (target - initial_step)))

    out["done"], out["latest_done"] = fraction(kept), fraction(last)
    if kept >= target:
        out["eta_seconds"] = 0.0
    elif out["steps_per_second"]:
        # From the newest row (a live run's); a stopped run past its target restarts at the checkpoint.
        out["eta_seconds"] = (target - (last if last < target else kept)) / out["steps_per_second"]
    return out


# -- pandas and xarray views ----------------------------------------------------------------------
def _need(module: str) -> Any:
    try:
        return __import__(module)
    except ImportError:
        raise ImportError(f"this export needs {module}: pip install 'warpratchet[xarray]'") from None


def attributes(arc, group: str, name: str) -> dict[str, str]:
    """``units`` and ``long_name`` of ``/group/name`` as stored (format v1: as documented), found
    under its former name in a file written before it had this one."""
    attrs = arc.h5[group][stored_name(arc.h5[group], name)].attrs
    if "units" in attrs and "long_name" in attrs:
        return {"units": str(attr_value(attrs["units"])), "long_name": str(attr_value(attrs["long_name"]))}
    units, long_name = describe(group, name)
    return {"units": units, "long_name": long_name}


def _history(arc):
    """The archive's :class:`~warpratchet.history.History` (ValueError for an archive without one)."""
    history = arc.history
    if history is None:
        raise ValueError(f"{arc.path} has no history (its features: {', '.join(arc.features) or 'none'})")
    return history


def _group_rows(arc, group: str) -> tuple[dict, tuple[str, ...]]:
    """The rows of ``series`` or ``history`` and their field names (``step`` first)."""
    if group == "series":
        return arc.series, SERIES_FIELDS
    if group == "history":
        return {k: np.asarray(v) for k, v in _history(arc).rows.items()}, HISTORY_FIELDS
    raise ValueError(f"group = {group!r} is not 'series' or 'history'")


def series_frame(arc, group: str = "series"):
    """``arc.series`` (or the history rows) as a DataFrame indexed by ``step``; ``frame.attrs`` holds
    units and long names."""
    pd = _need("pandas")
    series, fields = _group_rows(arc, group)
    frame = pd.DataFrame({name: series[name] for name in fields[1:]}, index=series["step"])
    frame.index.name = "step"
    described = {name: attributes(arc, group, name) for name in fields}
    frame.attrs = {
        "units": {name: d["units"] for name, d in described.items()},
        "long_name": {name: d["long_name"] for name, d in described.items()},
        "path": arc.path,
    }
    return frame


def unwrapped_momentum(
    p0: np.ndarray, steps: np.ndarray, p: np.ndarray, finite_time_acceleration: np.ndarray
) -> np.ndarray:
    """The momentum ``p_n`` of snapshot points, not reduced mod 1: ``p0 + n A_n`` (Eq. An).

    ``p0`` ``(M,)`` is the points' initial momentum (``/initial/p0`` at ``/snapshots/indices``),
    ``steps`` ``(S,)``, ``p`` (mod 1) and ``finite_time_acceleration`` (``A_n``) ``(S, M)`` the
    snapshots'. ``p0 + n A_n`` carries the rounding of ``A_n``; its whole part is exact once
    rounded against the stored ``p`` mod 1, so the result is ``round(p0 + n A_n - p) + p``, the
    stored fraction unchanged.
    """
    approx = p0[None, :] + steps[:, None].astype(np.float64) * finite_time_acceleration
    return np.round(approx - p) + p


def _dataset_attrs(arc) -> dict[str, Any]:
    """The Dataset's attributes: the file's CF global attributes (format 2.1) and the map's parameters."""
    skip = {"format", "format_version", "format_minor", "features", "text_crc32"}
    stored = {k: attr_value(v) for k, v in arc.h5.attrs.items() if k not in skip}
    return {**stored, "path": arc.path, **arc.params.as_dict()}


def dataset(arc, group: str = "series"):
    """``/series`` (dimension ``step``), ``/snapshots`` (``step``, ``indices``) or ``/history``
    (``step``; block gains on ``block_step``, ``block_indices``) as a Dataset, named and decoded as
    ``xarray.open_dataset(path, group=group, engine="h5netcdf")`` names and decodes the file (a
    file before minor version 2: its snapshots' ``A`` named ``finite_time_acceleration``)."""
    xr = _need("xarray")
    attrs = _dataset_attrs(arc)
    if group == "series":
        series = arc.series
        coords = {"step": ("step", series["step"], attributes(arc, "series", "step"))}
        data = {name: ("step", series[name], attributes(arc, "series", name)) for name in SERIES_FIELDS[1:]}
        return xr.decode_cf(xr.Dataset(data, coords=coords, attrs=attrs))
    if group == "snapshots":
        snaps = arc.snapshots
        dims = ("step", "indices")
        coords = {
            "step": ("step", snaps.steps, attributes(arc, "snapshots", "step")),
            "indices": ("indices", snaps.indices, attributes(arc, "snapshots", "indices")),
        }
        data = {
            name: (dims, getattr(snaps, name), attributes(arc, "snapshots", name)) for name in SNAPSHOT_FIELDS
        }
        p0 = arc.initial["p0"][snaps.indices]
        units, long_name = describe("snapshots", "p_unwrapped")
        data["p_unwrapped"] = (
            dims,
            unwrapped_momentum(p0, snaps.steps, snaps.p, snaps.finite_time_acceleration),
            {"units": units, "long_name": long_name},
        )
        return xr.Dataset(data, coords=coords, attrs=attrs)
    if group == "history":
        history = _history(arc)
        rows, blocks = history.rows, history.block_rows
        coords = {
            "step": ("step", np.asarray(rows["step"]), attributes(arc, "history", "step")),
            "block_step": (
                "block_step",
                np.asarray(blocks["block_step"]),
                attributes(arc, "history", "block_step"),
            ),
            "block_indices": (
                "block_indices",
                np.asarray(history.block_indices),
                attributes(arc, "history", "block_indices"),
            ),
        }
        width = len(history.block_indices)
        data = {
            name: ("step", np.asarray(rows[name]), attributes(arc, "history", name))
            for name in HISTORY_FIELDS[1:]
        }
        for name in ("block_gain", "block_ftle"):
            values = np.asarray(blocks[name], dtype=np.float64).reshape(len(blocks["block_step"]), width)
            data[name] = (("block_step", "block_indices"), values, attributes(arc, "history", name))
        return xr.Dataset(data, coords=coords, attrs=attrs)
    raise ValueError(f"group = {group!r} is not 'series', 'snapshots' or 'history'")
