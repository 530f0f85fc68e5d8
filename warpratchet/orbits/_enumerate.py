"""Every periodic orbit of exact period ``m`` of the torus map, and the families of them.

:func:`enumerate_orbits` runs the tree search (:mod:`~warpratchet.orbits._search`) and decides
each candidate itinerary (a least rotation, so each cycle once) exactly
(:mod:`~warpratchet.orbits._exact`):

* ``det(A - I) != 0`` and the itinerary primitive: the 2x2 solve gives one point; it is an
  :class:`Orbit` iff the exact map, iterated from it, follows the itinerary and returns. A
  non-primitive itinerary ``W = V^r`` has the fixed point of ``V`` as its only solution, an
  orbit of lower period, and is skipped.
* ``det(A - I) = 0`` (``tr A = 2``, Greene's residue exactly 0): if ``A = I`` and ``b = 0``
  every point of the itinerary's cell is periodic, a :class:`Family` with that polygon (at
  K = 3 the middle piece has ``DM^3 = I``, Eq. eig, and period-3 families fill the islands of
  Appendices D-E); if ``A != I`` and ``(A - I) z = -b`` has a line of solutions, the family is
  the segment of that line in the cell; otherwise there is no periodic point. A family whose
  points all have a lower period (the map of ``V^d``, ``d < r``, fixes its vertices) is skipped.

Periodic points are those of the paper's map at the float64 ``K, b1, b2`` (Eq. mmc solved
exactly, :mod:`~warpratchet.orbits._exact`); the reported coordinates are their correctly
rounded float64 values.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from fractions import Fraction
from functools import cached_property

import numpy as np

from ..params import MapParams
from . import _cells
from ._exact import Composite, ExactMap, as_fractions, from_fractions
from ._search import search
from ._symbols import decode, winding

__all__ = [
    "KINDS",
    "SLOPE_ULPS",
    "Orbit",
    "Family",
    "Enumeration",
    "enumerate_orbits",
    "periodic_orbits",
    "orbit_families",
    "check_period",
]

#: The kinds of an orbit, by Greene's residue ``R = (2 - tr DM^m) / 4``.
KINDS = ("elliptic", "hyperbolic", "parabolic")
#: Ulps by which the kernels' slopes ``K * l1``, ``K * l2`` (float64 ``l1, l2`` of Eq. mmc,
#: good to a few ulps, times K) may miss the exact ones: the parabolic tolerance of a residue.
SLOPE_ULPS = 4


@dataclass(frozen=True)
class Orbit:
    """A periodic orbit of exact period ``m`` (Eq. am: ``x_m = x_0``, ``p_m = p_0 + w``).

    ``x, p`` have shape ``(m,)``: the orbit on the unit torus, from the point whose itinerary
    is the least rotation. ``nu = w / m`` (Eq. AIn); ``residue`` is Greene's ``R`` (exact for the
    paper's map at the float64 ``K, b1, b2``, then rounded); ``kind`` is ``"parabolic"`` when
    ``|R|`` or ``|R - 1|`` is within ``residue_tolerance`` (what ``SLOPE_ULPS`` ulps in the
    slopes ``K l1, K l2`` can change: the kernels' tangent uses them rounded), else
    ``"elliptic"`` (``0 < R < 1``) or ``"hyperbolic"``.
    """

    period: int
    itinerary: tuple[int, ...]
    x: np.ndarray
    p: np.ndarray
    winding: int
    residue: float
    residue_tolerance: float
    kind: str
    #: The exact points as integers ``(X, Q, D)``: ``(x, q) = (X / D, Q / D)``; ``x, p`` are
    #: their correctly rounded float64 values.
    points: tuple[tuple[int, int, int], ...] = field(repr=False, compare=False)

    @property
    def nu(self) -> float:
        """Mean acceleration ``w / m`` of the orbit (Eq. AIn)."""
        return self.winding / self.period

    @cached_property
    def exact(self) -> tuple[tuple[Fraction, Fraction], ...]:
        """The exact points ``(x, q)`` as Fractions."""
        return tuple(as_fractions(point) for point in self.points)


@dataclass(frozen=True)
class Family:
    """A set of periodic points of exact period ``m`` with one itinerary and ``DM^m`` of trace 2.

    ``vertices`` (shape ``(n, 2)``, rows ``(x, p)``) is the closure of the set: a convex polygon
    (``shape = "polygon"``), a segment (two rows) or a point. ``area`` is its area; every orbit
    of the family has ``m / root`` of its points in it (``root`` = length of the itinerary's
    primitive root), so the invariant set the family's orbits make has area
    ``invariant_area = root * area``. ``residue`` is 0 exactly; ``kind`` is ``"parabolic"``.
    """

    period: int
    itinerary: tuple[int, ...]
    winding: int
    shape: str
    vertices: np.ndarray
    area: float
    invariant_area: float
    root: int
    identity: bool
    residue: float = 0.0
    kind: str = "parabolic"

    @property
    def nu(self) -> float:
        """Mean acceleration ``w / m`` of every orbit of the family (Eq. AIn)."""
        return self.winding / self.period


@dataclass(frozen=True)
class Enumeration:
    """Result of :func:`enumerate_orbits`: orbits, families and the cost of the search."""

    params: MapParams
    period: int
    orbits: list[Orbit]
    families: list[Family]
    #: Tree nodes visited and candidate itineraries decided exactly.
    nodes: int
    candidates: int
    seconds: float


def check_period(period: object) -> int:
    """``period`` as an int ``>= 1`` or a one-line ``ValueError`` naming it."""
    if isinstance(period, bool) or not isinstance(period, (int, np.integer)) or period < 1:
        raise ValueError(f"period = {period!r} is outside the allowed range period >= 1 (an integer)")
    return int(period)


def _torus_float(numerator: int, denominator: int) -> float:
    """Correctly rounded ``numerator / denominator`` in ``[0, 1)`` (Python's int division is);
    one that rounds up to 1 is 0 on the torus."""
    out = numerator / denominator
    return 0.0 if out >= 1.0 else out


def _residue_tolerance(em: ExactMap, word) -> float:
    """Bound on ``|dR|`` when ``l1, l2`` move by ``SLOPE_ULPS`` ulps: with ``S_i = DM`` of step ``i``,
    ``|d tr| <= 2 sum_i |d(K a_i)| prod_{j != i} ||S_j||_inf`` and ``R = (2 - tr) / 4``."""
    ka = em.ka_float
    norms = [abs(1.0 + ka[decode(s)[0]]) + 1.0 for s in word]
    total = 0.0
    for i, symbol in enumerate(word):
        piece = decode(symbol)[0]
        if piece == 1:  # the middle slope -K is exact
            continue
        others = math.prod(norms[:i]) * math.prod(norms[i + 1 :])
        total += 2.0 * SLOPE_ULPS * 2.0**-53 * abs(ka[piece]) * others
    return total / 4.0


def _kind(residue: Fraction, tolerance: float) -> str:
    if abs(residue) <= tolerance or abs(residue - 1) <= tolerance:
        return "parabolic"
    return "elliptic" if 0 < residue < 1 else "hyperbolic"


def _orbit(em: ExactMap, word, point: tuple[int, int, int], comp: Composite) -> Orbit:
    m = len(word)
    points = em.orbit(point, m)
    residue = comp.residue()
    tolerance = _residue_tolerance(em, word)
    return Orbit(
        period=m,
        itinerary=word,
        x=np.array([_torus_float(X, D) for X, _, D in points]),
        p=np.array([_torus_float(Q, D) for _, Q, D in points]),
        winding=winding(word),
        residue=float(residue),
        residue_tolerance=tolerance,
        kind=_kind(residue, tolerance),
        points=tuple(points),
    )


def _lower_period(em: ExactMap, word, root: int, points) -> bool:
    """Whether ``V^d`` fixes every point (``V`` the primitive root, ``d`` a proper divisor of m / root)."""
    repeats = len(word) // root
    for d in range(1, repeats):
        if repeats % d == 0:
            comp = em.composite(word[: d * root])
            if all(comp.apply(v) == v for v in points):
                return True
    return False


def _family(em: ExactMap, word, root: int, cell: _cells.Cell, comp: Composite) -> Family | Orbit | None:
    """The periodic points of a degenerate itinerary (``tr A = 2``): a Family, an Orbit (a line of
    solutions that meets the cell in one point), or None."""
    identity = comp.linear_is_identity()
    if identity and comp.b1 == comp.b2 == 0:
        fixed = cell
    elif identity:  # A = I, b != 0: nothing returns
        return None
    else:  # A - I != 0 has rank 1: a line of solutions, or none
        a11, a12, a21, a22, b1, b2, s = comp
        rows = [(a11 - s, a12, b1), (a21, a22 - s, b2)]  # row . (x, q, 1) = 0
        r = max(rows, key=lambda row: abs(row[0]) + abs(row[1]))
        other = rows[1 - rows.index(r)]
        if other[0] * r[2] != other[2] * r[0] or other[1] * r[2] != other[2] * r[1]:
            return None  # [A - I | b] has rank 2: no solution
        start, identity_map = _cells.at_start(cell), em.identity()
        fixed = _cells.clip(start, r, identity_map)
        fixed = _cells.clip(fixed, (-r[0], -r[1], -r[2]), identity_map) if fixed is not None else None
        if fixed is None:
            return None
    points = _cells.vertices(fixed)
    area = _cells.area(points) if len(points) > 2 else Fraction(0)
    if area == 0 and len(points) > 2:  # collinear: keep the end points
        ends = sorted(set(points))
        points = [ends[0], ends[-1]]
    if _lower_period(em, word, root, points):
        return None
    if len(points) == 1:
        point = from_fractions(points[0])
        if root == len(word) and em.follows(word, point):
            return _orbit(em, word, point, comp)
        return None
    inner = (sum(x for x, _ in points) / len(points), sum(q for _, q in points) / len(points))
    if not em.follows(word, from_fractions(inner)):
        return None  # only the closure's boundary: those points follow a neighbouring itinerary
    return Family(
        period=len(word),
        itinerary=word,
        winding=winding(word),
        shape="polygon" if area > 0 else "segment",
        vertices=np.array([[float(x), float(q)] for x, q in points]),
        area=float(area),
        invariant_area=float(root * area),
        root=root,
        identity=identity,
    )


def enumerate_orbits(params: MapParams, period: int) -> Enumeration:
    """Every periodic orbit of exact period ``period`` and every family of them, each cycle once.

    Parameters
    ----------
    params : MapParams
    period : int
        The period ``m >= 1``. The cost grows like the number of admissible itineraries,
        about ``3.3^m`` at K = 3, b1 = 0.1, b2 = 0.01 (``benchmarks/orbits.py``).

    Returns
    -------
    Enumeration
        Orbits sorted by ``(nu, x_0, p_0)``, families by ``(nu, itinerary)``.
    """
    if not isinstance(params, MapParams):
        raise ValueError(f"params = {params!r} is not a MapParams")
    period = check_period(period)
    start = time.perf_counter()
    em = ExactMap(params)
    orbits: list[Orbit] = []
    families: list[Family] = []
    leaves = 0

    def on_leaf(word, root, cell, comp):
        nonlocal leaves
        leaves += 1
        if comp.trace2 == 0:
            found = _family(em, word, root, cell, comp)
            if isinstance(found, Family):
                families.append(found)
            elif found is not None:
                orbits.append(found)
        elif root == period:  # a power V^r has only V's fixed point, of lower period
            point = comp.fixed_point()
            X, Q, D = point
            if all(a * X + b * Q + c * D >= 0 for a, b, c in cell[1]) and em.follows(word, point):
                orbits.append(_orbit(em, word, point, comp))

    nodes = search(em, period, on_leaf)
    orbits.sort(key=lambda o: (o.nu, o.x[0], o.p[0], o.itinerary))
    families.sort(key=lambda f: (f.nu, f.itinerary))
    return Enumeration(
        params=params,
        period=period,
        orbits=orbits,
        families=families,
        nodes=nodes,
        candidates=leaves,
        seconds=time.perf_counter() - start,
    )


def periodic_orbits(
    params: MapParams,
    period: int,
) -> list[Orbit]:
    """The isolated periodic orbits of exact period ``period`` (:func:`enumerate_orbits`)."""
    return enumerate_orbits(params, period).orbits


def orbit_families(
    params: MapParams,
    period: int,
) -> list[Family]:
    """The families (whole polygons or segments) of period-``period`` points (:func:`enumerate_orbits`)."""
    return enumerate_orbits(params, period).families
