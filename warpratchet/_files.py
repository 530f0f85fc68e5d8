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
* **HDF5** (:func:`sync_h5`, :func:`open_h5_reader`): flush-and-fsync of an open file, and the
  reader options for files that another process may be writing (SWMR with bounded retries, no
  raw-chunk cache).

Errors are the standard ``OSError`` subclasses with a one-line message naming the path
(``FileExistsError``, ``FileNotFoundError``, ``BlockingIOError`` for a file in use); callers
with their own error type (e.g. :class:`warpratchet.archive.ArchiveError`) wrap them.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import re
import tempfile
from collections.abc import Iterator

import h5py
from h5py import h5f, h5p

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
    "SWMR_READ_ATTEMPTS",
    "open_h5_reader",
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
    """
    path = os.fspath(path)
    fd = os.open(path, os.O_RDONLY)
    if not try_lock(fd, exclusive=exclusive):
        os.close(fd)
        raise BlockingIOError(
            f"{path} is in use by another process (a run writing it, or a program reading it); "
            "wait for it to finish or close it"
        )
    return fd


# -- HDF5 --------------------------------------------------------------------------------------------
def sync_h5(f: h5py.File) -> None:
    """Flush an open HDF5 file and fsync it: everything written so far is on disk."""
    f.flush()
    os.fsync(f.id.get_vfd_handle())


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


def open_h5_reader(path: str | os.PathLike, *, locking: bool | None = None, swmr: bool = False) -> h5py.File:
    """Open an HDF5 file read-only for a reader that may share it with a live writer.

    ``swmr=True`` opens in SWMR-read mode with :data:`SWMR_READ_ATTEMPTS` metadata retries.
    No raw-chunk cache, so that a live reader never serves a stale chunk. ``locking`` is HDF5's
    own file locking (None: HDF5's default).

    Raises
    ------
    OSError
        HDF5's error, e.g. "already open for write" for a file a writer (or a killed one) left
        marked open, which a caller retries with ``swmr=True``.
    """
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
