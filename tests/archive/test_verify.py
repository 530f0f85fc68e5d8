"""``warpratchet verify``, single-bit flips, resuming past damage, non-finite states (issue 13.2, 13.5).

The flip census (tried / detected / harmless / silently wrong) is printed with ``-s``; its
acceptance: no flip ever changes a number a reader returns without an error or a warning, and
``verify`` finds every flip that lands in stored data.
"""

from __future__ import annotations

import json
import os
import shutil
import warnings

import h5py
import numpy as np
import pytest
from support import flip_bit, in_process, same_state

from warpratchet import Ensemble, MapParams, Observer, open_archive
from warpratchet.archive import (
    ArchiveError,
    ArchiveSink,
    ArchiveWarning,
    NonFiniteStateError,
    run_to,
    verify_archive,
)
from warpratchet.cli import main

PARAMS = MapParams(3.0, 0.1, 0.01)
SCHEDULE = {"snapshot_every": 200, "snapshot_points": 40, "checkpoint_every": 400, "chunk_steps": 100}
DATA = os.path.join(os.path.dirname(__file__), os.pardir, "data")


def fresh() -> Ensemble:
    return Ensemble.sample(PARAMS, 300, "strip", 5)


@pytest.fixture(scope="module")
def archived(tmp_path_factory):
    path = tmp_path_factory.mktemp("verify") / "run.h5"
    ens = fresh()
    with ArchiveSink(path, ens, **SCHEDULE) as sink:
        ens.run(1000, [sink], chunk_steps=sink.chunk_steps)
    return path


def test_verify_exit_status(archived, tmp_path, capfd):
    """In this process (``main``); the missing file's one line read from file descriptor 2."""
    assert main(["verify", str(archived)]) == 0
    assert main(["verify", os.path.join(DATA, "archive_v1.h5")]) == 0
    assert main(["verify", os.path.join(DATA, "sweep_v1.h5")]) == 0
    proc = in_process(capfd, "verify", str(tmp_path / "missing.h5"))
    assert proc.returncode == 2 and "no such file" in proc.stderr and "Traceback" not in proc.stderr
    (tmp_path / "notes.txt").write_text("hello")
    assert main(["verify", str(tmp_path / "notes.txt")]) == 2
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["x"] = 1
    assert main(["verify", str(tmp_path / "other.h5")]) == 2
    capfd.readouterr()
    code = main(["verify", str(archived), "--json"])
    report = json.loads(capfd.readouterr().out)
    assert code == 0 and report["ok"] and report["checked"]["datasets"] > 40


def test_single_bit_flips_are_detected_or_harmless(archived, tmp_path):
    """Bits flipped at a deterministic sample of offsets: verify finds each flip in stored data; a
    reader never returns a changed number without an error or a warning naming what it recovered.

    The sample (``support.flip_sample``) is every 1/20 of the file plus one byte of every
    checksummed dataset. The full census, every byte of the same archive, is
    ``python scripts/flip_census.py archive`` (exit 1 on any failure).
    """
    from support import archive_flip_census, flip_sample, stored_chunks

    offsets = flip_sample(archived, os.path.getsize(archived) // 20)
    census = archive_flip_census(
        archived, offsets, tmp_path, lambda step: fresh().run(step, chunk_steps=100).state()
    )
    missed, wrong = census.pop("missed"), census.pop("wrong")
    print(f"archive flips: {census}")
    assert wrong == [], f"offsets whose recovered checkpoint differs from the run: {wrong}"
    assert census["silent"] == 0
    assert missed == [], f"flips in stored data that verify missed: {missed}"
    chunks = [(start, size) for _, start, size in stored_chunks(archived)]
    assert census["detected"] >= len([o for o in offsets if any(s <= o < s + n for s, n in chunks)])


def test_resume_skips_a_damaged_snapshot_and_initial_state(archived, tmp_path):
    path = tmp_path / "bad.h5"
    shutil.copy(archived, path)
    with h5py.File(path, "r") as f:
        snap = f["snapshots/x"].id.get_chunk_info(1).byte_offset  # the snapshot at step 400
        initial = f["initial/x"].id.get_chunk_info(0).byte_offset
    for offset in (snap + 20, initial + 20):
        flip_bit(path, tmp_path / "tmp.h5", offset, 3)
        os.replace(tmp_path / "tmp.h5", path)
    problems, _ = verify_archive(path)
    assert any("/snapshots/x" in p for p in problems) and any("/initial/x" in p for p in problems)
    with pytest.warns(ArchiveWarning, match=r"damaged row\(s\) of /snapshots/x.*initial state is unreadable"):
        sink, ens = ArchiveSink.resume(path, threads=1)
    with sink:
        assert ens.step == 1000
        run_to(ens, 1200, [sink], sink.chunk_steps)
    assert same_state(ens.state(), fresh().run(1200).state())
    with open_archive(path) as arc:
        assert list(arc.snapshots.steps) == [200, 600, 800, 1000, 1200]  # 400 skipped, the rest kept
        assert same_state(arc.initial, fresh().state())  # sampled again, bit for bit
    assert main(["verify", str(path)]) == 0


def test_cli_resume_says_what_it_skipped(archived, tmp_path, capfd):
    path = tmp_path / "bad.h5"
    shutil.copy(archived, path)
    with h5py.File(path, "r") as f:
        offset = f["series/A"].id.get_chunk_info(0).byte_offset
    flip_bit(path, tmp_path / "tmp.h5", offset + 9, 0)
    os.replace(tmp_path / "tmp.h5", path)
    proc = in_process(capfd, "resume", str(path), "--steps", "1100", "--quiet", "--json")
    assert proc.returncode == 0, proc.stderr
    assert "warpratchet: warning:" in proc.stderr and "damaged row(s) of /series/A" in proc.stderr
    assert json.loads(proc.stdout)["steps"] == 1100


class _Overflow(Observer):
    """Overflows some tangents at step 2500, as a tiny b did (issue 13.5): ``RunSpec`` and
    ``Ensemble`` now refuse such b up front, so the overflow is made by hand, in the live state
    behind the read-only ``array`` views (a fault no public method can make)."""

    def after_chunk(self, ensemble, seconds):
        if ensemble.step == 2500:
            ensemble._arrays["dx"].numpy()[[3, 30, 300]] = np.inf


def test_non_finite_state_is_never_checkpointed(tmp_path):
    """Tangents that overflowed float64: the sink refuses; the last good checkpoint stays."""
    path = tmp_path / "tiny.h5"
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 1000, "strip", 0)
    sink = ArchiveSink(path, ens, chunk_steps=500, checkpoint_every=1000)
    with np.errstate(divide="ignore", invalid="ignore"):  # the overflow this test is about
        with pytest.raises(NonFiniteStateError, match="not finite.*keeps its checkpoint at step"):
            ens.run(10_000, [_Overflow(), sink], chunk_steps=sink.chunk_steps)
    sink.close()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ArchiveWarning)  # no damaged or non-finite checkpoint to skip
        with open_archive(path) as arc:
            state, step = arc.checkpoint()
    assert step < ens.step and all(np.all(np.isfinite(v)) for v in state.values())
    assert main(["verify", str(path)]) == 0


def test_non_finite_checkpoints_of_release_0_1_are_reported(tmp_path, capsys):
    """0.1.0 could checkpoint a non-finite state: inspect warns, verify reports, resume skips it."""
    path = tmp_path / "v1.h5"
    shutil.copy(os.path.join(DATA, "archive_v1.h5"), path)
    with h5py.File(path, "r+") as f:
        slot = ("a", "b")[int(f["checkpoint/current"][0])]
        dx = f[f"checkpoint/{slot}/dx"][:]
        dx[:5] = np.inf
        f[f"checkpoint/{slot}/dx"][:] = dx  # what 0.1.0 wrote for a tiny b (checksums valid)
    assert main(["verify", str(path)]) == 1
    out = capsys.readouterr().out
    assert "damaged: the checkpoint at step 512" in out and "non-finite values (5 dx)" in out
    assert main(["inspect", str(path)]) == 0
    err = capsys.readouterr().err
    assert "warpratchet: warning:" in err and "non-finite values (5 dx)" in err
    with pytest.warns(ArchiveWarning, match="non-finite"):
        sink, ens = ArchiveSink.resume(path, threads=1)
    sink.close()
    assert ens.step == 256  # the older, finite checkpoint


def test_verify_refuses_a_file_a_run_is_writing(tmp_path, capsys):
    """ "In use" is its own status (3), neither damage (1) nor "not an archive" (2); the API says
    "in use" too, instead of reporting a write in progress as damage."""
    from warpratchet.archive import verify_archive

    path = tmp_path / "live.h5"
    with ArchiveSink(path, fresh(), chunk_steps=100):
        assert main(["verify", str(path)]) == 3
        [line] = capsys.readouterr().err.strip().splitlines()
        assert line.startswith("warpratchet: verify: ") and "in use by another process" in line
        with pytest.raises(ArchiveError, match="in use by another process.*verify it once the run is done"):
            verify_archive(path)
    assert main(["verify", str(path)]) == 0
    assert verify_archive(path)[0] == []
