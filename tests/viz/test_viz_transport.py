"""``python -m viz transport``: the distributions of a --transport run and the orbit portrait draw."""

from __future__ import annotations

import json

import pytest

from warpratchet import MapParams
from warpratchet.transport import TransportEnsemble

pytest.importorskip("matplotlib")
from viz.transport import main  # noqa: E402 - after the optional-dependency check


def test_distributions_from_run_json_and_from_an_archive(tmp_path, capsys):
    p = MapParams(3.242, 0.088, 0.013)
    ens = TransportEnsemble.sample(p, 2000, "strip", seed=1)
    ens.run(20_000)
    report = {"K": p.K, "b1": p.b1, "b2": p.b2, "points": 2000, "steps": 20_000, "transport": ens.report()}
    source = tmp_path / "run.json"
    source.write_text(json.dumps(report))
    assert main([str(source), "-o", str(tmp_path / "t.png")]) == 0
    assert (tmp_path / "t.png").stat().st_size > 10_000
    assert main([str(source), "-o", str(tmp_path / "t.png")]) == 2  # never overwrites
    assert "already exists" in capsys.readouterr().err
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps({k: v for k, v in report.items() if k != "transport"}))
    assert main([str(plain), "-o", str(tmp_path / "p.png")]) == 2
    assert 'holds no "transport" object' in capsys.readouterr().err


def test_orbit_portrait(tmp_path):
    out = tmp_path / "orbits.pdf"
    args = ["--orbits", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--period", "1,3", "--background", "0"]
    assert main([*args, "-o", str(out)]) == 0 and out.stat().st_size > 5_000
    assert main(["--orbits", "--K", "3", "--period", "1", "-o", str(tmp_path / "x.png")]) == 2


def test_orbit_portrait_legend_tells_areas_from_segments():
    """Polygon families have DM^m = I; segment families a shear of trace 2 (docs/orbits.md)."""
    from viz.figures.canvas import pyplot
    from viz.transport import portrait
    from warpratchet.orbits import enumerate_orbits

    params = MapParams(3.0, 0.1, 0.01)
    families = enumerate_orbits(params, 3).families
    assert {(f.shape, f.identity) for f in families} == {("polygon", True), ("segment", False)}
    plt = pyplot()
    fig = portrait(plt, params, [3], background=0)
    labels = [text.get_text() for text in fig.axes[0].get_legend().get_texts()]
    plt.close(fig)
    assert "cyan areas: periodic points with DM^m = I" in labels
    segments = next(label for label in labels if label.startswith("blue segments"))
    assert "shear" in segments and "= I" not in segments


def test_a_flagged_mu_is_never_shown_bare():
    from viz.transport import mu_label

    assert mu_label({"mu": 1.0571, "mu_stderr": 0.0182, "mu_fit": {"reason": None}}) == "mu = 1.057 +- 0.018"
    flagged = {"mu": 2.124, "mu_stderr": 0.019, "mu_fit": {"reason": "mu > 2, faster than ballistic. More."}}
    assert mu_label(flagged) == "mu = 2.124 +- 0.019 (mu > 2, faster than ballistic)"
    assert mu_label({"mu": float("nan"), "mu_fit": {"reason": "3 rows"}}) == "mu = n/a (3 rows)"
