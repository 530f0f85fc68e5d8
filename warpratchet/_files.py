"""File safety shared by every writer of warpratchet: the one implementation of each mechanism.

* **New paths** (:func:`check_new_path`): a writer never overwrites a file unless asked to, and
  fails before any work when the folder is missing.
* **Atomic publication** (:func:`temporary_beside`, :func:`publish`): a new file is built under
  a temporary name in the same folder (same filesystem, so the rename is atomic), made durable,
  then given its name with ``link`` (which refuses to clobber a file that appeared meanwhile) or
  ``rename`` (to replace one), and the folder is fsynced so that the name survives a power cut.
  A path therefore never holds half a file. A kill between the two steps can leave the
  temporary ``.NAME.XXXX.tmp`` behind; nothing else.
* **Advisory locks** (:func:`try_lock`, :func:`claim`): ``flock`` on a descriptor; a writer holds
  a shared lock, and whoever replaces or rebuilds a file needs an exclusive one, so a file that
  a live process uses is never touched.
* **HDF5** (:data:`LIBVER`, :func:`sync_h5`, :func:`open_h5_reader`, :func:`open_h5`, in
  :mod:`warpratchet._h5`): the file format every writer pins, flush-and-fsync of an open file,
  and opening a file that another process may be writing (SWMR-read when the file says a writer
  has it open, with bounded retries, no raw-chunk cache).
* **Storage failures** (:func:`storage_errors`, :class:`StorageError`, :func:`ensure_space`, in
  :mod:`warpratchet._storage`): a full disk, a read-only folder or a missing permission becomes
  one line naming the file and the cause.

Errors are the standard ``OSError`` subclasses with a one-line message naming the path
(``FileExistsError``, ``FileNotFoundError``, ``BlockingIOError`` for a file in use,
:class:`StorageError` for a write the system refused); callers with their own error type (e.g.
:class:`warpratchet.archive.ArchiveError`) wrap the first three.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator

# The HDF5 side and the storage failures live in modules of their own; their names are
# re-exported here, where every writer has always found them.
from ._h5 import (
    LIBVER,
    SWMR_READ_ATTEMPTS,
    abandon_h5,
    compact_links,
    open_h5,
    open_h5_reader,
    sync_h5,
    writer_marked,
)
from ._storage import (
    SPACE_MARGIN,
    StorageError,
    dataset_bytes,
    ensure_space,
    h5_bytes,
    storage_cause,
    storage_errors,
)

try:  # advisory locks; absent on Windows, where files are simply not locked
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None

__all__ = [
    "check_new_path",
    "temporary_beside",
    "publish",
    "fsync_dir",
    "try_lock",
    "claim",
    "sync_h5",
    "LIBVER",
    "SWMR_READ_ATTEMPTS",
    "open_h5_reader",
    "compact_links",
    "writer_marked",
    "open_h5",
    "StorageError",
    "storage_errors",
    "abandon_h5",
    "SPACE_MARGIN",
    "ensure_space",
    "h5_bytes",
    "dataset_bytes",
    "storage_cause",
]


# -- new paths and atomic publication ----------------------------------------------------------------
def check_new_path(path: str | os.PathLike, *, force: bool = False, hint: str = "") -> bool:
    """Check that ``path`` may be created: its folder exists, and nothing is there unless ``force``.

    Parameters
    ----------
    path : str or PathLike
        The file to be written.
    force : bool
        Allow an existing *regular file* to be replaced (the caller replaces it atomically).
    hint : str
        Appended to the "exists" message, e.g. ``" (use force=True / --force)"``.

    Returns
    -------
    bool
        Whether ``path`` exists (only possible with ``force``).

    Raises
    ------
    FileNotFoundError
        The folder does not exist.
    FileExistsError
        ``path`` exists (a dangling symlink counts) and ``force`` is false, or it is not a
        regular file.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"{path}: the folder {folder} does not exist")
    exists = os.path.lexists(path)
    if exists and not force:
        raise FileExistsError(f"{path} exists; refusing to overwrite it{hint}")
    if exists and not os.path.isfile(path):
        raise FileExistsError(f"{path} exists and is not a regular file")
    return exists


@contextlib.contextmanager
def temporary_beside(path: str | os.PathLike) -> Iterator[str]:
    """An empty file ``.NAME.XXXX.tmp`` next to ``path``, removed again if the block raises.

    It has the permissions a plain ``open()`` would give (``mkstemp`` makes files private).
    Give it its name with :func:`publish` inside the block.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".tmp", dir=folder)
    os.close(fd)
    try:
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        yield tmp
    except BaseException:
        with contextlib.suppress(OSError):  # already published (renamed), or never made
            os.unlink(tmp)
        raise


def publish(tmp: str, path: str | os.PathLike, *, replace: bool) -> None:
    """Give the complete file ``tmp`` the name ``path`` atomically, then fsync the folder.

    The caller makes ``tmp``'s contents durable first (fsync); otherwise a power cut could
    leave the name pointing at an empty file.

    Parameters
    ----------
    replace : bool
        Atomically replace an existing ``path`` (``rename``). Otherwise ``link``, which fails if
        a file appeared at ``path`` since it was checked (on filesystems without hard links:
        check, then rename).

    Raises
    ------
    FileExistsError
        ``replace`` is false and ``path`` exists.
    """
    path = os.fspath(path)
    if replace:
        os.replace(tmp, path)
    else:
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise FileExistsError(f"{path} exists; refusing to overwrite it") from None
        except OSError:  # no hard links on this filesystem
            if os.path.lexists(path):
                raise FileExistsError(f"{path} exists; refusing to overwrite it") from None
            os.rename(tmp, path)
        else:
            os.unlink(tmp)
    fsync_dir(path)


def fsync_dir(path: str | os.PathLike) -> None:
    """fsync the folder holding ``path``, so that a new or renamed entry survives a power cut."""
    with contextlib.suppress(OSError):  # not every filesystem lets a directory be fsynced
        fd = os.open(os.path.dirname(os.path.abspath(path)) or ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


# -- advisory locks ------------------------------------------------------------------------------
def try_lock(fd: int, *, exclusive: bool) -> bool:
    """Try an advisory ``flock`` on ``fd`` (never blocks); True if held (or locking is unavailable)."""
    if fcntl is None:  # pragma: no cover
        return True
    try:
        fcntl.flock(fd, (fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH) | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError:  # filesystems without flock: no protection, but no failure either
        return True
    return True


def claim(path: str | os.PathLike, *, exclusive: bool) -> int:
    """Open ``path`` read-only and lock it; returns the descriptor (close it to release).

    Raises
    ------
    BlockingIOError
        Another process holds a conflicting lock (a run writing the file, or a reader).
    FileExistsError
        ``path`` is not a regular file (a FIFO, a device, a folder).
    """
    path = os.fspath(path)
    # Non-blocking: opening a FIFO for reading would wait for a writer forever.
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise FileExistsError(f"{path} exists and is not a regular file")
    if not try_lock(fd, exclusive=exclusive):
        os.close(fd)
        raise BlockingIOError(
            f"{path} is in use by another process (a run writing it, or a program reading it); "
            "wait for it to finish or close it"
        )
    return fd
