"""Reading an archive safely: HDF5 failures as one line, SWMR refreshes, extents, counters and the
valid rows they count, finite states.

Shared by the reader, the writer, ``resume`` and ``verify`` of :mod:`warpratchet.archive`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import h5py
import numpy as np

from .._h5verify import chunk_past_end, first_line, read_rows, refresh
from ._format import TEXT_CHECKSUM, ArchiveError, text_checksum

__all__ = [
    "reading",
    "refresh",
    "check_extent",
    "read_counter",
    "valid_rows",
    "nonfinite",
    "listed",
    "check_text",
]


@contextlib.contextmanager
def reading(path: str, what: str) -> Iterator[None]:
    """Turn any HDF5/h5py failure while reading ``what`` into one clear :class:`ArchiveError`."""
    try:
        yield
    except ArchiveError:
        raise
    except (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError) as exc:
        raise ArchiveError(
            f"{path}: cannot read {what} ({first_line(exc)}); the archive is truncated or corrupted"
        ) from None


def check_extent(path: str, ds: h5py.Dataset, rows: int | None = None) -> None:
    """ArchiveError if a chunk of ``ds`` holding one of its first ``rows`` rows is past the end of
    the file (HDF5 would read it as zeros with a valid checksum; see ``_h5verify.chunk_past_end``)."""
    past = chunk_past_end(path, ds, rows)
    if past is not None:
        raise ArchiveError(f"{path}: {past}; the archive is truncated or corrupted")


def read_counter(path: str, f: h5py.File, where: str, *, signed: bool = False) -> int:
    """The ``(1,)`` int64 counter at ``where`` in ``f`` (``"progress/series_rows"``, ...), read afresh.

    ArchiveError if it is unreadable, past the end of the file, or negative (unless ``signed``:
    ``progress/target_step`` is -1 before a run's first target is known).
    """
    with reading(path, f"/{where}"):
        ds = refresh(f[where])
        check_extent(path, ds)
        n = int(ds[0])
    if n < 0 and not signed:
        raise ArchiveError(f"{path}: /{where} = {n} is negative; the archive is corrupted")
    return n


def valid_rows(path: str, group: h5py.Group, name: str, n: int) -> np.ndarray:
    """The first ``n`` rows of the appendable dataset ``group[name]``: the valid ones, as its
    counter says (``(n, ...)``, the dataset's dtype).

    Read afresh (a live writer may have appended since), refused if the dataset holds fewer rows
    or a chunk of them lies past the end of the file, every checksum verified; a torn append of
    a killed writer, or a rewrite a live writer is half way through, reads as
    :func:`warpratchet._h5verify.read_rows` reads it. Any failure is one :class:`ArchiveError`.
    """
    where = f"{group.name}/{name}"
    with reading(path, where):
        ds = refresh(group[name])
        if ds.shape[0] < n:
            raise ArchiveError(f"{path}: {where} has {ds.shape[0]} rows, {n} are valid")
        check_extent(path, ds, n)
        return read_rows(ds, n)


def nonfinite(state: dict[str, np.ndarray]) -> dict[str, int]:
    """How many non-finite values each field of ``state`` holds (only the fields that have some)."""
    counts = {name: int(np.size(v) - np.count_nonzero(np.isfinite(v))) for name, v in state.items()}
    return {name: c for name, c in counts.items() if c}


def listed(counts: dict[str, int]) -> str:
    """``{"dx": 766}`` as ``"766 dx"`` (several joined by commas)."""
    return ", ".join(f"{count} {field}" for field, count in counts.items())


def check_text(path: str, obj: h5py.Group, what: str) -> None:
    """ArchiveError if the string attributes of ``obj`` differ from their :data:`TEXT_CHECKSUM`
    (archives without one, written before strings were variable-length, are not checked)."""
    with reading(path, what):
        attrs = dict(obj.attrs.items())
    stored = attrs.get(TEXT_CHECKSUM)
    if stored is not None and int(stored) != text_checksum(attrs):
        raise ArchiveError(f"{path}: {what} are damaged (their checksum differs); the archive is corrupted")
