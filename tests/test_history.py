"""The run history (issue 15): log-spaced rows, equal to the end summary, independent of chunking."""

import math

import numpy as np
import pytest

from warpratchet import Ensemble, MapParams, Observer, summarize
from warpratchet.history import HISTORY_FIELDS, History, history_row, history_steps

PARAMS = MapParams(3.0, 0.1, 0.01)


def test_steps_are_log_spaced_with_half_and_last():
    steps = history_steps(0, 120_000)
    assert steps == sorted(set(steps)) and steps[0] == 1 and steps[-1] == 120_000 and 60_000 in steps
    for decade in range(5):  # at least 8 rows in every full decade [10^d, 10^(d+1))
        assert sum(10**decade <= n < 10 ** (decade + 1) for n in steps) >= 8 or decade == 0
    assert history_steps(250, 1000) == [n for n in history_steps(0, 1000) if n > 250]
    assert history_steps(1000, 1000) == []


def _rows(history):
    return {name: np.array(values, dtype=float) for name, values in history.rows.items()}


def _same(a, b):
    return all(np.array_equal(a[k], b[k], equal_nan=True) for k in HISTORY_FIELDS)


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
    assert last == history_row(ens.state(), ens.step)
    assert history.rows["step"] == history_steps(0, 3000)
    # var(p_n - p_0) over all points, directly from the momentum
    dp = ens.momentum() - ens.array("p0")
    assert math.isclose(last["var_dp_all"], dp.var(ddof=1), rel_tol=1e-9)


def test_rows_do_not_depend_on_chunking_or_threads():
    a, b = History(), History()
    Ensemble.sample(PARAMS, 500, "torus", seed=1, threads=1).run(1500, [a], chunk_steps=7)
    Ensemble.sample(PARAMS, 500, "torus", seed=1, threads=2).run(1500, [b])
    assert _same(_rows(a), _rows(b))


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
    joined = {k: np.concatenate([_rows(first)[k], _rows(rest)[k]]) for k in HISTORY_FIELDS}
    assert _same(joined, _rows(whole))


def test_bad_arguments_name_the_parameter():
    with pytest.raises(ValueError, match="threshold = -1.0 is outside the allowed range"):
        History(threshold=-1)
    with pytest.raises(ValueError, match="per_decade = 0 is outside the allowed range"):
        History(per_decade=0)
