"""docs/validation.md states the uncertainty of A that the threshold carries, and the census's
definition of C with S_C both ways (viz/fig9.py, warpratchet.sumrule)."""

from __future__ import annotations

import math

import pytest

from viz import fig9
from viz.checks import BiasBound, CheckedRow
from warpratchet import MapParams
from warpratchet.cli import main
from warpratchet.sumrule import census


def _row(b2: float, A: float, stderr: float, verdict: str = "converged") -> CheckedRow:
    row = {
        "b1": 0.25,
        "b2": b2,
        "A": A,
        "A_stderr": stderr,
        "A_stderr_robust": stderr,
        "lyapunov": 0.5,
        "drift_z": 0.1,
        "verdict": verdict,
    }
    bias = BiasBound(window=0, offset=0.0, offset_stderr=0.0, bound=0.0)
    return CheckedRow(row=row, theory=0.05, bias=bias)


def test_threshold_verdict():
    assert fig9.threshold_verdict("converged", 7.2e-4, 2.6e-4) == "threshold-sensitive"
    assert fig9.threshold_verdict("drifting", 7.2e-4, 2.6e-4) == "drifting, threshold-sensitive"
    assert fig9.threshold_verdict("converged", 1e-5, 2.6e-4) == "converged"
    assert fig9.threshold_verdict("converged", math.nan, 2.6e-4) == "converged"


def test_fig9_table_has_the_threshold_column_and_verdict():
    rows = [_row(0.005, 0.042511, 0.00026), _row(0.14, 0.002214, 0.000024)]
    thresholds = {
        "points": 10000,
        "steps": 120000,
        "rows": [{"b2": 0.005, "sensitivity": 0.00072}, {"b2": 0.14, "sensitivity": 0.000001}],
    }
    lines = fig9._main_table(rows, [], thresholds)
    head = [cell.strip() for cell in lines[0].strip("|").split("|")]
    first = [cell.strip() for cell in lines[2].strip("|").split("|")]
    last = [cell.strip() for cell in lines[3].strip("|").split("|")]
    at = head.index("threshold sensitivity")
    assert first[at] == "0.00072" and first[head.index("verdict")] == "threshold-sensitive"
    assert last[at] == "1e-06" and last[head.index("verdict")] == "converged"
    assert len(head) == len(first) == len(last)
    # without the script's JSON the column says n/a, and the summary sentence is left out
    assert [c.strip() for c in fig9._main_table(rows, [])[2].strip("|").split("|")][at] == "n/a"
    summary = fig9._threshold_summary(rows, thresholds)
    assert "at 1 of 2 points" in summary[0]


def test_census_gives_S_C_both_ways(capsys):
    """The census counts a point locked to a class nu as island whatever its FTLE says; S_C by the
    indicator alone adds those points back."""
    c = census(MapParams(3.0, 0.1, 0.01), steps=14000, points=2000, seed=0)
    locked_chaotic = sum(item.area * item.chaotic_fraction for item in c.islands)
    assert c.S_C_indicator == pytest.approx(c.S_C + locked_chaotic, rel=1e-12)
    assert c.S_C_indicator >= c.S_C and c.as_dict()["S_C_indicator"] == c.S_C_indicator
    argv = ["sumrule", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--points", "2000", "--steps", "14000"]
    assert main([*argv, "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "C: chaotic by ftle and locked to no nu; by ftle alone (islands' chaotic points too) S_C" in out
