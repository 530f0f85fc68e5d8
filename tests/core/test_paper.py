"""warpratchet.paper: the paper's parameter sets, checked against its captions and the theory.

The numbers typed here are copied from the captions of Dana & Roitberg independently of
paper.py, so a typo on either side fails; the theory checks what the captions say of each set
(which islands exist, where a path ends, which limit it approaches).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from warpratchet import paper, theory
from warpratchet.params import MapParams


def test_rotation_angles_of_fig1_follow_eq_eig():
    a, b, c = paper.ROTATIONS
    assert [r.panel for r in paper.ROTATIONS] == ["a", "b", "c"]
    assert (a.alpha, b.alpha, c.alpha) == (2 * math.pi / 3, 6 * math.pi / 5, math.pi * (math.sqrt(5) - 1) / 2)
    # Panel (a) is K = 3 exactly, where Eq. (eig) rounds to 2.9999999999999996.
    assert a.K == 3.0 and abs(theory.K_from_alpha(a.alpha) - 3.0) <= 4.5e-16
    # (b) and (c): Eq. (eig) itself, bit for bit the theory's K_from_alpha.
    assert b.K == theory.K_from_alpha(b.alpha) and c.K == theory.K_from_alpha(c.alpha)
    # Fig. 1 caption: K = 3, K ~ 3.618, K ~ 2.7247 (rounded to the printed digits).
    assert (a.K_stated, b.K_stated, c.K_stated) == (3.0, 3.618, 2.7247)
    for r, digits in zip(paper.ROTATIONS, (0, 3, 4), strict=True):
        assert abs(r.K - r.K_stated) <= 0.5 * 10.0**-digits


def test_figs_1_and_2_share_their_K_and_differ_in_the_strip():
    assert paper.FIG1_WIDTHS == (0.05, 0.02)  # Fig. 1 caption
    assert paper.FIG2_WIDTHS == (1e-7, 1e-7)  # Fig. 2 caption: b1 = b2 = 10^-7
    for r, fig1, fig2 in zip(paper.ROTATIONS, paper.FIG1, paper.FIG2, strict=True):
        assert fig1 == MapParams(r.K, 0.05, 0.02) and fig2 == MapParams(r.K, 1e-7, 1e-7)
        # "The left (L) and right (R) period-1 accelerator-mode islands are indicated in each case."
        assert theory.domain(fig1) == "LR" and theory.domain(fig2) == "LR"


@pytest.mark.parametrize(
    ("params", "expected", "domain"),
    [
        (paper.FIG4, (3.0, 0.226, 0.02), "R"),  # Fig. 4: "only the right period-1 AI exists"
        (paper.FIG10, (3.0, 0.1, 0.05), "LR"),  # Fig. 10; Fig. 11: "both AIs, L and R, exist"
        (paper.FIG11, (3.0, 0.1, 0.05), "LR"),
        (paper.FIG12, (3.0, 0.3, 0.03), "R"),  # Fig. 12: "only the R AI exists"
    ],
)
def test_single_parameter_sets_and_their_domains(params, expected, domain):
    assert (params.K, params.b1, params.b2) == expected
    assert theory.domain(params) == domain


@pytest.mark.parametrize(
    ("path", "K", "kind", "b2_range", "count"),
    [
        (paper.FIG7, 3.0, "maximal", (0.005, 0.165), 33),
        (paper.FIG7_INSET, 3.0, "maximal", (0.00025, 0.00475), 19),
        (paper.FIG8, 3.0, "line", (0.005, 0.1), 20),
        (paper.FIG9, 2.99, "fixed-b1", (0.005, 0.14), 28),
    ],
)
def test_paths_of_figs_7_to_9(path, K, kind, b2_range, count):
    assert (path.K, path.kind, path.b2_range, path.count) == (K, kind, b2_range, count)
    values = path.b2_values()
    assert values.shape == (count,) and (values[0], values[-1]) == b2_range
    np.testing.assert_allclose(np.diff(values), path.b2_spacing, rtol=1e-9)
    assert path.b2_values(4).shape == (4,)


def test_path_parameters_and_stated_numbers():
    assert paper.FIG8.a == 1 / 3  # b1 = 3 b2 is b1 = b2 / a
    assert paper.FIG9.b1 == 0.25
    assert list(paper.PATHS) == ["fig7", "fig7_inset", "fig8", "fig9"]
    # Fig. 8 caption: the limit 0.125 of Eq. (Ama) at a = 1/3, and A ~ 0.12 for small sigma.
    assert theory.limit_on_line(paper.FIG8.a) == pytest.approx(paper.FIG8_LIMIT, abs=1e-15)
    assert abs(paper.FIG8_SMALL_SIGMA_A - paper.FIG8_LIMIT) < 0.01
    # The maximal path ends at b1 = b2 = 1/6 (the text after Eq. b2max).
    assert theory.b1_on_maximal_path(paper.MAXIMAL_PATH_END) == pytest.approx(paper.MAXIMAL_PATH_END)
    # The domain lines of Fig. 3 meet the axes at the edge of the plane shown, F(0) = 1/2 at K = 3.
    assert theory.F(0.0, paper.K3) == paper.PLANE_EXTENT
    assert (paper.POINTS, paper.STEPS, paper.SAMPLER) == (10_000, 120_000, "strip")
    assert paper.FIG9_SIGMA == (0.4787, 0.8326)


def test_paper_is_pure():
    """paper.py imports nothing of the project but params, and no Warp (house rule for pure modules)."""
    import ast
    import inspect

    tree = ast.parse(inspect.getsource(paper))
    imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    imported |= {
        ("." * node.level) + (node.module or "")
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom)
    }
    assert imported <= {"__future__", "math", "dataclasses", "typing", "numpy", ".params"}, imported
