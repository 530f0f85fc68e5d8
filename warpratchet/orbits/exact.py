"""Exact arithmetic of the torus map: itineraries, fixed points of ``M^m`` and their residues.

The map here is the torus map whose kick on each piece is ``K f = ka x + kd`` with the float64
numbers of :func:`~warpratchet.orbits.symbols.kicks` (the slope ``ka`` is the kernels' own
``K * f'``, so ``DM`` and the residues are those of the kernels' tangent), its cells cut at the
float64 ``b1`` and ``1 - b2`` as the kernels round them. Every coefficient is a float64, i.e. a
dyadic rational, so with one power of two ``L = 2^E`` the numbers ``L b1``, ``L (1 - b2)``,
``L ka`` and ``L kd`` are integers. A point ``(x, q) = (X, Q) / D`` with
integers ``X, Q, D`` steps to ``(X', Q') / (L D)`` with integer arithmetic only, so the map
with the kernels' float64 coefficients is iterated *exactly*, including its half-open cells
(``x <= b1`` left, ``x < 1 - b2`` middle, ``k = floor(t)``, ``j = [x + q' >= 1]``). This is
what decides, without any tolerance, whether a candidate itinerary has a periodic point and
which cell a point on a boundary belongs to: each orbit is then found exactly once.

An itinerary of ``m`` symbols composes to ``z -> A z + b`` with ``A = DM^m``; its fixed point
solves ``(A - I) z = -b``, and ``det(A - I) = 2 - tr A = 4 R`` (``det A = 1``): the
degenerate itineraries are exactly those with Greene's residue ``R = 0``.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction
from typing import NamedTuple

from ..params import MapParams
from .symbols import kicks

__all__ = ["ExactMap", "Composite", "as_fractions", "from_fractions"]


class Composite(NamedTuple):
    """``z -> A z + b`` of an itinerary as integers over ``scale = L^m``:
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
    """The torus map with ``params``' float64 coefficients, in exact integer arithmetic.

    ``L`` is the common power of two; ``b1_L``, ``right_L``, ``ka_L[s]``, ``kd_L[s]`` are
    ``L b1``, ``L (1 - b2)``, ``L K a_s``, ``L K d_s`` as integers.
    """

    def __init__(self, params: MapParams) -> None:
        self.params = params
        self.right = 1.0 - params.b2  # as the kernels round it
        pieces = kicks(params)
        self.ka_float = [ka for ka, _ in pieces]
        self.ka = [Fraction(ka) for ka, _ in pieces]
        self.kd = [Fraction(kd) for _, kd in pieces]
        rationals = [Fraction(params.b1), Fraction(self.right), *self.ka, *self.kd]
        self.L = max(r.denominator for r in rationals)  # all are powers of two: their lcm
        self.log2_L = self.L.bit_length() - 1
        self.b1_L = int(Fraction(params.b1) * self.L)
        self.right_L = int(Fraction(self.right) * self.L)
        self.ka_L = [int(v * self.L) for v in self.ka]
        self.kd_L = [int(v * self.L) for v in self.kd]

    # -- iterating points -----------------------------------------------------------------------
    def step(self, X: int, Q: int, D: int) -> tuple[int, int, int, int]:
        """One exact step of ``(x, q) = (X, Q) / D`` (``D > 0``): ``(symbol, X', Q', L D)``."""
        L = self.L
        if X * L <= self.b1_L * D:
            s = 0
        elif X * L < self.right_L * D:
            s = 1
        else:
            s = 2
        LD = L * D
        T = L * Q + self.ka_L[s] * X + self.kd_L[s] * D  # t = T / (L D)
        k = T // LD
        Q1 = T - k * LD
        X1 = L * X + Q1
        j = 1 if X1 >= LD else 0
        return 10 * s + 2 * (k + 2) + j, X1 - j * LD, Q1, LD

    def follows(self, word: Sequence[int], point: tuple[int, int, int]) -> bool:
        """Whether ``(X, Q) / D`` lies in ``[0, 1)^2``, has itinerary ``word`` and returns to itself."""
        X0, Q0, D = point
        if not (0 <= X0 < D and 0 <= Q0 < D):
            return False
        X, Q = X0, Q0
        for symbol in word:
            got, X, Q, D = self.step(X, Q, D)
            if got != symbol:
                return False
        scale = self.L ** len(word)
        return X == X0 * scale and Q == Q0 * scale

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
        L = self.L
        a11, a12, a21, a22, b1, b2, scale = comp
        s, rest = divmod(symbol, 10)
        k, j = rest // 2 - 2, rest % 2
        ka, kd = self.ka_L[s], self.kd_L[s]
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
