"""Requests that used to hang, raise a traceback or be adjusted silently: each is refused up front.

A hang is tried in a fresh process with a generous timeout: if it ever hangs again, the test
fails with the command named (``subprocess.TimeoutExpired``), instead of the suite hanging.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest
from support import cli, error_line, refused, run_argv

from warpratchet import Ensemble, MapParams, theory
from warpratchet.errors import ParameterError

#: Seconds a child process may take (a busy machine is slow, not broken); a hang takes forever.
PATIENCE = 600
PARAMS = MapParams(3.0, 0.1, 0.01)


def _python(code: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *args], capture_output=True, text=True, timeout=PATIENCE
    )


@pytest.mark.parametrize("flag", ["--checkpoint-every", "--snapshot-every"])
def test_an_interval_beyond_the_largest_step_is_refused(tmp_path, capsys, flag):
    out = tmp_path / "r.h5"
    line = refused(capsys, run_argv("--points", "100", "--out", str(out), flag, str(2**63)))
    name = flag[2:].replace("-", "_")
    assert (
        f"{name} = 9223372036854775808 is outside the allowed range" in line and "9223372036854775807" in line
    )
    assert not out.exists()


def test_the_chunk_for_a_huge_interval_is_found_without_trial_division_to_its_root():
    """The old search tried every divisor up to sqrt(n): 3e9 trials (24 minutes) for n near 2^63."""
    proc = _python(
        """
        from warpratchet.archive import schedule
        print(schedule(100, checkpoint_every=2**62)[0])  # a power of two: 65536 divides it
        try:
            schedule(100, checkpoint_every=2**63 - 25)  # no divisor near the default chunk
        except ValueError as exc:
            print(exc)
        """
    )
    assert proc.returncode == 0, proc.stderr
    chunk, refusal = proc.stdout.strip().splitlines()
    assert chunk == "65536"
    assert refusal.startswith("checkpoint_every = 9223372036854775783 only allow chunks of ")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs a FIFO")
@pytest.mark.parametrize("command", [["inspect"], ["resume", "--steps", "10"], ["verify"]])
def test_a_fifo_is_refused_in_one_line_not_waited_on(tmp_path, command):
    fifo = tmp_path / "f.h5"
    os.mkfifo(fifo)
    name, *rest = command
    proc = cli(name, str(fifo), *rest, timeout=PATIENCE)
    assert proc.returncode == 2, proc.stderr
    line = error_line(proc.stderr)
    assert str(fifo) in line and ("not a regular file" in line or "no such file" in line), line


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs a FIFO")
def test_the_api_refuses_a_fifo_too(tmp_path):
    fifo = tmp_path / "f.h5"
    os.mkfifo(fifo)
    proc = _python(
        """
        import sys
        from warpratchet.archive import ArchiveError, ArchiveSink, open_archive
        for open_it in (open_archive, ArchiveSink.resume):
            try:
                open_it(sys.argv[1])
            except ArchiveError as exc:
                print(exc)
        """,
        str(fifo),
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("not a regular file") == 2, proc.stdout


def test_a_run_that_cannot_end_is_refused_with_its_estimate(capsys):
    line = refused(capsys, run_argv("--points", "10", "--steps", "4611686018427387904"))
    assert "10 points x 4611686018427387904 steps would take at least" in line and "years" in line
    assert line.rstrip().endswith("pass --long to run it")


def test_long_lets_a_long_request_through():
    import argparse

    from warpratchet.cli.run import _check_duration
    from warpratchet.spec import RunSpec

    spec = RunSpec(K=3.0, b1=0.1, b2=0.01, points=10, steps=2**62, threads=2)
    _check_duration(argparse.Namespace(long=True), spec)  # no error
    with pytest.raises(Exception, match="pass --long"):
        _check_duration(argparse.Namespace(long=False), spec)
    # A day at the fastest speed is allowed without it: the paper's largest runs are far below.
    _check_duration(
        argparse.Namespace(long=False), RunSpec(K=3.0, b1=0.1, b2=0.01, points=10**6, steps=10**9, threads=2)
    )


def test_a_resume_that_cannot_end_is_refused_with_its_estimate(tmp_path, capsys):
    from warpratchet.cli import main

    out = tmp_path / "r.h5"
    assert main(run_argv("--points", "10", "--steps", "100", "--quiet", "--out", str(out))) == 0
    before = out.read_bytes()
    capsys.readouterr()
    line = refused(capsys, ["resume", str(out), "--steps", str(2**62), "--quiet"])
    assert f"10 points x {2**62 - 100} more steps would take at least" in line and "years" in line
    assert line.rstrip().endswith("pass --long to run it")
    assert out.read_bytes() == before  # refused before the archive is rebuilt
    # --long is resume's flag too (here on a resume that is complete already).
    assert main(["resume", str(out), "--steps", "100", "--quiet", "--long"]) == 0


def test_a_sweep_that_cannot_end_is_refused_with_its_estimate(tmp_path, capsys):
    from warpratchet.cli import main

    out = tmp_path / "s.h5"
    sweep = ["sweep", "--path", "maximal", "--b2", "0.01:0.1:3", "--points", "10", "--quiet"]
    line = refused(capsys, [*sweep, "--steps", str(2**62), "--out", str(out)])
    assert f"3 sweep points x 10 points x {2**62} steps would take at least" in line and "years" in line
    assert line.rstrip().endswith("pass --long to run it")
    assert not out.exists()
    # Every sweep point counts: 3 x 10**6 points x 10**9 steps on 2 threads, 1.74 days at the fastest.
    big = ["sweep", "--path", "maximal", "--b2", "0.01:0.1:3", "--points", str(10**6), "--threads", "2"]
    assert "would take at least 1.74 days" in refused(capsys, [*big, "--steps", str(10**9)])
    assert main([*sweep, "--steps", "100", "--out", str(out), "--long"]) == 0  # --long is sweep's flag too


@pytest.mark.parametrize(
    "function",
    [
        theory.acceleration,
        theory.domain,
        theory.summary,
        theory.area_chaotic,
        theory.accelerator_modes,
        theory.necessary_condition,
    ],
)
def test_theory_refuses_a_wrong_type_naming_the_argument(function):
    with pytest.raises(TypeError, match=r"p = None is not a MapParams"):
        function(None)


def test_more_snapshot_points_than_points_is_refused(tmp_path, capsys):
    out = tmp_path / "r.h5"
    line = refused(
        capsys,
        run_argv(
            "--points", "1000", "--out", str(out), "--snapshot-every", "1000", "--snapshot-points", "5000"
        ),
    )
    assert "--snapshot-points 5000 is more than the run's 1000 points" in line
    assert not out.exists()


def test_sweep_force_without_out_is_refused(capsys):
    line = refused(capsys, ["sweep", "--path", "maximal", "--b2", "0.01:0.02:2", "--points", "10", "--force"])
    assert "--force needs --out FILE" in line


def test_figures_refuse_a_file_as_the_sweeps_folder(tmp_path):
    pytest.importorskip("matplotlib")
    afile = tmp_path / "sweeps.txt"
    afile.write_text("not a folder")
    args = ["figures", "--only", "fig7", "--out", str(tmp_path / "figs"), "--sweeps", str(afile)]
    proc = cli(*args, "--quiet", timeout=PATIENCE)
    assert proc.returncode == 2, proc.stderr
    assert f"--sweeps {afile}: exists and is not a directory" in error_line(proc.stderr)
    assert afile.read_text() == "not a folder" and not (tmp_path / "figs").exists()


def test_a_seed_no_archive_can_store_is_refused_when_sampling():
    with pytest.raises(ParameterError, match="seed = 18446744073709551616 is outside the allowed range"):
        Ensemble.sample(PARAMS, 10, seed=2**64)


def test_a_refused_write_tells_a_python_user_what_holds(tmp_path, monkeypatch):
    """Not "run the same command again" (there is no command): where the archive and the
    ensemble stand, and how to continue from the archive."""
    import errno

    from warpratchet._storage import StorageError
    from warpratchet.archive import _writer, open_archive

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(_writer, "write_slot", full)
    path = tmp_path / "nb.h5"
    ens = Ensemble.sample(PARAMS, 200, seed=1)
    with pytest.raises(StorageError) as caught:
        ens.run(2000, chunk_steps=1000, archive=path)
    message = str(caught.value)
    assert "the archive keeps its checkpoint at step 0: once there is space, continue from it with" in message
    assert "open_archive(path).ensemble() (this ensemble is at step 2000, ahead of the archive)" in message
    assert "same command" not in message
    monkeypatch.undo()
    with open_archive(path) as arc:
        assert arc.checkpoint()[1] == 0
