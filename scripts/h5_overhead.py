"""HDF5's file space beyond the raw data: the numbers behind the free-space estimates.

Prints, for a plain file (``h5py.File(..., libver=LIBVER)``, the sweep file) and a paged one
(``warpratchet._h5.create_h5``, the archive):

* an empty file, and what chunked, Fletcher-32 datasets add before any data (object headers);
* what the first chunk and 1000 chunks of 512 bytes take beyond their raw bytes (chunk index,
  page packing);
* what 16 row chunks of 256 float64 (2052 bytes with the checksum) take in each;
* the layout of an archive before any rows (10000 points: bare, with a history of a 4096-point
  subsample, with transport counts too) and of an empty sweep file (12 points).

``warpratchet._storage.CHUNK_BYTES``, ``warpratchet._storage.SPACE_MARGIN``,
``warpratchet.archive._writer.LAYOUT_BYTES`` and ``warpratchet.sweep._file.LAYOUT_BYTES`` cite
these numbers. Usage: ``python scripts/h5_overhead.py``.
"""

from __future__ import annotations

import os
import tempfile

import h5py
import numpy as np

from warpratchet import Ensemble, MapParams
from warpratchet._h5 import LIBVER, create_h5
from warpratchet._storage import h5_bytes
from warpratchet.archive import ArchiveSink
from warpratchet.archive._format import FILL
from warpratchet.history import History
from warpratchet.spec import SweepSpec
from warpratchet.sweep import _file as sweep_file
from warpratchet.transport import TransportEnsemble


def _plain(path: str) -> h5py.File:
    return h5py.File(path, "w", libver=LIBVER, locking=False)


def _size_after(make, path: str, fill) -> int:
    f = make(path)
    try:
        fill(f)
    finally:
        f.close()
    return os.path.getsize(path)


def _datasets(n: int):
    def fill(f):
        for i in range(n):
            f.create_dataset(f"d{i}", shape=(0,), maxshape=(None,), dtype="f8", chunks=(64,), fletcher32=True)

    return fill


def _chunks(k: int, rows: int):
    def fill(f):
        ds = f.create_dataset("d", shape=(0,), maxshape=(None,), dtype="f8", chunks=(rows,), fletcher32=True)
        ds.resize((rows * k,))
        ds[:] = 1.0

    return fill


def main() -> None:
    folder = tempfile.mkdtemp()
    path = os.path.join(folder, "x.h5")
    for name, make in (("plain", _plain), ("paged", create_h5)):
        empty = _size_after(make, path, lambda f: None)
        print(f"{name}: empty file {empty} B")
        for n in (1, 10, 40):
            extra = _size_after(make, path, _datasets(n)) - empty
            print(f"{name}:   {n:4d} empty chunked datasets add {extra:7d} B ({extra / n:.0f} B each)")
        one = _size_after(make, path, _chunks(1, 64)) - empty - 512
        many = _size_after(make, path, _chunks(1000, 64)) - empty - 512_000
        print(f"{name}:   the first chunk of 512 B takes {one} B beyond its data (the chunk index)")
        print(f"{name}:   1000 chunks of 512 B take {(many - one) / 999:.0f} B each beyond their data")
        rows = _size_after(make, path, _chunks(16, 256)) - _size_after(make, path, _chunks(1, 256))
        print(f"{name}:   a row chunk of 256 float64 (2052 B with its checksum) takes {rows / 15:.0f} B")

    params = MapParams(3.0, 0.1, 0.01)
    for label, ensemble, history in (
        ("bare", Ensemble.sample(params, 10000, "strip", 0), None),
        ("history", Ensemble.sample(params, 10000, "strip", 0), History()),
        ("transport", TransportEnsemble.sample(params, 10000, "strip", 0), History()),
    ):
        archive = os.path.join(folder, f"{label}.h5")
        initial = ensemble.views()  # the fields that are not uniform take storage
        data = sum(h5_bytes(v.nbytes) for k, v in initial.items() if np.any(v != FILL[k]))
        with ArchiveSink(archive, ensemble, history=history):
            size = os.path.getsize(archive)
        print(f"archive layout, 10000 points, {label}: {size - data} B beyond the initial state's {data} B")

    table = np.array([[3.0, 0.1, b2] for b2 in np.linspace(0.01, 0.12, 12)])
    sweep = os.path.join(folder, "sweep.h5")
    sweep_file.SweepFile(sweep, table, SweepSpec(points=50, steps=100), force=False).close()
    print(f"sweep file layout, 12 points, no records: {os.path.getsize(sweep)} B")


if __name__ == "__main__":
    main()
