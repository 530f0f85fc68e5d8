"""Has ``A_n`` converged? Drift between ``n/2`` and ``n``, and a standard error robust to sticking.

Pure NumPy: no Warp, no I/O. Two questions about the ensemble mean ``A_n`` of Eq. (An):

1. **Drift** (:func:`drift`). ``A_n - A_{n/2}`` in units of its standard error. A run that starts
   off the invariant measure (the strip B, the torus) carries a transient: ``E A_n = A + b(n)``
   with ``b(n) -> 0``. If ``b(n) ~ n^-alpha`` then ``E(A_n - A_{n/2}) = b(n) (1 - 2^alpha)``, so the
   drift estimates the bias of ``A_n`` itself: ``|b(n)| = |drift| / (2^alpha - 1)``, i.e. ``|drift|``
   for a transient that settles (``alpha = 1``, Eq. An) and more than ``|drift|`` when orbits stick
   to islands for heavy-tailed times (``alpha = gamma - 1 < 1`` for sticking times with
   ``P(tau > t) ~ t^-gamma``, ``1 < gamma < 2``). Rule: **drifting** when ``|z| > DRIFT_Z_MAX = 3``
   (a false alarm in 0.27% of converged Gaussian runs), **converged** otherwise, **too short**
   when the record does not reach back to ``n/2``.
2. **Robust standard error** (:func:`robust_stderr`). Orbits are independent, so the spread of
   ``A_n`` over orbits, ``std / sqrt(N)``, is an unbiased estimate of the variance of the mean in
   mean square. Near islands it is unreliable in a typical run: the variance is carried by rare
   long flights (an orbit stuck to the R island moves at ``nu = -1`` against ``A ~ 0.01-0.05``),
   an ensemble of 10^4 orbits holds a handful of them or none, and the runs that hold none report
   both a small error and an ``A`` that is off (seen on Fig. 9's path: neighbouring ``b2`` with
   standard errors 4x apart). We use **batch means over time with variance-time scaling**: the
   across-orbit variance ``V(T)`` of the momentum gain over blocks of ``T`` steps is measured at
   the finest block lengths, where every orbit contributes ``n/T`` blocks and short flights are
   sampled thousands of times, its growth exponent ``mu`` (``V ~ T^mu``: 1 diffusive, up to 2
   ballistic; the flights make ``mu > 1``) is fitted there, and ``V(n)`` is extrapolated. The
   reported error is the larger of that and the plain one.

   Why not the two textbook choices. *Plain batch means over time* (ensemble-mean velocity in
   ``B`` time blocks treated as independent) cuts sticking episodes at block edges and ignores the
   correlation between blocks: on the heavy-tailed test process of ``tests/core/test_convergence.py``
   (Pareto sticking times, ``gamma = 1.3-1.5``) it reports 0.41-0.55 of the true error. *A block
   bootstrap over orbits* (each orbit's whole history one block, which keeps every episode intact)
   is right in mean square but reproduces ``std / sqrt(N)``, and so fails in the same typical runs:
   there the plain error has median 0.78-0.92 of the true error and its ``+-2`` error bars cover
   91-93% instead of 95.4%. The variance-time error has median 1.00-1.16 of the true error and
   covers 94-97%: slightly conservative, never optimistic in those tests. It is exact when the
   increments are stationary and ``V(T)`` is a power law. Orbits started off the invariant
   measure hold fewer flights early in the run than later, which makes it conservative (the
   1.00-1.16 above); a local exponent that keeps growing beyond the finest blocks would make it
   err low, and there the ``max`` with the plain error is the floor.

Data a run must provide.

* :func:`drift` needs only the history rows (log-spaced steps, >= 8 per decade): ``step``, ``A``,
  ``A_stderr`` and, optionally, ``var_dp_chaotic``. ``n/2`` need not be a recorded step: ``A`` is
  interpolated linearly in ``1/step`` between the rows around it (exact for a settled transient,
  ``A + B/n``), ``var_dp`` linearly in ``log step``.
* :func:`robust_stderr` needs the momentum gain of each orbit over ``B >= 8`` equal consecutive
  blocks covering ``[0, n]`` (shape ``(B, M)``, ``B = 64`` recommended) for a fixed subsample of
  ``M`` chaotic orbits (a few thousand suffice: every one contributes ``B`` blocks); the error it
  returns is for a mean over ``points`` orbits. An archive's snapshots hold exactly this when
  taken every ``n/B`` steps: the gain is the difference of ``step * A_n`` between snapshots,
  chaotic by the last snapshot's FTLE.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np

__all__ = [
    "DRIFT_Z_MAX",
    "VERDICTS",
    "Drift",
    "drift",
    "drift_from_history",
    "value_at",
    "diffusion_exponent",
    "RobustStderr",
    "robust_stderr",
]

#: ``|z|`` above which ``A_n - A_{n/2}`` counts as drift (two-sided Gaussian tail 0.27%).
DRIFT_Z_MAX = 3.0
#: Possible :attr:`Drift.verdict` values; ``"undefined"``: no A or no error at n or n/2 (no
#: chaotic points, or a single one).
VERDICTS = ("converged", "drifting", "too short", "undefined")


def _as_history(steps, values, name: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(steps, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if t.ndim != 1 or t.shape != v.shape:
        raise ValueError(f"steps and {name} must be 1-D of equal length; got shapes {t.shape}, {v.shape}")
    if t.size and (np.any(t <= 0) or np.any(np.diff(t) <= 0)):
        raise ValueError("steps must be positive and strictly increasing")
    return t, v


def value_at(
    steps: Sequence[float], values: Sequence[float], target: float, *, scale: str = "inverse"
) -> float:
    """A recorded quantity at ``target`` steps, interpolated between the two rows around it.

    Parameters
    ----------
    steps : sequence of float, shape (rows,)
        Strictly increasing positive steps of the record.
    values : sequence of float, shape (rows,)
        The quantity at each step.
    target : float
        Step at which it is wanted, ``steps[0] <= target <= steps[-1]``.
    scale : {"inverse", "log"}
        ``"inverse"``: linear in ``1/step`` (exact for ``A + B/n``, the settled transient of
        ``A_n``); ``"log"``: ``log value`` linear in ``log step`` (exact for a power law, e.g. the
        variance of ``p_n - p_0``).

    Returns
    -------
    float
        NaN if ``target`` is outside the record.
    """
    t, v = _as_history(steps, values, "values")
    if t.size == 0 or not t[0] <= target <= t[-1]:
        return math.nan
    if scale == "inverse":
        return float(np.interp(-1.0 / target, -1.0 / t, v))
    if scale == "log":
        return float(np.exp(np.interp(math.log(target), np.log(t), np.log(v))))
    raise ValueError(f"scale = {scale!r} is not one of inverse, log")


def diffusion_exponent(steps: Sequence[float], var_dp: Sequence[float], n: float | None = None) -> float:
    """Local growth exponent ``mu = log2(V(n) / V(n/2))`` of ``V(t) = Var(p_t - p_0)``.

    ``mu = 1``: normal diffusion; ``1 < mu <= 2``: superdiffusion by long flights (sticking);
    ``mu < 1``: subdiffusion. ``n`` defaults to the last step. NaN if the record does not reach
    ``n/2`` or a variance is not positive.
    """
    t, v = _as_history(steps, var_dp, "var_dp")
    if t.size == 0:
        return math.nan
    n = float(t[-1] if n is None else n)
    if np.any(v[t >= n / 2] <= 0):
        return math.nan
    full, half = value_at(t, v, n, scale="log"), value_at(t, v, n / 2, scale="log")
    return math.log2(full / half) if half > 0 else math.nan


@dataclass(frozen=True)
class Drift:
    """Result of :func:`drift`: ``A_n - A_{n/2}``, its standard error and the verdict."""

    step: int
    A: float
    A_half: float
    #: ``A_n - A_{n/2}`` per iteration; estimates minus the bias of ``A_n`` (module docstring).
    delta: float
    stderr: float
    z: float
    #: ``mu`` of :func:`diffusion_exponent`, NaN without ``var_dp``.
    exponent: float
    verdict: str
    rule: str

    def as_dict(self) -> dict:
        return asdict(self)


def drift(
    steps: Sequence[float],
    A: Sequence[float],
    A_stderr: Sequence[float],
    var_dp: Sequence[float] | None = None,
    *,
    stderr: float | None = None,
    z_max: float = DRIFT_Z_MAX,
) -> Drift:
    """Drift of ``A`` between ``n/2`` and ``n = steps[-1]`` and the verdict of the module's rule.

    Parameters
    ----------
    steps : sequence of int, shape (rows,)
        Recorded steps, strictly increasing (a history: log-spaced, the last one ``n``).
    A, A_stderr : sequence of float, shape (rows,)
        Mean ``A_n`` over chaotic points and its standard error at each step, per iteration.
    var_dp : sequence of float, shape (rows,), optional
        Ensemble variance of ``p_n - p_0`` over the chaotic points (for the exponent ``mu``).
    stderr : float, optional
        Standard error of ``A_n`` to use instead of ``A_stderr[-1]``, e.g.
        :attr:`RobustStderr.stderr`.
    z_max : float
        Threshold of the rule (default :data:`DRIFT_Z_MAX`).

    Notes
    -----
    With ``X, Y`` the gains of the two halves, ``A_n - A_{n/2} = (Y - X)/n``. If the increments
    are stationary with ``Var(p_t - p_0) ~ t^mu``, ``Var(A_n - A_{n/2}) = Var(A_n) (2^(2 - mu) - 1)``:
    equal to ``Var(A_n)`` for diffusion, smaller under flights (the halves are correlated), larger
    under subdiffusion. The standard error used is ``se(A_n) sqrt(max(1, 2^(2 - mu) - 1))``: never
    below ``se(A_n)``, so flights cannot raise false alarms through a small error.
    """
    t, a = _as_history(steps, A, "A")
    _, se = _as_history(steps, A_stderr, "A_stderr")
    if not z_max > 0:
        raise ValueError(f"z_max = {z_max!r} is outside the allowed range z_max > 0")
    rule = f"drifting if |A_n - A_n/2| > {z_max:g} x its standard error; too short if no record at <= n/2"
    if t.size == 0:
        raise ValueError("the record is empty: need at least the row of the last step")
    n = float(t[-1])
    mu = diffusion_exponent(t, var_dp, n) if var_dp is not None else math.nan
    base = float(se[-1]) if stderr is None else float(stderr)
    half = value_at(t, a, n / 2.0)
    if math.isnan(half):
        return Drift(int(n), float(a[-1]), math.nan, math.nan, base, math.nan, mu, "too short", rule)
    factor = math.sqrt(max(1.0, 2.0 ** (2.0 - mu) - 1.0)) if math.isfinite(mu) else 1.0
    delta = float(a[-1]) - half
    err = base * factor
    if not (math.isfinite(delta) and err >= 0):  # NaN A or error: nothing to judge
        return Drift(int(n), float(a[-1]), half, delta, err, math.nan, mu, "undefined", rule)
    z = delta / err if err > 0 else (math.inf if delta else 0.0)
    verdict = "drifting" if abs(z) > z_max else "converged"
    return Drift(int(n), float(a[-1]), half, delta, err, z, mu, verdict, rule)


def drift_from_history(history: Mapping[str, Sequence[float]], *, stderr: float | None = None) -> Drift:
    """:func:`drift` on a run's history (keys ``step``, ``A``, ``A_stderr``, optional ``var_dp_chaotic``)."""
    missing = [key for key in ("step", "A", "A_stderr") if key not in history]
    if missing:
        raise ValueError(f"history is missing keys {missing}")
    return drift(
        history["step"], history["A"], history["A_stderr"], history.get("var_dp_chaotic"), stderr=stderr
    )


# -- batch means over time with variance-time scaling -----------------------------------------------
@dataclass(frozen=True)
class RobustStderr:
    """Result of :func:`robust_stderr` (per-iteration units, like ``A``)."""

    #: The robust standard error: ``max(variance_time_stderr, naive_stderr)``.
    stderr: float
    #: Error from the variance extrapolated from the finest blocks to ``n``.
    variance_time_stderr: float
    #: ``std(p_n - p_0) / (n sqrt(points))`` of the same orbits: the plain error.
    naive_stderr: float
    #: Fitted growth exponent ``mu`` of the block variance (clipped to [0, 2]).
    exponent: float
    #: Block lengths (steps) and across-orbit variances of the gain at each level, finest first.
    block_steps: tuple[float, ...]
    variances: tuple[float, ...]
    points: int

    def as_dict(self) -> dict:
        return asdict(self)


def _levels(gains: np.ndarray, block: float) -> tuple[list[float], list[float]]:
    """Across-orbit variance of the gain over blocks of ``block * 2^l`` steps, ``l = 0, 1, ...``.

    At each level adjacent blocks are merged in pairs from the end of the run; an odd block left
    at the start (the transient) is dropped from the coarser levels. The variance at a level is
    the across-orbit variance of each block, averaged over blocks, so differences of the ensemble
    mean between blocks (the transient) do not enter.
    """
    lengths, variances = [], []
    level = gains
    while True:
        lengths.append(block)
        variances.append(float(level.var(axis=1, ddof=1).mean()))
        if level.shape[0] < 2:
            return lengths, variances
        if level.shape[0] % 2:
            level = level[1:]
        level = level[0::2] + level[1::2]
        block *= 2.0


def robust_stderr(
    gains: np.ndarray, steps: int, *, points: int | None = None, fit_levels: int = 3
) -> RobustStderr:
    """Standard error of the mean ``A_n`` robust to heavy-tailed sticking (module docstring).

    Parameters
    ----------
    gains : ndarray, shape (B, M)
        Momentum gain ``p_{(b+1)T} - p_{bT}`` of each of ``M >= 2`` orbits over ``B >= 8`` equal
        consecutive blocks of ``T = steps / B`` steps covering ``[0, steps]``.
    steps : int
        ``n``, the run length.
    points : int, optional
        Number of orbits in the mean whose error is wanted (default ``M``): the ``M`` orbits may be
        a subsample of the chaotic points of the ensemble.
    fit_levels : int
        Number of finest block lengths ``T, 2T, ...`` on which ``mu`` is fitted, by least squares
        of ``log V`` on ``log T``: at least 2, fewer than the number of block lengths
        (``1 + ceil(log2 B)`` or so; 7 for ``B = 64``).

    Returns
    -------
    RobustStderr
        ``V(n) = V(T_0) (n / T_0)^mu`` (from the fit's centroid), ``stderr =
        max(sqrt(V(n) / points) / n, naive)``.
    """
    g = np.asarray(gains, dtype=np.float64)
    if g.ndim != 2 or g.shape[0] < 8 or g.shape[1] < 2:
        raise ValueError(f"gains must have shape (B >= 8 blocks, M >= 2 orbits); got {g.shape}")
    if not np.all(np.isfinite(g)):
        raise ValueError("gains must be finite")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < g.shape[0]:
        raise ValueError(
            f"steps = {steps!r} is outside the allowed range steps >= B = {g.shape[0]} (an integer)"
        )
    n_points = g.shape[1] if points is None else points
    if isinstance(n_points, bool) or not isinstance(n_points, (int, np.integer)) or n_points < 1:
        raise ValueError(f"points = {points!r} is outside the allowed range points >= 1 (an integer)")
    lengths, variances = _levels(g, steps / g.shape[0])
    if isinstance(fit_levels, bool) or not isinstance(fit_levels, int) or not 2 <= fit_levels < len(lengths):
        raise ValueError(
            f"fit_levels = {fit_levels!r} is outside the allowed range 2 <= fit_levels < {len(lengths)} "
            f"(the number of block lengths for B = {g.shape[0]})"
        )
    # The plain error: the variance of the whole gain over the same orbits (no block dropped).
    naive = math.sqrt(g.sum(axis=0).var(ddof=1) / n_points) / steps
    x, y = np.log(lengths[:fit_levels]), np.log(np.maximum(variances[:fit_levels], 1e-300))
    if np.all(np.asarray(variances[:fit_levels]) > 0):
        mu = float(np.clip(np.polyfit(x, y, 1)[0], 0.0, 2.0))
        v_n = math.exp(y.mean() + mu * (math.log(steps) - x.mean()))
    else:  # every orbit moved identically over the finest blocks: nothing to extrapolate
        mu, v_n = math.nan, 0.0
    vt = math.sqrt(v_n / n_points) / steps
    return RobustStderr(
        stderr=max(vt, naive),
        variance_time_stderr=vt,
        naive_stderr=naive,
        exponent=mu,
        block_steps=tuple(lengths),
        variances=tuple(variances),
        points=int(n_points),
    )
