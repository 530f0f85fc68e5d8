"""Disk full, read-only folders, permissions (issue 13.3): one line naming the file and the cause,
exit status 1 (not 139, no traceback), no temporary file left, the partial archive resumable.

Two ways: a real small tmpfs where this process may mount one (root; skipped with the reason
elsewhere), and an ``OSError(ENOSPC)`` injected at each write site, everywhere.
"""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import uuid

import numpy as np
import pytest
from support import MAP_FLAGS, cli, no_temporaries

from warpratchet import Ensemble, MapParams, open_archive, summarize
from warpratchet.archive import ArchiveSink, _format, _recovery, _rows
from warpratchet.cli import main
from warpratchet.sweep import _file as sweep_file
from warpratchet.sweep import read_sweep

POINTS, SEED = 20_000, 3  # 56 B per point: a checkpoint slot is 1.1 MB
RUN = ["run", *MAP_FLAGS, "--points", str(POINTS), "--seed", str(SEED), "--chunk-steps", "100"]
RUN += ["--checkpoint-every", "200", "--quiet", "--json"]
SWEEP = ["sweep", "--path", "maximal", "--b2", "0.01:0.1:3", "--points", "50", "--steps", "100", "--quiet"]


def _one_line_disk_error(proc_or_err: str, path) -> None:
    lines = proc_or_err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warpratchet: error: cannot "), proc_or_err
    assert str(path) in lines[0] and "disk full" in lines[0], lines[0]


# -- a real full disk ---------------------------------------------------------------------------
@pytest.fixture
def small_disk(tmp_path):
    """A 12 MiB tmpfs, and a function that fills it up to leaving ``free`` bytes."""
    mnt = tmp_path / f"disk-{uuid.uuid4().hex[:6]}"
    mnt.mkdir()
    try:
        proc = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=12m", "tmpfs", str(mnt)],
            capture_output=True,
            text=True,
            timeout=600,
        )
    except OSError as exc:
        pytest.skip(f"cannot mount a tmpfs here ({exc})")
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({proc.stderr.strip() or 'not root'})")

    def fill(free: int) -> None:
        filler = mnt / "filler"
        filler.unlink(missing_ok=True)
        st = os.statvfs(mnt)
        size = st.f_bavail * st.f_frsize - free
        with open(filler, "wb") as fh:
            fh.write(b"\0" * max(0, size))

    try:
        yield mnt, fill
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True, timeout=600)


def test_disk_full_mid_run_then_resumed(small_disk):
    mnt, fill = small_disk
    out = mnt / "run.h5"
    # Room for the file, the initial state, one checkpoint and the rows up to the second, not two
    # checkpoints (a slot needs 1.38 MB; the history's block gains take ~0.7 MB up to step 400).
    fill(4_200_000)
    argv = [*RUN, "--steps", "1000", "--out", str(out)]
    proc = cli(*argv)
    assert proc.returncode == 1, proc.stderr
    _one_line_disk_error(proc.stderr, out)
    assert "keeps its checkpoint at step" in proc.stderr and "run the same command again" in proc.stderr
    no_temporaries(mnt)
    with open_archive(out) as arc:
        assert arc.checkpoint_step >= 200 and arc.rows >= 2
    (mnt / "filler").unlink()  # space again: the same command resumes it
    proc = cli(*argv)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    ref = Ensemble.sample(MapParams(3.0, 0.1, 0.01), POINTS, "strip", SEED).run(1000)
    assert report["steps"] == 1000 and report["A"] == summarize(ref.state(), 1000).A
    assert main(["verify", str(out)]) == 0


def test_disk_full_at_creation(small_disk):
    mnt, fill = small_disk
    out = mnt / "run.h5"
    fill(100_000)
    proc = cli(*RUN, "--steps", "400", "--out", str(out))
    assert proc.returncode == 1, proc.stderr
    _one_line_disk_error(proc.stderr, out)
    assert not out.exists()
    no_temporaries(mnt)


def test_disk_full_during_resume_leaves_the_archive(small_disk):
    mnt, fill = small_disk
    out = mnt / "run.h5"
    assert cli(*RUN, "--steps", "400", "--out", str(out)).returncode == 0
    before = out.read_bytes()
    fill(500_000)  # the rebuilt archive (a second copy) does not fit
    proc = cli("resume", str(out), "--steps", "800", "--quiet")
    assert proc.returncode == 1, proc.stderr
    _one_line_disk_error(proc.stderr, out)
    assert out.read_bytes() == before
    no_temporaries(mnt)


def test_disk_full_during_a_sweep(small_disk):
    mnt, fill = small_disk
    out = mnt / "sweep.h5"
    fill(0)
    proc = cli(*SWEEP, "--out", str(out))
    assert proc.returncode == 1, proc.stderr
    _one_line_disk_error(proc.stderr, out)
    assert not out.exists()
    no_temporaries(mnt)
    (mnt / "filler").unlink()
    assert cli(*SWEEP, "--out", str(out)).returncode == 0
    assert len(read_sweep(out)) == 3


def test_read_only_folder(small_disk):
    mnt, _ = small_disk
    subprocess.run(["mount", "-o", "remount,ro", str(mnt)], check=True, timeout=600)
    proc = cli(*RUN, "--steps", "200", "--out", str(mnt / "run.h5"))
    assert proc.returncode == 1, proc.stderr
    line = proc.stderr.strip()
    assert "\n" not in line and "run.h5" in line and "read-only file system" in line, line


# -- an injected ENOSPC at each write site -------------------------------------------------------
def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@pytest.mark.parametrize(
    ("where", "target", "name"),
    [
        ("creation", _format, "create"),
        ("series row", _rows.Rows, "put"),
        ("checkpoint", _rows, "sync_h5"),
    ],
)
def test_injected_enospc_in_a_run(tmp_path, monkeypatch, capsys, where, target, name):
    out = tmp_path / "run.h5"
    argv = ["run", *MAP_FLAGS, "--points", "300", "--steps", "1000", "--chunk-steps", "100"]
    argv += ["--checkpoint-every", "200", "--quiet", "--out", str(out)]
    calls = {"n": 0}
    real = getattr(target, name)

    def failing(*args, **kwargs):
        calls["n"] += 1
        if where == "creation" or calls["n"] > 3:  # a few writes succeed mid-run
            _enospc()
        return real(*args, **kwargs)

    monkeypatch.setattr(target, name, failing)
    assert main(argv) == 1
    _one_line_disk_error(capsys.readouterr().err, out)
    no_temporaries(tmp_path)
    monkeypatch.undo()
    if where == "creation":
        assert not out.exists()
        return
    assert main(argv) == 0  # the same command resumes it
    ref = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 300, "strip", 0).run(1000)
    with open_archive(out) as arc:
        assert arc.checkpoint_step == 1000
        assert all(np.array_equal(v, ref.state()[k]) for k, v in arc.checkpoint()[0].items())


def test_injected_enospc_while_resuming(tmp_path, monkeypatch, capsys):
    out = tmp_path / "run.h5"
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 300, "strip", 0)
    with ArchiveSink(out, ens, chunk_steps=100) as sink:
        ens.run(300, [sink], chunk_steps=sink.chunk_steps)
    before = out.read_bytes()
    monkeypatch.setattr(_recovery.Salvage, "write", _enospc)
    assert main(["resume", str(out), "--steps", "600", "--quiet"]) == 1
    _one_line_disk_error(capsys.readouterr().err, out)
    assert out.read_bytes() == before
    no_temporaries(tmp_path)


def test_injected_enospc_in_a_sweep(tmp_path, monkeypatch, capsys):
    out = tmp_path / "sweep.h5"
    real = sweep_file.to_record
    calls = {"n": 0}

    def failing(row):
        calls["n"] += 1
        if calls["n"] == 2:
            _enospc()
        return real(row)

    monkeypatch.setattr(sweep_file, "to_record", failing)
    assert main([*SWEEP, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    _one_line_disk_error(err, out)
    assert "run the same command again" in err
    no_temporaries(tmp_path)
    monkeypatch.undo()
    assert len(read_sweep(out)) == 1  # the finished point is kept
    assert main([*SWEEP, "--out", str(out)]) == 0
    assert len(read_sweep(out)) == 3


def test_no_crash_at_exit_after_a_failed_write(tmp_path):
    """The segfault of issue 13.3: HDF5 retried a failed write at interpreter exit."""
    script = f"""
import errno, os
from warpratchet import Ensemble, MapParams
from warpratchet.archive import ArchiveSink, _rows
ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 100, "strip", 0)
sink = ArchiveSink({str(tmp_path / "x.h5")!r}, ens, chunk_steps=10)
def fail(*a, **k):
    raise OSError(errno.ENOSPC, "No space left on device")
_rows.Rows.put = fail
try:
    ens.run(100, [sink], chunk_steps=10)
except OSError as exc:
    print("refused:", exc)
"""
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr
    assert "refused: cannot write" in proc.stdout and "disk full" in proc.stdout
