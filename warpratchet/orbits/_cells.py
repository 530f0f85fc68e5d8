"""Exact convex cells: the closure of the set of starting points that follow an itinerary.

A cell is a convex polygon in the starting point ``z0 = (x, q)``, held exactly: its edges are
integer lines ``a x + b q + c >= 0`` in ``z0`` and its vertices homogeneous integer points
``(X, Q, W)``, ``W > 0`` (the point ``(X/W, Q/W)``), each the crossing of two edge lines, so
the numbers never grow beyond twice a line's size. Each vertex also carries its image under the
itinerary so far, ``z_i = (x_i, q_i)``, as ``(xv, qv, sw)``, a positive multiple of
``(x_i, q_i, 1)``: the next symbol's half-planes have small integer coefficients in ``z_i``, so
testing a vertex costs small-by-large products, and a child updates ``(xv, qv, sw)`` by one
step of the map.

Integers, not floats: a cell of an ``m``-step itinerary is ``~Lambda^-m`` thin (``Lambda`` up to
``1 + K l2 ~ 140`` per step at b2 = 0.01) while its pulled-back edges are nearly parallel, so
float64 geometry cannot tell an empty cell from a thin one after a few steps.

A cell may degenerate to a segment or a point (points on a boundary line that the half-open
rules give to it); only closures are computed here, the half-open rules are applied by
:meth:`~warpratchet.orbits._exact.ExactMap.follows`.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction

from ._exact import Composite, ExactMap

__all__ = ["Cell", "unit_square", "clip", "advance", "at_start", "vertices", "area"]

#: ``(vertices, lines)``: vertex ``(X, Q, W, xv, qv, sw)``; vertex ``i`` to vertex ``i + 1`` runs
#: along ``lines[i]`` (counter-clockwise).
Cell = tuple[list[tuple[int, ...]], list[tuple[int, int, int]]]


def unit_square() -> Cell:
    """``[0, 1]^2`` at depth 0 (``z_0 = z0``): edges ``q >= 0``, ``x <= 1``, ``q <= 1``, ``x >= 0``."""
    corners = [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    return [c + c for c in corners], [(0, 1, 0), (-1, 0, 1), (0, -1, 1), (1, 0, 0)]


def _vertex(l1: tuple[int, int, int], l2: tuple[int, int, int], comp: Composite) -> tuple[int, ...]:
    """The crossing of two non-parallel lines (``W > 0``) with its image ``(xv, qv, sw) ~ (z_i, 1)``."""
    a1, b1, c1 = l1
    a2, b2, c2 = l2
    X, Q, W = b1 * c2 - c1 * b2, c1 * a2 - a1 * c2, a1 * b2 - b1 * a2
    if W < 0:
        X, Q, W = -X, -Q, -W
    a11, a12, a21, a22, t1, t2, scale = comp
    return (X, Q, W, *_reduced(a11 * X + a12 * Q + t1 * W, a21 * X + a22 * Q + t2 * W, scale * W))


def _reduced(xv: int, qv: int, sw: int) -> tuple[int, int, int]:
    """An image triple divided by the largest power of two common to its entries (``sw > 0``):
    the scales (products of the pieces' denominators ``L_s``) leave many trailing zero bits, and
    only ratios count."""
    shift = ((xv | qv | sw) & -(xv | qv | sw)).bit_length() - 1
    return xv >> shift, qv >> shift, sw >> shift


def clip(
    cell: Cell, constraint: tuple[int, int, int], comp: Composite, values: list[int] | None = None
) -> Cell | None:
    """``cell`` cut by the closed half-plane ``ux x_i + uq q_i + v >= 0`` of the current point
    (``comp`` maps ``z0`` to ``z_i``); None if that is empty. ``values``, if given, are the
    half-plane's values at the vertices times any positive numbers (only their signs count).

    Sutherland-Hodgman with exact signs: a vertex on the line stays, so a cell can shrink to a
    segment or a point but never loses a point of its closure.
    """
    verts, lines = cell
    ux, uq, v = constraint
    if values is None:
        values = [ux * xv + uq * qv + v * sw for _, _, _, xv, qv, sw in verts]
    if min(values) >= 0:
        return cell
    if max(values) < 0:
        return None
    # the same half-plane in z0, through z_i = (A z0 + b) / scale
    a11, a12, a21, a22, b1, b2, scale = comp
    line = (ux * a11 + uq * a21, ux * a12 + uq * a22, ux * b1 + uq * b2 + v * scale)
    n = len(verts)
    out_v: list[tuple[int, ...]] = []
    out_l: list[tuple[int, int, int]] = []
    for i in range(n):
        v0, v1 = values[i], values[(i + 1) % n]
        if v0 > 0:
            out_v.append(verts[i])
            out_l.append(lines[i])
            if v1 < 0:  # leaves the half-plane: the exit point starts an edge on the line
                out_v.append(_vertex(lines[i], line, comp))
                out_l.append(line)
        elif v0 == 0:
            out_v.append(verts[i])
            out_l.append(line if v1 < 0 else lines[i])
        elif v1 > 0:  # enters: the entry point starts the rest of edge i
            out_v.append(_vertex(lines[i], line, comp))
            out_l.append(lines[i])
    return out_v, out_l


def advance(em: ExactMap, cell: Cell, symbol: int) -> Cell:
    """The same cell with its vertices' images carried one step further, by ``symbol``'s affine map."""
    s, rest = divmod(symbol, 10)
    k, j = rest // 2 - 2, rest % 2
    L, ka, kd = em.L[s], em.ka_L[s], em.kd_L[s]
    cx, cq = kd - L * (k + j), kd - L * k
    verts = [
        (X, Q, W, *_reduced((L + ka) * xv + L * qv + cx * sw, ka * xv + L * qv + cq * sw, L * sw))
        for X, Q, W, xv, qv, sw in cell[0]
    ]
    return verts, cell[1]


def at_start(cell: Cell) -> Cell:
    """The same cell at depth 0 (the images are the points): for cutting it by lines in ``z0``."""
    return [(X, Q, W, X, Q, W) for X, Q, W, *_ in cell[0]], cell[1]


def vertices(cell: Cell) -> list[tuple[Fraction, Fraction]]:
    """The distinct vertices of a cell as exact points ``z0``, in order."""
    out: list[tuple[Fraction, Fraction]] = []
    for X, Q, W, *_ in cell[0]:
        point = (Fraction(X, W), Fraction(Q, W))
        if not out or point != out[-1]:
            out.append(point)
    while len(out) > 1 and out[0] == out[-1]:
        out.pop()
    return out


def area(points: Sequence[tuple[Fraction, Fraction]]) -> Fraction:
    """Area of a convex polygon given by its vertices in order (shoelace), exact."""
    n = len(points)
    twice = sum(
        points[i][0] * points[(i + 1) % n][1] - points[(i + 1) % n][0] * points[i][1] for i in range(n)
    )
    return abs(Fraction(twice)) / 2
