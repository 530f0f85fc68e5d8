"""Nothing silently wrong from inputs (issue 13, items 1, 5, 7, 8 and 9), each through the API and the CLI.

1. counts beyond what the code carries and requests beyond this machine's memory: refused before
   anything is allocated, naming the size needed and the memory available;
5. tiny b: refused up front with its allowed range where the kernels run (not by MapParams);
   a non-finite state is never summarised as a number;
7. bad values accepted: NaN or negative thresholds, absurd thread counts, negative steps and NaN
   states in ``from_state``;
8. valid values refused: NumPy integers and floats, with the same results as Python's;
9. tracebacks: each is now one line (API: a ``ValueError``; CLI: exit 2, or 1 for a folder that
   refuses the write).
"""

from __future__ import annotations

import errno
import json
import os
import subprocess
import uuid

import numpy as np
import pytest
from support import MAP_FLAGS, cli, error_line, same_state

from warpratchet import Ensemble, MapParams, Observer, RunSpec, paper, summarize, theory
from warpratchet.archive import ArchiveSink, open_archive
from warpratchet.cli import main
from warpratchet.errors import NonFiniteStateError, ParameterError, ResourceError
from warpratchet.limits import MAX_POINTS
from warpratchet.sumrule import census
from warpratchet.sweep import SweepSpec, maximal_path, read_sweep, run_sweep

P = MapParams(3.0, 0.1, 0.01)
TINY = MapParams(3.0, 1e-150, 1e-150)


def _refused_in_one_line(capsys, argv, needle, code=2) -> str:
    assert main(argv) == code
    captured = capsys.readouterr()
    line = error_line(captured.err)
    assert needle in line and "Traceback" not in captured.err, captured.err
    return line


@pytest.fixture
def low_memory(monkeypatch):
    """This machine has 1 GiB available, whatever it really has."""
    from warpratchet import limits

    monkeypatch.setattr(limits, "available_memory", lambda: 2**30)


# -- 1. counts and memory ---------------------------------------------------------------------------
def test_more_points_than_the_kernels_index_are_refused(capsys):
    line = _refused_in_one_line(
        capsys, ["run", *MAP_FLAGS, "--points", "10000000000", "--quiet"], "points = 10000000000"
    )
    assert f"1 <= points <= {MAX_POINTS}" in line
    for build in (
        lambda: RunSpec(K=3, b1=0.1, b2=0.01, points=MAX_POINTS + 1),
        lambda: SweepSpec(points=10**10),
        lambda: Ensemble.sample(P, 10**10),
        lambda: census(P, 13_824, points=10**10),
        lambda: census(P, 13_824, grid=10**5),
    ):
        with pytest.raises(ParameterError, match=r"is outside the allowed range .* <= "):
            build()


def test_an_ensemble_beyond_this_machines_memory_is_refused_before_allocation(capsys, low_memory):
    line = _refused_in_one_line(
        capsys, ["run", *MAP_FLAGS, "--points", "100000000", "--quiet"], "points = 100000000 needs"
    )
    assert line == (
        "warpratchet: error: points = 100000000 needs 5.28 GiB of memory (56 B of state per point "
        "and 64 MiB to summarise it); this machine has 1 GiB available"
    )
    with pytest.raises(ResourceError, match=r"^points = 100000000 needs 5\.28 GiB"):
        Ensemble.sample(P, 10**8)
    with pytest.raises(ResourceError, match=r"^points = 100000000 needs"):
        Ensemble.check_fits(10**8)
    with pytest.raises(ResourceError, match=r"^points = 100000000 needs"):  # before any row is run
        run_sweep(maximal_path([0.01]), SweepSpec(points=10**8, steps=10), progress=False)
    _refused_in_one_line(
        capsys,
        ["sumrule", *MAP_FLAGS, "--grid", "20000", "--quiet"],
        "a census of 400000000 points (grid = 20000, a 20000 x 20000 lattice) needs",
    )


def test_a_real_ensemble_of_two_billion_points_is_refused_here(capsys):
    """Without pretending: 2e9 points need 104 GiB, far beyond this machine (or skip)."""
    from warpratchet.limits import available_memory

    available = available_memory()
    if available is None or available > 224 * 2**30:
        pytest.skip(f"this machine has {available} bytes available: 2e9 points might fit")
    _refused_in_one_line(
        capsys,
        ["run", *MAP_FLAGS, "--points", "2000000000", "--quiet"],
        "points = 2000000000 needs 104 GiB of memory",
    )


def test_a_sweep_range_of_a_trillion_points_is_refused_before_it_is_made(capsys):
    line = _refused_in_one_line(
        capsys,
        ["sweep", "--path", "maximal", "--b2", "0:1:1000000000000", "--quiet"],
        "--b2 '0:1:1000000000000' (1000000000000 points) needs 7.28 PiB of memory",
    )
    assert line.endswith("available")
    _refused_in_one_line(
        capsys,
        ["sweep", "--grid", "b1=0.001:0.5:100000,b2=0.001:0.5:100000", "--quiet"],
        "a grid of 100000 x 100000 = 10000000000 (b1, b2) points needs",
    )


def test_steps_beyond_the_64_bit_step_counter_are_refused():
    ens = Ensemble.sample(P, 8, threads=1).run(10)
    with pytest.raises(
        ParameterError, match=r"^steps = 9223372036854775807 is outside .* <= 9223372036854775797"
    ):
        ens.run(2**63 - 1)
    assert ens.step == 10


# -- 5. tiny b --------------------------------------------------------------------------------------
TINY_RUN = ["run", "--K", "3", "--b1", "1e-150", "--b2", "1e-150", "--points", "1000", "--steps", "10000"]
TINY_MESSAGE = "b1 = 1e-150 is outside the range the kernels can carry at K = 3.0: b1 >= 1.4e-26"


@pytest.mark.parametrize("out", [False, True])
def test_tiny_b_is_refused_up_front_with_its_range(out, tmp_path, capsys):
    argv = [*TINY_RUN, "--quiet"] + (["--out", str(tmp_path / "tiny.h5")] if out else [])
    line = _refused_in_one_line(capsys, argv, TINY_MESSAGE)
    assert line.startswith("warpratchet: error: ")
    assert os.listdir(tmp_path) == []  # nothing written


def test_tiny_b_is_refused_wherever_the_kernels_run_and_nowhere_else(tmp_path):
    for build in (
        lambda: RunSpec(K=3, b1=1e-150, b2=1e-150),
        lambda: Ensemble.sample(TINY, 10),
        lambda: Ensemble(TINY, np.zeros(3), np.zeros(3)),
        lambda: census(TINY, 13_824, points=100),
    ):
        with pytest.raises(ParameterError, match=TINY_MESSAGE):
            build()
    # A sweep refuses before its first point runs, naming the point.
    out = tmp_path / "sweep.h5"
    points = [P, MapParams(3.0, 0.1, 1e-30)]
    with pytest.raises(ParameterError, match=r"^sweep point 1 \(K=3\.0, b1=0\.1, b2=1e-30\): b2 = 1e-30"):
        run_sweep(points, SweepSpec(points=10, steps=10), out=out, progress=False)
    assert not out.exists()
    # The map itself is exact for any b: theory and MapParams take it.
    assert theory.summary(TINY)["A"] is not None and TINY.b1 == 1e-150


def test_figure_2s_widths_still_run():
    from warpratchet.observables import lyapunov

    for p in paper.FIG2:  # b1 = b2 = 1e-7 at the three K of Fig. 1
        ens = Ensemble.sample(p, 512, threads=1).run(4000)
        assert np.all(np.isfinite(lyapunov(ens.state(), ens.step)))
        assert 0.0 <= summarize(ens.state(), ens.step).chaotic_fraction <= 1.0


def test_a_non_finite_state_is_never_summarised_as_a_number():
    ens = Ensemble.sample(P, 100, threads=1).run(100)
    state = ens.state()
    state["dx"][[3, 7]] = np.inf
    with pytest.raises(NonFiniteStateError, match=r"^2 of 100 points have a non-finite FTLE"):
        summarize(state, 100)
    state = ens.state()
    state["q"][0] = np.nan
    with pytest.raises(ValueError, match=r"^1 of 100 points have a non-finite A_n"):
        summarize(state, 100)
    assert issubclass(NonFiniteStateError, FloatingPointError)  # what summarize raised before


def test_the_census_refuses_a_non_finite_indicator_instead_of_calling_it_regular():
    from warpratchet.sumrule._islands import _check_finite

    ens = Ensemble.sample(P, 10, threads=1).run(16)
    state = ens.state()
    ok = {"megno": np.ones(10), "fli": np.ones(10)}
    _check_finite(state, ok, 16)
    with pytest.raises(NonFiniteStateError, match=r"^1 of 10 points have a non-finite megno"):
        _check_finite(state, {**ok, "megno": np.r_[np.nan, np.ones(9)]}, 16)


# -- 7. bad values accepted -------------------------------------------------------------------------
@pytest.mark.parametrize("value", ["nan", "-1", "inf"])
@pytest.mark.parametrize("command", ["run", "sumrule", "sweep"])
def test_bad_thresholds_are_refused_by_every_command(command, value, capsys):
    argv = {
        "run": ["run", *MAP_FLAGS, "--points", "10", "--steps", "10"],
        "sumrule": ["sumrule", *MAP_FLAGS, "--points", "10"],
        "sweep": ["sweep", "--path", "maximal", "--b2", "0.01", "--points", "10", "--steps", "10"],
    }[command]
    _refused_in_one_line(capsys, [*argv, "--threshold", value, "--quiet"], "threshold = ")


@pytest.mark.parametrize("threshold", [float("nan"), -1.0, float("inf"), np.float64("nan")])
def test_bad_thresholds_are_refused_by_the_api(threshold):
    ens = Ensemble.sample(P, 64, threads=1).run(100)
    for call in (
        lambda: summarize(ens.state(), 100, threshold),
        lambda: ens.summary(threshold),
        lambda: census(P, 13_824, points=100, threshold=threshold),
        lambda: SweepSpec(threshold=threshold),
        lambda: RunSpec(K=3, b1=0.1, b2=0.01, threshold=threshold),
    ):
        with pytest.raises(ParameterError, match=r"^threshold = "):
            call()


def test_absurd_thread_counts_are_refused(capsys):
    _refused_in_one_line(
        capsys, ["run", *MAP_FLAGS, "--threads", "1000000000", "--quiet"], "threads = 1000000000"
    )
    with pytest.raises(ParameterError, match=r"^threads = 1000000000 is outside"):
        Ensemble.sample(P, 10, threads=10**9)


def test_from_state_refuses_a_negative_step_and_a_state_it_cannot_hold(tmp_path):
    good = Ensemble.sample(P, 50, threads=1).run(30)
    with pytest.raises(ParameterError, match=r"^step = -5 is outside the allowed range 0 <= step"):
        Ensemble.from_state(P, good.state(), -5)
    for field, value, needle in [
        ("x", np.nan, "state['x'] holds NaN or infinite values"),
        ("dx", np.inf, "state['dx'] holds NaN or infinite values"),
        ("x", 1.5, "state['x'] is outside the allowed range 0 <= x < 1"),
        ("q", -0.25, "state['q'] is outside the allowed range 0 <= q < 1"),
        ("p0", 2.0**60, "state['p0'] is outside the allowed range |p0| < 2^52"),
    ]:
        state = good.state()
        state[field][4] = value
        with pytest.raises(ParameterError, match=f"^{needle.replace('[', '.').replace(']', '.')}"):
            Ensemble.from_state(P, state, 30)
    state = good.state()
    state["winding"] = state["winding"] + 0.5
    with pytest.raises(ParameterError, match="windings are whole units"):
        Ensemble.from_state(P, state, 30)
    again = Ensemble.from_state(P, good.state(), np.int64(30), threads=1)  # and a good one is taken
    assert again.step == 30 and again.run(10).step == 40
    np.savez(tmp_path / "state.npz", **good.state())  # any mapping of arrays, e.g. a saved .npz
    with np.load(tmp_path / "state.npz") as saved:
        assert same_state(Ensemble.from_state(P, saved, 30, threads=1).run(10).state(), again.state())


# -- 8. valid values refused ------------------------------------------------------------------------
@pytest.mark.filterwarnings("ignore::warpratchet.observables.UnreliableWarning")
def test_numpy_numbers_are_taken_everywhere_with_the_same_results(tmp_path):
    i = np.int64
    # Thresholds exact in float32, so that the same value is asked for both ways.
    a = Ensemble.sample(P, i(500), "strip", i(3), threads=i(2)).run(i(2000), chunk_steps=i(500))
    b = Ensemble.sample(P, 500, "strip", 3, threads=2).run(2000, chunk_steps=500)
    assert a.summary(np.float32(0.125)) == b.summary(0.125) and a.step == 2000 and type(a.step) is int
    assert summarize(a.state(), i(2000), np.float32(0.25)) == summarize(b.state(), 2000, 0.25)
    c1 = census(
        P, i(13_824), points=i(200), seed=i(1), threads=i(1), m_max=i(12), threshold=np.float32(0.125)
    )
    c2 = census(P, 13_824, points=200, seed=1, threads=1, m_max=12, threshold=0.125)
    assert c1.A_sumrule == c2.A_sumrule and c1.points == 200
    spec = SweepSpec(points=i(20), steps=i(30), seed=i(2), threshold=np.float32(0.5))
    assert spec == SweepSpec(points=20, steps=30, seed=2, threshold=0.5)
    rows = run_sweep(maximal_path([0.01]), spec, out=tmp_path / "s.h5", progress=False, threads=i(1))
    stored = read_sweep(tmp_path / "s.h5")  # NaN where a tiny run has no robust error: compare as text
    assert json.dumps(stored, sort_keys=True) == json.dumps(rows, sort_keys=True) and rows[0]["points"] == 20
    sink = ArchiveSink(
        tmp_path / "a.h5",
        b,
        snapshot_every=i(100),
        snapshot_points=i(8),
        checkpoint_every=i(100),
        chunk_steps=i(50),
        threshold=np.float32(0.5),
    )
    b.run(i(200), [sink], chunk_steps=sink.chunk_steps)
    sink.close()
    with open_archive(tmp_path / "a.h5") as arc:
        assert arc.checkpoint_step == 2200 and arc.settings["snapshot_points"] == 8


# -- 9. tracebacks ----------------------------------------------------------------------------------
def test_api_mistakes_are_one_line_value_errors(tmp_path):
    ens = Ensemble.sample(P, 10, threads=1)
    for call, needle in [
        (lambda: Ensemble.sample(None, 10), "params = None is not a MapParams"),
        (lambda: Ensemble.sample((3, 0.1, 0.01), 10), "params = (3, 0.1, 0.01) is not a MapParams"),
        (lambda: ens.run(10, [None]), "observers[0] = None is not an Observer"),
        (lambda: ens.run(10, [Observer(), print]), "observers[1] = <built-in function print> is not"),
        (lambda: ens.run(10, None), "observers = None is not a sequence of Observers"),
        (lambda: ArchiveSink("", ens), "path = '' is not a file name"),
        (lambda: run_sweep(None, SweepSpec(), progress=False), "points = None is not a sequence"),
    ]:
        with pytest.raises(ValueError) as info:
            call()
        assert str(info.value).startswith(needle) and "\n" not in str(info.value), info.value
    assert ens.step == 0 and ens.undefined is None  # nothing ran


def test_a_recording_into_a_folder_that_refuses_it_is_one_line_and_status_1(tmp_path, capsys, monkeypatch):
    """An injected EROFS here; a real read-only mount in the next test (where it can be made)."""
    from warpratchet.recording import _stream as stream

    real_open = os.open

    def read_only(path, flags, *args):
        if os.fspath(path).endswith(".rrd"):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fspath(path))
        return real_open(path, flags, *args)

    pytest.importorskip("rerun")
    monkeypatch.setattr(stream.os, "open", read_only)
    out = tmp_path / "x.rrd"
    line = _refused_in_one_line(
        capsys,
        ["run", *MAP_FLAGS, "--points", "50", "--steps", "50", "--quiet", "--rerun", str(out)],
        "",
        code=1,
    )
    assert line == f"warpratchet: error: cannot write {out}: read-only file system"
    assert not out.exists()


def test_a_recording_on_a_read_only_mount(tmp_path):
    pytest.importorskip("rerun")
    mnt = tmp_path / f"ro-{uuid.uuid4().hex[:6]}"
    mnt.mkdir()
    try:
        proc = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=1m,ro", "tmpfs", str(mnt)], capture_output=True, timeout=600
        )
    except OSError as exc:
        pytest.skip(f"cannot mount a tmpfs here ({exc})")
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({proc.stderr.decode().strip() or 'not root'})")
    try:
        done = cli(
            "run", *MAP_FLAGS, "--points", "50", "--steps", "50", "--quiet", "--rerun", str(mnt / "x.rrd")
        )
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True, timeout=600)
    assert done.returncode == 1, done.stderr
    assert done.stderr == f"warpratchet: error: cannot write {mnt / 'x.rrd'}: read-only file system\n"
