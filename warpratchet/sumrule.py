"""Island census of the torus and the sum rule, Eq. (sum), for any K.

Sample the unit torus, iterate map and tangent, and sort every point into

* an **island class** ``nu = w/m`` (Eq. AIn, ``m <= m_max``, lowest terms): the momentum gain
  ``p_k - p_0`` stays within ``4m`` of ``k w/m`` at each of :data:`CHECKPOINTS` run lengths
  ``k = n/8, ..., n``, as it does for any orbit confined to a period-``m`` island chain
  (:func:`excursion_bound`). This takes in every set with a rational mean velocity over the
  run: islands around accelerator modes of any period, normal islands (``nu = 0``), chaotic
  layers trapped inside island chains, and orbits of ``C`` stuck to an island for the whole
  run (sticky orbits; their share falls as ``n`` grows, see ``docs/validation.md``);
* the **global chaotic region** ``C``: chaotic by the chosen indicator and in no island class;
* **unidentified**: regular by the indicator but with no rational ``nu`` of denominator
  ``<= m_max`` (islands of longer period, or orbits that have not settled); reported, never
  silently folded into ``C``.

Then (sampling error in parentheses, see :class:`Census`):

* Eq. (sum): ``A_sumrule = -sum_j S_j nu_j / S_C``;
* ``A_direct``: the mean of ``A_n`` (Eq. An) over points of ``C``. Lebesgue measure restricted
  to an invariant set is invariant, so ``<A_n>_C = K <f>_C`` for every ``n``; ``A_force`` is
  that second route, ``K`` times the mean force at the initial points of ``C``;
* ``torus_mean_A``: ``<A_n>`` over all points, zero in expectation by Eq. (proof).

At ``K = 3`` the census is compared with Eqs. (SL), (SR), (SC1)-(SC3), (Aa)/(Ab) and with the
region ``C`` of Eq. (Cs) (:func:`warpratchet.regions.in_C`).

Chaos indicators (one Warp pass, :func:`warpratchet.kernels.advance_map_indicators`):
``"ftle"`` (the package's default FTLE threshold), ``"megno"`` (Cincotta & Simo 2000) and
``"fli"`` (fast Lyapunov indicator), the latter two of the map ``M^8``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
import warp as wp

from . import kernels, theory
from .ensemble import Ensemble, Observer, grid_nodes
from .observables import acceleration, default_lyapunov_threshold, lyapunov
from .params import MapParams

__all__ = [
    "CLASSIFIERS",
    "MEGNO_THRESHOLD",
    "DEFAULT_M_MAX",
    "IndicatorEnsemble",
    "fli_threshold",
    "chaotic_by",
    "CHECKPOINTS",
    "excursion_bound",
    "min_steps",
    "identify_nu",
    "lattice",
    "PointClasses",
    "classify",
    "IslandClass",
    "Census",
    "census",
]

#: Chaos indicators understood by :func:`chaotic_by`.
CLASSIFIERS = ("ftle", "megno", "fli")
#: Mean MEGNO above which an orbit counts as chaotic. Regular orbits tend to 2 (0 when the
#: tangent map is periodic, as in the period-1 islands at K = 3 where ``DM^3 = I``, Eq. eig);
#: chaotic ones grow like ``sigma n / 2``. Twice the regular limit leaves room for the O(1)
#: oscillations of short runs.
MEGNO_THRESHOLD = 4.0
#: Default bound on the reduced denominator of ``nu = w/m``.
DEFAULT_M_MAX = 12

_INDICATOR_FIELDS = ("fli", "megno_lsum", "megno_ysum")


# -- one kernel pass: orbit, tangent, FTLE, MEGNO, FLI ---------------------------------------------
class IndicatorEnsemble(Ensemble):
    """An :class:`~warpratchet.ensemble.Ensemble` whose runs also accumulate MEGNO and the FLI.

    Same constructor and :meth:`run`; the orbit and tangent are bitwise those of a plain
    ensemble. The indicators need the whole orbit from step 0, so there is no ``from_state``.
    """

    def __init__(self, params: MapParams, x0, p0, **kwargs) -> None:
        super().__init__(params, x0, p0, **kwargs)
        self._indicators = {
            name: wp.zeros(self.points, dtype=wp.float64, device=self.device) for name in _INDICATOR_FIELDS
        }

    @classmethod
    def from_state(cls, *args, **kwargs):
        raise ValueError("an IndicatorEnsemble must start at step 0: MEGNO and FLI need the whole orbit")

    # Ensemble's subclass hooks: the indicator kernel and its accumulators; the chunked,
    # multi-threaded run loop (and observers) are reused unchanged.
    _kernel = kernels.advance_map_indicators

    def _extra_arrays(self) -> list:
        return [self._indicators[name] for name in _INDICATOR_FIELDS]

    def indicators(self) -> dict[str, np.ndarray]:
        """Copies of ``fli`` (``max_j ln|v_8j|``) and ``megno`` (``<Y>`` of ``M^8``), shape ``(points,)``.

        Both refer to the last checkpoint ``8 * (step // 8)``; NaN before the first one.
        """
        checkpoints = self.step // kernels.RENORM_CHECK_EVERY
        fli = np.array(self._indicators["fli"].numpy(), copy=True)
        ysum = self._indicators["megno_ysum"].numpy()
        megno = ysum / checkpoints if checkpoints else np.full(self.points, np.nan)
        if not checkpoints:
            fli[:] = np.nan
        return {"fli": fli, "megno": megno}


def fli_threshold(step: int) -> float:
    """FLI above which an orbit counts as chaotic after ``step`` iterations: ``2 ln n``.

    A regular orbit has ``|v_n| <= a + b n``, so ``FLI <= ln(a + b) + ln n``; ``2 ln n`` admits any
    ``a + b <= n`` (an island whose shear exceeds ``n`` is not resolved after ``n`` steps anyway).
    A chaotic orbit passes it once ``sigma n > 2 ln n``.
    """
    if step <= 0:
        raise ValueError(f"step = {step!r}: the FLI needs at least one iteration")
    return 2.0 * math.log(step)


def chaotic_by(
    classifier: str,
    state: dict[str, np.ndarray],
    indicators: dict[str, np.ndarray],
    step: int,
    threshold: float | None = None,
) -> np.ndarray:
    """Boolean mask, shape ``(points,)``: chaotic according to ``classifier``.

    ``"ftle"``: FTLE ``> threshold`` (default :func:`~warpratchet.observables.default_lyapunov_threshold`);
    ``"megno"``: mean MEGNO ``> threshold`` (default :data:`MEGNO_THRESHOLD`);
    ``"fli"``: FLI ``> threshold`` (default :func:`fli_threshold`).
    """
    if classifier == "ftle":
        limit = default_lyapunov_threshold(step) if threshold is None else threshold
        return lyapunov(state, step) > limit
    if classifier == "megno":
        return indicators["megno"] > (MEGNO_THRESHOLD if threshold is None else threshold)
    if classifier == "fli":
        return indicators["fli"] > (fli_threshold(step) if threshold is None else threshold)
    raise ValueError(f"classifier = {classifier!r} is not one of {', '.join(CLASSIFIERS)}")


# -- nu = w/m from the momentum record ------------------------------------------------------------
#: Run lengths ``n i / CHECKPOINTS`` (``i = 1..CHECKPOINTS``) at which an island orbit's momentum is
#: checked against ``p_0 + k nu``.
CHECKPOINTS = 8


def excursion_bound(m: int | np.ndarray) -> int | np.ndarray:
    """Bound ``4 m`` on ``|p_k - p_0 - k nu|`` for an orbit in a period-``m`` island chain.

    The island centre moves by ``|K f| < 2`` per step (``max|f| < 1/2``, Sec. III C) and
    ``|nu| < 2``, so its lifted momentum strays at most ``4 (m - 1)`` from the line ``k nu``
    within a period; a point of the island adds at most its distance to the centre (< 1) at
    both ends.
    """
    return 4 * m


def min_steps(m_max: int) -> int:
    """Fewest steps ``n`` for which :func:`identify_nu` is unambiguous up to ``m_max``.

    Two rationals of denominators ``<= m`` differ by ``>= 1/m^2``; their windows
    ``excursion_bound(m) / n`` around ``A_n`` must not overlap: ``n >= 8 m_max^3``.
    """
    return 8 * m_max**3


def identify_nu(rise: np.ndarray, times: np.ndarray, m_max: int = DEFAULT_M_MAX):
    """Rational mean velocity ``nu = w/m`` (Eq. AIn) of each point, or ``m = 0`` if none.

    A point gets ``nu = w/m`` when its momentum gain stays within :func:`excursion_bound` of
    ``k nu`` at every recorded time ``k``: a confined orbit always does, while an orbit of the
    chaotic sea diffuses away from any line, so demanding it at several times makes a chance
    match vanishingly rare (a single time would let ~0.5% of the sea through at n = 3e4).

    Parameters
    ----------
    rise : ndarray, shape (len(times), points)
        ``p_k - p_0`` at each time ``k`` of ``times``.
    times : ndarray of int, shape (len(times),)
        Increasing step numbers; the last one, ``n``, must be ``>= min_steps(m_max)``.
    m_max : int
        Largest period tried.

    Returns
    -------
    w, m : ndarray of int64, shape (points,)
        ``nu = w/m`` in lowest terms; ``w = m = 0`` where no period ``<= m_max`` fits. The
        candidate ``w`` for period ``m`` is ``round(m A_n)``; the smallest fitting period wins.
    """
    if isinstance(m_max, bool) or not isinstance(m_max, (int, np.integer)) or m_max < 1:
        raise ValueError(f"m_max = {m_max!r} is outside the allowed range m_max >= 1 (an integer)")
    times = np.asarray(times, dtype=np.int64)
    steps = int(times[-1])
    if steps < min_steps(m_max):
        raise ValueError(
            f"steps = {steps!r} is too few to identify nu with m <= {m_max}: need steps >= {min_steps(m_max)}"
        )
    rise = np.asarray(rise, dtype=np.float64)
    a_full = rise[-1] / steps
    w = np.zeros(a_full.shape, dtype=np.int64)
    m = np.zeros(a_full.shape, dtype=np.int64)
    for period in range(int(m_max), 0, -1):  # descending, so the smallest fitting period wins
        num = np.rint(a_full * period)
        off = np.abs(rise - times[:, None] * (num / period)).max(axis=0)
        ok = off <= excursion_bound(period)
        w = np.where(ok, num.astype(np.int64), w)
        m = np.where(ok, period, m)
    common = np.gcd(w, m)
    common[common == 0] = 1
    return w // common, m // common


# -- per-point classification -------------------------------------------------------------------
@dataclass(frozen=True)
class PointClasses:
    """Per-point result of :func:`classify`; every array has shape ``(points,)``.

    ``island`` is ``m > 0``; ``in_C = chaotic & ~island`` is the global chaotic region;
    ``unidentified = ~chaotic & ~island``.
    """

    x0: np.ndarray
    p0: np.ndarray
    steps: int
    classifier: str
    threshold: float
    #: Chaotic by the indicator.
    chaotic: np.ndarray
    #: ``nu = w/m``; ``m = 0``: no rational found.
    w: np.ndarray
    m: np.ndarray
    #: ``A_n`` (Eq. An) at ``n = steps`` and at about ``steps / 2``.
    A: np.ndarray
    A_half: np.ndarray
    ftle: np.ndarray
    megno: np.ndarray
    fli: np.ndarray

    @property
    def island(self) -> np.ndarray:
        return self.m > 0

    @property
    def in_C(self) -> np.ndarray:
        return self.chaotic & (self.m == 0)

    @property
    def unidentified(self) -> np.ndarray:
        return ~self.chaotic & (self.m == 0)


def classify(
    params: MapParams,
    x0: np.ndarray,
    p0: np.ndarray,
    steps: int,
    *,
    m_max: int = DEFAULT_M_MAX,
    classifier: str = "ftle",
    threshold: float | None = None,
    threads: int | None = None,
    device: str | None = None,
    observers: Sequence[Observer] = (),
) -> PointClasses:
    """Iterate the points ``(x0, p0)`` for ``steps`` steps and classify each one (module docstring).

    Parameters
    ----------
    params : MapParams
    x0, p0 : array_like, shape (points,)
        Initial points on the torus.
    steps : int
        Iterations ``n >= min_steps(m_max)``; the momentum is also recorded at
        ``n i / CHECKPOINTS`` for :func:`identify_nu`.
    m_max, classifier, threshold
        See :func:`identify_nu` and :func:`chaotic_by`.
    threads, device, observers
        Passed to the ensemble and its :meth:`~warpratchet.ensemble.Ensemble.run`.
    """
    if classifier not in CLASSIFIERS:
        raise ValueError(f"classifier = {classifier!r} is not one of {', '.join(CLASSIFIERS)}")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps = {steps!r} is outside the allowed range steps >= 1")
    steps = int(steps)
    if steps < min_steps(m_max):  # fail before the run, not after it
        identify_nu(np.zeros((1, 0)), np.array([steps]), m_max)
    ens = IndicatorEnsemble(params, x0, p0, threads=threads, device=device)
    times = np.unique(np.linspace(0, steps, CHECKPOINTS + 1).astype(np.int64)[1:])
    rise = np.empty((times.size, ens.points))
    for i, k in enumerate(times):
        ens.run(int(k) - ens.step, observers)
        rise[i] = acceleration(ens.state(), ens.step) * ens.step
    state = ens.state()
    ind = ens.indicators()
    chaotic = chaotic_by(classifier, state, ind, steps, threshold)
    if threshold is None:
        threshold = {
            "ftle": default_lyapunov_threshold(steps),
            "megno": MEGNO_THRESHOLD,
            "fli": fli_threshold(steps),
        }[classifier]
    a_full = rise[-1] / steps
    w, m = identify_nu(rise, times, m_max)
    return PointClasses(
        x0=np.asarray(x0, dtype=np.float64),
        p0=np.asarray(p0, dtype=np.float64),
        steps=steps,
        classifier=classifier,
        threshold=float(threshold),
        chaotic=chaotic,
        w=w,
        m=m,
        A=a_full,
        A_half=rise[(times.size - 1) // 2] / times[(times.size - 1) // 2],
        ftle=lyapunov(state, steps),
        megno=ind["megno"],
        fli=ind["fli"],
    )


# -- the census ---------------------------------------------------------------------------------
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
    b1: float
    b2: float
    sampling: str
    points: int
    steps: int
    seed: int | None
    m_max: int
    classifier: str
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

    def island(self, nu: float) -> IslandClass | None:
        """The island class with mean velocity ``nu`` (exact rational match), if found."""
        for item in self.islands:
            if abs(item.nu - nu) < 1e-12:
                return item
        return None

    def as_dict(self) -> dict:
        """Plain dict (the JSON of ``warpratchet sumrule --json``)."""
        return asdict(self)


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
    m_max: int = DEFAULT_M_MAX,
    classifier: str = "ftle",
    threshold: float | None = None,
    threads: int | None = None,
    device: str | None = None,
    observers: Sequence[Observer] = (),
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
    seed, m_max, classifier, threshold, threads, device, observers
        See :func:`classify`.

    Returns
    -------
    Census
    """
    if (points is None) == (grid is None):
        raise ValueError("give exactly one of points = N (random) and grid = G (regular lattice)")
    if grid is not None:
        if isinstance(grid, bool) or not isinstance(grid, (int, np.integer)) or grid < 2:
            raise ValueError(f"grid = {grid!r} is outside the allowed range grid >= 2 (an integer)")
        x0, p0 = lattice(int(grid))
        sampling, used_seed = "grid", None
    else:
        if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 2:
            raise ValueError(f"points = {points!r} is outside the allowed range points >= 2 (an integer)")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed = {seed!r} is outside the allowed range seed >= 0 (an integer)")
        rng = np.random.default_rng(seed)
        x0, p0 = rng.random(int(points)), rng.random(int(points))
        sampling, used_seed = "random", int(seed)
    start = time.perf_counter()
    pc = classify(
        params, x0, p0, steps, m_max=m_max, classifier=classifier, threshold=threshold,
        threads=threads, device=device, observers=observers,
    )  # fmt: skip
    seconds = time.perf_counter() - start
    return _aggregate(params, pc, sampling, used_seed, m_max, grid, seconds)


def _mean_stderr(values: np.ndarray) -> tuple[float, float]:
    if values.size == 0:
        return math.nan, math.nan
    if values.size == 1:
        return float(values[0]), math.nan
    return float(values.mean()), float(values.std(ddof=1) / math.sqrt(values.size))


def _aggregate(params, pc: PointClasses, sampling, seed, m_max, grid, seconds) -> Census:
    n = pc.x0.size
    in_c = pc.in_C
    unidentified = pc.unidentified
    is_grid = sampling == "grid"

    def area_error(member: np.ndarray) -> float:
        f = float(member.mean())
        if is_grid:
            return _boundary_fraction(int(grid), member)
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
    a_direct, a_direct_err = _mean_stderr(pc.A[in_c])
    a_force, a_force_err = _mean_stderr(params.K * params.force(pc.x0[in_c]))
    torus_mean = float(pc.A.mean())
    torus_err = None if is_grid else float(pc.A.std(ddof=1) / math.sqrt(n))

    theory_values = c_check = None
    if params.K == 3.0:
        from .regions import in_C

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
        sampling=sampling,
        points=n,
        steps=pc.steps,
        seed=seed,
        m_max=int(m_max),
        classifier=pc.classifier,
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
    )
