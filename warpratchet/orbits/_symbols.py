"""Symbols of the torus map: on which piece of Eq. (fx) a step starts, and which integers it drops.

One step of the torus map (the kernels' arithmetic, see :mod:`warpratchet.kernels`) from
``(x, q)`` in ``[0, 1)^2``::

    t = q + K f(x),   k = floor(t),   q' = t - k,   j = [x + q' >= 1],   x' = x + q' - j.

``f`` is affine on each piece ``s`` of Eq. (fx), ``f = a_s x + d_s`` with ``(a, d) = (l1, 0)``
(left, ``x <= b1``), ``(-1, c)`` (middle, ``b1 < x < 1 - b2``), ``(l2, -l2)`` (right,
``x >= 1 - b2``), so on the cell of the symbol ``(s, k, j)`` the step is the affine map
(:meth:`~warpratchet.force.Force.exact_kicks` gives ``K a_s``, ``K d_s``)

    (x', q') = S_s (x, q) + (K d_s - k - j, K d_s - k),   S_s = [[1 + K a_s, 1], [K a_s, 1]],

with ``S_s = DM`` (:meth:`warpratchet.params.MapParams.jacobian`, ``det S_s = 1``). Since
``|K f| < 2`` (``max |f| < 1/2``, Sec. III C; for another force the kernels' bound
:data:`warpratchet.limits.MAX_KICK`), ``t`` lies in ``(-2, 3)`` and ``k`` in ``{-2, ..., 2}``:
``10 n`` symbols for ``n`` pieces (30 for Eq. fx), coded as the integers ``10 s + 2 (k + 2) + j``.
The winding (momentum gain ``p_m - p_0``, Eq. am) of an itinerary is the sum of its ``k``.

Pure: no Warp, no I/O.
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction

__all__ = [
    "PIECES",
    "K_RANGE",
    "alphabet",
    "encode",
    "decode",
    "winding",
    "describe",
    "piece_constraints",
    "k_constraints",
    "j_constraint",
]

#: Names of the three pieces of Eq. (fx), in symbol order.
PIECES = ("left", "middle", "right")
#: Whole momentum units a step can drop, ``k = floor(q + K f)`` with ``|K f| < 2``.
K_RANGE = (-2, -1, 0, 1, 2)


def encode(piece: int, k: int, j: int) -> int:
    """Symbol code ``10 piece + 2 (k + 2) + j`` (piece 0, 1, 2; ``k`` in ``-2..2``; ``j`` 0 or 1)."""
    return 10 * piece + 2 * (k + 2) + j


def decode(symbol: int) -> tuple[int, int, int]:
    """``(piece, k, j)`` of a symbol code (inverse of :func:`encode`)."""
    piece, rest = divmod(symbol, 10)
    return piece, rest // 2 - 2, rest % 2


def alphabet(pieces: int) -> tuple[int, ...]:
    """Every symbol code of a force of ``pieces`` pieces, in increasing order: ``(s, k, j)`` for
    each piece ``s``, each ``k`` of :data:`K_RANGE` and ``j`` in ``{0, 1}`` (``10 pieces`` codes)."""
    return tuple(encode(s, k, j) for s in range(pieces) for k in K_RANGE for j in (0, 1))


def winding(word: Sequence[int]) -> int:
    """Momentum gain ``w = sum k`` of an itinerary (Eq. am: ``p_m = p_0 + w``)."""
    return sum(decode(symbol)[1] for symbol in word)


def describe(word: Sequence[int], pieces: int = 3) -> list[list]:
    """An itinerary as JSON-friendly ``[piece name, k, j]`` triples (:data:`PIECES` for a force
    of three pieces, ``"piece s"`` for another)."""
    out = []
    for symbol in word:
        piece, k, j = decode(symbol)
        out.append([PIECES[piece] if pieces == 3 else f"piece {piece}", k, j])
    return out


# -- the cell of a symbol as half-planes u_x x + u_q q + v >= 0 in the current point (x, q) ------------
# Integer lines (any positive multiple of a half-plane is the same half-plane). Only the closure
# matters there (strict or not changes no area); the half-open rules are applied exactly by
# ExactMap.step. x >= 0 and x < 1 are not listed: the unit square, and the previous step's j,
# imply them.
def piece_constraints(piece: int, edges: Sequence[Fraction]) -> tuple[tuple[int, int, int], ...]:
    """Half-planes of piece ``s`` between the knots ``edges`` (``x_1 .. x_{n-1}``): ``x >= x_s``
    and ``x <= x_{s+1}``; for Eq. (fx) left ``x <= b1``, middle ``b1 < x < right``, right
    ``x >= right`` (``right = 1 - b2``)."""
    out = []
    if piece > 0:
        edge = edges[piece - 1]
        out.append((edge.denominator, 0, -edge.numerator))  # x - edge >= 0, times the denominator
    if piece < len(edges):
        edge = edges[piece]
        out.append((-edge.denominator, 0, edge.numerator))
    return tuple(out)


def k_constraints(ka: int, kd: int, k: int, one: int) -> tuple[tuple, tuple]:
    """``k <= t < k + 1`` with ``t = q + K f = (ka x + kd) / one + q`` (integers over ``one``)."""
    return ((ka, one, kd - k * one), (-ka, -one, (k + 1) * one - kd))


def j_constraint(ka: int, kd: int, k: int, j: int, one: int) -> tuple:
    """``x + q' < 1`` (``j = 0``) or ``>= 1`` (``j = 1``), with ``q' = t - k``."""
    sign = 1 - 2 * j
    return (-sign * (one + ka), -sign * one, sign * ((1 + k) * one - kd))
