"""Island census and sum rule (warpratchet.sumrule): indicators, nu identification, Eqs. (sum), (proof).

Statistical checks compare with the closed forms at K = 3 within 4 computed standard errors plus
the census's own measured misassignment (points whose census class disagrees with Eq. Cs, a
computed bias bound, reported in ``Census.C_check``).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from warpratchet import MapParams, theory
from warpratchet.cli import main
from warpratchet.ensemble import STATE_FIELDS, Ensemble
from warpratchet.reference import advance
from warpratchet.regions import in_C
from warpratchet.sumrule import (
    MEGNO_THRESHOLD,
    IndicatorEnsemble,
    census,
    identify_nu,
    lattice,
    min_steps,
)

STEPS = 16_000  # >= min_steps(12) = 13824
POINTS = 40_000


def _points(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.random(n), rng.random(n)


# -- the indicator kernel -------------------------------------------------------------------------
def test_indicator_kernel_leaves_the_orbit_bitwise_unchanged():
    p = MapParams(2.99, 0.1, 0.01)
    x, y = _points(3001, 1)
    plain = Ensemble(p, x, y, threads=2).run(1000, chunk_steps=77)
    with_indicators = IndicatorEnsemble(p, x, y, threads=1).run(1000, chunk_steps=123)
    a, b = plain.state(), with_indicators.state()
    for name in STATE_FIELDS:
        assert np.array_equal(a[name], b[name]), name


def test_megno_and_fli_match_a_numpy_reference():
    """MEGNO and FLI of M^8 recomputed from the NumPy twin of the kernel, step by step."""
    p = MapParams(3.0, 0.1, 0.05)
    x, y = _points(64, 2)
    ens = IndicatorEnsemble(p, x, y, threads=1).run(400, chunk_steps=37)
    state = {k: v.copy() for k, v in Ensemble(p, x, y).state().items()}
    fli = np.zeros(x.size)
    lsum_megno = np.zeros(x.size)
    ysum = np.zeros(x.size)
    for j in range(1, 51):
        state.update(advance(p, state, 8, step0=8 * (j - 1)))
        big_l = state["log_stretch"] + 0.5 * np.log(state["dx"] ** 2 + state["dp"] ** 2)
        fli = np.maximum(fli, big_l)
        ysum += 2.0 * big_l - 2.0 * lsum_megno / j  # Y(j) = 2 L_j - (2/j) sum_{i<j} L_i
        lsum_megno += big_l
    got = ens.indicators()
    assert np.allclose(got["fli"], fli, rtol=1e-12, atol=1e-12)
    assert np.allclose(got["megno"], ysum / 50, rtol=1e-10, atol=1e-10)


def test_megno_limits_at_K3():
    """Period-1 islands: DM^3 = I (Eq. eig, alpha = 2 pi/3), so the MEGNO of M^8 tends to 0;
    chaotic orbits: <Y> ~ sigma n / 2."""
    p = MapParams(3.0, 0.1, 0.01)
    x, y = _points(4000, 3)
    n = 4000
    ens = IndicatorEnsemble(p, x, y).run(n)
    ind = ens.indicators()
    ftle = (ens.array("log_stretch") + np.log(np.hypot(ens.array("dx"), ens.array("dp")))) / n
    outside = ~in_C(p, x, y)
    j = n // 8
    # Y(j) = 2 (L_j - mean L) + O(1/j) for a periodic L, so |<Y>(J)| <= 4 max|L| (1 + ln J) / J.
    big_l_max = np.max(np.abs(ind["fli"][outside])) + 1.0
    assert np.all(np.abs(ind["megno"][outside]) <= 4.0 * big_l_max * (1.0 + math.log(j)) / j)
    chaotic = ~outside
    ratio = ind["megno"][chaotic] / (ftle[chaotic] * n / 2.0)
    # <Y>(J) = sigma'(J + 3)/2 for L_j = sigma' j exactly; a varying local rate weights late
    # growth more than the FTLE does, so only the typical orbit sits at ratio 1.
    assert abs(np.median(ratio) - 1.0) < 0.05
    # Sticky orbits of C can look regular for a while (~1e-4 of C at 3e4 steps, see docs).
    assert (ind["megno"][chaotic] > MEGNO_THRESHOLD).mean() >= 0.995


# -- nu = w/m -------------------------------------------------------------------------------------
def test_identify_nu_finds_reduced_rationals_and_rejects_diffusion():
    times = np.arange(1, 9) * 2000
    rng = np.random.default_rng(4)
    nus = [(0, 1), (1, 1), (-1, 1), (1, 3), (-2, 5), (2, 12), (7, 11)]
    rises = []
    for w, m in nus:
        # a bounded excursion of at most 2m (the bound is 4m) around the line k w/m
        rises.append(times * (w / m) + rng.uniform(-2.0 * m, 2.0 * m, times.size))
    # Diffusion like the chaotic sea at K = 3 (std of p_n - p_0 ~ 450 after 3e4 steps).
    walk = np.cumsum(rng.normal(0.0, 300.0, (times.size, 500)), axis=0) + 0.145 * times[:, None]
    rise = np.concatenate([np.array(rises).T, walk], axis=1)
    w, m = identify_nu(rise, times, 12)
    expected = [(0, 1), (1, 1), (-1, 1), (1, 3), (-2, 5), (1, 6), (7, 11)]  # 2/12 -> 1/6
    assert list(zip(w[: len(nus)].tolist(), m[: len(nus)].tolist(), strict=True)) == expected
    assert np.all(m[len(nus) :] == 0)


def test_identify_nu_needs_enough_steps():
    with pytest.raises(ValueError, match="need steps >= 13824"):
        identify_nu(np.zeros((1, 3)), np.array([1000]), 12)
    with pytest.raises(ValueError, match="m_max = 0"):
        identify_nu(np.zeros((1, 3)), np.array([10**6]), 0)
    assert min_steps(4) == 512


# -- the census against the closed forms at K = 3 ----------------------------------------------------
@pytest.fixture(scope="module", params=["maximal path", "R domain (Fig. 12)"])
def k3_census(request):
    b1, b2 = {"maximal path": (theory.b1_on_maximal_path(0.02), 0.02), "R domain (Fig. 12)": (0.3, 0.03)}[
        request.param
    ]
    p = MapParams(3.0, b1, b2)
    return p, census(p, STEPS, points=POINTS, seed=11)


def test_areas_match_SL_SR_SC(k3_census):
    p, c = k3_census
    # Points the census put on the wrong side of Eq. (Cs) (sticky orbits, counted exactly).
    bias = c.C_check["not_C_inside_Cs"] + c.C_check["C_outside_Cs"]
    assert abs(c.S_C - theory.area_chaotic(p)) <= 4.0 * c.S_C_stderr + bias
    for nu, exact in ((1.0, theory.area_left(p)), (-1.0, theory.area_right(p))):
        island = c.island(nu)
        if exact == 0.0:
            assert island is None or island.area <= bias
        else:
            assert abs(island.area - exact) <= 4.0 * island.area_stderr + bias


def test_sum_rule_and_direct_mean_match_Aa_Ab(k3_census):
    p, c = k3_census
    a_exact = theory.acceleration(p)
    # The sum rule moves by at most |A| + max|nu| = |A| + 1 per unit of misassigned area.
    bias = (c.C_check["not_C_inside_Cs"] + c.C_check["C_outside_Cs"]) * (abs(a_exact) + 1.0) / c.S_C
    assert abs(c.A_sumrule - a_exact) <= 4.0 * c.A_sumrule_stderr + bias
    assert abs(c.A_direct - a_exact) <= 4.0 * c.A_direct_stderr + bias
    assert abs(c.A_force - a_exact) <= 4.0 * c.A_force_stderr + bias
    assert abs(c.torus_mean_A) <= 4.0 * c.torus_mean_A_stderr  # Eq. (proof)


def test_paper_assumptions_at_K3(k3_census):
    """Outside Eq. (Cs) nothing is chaotic (those orbits never meet B, Sec. IV), and every
    island class found is period-1 (Sec. III C) up to the sticky points counted in C_check."""
    p, c = k3_census
    assert c.C_check["chaotic_outside_Cs"] == 0.0
    assert c.C_check["islands_beyond_period_1"] <= c.C_check["not_C_inside_Cs"]
    assert c.unidentified_area <= c.C_check["regular_inside_Cs"]


def test_lattice_avoids_kinks_and_sloped_edges():
    """No node on x = b1, 1 - b2 (Eq. fx) nor on the edges p = x - b1, x + b2 (Eq. B1e) or on a
    slope-2 line p = 2x + k/G (Eq. B2e), even when b1, b2 are multiples of the spacing."""
    side = 450
    x, p = lattice(side)
    assert x.shape == p.shape == (side * side,)
    for line in (x - 0.1, x - 0.99, p - x + 0.1, p - x - 0.01, p - 2.0 * x):
        frac = np.mod(line * side, 1.0)
        assert np.min(np.minimum(frac, 1.0 - frac)) > 1e-6


def test_grid_census_areas_within_their_bound():
    p = MapParams(3.0, 0.1, 0.01)
    c = census(p, STEPS, grid=200)
    assert c.error_kind == "bound" and c.points == 200 * 200
    assert c.torus_mean_A_stderr is None
    assert abs(c.S_C - theory.area_chaotic(p)) <= c.S_C_stderr
    assert abs(c.island(1.0).area - theory.area_left(p)) <= c.island(1.0).area_stderr
    assert abs(c.island(-1.0).area - theory.area_right(p)) <= c.island(-1.0).area_stderr
    assert abs(c.A_sumrule - theory.acceleration(p)) <= c.A_sumrule_stderr


def test_sum_rule_and_direct_mean_agree_without_closed_forms():
    """K = 2.99 on Fig. 9's path: no closed form, but both routes to A must agree.

    A_direct - A_sumrule = (torus mean of A_n)/S_C up to O(1/n) terms, so the pair's error is the
    torus mean's, a computed standard error."""
    p = MapParams(2.99, 0.25, 0.05)
    c = census(p, STEPS, points=POINTS, seed=12)
    assert abs(c.A_direct - c.A_sumrule) <= 4.0 * c.torus_mean_A_stderr / c.S_C + 4.0 * c.A_direct_stderr
    assert abs(c.torus_mean_A) <= 4.0 * c.torus_mean_A_stderr


# -- command line ----------------------------------------------------------------------------------
def test_cli_sumrule_json(capsys):
    code = main(["sumrule", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--points", "3000", "--steps", "14000",
                 "--json", "--quiet"])  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    keys = ("S_C", "islands", "A_sumrule", "A_sumrule_stderr", "A_direct", "A_direct_stderr", "torus_mean_A")
    assert all(key in out for key in keys)
    assert {"nu", "m", "w", "area", "area_stderr"} <= set(out["islands"][0])
    assert {(i["w"], i["m"]) for i in out["islands"]} <= {(-1, 1), (0, 1), (1, 1)}


def test_cli_sumrule_text_at_k3_compares_with_eq_cs(capsys):
    """README: at K = 3 the text prints the closed forms and the point-by-point comparison with Eq. (Cs)."""
    argv = ["sumrule", "--K", "3", "--b1", "0.1", "--b2", "0.01", "--points", "2000", "--steps", "14000"]
    assert main([*argv, "--quiet"]) == 0
    text = capsys.readouterr().out
    assert main([*argv, "--quiet", "--json"]) == 0
    check = json.loads(capsys.readouterr().out)["C_check"]
    [line] = [line for line in text.splitlines() if "Eq. (Cs)" in line]
    for key, share in check.items():
        assert f"{key.replace('_', ' ')} {share:.2g}" in line


def test_classifier_benchmark_quick(capsys):
    """benchmarks/classifiers.py runs and reports a consistent agreement curve (no timings checked)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "classifiers.py"
    spec = importlib.util.spec_from_file_location("classifiers_benchmark", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--json", "--points", "400", "--reference", "2000"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert len(report["cases"]) == len(module.CASES)
    for case in report["cases"]:
        ftle = case["indicators"]["ftle"]
        assert ftle["agreement"][-1] == [2000, 1.0]  # the reference agrees with itself
        for result in case["indicators"].values():
            steps = result["steps_to_999"]
            assert steps is None or steps in [n for n, _ in result["agreement"]]
            assert all(0.0 <= share <= 1.0 for _, share in result["agreement"])
