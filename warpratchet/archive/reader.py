"""Reading an archive: :func:`open_archive`, :class:`Archive`, :class:`Snapshots`.

A reader is safe while a run is still writing the file (HDF5 SWMR): metadata are read on
opening, while ``series``, ``snapshots`` and the checkpoint slots are read afresh on every
access and only up to the ``n_valid`` counters, which the writer bumps after the rows are on
disk. A slot's ``step`` is read before and after its data (a sequence lock), so a checkpoint
the writer recycles meanwhile is never returned. Any HDF5 failure becomes one
:class:`~warpratchet.archive.layout.ArchiveError` line; a damaged checkpoint is skipped with an
:class:`~warpratchet.archive.layout.ArchiveWarning` naming what was recovered instead.
"""

from __future__ import annotations

import contextlib
import os
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import h5py
import numpy as np

from .._files import open_h5_reader
from ..ensemble import STATE_FIELDS, Ensemble
from ..params import MapParams
from .layout import (
    FORMAT,
    FORMAT_VERSION,
    SERIES_FIELDS,
    SLOTS,
    SNAPSHOT_FIELDS,
    ArchiveError,
    ArchiveWarning,
    attr,
    read_settings,
)

__all__ = ["Snapshots", "Archive", "open_archive"]


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


def _refresh(ds: h5py.Dataset) -> h5py.Dataset:
    with contextlib.suppress(Exception):  # only meaningful (and only allowed) in SWMR mode
        ds.refresh()
    return ds


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
                    return open_h5_reader(self.path, locking=locking, swmr=False)
                except OSError as exc:
                    if "already open for write" not in str(exc):
                        raise
                return open_h5_reader(self.path, locking=locking, swmr=True)
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
            fmt = attr(f.attrs.get("format", b""))
            version = attr(f.attrs.get("format_version", -1))
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
            self.created = str(attr(f.attrs["created"]))
            p = {k: attr(v) for k, v in f["params"].attrs.items()}
            self.params = MapParams(p["K"], p["b1"], p["b2"])
            self.settings = read_settings(f["settings"].attrs)
            self.versions = {k: str(attr(v)) for k, v in f["versions"].attrs.items()}
            self.initial_step = int(attr(f["initial"].attrs["step"]))
        self.points = int(self.settings["points"])

    def _stored_settings(self) -> dict[str, Any]:
        """``/settings`` exactly as stored (seed -1 and threshold NaN not decoded), to copy it."""
        with _reading(self.path, "the metadata"):
            return {k: attr(v) for k, v in self._file["settings"].attrs.items()}

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
        for name in SLOTS:
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

    def _restore(
        self, state: dict[str, np.ndarray], step: int, threads: int | None = None, device: str | None = None
    ) -> Ensemble:
        """An :class:`Ensemble` of this archive's run holding ``state`` at ``step``."""
        return Ensemble.from_state(
            self.params,
            state,
            step,
            device=device,
            threads=threads,
            sampler=self.settings["sampler"],
            seed=self.settings["seed"],
        )

    def ensemble(self, threads: int | None = None, device: str | None = None) -> Ensemble:
        """An :class:`Ensemble` restored bit for bit at the newest good checkpoint."""
        state, step = self.checkpoint()
        return self._restore(state, step, threads, device)

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
