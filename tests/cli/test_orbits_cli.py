"""``warpratchet orbits``: the period-1 closed form through the CLI, the guard on long periods."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from support import assert_one_line_error, in_process, refused

from warpratchet import MapParams


def test_period_one_orbits_are_the_closed_form(capfd):
    """Issue 16's acceptance: the elliptic period-1 orbits at K = 3 have R = 0.75 = K/4.

    Period-1 points have q = 0 and K f(x) = k: in the middle piece x = c - k/K (Eq. xp) with
    R = K/4, elliptic for K < 4; in the left and right pieces x = k/(K l1), 1 + k/(K l2), with
    R = -K l/4 < 0, hyperbolic.
    """
    proc = in_process(capfd, "orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", "1", "--json")
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
    text = in_process(capfd, "orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", "1").stdout
    assert text.startswith("period-1 orbits at K = 3.0") and text.count("elliptic") == 4  # title + 3 rows


def test_a_period_that_would_take_minutes_needs_long(capfd):
    proc = in_process(capfd, "orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", "11")
    assert_one_line_error(proc)
    assert "period 11 would take about" in proc.stderr and "pass --long to run it" in proc.stderr


def test_bad_periods_are_one_line_errors(capsys):
    for period in ("0", "-1", "x"):
        assert "period" in refused(
            capsys, ["orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", period]
        )


def _cost_tables() -> dict[MapParams, dict[int, tuple[int, float]]]:
    """docs/orbits.md's "Cost" tables, read from the page: ``{params: {m: (tree nodes, wall s)}}``.

    Tree nodes are exact on any machine; the seconds are the page's measurement.
    """
    text = (Path(__file__).resolve().parents[2] / "docs" / "orbits.md").read_text()
    tables = {}
    for K, b1, b2, rows in re.findall(
        r"^K = ([\d.]+), b1 = ([\d.]+), b2 = ([\d.]+):\n\n((?:\|.*\n)+)", text, re.M
    ):
        cells = [[c.strip() for c in row.strip("|").split("|")] for row in rows.splitlines()[2:]]
        tables[MapParams(float(K), float(b1), float(b2))] = {
            int(c[0]): (int(c[3]), float(c[1])) for c in cells
        }
    return tables


MEASURED = _cost_tables()


def test_the_cost_tables_of_the_docs_are_read():
    assert set(MEASURED) == {MapParams(3.0, 0.1, 0.01), MapParams(2.99, 0.25, 0.05)}
    assert MEASURED[MapParams(3.0, 0.1, 0.01)][9] == (268360, 41.7)
    assert all(set(range(1, 10)) <= set(table) for table in MEASURED.values())


def test_the_node_count_of_longer_periods_is_extrapolated_from_the_probes():
    """Periods 8 and 9 from the exact counts of 5-7, within 3% (a constant growth: ~10% low at 9)."""
    from warpratchet.cli.orbits import PROBES, extrapolate_nodes

    for params, table in MEASURED.items():
        probes = [table[m][0] for m in PROBES]
        for period in (8, 9):
            nodes, _ = extrapolate_nodes(probes, period)
            assert nodes == pytest.approx(table[period][0], rel=0.03), (params, period)


def test_the_estimate_refuses_period_10_and_runs_period_9(monkeypatch):
    """The guard's extrapolation on the probe costs measured for docs/orbits.md.

    Period 10 took 77-138 s at these two points (over a minute: needs --long) and period 9 took
    34-42 s (runs). The search's cost per node grows with the period (longer exact integers) and so
    does its node growth per period: a constant growth and cost per node predicted 34-48 s for
    period 10 and let it run.
    """
    import warpratchet.orbits
    from warpratchet.cli.orbits import LONG_SECONDS, estimate_seconds

    def probe(params, period):
        nodes, seconds = MEASURED[params][period]
        return type("Probe", (), {"nodes": nodes, "seconds": seconds})()

    monkeypatch.setattr(warpratchet.orbits, "enumerate_orbits", probe)
    for params in MEASURED:
        assert estimate_seconds(params, 10)[0] > LONG_SECONDS, params
        assert estimate_seconds(params, 9)[0] < LONG_SECONDS, params
