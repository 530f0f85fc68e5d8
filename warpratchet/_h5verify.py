"""Checking stored HDF5 data of any warpratchet file: chunk extents and every checksum.

Used by the archive reader (:func:`chunk_past_end`, :func:`read_rows`) and by ``warpratchet
verify`` for archives and sweep files (:func:`read_everything`).
"""

from __future__ import annotations

import contextlib
import io
import os
import time

import h5py
import numpy as np
from h5py import h5d, h5s, h5z

__all__ = ["chunk_past_end", "read_rows", "read_everything", "first_line", "refresh"]


def first_line(exc: BaseException) -> str:
    """The first line of an error's text (HDF5's run over several)."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


def refresh(ds: h5py.Dataset) -> h5py.Dataset:
    """``ds`` with the metadata a live SWMR writer has flushed since (a no-op outside SWMR reads)."""
    with contextlib.suppress(Exception):  # only meaningful (and only allowed) in SWMR mode
        ds.refresh()
    return ds


def chunk_past_end(path: str, ds: h5py.Dataset, rows: int | None = None) -> str | None:
    """Why a stored chunk of ``ds`` (holding one of its first ``rows`` rows) is past the end of the
    file, or None.

    HDF5 reads past the end of a file as zeros, and a chunk of zeros carries a valid Fletcher-32
    checksum (zero). A file opened in SWMR mode (a killed writer's) skips HDF5's own size check,
    so a truncated one would give zeros as data; readers refuse them with this check. A live
    writer's file passes: its valid rows and complete checkpoints are on disk before anything
    points at them.
    """
    if ds.chunks is None:
        return None
    size = os.path.getsize(path)
    for i in range(ds.id.get_num_chunks()):
        info = ds.id.get_chunk_info(i)
        if rows is not None and info.chunk_offset[0] >= rows:
            continue
        if info.byte_offset + info.size > size:
            end = info.byte_offset + info.size
            return f"{ds.name} has data past the end of the file (byte {end} of {size})"
    return None


#: Reads of rows a live writer may be rewriting: a reader can copy a page while the writer's
#: copy into it is half done, see a chunk whose checksum fails, and must read it again.
_LIVE_READ_ATTEMPTS = 4


def read_rows(ds: h5py.Dataset, n: int) -> np.ndarray:
    """The first ``n`` rows of an appendable dataset (the valid ones), every checksum verified.

    An SWMR writer appends a row by rewriting the chunk that holds it in place. A writer killed
    inside that write (files created before :func:`warpratchet._h5.create_h5` paged their file
    space) can leave the chunk's first page new and its Fletcher-32 checksum, at the chunk's
    end, old: HDF5 then refuses the whole chunk, valid rows included. The old checksum is that
    of the chunk as the last completed write left it: the valid rows, then the fill value. So
    when the chunk holding row ``n - 1`` fails, that image is rebuilt from the stored bytes and
    HDF5 checks it against the stored checksum (:func:`_torn_tail`); the rows are returned only
    if it verifies, so a damaged row stays an error, never a changed number. A file a writer
    has open is read again a few times first (a reader may catch a rewrite half copied).

    Raises
    ------
    OSError
        HDF5's error for rows that do not verify.
    """
    swmr = ds.file.swmr_mode
    for attempt in range(_LIVE_READ_ATTEMPTS if swmr else 1):
        try:
            return ds[:n]
        except OSError:
            rows = _torn_tail(ds, n)
            if rows is not None:
                return rows
            if attempt == _LIVE_READ_ATTEMPTS - 1 or not swmr:
                raise
        time.sleep(0.001 * 2**attempt)
        ds.refresh()
    raise AssertionError("unreachable")  # pragma: no cover


def _torn_tail(ds: h5py.Dataset, n: int) -> np.ndarray | None:
    """The first ``n`` rows of ``ds`` if only the chunk holding row ``n - 1`` fails, and it is a
    torn append: its stored rows up to ``n`` with the fill value after them verify against its
    stored checksum. None otherwise (nothing to recover, or it does not verify)."""
    per = ds.chunks[0] if ds.chunks else 0
    dcpl = ds.id.get_create_plist()
    whole_rows = ds.chunks is not None and tuple(ds.chunks[1:]) == tuple(ds.shape[1:])
    fletcher_only = dcpl.get_nfilters() == 1 and dcpl.get_filter(0)[0] == h5z.FILTER_FLETCHER32
    if not (whole_rows and fletcher_only and per > 1 and 0 < n <= ds.shape[0] and n % per):
        return None  # a full last chunk was never rewritten; other layouts are not appended to
    start = n - n % per
    try:
        mask, stored = ds.id.read_direct_chunk((start,) + (0,) * (ds.ndim - 1))
        head = ds[:start]  # the chunks before it must verify as they are
    except (OSError, KeyError, RuntimeError, ValueError):
        return None
    width = int(np.prod(ds.chunks)) * ds.dtype.itemsize
    if mask != 0 or len(stored) != width + 4:
        return None
    image = np.frombuffer(stored[:width], dtype=ds.dtype).reshape(ds.chunks).copy()
    image[n - start :] = ds.fillvalue
    # The same datatype, chunking and filters as ``ds``, in memory: HDF5 itself checks the sum.
    with h5py.File(io.BytesIO(), "w") as scratch:
        space = h5s.create_simple(ds.chunks)
        check = h5d.create(scratch.id, b"chunk", ds.id.get_type(), space, dcpl=dcpl)
        check.write_direct_chunk((0,) * ds.ndim, image.tobytes() + stored[width:])
        try:
            tail = scratch["chunk"][: n - start]
        except OSError:
            return None
    return np.concatenate([head, tail])


#: Rows read at a time while verifying (bounds the memory of a 10^8-point checkpoint to ~100 MB).
_BLOCK_ELEMENTS = 1 << 24


def read_everything(f: h5py.File, path: str, problems: list[str]) -> dict[str, int]:
    """Read every attribute and every dataset of ``f`` in blocks; one problem line per damaged object.

    Returns counts: ``datasets``, ``attributes``, ``bytes`` read.
    """
    counts = {"datasets": 0, "attributes": 0, "bytes": 0}
    names: list[str] = []

    def walk(group: h5py.Group, prefix: str) -> None:
        # Links by name (H5Literate), not h5py's visit (H5Ovisit): that one also sums every
        # object's storage, walking chunk indices, and crashed HDF5 on a damaged B-tree header.
        for key in group:
            name = f"{prefix}{key}"
            names.append(name)
            obj = group.get(key, getlink=True)
            if isinstance(obj, h5py.HardLink) and isinstance(group[key], h5py.Group):
                walk(group[key], f"{name}/")

    try:
        walk(f, "")
    except (OSError, KeyError, RuntimeError) as exc:
        problems.append(f"the file's structure is damaged ({first_line(exc)})")
    for name in ["", *names]:
        where = f"/{name}"
        try:
            obj = f[name] if name else f
            for key in obj.attrs:
                obj.attrs[key]  # noqa: B018 - reading it is the check
                counts["attributes"] += 1
        except (OSError, KeyError, RuntimeError, TypeError, ValueError) as exc:
            problems.append(f"{where}: damaged metadata ({first_line(exc)})")
            continue
        if not isinstance(obj, h5py.Dataset):
            continue
        counts["datasets"] += 1
        try:
            past = chunk_past_end(path, obj)
        except (OSError, RuntimeError, ValueError) as exc:
            problems.append(f"{where}: damaged chunk index ({first_line(exc)})")
            continue
        if past is not None:
            problems.append(f"{past}: the file is truncated")
            continue
        if obj.shape == () or obj.size == 0:
            try:
                obj[()]
            except (OSError, RuntimeError, ValueError) as exc:
                problems.append(f"{where}: damaged data ({first_line(exc)})")
            continue
        rows = max(1, _BLOCK_ELEMENTS // max(1, obj.size // obj.shape[0]))
        bad = []
        for start in range(0, obj.shape[0], rows):
            try:
                block = obj[start : start + rows]
                counts["bytes"] += block.nbytes
            except (OSError, RuntimeError, ValueError) as exc:
                bad.append(f"rows {start}-{min(obj.shape[0], start + rows) - 1} ({first_line(exc)})")
        if bad:
            problems.append(f"{where}: damaged data, {'; '.join(bad)}")
    return counts
