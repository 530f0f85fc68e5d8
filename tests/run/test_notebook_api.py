"""The notebook API (issue 14, item 9): progress=, archive=, summary(), to_pandas(), h5py + read_sweep."""

from __future__ import annotations

import numpy as np
import pytest
from support import same_state

from warpratchet import Ensemble, MapParams, open_archive, summarize
from warpratchet.archive import MIN_ARCHIVE_CHUNK_STEPS

PARAMS = MapParams(3.0, 0.1, 0.01)


def test_progress_draws_a_bar_when_asked_for(capsys):
    ens = Ensemble.sample(PARAMS, 2000, seed=1)
    ens.run(3000, progress=True, chunk_steps=1000)
    err = capsys.readouterr().err
    assert "steps" in err and "100%" in err and "3.00k/3.00k" in err
    ens.run(10)  # and only then
    assert capsys.readouterr().err == ""


def test_summary_is_summarize_of_the_state():
    ens = Ensemble.sample(PARAMS, 3000, seed=2).run(20_000)
    assert ens.summary() == summarize(ens.state(), ens.step)
    assert ens.summary(threshold=0.05) == summarize(ens.state(), ens.step, 0.05)


def test_a_summary_is_computed_once_per_step_for_every_sink(tmp_path, monkeypatch, capsys):
    """``run --out --json``: the history's row, the archive's series row and the report at one step
    share one summary (one per step and threshold), and each equals ``summarize`` of the state."""
    import json

    from support import run_argv

    import warpratchet.ensemble
    from warpratchet.cli import main as cli_main
    from warpratchet.observables import lyapunov_threshold, summarize_with_variance

    calls = []  # (step, threshold) of every summary computed, by either route

    def spy(state, step, threshold=None, rule="strict", ftle=None, gain=None):
        calls.append((step, lyapunov_threshold(step, rule) if threshold is None else threshold))
        return summarize(state, step, threshold, rule, ftle, gain)

    def spy_on_threads(state, step, threshold, ftle=None, **options):
        calls.append((step, threshold))
        return summarize_with_variance(state, step, threshold, ftle, **options)

    monkeypatch.setattr(warpratchet.ensemble, "summarize", spy)
    monkeypatch.setattr(warpratchet.ensemble, "summarize_with_variance", spy_on_threads)
    argv = run_argv("--points", "500", "--steps", "800", "--json", "--quiet", "--out", str(tmp_path / "a.h5"))
    assert cli_main([*argv, "--threshold-rule", "positive"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert calls and len(calls) == len(set(calls)) and calls[-1] == (800, lyapunov_threshold(800, "positive"))
    with open_archive(tmp_path / "a.h5") as arc:
        series, state = arc.series, arc.checkpoint()[0]
    assert series["step"][-1] == 800 and series["A"][-1] == report["A"] == report["history"]["A"][-1]
    assert summarize(state, 800, None, "positive").A == report["A"]
    ens = Ensemble.sample(PARAMS, 500, seed=2).run(100)
    assert ens.summary(0.05, warn=False) is ens.summary(0.05, warn=False)  # cached, not recomputed
    assert ens.summary(0.05, warn=False) is not ens.run(1).summary(0.05, warn=False)  # until it moves
    with pytest.raises(ValueError, match="read-only"):  # so nothing changes a kept summary's state
        ens.array("x")[0] = 0.5


def test_to_pandas_is_one_row_per_summary_and_stacks():
    pd = pytest.importorskip("pandas", reason="pandas is optional (Summary.to_pandas)")
    ens = Ensemble.sample(PARAMS, 3000, seed=2)
    rows = [ens.run(5000).summary().to_pandas() for _ in range(3)]
    table = pd.concat(rows)
    assert table.index.name == "step" and table.index.tolist() == [5000, 10000, 15000]
    assert table.loc[15000, "A"] == ens.summary().A
    assert {"A", "A_stderr", "reliable", "reason", "chaotic_points"} <= set(table.columns)


def test_to_pandas_without_pandas_names_the_package(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pandas", None)
    s = Ensemble.sample(PARAMS, 2000, seed=2).run(5000).summary()
    with pytest.raises(ImportError, match="pip install pandas"):
        s.to_pandas()


def test_run_with_archive_does_its_own_chunking_and_appends(tmp_path):
    path = tmp_path / "run.h5"
    ens = Ensemble.sample(PARAMS, 2000, seed=4)
    ens.run(3000, archive=path)
    with open_archive(path) as arc:
        chunk = arc.settings["chunk_steps"]
        assert chunk >= MIN_ARCHIVE_CHUNK_STEPS  # the archive's schedule, not 2.5e8/points
        assert arc.checkpoint_step == 3000 and arc.series["step"][-1] == 3000
        np.testing.assert_array_equal(arc.series["step"], [s for s in range(chunk, 3000, chunk)] + [3000])
    ens.run(2000, archive=path)  # the same run, continued: appended
    plain = Ensemble.sample(PARAMS, 2000, seed=4).run(5000)
    with open_archive(path) as arc:
        state, step = arc.checkpoint()
        assert step == 5000 and arc.series["step"][-1] == 5000
        assert arc.initial_step == 0
    assert same_state(state, plain.state()) and same_state(ens.state(), plain.state())


def test_run_with_archive_refuses_another_run_and_a_different_chunking(tmp_path):
    path = tmp_path / "run.h5"
    Ensemble.sample(PARAMS, 500, seed=4).run(100, archive=path)
    other = Ensemble.sample(PARAMS, 500, seed=5).run(100)
    with pytest.raises(ValueError, match="does not hold this ensemble at step 100"):
        other.run(100, archive=path)
    twin = Ensemble.sample(PARAMS, 500, seed=4).run(100)
    with pytest.raises(ValueError, match="chunk_steps = 7 differs"):
        twin.run(100, archive=path, chunk_steps=7)
    twin.run(100, archive=path)  # the same state at the same step: continues
    with open_archive(path) as arc:
        assert arc.checkpoint_step == 200


@pytest.mark.parametrize("locking", [None, True, False, "best-effort"])
def test_read_sweep_while_h5py_holds_the_file(tmp_path, locking):
    import h5py

    from warpratchet.sweep import SweepSpec, maximal_path, read_sweep, run_sweep

    path = tmp_path / "s.h5"
    rows = run_sweep(maximal_path([0.02], K=3.0), SweepSpec(points=200, steps=200), out=path)
    with h5py.File(path, "r", **({} if locking is None else {"locking": locking})):
        assert read_sweep(path) == rows


@pytest.mark.parametrize("locking", [None, True, False, "best-effort"])
def test_open_archive_while_h5py_holds_the_file(tmp_path, locking):
    import h5py

    path = tmp_path / "a.h5"
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 200, threads=1).run(300, archive=path)
    with h5py.File(path, "r", **({} if locking is None else {"locking": locking})):
        with open_archive(path) as arc:
            state, step = arc.checkpoint()
    assert step == 300 and same_state(state, ens.state())
