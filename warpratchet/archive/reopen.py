"""Reopening an archive for appending: ``ArchiveSink.resume`` (:mod:`warpratchet.archive.writer`).

The archive is rebuilt from what is valid in it (:func:`~warpratchet.archive._recovery.salvage`)
under a temporary name and put in place of the old file atomically, under an exclusive lock.
"""

from __future__ import annotations

import os
from typing import TypeVar

from .._files import claim
from ..ensemble import Ensemble
from ._format import ArchiveError
from ._recovery import salvage

#: The sink class (``ArchiveSink``), passed in by the classmethod ``ArchiveSink.resume``.
Sink = TypeVar("Sink")

__all__ = ["reopen"]


def reopen(
    cls: type[Sink], path: str | os.PathLike, *, threads: int | None = None, device: str | None = None
) -> tuple[Sink, Ensemble]:
    """Reopen an archive for appending, from its newest good checkpoint.

    The archive is rebuilt under a temporary name from what is valid (metadata, initial
    state, series rows and snapshots up to the checkpoint, the checkpoint; see
    :mod:`warpratchet.archive._recovery`) and atomically put in place of the old file, so a
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
            needed=os.path.getsize(path),  # a rebuilt copy is about as large
        )
    finally:
        os.close(old_fd)
    sink.checkpoint_step = old.step
    sink._last_snapshot = old.step
    return sink, old.ensemble
