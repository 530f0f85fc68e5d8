"""Crash-safe, resumable HDF5 archives of ensemble runs.

Modelled on REBOUND's simulation archive: one HDF5 file per run that the run loop streams into
after every chunk, that survives a kill at any moment, and from which a run continues *bit for
bit* as if it had never stopped. The layout is documented name by name in ``docs/archive.md``
(format ``warpratchet-archive``, version :data:`FORMAT_VERSION`).

How it stays consistent (a kill can land between any two writes):

* every dataset is created up front, chunked and resizable, then the file switches to SWMR
  (single writer, multiple readers) so that other processes can read it while it grows;
* rows (time series, snapshots) are appended and flushed *before* the ``n_valid`` counter that
  makes them visible is bumped and flushed: a reader never sees a row that is not on disk;
* the full state is checkpointed into one of two slots, the one *not* holding the newest
  checkpoint: its ``step`` is set to -1, the state written, flushed and fsynced, then ``step``
  and the ``current`` pointer are written. The previous checkpoint stays intact until a newer
  one is complete, and a reader checks ``step`` before and after reading (a sequence lock);
* every raw chunk carries a Fletcher-32 checksum and, with ``libver="latest"``, every piece of
  HDF5 metadata carries its own (strings are fixed-length, inside the checksummed headers):
  flipped bytes give an error, never silently wrong numbers. Readers open a cleanly closed file
  in normal mode, where HDF5 also checks its size against the superblock (truncation);
* a new file is built under a temporary name and published with ``link`` (or ``replace`` for
  ``force=True``), so the path never holds half an archive. :meth:`ArchiveSink.resume`
  rebuilds the archive the same way from its newest good checkpoint, which also clears the
  "open for writing" mark a killed SWMR writer leaves in the superblock.

A writer holds a shared ``flock`` on the file for its lifetime; :meth:`ArchiveSink.resume` and
``force=True`` need an exclusive one, so they refuse to touch a file that a live run (or an open
reader) is using. The observables written per chunk are those of Eqs. (An) and the FTLE, see
:mod:`warpratchet.observables`.
"""

from __future__ import annotations

import contextlib
import ctypes
import datetime
import functools
import math
import os
import platform
import re
import shutil
import tempfile
import time
import warnings
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _dist_version
from typing import Any

import h5py
import numpy as np
from h5py import h5f, h5g, h5p, h5s

from .ensemble import (
    RENORM_CHECK_EVERY,
    RENORM_THRESHOLD,
    STATE_FIELDS,
    Ensemble,
    Observer,
    default_chunk_steps,
)
from .observables import acceleration, lyapunov, summarize
from .params import MapParams

try:  # advisory locks; absent on Windows, where archives are simply not locked
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "SERIES_FIELDS",
    "SNAPSHOT_FIELDS",
    "ArchiveError",
    "ArchiveWarning",
    "Archive",
    "Snapshots",
    "ArchiveSink",
    "open_archive",
    "schedule",
    "run_to",
]

#: Format name, root attribute ``format``.
FORMAT = "warpratchet-archive"
#: Layout version, root attribute ``format_version``; readers refuse any other.
FORMAT_VERSION = 1

#: Columns of ``/series`` (one row per chunk); ``step`` and ``chaotic_points`` are int64.
SERIES_FIELDS = (
    "step",
    "A",
    "A_stderr",
    "lyapunov",
    "lyapunov_std",
    "lyapunov_min",
    "chaotic_fraction",
    "chaotic_points",
    "threshold",
    "wall_time",
    "unix_time",
)
_INT_SERIES = ("step", "chaotic_points")
#: Per-point arrays of ``/snapshots``, each ``(S, M)``.
SNAPSHOT_FIELDS = ("x", "p", "ftle", "A")
_SLOTS = ("a", "b")

#: Checkpoint every this many chunks by default: a checkpoint writes 56 bytes per point (the cost
#: of ~50 point-steps of the kernel) plus two fsyncs, so 8 chunks keep it well under 1% of the
#: kernel time while never losing more than ~8 chunks (a few seconds at the default chunk).
CHECKPOINT_CHUNKS = 8
#: Smallest default chunk while archiving: one series row costs ~25 point-steps per point
#: (the summary of Eq. An and the FTLE), so chunks of >= 1024 steps keep it below ~3%.
MIN_ARCHIVE_CHUNK_STEPS = 1024
#: Salt of the snapshot subsample's generator, so it differs from the sampler's stream.
_SNAPSHOT_SALT = 0x5A4E
#: Initial-state fill values: a field equal to its fill everywhere is not written (costs no space).
_FILL = {"x": 0.0, "q": 0.0, "winding": 0, "p0": 0.0, "dx": 1.0, "dp": 0.0, "log_stretch": 0.0}
_ROW_CHUNK = 256
_STATE_CHUNK = 1 << 17  # 1 MiB of float64 per chunk


class ArchiveError(ValueError):
    """An archive that cannot be used: missing, truncated, corrupted, incompatible or in use."""


class ArchiveWarning(UserWarning):
    """Something was recovered, e.g. an older checkpoint because the newest one is damaged."""


# -- small helpers --------------------------------------------------------------------------------
def _check_int(name: str, value: object, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} = {value!r} is outside the allowed range {name} >= {low} (an integer)")
    return int(value)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


@contextlib.contextmanager
def _reading(path: str, what: str) -> Iterator[None]:
    """Turn any HDF5/h5py failure while reading ``what`` into one clear :class:`ArchiveError`."""
    try:
        yield
    except ArchiveError:
        raise
    except (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError) as exc:
        raise ArchiveError(
            f"{path}: cannot read {what} ({_first_line(exc)}); the archive is truncated or corrupted"
        ) from None


def _versions() -> dict[str, str]:
    def dist(name: str) -> str:
        try:
            return _dist_version(name)
        except PackageNotFoundError:  # pragma: no cover - source tree
            return "unknown"

    import warp

    return {
        "warpratchet": dist("warpratchet"),
        "warp": str(getattr(warp.config, "version", dist("warp-lang"))),
        "numpy": np.__version__,
        "h5py": h5py.__version__,
        "hdf5": h5py.version.hdf5_version,
        "python": platform.python_version(),
    }


def _attr(value: Any) -> Any:
    """A Python/NumPy value as read from an HDF5 attribute (bytes -> str, 0-d -> scalar)."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _lock(fd: int, exclusive: bool) -> bool:
    """Try an advisory ``flock`` (never blocks); True if held (or locking is unavailable)."""
    if fcntl is None:  # pragma: no cover
        return True
    try:
        fcntl.flock(fd, (fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH) | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:  # filesystems without flock: no protection, but no failure either
        return True
    return True


def _claim(path: str, exclusive: bool) -> int:
    """Open ``path`` and lock it; raise :class:`ArchiveError` if another process holds it."""
    fd = os.open(path, os.O_RDONLY)
    if not _lock(fd, exclusive):
        os.close(fd)
        raise ArchiveError(
            f"{path} is in use by another process (a run writing it, or a program reading it); "
            "wait for it to finish or close it"
        )
    return fd


def _fsync_dir(path: str) -> None:
    with contextlib.suppress(OSError):  # not every filesystem lets a directory be fsynced
        fd = os.open(os.path.dirname(os.path.abspath(path)) or ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


# -- chunk schedule -------------------------------------------------------------------------------
def _largest_divisor_at_most(n: int, cap: int) -> int:
    best = 1
    d = 1
    while d * d <= n:
        if n % d == 0:
            for c in (d, n // d):
                if best < c <= cap:
                    best = c
        d += 1
    return best


def schedule(
    points: int,
    chunk_steps: int | None = None,
    snapshot_every: int = 0,
    checkpoint_every: int | None = None,
) -> tuple[int, int]:
    """Chunk length and checkpoint interval whose chunk ends land on every snapshot and checkpoint.

    Parameters
    ----------
    points : int
        Ensemble size.
    chunk_steps : int, optional
        Steps per chunk; must divide ``snapshot_every`` and ``checkpoint_every`` when given.
        Default: the largest divisor of their gcd not above ``max(default_chunk_steps(points),
        MIN_ARCHIVE_CHUNK_STEPS)``.
    snapshot_every : int
        Steps between snapshots (0: none).
    checkpoint_every : int, optional
        Steps between checkpoints; default ``CHECKPOINT_CHUNKS * chunk_steps``.

    Returns
    -------
    (chunk_steps, checkpoint_every) : tuple of int

    Raises
    ------
    ValueError
        If an explicit ``chunk_steps`` does not divide the intervals, or if the intervals only
        admit chunks so short that the run would crawl.
    """
    points = _check_int("points", points, 1)
    snapshot_every = _check_int("snapshot_every", snapshot_every, 0)
    if checkpoint_every is not None:
        checkpoint_every = _check_int("checkpoint_every", checkpoint_every, 1)
    intervals = {
        name: v
        for name, v in (("snapshot_every", snapshot_every), ("checkpoint_every", checkpoint_every))
        if v
    }
    if chunk_steps is not None:
        chunk_steps = _check_int("chunk_steps", chunk_steps, 1)
        bad = {name: v for name, v in intervals.items() if v % chunk_steps}
        if bad:
            listed = " and ".join(f"{name} = {v}" for name, v in bad.items())
            raise ValueError(
                f"chunk_steps = {chunk_steps} must divide {listed} (chunk ends must land on them)"
            )
    else:
        cap = max(default_chunk_steps(points), MIN_ARCHIVE_CHUNK_STEPS)
        if intervals:
            g = math.gcd(*intervals.values())
            chunk_steps = _largest_divisor_at_most(g, cap)
            if 16 * chunk_steps < min(g, cap):
                listed = " and ".join(f"{name} = {v}" for name, v in intervals.items())
                raise ValueError(
                    f"{listed} only allow chunks of {chunk_steps} steps (want about {min(g, cap)}); "
                    "choose intervals with small factors (e.g. multiples of 1000) or pass chunk_steps"
                )
        else:
            chunk_steps = cap
    if checkpoint_every is None:
        checkpoint_every = CHECKPOINT_CHUNKS * chunk_steps
    return chunk_steps, checkpoint_every


def run_to(
    ensemble: Ensemble,
    target_step: int,
    observers: Iterable[Observer] = (),
    chunk_steps: int | None = None,
) -> Ensemble:
    """Advance ``ensemble`` to the global step ``target_step`` (not by it: resume's total).

    :meth:`Ensemble.run` ends chunks at global multiples of ``chunk_steps``, so a resumed run's
    series rows, snapshots and checkpoints land on the same steps as an uninterrupted run's.
    """
    target_step = _check_int("target_step", target_step, ensemble.step)
    return ensemble.run(target_step - ensemble.step, observers, chunk_steps)


# -- reading --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Snapshots:
    """Phase-space snapshots of a fixed random subsample of ``M`` points.

    Attributes
    ----------
    steps : ndarray, shape (S,), int64
        Iteration numbers of the snapshots.
    indices : ndarray, shape (M,), int64
        Indices of the sampled points in the ensemble (sorted).
    x, p : ndarray, shape (S, M)
        Position and momentum mod 1, both in ``[0, 1)`` (Eq. cpem on the torus).
    ftle : ndarray, shape (S, M)
        Finite-time Lyapunov exponent per iteration.
    A : ndarray, shape (S, M)
        Mean acceleration ``A_n`` of Eq. (An), per iteration.
    """

    steps: np.ndarray
    indices: np.ndarray
    x: np.ndarray
    p: np.ndarray
    ftle: np.ndarray
    A: np.ndarray

    def __len__(self) -> int:
        return int(self.steps.size)


def _refresh(ds: h5py.Dataset) -> h5py.Dataset:
    with contextlib.suppress(Exception):  # only meaningful (and only allowed) in SWMR mode
        ds.refresh()
    return ds


#: Metadata read attempts of an SWMR reader. A reader may catch metadata the writer is
#: rewriting, fail its checksum and must retry; HDF5 retries 100 times backing off to 36 s a
#: try, so a *damaged* file would hang a reader for ~40 minutes. 27 attempts (doubling from
#: 1 ns) still retry a torn read for ~0.13 s, far longer than a writer's flush.
SWMR_READ_ATTEMPTS = 27


@functools.cache
def _read_attempts_setter():
    """``H5Pset_metadata_read_attempts`` of the libhdf5 that h5py uses (h5py does not wrap
    it), or None if that library cannot be identified (then HDF5's default applies)."""
    try:
        with open("/proc/self/maps") as fh:
            fields = [line.split(None, 5) for line in fh]
        paths = {f[5].strip() for f in fields if len(f) == 6}
    except OSError:  # not Linux
        return None
    libs = [p for p in paths if re.match(r"libhdf5[-.]", os.path.basename(p))]
    if len(libs) > 1:  # several HDF5 copies loaded: only trust the one shipped with h5py
        libs = [p for p in libs if "h5py" in p]
    if len(libs) != 1:
        return None
    try:
        setter = ctypes.CDLL(libs[0]).H5Pset_metadata_read_attempts
    except (OSError, AttributeError):
        return None
    setter.argtypes = [ctypes.c_int64, ctypes.c_uint]
    setter.restype = ctypes.c_int
    return setter


def _open_reader(path: str, locking: bool | None, swmr: bool) -> h5py.File:
    """Open read-only (SWMR mode with bounded metadata retries), without a raw-chunk cache so
    that a live reader never serves a stale chunk."""
    fapl = h5p.create(h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5f.LIBVER_LATEST, h5f.LIBVER_LATEST)
    mdc, nslots, _, w0 = fapl.get_cache()
    fapl.set_cache(mdc, nslots, 0, w0)
    if locking is not None:
        fapl.set_file_locking(locking, True)
    setter = _read_attempts_setter() if swmr else None
    if setter is not None:
        setter(fapl.id, SWMR_READ_ATTEMPTS)
    flags = h5f.ACC_RDONLY | (h5f.ACC_SWMR_READ if swmr else 0)
    fid = h5f.open(os.fsencode(path), flags, fapl=fapl)
    return h5py.File(fid)


class Archive:
    """A read-only view of an archive; see :func:`open_archive`.

    Metadata (``params``, ``settings``, ``versions``, ``created``) are read on opening; ``series``,
    ``snapshots`` and ``checkpoint_step`` are read afresh on every access, so a reader follows a
    run that is still being written.
    """

    def __init__(self, path: str | os.PathLike, *, locking: bool | None = None) -> None:
        self.path = os.fspath(path)
        if not os.path.exists(self.path):
            raise ArchiveError(f"{self.path}: no such archive")
        self._file = self._open(locking)
        try:
            self._read_metadata()
        except BaseException:
            self._file.close()
            raise

    def _open(self, locking: bool | None) -> h5py.File:
        """Open read-only. A file closed cleanly opens normally, so HDF5 checks its size against
        the superblock (a truncated file is an error at once, and damaged metadata is not
        retried); a file that a writer has open, or that a killed writer left marked as open,
        opens in SWMR mode."""
        for attempt in range(20):
            try:
                try:
                    return _open_reader(self.path, locking, swmr=False)
                except OSError as exc:
                    if "already open for write" not in str(exc):
                        raise
                return _open_reader(self.path, locking, swmr=True)
            except OSError as exc:
                text = str(exc)
                if "SWMR read access flag not the same" in text:
                    # This process is writing it: HDF5 shares the writer's handle instead.
                    kw = {} if locking is None else {"locking": locking}
                    with _reading(self.path, "the file"):
                        return h5py.File(self.path, "r", **kw)
                if "unable to lock file" in text:
                    if attempt < 19:  # another program's writer, about to enter SWMR mode
                        time.sleep(0.05)
                        continue
                    raise ArchiveError(f"{self.path} is locked by another process") from None
                raise ArchiveError(
                    f"{self.path}: not a readable HDF5 archive ({_first_line(exc)}); "
                    "the file is truncated or corrupted"
                ) from None
        raise AssertionError("unreachable")  # pragma: no cover

    def _read_metadata(self) -> None:
        f = self._file
        with _reading(self.path, "the root attributes"):
            fmt = _attr(f.attrs.get("format", b""))
            version = _attr(f.attrs.get("format_version", -1))
        if fmt != FORMAT:
            raise ArchiveError(
                f"{self.path}: not a warpratchet archive (format = {fmt!r}, expected {FORMAT!r})"
            )
        if version != FORMAT_VERSION:
            raise ArchiveError(
                f"{self.path}: archive format version {version} is not supported "
                f"(this warpratchet reads version {FORMAT_VERSION})"
            )
        self.format_version = int(version)
        with _reading(self.path, "the metadata"):
            self.created = str(_attr(f.attrs["created"]))
            p = {k: _attr(v) for k, v in f["params"].attrs.items()}
            self.params = MapParams(p["K"], p["b1"], p["b2"])
            settings = {k: _attr(v) for k, v in f["settings"].attrs.items()}
            self.versions = {k: str(_attr(v)) for k, v in f["versions"].attrs.items()}
            self.initial_step = int(_attr(f["initial"].attrs["step"]))
        settings["seed"] = None if settings.get("seed", -1) < 0 else settings["seed"]
        if isinstance(settings.get("threshold"), float) and math.isnan(settings["threshold"]):
            settings["threshold"] = None
        self.settings = settings
        self.points = int(settings["points"])

    # -- live data ------------------------------------------------------------------------------
    def _count(self, group: str) -> int:
        with _reading(self.path, f"/{group}/n_valid"):
            n = int(_refresh(self._file[group]["n_valid"])[0])
        if n < 0:
            raise ArchiveError(f"{self.path}: /{group}/n_valid = {n} is negative; the archive is corrupted")
        return n

    @property
    def rows(self) -> int:
        """Number of valid rows of ``series`` (chunks recorded)."""
        return self._count("series")

    @property
    def series(self) -> dict[str, np.ndarray]:
        """One row per chunk, keys :data:`SERIES_FIELDS`, each of shape ``(rows,)``.

        ``A``, ``A_stderr`` are the mean of ``A_n`` (Eq. An) over chaotic points and its standard
        error, ``lyapunov*`` FTLE statistics of the chaotic points (per iteration),
        ``wall_time`` the chunk's kernel seconds, ``unix_time`` when the row was written.
        """
        n = self._count("series")
        out = {}
        for name in SERIES_FIELDS:
            with _reading(self.path, f"/series/{name}"):
                ds = _refresh(self._file["series"][name])
                if ds.shape[0] < n:
                    raise ArchiveError(
                        f"{self.path}: /series/{name} has {ds.shape[0]} rows, n_valid says {n}"
                    )
                out[name] = ds[:n]
        return out

    @property
    def snapshots(self) -> Snapshots:
        """Snapshots recorded so far (``S`` may be 0); see :class:`Snapshots`."""
        n = self._count("snapshots")
        g = self._file["snapshots"]
        with _reading(self.path, "/snapshots"):
            indices = _refresh(g["indices"])[:]
            steps = _refresh(g["step"])
            if steps.shape[0] < n:
                raise ArchiveError(
                    f"{self.path}: /snapshots/step has {steps.shape[0]} rows, n_valid says {n}"
                )
            fields = {"steps": steps[:n], "indices": indices}
            for name in SNAPSHOT_FIELDS:
                ds = _refresh(g[name])
                if ds.shape[0] < n or ds.shape[1] != indices.size:
                    raise ArchiveError(
                        f"{self.path}: /snapshots/{name} has shape {ds.shape}, expected ({n}, M)"
                    )
                fields[name] = ds[:n]
        return Snapshots(**fields)

    def _slot_steps(self, problems: list[str] | None = None) -> list[tuple[int, str]]:
        """Complete slots as ``(step, name)``, newest first (``step`` -1 marks a slot in progress).

        An unreadable slot raises, or is skipped and described in ``problems`` if given.
        """
        out = []
        for name in _SLOTS:
            try:
                with _reading(self.path, f"/checkpoint/{name}/step"):
                    step = int(_refresh(self._file["checkpoint"][name]["step"])[0])
            except ArchiveError as exc:
                if problems is None:
                    raise
                problems.append(f"checkpoint slot {name!r} is unreadable ({exc})")
                continue
            if step >= 0:
                out.append((step, name))
        return sorted(out, reverse=True)

    @property
    def checkpoint_step(self) -> int:
        """Step of the newest complete checkpoint (the initial step if there is none yet).

        Read from metadata only; :meth:`checkpoint` also verifies the data and falls back (with
        an :class:`ArchiveWarning`) if it is damaged.
        """
        slots = self._slot_steps()
        return slots[0][0] if slots else self.initial_step

    def _read_state(self, group: h5py.Group, where: str) -> dict[str, np.ndarray]:
        state = {}
        for name in STATE_FIELDS:
            with _reading(self.path, f"{where}/{name}"):
                ds = _refresh(group[name])
                if ds.shape != (self.points,):
                    raise ArchiveError(
                        f"{self.path}: {where}/{name} has shape {ds.shape}, expected ({self.points},)"
                    )
                state[name] = ds[:]
        return state

    @property
    def initial(self) -> dict[str, np.ndarray]:
        """The state the archive started from (at step ``initial_step``), keys ``STATE_FIELDS``."""
        return self._read_state(self._file["initial"], "/initial")

    def checkpoint(self) -> tuple[dict[str, np.ndarray], int]:
        """The newest checkpoint whose data verify, as ``(state, step)``.

        Tries the complete slots newest first, then the initial state. A slot whose checksum
        fails is skipped with an :class:`ArchiveWarning` naming what was recovered instead.
        """
        problems = []
        for _attempt in range(10):  # a live writer may recycle a slot while we read it
            problems.clear()
            retry = False
            for step, name in self._slot_steps(problems):
                where = f"/checkpoint/{name}"
                try:
                    state = self._read_state(self._file["checkpoint"][name], where)
                except ArchiveError as exc:
                    problems.append(f"checkpoint at step {step} is unreadable ({exc})")
                    continue
                with _reading(self.path, f"{where}/step"):
                    again = int(_refresh(self._file["checkpoint"][name]["step"])[0])
                if again != step:  # overwritten while we read: start over
                    retry = True
                    break
                self._warn(problems, f"recovered the checkpoint at step {step}")
                return state, step
            if not retry:
                break
        state = self.initial
        if problems:
            self._warn(problems, f"recovered the initial state at step {self.initial_step}")
        return state, self.initial_step

    def _warn(self, problems: list[str], outcome: str) -> None:
        if problems:
            warnings.warn(f"{self.path}: {'; '.join(problems)}; {outcome}", ArchiveWarning, stacklevel=3)

    def ensemble(self, threads: int | None = None, device: str | None = None) -> Ensemble:
        """An :class:`Ensemble` restored bit for bit at the newest good checkpoint."""
        state, step = self.checkpoint()
        return Ensemble.from_state(
            self.params,
            state,
            step,
            device=device,
            threads=threads,
            sampler=self.settings["sampler"],
            seed=self.settings["seed"],
        )

    def latest(self) -> dict[str, float | int] | None:
        """The last series row as a dict (None before the first chunk)."""
        series = self.series
        if series["step"].size == 0:
            return None
        return {name: values[-1].item() for name, values in series.items()}

    def info(self) -> dict[str, Any]:
        """Everything ``warpratchet inspect`` shows: metadata, progress, latest summary."""
        return {
            "path": self.path,
            "format": FORMAT,
            "format_version": self.format_version,
            "created": self.created,
            "params": self.params.as_dict(),
            "settings": dict(self.settings),
            "versions": dict(self.versions),
            "initial_step": self.initial_step,
            "checkpoint_step": self.checkpoint()[1],  # verified: where a resume would start
            "rows": self.rows,
            "snapshots": self._count("snapshots"),
            "latest": self.latest(),
        }

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> Archive:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        p = self.params
        return f"Archive({self.path!r}, K={p.K!r}, b1={p.b1!r}, b2={p.b2!r}, points={self.points})"


def open_archive(path: str | os.PathLike) -> Archive:
    """Open an archive read-only (SWMR: safe while a run is still writing it).

    Returns an :class:`Archive` with ``params``, ``settings``, ``versions``, ``created``,
    ``series``, ``snapshots``, ``checkpoint_step`` and ``ensemble()``; use it as a context
    manager. Raises :class:`ArchiveError` (a ``ValueError``) with one clear line for a missing,
    truncated, corrupted or incompatible file.
    """
    return Archive(path)


# -- writing --------------------------------------------------------------------------------------
def _make(
    f: h5py.File,
    *,
    params: MapParams,
    settings: dict[str, Any],
    versions: dict[str, str],
    created: str,
    initial: dict[str, np.ndarray],
    initial_step: int,
    indices: np.ndarray,
) -> None:
    """Create the whole layout of ``docs/archive.md`` (SWMR allows no new objects later)."""
    n = int(settings["points"])
    m = int(indices.size)
    _set_attrs(f, {"format": FORMAT, "format_version": FORMAT_VERSION, "created": created})
    _set_attrs(_group(f, "params"), params.as_dict())
    _set_attrs(_group(f, "settings"), settings)
    _set_attrs(_group(f, "versions"), versions)

    def state_dataset(group: h5py.Group, name: str, fill: float | int | None = None) -> h5py.Dataset:
        dtype = np.int64 if name == "winding" else np.float64
        kw = {} if fill is None else {"fillvalue": dtype(fill)}
        return group.create_dataset(
            name, shape=(n,), dtype=dtype, chunks=(min(n, _STATE_CHUNK),), fletcher32=True, **kw
        )

    def counter(group: h5py.Group, name: str, value: int) -> None:
        # Mutable scalars are (1,) chunked datasets: checksummed, and writable under SWMR.
        group.create_dataset(name, data=np.array([value], np.int64), chunks=(1,), fletcher32=True)

    g = _group(f, "initial")
    _set_attrs(g, {"step": int(initial_step)})
    for name in STATE_FIELDS:
        ds = state_dataset(g, name, _FILL[name])
        values = np.asarray(initial[name])
        if np.any(values != _FILL[name]):  # a uniform field stays a fill value, no storage
            ds.write_direct(np.ascontiguousarray(values, dtype=ds.dtype))

    g = _group(f, "series")
    for name in SERIES_FIELDS:
        g.create_dataset(
            name,
            shape=(0,),
            maxshape=(None,),
            chunks=(_ROW_CHUNK,),
            dtype=np.int64 if name in _INT_SERIES else np.float64,
            fletcher32=True,
        )
    counter(g, "n_valid", 0)

    g = _group(f, "snapshots")
    g.create_dataset(
        "indices",
        data=indices.astype(np.int64),
        maxshape=(None,),
        chunks=(max(1, min(m, _STATE_CHUNK)),),
        fletcher32=True,
    )
    g.create_dataset(
        "step", shape=(0,), maxshape=(None,), chunks=(_ROW_CHUNK,), dtype=np.int64, fletcher32=True
    )
    for name in SNAPSHOT_FIELDS:
        g.create_dataset(
            name,
            shape=(0, m),
            maxshape=(None, None),
            chunks=(1, max(1, min(m, _STATE_CHUNK))),
            dtype=np.float64,
            fletcher32=True,
        )
    counter(g, "n_valid", 0)

    g = _group(f, "checkpoint")
    counter(g, "current", -1)
    for slot in _SLOTS:
        s = _group(g, slot)
        counter(s, "step", -1)
        for name in STATE_FIELDS:
            state_dataset(s, name)


def _group(parent: h5py.Group, name: str) -> h5py.Group:
    """A group whose attributes all live in its (checksummed) object header, not in dense storage."""
    gcpl = h5p.create(h5p.GROUP_CREATE)
    gcpl.set_attr_phase_change(64, 32)
    h5g.create(parent.id, name.encode(), gcpl=gcpl)
    return parent[name]


def _set_attrs(obj: h5py.HLObject, values: dict[str, Any]) -> None:
    """Attributes, strings as fixed-length UTF-8 (stored in the checksummed header, unlike the
    variable-length strings h5py writes by default, which live in an unchecked global heap)."""
    for key, value in values.items():
        obj.attrs[key] = np.bytes_(value.encode()) if isinstance(value, str) else value


def _new_file(path: str) -> tuple[str, h5py.File]:
    """A fresh HDF5 file under a temporary name next to ``path`` (same filesystem: atomic rename)."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".tmp", dir=folder)
    os.close(fd)
    mask = os.umask(0)  # mkstemp makes the file private; an archive gets the usual permissions
    os.umask(mask)
    os.chmod(tmp, 0o666 & ~mask)
    try:
        return tmp, h5py.File(tmp, "w", libver="latest")
    except BaseException:
        os.unlink(tmp)
        raise


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
        See :func:`schedule`.
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
        snapshot_points = _check_int("snapshot_points", snapshot_points, 1)
        chunk_steps, checkpoint_every = schedule(
            ensemble.points, chunk_steps, snapshot_every, checkpoint_every
        )
        if threshold is not None and not (isinstance(threshold, (int, float)) and math.isfinite(threshold)):
            raise ValueError(f"threshold = {threshold!r} is not a finite number")
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            raise ArchiveError(f"{path}: the folder {folder} does not exist")
        exists = os.path.lexists(path)
        if exists and not force:
            raise ArchiveError(f"{path} exists; refusing to overwrite it (use force=True / --force)")
        if exists and not os.path.isfile(path):
            raise ArchiveError(f"{path} exists and is not a regular file")
        old_fd = _claim(path, exclusive=True) if exists else None
        m = min(snapshot_points, ensemble.points) if snapshot_every else 0
        rng = np.random.default_rng([_SNAPSHOT_SALT, ensemble.seed or 0])
        indices = np.sort(rng.choice(ensemble.points, size=m, replace=False)).astype(np.int64)
        settings = {
            "points": ensemble.points,
            "sampler": ensemble.sampler,
            "seed": -1 if ensemble.seed is None else int(ensemble.seed),
            "threads": ensemble.threads,
            "device": ensemble.device,
            "chunk_steps": chunk_steps,
            "checkpoint_every": checkpoint_every,
            "snapshot_every": snapshot_every,
            "snapshot_points": m,
            "threshold": math.nan if threshold is None else float(threshold),
            "renorm_threshold": RENORM_THRESHOLD,
            "renorm_check_every": RENORM_CHECK_EVERY,
            "dtype": "float64",
        }
        try:
            tmp, f = _new_file(path)
            try:
                _make(
                    f,
                    params=ensemble.params,
                    settings=settings,
                    versions=_versions(),
                    created=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                    initial={name: ensemble.array(name) for name in STATE_FIELDS},
                    initial_step=ensemble.step,
                    indices=indices,
                )
                self._start(f, path, ensemble, settings, indices, rows=0, snaps=0)
                self._publish(tmp, path, replace=exists)
            except BaseException:
                f.close()
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
                raise
        finally:
            if old_fd is not None:
                os.close(old_fd)
        self.checkpoint_step = ensemble.step
        self._last_snapshot = ensemble.step

    def _start(self, f, path, ensemble, settings, indices, rows, snaps) -> None:
        """Enter SWMR mode and bind the open file to this sink."""
        f.swmr_mode = True
        f.flush()
        os.fsync(f.id.get_vfd_handle())
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
        g = f["checkpoint"]
        self._current = int(g["current"][0])

    def _publish(self, tmp: str, path: str, replace: bool) -> None:
        """Give the complete file its name: atomically, never clobbering a file that appeared."""
        if replace:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)
            except FileExistsError:
                raise ArchiveError(
                    f"{path} exists; refusing to overwrite it (use force=True / --force)"
                ) from None
            except OSError:  # no hard links on this filesystem: check, then rename
                if os.path.lexists(path):
                    raise ArchiveError(f"{path} exists; refusing to overwrite it") from None
                os.rename(tmp, path)
            else:
                os.unlink(tmp)
        _fsync_dir(path)
        self._lock_fd = os.open(path, os.O_RDONLY)
        _lock(self._lock_fd, exclusive=False)

    # -- resume -----------------------------------------------------------------------------------
    @classmethod
    def resume(
        cls, path: str | os.PathLike, *, threads: int | None = None, device: str | None = None
    ) -> tuple[ArchiveSink, Ensemble]:
        """Reopen an archive for appending, from its newest good checkpoint.

        The archive is rebuilt under a temporary name from what is valid (metadata, initial
        state, series rows and snapshots up to the checkpoint, the checkpoint) and atomically
        put in place of the old file, so a kill during ``resume`` loses nothing either.

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
        old_fd = _claim(path, exclusive=True)
        try:
            with Archive(path, locking=False) as arc:
                s = arc.settings
                kernel = {"renorm_threshold": RENORM_THRESHOLD, "renorm_check_every": RENORM_CHECK_EVERY}
                for key, ours in kernel.items():
                    if s.get(key) != ours:
                        raise ArchiveError(
                            f"{path}: written with {key} = {s.get(key)!r} but this kernel uses {ours!r}; "
                            "a resumed run would not continue it bit for bit"
                        )
                state, step = arc.checkpoint()
                ensemble = Ensemble.from_state(
                    arc.params,
                    state,
                    step,
                    device=device,
                    threads=threads,
                    sampler=s["sampler"],
                    seed=s["seed"],
                )
                series = arc.series
                keep = int(np.searchsorted(series["step"], step, side="right"))
                snaps = arc.snapshots
                keep_snaps = int(np.searchsorted(snaps.steps, step, side="right"))
                with _reading(path, "the metadata"):
                    settings = {k: _attr(v) for k, v in arc._file["settings"].attrs.items()}
                initial = arc.initial
                meta = {
                    "params": arc.params,
                    "settings": settings,
                    "versions": dict(arc.versions),
                    "created": arc.created,
                    "initial": initial,
                    "initial_step": arc.initial_step,
                    "indices": snaps.indices,
                }
            sink = cls.__new__(cls)
            tmp, f = _new_file(path)
            with contextlib.suppress(OSError):
                shutil.copymode(path, tmp)  # the rebuilt archive keeps the user's permissions
            try:
                _make(f, **meta)
                g = f["series"]
                for name in SERIES_FIELDS:
                    if keep:
                        g[name].resize(keep, axis=0)
                        g[name][:] = series[name][:keep]
                g["n_valid"][0] = keep
                g = f["snapshots"]
                for name, values in (
                    ("step", snaps.steps),
                    *((n, getattr(snaps, n)) for n in SNAPSHOT_FIELDS),
                ):
                    if keep_snaps:
                        g[name].resize(keep_snaps, axis=0)
                        g[name][...] = values[:keep_snaps]
                g["n_valid"][0] = keep_snaps
                if step != meta["initial_step"]:
                    slot = f["checkpoint"]["a"]
                    for name in STATE_FIELDS:
                        slot[name].write_direct(np.ascontiguousarray(state[name]))
                    slot["step"][0] = step
                    f["checkpoint"]["current"][0] = 0
                sink._start(f, path, ensemble, settings, snaps.indices, rows=keep, snaps=keep_snaps)
                sink._publish(tmp, path, replace=True)
            except BaseException:
                f.close()
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
                raise
        finally:
            os.close(old_fd)
        sink.checkpoint_step = step
        sink._last_snapshot = step
        return sink, ensemble

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
        s = summarize(live, step, self.threshold)
        row = {
            "step": step,
            "A": s.A,
            "A_stderr": s.A_stderr,
            "lyapunov": s.lyapunov,
            "lyapunov_std": s.lyapunov_std,
            "lyapunov_min": s.lyapunov_min,
            "chaotic_fraction": s.chaotic_fraction,
            "chaotic_points": s.chaotic_points,
            "threshold": s.threshold,
            "wall_time": seconds,
            "unix_time": time.time(),
        }
        self._series.put(row)
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
        slot = f["checkpoint"][_SLOTS[free]]
        _set_counter(slot["step"], -1)  # in progress: neither a reader nor a recovery may trust it
        f.flush()
        for name in STATE_FIELDS:
            slot[name].write_direct(np.ascontiguousarray(ensemble.array(name)))
        f.flush()
        os.fsync(f.id.get_vfd_handle())  # the data is durable before anything points at it
        _set_counter(slot["step"], ensemble.step)
        _set_counter(f["checkpoint"]["current"], free)
        f.flush()
        os.fsync(f.id.get_vfd_handle())
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
            self.capacity = self.count + _ROW_CHUNK
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
