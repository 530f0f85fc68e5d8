"""The run history (issue 15): log-spaced rows equal to the end summary, block gains, the verdict.

Rows and blocks are independent of chunking, threads and interruption; a history restored from its
records continues like the uninterrupted one; a drifting history is reported as drifting; the
threshold rules; ``run --json`` carries the history (resumes from archives: test_archive_kill.py).
"""

import json
import math

import numpy as np
import pytest
from support import quick_benchmark, run_argv, same_history

from warpratchet import Ensemble, MapParams, Observer, RunSpec, finite_time_acceleration, lyapunov, summarize
from warpratchet.archive._rows import snapshot_indices
from warpratchet.cli import main
from warpratchet.history import (
    BLOCK_FIELDS,
    HISTORY_FIELDS,
    History,
    block_steps,
    block_subsample,
    copies_blocks,
    history_row,
    history_steps,
)
from warpratchet.observables import THRESHOLD_RULES as RULE_FACTORS
from warpratchet.observables import lyapunov_threshold
from warpratchet.sampling import salted_subsample
from warpratchet.spec import THRESHOLD_RULES

PARAMS = MapParams(3.0, 0.1, 0.01)


def test_steps_are_log_spaced_with_half_and_last():
    steps = history_steps(0, 120_000)
    assert steps == sorted(set(steps)) and steps[0] == 1 and steps[-1] == 120_000 and 60_000 in steps
    for decade in range(5):  # at least 8 rows in every full decade [10^d, 10^(d+1))
        assert sum(10**decade <= n < 10 ** (decade + 1) for n in steps) >= 8 or decade == 0
    assert history_steps(250, 1000) == [n for n in history_steps(0, 1000) if n > 250]
    assert history_steps(1000, 1000) == []


def test_last_row_is_the_end_summary_bit_for_bit():
    ens = Ensemble.sample(PARAMS, 2000, "strip", seed=3, threads=2)
    history = History()
    ens.run(3000, [history])
    s = summarize(ens.state(), ens.step)
    last = {name: values[-1] for name, values in history.rows.items()}
    assert last["step"] == 3000 == ens.step
    assert (last["A"], last["A_stderr"], last["sigma"], last["chaotic_fraction"]) == (
        s.A,
        s.A_stderr,
        s.lyapunov,
        s.chaotic_fraction,
    )
    assert last == history_row(ens.state(), summarize(ens.state(), ens.step))
    assert history.rows["step"] == history_steps(0, 3000)
    # var(p_n - p_0) over all points, directly from the momentum
    dp = ens.momentum() - ens.array("p0")
    assert math.isclose(last["var_dp_all"], dp.var(ddof=1), rel_tol=1e-9)


def test_rows_do_not_depend_on_chunking_or_threads():
    a, b = History(), History()
    Ensemble.sample(PARAMS, 500, "torus", seed=1, threads=1).run(1500, [a], chunk_steps=7)
    Ensemble.sample(PARAMS, 500, "torus", seed=1, threads=2).run(1500, [b])
    assert same_history(a, b)  # rows, block records and subsample


class _StopAt(Observer):
    def __init__(self, step):
        self.step = step

    def after_chunk(self, ensemble, seconds):
        if ensemble.step == self.step:
            raise KeyboardInterrupt


def test_an_interrupted_run_continued_to_its_target_records_the_same_rows():
    whole = History()
    Ensemble.sample(PARAMS, 500, "strip", seed=2).run(2000, [whole], chunk_steps=100)
    ens = Ensemble.sample(PARAMS, 500, "strip", seed=2)
    first, rest = History(), History()
    with pytest.raises(KeyboardInterrupt):
        ens.run(2000, [first, _StopAt(700)], chunk_steps=100)
    ens.run(2000 - ens.step, [rest], chunk_steps=100)
    joined = {k: first.rows[k] + rest.rows[k] for k in HISTORY_FIELDS}
    assert same_history(joined, whole)


def test_bad_arguments_name_the_parameter():
    with pytest.raises(ValueError, match="threshold = -1.0 is outside the allowed range"):
        History(threshold=-1)
    with pytest.raises(ValueError, match="per_decade = 0 is outside the allowed range"):
        History(per_decade=0)


# -- block gains, the verdict, the threshold rule, the CLI -----------------------------------------
def test_subsamples_are_salted_draws_kept_apart_by_their_salts():
    """``salted_subsample`` (the block subsample's and the snapshots'): distinct sorted indices, the
    same for the same seed (None as 0), different for different salts."""
    a = salted_subsample(1000, 4, 300, 1)
    assert a.dtype == np.int64 and a.size == 300 and np.all(np.diff(a) > 0) and 0 <= a[0] and a[-1] < 1000
    assert np.array_equal(a, salted_subsample(1000, np.int64(4), 300, 1))
    assert np.array_equal(salted_subsample(1000, None, 300, 1), salted_subsample(1000, 0, 300, 1))
    assert not np.array_equal(a, salted_subsample(1000, 4, 300, 2))
    assert not np.array_equal(block_subsample(1000, 4, 300), snapshot_indices(1000, 300, 4))
    assert np.array_equal(salted_subsample(5, 9, 5, 2), np.arange(5))


def test_block_gains_are_the_momentum_gains_of_a_fixed_subsample_at_equal_blocks():
    """Each block record is p_n - p_0 (and the FTLE) of the subsample at floor(target j / 64)."""
    target = 6400
    ens = Ensemble.sample(PARAMS, 1000, "strip", seed=4, threads=2)
    history = History(block_points=300)
    ens.run(target, [history], chunk_steps=999)
    steps = history.block_rows["block_step"]
    assert steps == block_steps(0, target) == [100 * j for j in range(1, 65)]
    idx = history.block_indices
    assert np.array_equal(idx, block_subsample(1000, 4, 300)) and np.all(np.diff(idx) > 0)
    twin = Ensemble.sample(PARAMS, 1000, "strip", seed=4, threads=1)
    for step, gain, ftle in zip(*history.block_rows.values(), strict=True):
        twin.run(step - twin.step)
        state = twin.state()
        p0 = state["p0"]
        exact = (state["winding"] + (state["q"] - (p0 - np.floor(p0))))[idx]  # A_n * n before the division
        assert np.array_equal(gain, exact)
        assert np.allclose(gain / step, finite_time_acceleration(state, step)[idx], rtol=0, atol=1e-15)
        assert np.array_equal(ftle, lyapunov(state, step)[idx])
    gains, reason = history.block_gains(target)
    assert reason == "" and gains.shape[0] == 64
    chaotic = history.block_rows["block_gain"][-1][ftle > history_threshold(target)]
    assert np.allclose(gains.sum(axis=0), chaotic, rtol=1e-12, atol=1e-9)  # the increments add up
    assert block_steps(0, 100, 64)[:3] == [1, 3, 4] and len(block_steps(0, 100, 64)) == 64


def history_threshold(step):
    return lyapunov_threshold(step, "strict")


def test_restored_history_continues_like_the_uninterrupted_one():
    whole = History()
    Ensemble.sample(PARAMS, 400, "torus", seed=9).run(3000, [whole], chunk_steps=250)
    ens = Ensemble.sample(PARAMS, 400, "torus", seed=9)
    first = History()
    with pytest.raises(KeyboardInterrupt):
        ens.run(3000, [first, _StopAt(1250)], chunk_steps=250)
    keep = [i for i, s in enumerate(first.rows["step"]) if s <= 1250]
    blocks = [i for i, s in enumerate(first.block_rows["block_step"]) if s <= 1250]
    again = History.restore(
        {k: [v[i] for i in keep] for k, v in first.rows.items()},
        {k: [v[i] for i in blocks] for k, v in first.block_rows.items()},
        first.block_indices,
        **first.settings(),
    )
    ens.run(3000 - ens.step, [again], chunk_steps=250)
    assert same_history(again, whole)  # rows, block records and subsample
    assert again.convergence() == whole.convergence()


def _synthetic(drift_per_step: float) -> History:
    """Rows of a run whose A_n moves as A + drift_per_step * (n - 1000), with a small stderr."""
    steps = history_steps(0, 64_000)
    a = [0.05 + drift_per_step * (n - 1000) for n in steps]
    rows = {
        "step": steps,
        "A": a,
        "A_stderr": [1e-4] * len(steps),
        "sigma": [0.5] * len(steps),
        "chaotic_fraction": [1.0] * len(steps),
        "chaotic_points": [10_000] * len(steps),
        "var_dp_all": [2.0 * n for n in steps],
        "var_dp_chaotic": [2.0 * n for n in steps],
    }
    return History.restore(rows, {name: [] for name in BLOCK_FIELDS}, None)


def test_a_drifting_history_is_reported_as_drifting():
    """The verdict wiring: A_n moving by 10 standard errors between n/2 and n is 'drifting'."""
    moving = _synthetic(-1e-3 / 32_000).convergence()  # A_n - A_n/2 = -1e-3 = -10 stderr
    assert moving.verdict == "drifting" and moving.drift == pytest.approx(-1e-3) and moving.drift_z < -3
    assert math.isnan(moving.A_stderr_robust) and "no block record" in moving.missing
    still = _synthetic(0.0).convergence()
    assert still.verdict == "converged" and still.drift == 0.0
    # The same wiring end to end: a sweep row and the report's result column.
    from viz.checks import BiasBound, CheckedRow

    row = {"A": 0.05, "A_stderr": 1e-4, "verdict": moving.verdict, "drift_z": moving.drift_z}
    checked = CheckedRow(row, 0.05, BiasBound(1, 0.0, 0.0, 0.0))
    assert checked.passed and checked.drifting and checked.result.startswith("drifting (z = -")


def test_threshold_rules_and_their_rows():
    ens = Ensemble.sample(MapParams(2.99, 0.25, 0.005), 1000, "torus", seed=1)
    strict, positive = History(), History(threshold_rule="positive")
    ens.run(4000, [strict, positive])
    assert positive.rows["chaotic_points"][-1] > strict.rows["chaotic_points"][-1]
    s = summarize(ens.state(), 4000, threshold_rule="positive")
    assert (s.A, s.lyapunov) == (positive.rows["A"][-1], positive.rows["sigma"][-1])
    assert s.threshold == lyapunov_threshold(4000, "positive")
    assert lyapunov_threshold(4000, "strict") == 10.0 * (1.0 + math.log(4000)) / 4000
    assert lyapunov_threshold(4000, "positive") == (1.0 + math.log(4000)) / 4000
    with pytest.raises(ValueError, match="threshold_rule = 'loose' is not one of strict, positive"):
        History(threshold_rule="loose")
    with pytest.raises(ValueError, match="threshold = 0.01 and threshold_rule = 'positive' both given"):
        RunSpec(K=3, b1=0.1, b2=0.01, threshold=0.01, threshold_rule="positive")
    assert set(THRESHOLD_RULES) == set(RULE_FACTORS)


def test_the_former_keyword_rule_still_works_and_says_its_new_name():
    # One name, threshold_rule, across the API; rule= keeps working for the code that has it.
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 200, "strip", seed=1).run(50)
    state = ens.state()
    with pytest.warns(DeprecationWarning, match=r"summarize\(rule=\.\.\.\) is spelled threshold_rule="):
        old = summarize(state, 50, rule="positive")
    assert old == summarize(state, 50, threshold_rule="positive")
    with pytest.warns(DeprecationWarning, match="threshold_rule"):
        assert ens.summary(rule="positive", warn=False) == ens.summary(threshold_rule="positive", warn=False)
    with pytest.warns(DeprecationWarning, match="threshold_rule"):
        assert lyapunov_threshold(50, rule="positive") == lyapunov_threshold(50, "positive")
    with pytest.warns(DeprecationWarning, match="threshold_rule"):
        history = History(rule="positive")
    assert history.threshold_rule == "positive"
    with pytest.warns(DeprecationWarning, match="History.rule is spelled History.threshold_rule"):
        assert history.rule == "positive"
    with pytest.raises(TypeError, match="give threshold_rule= only"):
        summarize(state, 50, rule="strict", threshold_rule="positive")


def test_run_json_carries_the_history_and_the_verdict(capsys):
    assert main(run_argv("--points", "500", "--steps", "3000", "--seed", "2", "--json", "--quiet")) == 0
    report = json.loads(capsys.readouterr().out)
    history = History()
    Ensemble.sample(PARAMS, 500, "strip", seed=2).run(3000, [history])
    expected = {k: [None if isinstance(v, float) and math.isnan(v) else v for v in values] for k, values in
                history.as_dict().items()}  # fmt: skip
    assert report["history"] == expected  # equal-length lists, bit for bit (NaN is null in JSON)
    assert {"step", "A", "A_stderr", "sigma", "var_dp_all", "var_dp_chaotic"} <= report["history"].keys()
    verdict = history.convergence()
    assert report["verdict"] == verdict.verdict in ("converged", "drifting")
    assert (report["drift"], report["drift_z"], report["A_stderr_robust"]) == (
        verdict.drift,
        verdict.drift_z,
        verdict.A_stderr_robust,
    )
    assert report["A"] == report["history"]["A"][-1] and report["steps"] == report["history"]["step"][-1]


def test_overhead_benchmark_runs_and_the_history_changes_nothing():
    """Smoke test of benchmarks/history_overhead.py --quick (structure only, no timing assertions)."""
    report = quick_benchmark("history_overhead.py")
    assert report["quick"] and report["budget"] == 1.05 and len(report["cases"]) == 2
    for case in report["cases"]:
        assert case["identical"] and case["rows"] == len(history_steps(0, case["steps"]))
        assert case["blocks"] == 64 and case["wall_ratio"] > 0 and case["history_share_of_kernel"] > 0


def test_an_archive_refuses_a_history_it_cannot_keep(tmp_path):
    from warpratchet.archive import ArchiveSink

    ens = Ensemble.sample(PARAMS, 100, "strip", seed=1)
    with pytest.raises(ValueError, match="threshold = None, threshold_rule = 'strict'; the archive"):
        ArchiveSink(tmp_path / "a.h5", ens, threshold_rule="positive", history=History())
    used = History()
    ens.run(100, [used])
    with pytest.raises(ValueError, match="holds records of an earlier run"):
        ArchiveSink(tmp_path / "b.h5", ens, history=used)
    sink = ArchiveSink(tmp_path / "c.h5", ens, history=History())  # not among the run's observers
    with pytest.raises(ValueError, match="missed its step .*: pass sink.history to Ensemble.run"):
        ens.run(1000, [sink], chunk_steps=500)
    sink.close()
    assert not (tmp_path / "a.h5").exists() and not (tmp_path / "b.h5").exists()


def test_the_run_stops_only_at_history_rows_not_at_block_steps():
    """The block records come from the history's own copy of the subsample, so a run ends chunks at
    its row steps and its regular chunk ends only (each stop is a launch boundary)."""
    ens = Ensemble.sample(PARAMS, 500, "strip", seed=2, threads=2)
    stops = []
    real = ens._advance
    ens._advance = lambda steps, pool: (stops.append(ens.step + steps), real(steps, pool))
    history = History(block_points=100)
    ens.run(3000, [history], chunk_steps=3000)
    assert stops == history_steps(0, 3000)
    assert history.block_rows["block_step"] == block_steps(0, 3000)


@pytest.mark.parametrize("threads", [1, 2])
def test_a_small_ensemble_run_long_stops_at_its_block_steps_with_the_same_records(monkeypatch, threads):
    """Where advancing the subsample's copy costs more than stopping the run (copies_blocks), the run
    stops at the block steps and reads the records from the ensemble: the same bits as the copy."""
    import warpratchet.history as history_module

    assert copies_blocks(10**6, 4096, 6000, 64) and not copies_blocks(10**4, 4096, 120_000, 64)
    histories, stops = [], []
    for stop_steps in (10**9, 0):  # the copy, then the stops
        monkeypatch.setattr(history_module, "STOP_STEPS", stop_steps)
        ens = Ensemble.sample(PARAMS, 300, "strip", seed=5, threads=threads)
        real, seen = ens._advance, []
        ens._advance = lambda steps, pool, real=real, seen=seen, ens=ens: (
            seen.append(ens.step + steps),
            real(steps, pool),
        )
        history = History(block_points=64)
        ens.run(2000, [history], chunk_steps=2000)
        histories.append(history)
        stops.append(seen)
    assert stops[0] == history_steps(0, 2000)
    assert stops[1] == sorted(set(history_steps(0, 2000)) | set(block_steps(0, 2000)))
    assert histories[1].block_rows["block_step"] == block_steps(0, 2000)
    assert same_history(histories[0], histories[1])
    assert histories[0].convergence() == histories[1].convergence()


@pytest.mark.parametrize(("threads", "chunk"), [("1", None), ("2", None), ("2", 1000)])
def test_a_runs_report_and_history_equal_those_of_summarize_and_the_reference_variance(
    monkeypatch, capsys, threads, chunk
):
    """Every number ``run --json`` reports (the rows, A, its errors, the verdict) is the same with the
    summaries and variances computed on the run's threads as with ``summarize`` and the history's own
    variance, bit for bit; the runs differ only in their timings. Also past one summary chunk (shrunk
    here to 1000 points: 3 chunks), where both add up their chunks' sums."""
    argv = run_argv(
        "--points", "3000", "--steps", "2500", "--seed", "4", "--threads", threads, "--json", "--quiet"
    )
    import warpratchet.ensemble
    import warpratchet.kernels
    import warpratchet.observables

    for module in (warpratchet.ensemble, warpratchet.observables):  # many leaves, on the threads
        monkeypatch.setattr(module, "TREE_LEAF", 128)
    if chunk is not None:  # the summaries' and the history variance's chunks
        monkeypatch.setattr(warpratchet.observables, "SUMMARY_CHUNK", chunk)
    passes = []  # the rows' per-point pass runs in the kernel (its FTLE computed there, where NumPy's)

    class RowPass(warpratchet.kernels.RowPass):
        def __call__(self, *args):
            passes.append(self.inputs.ftle.shape[0] == 0)
            return super().__call__(*args)

    monkeypatch.setattr(warpratchet.kernels, "RowPass", RowPass)
    reports = []
    for on_threads in (True, False):
        if not on_threads:  # the reference path: summarize, then history_row's own variance
            monkeypatch.setattr(Ensemble, "_summary_on_threads", lambda self, *args: None)
        assert main(argv) == 0
        report = json.loads(capsys.readouterr().out)
        for timing in ("seconds", "point_steps_per_second"):
            report.pop(timing)
        reports.append(report)
    assert reports[0] == reports[1] and len(reports[0]["history"]["step"]) == len(history_steps(0, 2500))
    assert passes and all(p == warpratchet.kernels.row_pass_available() for p in passes)


def test_one_pool_serves_a_runs_launches_and_its_rows_and_a_row_outside_a_run_has_its_own(monkeypatch):
    """The history rows of a run on 2 threads are summarised on the pool of its launches (the only
    pool the run makes) where the threads meet (the chunk's end), and on the observer's thread where
    they go on (copies of the state at the rows inside the chunk); a summary outside a run makes a
    pool of its own. Bits as ``summarize``'s."""
    import warpratchet.ensemble as module

    monkeypatch.setattr(module, "TREE_LEAF", 128)  # many leaves: the rows go on the threads
    made, used = [], []
    real_pool, real_summarize = module.ThreadPoolExecutor, module.summarize_with_variance

    def pool(*args, **kwargs):
        made.append(real_pool(*args, **kwargs))
        return made[-1]

    def summarize_with_variance(*args, pool=None, **kwargs):
        used.append(pool)
        return real_summarize(*args, pool=pool, **kwargs)

    monkeypatch.setattr(module, "ThreadPoolExecutor", pool)
    monkeypatch.setattr(module, "summarize_with_variance", summarize_with_variance)
    ens = Ensemble.sample(PARAMS, 3000, "strip", seed=4, threads=2)
    history = History()
    ens.run(2500, [history])
    assert len(made) == 1 and len(used) == len(history.rows["step"]) > 10
    assert used[-1] is made[0] and all(p is None for p in used[:-1])  # one chunk: 2500 steps
    assert ens.summary(warn=False) == summarize(ens.state(), ens.step)  # the last row's, cached
    outside = ens.summary(threshold=0.05, warn=False)  # a new threshold: a new summary, no run
    assert len(made) == 2 and used[-1] is made[1] and made[1] is not made[0]
    assert outside == summarize(ens.state(), ens.step, 0.05)
