"""The regions of Appendices B-E (warpratchet.regions) against the paper's geometry at K = 3."""

from __future__ import annotations

import math

import numpy as np
import pytest

from warpratchet import MapParams, theory
from warpratchet.regions import (
    B2_vertices,
    in_B1,
    in_B2,
    in_C,
    in_image,
    in_MB,
    in_strip,
    inverse_torus_map,
    torus_map,
)

# One parameter point per domain of Fig. 3, plus the two of the acceptance list.
K3_POINTS = {
    "LR": (0.1, 0.01),
    "LR maximal path": (theory.b1_on_maximal_path(0.02), 0.02),
    "R (Fig. 12)": (0.3, 0.03),
    "L": (0.02, 0.3),
    "none": (0.3, 0.3),
}


def _torus_points(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.random(n), rng.random(n)


@pytest.mark.parametrize("K", [2.5, 2.99, 3.0])
def test_inverse_map_inverts_the_map(K):
    p = MapParams(K, 0.1, 0.05)
    x, y = _torus_points(10_000, 1)
    x1, y1 = torus_map(p, *inverse_torus_map(p, x, y))
    # Distances on the torus: wrap differences into [-1/2, 1/2).
    assert np.max(np.abs((x1 - x + 0.5) % 1.0 - 0.5)) < 1e-12
    assert np.max(np.abs((y1 - y + 0.5) % 1.0 - 0.5)) < 1e-12


@pytest.mark.parametrize("K", [2.5, 3.0])
def test_explicit_MB_and_B1_match_their_definitions(K):
    p = MapParams(K, 0.1, 0.05)
    x, y = _torus_points(100_000, 2)
    mb = in_MB(p, x, y)
    assert np.array_equal(mb, in_image(p, x, y, 1))  # Eq. (B1) is M B for every K
    assert np.array_equal(in_B1(p, x, y), mb & ~in_strip(p, x, y))  # Eq. (B1e) = Eq. (Bb1)
    assert np.array_equal(in_image(p, x, y, 0), in_strip(p, x, y))


@pytest.mark.parametrize("label", list(K3_POINTS))
def test_C_is_invariant_at_K3(label):
    """Eq. (mc): M C' = C'. No point may change membership under one step (edges have zero area)."""
    p = MapParams(3.0, *K3_POINTS[label])
    x, y = _torus_points(200_000, 3)
    inside = in_C(p, x, y)
    assert np.array_equal(in_C(p, *torus_map(p, x, y)), inside)
    assert np.array_equal(in_C(p, *inverse_torus_map(p, x, y)), inside)


@pytest.mark.parametrize("label", list(K3_POINTS))
def test_B2_bar_maps_into_B(label):
    """Eq. (mb2): the part of B^(2) over the middle interval is mapped into the strip B."""
    p = MapParams(3.0, *K3_POINTS[label])
    x, y = _torus_points(200_000, 4)
    b2_bar = in_B2(p, x, y) & ~in_strip(p, x, y)
    assert b2_bar.sum() > 1000
    assert in_strip(p, *torus_map(p, x[b2_bar], y[b2_bar])).all()


@pytest.mark.parametrize("label", [k for k in K3_POINTS if k != "none"])
def test_area_of_C_matches_SC1_to_SC3(label):
    """Fraction of uniform points in C against Eqs. (SC1)-(SC3), within 4 binomial standard errors."""
    p = MapParams(3.0, *K3_POINTS[label])
    n = 400_000
    f = in_C(p, *_torus_points(n, 5)).mean()
    stderr = math.sqrt(f * (1.0 - f) / n)
    assert abs(f - theory.area_chaotic(p)) < 4.0 * stderr


@pytest.mark.parametrize("label", ["LR", "R (Fig. 12)"])
def test_overlap_of_B_and_B2(label):
    """Appendix E: S(B n B^(2)) = b^2 with both islands; without the L island the triangles
    def, efg of Fig. 12, of area (3c - 3b1 - 1)^2 / 2 (the Eq. SL expression), are missing."""
    p = MapParams(3.0, *K3_POINTS[label])
    n = 400_000
    x, y = _torus_points(n, 6)
    f = (in_strip(p, x, y) & in_B2(p, x, y)).mean()
    missing = 0.5 * (3.0 * p.c - 3.0 * p.b1 - 1.0) ** 2 if theory.domain(p) == "R" else 0.0
    expected = p.b**2 - missing
    assert abs(f - expected) < 4.0 * math.sqrt(f * (1.0 - f) / n)


@pytest.mark.parametrize("label", [k for k in K3_POINTS if k != "none"])
def test_B2_vertices_are_images_of_B1_vertices(label):
    """Eqs. (xj)-(pj) with Appendix C's corrections equal M applied to the vertices of Eq. (xpb)."""
    p = MapParams(3.0, *K3_POINTS[label])
    b1, b2, b = p.b1, p.b2, p.b
    xb = np.array([b1, b1, 1.0 - b2, 1.0 - b2])
    pb = np.array([0.0, b, 1.0, 1.0 - b])
    x, y = torus_map(p, xb, pb)
    vertices = B2_vertices(p)
    assert np.allclose(vertices[:, 0], x, atol=1e-12)
    assert np.allclose(vertices[:, 1], y, atol=1e-12)


def test_orbits_outside_C_never_visit_B():
    """Sec. IV: the complement of C is invariant, so its orbits stay in the elliptic middle interval."""
    p = MapParams(3.0, 0.1, 0.05)
    x, y = _torus_points(20_000, 7)
    outside = ~in_C(p, x, y)
    x, y = x[outside], y[outside]
    for _ in range(60):
        x, y = torus_map(p, x, y)
        assert not in_strip(p, x, y).any()


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="K = 2.99"):
        in_C(MapParams(2.99, 0.1, 0.01), 0.5, 0.5)
    with pytest.raises(ValueError, match="s = -1"):
        in_image(MapParams(3.0, 0.1, 0.01), 0.5, 0.5, -1)
    with pytest.raises(ValueError, match="b1 \\+ b2"):
        B2_vertices(MapParams(3.0, 0.3, 0.3))


def test_membership_broadcasts_and_keeps_shape():
    p = MapParams(3.0, 0.1, 0.01)
    x = np.linspace(0.0, 1.0, 7, endpoint=False)[:, None]
    y = np.linspace(0.0, 1.0, 5, endpoint=False)[None, :]
    assert in_C(p, x, y).shape == (7, 5)
    assert in_strip(p, 0.05, 0.5).shape == ()
