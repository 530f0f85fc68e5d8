"""Torn row chunks of ``/history`` and ``/transport`` read like those of ``/series`` (issue 3).

A writer killed inside a row append can leave the chunk's next row on disk and its Fletcher-32
checksum old: HDF5 then refuses the whole chunk, committed rows included. ``/series`` and
``/snapshots`` read past that (``_h5verify.read_rows``, ``test_archive_kill``); so must every
group appended to the same way. ``/transport/counts`` is appended in chunks of 16 rows of 1.5
KiB, which span several pages, so a kill can tear them even in a paged archive of today.
"""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from support import same_state

from warpratchet import MapParams
from warpratchet._h5 import LIBVER, open_h5
from warpratchet.archive import Archive, ArchiveSink, _writer, run_to
from warpratchet.history import BLOCK_FIELDS, HISTORY_FIELDS, History
from warpratchet.transport import TransportEnsemble

SMALL = {"snapshot_every": 20, "snapshot_points": 8, "checkpoint_every": 40, "chunk_steps": 10}


def _live_copy(path, copy) -> None:
    """A transport run with a history archived to step 50; ``copy``: the file's bytes while open
    (what a writer killed then leaves, still marked open)."""
    ens = TransportEnsemble.sample(MapParams(3.0, 0.1, 0.01), 100, "strip", 7, threads=1)
    history = History()
    with ArchiveSink(path, ens, history=history, **SMALL) as sink:
        ens.run(50, [sink, history], chunk_steps=sink.chunk_steps)
        shutil.copy(path, copy)


def _tear(path) -> list[str]:
    """Write a next row into the stored chunk holding the last valid row of every multi-row
    ``/history`` and ``/transport`` dataset, leaving its checksum old; the datasets torn."""
    torn = []
    with open_h5(path) as f:
        counts = {
            "history": (int(f["progress/history_rows"][0]), int(f["progress/block_rows"][0])),
            "transport": (int(f["transport/rows"][0]),) * 2,
        }
        places = []
        groups = {"history": (*HISTORY_FIELDS, *BLOCK_FIELDS), "transport": ("step", "counts")}
        for group, names in groups.items():
            for name in names:
                ds = f[group][name]
                n = counts[group][name in BLOCK_FIELDS]
                per = ds.chunks[0]
                if per == 1 or n % per == 0:
                    continue  # a chunk of one row is written once; a full chunk is not rewritten
                row = int(np.prod(ds.shape[1:], dtype=np.int64)) * ds.dtype.itemsize
                info = ds.id.get_chunk_info_by_coord((n - n % per,) + (0,) * (ds.ndim - 1))
                places.append((info.byte_offset + (n % per) * row, row, ds.name))
    with open(path, "r+b") as fh:
        for offset, row, name in places:
            fh.seek(offset)
            fh.write(np.full(row // 8, 3, dtype=np.int64).tobytes())  # not the fill value
            torn.append(name)
    return torn


@pytest.mark.parametrize("space", ["unpaged", "paged"])
def test_torn_history_and_transport_chunks_read_their_committed_rows_and_resume(tmp_path, monkeypatch, space):
    """The torn file reads the committed rows of the intact copy and resumes to the same bits.
    ``unpaged``: a file as archives were written before paged file space (any row chunk tears)."""
    intact, torn = tmp_path / "intact.h5", tmp_path / "torn.h5"
    if space == "unpaged":
        monkeypatch.setattr(_writer, "create_h5", lambda p: h5py.File(p, "w", libver=LIBVER))
    _live_copy(tmp_path / "live.h5", intact)
    monkeypatch.undo()  # the resumes below write as today
    shutil.copy(intact, torn)
    names = _tear(torn)
    assert {"/transport/step", "/transport/counts", "/history/step", "/history/A"} <= set(names)
    with open_h5(torn) as f:
        for name in ("transport/counts", "history/step"):  # HDF5 refuses the chunk, committed rows and all
            with pytest.raises(OSError, match="filter returned failure"):
                f[name][:1]

    with Archive(intact) as a, Archive(torn) as b:
        want, got = a.transport, b.transport
        assert want["step"].size == 5
        for name in ("step", "counts"):
            assert np.array_equal(got[name], want[name]), name
        ha, hb = a.history, b.history
        assert len(ha.rows["step"]) > 0
        for name in HISTORY_FIELDS:
            assert np.array_equal(hb.rows[name], ha.rows[name], equal_nan=True), name
        for name in BLOCK_FIELDS:
            assert np.array_equal(np.asarray(hb.block_rows[name]), np.asarray(ha.block_rows[name])), name

    ends = []
    for path in (intact, torn):
        sink, ens = ArchiveSink.resume(path, threads=1)
        with sink:
            run_to(ens, 100, [sink, sink.history], sink.chunk_steps)
        with Archive(path) as arc:
            ends.append((ens.state(), arc.transport, arc.history.as_dict()))
    (state_a, rows_a, hist_a), (state_b, rows_b, hist_b) = ends
    assert same_state(state_a, state_b)
    assert all(np.array_equal(rows_a[k], rows_b[k]) for k in rows_a) and rows_b["step"][-1] == 100
    assert hist_a.keys() == hist_b.keys() and hist_b["step"][-1] == 100
    for name in hist_a:
        assert np.array_equal(np.asarray(hist_a[name]), np.asarray(hist_b[name]), equal_nan=True), name
