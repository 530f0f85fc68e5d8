"""Storage failures as one line: a full disk, a read-only file system, a missing permission.

:func:`storage_errors` turns the ``OSError`` (or HDF5's error text) of a refused write into a
:class:`StorageError` naming the file and the cause (the CLI exits with status 1);
:func:`ensure_space` refuses a write before HDF5 meets a full disk.
"""

from __future__ import annotations

import contextlib
import errno
import os
from collections.abc import Iterator

__all__ = [
    "StorageError",
    "STORAGE_ERRNOS",
    "storage_cause",
    "storage_errors",
    "SPACE_MARGIN",
    "ensure_space",
]


class StorageError(OSError):
    """The system refused a write: disk full, read-only file system, no permission, I/O error.

    ``str()`` is one line naming the file and the cause; the CLI exits with status 1.
    """

    def __str__(self) -> str:
        return self.strerror or super().__str__()


#: errno values that mean "this storage cannot take the write", not "bad input".
STORAGE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO, errno.EFBIG}
_CAUSES = {
    errno.ENOSPC: "no space left on the device (disk full)",
    errno.EDQUOT: "disk quota exceeded",
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.EIO: "input/output error",
    errno.EFBIG: "file too large",
}
#: HDF5 reports a failed write(2) in its own words; the errno survives only as text.
_HDF5_CAUSES = (
    ("No space left on device", errno.ENOSPC),
    ("Disk quota exceeded", errno.EDQUOT),
    ("Read-only file system", errno.EROFS),
    ("Permission denied", errno.EACCES),
    ("Input/output error", errno.EIO),
    ("File too large", errno.EFBIG),
)


def storage_cause(exc: BaseException) -> int | None:
    """The errno of a storage failure (:data:`STORAGE_ERRNOS`), from ``OSError`` or HDF5's text."""
    if isinstance(exc, StorageError):
        return exc.errno
    if isinstance(exc, OSError) and exc.errno in STORAGE_ERRNOS:
        return exc.errno
    if isinstance(exc, (OSError, RuntimeError)):
        text = str(exc)
        for words, code in _HDF5_CAUSES:
            if words in text:
                return code
    return None


@contextlib.contextmanager
def storage_errors(path: str | os.PathLike, doing: str = "write", hint: str = "") -> Iterator[None]:
    """Re-raise a storage failure inside the block as one :class:`StorageError` line.

    ``"cannot {doing} {path}: {cause}{hint}"``; other errors pass unchanged.
    """
    try:
        yield
    except StorageError as exc:
        if hint and not str(exc).endswith(hint):
            raise StorageError(exc.errno, f"{exc}{hint}") from None
        raise
    except (OSError, RuntimeError) as exc:
        code = storage_cause(exc)
        if code is None:
            raise
        raise StorageError(code, f"cannot {doing} {os.fspath(path)}: {_CAUSES[code]}{hint}") from None


#: Free space kept beyond what a write needs: HDF5's own metadata of the write, with room to spare.
SPACE_MARGIN = 256 * 1024


def ensure_space(path: str | os.PathLike, needed: int, what: str) -> None:
    """StorageError (disk full) unless the file system of ``path`` has ``needed`` bytes (+ margin) free.

    Called before a write that allocates new space, so that HDF5 itself never meets a full disk:
    a write HDF5 cannot complete can surface later, where no caller can catch it (while an object
    is released) and crash the process at exit. A disk that another process fills meanwhile can
    still fail a write; the writers handle that too (:func:`abandon_h5`).
    """
    folder = os.path.dirname(os.path.abspath(path))
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):  # no statvfs (Windows) or a vanished folder: let the write tell
        return
    free = st.f_bavail * st.f_frsize
    if free < needed + SPACE_MARGIN:
        raise StorageError(
            errno.ENOSPC,
            f"cannot write {os.fspath(path)}: {_CAUSES[errno.ENOSPC]}: {what} needs "
            f"{(needed + SPACE_MARGIN) / 1e6:.2f} MB, {free / 1e6:.2f} MB free",
        )
