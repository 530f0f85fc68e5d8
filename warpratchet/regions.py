"""The regions of Appendices B-E: the strip B, its images under the torus map, and C.

Membership tests on the unit torus, vectorised in NumPy, for plotting Figs. 10-12 and for
checking the paper's geometry. Every test takes ``(params, x, p)`` with ``x, p`` array_like of
one shape (broadcast) and returns a boolean array of that shape; points are taken mod 1.

* ``B`` (Eq. B): the hyperbolic strip ``0 <= x <= b1`` or ``1 - b2 <= x < 1``;
* ``M B`` (Eq. B1): ``x - b1 <= p <= x + b2`` mod 1, for every ``K`` (``x1 = x0 + p1`` with
  ``p1`` arbitrary);
* ``B^(1)`` (Eq. B1e): ``M B`` minus ``B``, the slope-1 parallelogram over the middle interval;
* ``B^(2) = M B^(1)`` (Eq. B2), the folded slope-2 parallelogram of Eq. (B2e);
* ``C = B u M B u M^2 B`` (Eq. Cs), exact at ``K = 3`` (Appendix B).

Images are tested through the inverse map: ``z`` is in ``M^s B`` iff ``M^-s z`` is in ``B``.
A point within a few ulps of a region's edge may land on either side; such points have zero
area.
"""

from __future__ import annotations

import numpy as np

from .errors import check_count
from .params import MapParams

__all__ = [
    "torus_map",
    "inverse_torus_map",
    "in_strip",
    "in_image",
    "in_MB",
    "in_B1",
    "in_B2",
    "in_C",
    "B2_vertices",
]


def _fold(v: np.ndarray) -> np.ndarray:
    """``v mod 1`` in ``[0, 1)``: ``np.mod`` of a tiny negative number rounds to 1.0."""
    v = np.mod(v, 1.0)
    return np.where(v >= 1.0, 0.0, v)


def _points(x, p) -> tuple[np.ndarray, np.ndarray]:
    x, p = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(p, dtype=np.float64))
    return _fold(x), _fold(p)


def torus_map(params: MapParams, x, p) -> tuple[np.ndarray, np.ndarray]:
    """One step of the torus map ``M`` (Eq. cpem mod 1): ``p' = p + K f(x)``, ``x' = x + p'``.

    Parameters
    ----------
    params : MapParams
    x, p : array_like, same shape (broadcast)
        Points of the unit torus (taken mod 1).

    Returns
    -------
    x1, p1 : ndarray
        The images, in ``[0, 1)``.
    """
    x, p = _points(x, p)
    p1 = _fold(p + params.K * params.force(x))
    return _fold(x + p1), p1


def inverse_torus_map(params: MapParams, x, p) -> tuple[np.ndarray, np.ndarray]:
    """One step of ``M^-1``: ``x0 = x - p``, ``p0 = p - K f(x0)`` (mod 1), inverting Eq. (cpem)."""
    x, p = _points(x, p)
    x0 = _fold(x - p)
    return x0, _fold(p - params.K * params.force(x0))


def in_strip(params: MapParams, x, p) -> np.ndarray:
    """Membership of the strip ``B`` of Eq. (B): ``x <= b1`` or ``x >= 1 - b2`` (any ``p``); for
    another force, its pieces with ``f' > 0`` (:meth:`~warpratchet.force.Force.in_strip`)."""
    x, _ = _points(x, p)
    if not params.is_paper:
        return params.table.in_strip(x)
    return (x <= params.b1) | (x >= 1.0 - params.b2)


def in_image(params: MapParams, x, p, s: int) -> np.ndarray:
    """Membership of ``M^s B`` for an integer ``s >= 0``: ``M^-s z`` lies in ``B`` (any ``K``)."""
    s = check_count("s", s, 0)
    x, p = _points(x, p)
    for _ in range(s):
        x, p = inverse_torus_map(params, x, p)
    return in_strip(params, x, p)


def in_MB(params: MapParams, x, p) -> np.ndarray:
    """Membership of ``M B``, Eq. (B1): ``x - b1 <= p <= x + b2`` mod 1 (any ``K``).

    Written as ``d = (p - x) mod 1`` with ``d <= b2`` or ``d >= 1 - b1``; equal to
    ``in_image(params, x, p, 1)`` since ``x0 = x - p``.
    """
    params.require_paper("in_MB")
    x, p = _points(x, p)
    d = _fold(p - x)
    return (d <= params.b2) | (d >= 1.0 - params.b1)


def in_B1(params: MapParams, x, p) -> np.ndarray:
    """Membership of ``B^(1) = M B - B n M B``, Eq. (B1e) (Eq. Bb1).

    ``b1 < x < 1 - b2`` and ``x - b1 <= p <= x + b2`` with no wrap in ``p``: over the middle
    interval the band of Eq. (B1) lies inside ``0 <= p < 1``.
    """
    params.require_paper("in_B1")
    x, p = _points(x, p)
    middle = (x > params.b1) & (x < 1.0 - params.b2)
    return middle & (p >= x - params.b1) & (p <= x + params.b2)


def in_B2(params: MapParams, x, p) -> np.ndarray:
    """Membership of ``B^(2) = M B^(1)``, Eq. (B2): ``M^-1 z`` lies in ``B^(1)``.

    At ``K = 3`` this is the folded slope-2 parallelogram of Eq. (B2e) (Fig. 10c).
    """
    x0, p0 = inverse_torus_map(params, x, p)
    return in_B1(params, x0, p0)


def in_C(params: MapParams, x, p) -> np.ndarray:
    """Membership of ``C = B u M B u M^2 B`` (Eq. Cs), equal to Eq. (C) at ``K = 3``.

    Equivalently ``B u B^(1) u B^(2)`` (Appendix C). The paper assumes, and ``warpratchet.sumrule``
    tests, that ``C`` is the global chaotic region at ``K = 3``.

    Raises
    ------
    ValueError
        If ``K != 3``: Appendix B proves ``M C' = C'`` only at ``K = 3``; at other ``K`` the union
        of three images is not invariant and is not Eq. (C).
    """
    if params.K != 3.0:
        raise ValueError(f"K = {params.K!r}: C = B u MB u M^2 B (Eq. Cs) holds only at K = 3 (Appendix B)")
    x, p = _points(x, p)
    x1, p1 = inverse_torus_map(params, x, p)
    x2, p2 = inverse_torus_map(params, x1, p1)
    return in_strip(params, x, p) | in_strip(params, x1, p1) | in_strip(params, x2, p2)


def B2_vertices(params: MapParams) -> np.ndarray:
    """Vertices ``(x^(j), p^(j))``, ``j = 1..4``, of ``B^(2)`` at ``K = 3`` (Appendix C).

    Eq. (xj) for ``x^(j)`` and Eq. (pj) for ``p^(j)``, with the corrections stated after
    Eq. (pj): ``p^(1) -> x^(1) - b1 + 1`` when vertex 1 lies in the left part of ``B``
    (domain R), ``p^(3) -> x^(3) + b2 - 1`` when vertex 3 lies in the right part (domain L).
    They are the images under ``M`` of the vertices of ``B^(1)`` in Eq. (xpb).

    Returns
    -------
    ndarray, shape (4, 2)
        Rows ``(x^(j), p^(j))``.

    Raises
    ------
    ValueError
        If ``K != 3``, or if ``b1 + b2 >= 1/2`` (no island, Eq. ccs; Eq. xj then leaves the torus).
    """
    params.require_paper("B2_vertices")
    if params.K != 3.0:
        raise ValueError(f"K = {params.K!r}: Eqs. (xj)-(pj) hold only at K = 3 (Appendix C)")
    b1, b2, b, c = params.b1, params.b2, params.b, params.c
    if not b < 0.5:
        raise ValueError(f"b1 + b2 = {b!r} is outside the range b1 + b2 < 1/2 of Eqs. (xj)-(pj)")
    x1 = 3.0 * c - 2.0 * b1 - 1.0
    xs = np.array([x1, x1 + b, x1 + 2.0 * b, x1 + b])  # Eq. (xj)
    ps = np.array([xs[0] - b1, xs[1] - b1, xs[2] + b2, xs[3] + b2])  # Eq. (pj)
    if xs[0] < b1:
        ps[0] += 1.0
    if xs[2] > 1.0 - b2:
        ps[2] -= 1.0
    return np.stack([xs, ps], axis=1)
