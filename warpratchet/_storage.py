"""Storage failures as one line: a full disk, a read-only file system, a missing permission.

:func:`storage_errors` turns the ``OSError`` (or HDF5's error text) of a refused write into a
:class:`StorageError` naming the file and the cause (the CLI exits with status 1);
:func:`ensure_space` refuses a write before HDF5 meets a full disk.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import shutil
from collections.abc import Iterator
from typing import Any

from .limits import format_bytes

__all__ = [
    "StorageError",
    "STORAGE_ERRNOS",
    "storage_cause",
    "storage_errors",
    "CHUNK_BYTES",
    "SPACE_MARGIN",
    "h5_bytes",
    "dataset_bytes",
    "free_space",
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


#: HDF5's bytes beyond the raw data of one chunk: its entry in the dataset's chunk index and the
#: packing of small chunks into file-space pages. ``scripts/h5_overhead.py`` measures 20 B per
#: 512-byte chunk in a plain file and 87 B in a paged one (``warpratchet._h5.create_h5``), over
#: 1000 chunks of one dataset (h5py 3.16, HDF5 2.0, the 1.10 formats).
CHUNK_BYTES = 128

#: Free space kept beyond an estimate: HDF5 metadata the estimates leave out (chunk indices and
#: object headers growing as datasets are resized, a new 4096-byte metadata page). Over the 27
#: writes of ``run --points 10000 --steps 120000 --chunk-steps 5000 --checkpoint-every 40000
#: --snapshot-every 20000 --out``, the file grew by 3.3 kB to 19 kB more than each estimate.
SPACE_MARGIN = 64 * 1024


def h5_bytes(raw: int, chunks: int = 1) -> int:
    """The file space ``raw`` bytes of data take as ``chunks`` equal new chunks of a dataset.

    Each chunk adds its 4-byte Fletcher-32 checksum and :data:`CHUNK_BYTES`. In a paged file
    (``warpratchet._h5.create_h5``) no chunk straddles a page boundary unless it is larger than a
    page, so a chunk over half a page (``warpratchet._h5.PAGE_SIZE``) is counted in whole pages:
    no second one fits beside it (a row chunk of 256 float64, 2052 bytes with its checksum, takes a page).
    """
    from ._h5 import PAGE_SIZE  # here: every command imports this module, not every one needs h5py

    if chunks <= 0 or raw <= 0:
        return 0
    size = -(-int(raw) // chunks) + 4
    if size > PAGE_SIZE // 2:
        size = -(-size // PAGE_SIZE) * PAGE_SIZE
    return chunks * (size + CHUNK_BYTES)


def dataset_bytes(ds: Any) -> int:
    """The file space of the chunked dataset ``ds`` once every chunk is written (:func:`h5_bytes`)."""
    per_chunk = ds.dtype.itemsize * math.prod(ds.chunks)
    chunks = math.prod(-(-n // c) for n, c in zip(ds.shape, ds.chunks, strict=True))
    return h5_bytes(per_chunk * chunks, chunks)


def free_space(path: str | os.PathLike) -> int | None:
    """Bytes this user may write on the file system of ``path`` (None where that cannot be told)."""
    folder = os.path.dirname(os.path.abspath(path))
    try:
        return shutil.disk_usage(folder).free  # statvfs f_bavail: what a user other than root gets
    except OSError:  # a vanished folder: let the write tell
        return None


def ensure_space(path: str | os.PathLike, needed: int, what: str) -> None:
    """StorageError (disk full) unless the file system of ``path`` has ``needed`` bytes free.

    ``needed`` is the caller's estimate of the bytes the write adds to the file (:func:`h5_bytes`,
    :func:`dataset_bytes`); :data:`SPACE_MARGIN` more must be free: 64 KiB, three times the most
    HDF5 metadata measured beyond an estimate in one write (19 kB). Called before a write that
    allocates new space, so that HDF5 itself never meets a full disk: a write HDF5 cannot
    complete can surface later, where no caller can catch it (while an object is released) and
    crash the process at exit. A disk that another process fills meanwhile can still fail a
    write; the writers handle that too (:func:`abandon_h5`).
    """
    free = free_space(path)
    if free is not None and free < needed + SPACE_MARGIN:
        raise StorageError(
            errno.ENOSPC,
            f"cannot write {os.fspath(path)}: {_CAUSES[errno.ENOSPC]}: {what} needs an estimated "
            f"{format_bytes(needed)} (and {format_bytes(SPACE_MARGIN)} to spare), {format_bytes(free)} free",
        )
