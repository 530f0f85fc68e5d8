"""Exact arithmetic of the torus map: itineraries, fixed points of ``M^m`` and their residues.

The map is Eq. (cpem) with the force's exact piece table (:mod:`warpratchet.force`): for the
paper's family, Eq. (fx) with the coefficients of Eq. (mmc) computed in exact rational
arithmetic from the float64 values of ``K, b1, b2``. The force is then exactly continuous and
of zero mean (the kernels use ``l1, l2, c`` rounded to float64: a few ulps off, and continuous
only to an ulp). Continuity matters: at K = 3 periodic orbits run through the
kinks ``x = b1`` and ``x = 1 - b2`` (corners of the chaotic region C of Eq. Cs), and with an
ulp-sized jump there a kink orbit can vanish or split in two; here it is in exactly one cell.

On piece ``s`` the kick is ``K f = ka x + kd`` (:meth:`~warpratchet.force.Force.exact_kicks`)
with rationals over a common denominator ``L_s``. A point ``(x, q) = (X, Q) / D`` with integers
``X, Q, D`` steps to ``(X', Q') / (L_s D)`` with integer arithmetic only, so the map is iterated
*exactly*, half-open cells included (the kernels' rule at each knot, for Eq. fx ``x <= b1``
left and ``x < 1 - b2`` middle; ``k = floor(t)``, ``j = [x + q' >= 1]``). This decides,
without any tolerance, whether a candidate itinerary has a periodic point and which cell a
point on a boundary belongs to: each orbit is found once.

An itinerary of ``m`` symbols composes to ``z -> A z + b`` with ``A = DM^m``; its fixed point
solves ``(A - I) z = -b``, and ``det(A - I) = 2 - tr A = 4 R`` (``det A = 1``): the
degenerate itineraries are exactly those with Greene's residue ``R = 0``.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction
from typing import NamedTuple

from ..params import MapParams

__all__ = ["ExactMap", "Composite", "as_fractions", "from_fractions"]


class Composite(NamedTuple):
    """``z -> A z + b`` of an itinerary as integers over ``scale``, the product of its steps' ``L_s``:
    ``A = [[a11, a12], [a21, a22]] / scale``, ``b = (b1, b2) / scale``."""

    a11: int
    a12: int
    a21: int
    a22: int
    b1: int
    b2: int
    scale: int

    @property
    def trace2(self) -> int:
        """``scale (2 - tr A)``, whose sign and zero decide the kind exactly."""
        return 2 * self.scale - self.a11 - self.a22

    def residue(self) -> Fraction:
        """Greene's residue ``R = (2 - tr A) / 4``, exact."""
        return Fraction(self.trace2, 4 * self.scale)

    def linear_is_identity(self) -> bool:
        return self.a11 == self.a22 == self.scale and self.a12 == self.a21 == 0

    def apply(self, z: tuple[Fraction, Fraction]) -> tuple[Fraction, Fraction]:
        x, q = z
        return (
            (self.a11 * x + self.a12 * q + self.b1) / self.scale,
            (self.a21 * x + self.a22 * q + self.b2) / self.scale,
        )

    def fixed_point(self) -> tuple[int, int, int] | None:
        """``(X, Q, D)``, ``D > 0``: the solution ``(X, Q) / D`` of ``(A - I) z = -b``, or None
        when ``det(A - I) = 0``."""
        a11, a12, a21, a22, b1, b2, s = self
        det = (a11 - s) * (a22 - s) - a12 * a21
        if det == 0:
            return None
        X = -((a22 - s) * b1 - a12 * b2)
        Q = -(-a21 * b1 + (a11 - s) * b2)
        return (X, Q, det) if det > 0 else (-X, -Q, -det)


def as_fractions(point: tuple[int, int, int]) -> tuple[Fraction, Fraction]:
    """``(X, Q, D)`` as the point ``(X / D, Q / D)``."""
    X, Q, D = point
    return Fraction(X, D), Fraction(Q, D)


def from_fractions(z: tuple[Fraction, Fraction]) -> tuple[int, int, int]:
    """The point ``(x, q)`` as ``(X, Q, D)`` with ``D > 0``."""
    x, q = z
    return x.numerator * q.denominator, q.numerator * x.denominator, x.denominator * q.denominator


class ExactMap:
    """The torus map at ``params``, in exact integer arithmetic.

    ``edges``: the knots ``x_1 .. x_{n-1}`` (Fractions; ``b1``, ``1 - b2`` for Eq. fx) and
    whether each belongs to the piece on its left; per piece ``s``: ``L[s]``, the common
    denominator of its kick, and the integers ``ka_L[s] = L[s] K a_s``, ``kd_L[s] = L[s] K d_s``;
    ``ka_float[s]``, the slope ``K f'`` rounded to float64.
    """

    def __init__(self, params: MapParams) -> None:
        self.params = params
        self.pieces = params.table.n_pieces
        self.edges = params.table.exact_edges()
        kicks = params.table.exact_kicks(params.K)
        self.ka_float = [float(ka) for ka, _ in kicks]
        self.L = [math.lcm(ka.denominator, kd.denominator) for ka, kd in kicks]
        self.ka_L = [int(ka * L) for (ka, _), L in zip(kicks, self.L, strict=True)]
        self.kd_L = [int(kd * L) for (_, kd), L in zip(kicks, self.L, strict=True)]
        self._edges = [(edge.numerator, edge.denominator, closed) for edge, closed in self.edges]

    # -- iterating points -----------------------------------------------------------------------
    def piece(self, X: int, D: int) -> int:
        """Piece of ``x = X / D`` (``D > 0``); Eq. (fx): 0 left (``x <= b1``), 1 middle, 2 right."""
        for s, (num, den, closed) in enumerate(self._edges):
            if X * den < num * D or (closed and X * den == num * D):
                return s
        return self.pieces - 1

    def step(self, X: int, Q: int, D: int) -> tuple[int, int, int, int]:
        """One exact step of ``(x, q) = (X, Q) / D`` (``D > 0``): ``(symbol, X', Q', L_s D)``."""
        s = self.piece(X, D)
        LD = self.L[s] * D
        T = self.L[s] * Q + self.ka_L[s] * X + self.kd_L[s] * D  # t = T / (L_s D)
        k = T // LD
        Q1 = T - k * LD
        X1 = self.L[s] * X + Q1
        j = 1 if X1 >= LD else 0
        return 10 * s + 2 * (k + 2) + j, X1 - j * LD, Q1, LD

    def follows(self, word: Sequence[int], point: tuple[int, int, int]) -> bool:
        """Whether ``(X, Q) / D`` lies in ``[0, 1)^2``, has itinerary ``word`` and returns to itself."""
        X0, Q0, D0 = point
        if not (0 <= X0 < D0 and 0 <= Q0 < D0):
            return False
        X, Q, D = point
        for symbol in word:
            got, X, Q, D = self.step(X, Q, D)
            if got != symbol:
                return False
        return X * D0 == X0 * D and Q * D0 == Q0 * D

    def orbit(self, point: tuple[int, int, int], steps: int) -> list[tuple[int, int, int]]:
        """``z, M z, ..., M^(steps-1) z`` exactly, as ``(X, Q, D)``, from ``z = (X, Q) / D``."""
        X, Q, D = point
        points = [point]
        for _ in range(steps - 1):
            _, X, Q, D = self.step(X, Q, D)
            points.append((X, Q, D))
        return points

    # -- itineraries as affine maps -------------------------------------------------------------
    @staticmethod
    def identity() -> Composite:
        return Composite(1, 0, 0, 1, 0, 0, 1)

    def extend(self, comp: Composite, symbol: int) -> Composite:
        """The composite of an itinerary followed by one more symbol."""
        a11, a12, a21, a22, b1, b2, scale = comp
        s, rest = divmod(symbol, 10)
        k, j = rest // 2 - 2, rest % 2
        L, ka, kd = self.L[s], self.ka_L[s], self.kd_L[s]
        # one step over L: matrix [[L + ka, L], [ka, L]], offset (kd - L (k + j), kd - L k)
        return Composite(
            (L + ka) * a11 + L * a21,
            (L + ka) * a12 + L * a22,
            ka * a11 + L * a21,
            ka * a12 + L * a22,
            (L + ka) * b1 + L * b2 + (kd - L * (k + j)) * scale,
            ka * b1 + L * b2 + (kd - L * k) * scale,
            scale * L,
        )

    def composite(self, word: Sequence[int]) -> Composite:
        """``M^m`` on the cell of ``word``."""
        comp = self.identity()
        for symbol in word:
            comp = self.extend(comp, symbol)
        return comp
