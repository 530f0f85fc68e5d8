"""MapParams: validation and the derived coefficients of Eq. (mmc)."""

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from warpratchet.params import MapParams


@pytest.mark.parametrize(
    ("K", "b1", "b2", "names"),
    [
        (0.0, 0.1, 0.1, "K = 0.0"),
        (4.0, 0.1, 0.1, "K = 4.0"),
        (-1.0, 0.1, 0.1, "0 < K < 4"),
        (float("nan"), 0.1, 0.1, "K = nan"),
        (float("inf"), 0.1, 0.1, "K = inf"),
        (3.0, 0.0, 0.1, "b1 = 0.0"),
        (3.0, -0.1, 0.1, "b1 > 0"),
        (3.0, 0.1, 0.0, "b2 = 0.0"),
        (3.0, 0.6, 0.4, "b1 + b2"),
        (3.0, 0.1, float("nan"), "b2 = nan"),
        (3.0, "0.1", 0.1, "b1 = '0.1'"),
        (True, 0.1, 0.1, "K = True"),
    ],
)
def test_bad_parameters_are_rejected_with_the_value_named(K, b1, b2, names):
    with pytest.raises(ValueError) as err:
        MapParams(K, b1, b2)
    message = str(err.value)
    assert names in message
    assert "\n" not in message


def test_boundary_values_just_inside_are_accepted():
    MapParams(1e-300, 1e-300, 1e-300)
    MapParams(np.nextafter(4.0, 0.0), 0.5, 0.5 - 1e-15)


def _exact(b1: float, b2: float) -> tuple[Fraction, Fraction, Fraction]:
    """Eq. (mmc) in exact rational arithmetic on the float inputs."""
    B1, B2 = Fraction(b1), Fraction(b2)
    l1 = (1 - B1) * (1 - B1 - B2) / (B1 * (2 - B1 - B2))
    l2 = (1 - B2) * (1 - B1 - B2) / (B2 * (2 - B1 - B2))
    c = (1 - B2) / (2 - B1 - B2)
    return l1, l2, c


def _relative(value: float, exact: Fraction) -> float:
    return abs(Fraction(value) - exact) / abs(exact)


@given(
    st.floats(1e-9, 0.999, allow_nan=False),
    st.floats(1e-9, 0.999, allow_nan=False),
)
def test_coefficients_are_accurate_to_rounding_down_to_tiny_widths(b1, b2):
    """l1, l2, c of Eq. (mmc) within a few ulps of exact arithmetic, b1, b2 down to 1e-9 (Fig. 2)."""
    if b1 + b2 >= 1.0:
        return
    p = MapParams(3.0, b1, b2)
    l1, l2, c = _exact(b1, b2)
    for value, exact in ((p.l1, l1), (p.l2, l2), (p.c, c)):
        assert _relative(value, exact) < 8 * 2.0**-53


@given(st.floats(1e-9, 0.9), st.floats(1e-9, 0.9))
def test_force_is_continuous_and_has_zero_mean(b1, b2):
    """Continuity, Eq. (lb), and the ratchet condition int_0^1 f dx = 0 (Appendix A), exactly."""
    if b1 + b2 >= 1.0:
        return
    l1, l2, c = _exact(b1, b2)
    B1, B2 = Fraction(b1), Fraction(b2)
    assert l1 * B1 == c - B1
    assert l2 * B2 == 1 - B2 - c
    # Integral of each linear branch: l1 b1^2/2, then c - x over (b1, 1-b2), then l2 (x-1) over (1-b2, 1).
    mid_lo, mid_hi = B1, 1 - B2
    integral = l1 * B1**2 / 2 + c * (mid_hi - mid_lo) - (mid_hi**2 - mid_lo**2) / 2 - l2 * B2**2 / 2
    assert integral == 0


def test_force_values_and_slopes_on_each_branch():
    p = MapParams(3.0, 0.1, 0.05)
    x = np.array([0.0, 0.05, 0.1, 0.5, 0.94, 0.95, 0.99])
    f = p.force(x)
    expected = [0.0, p.l1 * 0.05, p.l1 * 0.1, p.c - 0.5, p.c - 0.94, p.l2 * (0.95 - 1.0), p.l2 * (0.99 - 1.0)]
    np.testing.assert_array_equal(f, expected)
    np.testing.assert_array_equal(p.force_slope(x), [p.l1, p.l1, p.l1, -1, -1, p.l2, p.l2])
    # The maximal |f| is below 1/2 (used for Eq. wK).
    grid = np.linspace(0, 1, 100_001, endpoint=False)
    assert np.max(np.abs(p.force(grid))) < 0.5


@given(st.floats(0.01, 3.99), st.floats(1e-6, 0.45), st.floats(1e-6, 0.45), st.floats(0, 1, exclude_max=True))
def test_tangent_map_is_area_preserving(K, b1, b2, x):
    """det DM = 1 on every branch (the map is symplectic, used in Eq. proof)."""
    J = MapParams(K, b1, b2).jacobian(np.array([x]))[0]
    scale = 1.0 + np.abs(J).max() ** 2
    assert abs(np.linalg.det(J) - 1.0) < 1e-14 * scale


def test_middle_branch_is_elliptic_with_rotation_angle_alpha():
    """Eq. (eig): eigenvalues exp(+-i alpha) with 2 cos(alpha) = 2 - K in the middle interval."""
    for K in (1.0, 2.0, 3.0, 3.618, 2.7247):
        p = MapParams(K, 0.05, 0.02)
        eig = np.linalg.eigvals(p.jacobian(np.array([0.5]))[0])
        np.testing.assert_allclose(np.abs(eig), 1.0, atol=1e-12)
        np.testing.assert_allclose(sorted(np.abs(np.angle(eig))), [p.alpha, p.alpha], atol=1e-12)
