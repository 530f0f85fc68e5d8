"""The paper's figures and the validation report, in ``--quick`` mode (viz.figures, viz.report).

One quick run of ``python -m viz figures --all`` (small ensembles, a few sweep points per path)
feeds every test here: every figure must exist as a non-trivial PNG and PDF, and the report
generated from its sweep files must agree with the closed forms of the paper point by point.
The statistical verdicts use the report's own tolerance, 4 standard errors plus the bias bound
beta of :func:`viz.report.bias_bound`: at the quick settings a fair ensemble fails a point with
probability ~6e-5, so a failure here means a real disagreement.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from matplotlib import image as mpimg

from viz import figures, report
from viz.fig9 import fig9_section
from warpratchet import paper, theory
from warpratchet.ensemble import Ensemble
from warpratchet.params import MapParams

CENSUS = (
    "<!-- census:begin -->\n## Census (kept verbatim)\n| S_L | S_R |\n|---|---|\n| 0.1 | 0.2 |\n"
    "<!-- census:end -->"
)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """Figures and report of one ``--quick`` run: ``(out_dir, report_text)``."""
    out = tmp_path_factory.mktemp("figures")
    assert figures.main(["--all", "--quick", "--out", str(out), "--quiet"]) == 0
    validation = out / "validation.md"
    # An existing report with a census block: the generator must keep the block verbatim.
    validation.write_text(f"{report.GENERATED}\n\nold text\n\n{CENSUS}\n", encoding="utf-8")
    assert report.main(["--sweeps", str(out / "sweeps"), "--out", str(validation), "--overwrite"]) == 0
    return out, validation.read_text(encoding="utf-8")


@pytest.mark.parametrize("name", list(figures.FIGURES))
def test_every_figure_is_written_and_not_blank(quick_run, name):
    out, _ = quick_run
    png, pdf = out / f"{name}.png", out / f"{name}.pdf"
    assert pdf.read_bytes().startswith(b"%PDF") and pdf.stat().st_size > 5_000
    pixels = mpimg.imread(png)[..., :3]
    assert pixels.shape[0] > 400 and pixels.shape[1] > 400
    # Non-trivial: a good share of the pixels is drawn (not background white) and several grey
    # levels or colours occur (axes, data, caption).
    drawn = np.mean(np.any(pixels < 0.9, axis=-1))
    assert drawn > 0.02, f"{png} is almost empty ({drawn:.3%} drawn)"
    assert np.unique(np.round(pixels.reshape(-1, 3), 2), axis=0).shape[0] > 10


def _table(text: str, heading: str) -> list[dict[str, str]]:
    """The Markdown table under the section whose heading starts with ``heading``."""
    section = text.split(f"## {heading}", 1)[1].split("\n## ", 1)[0]
    lines = [ln for ln in section.splitlines() if ln.startswith("|")]
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    return [dict(zip(head, (c.strip() for c in ln.strip("|").split("|")), strict=True)) for ln in lines[2:]]


def _rounding_tolerance(f, b1: float, b2: float, half_ulp: float = 5e-7) -> float:
    """Largest change of ``f`` over the +-half_ulp rounding box of (b1, b2), plus A's own rounding."""
    centre = f(b1, b2)
    corners = [f(b1 + s1 * half_ulp, b2 + s2 * half_ulp) for s1 in (-1, 1) for s2 in (-1, 1)]
    return max(abs(c - centre) for c in corners) + half_ulp + 1e-12


@pytest.mark.parametrize("heading", ["Fig. 7: maximal path", "Fig. 7, inset", "Fig. 8: path b1 = 3 b2"])
def test_report_table_matches_theory_and_passes(quick_run, heading):
    _, text = quick_run
    rows = _table(text, heading)
    assert rows, f"no table under {heading!r}"
    for row in rows:
        b1, b2 = float(row["b1"]), float(row["b2"])
        closed = theory.acceleration(MapParams(3.0, b1, b2))
        # The table rounds b1, b2 and A to 6 decimals: allow what that rounding can move A by.
        tol = _rounding_tolerance(lambda u, v: theory.acceleration(MapParams(3.0, u, v)), b1, b2)
        assert abs(float(row["A (closed form)"]) - closed) <= tol
        if heading.startswith("Fig. 7"):
            on_path = _rounding_tolerance(lambda u, v: theory.acceleration_on_maximal_path(v), b1, b2)
            assert abs(float(row["A (closed form)"]) - theory.acceleration_on_maximal_path(b2)) <= on_path
            printed = theory.acceleration_on_maximal_path_as_printed(b2)
            assert abs(float(row["Eq. (Amax) as printed"]) - printed) <= on_path
        z = (float(row["A (numerics)"]) - float(row["A (closed form)"])) / float(row["stderr"])
        assert math.isclose(z, float(row["z"]), abs_tol=0.1)
        # Agreement with the closed form; a row whose A_n still drifts says so instead of "pass"
        # (a drifting row that also disagrees reads "**FAIL**, drifting ...").
        assert row["result"] == "pass" or row["result"].startswith("drifting (z = "), (
            f"{heading}: b2 = {b2}: |z| = {abs(z):.2f}, beta = {row['beta']}, {row['result']}"
        )


def test_report_verdicts_are_the_stated_test(quick_run):
    """Recompute the checks through the API: the verdict is |A - A_theory| < 4 stderr + beta."""
    out, text = quick_run
    sweeps = report.load_sweeps(out / "sweeps")
    checked = report.check_rows("fig8", sweeps["fig8"])
    table = _table(text, "Fig. 8: path b1 = 3 b2")
    assert len(checked) == len(table)
    for c, row in zip(checked, table, strict=True):
        assert c.passed == (abs(c.row["A"] - c.theory) < 4 * c.row["A_stderr"] + c.bias.bound)
        assert c.drifting == (c.row["verdict"] == "drifting") == (abs(c.row["drift_z"]) > 3)
        verdict = "pass" if c.passed else "**FAIL**"
        if c.drifting:
            drift = f"drifting (z = {c.row['drift_z']:+.1f})"
            verdict = f"**FAIL**, {drift}" if not c.passed else drift
        assert row["result"] == c.result == verdict
        b = c.bias
        left_out = (1 - c.row["chaotic_fraction"]) * b.window * c.row["K"]
        assert b.bound == pytest.approx((abs(b.offset) + 4 * b.offset_stderr + left_out) / c.row["steps"])


def test_fig9_pairs_the_ensembles_by_b2(quick_run):
    """The Fig. 9 section pairs the strip's row with the paper's ensemble's at the same b2, not at the
    same position: the strip's rows reversed give the same table and summary; without its first row,
    that row's cells are empty and the summary counts one point fewer."""
    out, _ = quick_run
    sweeps = report.load_sweeps(out / "sweeps")
    checked = {name: report.check_rows(name, sweeps[name]) for name in ("fig9", "fig9_paper")}
    strip = checked["fig9"]
    assert len(strip) > 1 and [c.row["b2"] for c in strip] == [c.row["b2"] for c in checked["fig9_paper"]]
    text = fig9_section(checked, sweeps, None, "sweeps")
    reversed_text = fig9_section({**checked, "fig9": strip[::-1]}, sweeps, None, "sweeps")
    paired = [i for i, line in enumerate(text) if line.startswith("| 0.") or "lies below the strip's" in line]
    assert len(paired) == len(strip) + 1 and [reversed_text[i] for i in paired] == [text[i] for i in paired]
    fewer = fig9_section({**checked, "fig9": strip[1:]}, sweeps, None, "sweeps")
    [summary] = [line for line in text if "lies below the strip's at" in line]
    [summary_fewer] = [line for line in fewer if "lies below the strip's at" in line]
    assert f" of {len(strip)} points" in summary and f" of {len(strip) - 1} points" in summary_fewer
    first = f"| {strip[0].row['b2']:.4f} |"
    [row] = [line for line in fewer if line.startswith(first)]
    assert " |  |  |  | " in row
    # no b2 in common: the sentence says so (it used to fail on min() of no gaps)
    shifted = [dataclasses.replace(c, row={**c.row, "b2": c.row["b2"] + 1e-3}) for c in strip]
    apart = fig9_section({**checked, "fig9": shifted}, sweeps, None, "sweeps")
    assert any("share no b2, so they are not compared" in line for line in apart)


def test_transient_has_settled_by_the_bias_window(quick_run):
    """beta assumes B(T) stops changing after T0 steps: B(2 T0) - B(T0) must be zero within its noise.

    Checked at the weakest chaos of the quick Fig. 8 sweep (smallest b2), where relaxation is slowest.
    """
    out, _ = quick_run
    row = min(report.load_sweeps(out / "sweeps")["fig8"], key=lambda r: r["b2"])
    t0 = report.bias_window(row["steps"])
    ens = Ensemble.sample(MapParams(row["K"], row["b1"], row["b2"]), row["points"], row["init"], row["seed"])
    ens.run(t0)
    first = ens.momentum().copy()
    ens.run(t0)
    # Excess displacement of each orbit over steps T0..2 T0, with the sweep's A as the drift.
    excess = ens.momentum() - first - t0 * row["A"]
    se = math.hypot(excess.std(ddof=1) / math.sqrt(excess.size), t0 * row["A_stderr"])
    assert abs(excess.mean()) < 4 * se, f"B(2T0) - B(T0) = {excess.mean():.3f} +- {se:.3f}"


def test_report_keeps_the_census_block_and_states_the_misprint(quick_run):
    _, text = quick_run
    assert text.count(CENSUS) == 1
    assert "old text" not in text
    assert "Eq. (Amax) is misprinted" in text
    assert re.search(r"\*\*\d+ of \d+\*\* K = 3 points", text)


def test_figures_refuse_to_overwrite(quick_run, capsys):
    out, _ = quick_run
    before = (out / "fig3.png").read_bytes()
    assert figures.main(["--only", "fig3", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "already exists" in err and "--overwrite" in err and len(err.splitlines()) == 1
    assert (out / "fig3.png").read_bytes() == before


def test_bad_figure_name_is_one_line_error(tmp_path, capsys):
    assert figures.main(["--only", "fig7,fig99", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "fig99" in err and "fig12" in err and len(err.splitlines()) == 1
    assert not any(tmp_path.iterdir())


def test_report_refuses_foreign_file(quick_run, tmp_path, capsys):
    out, _ = quick_run
    target = tmp_path / "validation.md"
    target.write_text("# my notes\n", encoding="utf-8")
    assert report.main(["--sweeps", str(out / "sweeps"), "--out", str(target), "--overwrite"]) == 2
    assert "--force" in capsys.readouterr().err
    assert target.read_text(encoding="utf-8") == "# my notes\n"


def test_report_replaces_an_existing_report_only_with_overwrite(tmp_path, capsys):
    """A quick run must not silently replace the committed docs/validation.md."""
    target = tmp_path / "validation.md"
    target.write_text(f"{report.GENERATED}\n\nthe committed report\n", encoding="utf-8")
    assert report.main(["--sweeps", str(tmp_path), "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert "already exists; pass --overwrite" in err and len(err.strip().splitlines()) == 1
    assert target.read_text(encoding="utf-8") == f"{report.GENERATED}\n\nthe committed report\n"


def test_report_names_missing_sweeps(tmp_path, capsys):
    assert report.main(["--sweeps", str(tmp_path), "--out", str(tmp_path / "v.md")]) == 2
    err = capsys.readouterr().err
    assert "fig7.h5" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "v.md").exists()


def test_full_settings_follow_the_papers_paths():
    """Without --quick the sweeps of Figs. 7-9 are the paper's: its ranges, spacing, K and ensemble."""
    s = figures.settings_for(quick=False)
    assert (s.points, s.steps) == (paper.POINTS, paper.STEPS) == (10_000, 120_000)
    for name, path in paper.PATHS.items():
        points = figures.sweep_points(name, s)
        assert len(points) == path.count
        assert (points[0].b2, points[-1].b2) == path.b2_range
        assert all(p.K == path.K for p in points)
    assert all(p.b1 == theory.b1_on_maximal_path(p.b2) for p in figures.sweep_points("fig7", s))
    assert all(math.isclose(p.b1, 3 * p.b2, rel_tol=1e-15) for p in figures.sweep_points("fig8", s))
    assert all(p.b1 == 0.25 and p.K == 2.99 for p in figures.sweep_points("fig9", s))
