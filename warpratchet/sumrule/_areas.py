"""The island census of the torus and the three routes to ``A``, Eq. (sum), for any K.

Sample the unit torus (random points or a regular lattice), classify every point
(:func:`~warpratchet.sumrule._islands.classify`), and report the areas with their errors
(see :class:`Census`):

* Eq. (sum): ``A_sumrule = -sum_j S_j nu_j / S_C``;
* ``A_direct``: the mean of ``A_n`` (Eq. An) over points of ``C``. Lebesgue measure restricted
  to an invariant set is invariant, so ``<A_n>_C = K <f>_C`` for every ``n``; ``A_force`` is
  that second route, ``K`` times the mean force at the initial points of ``C``;
* ``torus_mean_A``: ``<A_n>`` over all points, zero in expectation by Eq. (proof).

At ``K = 3`` the census is compared with Eqs. (SL), (SR), (SC1)-(SC3), (Aa)/(Ab) and with the
region ``C`` of Eq. (Cs) (:func:`warpratchet.regions.in_C`).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .. import theory
from ..ensemble import grid_nodes
from ..errors import check_count, renamed_attribute
from ..limits import MAX_POINTS
from ..observables import mean_stderr
from ..params import MapParams
from ._islands import PointClasses, check_census_memory, classify

__all__ = ["IslandClass", "Census", "lattice", "census"]


@dataclass(frozen=True)
class IslandClass:
    """All sample points with one mean velocity ``nu = w/m`` (Eq. AIn), possibly many islands."""

    nu: float
    w: int
    m: int
    area: float
    area_stderr: float
    points: int
    #: Mean ``A_n`` of its points (should be ``nu`` to within ``4 m / n``).
    A_mean: float
    #: Fraction of its points that the indicator calls chaotic (chaotic layers inside islands).
    chaotic_fraction: float


@dataclass(frozen=True)
class Census:
    """Areas, island classes and the three routes to ``A``; see :func:`census`.

    Errors: with random sampling (``error_kind = "stderr"``) every ``*_stderr`` is a standard
    error: binomial ``sqrt(f (1 - f) / N)`` for areas, the delta method on the per-point
    multinomial for ``A_sumrule``, ``std / sqrt(N_C)`` for means. With a regular grid
    (``error_kind = "bound"``) an area's error is the fraction of grid nodes next to the class's
    boundary (the counting error of a lattice is at most the share of cells the boundary
    crosses), ``A_sumrule``'s is that propagated linearly, and ``torus_mean_A_stderr`` is None.
    """

    K: float
    b1: float | None  # None for another force than Eq. (fx): see knots, values
    b2: float | None
    sampling: str
    points: int
    steps: int
    seed: int | None
    m_max: int
    indicator: str
    threshold: float
    error_kind: str
    S_C: float
    S_C_stderr: float
    islands: list[IslandClass]
    unidentified_area: float
    unidentified_area_stderr: float
    A_sumrule: float
    A_sumrule_stderr: float
    A_direct: float
    A_direct_stderr: float
    A_force: float
    A_force_stderr: float
    torus_mean_A: float
    torus_mean_A_stderr: float | None
    #: Closed forms at K = 3 (``theory.summary``), else None.
    theory: dict | None = None
    #: At K = 3: fractions of points where the census and Eq. (Cs) disagree, else None.
    C_check: dict | None = None
    seconds: float = 0.0
    #: Another force's knots and values (``MapParams.as_dict``), else None.
    knots: str | None = None
    values: str | None = None

    classifier = renamed_attribute("Census", "classifier", "indicator")

    def island(self, nu: float) -> IslandClass | None:
        """The island class with mean velocity ``nu`` (exact rational match), if found."""
        for item in self.islands:
            if abs(item.nu - nu) < 1e-12:
                return item
        return None

    @property
    def S_C_indicator(self) -> float:
        """The chaotic area by the indicator alone: ``S_C`` plus the points of every island class
        that the indicator calls chaotic (chaotic layers inside islands, orbits stuck to them).

        ``S_C`` of the census (and of the sum rule, Eq. sum) is narrower: a point locked to a
        class ``nu`` counts as island whatever its indicator says.
        """
        return self.S_C + sum(item.area * item.chaotic_fraction for item in self.islands)

    @property
    def S_C_indicator_stderr(self) -> float:
        """Its standard error (binomial, as ``S_C_stderr``; a bound for a grid census likewise)."""
        if self.S_C <= 0 or not self.S_C_stderr:
            return self.S_C_stderr
        return self.S_C_stderr * float(
            np.sqrt(self.S_C_indicator * (1 - self.S_C_indicator)) / np.sqrt(self.S_C * (1 - self.S_C))
        )

    def as_dict(self) -> dict:
        """Plain dict (the JSON of ``warpratchet sumrule --json``), with ``S_C_indicator`` and its error."""
        return {
            **asdict(self),
            "S_C_indicator": self.S_C_indicator,
            "S_C_indicator_stderr": self.S_C_indicator_stderr,
        }


def lattice(side: int) -> tuple[np.ndarray, np.ndarray]:
    """The census lattice: :func:`warpratchet.ensemble.grid_nodes`, shape ``(G^2,)`` each."""
    return grid_nodes(side)


def _boundary_fraction(side: int, member: np.ndarray) -> float:
    """Fraction of the ``side x side`` torus grid's nodes with a 4-neighbour across ``member``'s edge."""
    grid = member.reshape(side, side)
    edge = np.zeros_like(grid)
    for axis in (0, 1):
        for shift in (1, -1):
            edge |= grid != np.roll(grid, shift, axis=axis)
    return float(edge.mean())


def census(
    params: MapParams,
    steps: int,
    *,
    points: int | None = None,
    grid: int | None = None,
    seed: int = 0,
    **options: Any,
) -> Census:
    """Island census of the torus and the sum rule Eq. (sum) at ``params``.

    Parameters
    ----------
    params : MapParams
        Any ``0 < K < 4``.
    steps : int
        Iterations per point (``>= min_steps(m_max)``, 13824 for the default ``m_max = 12``).
    points : int, optional
        Number of points uniform on the torus (``numpy.random.default_rng(seed)``).
    grid : int, optional
        Instead, the ``grid x grid`` :func:`lattice` (no node on a kink or on an edge of the
        regions of Appendix B). Exactly one of ``points`` and ``grid``.
    seed : int
        Seed of the random points.
    **options
        ``m_max``, ``indicator``, ``threshold``, ``threads``, ``device``, ``observers``: see
        :func:`~warpratchet.sumrule._islands.classify`.

    Returns
    -------
    Census
    """
    if (points is None) == (grid is None):
        raise ValueError("give exactly one of points = N (random) and grid = G (regular lattice)")
    if grid is not None:
        grid = check_count("grid", grid, 2, math.isqrt(MAX_POINTS))
        check_census_memory(grid * grid, f"grid = {grid}, a {grid} x {grid} lattice")  # before it is built
        x0, p0 = lattice(grid)
        used_seed = None
    else:
        points = check_count("points", points, 2, MAX_POINTS)
        used_seed = check_count("seed", seed, 0)
        check_census_memory(points)  # before the points are drawn
        rng = np.random.default_rng(used_seed)
        x0, p0 = rng.random(points), rng.random(points)
    start = time.perf_counter()
    pc = classify(params, x0, p0, steps, **options)
    seconds = time.perf_counter() - start
    return _aggregate(params, pc, used_seed, grid, seconds)


def _aggregate(params: MapParams, pc: PointClasses, seed: int | None, grid: int | None, seconds) -> Census:
    n = pc.x0.size
    in_c = pc.in_C
    unidentified = pc.unidentified
    is_grid = grid is not None

    def area_error(member: np.ndarray) -> float:
        f = float(member.mean())
        if is_grid:
            return _boundary_fraction(grid, member)
        return math.sqrt(f * (1.0 - f) / n)

    keys = np.unique(np.stack([pc.w[pc.island], pc.m[pc.island]], axis=1), axis=0)
    islands = []
    nu_point = np.zeros(n)
    for w, m in keys:
        member = pc.island & (pc.w == w) & (pc.m == m)
        nu_point[member] = w / m
        islands.append(
            IslandClass(
                nu=float(w / m),
                w=int(w),
                m=int(m),
                area=float(member.mean()),
                area_stderr=area_error(member),
                points=int(member.sum()),
                A_mean=float(pc.A[member].mean()),
                chaotic_fraction=float(pc.chaotic[member].mean()),
            )
        )
    islands.sort(key=lambda item: (item.nu, item.m))

    s_c = float(in_c.mean())
    # Eq. (sum): S_C A + sum_j S_j nu_j = 0.
    a_sum = -float(nu_point.mean()) / s_c if s_c > 0 else math.nan
    if is_grid:
        a_sum_err = (
            (sum(abs(item.nu) * item.area_stderr for item in islands) + abs(a_sum) * area_error(in_c)) / s_c
            if s_c > 0
            else math.nan
        )
    else:
        # Delta method for the ratio -mean(g)/mean(h), g = nu on islands, h = 1 on C:
        # Var = Var(g + A h) / (N S_C^2), which carries the multinomial covariances.
        u = nu_point + np.where(in_c, a_sum, 0.0)
        a_sum_err = float(u.std(ddof=1) / (math.sqrt(n) * s_c)) if s_c > 0 else math.nan
    a_direct, a_direct_err = mean_stderr(pc.A[in_c])
    a_force, a_force_err = mean_stderr(params.K * params.force(pc.x0[in_c]))
    torus_mean = float(pc.A.mean())
    torus_err = None if is_grid else float(pc.A.std(ddof=1) / math.sqrt(n))

    theory_values = c_check = None
    if params.K == 3.0 and params.is_paper:
        from ..regions import in_C

        theory_values = theory.summary(params)
        inside = in_C(params, pc.x0, pc.p0)
        c_check = {
            "C_outside_Cs": float((in_c & ~inside).mean()),
            "not_C_inside_Cs": float((~in_c & inside).mean()),
            "regular_inside_Cs": float((~pc.chaotic & inside).mean()),
            "chaotic_outside_Cs": float((pc.chaotic & ~inside).mean()),
            "islands_beyond_period_1": float((pc.island & (pc.m > 1)).mean()),
        }
    return Census(
        K=params.K,
        b1=params.b1,
        b2=params.b2,
        sampling="grid" if is_grid else "random",
        points=n,
        steps=pc.steps,
        seed=seed,
        m_max=pc.m_max,
        indicator=pc.indicator,
        threshold=pc.threshold,
        error_kind="bound" if is_grid else "stderr",
        S_C=s_c,
        S_C_stderr=area_error(in_c),
        islands=islands,
        unidentified_area=float(unidentified.mean()),
        unidentified_area_stderr=area_error(unidentified),
        A_sumrule=a_sum,
        A_sumrule_stderr=a_sum_err,
        A_direct=a_direct,
        A_direct_stderr=a_direct_err,
        A_force=a_force,
        A_force_stderr=a_force_err,
        torus_mean_A=torus_mean,
        torus_mean_A_stderr=torus_err,
        theory=theory_values,
        C_check=c_check,
        seconds=seconds,
        knots=None if params.is_paper else params.as_dict()["knots"],
        values=None if params.is_paper else params.as_dict()["values"],
    )
