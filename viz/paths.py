"""The paper's paths of Figs. 7-9 (:data:`warpratchet.paper.PATHS`) as map parameters.

Shared by the figures (the points of each sweep, the closed-form curves) and the validation
report (where the Fig. 9 path leaves domain R).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from warpratchet import paper, sweep, theory
from warpratchet.params import MapParams

__all__ = ["path_points", "point_on", "domain_edge", "fig9_domain_edge"]


def path_points(path: paper.Path, b2_values: Iterable[float], K: float | None = None) -> list[MapParams]:
    """The map at each ``b2`` of ``path``, from the constructors of :mod:`warpratchet.sweep`.

    Parameters
    ----------
    path : warpratchet.paper.Path
        Fig. 7 (maximal path, Eq. b2max), Fig. 8 (``b1 = b2 / a``, Eq. Ama) or Fig. 9 (fixed b1).
    b2_values : sequence of float, shape (n,)
        Right strip widths.
    K : float, optional
        Kick strength instead of the path's own (Fig. 9 compares with the closed form at K = 3).
    """
    K = path.K if K is None else K
    if path.kind == "maximal":
        return sweep.maximal_path(b2_values, K=K)
    if path.kind == "line":
        return sweep.line_path(path.a, b2_values, K=K)
    return sweep.fixed_b1_path(path.b1, b2_values, K=K)


def point_on(path: paper.Path, b2: float, K: float | None = None) -> MapParams:
    """The map at one ``b2`` of ``path`` (see :func:`path_points`)."""
    return path_points(path, [b2], K)[0]


def domain_edge(inside: Callable[[float], bool], low: float, high: float, halvings: int = 60) -> float:
    """The largest b2 found ``inside`` by bisection of ``[low, high]``; ``inside(low)`` is assumed.

    60 halvings take an interval of width 1/2 below 1e-18, far under the spacing of doubles there.
    """
    for _ in range(halvings):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if inside(mid) else (low, mid)
    return low


def fig9_domain_edge(K: float) -> float:
    """The b2 beyond which the right island of the Fig. 9 path (b1 = 0.25) no longer exists, Eq. (lai).

    Found with the existence test of Eq. (cam) (:func:`warpratchet.theory.island_exists`).
    """

    def right_island(b2: float) -> bool:
        return theory.island_exists(point_on(paper.FIG9, b2, K), "R")

    low = 1e-6
    if not right_island(low):
        return low
    return domain_edge(right_island, low, 0.5)
