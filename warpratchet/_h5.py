"""HDF5 files of warpratchet: the file format every writer pins, and opening files a writer may have open.

* :data:`LIBVER`: HDF5 1.10 object formats (readable by HDF5 1.10 tools, SWMR-capable, every
  piece of metadata checksummed); :func:`compact_links` keeps a group's links in its
  checksummed header; :func:`create_h5` creates a file whose in-place rewrites a SIGKILL
  cannot tear (paged file space, :data:`PAGE_SIZE`).
* :func:`sync_h5`: flush and fsync; :func:`abandon_h5`: close a file whose write failed without
  touching it again.
* :func:`open_h5`: read-only, in SWMR-read mode when the superblock says a writer has the file
  open (:func:`writer_marked`), with bounded metadata retries (:func:`open_h5_reader`).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import re
import time
from typing import Any

import h5py
from h5py import h5f, h5p

__all__ = [
    "LIBVER",
    "PAGE_SIZE",
    "create_h5",
    "sync_h5",
    "abandon_h5",
    "SWMR_READ_ATTEMPTS",
    "compact_links",
    "open_h5_reader",
    "writer_marked",
    "open_h5",
]

#: HDF5 file-format bounds of every file warpratchet writes: the object formats of HDF5 1.10, the
#: oldest line that has SWMR. ``libver="latest"`` would follow the installed library (HDF5 2.0
#: object formats that the 1.10 tools of Debian and Ubuntu cannot read: "h5dump error: internal
#: error"); 1.10's formats still checksum every piece of metadata (superblock v3, object
#: headers v2, chunk indices).
LIBVER = ("v110", "v110")

#: File-space page of the files an SWMR writer appends to (HDF5 "paged aggregation"), bytes.
#: An SWMR writer rewrites data in place: the chunk of rows being appended to, the counters,
#: and the metadata (object headers, chunk indices). Linux copies a write(2) into the page cache
#: one page at a time and lets a SIGKILL end it between two pages, so a write straddling a page
#: boundary can be torn: a chunk's new rows land, its Fletcher-32 checksum (in the next page)
#: does not, and every row of the chunk fails to read (the CI failure of test_archive_kill).
#: With paged file space every object smaller than a page lies inside one aligned page, so its
#: rewrite is one page copy that a kill cannot split; 4096 bytes is the smallest page of the
#: systems we run on (a larger page holds whole 4096-byte pages). Objects larger than a page
#: are page-aligned but span pages: a writer must not rewrite one holding valid data in place.
PAGE_SIZE = 4096


def create_h5(path: str | os.PathLike) -> h5py.File:
    """Create (truncate) ``path`` for an SWMR writer: :data:`LIBVER` formats, paged file space.

    Paged aggregation (HDF5 >= 1.10.1 reads it; the 1.10 tools print it) packs objects smaller
    than :data:`PAGE_SIZE` into pages they never straddle, so a SIGKILL leaves each of them as
    it was before or after its last rewrite, never half of each. Free space is not persisted
    (an SWMR writer never frees any). Where the libhdf5 cannot be called directly (not Linux),
    :func:`abandon_h5` could not close a paged file, and the file space is HDF5's default.

    The root group keeps up to 64 links and attributes in its checksummed object header, as
    every group of an archive does (``archive._format``): past 8 HDF5 would move them to an
    unchecksummed fractal heap, and an archive's root carries its CF global attributes.
    """
    fapl = h5p.create(h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5f.LIBVER_V110, h5f.LIBVER_V110)  # LIBVER
    fcpl = h5p.create(h5p.FILE_CREATE)
    if _file_info_getter() is not None:
        fcpl.set_file_space_strategy(h5f.FSPACE_STRATEGY_PAGE, False, 1)
        fcpl.set_file_space_page_size(PAGE_SIZE)
    fcpl.set_attr_phase_change(64, 32)
    compact_links(fcpl)
    return h5py.File(h5f.create(os.fsencode(path), h5f.ACC_TRUNC, fapl=fapl, fcpl=fcpl))


def sync_h5(f: h5py.File) -> None:
    """Flush an open HDF5 file and fsync it: everything written so far is on disk."""
    f.flush()
    os.fsync(f.id.get_vfd_handle())


def abandon_h5(f: h5py.File) -> None:
    """Close an HDF5 file whose last write failed, leaving the file on disk as it stands.

    After a failed write (a full disk), HDF5 keeps the unwritten metadata dirty and retries it
    when the file is closed, which fails again; at interpreter exit the library then closes
    the file once more and crashes (exit 139). Pointing HDF5's descriptor at a
    scratch file in memory first (``memfd``; ``/dev/null`` where there is none) lets the close
    succeed without touching the file: it keeps what the last successful flush wrote (for an
    SWMR writer, a consistent file still marked open, exactly what a killed writer leaves,
    which readers and ``resume`` handle). The scratch file must take the close's writes and the
    ``ftruncate`` to the allocated size that a paged file (:func:`create_h5`) needs; its reads
    are zeros, so the one object that close reads, the superblock extension (it rewrites the
    file-space message there), is loaded into HDF5's cache beforehand (``H5Fget_info2``).
    """
    with contextlib.suppress(Exception):
        if f.id.valid:
            file_info = _file_info_getter()
            if file_info is not None:
                file_info(f.id.id, ctypes.create_string_buffer(1024))  # >= sizeof(H5F_info2_t)
            memfd = getattr(os, "memfd_create", None)
            scratch = memfd("abandoned-hdf5") if memfd is not None else os.open(os.devnull, os.O_RDWR)
            try:
                os.dup2(scratch, f.id.get_vfd_handle())
            finally:
                os.close(scratch)
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


def _file_info_getter():
    """``H5Fget_info2`` (h5py does not wrap it), or None."""
    return _hdf5_call("H5Fget_info2", [ctypes.c_int64, ctypes.c_void_p])


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


#: HDF5 file-locking settings ``(use locking, ignore where the file system has none)``, in the
#: order :func:`open_h5` tries them when this process already has the file open with other
#: settings: HDF5's default first, then h5py's ``locking=False``, ``True`` and ``"best-effort"``.
_LOCKINGS: tuple[tuple[bool, bool] | None, ...] = (None, (False, False), (True, False), (True, True))


def open_h5_reader(
    path: str | os.PathLike, *, locking: bool | tuple[bool, bool] | None = None, swmr: bool = False
) -> h5py.File:
    """Open an HDF5 file read-only for a reader that may share it with a live writer.

    ``swmr=True`` opens in SWMR-read mode with :data:`SWMR_READ_ATTEMPTS` metadata retries.
    No raw-chunk cache, so that a live reader never serves a stale chunk. ``locking`` is HDF5's
    own file locking (None: HDF5's default; a bool ignores file systems without locks; a pair
    ``(use, ignore_when_disabled)`` is passed as it is).

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
        use, ignore = (locking, True) if isinstance(locking, bool) else locking
        fapl.set_file_locking(use, ignore)
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


def _open_beside(path: str, locking: bool | None, swmr: bool) -> h5py.File:
    """:func:`open_h5_reader`; if this process already has the file open with other locking
    settings (a notebook's own ``h5py.File``), HDF5 refuses a second handle whose settings differ
    ("file locking flag values don't match"): then the settings it has are found and used."""
    try:
        return open_h5_reader(path, locking=locking, swmr=swmr)
    except OSError as exc:
        if "flag values don't match" not in str(exc) or locking is not None:
            raise
        for other in _LOCKINGS[1:]:
            with contextlib.suppress(OSError):
                return open_h5_reader(path, locking=other, swmr=swmr)
        raise


def open_h5(path: str | os.PathLike, *, locking: bool | None = None) -> h5py.File:
    """Open an HDF5 file read-only, live or not: the one way readers of warpratchet files open them.

    A file that a writer has open (or that a killed writer left marked open) is opened in
    SWMR-read mode; any other normally, so that HDF5 compares its size with the superblock and
    a truncated file is an error at once. The superblock's mark decides, not a failed normal
    open: HDF5 checks a file's size *before* its mark, so a live file whose writer has just
    allocated space it has not written yet gives a false "truncated file".

    Locking. ``locking=None`` (the default) opens with HDF5's default file locking, like any
    ``h5py.File``; beside a handle this process already holds with other settings it takes
    those; and where a writer's lock refuses it for ~1 s (another program's writer that has not
    entered SWMR mode yet, or a lock this process holds itself) it reads without locking, as
    SWMR readers may. ``locking=False`` reads without HDF5's locks from the start (callers that
    hold their own ``flock`` claim on the file).

    Raises
    ------
    OSError
        HDF5's error (truncated, corrupted, not HDF5; with ``locking=True``, locked by a writer
        that has not yet entered SWMR mode after ~1 s of retries).
    """
    path = os.fspath(path)
    for attempt in range(20):
        try:
            return _open_beside(path, locking, swmr=writer_marked(path))
        except OSError as exc:
            text = str(exc)
            if "SWMR read access flag not the same" in text:
                # This process is writing it: HDF5 shares the writer's handle instead.
                return h5py.File(path, "r", **({} if locking is None else {"locking": locking}))
            if "unable to lock file" in text and attempt < 19:
                time.sleep(0.05)  # another program's writer, about to enter SWMR mode
                continue
            if "unable to lock file" in text and locking is None:
                return open_h5_reader(path, locking=False, swmr=writer_marked(path))
            raise
    raise AssertionError("unreachable")  # pragma: no cover
