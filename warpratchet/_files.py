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
* **HDF5** (:data:`LIBVER`, :func:`sync_h5`, :func:`open_h5_reader`, :func:`open_h5`): the file
  format every writer pins, flush-and-fsync of an open file, and opening a file that another
  process may be writing (SWMR-read when the file says a writer has it open, with bounded
  retries, no raw-chunk cache).
* **Storage failures** (:func:`storage_errors`, :class:`StorageError`): a full disk, a read-only
  folder or a missing permission becomes one line naming the file and the cause.

Errors are the standard ``OSError`` subclasses with a one-line message naming the path
(``FileExistsError``, ``FileNotFoundError``, ``BlockingIOError`` for a file in use,
:class:`StorageError` for a write the system refused); callers with their own error type (e.g.
:class:`warpratchet.archive.ArchiveError`) wrap the first three.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import os
import re
import tempfile
import time
from collections.abc import Iterator
from typing import Any

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
#: HDF5 file-format bounds of every file warpratchet writes: the object formats of HDF5 1.10, the
#: oldest line that has SWMR. ``libver="latest"`` would follow the installed library (HDF5 2.0
#: object formats that the 1.10 tools of Debian and Ubuntu cannot read: "h5dump error: internal
#: error"); 1.10's formats still checksum every piece of metadata (superblock v3, object
#: headers v2, chunk indices).
LIBVER = ("v110", "v110")


def sync_h5(f: h5py.File) -> None:
    """Flush an open HDF5 file and fsync it: everything written so far is on disk."""
    f.flush()
    os.fsync(f.id.get_vfd_handle())


def abandon_h5(f: h5py.File) -> None:
    """Close an HDF5 file whose last write failed, leaving the file on disk as it stands.

    After a failed write (a full disk), HDF5 keeps the unwritten metadata dirty and retries it
    when the file is closed, which fails again; at interpreter exit the library then closes
    the file once more and crashes (exit 139, issue 13.3). Pointing HDF5's descriptor at
    ``/dev/null`` first lets the close succeed without touching the file: it keeps what the last
    successful flush wrote (for an SWMR writer, a consistent file still marked open, exactly
    what a killed writer leaves, which readers and ``resume`` handle).
    """
    with contextlib.suppress(Exception):
        if f.id.valid:
            null = os.open(os.devnull, os.O_RDWR)
            try:
                os.dup2(null, f.id.get_vfd_handle())
            finally:
                os.close(null)
            f.close()


#: Metadata read attempts of an SWMR reader. A reader may catch metadata the writer is
#: rewriting, fail its checksum and must retry; HDF5 retries 100 times backing off to 36 s a
#: try, so a *damaged* file would hang a reader for ~40 minutes. 27 attempts (doubling from
#: 1 ns) still retry a torn read for ~0.13 s, far longer than a writer's flush.
SWMR_READ_ATTEMPTS = 27


@functools.cache
def _libhdf5() -> ctypes.CDLL | None:
    """The libhdf5 that h5py uses, for the few calls h5py does not wrap; None if it cannot be
    identified (then HDF5's defaults apply)."""
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
        return ctypes.CDLL(libs[0])
    except OSError:
        return None


def _hdf5_call(name: str, argtypes: list) -> Any:
    lib = _libhdf5()
    func = getattr(lib, name, None) if lib is not None else None
    if func is not None:
        func.argtypes = argtypes
        func.restype = ctypes.c_int
    return func


def _read_attempts_setter():
    """``H5Pset_metadata_read_attempts`` (h5py does not wrap it), or None."""
    return _hdf5_call("H5Pset_metadata_read_attempts", [ctypes.c_int64, ctypes.c_uint])


def compact_links(gcpl: h5p.PropGCID, max_compact: int = 64) -> bool:
    """Keep up to ``max_compact`` links of a new group in its (checksummed) object header.

    Past 8 links HDF5 moves them to "dense" storage, a fractal heap whose blocks carry no
    checksum: a flipped bit there changes a link silently, and crashed HDF5 while listing the
    group. ``H5Pset_link_phase_change`` (h5py does not wrap it); False if unavailable.
    """
    setter = _hdf5_call("H5Pset_link_phase_change", [ctypes.c_int64, ctypes.c_uint, ctypes.c_uint])
    return setter is not None and setter(gcpl.id, max_compact, max_compact // 2) >= 0


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


#: Superblock file-consistency flags (HDF5 file format spec, superblock versions 2 and 3): a
#: writer has the file open for writing / for SWMR writing.
_WRITE_ACCESS, _SWMR_WRITE_ACCESS = 0x01, 0x04
_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def writer_marked(path: str | os.PathLike) -> bool:
    """Whether the file's superblock says a writer has it open (a live one, or a killed one).

    Read from the superblock's consistency flags (versions 2 and 3; HDF5 looks for the
    superblock at 0, 512, 1024, ...). Older superblocks carry no such mark: False.
    """
    with open(path, "rb") as fh:
        size = os.fstat(fh.fileno()).st_size
        where = 0
        while where + 12 <= size:
            fh.seek(where)
            head = fh.read(12)
            if head[:8] == _SIGNATURE:
                return head[8] >= 2 and bool(head[11] & (_WRITE_ACCESS | _SWMR_WRITE_ACCESS))
            where = 512 if where == 0 else 2 * where
    return False


def open_h5(path: str | os.PathLike, *, locking: bool | None = None) -> h5py.File:
    """Open an HDF5 file read-only, live or not: the one way readers of warpratchet files open them.

    A file that a writer has open (or that a killed writer left marked open) is opened in
    SWMR-read mode; any other normally, so that HDF5 compares its size with the superblock and
    a truncated file is an error at once. The superblock's mark decides, not a failed normal
    open: HDF5 checks a file's size *before* its mark, so a live file whose writer has just
    allocated space it has not written yet gives a false "truncated file" (issue 13.4).

    Raises
    ------
    OSError
        HDF5's error (truncated, corrupted, not HDF5, locked by a writer that has not yet
        entered SWMR mode after ~1 s of retries).
    """
    path = os.fspath(path)
    for attempt in range(20):
        try:
            return open_h5_reader(path, locking=locking, swmr=writer_marked(path))
        except OSError as exc:
            text = str(exc)
            if "SWMR read access flag not the same" in text:
                # This process is writing it: HDF5 shares the writer's handle instead.
                return h5py.File(path, "r", **({} if locking is None else {"locking": locking}))
            if "unable to lock file" in text and attempt < 19:
                time.sleep(0.05)  # another program's writer, about to enter SWMR mode
                continue
            raise
    raise AssertionError("unreachable")  # pragma: no cover


# -- storage failures ----------------------------------------------------------------------------
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
