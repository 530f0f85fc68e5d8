"""Per-point classification: the global chaotic region ``C``, island classes ``nu = w/m``, the rest.

Every point falls into

* an **island class** ``nu = w/m`` (Eq. AIn, ``m <= m_max``, lowest terms): the momentum gain
  ``p_k - p_0`` stays within ``4m`` of ``k w/m`` at each of :data:`CHECKPOINTS` run lengths
  ``k = n/8, ..., n``, as it does for any orbit confined to a period-``m`` island chain
  (:func:`excursion_bound`). This takes in every set with a rational mean velocity over the
  run: islands around accelerator modes of any period, normal islands (``nu = 0``), chaotic
  layers trapped inside island chains, and orbits of ``C`` stuck to an island for the whole
  run (sticky orbits; their share falls as ``n`` grows, see ``docs/validation.md``);
* the **global chaotic region** ``C``: chaotic by the chosen indicator
  (:mod:`._indicators`) and in no island class;
* **unidentified**: regular by the indicator but with no rational ``nu`` of denominator
  ``<= m_max`` (islands of longer period, or orbits that have not settled); reported, never
  silently folded into ``C``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .. import errors
from ..ensemble import Observer
from ..errors import NonFiniteStateError, check_choice, check_count, check_optional, check_real
from ..limits import MAX_POINTS, check_memory
from ..observables import finite_time_acceleration, lyapunov
from ..params import MapParams
from ._indicators import INDICATORS, IndicatorEnsemble, chaotic_by, default_threshold

__all__ = [
    "DEFAULT_M_MAX",
    "CHECKPOINTS",
    "excursion_bound",
    "min_steps",
    "identify_nu",
    "PointClasses",
    "classify",
    "CLASSIFY_HOST_BYTES_PER_POINT",
    "check_census_memory",
]

#: Default bound on the reduced denominator of ``nu = w/m``.
DEFAULT_M_MAX = 12
#: Run lengths ``n i / CHECKPOINTS`` (``i = 1..CHECKPOINTS``) at which an island orbit's momentum is
#: checked against ``p_0 + k nu``.
CHECKPOINTS = 8
#: Host memory of :func:`classify` per point, bytes (besides the ensemble's arrays): the initial
#: points (16 B), the momentum record (``CHECKPOINTS`` x 8 B), a copy of the state per checkpoint
#: (56 B), the per-point results (~70 B) and :func:`identify_nu`'s temporaries (three records at a
#: time). ``tests/core/test_limits.py`` measures the peak and checks it stays below this.
CLASSIFY_HOST_BYTES_PER_POINT = 448


def check_census_memory(points: int, request: str | None = None) -> None:
    """ResourceError, before anything is allocated, if a census of ``points`` does not fit here;
    ``request`` names the setting that asks for them (e.g. ``"grid = 40000"``) in the error."""
    points = check_count("points", points, 1, MAX_POINTS)
    device, host = IndicatorEnsemble.bytes_per_point(), CLASSIFY_HOST_BYTES_PER_POINT
    detail = f"{device} B of state and indicators and {host} B of working memory per point"
    what = f"a census of {points} points" + (f" ({request})" if request else "")
    check_memory(what, points * (device + host), detail)


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
    m_max = check_count("m_max", m_max, 1)
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
    for period in range(m_max, 0, -1):  # descending, so the smallest fitting period wins
        num = np.rint(a_full * period)
        off = np.abs(rise - times[:, None] * (num / period)).max(axis=0)
        ok = off <= excursion_bound(period)
        w = np.where(ok, num.astype(np.int64), w)
        m = np.where(ok, period, m)
    common = np.gcd(w, m)
    common[common == 0] = 1
    return w // common, m // common


def _check_finite(state: dict[str, np.ndarray], indicators: dict[str, np.ndarray], steps: int) -> None:
    """NonFiniteStateError if a point's FTLE, MEGNO or FLI is not finite: a NaN compares False
    with any threshold, so it would be classified regular, silently."""
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        values = {"FTLE": lyapunov(state, steps), **indicators}
    for name, v in values.items():
        bad = int(np.count_nonzero(~np.isfinite(v)))
        if bad:
            raise NonFiniteStateError(
                f"{bad} of {v.size} points have a non-finite {name} after {steps} steps (the tangent "
                "overflowed float64): they cannot be classified"
            )


@dataclass(frozen=True)
class PointClasses:
    """Per-point result of :func:`classify`; every array has shape ``(points,)``.

    ``island`` is ``m > 0``; ``in_C = chaotic & ~island`` is the global chaotic region;
    ``unidentified = ~chaotic & ~island``.
    """

    x0: np.ndarray
    p0: np.ndarray
    steps: int
    m_max: int
    indicator: str
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

    classifier = errors.renamed_attribute("PointClasses", "classifier", "indicator")

    @property
    def island(self) -> np.ndarray:
        return self.m > 0

    @property
    def in_C(self) -> np.ndarray:
        return self.chaotic & (self.m == 0)

    @property
    def unidentified(self) -> np.ndarray:
        return ~self.chaotic & (self.m == 0)


@errors.renamed_keyword("classifier", "indicator")
def classify(
    params: MapParams,
    x0: np.ndarray,
    p0: np.ndarray,
    steps: int,
    *,
    m_max: int = DEFAULT_M_MAX,
    indicator: str = "ftle",
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
    m_max, indicator, threshold
        See :func:`identify_nu` and :func:`~warpratchet.sumrule._indicators.chaotic_by`.
    threads, device, observers
        Passed to the ensemble and its :meth:`~warpratchet.ensemble.Ensemble.run`.
    """
    indicator = check_choice("indicator", indicator, INDICATORS)
    steps = check_count("steps", steps, 1)
    m_max = check_count("m_max", m_max, 1)
    threshold = check_optional(check_real, "threshold", threshold, 0.0)
    if steps < min_steps(m_max):  # fail before the run, not after it
        identify_nu(np.zeros((1, 0)), np.array([steps]), m_max)
    check_census_memory(np.size(x0))
    ens = IndicatorEnsemble(params, x0, p0, threads=threads, device=device)
    times = np.unique(np.linspace(0, steps, CHECKPOINTS + 1).astype(np.int64)[1:])
    rise = np.empty((times.size, ens.points))
    for i, k in enumerate(times):
        ens.run(int(k) - ens.step, observers)
        rise[i] = finite_time_acceleration(ens.state(), ens.step) * ens.step
    state = ens.state()
    ind = ens.indicators()
    _check_finite(state, ind, steps)
    if threshold is None:
        threshold = default_threshold(indicator, steps)
    w, m = identify_nu(rise, times, m_max)
    half = (times.size - 1) // 2
    return PointClasses(
        x0=np.asarray(x0, dtype=np.float64),
        p0=np.asarray(p0, dtype=np.float64),
        steps=steps,
        m_max=m_max,
        indicator=indicator,
        threshold=float(threshold),
        chaotic=chaotic_by(indicator, state, ind, steps, threshold),
        w=w,
        m=m,
        A=rise[-1] / steps,
        A_half=rise[half] / times[half],
        ftle=lyapunov(state, steps),
        megno=ind["megno"],
        fli=ind["fli"],
    )
