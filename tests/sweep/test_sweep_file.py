"""The sweep file of format v2: checksums, --force that refuses a file in use and replaces atomically,
reading while a sweep writes (issue 13 items 2, 4, 5)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import h5py
import numpy as np
import pytest
from support import flip_sample, sweep_flip_census

from warpratchet import sweep as sweep_module
from warpratchet.cli import main
from warpratchet.errors import FileFormatError
from warpratchet.sweep import ROW_FIELDS, SweepSpec, maximal_path, read_sweep, run_sweep
from warpratchet.sweep._file import SweepFile

SPEC = SweepSpec(points=60, steps=200, seed=2)
POINTS = maximal_path([0.01, 0.05, 0.1])


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    path = tmp_path_factory.mktemp("sweep") / "sweep.h5"
    rows = run_sweep(POINTS, SPEC, out=path, progress=False)
    return path, rows


def test_every_dataset_is_checksummed_and_described(finished):
    with h5py.File(finished[0], "r") as f:
        assert f.attrs["format_version"] == 2
        for name in ("parameters", "rows", "rows_valid"):
            assert f[name].fletcher32 and f[name].attrs["units"] and f[name].attrs["long_name"], name
        assert len(f["rows"].attrs["column_units"]) == len(f["rows"].dtype.names)


def test_a_column_reads_as_the_archive_dataset_of_the_same_name(finished, tmp_path):
    """One concept, one wording (glossary.py): A, A_stderr, lyapunov, ... of a sweep's rows and
    of an archive's /series carry the same units and long_name in the files themselves."""
    from warpratchet import Ensemble, MapParams
    from warpratchet.spec import attr_value

    archive = tmp_path / "run.h5"
    Ensemble.sample(MapParams(K=3.0, b1=0.1, b2=0.01), 64, "strip", seed=1).run(100, archive=archive)
    with h5py.File(finished[0], "r") as sweep, h5py.File(archive, "r") as arc:
        rows = sweep["rows"]
        columns = dict(
            zip(
                rows.dtype.names,
                zip(rows.attrs["column_units"], rows.attrs["column_long_names"], strict=True),
                strict=True,
            )
        )
        shared = sorted(set(columns) & set(arc["series"]))
        assert {"A", "A_stderr", "lyapunov", "chaotic_fraction"} <= set(shared)
        for name in shared:
            units, long_name = (value.decode() for value in columns[name])
            stored = arc["series"][name].attrs
            assert (units, long_name) == (attr_value(stored["units"]), attr_value(stored["long_name"])), name


def test_flipped_bits_never_change_a_reported_number(finished, tmp_path):
    """Single-bit flips over the file (the rows more densely): an error, or the same rows.

    A deterministic sample: every 101st byte of the rows' records (each field and bit position
    in turn), every 1/32 of the file, and one byte of every checksummed dataset
    (``support.flip_sample``). The full census, every byte of the same file, is
    ``python scripts/flip_census.py sweep`` (exit 1 on any failure).
    """
    path, rows = finished
    with h5py.File(path, "r") as f:
        info = f["rows"].id.get_chunk_info(0)
        start, length = info.byte_offset, info.size
    dense = range(start, start + length, 101)
    offsets = sorted(set(dense) | set(flip_sample(path, os.path.getsize(path) // 32)))
    outcomes = sweep_flip_census(path, offsets, tmp_path)
    silent = outcomes.pop("silent")
    print(f"{len(offsets)} flips: {outcomes}")
    assert silent == [], f"flips at these bytes changed a row silently: {silent}"
    # Every flip inside the stored records is caught by their checksum.
    assert outcomes["error"] >= len([o for o in offsets if start <= o < start + length])


def test_force_refuses_a_file_another_sweep_is_writing(tmp_path, capsys):
    path = tmp_path / "busy.h5"
    other = SweepSpec(points=60, steps=300, seed=2)
    writer = SweepFile(path, np.array([[p.K, p.b1, p.b2] for p in POINTS]), SPEC, force=False)
    try:
        before = path.read_bytes()
        with pytest.raises(FileFormatError, match="in use by another process"):
            run_sweep(POINTS, other, out=path, progress=False, force=True)
        with pytest.raises(FileFormatError, match="in use by another process"):
            run_sweep(POINTS, SPEC, out=path, progress=False)  # a second sweep of the same file too
        argv = ["sweep", "--path", "maximal", "--b2", "0.01:0.1:3", "--points", "60", "--steps", "300"]
        assert main([*argv, "--seed", "2", "--out", str(path), "--force", "--quiet"]) == 2
        assert "in use by another process" in capsys.readouterr().err
        assert path.read_bytes() == before
    finally:
        writer.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["busy.h5"]


def test_force_replaces_atomically(finished, tmp_path, monkeypatch):
    path = tmp_path / "old.h5"
    path.write_bytes(finished[0].read_bytes())
    before = path.read_bytes()
    other = SweepSpec(points=60, steps=300, seed=2)

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(sweep_module._file, "publish", fail)
    with pytest.raises(OSError, match="disk full"):
        run_sweep(POINTS, other, out=path, progress=False, force=True)
    assert path.read_bytes() == before  # the old file stays until its replacement exists
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.h5"]
    monkeypatch.undo()
    rows = run_sweep(POINTS, other, out=path, progress=False, force=True)
    assert read_sweep(path) == rows and rows[0]["steps"] == 300
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.h5"]


def test_read_sweep_while_a_sweep_writes(tmp_path):
    """Reads of a live sweep file: every read gives complete rows, never an error (SWMR).

    The writer waits after each row until the reader has seen it (a marker file per row count),
    so the reads interleave with every one of the 12 writes however the machine schedules them.
    """
    path = tmp_path / "live.h5"
    script = textwrap.dedent(
        f"""
        import os, time
        from warpratchet.sweep import SweepSpec, _file, maximal_path, run_sweep
        written = 0
        real_append = _file.SweepFile.append
        def append(self, row):
            global written
            real_append(self, row)
            written += 1
            while not os.path.exists({str(path)!r} + f".seen{{written}}"):  # the reader's turn
                time.sleep(0.005)
        _file.SweepFile.append = append
        run_sweep(maximal_path([0.01 + 0.005 * i for i in range(12)]), SweepSpec(points=300, steps=2000),
                  out={str(path)!r}, progress=False)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", script], stderr=subprocess.PIPE, text=True)
    seen = set()
    try:
        while proc.poll() is None:
            if path.exists():
                rows = read_sweep(path)
                assert all(len(row) == len(ROW_FIELDS) == 25 and row["steps"] == 2000 for row in rows)
                seen.add(len(rows))
                (tmp_path / f"live.h5.seen{len(rows)}").touch()
            time.sleep(0.002)
    except BaseException:
        proc.kill()  # the writer would wait for this reader's next marker
        raise
    finally:
        _, err = proc.communicate(timeout=900)
    assert proc.returncode == 0, err
    assert len(read_sweep(path)) == 12
    assert set(range(1, 13)) <= seen, seen
