"""Too-short runs say so (issue 14, item 4): Summary.reliable/reason, a warning, the CLI's flag.

Before: ``warpratchet run --K 3 --b1 0.1 --b2 0.01 --steps 20 --points 1000`` printed ``A = nan``
and ``--steps 60`` printed 0.248 +- 0.036 from 7 of 10^4 points (theory 0.145), both silently.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from support import MAP_FLAGS

from warpratchet import Ensemble, MapParams, UnreliableWarning, theory
from warpratchet.cli import main
from warpratchet.observables import (
    AMBIGUITY_FACTOR,
    MIN_CHAOTIC_POINTS,
    finite_time_acceleration,
    lyapunov,
    reliability,
    summarize,
)

PARAMS = MapParams(3.0, 0.1, 0.01)


def test_the_issue_commands_are_flagged_in_text_and_json(capsys):
    assert main(["run", *MAP_FLAGS, "--steps", "20", "--points", "1000", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "nan" not in out
    assert "A           = n/a +- n/a" in out and "UNRELIABLE  : only 0 chaotic points" in out
    assert main(["run", *MAP_FLAGS, "--steps", "60", "--points", "10000", "--quiet", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["reliable"] is False and report["chaotic_points"] < MIN_CHAOTIC_POINTS
    assert report["reason"].startswith(f"only {report['chaotic_points']} chaotic points")


def test_a_long_run_is_reliable_and_says_nothing_more(capsys):
    argv = ["run", *MAP_FLAGS, "--steps", "20000", "--points", "4000", "--quiet"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    lines = out.strip().splitlines()
    # The header, A, the closed form beside it, sigma, the convergence verdict and the speed: no
    # warning line.
    assert "UNRELIABLE" not in out and len(lines) == 6
    assert lines[2].startswith("  theory      =") and lines[4].startswith("  convergence :")
    assert lines[4].endswith(": converged")
    assert main([*argv, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["reliable"] is True and report["reason"] == ""
    assert report["classification_bound"] <= report["A_stderr"]


def test_ensemble_summary_warns_with_its_own_category():
    ens = Ensemble.sample(PARAMS, 10_000, seed=0)
    ens.run(60)
    with pytest.warns(UnreliableWarning, match="A after 60 steps is unreliable: only 7 chaotic points"):
        s = ens.summary()
    assert not s.reliable and s.chaotic_points == 7
    ens.run(20_000 - 60)
    with warnings_as_errors():
        s = ens.summary()
    assert s.reliable and s.reason == ""


class warnings_as_errors:  # noqa: N801 - a context manager used like warnings.catch_warnings
    def __enter__(self):
        import warnings

        self._cm = warnings.catch_warnings()
        self._cm.__enter__()
        warnings.simplefilter("error", UnreliableWarning)

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)


@pytest.mark.parametrize("steps", [300, 1000, 5000])
def test_the_classification_bound_bounds_every_reclassification_of_the_band(steps):
    """Moving the threshold anywhere in the ambiguous band moves A by at most the bound."""
    ens = Ensemble.sample(PARAMS, 10_000, seed=3)
    ens.run(steps)
    state = ens.state()
    s = summarize(state, steps)
    ftle, acc = lyapunov(state, steps), finite_time_acceleration(state, steps)
    for factor in np.geomspace(1 / AMBIGUITY_FACTOR, AMBIGUITY_FACTOR, 13)[1:-1]:
        mask = ftle > s.threshold * factor
        if mask.sum() and math.isfinite(s.classification_bound):
            assert abs(acc[mask].mean() - s.A) <= s.classification_bound * (1 + 1e-12)


def test_short_runs_fail_the_classification_rule_and_long_ones_pass():
    """At n = 1000 the threshold (0.079) still sits among the chaotic FTLEs (sigma ~ 0.34)."""
    ens = Ensemble.sample(PARAMS, 10_000, seed=0)
    ens.run(1000)
    short = summarize(ens.state(), ens.step)
    assert short.chaotic_points >= MIN_CHAOTIC_POINTS  # enough points, yet:
    assert not short.reliable and "could move A by up to" in short.reason
    ens.run(19_000)
    long = summarize(ens.state(), ens.step)
    assert long.reliable
    excluded = long.chaotic_points - ens.points
    bias = 200 / ens.step + 2 * abs(excluded) / long.chaotic_points  # as in test_statistics
    assert abs(long.A - theory.acceleration(PARAMS)) < 4 * long.A_stderr + bias


def test_the_rule_itself():
    assert reliability(MIN_CHAOTIC_POINTS, 0.01, 0.01) == (True, "")
    ok, why = reliability(MIN_CHAOTIC_POINTS - 1, 0.01)
    assert not ok and f"only {MIN_CHAOTIC_POINTS - 1} chaotic points" in why
    ok, why = reliability(1000, math.nan, 0.0)  # NaN stderr is never reliable
    assert not ok
    assert not reliability(1000, 0.01, math.inf)[0]
    # No finite bound (as many points near the threshold as chaotic ones): said in words, not "up to inf".
    ok, why = reliability(1000, 0.01, math.inf)
    assert "without bound" in why and "up to inf" not in why
    # The 10% precision of the standard error behind MIN_CHAOTIC_POINTS.
    assert 1 / math.sqrt(2 * (MIN_CHAOTIC_POINTS - 1)) <= 0.1 < 1 / math.sqrt(2 * (MIN_CHAOTIC_POINTS - 2))


def test_sweep_table_marks_points_without_enough_chaotic_points(tmp_path, capsys):
    argv = ["sweep", "--path", "k", "--Ks", "3:3.2:2", "--b1", "0.1", "--b2", "0.01", "--points", "500",
            "--steps", "20", "--quiet"]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "nan" not in out
    assert "n/a" in out and out.count(" *\n") == 2
    assert "fewer than 51 chaotic points" in out and "UNRELIABLE" in out
