"""Building an archive file: its layout written under a temporary name, then published atomically.

A new archive (:class:`~warpratchet.archive.writer.ArchiveSink`) and a rebuilt one
(``ArchiveSink.resume``, :mod:`.reopen`) are both made here: the free space is checked first,
the layout (:func:`.layout.create`) and any contents are written into ``.NAME.XXXX.tmp`` next
to the path, the caller binds the open file (SWMR mode, fsync), and only then does the file get
its name (:func:`warpratchet._files.publish`). A failure (a full disk) leaves no temporary file
and the old file, if any, untouched.
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Callable, Iterator
from typing import Any

import h5py

from .._files import abandon_h5, ensure_space, publish, storage_errors, temporary_beside
from .._h5 import create_h5
from . import layout
from .names import ArchiveError

__all__ = ["as_archive_error", "build_file"]

#: File space of an archive's layout beyond its data (groups, datasets, attributes, counters,
#: a history's 4096 subsample indices): ``scripts/h5_overhead.py`` measures 40576 B for a bare
#: archive of 10000 points, 81536 B with a history, 93824 B with transport counts too.
LAYOUT_BYTES = 96 * 1024


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
    and the layout's :data:`LAYOUT_BYTES` must be free first; ``contents`` are the keyword arguments of
    :func:`.layout.create`; ``start`` binds the open file to its writer (and leaves it open);
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
            layout.create(f, **contents)
            if fill is not None:
                fill(f)
            start(f)
            with as_archive_error():
                publish(tmp, path, replace=replace)
        except BaseException:
            abandon_h5(f)  # a plain close would retry a failed write (and crash at exit)
            raise
