"""``warpratchet orbits``: the period-1 closed form through the CLI, the guard on long periods."""

from __future__ import annotations

import json

import pytest
from support import assert_one_line_error, cli

from warpratchet import MapParams


def test_period_one_orbits_are_the_closed_form():
    """Issue 16's acceptance: the elliptic period-1 orbits at K = 3 have R = 0.75 = K/4.

    Period-1 points have q = 0 and K f(x) = k: in the middle piece x = c - k/K (Eq. xp) with
    R = K/4, elliptic for K < 4; in the left and right pieces x = k/(K l1), 1 + k/(K l2), with
    R = -K l/4 < 0, hyperbolic.
    """
    proc = cli("orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", "1", "--json")
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    p = MapParams(3.0, 0.1, 0.01)
    elliptic = [o for o in report["orbits"] if o["kind"] == "elliptic"]
    hyperbolic = [o for o in report["orbits"] if o["kind"] == "hyperbolic"]
    assert len(elliptic) == 3 and len(hyperbolic) == 3 and report["counts"]["parabolic"] == 0
    for orbit in elliptic:
        k = orbit["winding"]
        assert orbit["residue"] == 0.75 and orbit["nu"] == k
        assert orbit["x"][0] == pytest.approx(p.c - k / p.K, abs=1e-15) and orbit["p"] == [0.0]
    for orbit in hyperbolic:
        k, x = orbit["winding"], orbit["x"][0]
        slope = p.l1 if x <= p.b1 else p.l2
        assert orbit["residue"] == pytest.approx(-p.K * slope / 4, rel=1e-13)
    text = cli("orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", "1").stdout
    assert text.startswith("period-1 orbits at K = 3.0") and text.count("elliptic") == 4  # title + 3 rows


def test_a_period_that_would_take_minutes_needs_long():
    proc = cli("orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", "11")
    assert_one_line_error(proc)
    assert "period 11 would take about" in proc.stderr and "pass --long to run it" in proc.stderr


def test_bad_periods_are_one_line_errors():
    for period in ("0", "-1", "x"):
        proc = cli("orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", period)
        assert proc.returncode == 2 and "period" in proc.stderr and "Traceback" not in proc.stderr
