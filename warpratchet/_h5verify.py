"""Checking stored HDF5 data of any warpratchet file: chunk extents and every checksum.

Used by the archive reader (:func:`chunk_past_end`) and by ``warpratchet verify`` for archives
and sweep files (:func:`read_everything`).
"""

from __future__ import annotations

import os

import h5py

__all__ = ["chunk_past_end", "read_everything", "first_line"]


def first_line(exc: BaseException) -> str:
    """The first line of an error's text (HDF5's run over several)."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


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
