"""Building an archive file: its layout written under a temporary name, then published atomically.

A new archive (:class:`~warpratchet.archive.writer.ArchiveSink`) and a rebuilt one
(``ArchiveSink.resume``, :mod:`.reopen`) are both made here: the free space is checked first,
the layout (:func:`._format.create`) and any contents are written into ``.NAME.XXXX.tmp`` next
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
from . import _format
from ._format import ArchiveError

__all__ = ["as_archive_error", "build_file"]


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

    ``needed`` bytes must be free first; ``contents`` are the keyword arguments of
    :func:`._format.create`; ``start`` binds the open file to its writer (and leaves it open);
    ``keep_mode`` keeps the permissions of the file at ``path`` (a rebuilt archive).
    """
    with storage_errors(path, "create"):
        ensure_space(path, needed, "the new archive")
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
