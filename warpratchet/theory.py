"""Closed forms of Dana & Roitberg, "Weak-Chaos Ratchet Accelerator".

Pure functions of ``(K, b1, b2)``; no Warp import. Every formula cites the ``\\label`` of the
paper's equation it implements. Area and acceleration formulas are exact only at ``K = 3``
(Sec. IV and Appendices B-E); asking for them at another ``K`` raises ``ValueError``.

One printed formula is wrong: Eq. (Amax), the acceleration on the maximal path, does not
follow from Eqs. (Aa) and (b2max). :func:`acceleration_on_maximal_path` uses the form that
does (checked symbolically and against the numerics, see ``docs/validation.md``), and
:func:`acceleration_on_maximal_path_as_printed` keeps the printed one for comparison.
"""

from __future__ import annotations

import math
from typing import Literal

from .errors import check_real
from .params import MapParams

__all__ = [
    "Domain",
    "F",
    "island_exists",
    "domain",
    "accelerator_modes",
    "symmetric_bound",
    "necessary_condition",
    "area_left",
    "area_right",
    "area_chaotic",
    "acceleration",
    "acceleration_both_islands",
    "acceleration_one_island",
    "b1_on_maximal_path",
    "acceleration_on_maximal_path",
    "acceleration_on_maximal_path_as_printed",
    "LIMIT_MAXIMAL_PATH",
    "limit_on_line",
    "K_from_alpha",
    "summary",
]

Domain = Literal["LR", "L", "R", "none"]

#: Eq. (Am): A on the maximal path as b2 -> 0.
LIMIT_MAXIMAL_PATH = 0.25


#: Why a force other than Eq. (fx) has no closed form here.
NO_CLOSED_FORM = (
    "the closed forms (islands, areas, A) are derived for the force of Eq. (fx) (Sec. IV, Appendices "
    "B-E); for another force, measure A (run) and the island census (sumrule)"
)


def _check_params(p: object) -> None:
    """TypeError naming the argument unless ``p`` is a :class:`MapParams` (not an AttributeError
    from deep inside)."""
    if not isinstance(p, MapParams):
        raise TypeError(f"p = {p!r} is not a MapParams (warpratchet.MapParams(K, b1, b2))")


def _require_K3(p: MapParams, what: str) -> None:
    _check_params(p)
    if p.K != 3.0:
        raise ValueError(
            f"{what} is exact only at K = 3 (Sec. IV, Appendices B-E); got K = {p.K!r}. "
            "Use warpratchet.sumrule for other K."
        )


# -- Sec. III C: period-1 accelerator-mode islands ---------------------------------------------
def F(b: float, K: float) -> float:
    """Existence boundary ``F(b)`` of Eq. (lai).

    ``F(b) = (K b^2 + (1 - 2K) b + K - 2) / (K - 1 - K b)``. The left island exists iff
    ``b2 < F(b1)`` and the right one iff ``b1 < F(b2)``, *provided* ``K - 1 - K b > 0``;
    past the pole ``b = (K - 1)/K`` the inequality derived from Eq. (cam) flips, which is
    why :func:`island_exists` uses Eq. (cam) directly.
    """
    denominator = K - 1.0 - K * b
    if denominator == 0.0:
        return math.inf
    return (K * b * b + (1.0 - 2.0 * K) * b + K - 2.0) / denominator


def accelerator_modes(p: MapParams) -> list[tuple[int, float]]:
    """Stable period-1 accelerator modes ``(w, x0)`` with ``p0 = 0 mod 1``.

    Eq. (xp): ``x0 = c - w/K``; Eq. (wK): ``w = +-1`` and only for ``2 <= K < 4``; a mode
    exists when ``x0`` lies in the elliptic middle branch, Eq. (cam): ``b1 < x0 < 1 - b2``.
    ``w = +1`` is the left (L) island, ``w = -1`` the right (R) one.
    """
    _check_params(p)
    modes = []
    if p.K >= 2.0:
        for w in (1, -1):
            x0 = p.c - w / p.K
            if p.b1 < x0 < 1.0 - p.b2:
                modes.append((w, x0))
    return modes


def island_exists(p: MapParams, side: Literal["L", "R"]) -> bool:
    """Whether the left (``w = 1``) or right (``w = -1``) period-1 island exists, Eq. (cam)."""
    _check_params(p)
    w = {"L": 1, "R": -1}[side]
    return any(mode_w == w for mode_w, _ in accelerator_modes(p))


def domain(p: MapParams) -> Domain:
    """Existence domain of Fig. 3: ``"LR"`` (Eq. ca), ``"L"``/``"R"`` (Eq. cb), ``"none"`` (Eq. cc)."""
    _check_params(p)
    left, right = island_exists(p, "L"), island_exists(p, "R")
    return {(True, True): "LR", (True, False): "L", (False, True): "R"}.get((left, right), "none")


def symmetric_bound(K: float) -> float:
    """Eq. (lais): for ``b1 = b2`` both islands exist iff ``b1 < 1/2 - 1/K``."""
    return 0.5 - 1.0 / check_real("K", K)


def necessary_condition(p: MapParams) -> bool:
    """Eq. (ccs): at least one period-1 island needs ``b1 + b2 < (K - 2)/(K - 1)``."""
    _check_params(p)
    return p.b < (p.K - 2.0) / (p.K - 1.0)


# -- Appendices D and E: areas at K = 3 ----------------------------------------------------------
def area_left(p: MapParams) -> float:
    """Area of the left island, Eq. (SL): ``S_L = (3c - 3 b1 - 1)^2 / 2``; 0 where it does not exist."""
    _check_params(p)
    _require_K3(p, "S_L")
    return 0.5 * (3.0 * p.c - 3.0 * p.b1 - 1.0) ** 2 if island_exists(p, "L") else 0.0


def area_right(p: MapParams) -> float:
    """Area of the right island, Eq. (SR): ``S_R = (2 - 3 b2 - 3c)^2 / 2``; 0 where it does not exist."""
    _check_params(p)
    _require_K3(p, "S_R")
    return 0.5 * (2.0 - 3.0 * p.b2 - 3.0 * p.c) ** 2 if island_exists(p, "R") else 0.0


def area_chaotic(p: MapParams) -> float | None:
    """Area of the chaotic region ``C = B u MB u M^2 B`` at K = 3 (Eq. Cs).

    Eq. (SC1) in domain LR, Eq. (SC2) in domain R (the missing L triangle, Eq. SL, is added),
    Eq. (SC3) in domain L. ``None`` in domain "none", where the paper gives no formula.
    """
    _check_params(p)
    _require_K3(p, "S_C")
    b = p.b
    base = 3.0 * b - 3.0 * b * b  # Eq. (SC1)
    dom = domain(p)
    if dom == "LR":
        return base
    if dom == "R":
        return base + 0.5 * (3.0 * p.c - 3.0 * p.b1 - 1.0) ** 2  # Eq. (SC2)
    if dom == "L":
        return base + 0.5 * (2.0 - 3.0 * p.b2 - 3.0 * p.c) ** 2  # Eq. (SC3)
    return None


# -- Sec. IV: the ratchet acceleration at K = 3 --------------------------------------------------
def acceleration_both_islands(b1: float, b2: float) -> float:
    """Eq. (Aa): ``A = (b1 - b2)(1 - 3b) / (2 (2 - b) b)``, ``b = b1 + b2`` (domain LR, K = 3)."""
    b = b1 + b2
    return (b1 - b2) * (1.0 - 3.0 * b) / (2.0 * (2.0 - b) * b)


def acceleration_one_island(b1: float, b2: float) -> float:
    """Eq. (Ab) for domain R, and its mirror image for domain L (K = 3).

    Domain R: ``A = (2 - 3b2 - 3c)^2 / (6b - 6b^2 + (3c - 3b1 - 1)^2)``. Domain L follows from
    the antisymmetry ``A(b2, b1) = -A(b1, b2)`` of Sec. V, i.e. exchanging ``b1 <-> b2``
    (which maps ``c -> 1 - c``) and flipping the sign.
    """
    p = MapParams(3.0, b1, b2)
    b, c = p.b, p.c
    if domain(p) == "R":
        return (2.0 - 3.0 * b2 - 3.0 * c) ** 2 / (6.0 * b - 6.0 * b * b + (3.0 * c - 3.0 * b1 - 1.0) ** 2)
    if domain(p) == "L":
        return -((3.0 * c - 3.0 * b1 - 1.0) ** 2) / (6.0 * b - 6.0 * b * b + (2.0 - 3.0 * b2 - 3.0 * c) ** 2)
    raise ValueError(f"(b1, b2) = ({b1!r}, {b2!r}) is in domain {domain(p)!r}, not in L or R (Eq. cb)")


def acceleration(p: MapParams) -> float | None:
    """Ratchet acceleration ``A`` at K = 3 in every domain (Sec. IV).

    Eq. (Aa) in LR, Eq. (Ab) (or its mirror) in R (L), and 0 where no island exists (case c).
    Equal to ``(S_R - S_L) / S_C`` (Eq. Ae), the sum rule Eq. (sum) with ``nu = +-1``.
    """
    _require_K3(p, "A")
    dom = domain(p)
    if dom == "LR":
        return acceleration_both_islands(p.b1, p.b2)
    if dom in ("L", "R"):
        return acceleration_one_island(p.b1, p.b2)
    return 0.0


# -- Sec. V: the maximal path and the weak-chaos limits ------------------------------------------
def b1_on_maximal_path(b2: float) -> float:
    """Eq. (b2max): ``b1(b2)`` maximizing Eq. (Aa) at fixed ``b2``, for ``0 < b2 <= 1/6``."""
    b2 = check_real("b2", b2)
    if not 0.0 < b2 <= 1.0 / 6.0:
        raise ValueError(f"b2 = {b2!r} is outside the maximal path's range 0 < b2 <= 1/6")
    root = math.sqrt(5.0 * b2 * (1.0 - b2))
    return (2.0 * root - b2 * (7.0 - 6.0 * b2)) / (5.0 - 6.0 * b2)


def acceleration_on_maximal_path(b2: float) -> float:
    """A on the maximal path: Eq. (Aa) evaluated at Eq. (b2max), in closed form.

    With ``r = [5 b2 (1 - b2)]^(1/2)``::

        A(b2) = (5 - 6 r)^2 / (20 (5 - 4 b2 - 2 r))

    The paper's Eq. (Amax) prints ``r`` instead of ``2 r`` in the denominator. Substituting
    Eq. (b2max) into Eq. (Aa) and reducing with ``r^2 = 5 b2 (1 - b2)`` gives the form here
    (it reproduces Eq. (Aa) on the path to rounding; the printed one is 7% low at b2 = 0.02).
    Both agree at the end points: 1/4 as ``b2 -> 0`` (Eq. Am) and 0 at ``b2 = 1/6``.
    """
    b1_on_maximal_path(b2)  # validates the range
    root = math.sqrt(5.0 * b2 * (1.0 - b2))
    return (5.0 - 6.0 * root) ** 2 / (20.0 * (5.0 - 4.0 * b2 - 2.0 * root))


def acceleration_on_maximal_path_as_printed(b2: float) -> float:
    """Eq. (Amax) exactly as printed in the paper (kept to document the misprint)."""
    b1_on_maximal_path(b2)
    root = math.sqrt(5.0 * b2 * (1.0 - b2))
    return (5.0 - 6.0 * root) ** 2 / (20.0 * (5.0 - 4.0 * b2 - root))


def limit_on_line(a: float) -> float:
    """Eq. (Ama): ``lim_{b2 -> 0} A = (1 - a) / (4 (1 + a))`` on the line ``b1 = b2 / a``."""
    a = check_real("a", a)
    if not a > 0.0:
        raise ValueError(f"a = {a!r} is outside the allowed range a > 0")
    return (1.0 - a) / (4.0 * (1.0 + a))


def K_from_alpha(alpha: float) -> float:
    """Kick strength for a rotation angle of the middle branch, Eq. (eig): ``K = 2 - 2 cos(alpha)``."""
    return 2.0 - 2.0 * math.cos(alpha)


def summary(p: MapParams) -> dict[str, object]:
    """Everything the theory says at ``p``: the keys of ``warpratchet theory --json``.

    ``S_L, S_R, S_C, A`` are ``None`` where not defined (``K != 3``; ``S_C`` in domain "none").
    Another force than Eq. (fx) has none of them: :data:`NO_CLOSED_FORM` says why.
    """
    _check_params(p)
    if not p.is_paper:
        return {
            **p.as_dict(),
            "domain": None,
            "S_L": None,
            "S_R": None,
            "S_C": None,
            "A": None,
            "why": NO_CLOSED_FORM,
        }
    out: dict[str, object] = dict(p.as_dict())
    out["domain"] = domain(p)
    if p.K == 3.0:
        out.update(S_L=area_left(p), S_R=area_right(p), S_C=area_chaotic(p), A=acceleration(p))
    else:
        out.update(S_L=None, S_R=None, S_C=None, A=None)
    return out
