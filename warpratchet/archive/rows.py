"""Append-only rows of an archive group (``/series``, ``/snapshots``, ``/history``) and their counter.

:meth:`Rows.put` writes the next row of every dataset (growing them :data:`ROW_CHUNK` rows at a
time), :meth:`Rows.commit` makes the rows put since the last commit valid by raising the
counter, :meth:`Rows.trim` cuts the datasets to the valid rows when the archive is closed (so a
closed archive holds exactly its rows); :func:`fill_rows` puts a rebuilt archive's kept rows
in at once. Rows are written with low-level HDF5 calls: h5py's indexing costs more per call
than a short chunk's kernel time (benchmarks/README.md, archive_overhead.py).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import h5py
import numpy as np
from h5py import h5s

from .._files import h5_bytes
from .layout import ROW_CHUNK

__all__ = ["Rows", "set_counter", "fill_rows"]


def set_counter(ds: h5py.Dataset, value: int) -> None:
    """Write a ``(1,)`` int64 counter (low-level: no h5py indexing machinery per chunk)."""
    ds.id.write(h5s.ALL, h5s.ALL, np.array([value], dtype=np.int64))


def fill_rows(group: h5py.Group, rows: Mapping[str, Any], counter: h5py.Dataset) -> None:
    """Put ``rows`` (name: its values, ``(n, ...)``, the same ``n`` for every name) into the empty
    datasets of a freshly created ``group`` and set ``counter`` to ``n`` (a rebuilt archive)."""
    n = 0
    for name, values in rows.items():
        ds = group[name]
        values = np.asarray(values, dtype=ds.dtype)
        n = len(values)
        if n:
            ds.resize(n, axis=0)
            ds[...] = values.reshape(ds.shape)
    set_counter(counter, n)


class Rows:
    """The datasets ``names`` of ``group``, whose first ``count`` rows are valid (``counter``)."""

    def __init__(self, group: h5py.Group, names: Sequence[str], counter: h5py.Dataset, count: int) -> None:
        self.datasets = {name: group[name] for name in names}
        self.dtypes = {name: ds.dtype for name, ds in self.datasets.items()}
        self.row_shapes = {name: ds.shape[1:] for name, ds in self.datasets.items()}
        self.capacity = min(ds.shape[0] for ds in self.datasets.values())
        self.counter = counter
        self.count = count
        self.staged = 0  # rows put since the last commit

    def put(self, row: dict[str, Any]) -> None:
        index = self.count + self.staged
        if index >= self.capacity:
            self.capacity = index + ROW_CHUNK
            for ds in self.datasets.values():
                ds.resize(self.capacity, axis=0)
        for name, value in row.items():
            shape = (1, *self.row_shapes[name])
            values = np.ascontiguousarray(value, dtype=self.dtypes[name]).reshape(shape)
            ds = self.datasets[name]
            space = ds.id.get_space()
            space.select_hyperslab((index,) + (0,) * (len(shape) - 1), shape)
            ds.id.write(h5s.create_simple(shape), space, values)
        self.staged += 1

    def growth_bytes(self, rows: int = 1) -> int:
        """File space of the new chunks the next ``rows`` :meth:`put` calls allocate (HDF5 allocates a
        chunk at its first write; :func:`~warpratchet._storage.h5_bytes`)."""
        first = self.count + self.staged
        return sum(
            h5_bytes(ds.dtype.itemsize * int(np.prod(ds.chunks)))
            * sum((first + k) % ds.chunks[0] == 0 for k in range(rows))
            for ds in self.datasets.values()
        )

    def commit(self) -> None:
        """Declare the rows put since the last commit valid (call after flushing them)."""
        self.count += self.staged
        self.staged = 0
        set_counter(self.counter, self.count)

    def trim(self) -> None:
        """Cut every dataset to the valid rows (a reader reads at most ``count`` rows anyway)."""
        if self.capacity != self.count:
            for ds in self.datasets.values():
                ds.resize(self.count, axis=0)
            self.capacity = self.count
