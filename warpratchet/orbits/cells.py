"""Exact convex cells: the closure of the set of starting points that follow an itinerary.

A cell is a convex polygon in the starting point ``z0 = (x, q)``, held exactly: its edges are
integer lines ``a x + b q + c >= 0`` and its vertices homogeneous integer points
``(X, Q, W)``, ``W > 0`` (the point ``(X/W, Q/W)``), each the crossing of two edge lines, so
the numbers never grow beyond twice a line's size. Integers are needed, not floats: a cell of
an ``m``-step itinerary is ``~Lambda^-m`` thin (``Lambda`` up to ``1 + K l2 ~ 140`` per step
at b2 = 0.01) while its pulled-back edges are nearly parallel, so float64 geometry cannot tell
an empty cell from a thin one after a few steps (measured: 71% of the float search's cells at
m = 8 were empty, and it was three times slower than this).

A cell may degenerate to a segment or a point (points on a boundary line that the half-open
rules give to it); only closures are computed here, the half-open rules are applied by
:meth:`~warpratchet.orbits.exact.ExactMap.follows`.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction

from .exact import Composite, ExactMap
from .symbols import decode, j_constraint, k_constraints, piece_constraints

__all__ = ["Cell", "UNIT_SQUARE", "clip", "pulled", "step_constraints", "cell_of", "vertices", "area"]

#: ``(vertices, lines)``: vertex ``i`` to vertex ``i + 1`` runs along ``lines[i]`` (counter-clockwise).
Cell = tuple[list[tuple[int, int, int]], list[tuple[int, int, int]]]

#: ``[0, 1]^2``: edges ``q >= 0``, ``x <= 1``, ``q <= 1``, ``x >= 0``.
UNIT_SQUARE: Cell = (
    [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
    [(0, 1, 0), (-1, 0, 1), (0, -1, 1), (1, 0, 0)],
)


def _meet(l1: tuple[int, int, int], l2: tuple[int, int, int]) -> tuple[int, int, int]:
    """The crossing of two non-parallel lines, homogeneous with ``W > 0``."""
    a1, b1, c1 = l1
    a2, b2, c2 = l2
    X, Q, W = b1 * c2 - c1 * b2, c1 * a2 - a1 * c2, a1 * b2 - b1 * a2
    return (X, Q, W) if W > 0 else (-X, -Q, -W)


def clip(cell: Cell, line: tuple[int, int, int]) -> Cell | None:
    """``cell`` intersected with the closed half-plane ``line >= 0``; None if that is empty.

    Sutherland-Hodgman with exact signs: a vertex on the line stays, so a cell can shrink to
    a segment or a point but never loses a point of its closure.
    """
    verts, lines = cell
    a, b, c = line
    values = [a * X + b * Q + c * W for X, Q, W in verts]
    if min(values) >= 0:
        return cell
    if max(values) < 0:
        return None
    n = len(verts)
    out_v: list[tuple[int, int, int]] = []
    out_l: list[tuple[int, int, int]] = []
    for i in range(n):
        v0, v1 = values[i], values[(i + 1) % n]
        if v0 > 0:
            out_v.append(verts[i])
            out_l.append(lines[i])
            if v1 < 0:  # leaves the half-plane: the exit point starts an edge on the line
                out_v.append(_meet(lines[i], line))
                out_l.append(line)
        elif v0 == 0:
            out_v.append(verts[i])
            out_l.append(line if v1 < 0 else lines[i])
        elif v1 > 0:  # enters: the entry point starts the rest of edge i
            out_v.append(_meet(lines[i], line))
            out_l.append(lines[i])
    return out_v, out_l


def pulled(comp: Composite, constraint: tuple[int, int, int]) -> tuple[int, int, int]:
    """The half-plane ``ux x_i + uq q_i + v >= 0`` of the current point (integers over ``L``)
    as an exact line in ``z0``, through ``z_i = (A z0 + b) / scale`` (times ``scale > 0``)."""
    a11, a12, a21, a22, b1, b2, scale = comp
    ux, uq, v = constraint
    return ux * a11 + uq * a21, ux * a12 + uq * a22, ux * b1 + uq * b2 + v * scale


def step_constraints(em: ExactMap, symbol: int) -> tuple[tuple[int, int, int], ...]:
    """The half-planes of the cell of one symbol in the current point, integers over ``L``."""
    s, k, j = decode(symbol)
    L, ka, kd = em.L, em.ka_L[s], em.kd_L[s]
    return (
        *piece_constraints(s, em.b1_L, em.right_L, L),
        *k_constraints(ka, kd, k, L),
        j_constraint(ka, kd, k, j, L),
    )


def cell_of(em: ExactMap, word: Sequence[int]) -> Cell | None:
    """The exact cell of an itinerary (None: no point follows it)."""
    cell: Cell | None = UNIT_SQUARE
    comp = em.identity()
    for symbol in word:
        for constraint in step_constraints(em, symbol):
            cell = clip(cell, pulled(comp, constraint))
            if cell is None:
                return None
        comp = em.extend(comp, symbol)
    return cell


def vertices(cell: Cell) -> list[tuple[Fraction, Fraction]]:
    """The distinct vertices of a cell as exact points, in order."""
    out: list[tuple[Fraction, Fraction]] = []
    for X, Q, W in cell[0]:
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
