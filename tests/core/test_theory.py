"""Every closed form of the paper against a second, independent route to the same number."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from warpratchet import theory
from warpratchet.params import MapParams

# (b1, b2) at K = 3 in each domain of Fig. 3.
LR_POINTS = [(0.1, 0.01), (0.05, 0.02), (0.01, 0.1), (0.1, 0.05), (0.1001, 0.02), (0.15, 0.15)]
R_POINTS = [(0.3, 0.03), (0.226, 0.02), (0.25, 0.1)]
L_POINTS = [(0.03, 0.3), (0.02, 0.226)]
NONE_POINTS = [(0.3, 0.3), (0.2, 0.2), (0.6, 0.3)]


def P(b1, b2, K=3.0):
    return MapParams(K, b1, b2)


def test_domains_of_fig3():
    assert {theory.domain(P(*b)) for b in LR_POINTS} == {"LR"}
    assert {theory.domain(P(*b)) for b in R_POINTS} == {"R"}
    assert {theory.domain(P(*b)) for b in L_POINTS} == {"L"}
    assert {theory.domain(P(*b)) for b in NONE_POINTS} == {"none"}


@given(st.floats(2.0, 3.99), st.floats(1e-6, 0.9), st.floats(1e-6, 0.9))
def test_existence_condition_lai_agrees_with_cam_before_the_pole(K, b1, b2):
    """Eq. (lai) b2 < F(b1) is Eq. (cam) rewritten, valid where K - 1 - K b1 > 0."""
    if b1 + b2 >= 1 or K - 1 - K * b1 <= 1e-9 or K - 1 - K * b2 <= 1e-9:
        return
    p = P(b1, b2, K)
    if abs(b2 - theory.F(b1, K)) > 1e-9:
        assert theory.island_exists(p, "L") == (b2 < theory.F(b1, K))
    if abs(b1 - theory.F(b2, K)) > 1e-9:
        assert theory.island_exists(p, "R") == (b1 < theory.F(b2, K))


def test_lai_fails_past_its_pole_and_cam_is_used():
    """Past b1 = (K-1)/K the printed inequality would claim an island that Eq. (cam) excludes."""
    p = P(0.9, 0.05)
    assert 0.05 < theory.F(0.9, 3.0)  # what Eq. (lai) taken literally would say
    assert not theory.island_exists(p, "L")
    x0 = p.c - 1.0 / p.K
    assert not p.b1 < x0  # Eq. (cam) directly


@given(st.floats(0.01, 3.99), st.floats(1e-6, 0.9), st.floats(1e-6, 0.9))
def test_modes_exist_only_for_K_at_least_2_and_imply_ccs(K, b1, b2):
    """Eq. (wK): w = +-1 only for 2 <= K < 4; Eq. (ccs) is necessary for any island."""
    if b1 + b2 >= 1:
        return
    p = P(b1, b2, K)
    modes = theory.accelerator_modes(p)
    if K < 2:
        assert modes == []
    if modes:
        assert theory.necessary_condition(p)
    for w, x0 in modes:
        # x0 is a fixed point of the lifted map up to the winding w (Eq. am with m = 1).
        assert abs(K * p.force(x0) - w) < 1e-12


@given(st.floats(2.01, 3.99), st.floats(1e-6, 0.49))
def test_symmetric_bound_lais(K, b):
    p = P(b, b, K)
    bound = theory.symmetric_bound(K)
    if abs(b - bound) > 1e-9:
        assert (theory.domain(p) == "LR") == (b < bound)
        assert (theory.domain(p) == "none") == (b > bound)


@given(st.floats(2.01, 3.99), st.floats(1e-6, 0.9))
def test_F_is_below_the_ccs_line(K, b):
    """F(b) <= (K-2)/(K-1) - b (Sec. III C), the step from Eqs. (ca)-(cc) to Eq. (ccs)."""
    if K - 1 - K * b > 1e-6:
        assert theory.F(b, K) <= (K - 2) / (K - 1) - b + 1e-12


@pytest.mark.parametrize("b", LR_POINTS + R_POINTS + L_POINTS + NONE_POINTS)
def test_A_equals_sum_rule_with_the_areas(b):
    """Eqs. (Aa), (Ab) and 0 against A = (S_R - S_L)/S_C, Eq. (Ae), with Eqs. (SL), (SR), (SC1)-(SC3)."""
    p = P(*b)
    A = theory.acceleration(p)
    if theory.domain(p) == "none":
        assert A == 0.0 and theory.area_chaotic(p) is None
        assert theory.area_left(p) == theory.area_right(p) == 0.0
        return
    via_areas = (theory.area_right(p) - theory.area_left(p)) / theory.area_chaotic(p)
    assert A == pytest.approx(via_areas, rel=1e-12, abs=1e-15)


@given(st.floats(1e-6, 0.9), st.floats(1e-6, 0.9))
def test_antisymmetry_and_zero_on_the_diagonal(b1, b2):
    """A(b2, b1) = -A(b1, b2) (Sec. V) and A = 0 for b1 = b2 (inversion symmetry, Sec. II)."""
    if b1 + b2 >= 1:
        return
    A12, A21 = theory.acceleration(P(b1, b2)), theory.acceleration(P(b2, b1))
    assert A12 == pytest.approx(-A21, rel=1e-10, abs=1e-14)
    assert theory.acceleration(P(b1, b1)) == 0.0 if 2 * b1 < 1 else True


@pytest.mark.parametrize("b2", [1e-8, 1e-4, 0.005, 0.02, 0.08, 0.165])
def test_maximal_path_is_a_stationary_maximum_and_Amax_follows_from_Aa(b2):
    """Eq. (b2max): dA/db1 = 0 and d2A/db1^2 < 0; A on the path equals Eq. (Aa) there."""
    b1 = theory.b1_on_maximal_path(b2)
    assert theory.domain(P(b1, b2)) == "LR"

    def A(x):
        return theory.acceleration_both_islands(x, b2)

    h = 1e-6 * b1
    slope = (A(b1 + h) - A(b1 - h)) / (2 * h)
    curvature = (A(b1 + h) - 2 * A(b1) + A(b1 - h)) / h**2
    assert abs(slope) < 1e-5 * abs(curvature) * b1 + 1e-9
    assert curvature < 0
    assert theory.acceleration_on_maximal_path(b2) == pytest.approx(A(b1), rel=1e-10)


def test_printed_Amax_is_a_misprint():
    """The paper's Eq. (Amax) disagrees with Eq. (Aa) on the path of Eq. (b2max): 7% at b2 = 0.02."""
    b2 = 0.02
    exact = theory.acceleration_both_islands(theory.b1_on_maximal_path(b2), b2)
    printed = theory.acceleration_on_maximal_path_as_printed(b2)
    assert printed / exact == pytest.approx(0.9320, abs=1e-3)
    # ... while both share the end points of Sec. V.
    assert theory.acceleration_on_maximal_path_as_printed(1 / 6) == pytest.approx(0.0, abs=1e-15)


def test_A_decreases_along_the_maximal_path_from_one_quarter():
    """Eq. (Am) and the monotonic decrease claimed in Sec. V."""
    b2 = np.geomspace(1e-12, 1 / 6, 400)
    A = np.array([theory.acceleration_on_maximal_path(v) for v in b2])
    assert np.all(np.diff(A) < 0)
    assert A[0] == pytest.approx(theory.LIMIT_MAXIMAL_PATH, abs=1e-5)
    assert A[-1] == pytest.approx(0.0, abs=1e-12)
    # Approach to the limit from Eq. (Aa) directly, with b1 ~ 2 sqrt(b2/5).
    assert theory.acceleration_both_islands(2 * math.sqrt(1e-14 / 5), 1e-14) == pytest.approx(0.25, abs=1e-6)


@pytest.mark.parametrize("a", [1 / 3, 0.5, 2.0, 10.0])
def test_limit_on_straight_lines(a):
    """Eq. (Ama): (1 - a)/(4 (1 + a)) on b1 = b2/a as b2 -> 0, from Eq. (Aa)."""
    b2 = 1e-10 * min(a, 1.0)
    assert theory.acceleration_both_islands(b2 / a, b2) == pytest.approx(theory.limit_on_line(a), abs=1e-8)
    assert theory.limit_on_line(1 / 3) == pytest.approx(0.125)


def test_K_values_of_fig1():
    assert theory.K_from_alpha(2 * math.pi / 3) == pytest.approx(3.0)
    assert theory.K_from_alpha(6 * math.pi / 5) == pytest.approx(3.618, abs=1e-3)
    assert theory.K_from_alpha(math.pi * (math.sqrt(5) - 1) / 2) == pytest.approx(2.7247, abs=1e-4)


def test_area_formulas_refuse_other_K():
    p = P(0.1, 0.01, K=2.99)
    for f in (theory.area_left, theory.area_right, theory.area_chaotic, theory.acceleration):
        with pytest.raises(ValueError, match="K = 3"):
            f(p)
    s = theory.summary(p)
    assert s["domain"] == "LR" and s["A"] is None and s["S_C"] is None


def test_bad_path_arguments():
    with pytest.raises(ValueError, match="b2 = 0.2"):
        theory.b1_on_maximal_path(0.2)
    with pytest.raises(ValueError, match="a = -1"):
        theory.limit_on_line(-1.0)


# -- areas by an independent route: the islands as sets of period-3 orbits --------------------
def _island_areas_by_monte_carlo(p: MapParams, n: int, seed: int):
    """At K = 3 the middle-branch DM satisfies DM^3 = I (alpha = 2 pi/3), so a point whose three
    iterates stay out of the strip B returns to itself and is regular forever; every other point
    visits B, i.e. lies in C = B u MB u M^2 B (Eq. Cs). Classify uniform random points that way
    and by their momentum gain over three steps (3w, w = +1 for L, -1 for R, 0 normal)."""
    rng = np.random.default_rng(seed)
    x, pm = rng.random(n), rng.random(n)
    x_start, p_start = x.copy(), pm.copy()
    stays_out = np.ones(n, dtype=bool)
    for _ in range(3):
        stays_out &= (x > p.b1) & (x < 1 - p.b2)
        pm = pm + p.K * p.force(x)
        x = np.mod(x + pm, 1.0)
    gain = np.rint(pm - p_start)
    assert np.allclose(np.mod(x[stays_out] - x_start[stays_out] + 0.5, 1) - 0.5, 0, atol=1e-9)
    fractions = {
        "L": np.mean(stays_out & (gain == 3)),
        "R": np.mean(stays_out & (gain == -3)),
        "C": np.mean(~stays_out),
    }
    return {k: (f, math.sqrt(f * (1 - f) / n)) for k, f in fractions.items()}


@pytest.mark.parametrize("b", [(0.1, 0.01), (0.1, 0.05), (0.3, 0.03), (0.226, 0.02), (0.03, 0.3)])
def test_areas_SL_SR_SC_against_period3_monte_carlo(b):
    p = P(*b)
    est = _island_areas_by_monte_carlo(p, 2_000_000, seed=7)
    for key, exact in (
        ("L", theory.area_left(p)),
        ("R", theory.area_right(p)),
        ("C", theory.area_chaotic(p)),
    ):
        value, err = est[key]
        assert abs(value - exact) < 4 * err + 1e-12, (key, value, exact, err)
