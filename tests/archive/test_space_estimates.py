"""Free-space checks estimate the bytes an operation adds, not a multiple of the file.

The free space is faked by replacing ``shutil.disk_usage``, the one call that reads it. A small
sweep fits in 256 KiB, resuming a 7.5 MiB archive fits in 7.93 MB, and an operation that
genuinely lacks the space is refused before it writes anything, in one line naming the estimate
and the free space, with the user's file untouched.
"""

from __future__ import annotations

import collections
import os
import re
import shutil

import pytest
from support import MAP_FLAGS, no_temporaries

from warpratchet import Ensemble, MapParams, open_archive
from warpratchet.archive import ArchiveSink
from warpratchet.cli import main
from warpratchet.limits import format_bytes
from warpratchet.sweep import read_sweep

Usage = collections.namedtuple("Usage", "total used free")
SWEEP = ["sweep", "--path", "maximal", "--points", "50", "--steps", "100", "--quiet"]
SWEEP12 = [*SWEEP, "--b2", "0.01:0.12:12"]
UNITS = {"B": 1, "KiB": 1024, "MiB": 1024**2, "GiB": 1024**3}


def _free(monkeypatch, free: int) -> None:
    monkeypatch.setattr(shutil, "disk_usage", lambda path: Usage(10**12, 10**12 - free, free))


def _refusal(err: str, path) -> int:
    """The one line of a refusal for lack of space; returns the estimate it names, in bytes."""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warpratchet: error: cannot "), err
    line = lines[0]
    assert str(path) in line and "disk full" in line, line
    size = r"([0-9.]+) (B|KiB|MiB|GiB)"
    match = re.search(rf"needs an estimated {size} .*, {size} free", line)
    assert match, line
    return round(float(match[1]) * UNITS[match[2]])


def test_a_12_point_sweep_fits_in_256_kib(tmp_path, monkeypatch, capsys):
    out = tmp_path / "sweep.h5"
    _free(monkeypatch, 256 * 1024)
    assert main([*SWEEP12, "--out", str(out)]) == 0, capsys.readouterr().err
    assert len(read_sweep(out)) == 12


def test_the_sweep_estimate_covers_the_file_it_writes(tmp_path, monkeypatch, capsys):
    out = tmp_path / "sweep.h5"
    _free(monkeypatch, 0)
    assert main([*SWEEP12, "--out", str(out)]) == 1
    estimate = _refusal(capsys.readouterr().err, out)
    assert not out.exists()
    no_temporaries(tmp_path)
    monkeypatch.undo()
    assert main([*SWEEP12, "--out", str(out)]) == 0
    written = os.path.getsize(out)
    # Three significant digits in the line: the estimate is within 0.5% of what it prints.
    assert written <= estimate * 1.005, (written, estimate)
    assert estimate <= 2 * written, (written, estimate)


@pytest.fixture(scope="module")
def archive_7_5_mib(tmp_path_factory):
    """An archive of 7.5 MiB (22000 points, both checkpoint slots used, a history), with its bytes."""
    path = tmp_path_factory.mktemp("space") / "big.h5"
    argv = ["run", *MAP_FLAGS, "--points", "22000", "--steps", "2000", "--chunk-steps", "500"]
    assert main([*argv, "--checkpoint-every", "1000", "--quiet", "--out", str(path)]) == 0
    assert 7.5 * 1024**2 <= os.path.getsize(path) <= 7.93e6, os.path.getsize(path)
    return path, path.read_bytes()


def _copy(archive, folder):
    path = folder / "run.h5"
    path.write_bytes(archive[1])
    return path


def test_resume_of_a_7_5_mib_archive_with_7_93_mb_free(archive_7_5_mib, tmp_path, monkeypatch, capsys):
    path = _copy(archive_7_5_mib, tmp_path)
    _free(monkeypatch, 7_930_000)
    assert main(["resume", str(path), "--steps", "4000", "--quiet"]) == 0, capsys.readouterr().err
    with open_archive(path) as arc:
        assert arc.checkpoint_step == 4000


def test_the_resume_estimate_covers_the_rebuilt_copy(archive_7_5_mib, tmp_path, monkeypatch, capsys):
    path = _copy(archive_7_5_mib, tmp_path)
    _free(monkeypatch, 1_000_000)
    assert main(["resume", str(path), "--steps", "4000", "--quiet"]) == 1
    estimate = _refusal(capsys.readouterr().err, path)
    assert path.read_bytes() == archive_7_5_mib[1]  # nothing the user had is lost
    no_temporaries(tmp_path)
    monkeypatch.undo()
    sink, _ = ArchiveSink.resume(path)
    try:
        rebuilt = os.path.getsize(path)  # the copy that existed beside the old file
    finally:
        sink.close()
    assert rebuilt <= estimate * 1.005, (rebuilt, estimate)
    assert estimate <= 1.5 * rebuilt, (rebuilt, estimate)


def test_a_run_without_room_for_its_initial_state_is_refused_before_it_starts(tmp_path, monkeypatch, capsys):
    out = tmp_path / "run.h5"
    _free(monkeypatch, 100_000)  # 20000 points: 0.48 MB of initial state beyond fill values
    argv = ["run", *MAP_FLAGS, "--points", "20000", "--steps", "200", "--quiet", "--out", str(out)]
    assert main(argv) == 1
    estimate = _refusal(capsys.readouterr().err, out)
    assert estimate >= 3 * 20000 * 8  # x, q, p0 are not fill values
    assert not out.exists()
    no_temporaries(tmp_path)


def test_a_sweep_without_room_keeps_the_finished_points(tmp_path, monkeypatch, capsys):
    out = tmp_path / "sweep.h5"
    three = [*SWEEP, "--b2", "0.01:0.1:3"]
    assert main([*three, "--out", str(out)]) == 0
    before = out.read_bytes()
    _free(monkeypatch, 4096)
    assert main([*SWEEP12, "--out", str(out), "--force"]) == 1
    _refusal(capsys.readouterr().err, out)
    assert out.read_bytes() == before
    no_temporaries(tmp_path)


def test_the_line_names_estimate_and_free_space(tmp_path, monkeypatch):
    from warpratchet._storage import StorageError, ensure_space

    _free(monkeypatch, 5000)
    with pytest.raises(StorageError) as info:
        ensure_space(tmp_path / "x.h5", 123_456, "the checkpoint")
    line = str(info.value)
    assert f"the checkpoint needs an estimated {format_bytes(123_456)}" in line
    assert f"{format_bytes(5000)} free" in line


def test_an_ensemble_archive_estimate_covers_the_checkpoint(tmp_path, monkeypatch):
    """A checkpoint's first use of a slot is refused when the slot does not fit, with the archive kept."""
    out = tmp_path / "run.h5"
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 20000, "strip", 0)
    with ArchiveSink(out, ens, chunk_steps=100) as sink:
        _free(monkeypatch, 200_000)  # the rows fit, a 1.1 MB slot does not
        with pytest.raises(OSError, match="the checkpoint needs an estimated"):
            ens.run(100, [sink], chunk_steps=sink.chunk_steps)
    monkeypatch.undo()
    with open_archive(out) as arc:
        assert arc.checkpoint_step == 0
