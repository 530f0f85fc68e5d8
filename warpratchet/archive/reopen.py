"""Reopening an archive for appending: ``ArchiveSink.resume`` (:mod:`warpratchet.archive.writer`).

The archive is rebuilt from what is valid in it (:func:`~warpratchet.archive.resume.salvage`)
under a temporary name and put in place of the old file atomically, under an exclusive lock.
"""

from __future__ import annotations

import os
from typing import TypeVar

import numpy as np

from .._files import claim, h5_bytes
from ..ensemble import Ensemble
from .layout import FILL, ROW_CHUNK, STATE_CHUNK
from .names import SNAPSHOT_FIELDS, ArchiveError
from .resume import Salvage, salvage

#: The sink class (``ArchiveSink``), passed in by the classmethod ``ArchiveSink.resume``.
Sink = TypeVar("Sink")

__all__ = ["reopen"]


def _rebuilt_bytes(old: Salvage) -> int:
    """Estimated file space of the data a rebuilt archive holds beside its layout.

    The state arrays (initial, checkpoint, transport state) take chunks of ``STATE_CHUNK``
    values, the rows whole chunks of ``ROW_CHUNK`` rows (one row per chunk where a row is an
    array, as a snapshot's); :func:`~warpratchet._storage.h5_bytes` adds HDF5's share.
    """
    initial = old.layout["initial"]
    states = [{k: v for k, v in initial.items() if np.any(v != FILL[k])}]  # a uniform field: no storage
    if old.step != old.layout["initial_step"]:
        states.append(old.state)
        if old.transport_rows is not None:
            carry = old.ensemble.transport_state()
            states.append({**carry.carry, "counts": carry.counts})
    rows = [old.series, old.transport_rows or {}]
    rows.append({name: getattr(old.snapshots, name) for name in ("steps", *SNAPSHOT_FIELDS)})
    if old.history is not None:
        rows += [old.history.rows, old.history.block_rows]
    total = sum(
        h5_bytes(v.nbytes, -(-v.size // STATE_CHUNK)) for s in states for v in map(np.asarray, s.values())
    )
    for group in rows:
        for v in map(np.asarray, group.values()):
            if v.ndim > 1:  # one row per chunk
                total += h5_bytes(v.nbytes, len(v))
            else:  # whole chunks of ROW_CHUNK rows
                chunks = -(-len(v) // ROW_CHUNK)
                total += h5_bytes(chunks * ROW_CHUNK * v.itemsize, chunks)
    return total


def reopen(
    cls: type[Sink], path: str | os.PathLike, *, threads: int | None = None, device: str | None = None
) -> tuple[Sink, Ensemble]:
    """Reopen an archive for appending, from its newest good checkpoint.

    The archive is rebuilt under a temporary name from what is valid (metadata, initial
    state, series rows and snapshots up to the checkpoint, the checkpoint; see
    :mod:`warpratchet.archive.resume`) and atomically put in place of the old file, so a
    kill during ``resume`` loses nothing either. A damaged checkpoint, snapshot, series row
    or initial state is skipped and named in an :class:`ArchiveWarning`. A format v1 archive
    is rebuilt in today's format.

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
            needed=_rebuilt_bytes(old),  # beside the old file until it takes its name
        )
    finally:
        os.close(old_fd)
    sink.checkpoint_step = old.step
    sink._last_snapshot = old.step
    return sink, old.ensemble
