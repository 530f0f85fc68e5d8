"""Exponents of transport: the diffusion exponent mu and the tails of the run-length histograms.

Pure NumPy: no Warp, no I/O.

**Diffusion exponent** (:func:`diffusion_fit`). ``V(n) = <(p_n - p_0 - A n)^2>``, the variance
over the chaotic points of the momentum gain at step ``n`` (``var_dp_chaotic`` of a History row:
``A n`` is one number at a given ``n``, so it is the variance of ``p_n - p_0``), grows like
``n^mu``: ``mu = 1`` for diffusion, ``1 < mu <= 2`` when flights along accelerator islands carry
the spread, ``mu < 1`` for subdiffusion. ``mu`` is the least-squares slope of ``log V`` on
``log n`` over the rows of the last ``decades`` decades (default 2: ``n >= n_last / 100``), where
the transient of an ensemble started off the invariant measure (the strip, the torus) has
decayed. Its standard error comes from the variance's own sampling error, through a **jackknife
over groups of points**: the ensemble is split into ``G`` groups (point ``i`` in group
``i mod G``), ``mu`` is refitted with each group left out, and
``se = sqrt((G - 1)/G sum_g (mu_-g - mean)^2)``. Rows at different ``n`` share their orbits, so
their errors are correlated and the least-squares error of the slope would be wrong; leaving out
whole groups of orbits keeps the correlations. (The fit's residuals are not an error either:
``V(n)`` is a smooth function of ``n`` plus sampling noise.)

**Tail exponents** (:func:`tail_fit`). For a histogram with log2 bins (bin ``k`` holds lengths
``2^k <= L < 2^(k+1)``) the fit is the maximum-likelihood estimate of ``alpha`` in a discrete
power law ``P(L) ~ L^-alpha`` restricted to the bins ``first..last``: the counts there are
multinomial with bin probabilities ``S_k(alpha) / sum_j S_j(alpha)``,
``S_k = sum_{L in bin k} L^-alpha`` (summed term by term up to bin 6, by the Euler-Maclaurin
midpoint formula beyond, relative error below 2e-7 there), so the discreteness of the lengths
causes no bias. The standard
error is from the curvature of the log-likelihood (observed Fisher information); ``p_value``
is the parametric-bootstrap probability of a worse fit (likelihood-ratio statistic against the
saturated model, 200 multinomial samples from the fitted law, a fixed seed), small when the
counts are not a power law over the range (below :data:`P_POWER_LAW` the fit says so:
``power_law`` is False). The default range starts at bin 3 (``L >= 8``) and
ends at the last bin whose lengths are below ``steps / 64``: a run of length ``L`` is counted
only if it ends within the run, so the counts of bin ``k`` are short by at most a fraction
``2^(k+1)/steps``; :attr:`TailFit.truncation_bias` bounds the resulting bias of ``alpha``. A
range with fewer than 3 non-empty bins or 50 counts gives no exponent (NaN) and says why.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

__all__ = [
    "MU_DECADES",
    "GROUPS",
    "TAIL_FIRST_BIN",
    "TAIL_LENGTH_FRACTION",
    "MIN_TAIL_BINS",
    "MIN_TAIL_COUNTS",
    "P_POWER_LAW",
    "DiffusionFit",
    "diffusion_fit",
    "group_moments",
    "pooled_variance",
    "TailFit",
    "tail_fit",
    "default_tail_bins",
    "bin_masses",
]

#: Decades of ``n`` (the last ones) over which ``mu`` is fitted.
MU_DECADES = 2.0
#: Groups of points of the jackknife error of ``mu``.
GROUPS = 16
#: First bin of the default tail range: lengths >= 8.
TAIL_FIRST_BIN = 3
#: The default tail range ends below ``steps * TAIL_LENGTH_FRACTION``.
TAIL_LENGTH_FRACTION = 1.0 / 64.0
#: A p-value below this flags the counts as not a power law over the fit range.
P_POWER_LAW = 0.01
#: Fewest non-empty bins, and fewest counts, for a tail exponent.
MIN_TAIL_BINS = 3
MIN_TAIL_COUNTS = 50
#: Largest bin whose mass is summed term by term (beyond: Euler-Maclaurin).
_EXACT_BINS = 6
_BOOTSTRAP = 200


# -- moments of groups of points ------------------------------------------------------------------
def group_moments(values: np.ndarray, groups: np.ndarray, count: int) -> np.ndarray:
    """Per-group ``(count, mean, sum of squared deviations)`` of ``values``, shape ``(count, 3)``.

    ``groups``: the group (``0 .. count - 1``) of each value. Deviations are taken from each
    group's own mean (no cancellation, whatever the mean).
    """
    values = np.asarray(values, dtype=np.float64)
    groups = np.asarray(groups)
    n = np.bincount(groups, minlength=count).astype(np.float64)
    total = np.bincount(groups, weights=values, minlength=count)
    mean = np.divide(total, n, out=np.zeros(count), where=n > 0)
    m2 = np.bincount(groups, weights=(values - mean[groups]) ** 2, minlength=count)
    return np.stack([n, mean, m2], axis=1)


def pooled_variance(moments: np.ndarray) -> float:
    """Sample variance (``ddof = 1``) of the union of groups from their :func:`group_moments`."""
    moments = np.asarray(moments, dtype=np.float64)
    n, mean, m2 = moments[:, 0], moments[:, 1], moments[:, 2]
    total = n.sum()
    if total < 2:
        return math.nan
    grand = float((n * mean).sum() / total)
    return float((m2.sum() + (n * (mean - grand) ** 2).sum()) / (total - 1.0))


# -- mu -----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DiffusionFit:
    """:func:`diffusion_fit`'s result. ``mu`` NaN (and ``reason`` set) when it cannot be fitted; a
    finite ``mu`` with ``reason`` set is flagged (the reason says why it is no diffusion exponent)."""

    mu: float
    stderr: float
    #: Steps of the first and last row of the fit.
    first_step: int
    last_step: int
    rows: int
    groups: int
    method: str
    reason: str | None = None
    #: ``1 - N_c(first row) / N_c(last row)``: how much the chaotic set grew over the fit range (the
    #: FTLE threshold falls with n, so later rows count orbits the earlier ones left out); NaN
    #: without groups.
    chaotic_growth: float = math.nan

    def as_dict(self) -> dict:
        return asdict(self)


def _slope(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.polyfit(x, y, 1)[0])


def diffusion_fit(
    steps: Sequence[float],
    var: Sequence[float],
    moments: np.ndarray | None = None,
    *,
    decades: float = MU_DECADES,
    min_rows: int = 4,
) -> DiffusionFit:
    """``mu`` of ``V(n) ~ n^mu`` over the last ``decades`` decades, with its jackknife error.

    Parameters
    ----------
    steps : sequence of int, shape (rows,)
        Log-spaced steps ``n`` (History rows), strictly increasing.
    var : sequence of float, shape (rows,)
        ``V(n)``, momentum units squared (``var_dp_chaotic``).
    moments : ndarray, shape (groups, rows, 3), optional
        :func:`group_moments` of ``p_n - p_0`` over the chaotic points of each group at each row;
        gives the jackknife standard error (NaN without). Rows where a group has fewer than 2
        chaotic points are left out of the fit.
    decades : float
        The fit uses the rows with ``n >= n_last / 10^decades``.
    min_rows : int
        Fewest rows in the range for a fit.
    """
    t = np.asarray(steps, dtype=np.float64)
    v = np.asarray(var, dtype=np.float64)
    if t.ndim != 1 or t.shape != v.shape:
        raise ValueError(f"steps and var must be 1-D of equal length; got shapes {t.shape}, {v.shape}")
    if not decades > 0:
        raise ValueError(f"decades = {decades!r} is outside the allowed range decades > 0")
    method = "least squares of log V on log n; error: jackknife over groups of points (point i in i mod G)"
    if t.size == 0:
        return DiffusionFit(math.nan, math.nan, 0, 0, 0, 0, method, "no rows")
    use = (t >= t[-1] / 10.0**decades) & np.isfinite(v) & (v > 0)
    m = None
    if moments is not None:
        m = np.asarray(moments, dtype=np.float64)
        if m.ndim != 3 or m.shape[1:] != (t.size, 3) or m.shape[0] < 2:
            raise ValueError(f"moments must have shape (groups >= 2, {t.size}, 3); got {m.shape}")
        # A row whose chaotic points leave a group with fewer than 2 (early rows, when the FTLE
        # threshold still classifies most points as regular) says little about V: left out.
        use &= np.all(m[:, :, 0] >= 2, axis=0)
    rows = int(use.sum())
    first, last = (int(t[use][0]), int(t[use][-1])) if rows else (0, 0)
    if rows < min_rows:
        reason = f"{rows} rows with V > 0 in the last {decades:g} decades of n; {min_rows} needed"
        return DiffusionFit(math.nan, math.nan, first, last, rows, 0, method, reason)
    x = np.log(t[use])
    mu = _slope(x, np.log(v[use]))
    if m is None:
        return DiffusionFit(mu, math.nan, first, last, rows, 0, method, "no groups of points: no error")
    groups = m.shape[0]
    leave_out = []
    for g in range(groups):
        rest = np.delete(m, g, axis=0)
        vg = np.array([pooled_variance(rest[:, i]) for i in np.flatnonzero(use)])
        if not np.all(np.isfinite(vg) & (vg > 0)):
            return DiffusionFit(mu, math.nan, first, last, rows, groups, method, "a group left no spread")
        leave_out.append(_slope(x, np.log(vg)))
    jack = np.array(leave_out)
    stderr = math.sqrt((groups - 1) / groups * float(((jack - jack.mean()) ** 2).sum()))
    counts = m[:, use, 0].sum(axis=0)
    growth = float(1.0 - counts[0] / counts[-1])
    reason = None
    if mu - 2.0 > 2.0 * stderr:
        # One set of orbits whose steps are bounded (|p_n - p_0| <= n K max|f|) spreads at most
        # ballistically, V ~ n^2, in the long run; a steeper slope is a transient (orbits entering
        # flights late, Delta p ~ v (n - tau)) or a set that changes with n.
        reason = (
            "mu > 2, faster than ballistic: no asymptotic diffusion exponent. Orbits still entering "
            "long flights within the fit range (sticky ones, riding an island) steepen V(n), and so "
            f"does the chaotic set, which grew by {growth:.1%} over the range as the FTLE threshold "
            "fell; see docs/transport.md"
        )
    return DiffusionFit(mu, stderr, first, last, rows, groups, method, reason, growth)


# -- tails ----------------------------------------------------------------------------------------------
def bin_masses(alpha: float, first: int, last: int) -> np.ndarray:
    """``S_k(alpha) = sum_{L = 2^k}^{2^(k+1) - 1} L^-alpha`` for ``k = first .. last``.

    Summed term by term up to bin 6; beyond, the Euler-Maclaurin midpoint formula
    ``int_{a}^{b} x^-alpha dx + alpha/24 (b^(-alpha-1) - a^(-alpha-1))`` with ``a = 2^k - 1/2``,
    ``b = 2^(k+1) - 1/2``. Its next term, ``7/5760 f'''(x)`` for ``f = x^-alpha``, is below 2e-7
    of the sum for ``L >= 128`` and ``|alpha| <= 12`` (2e-9 at ``alpha = 4``, measured against
    the direct sum).
    """
    out = np.empty(last - first + 1)
    for i, k in enumerate(range(first, last + 1)):
        if k <= _EXACT_BINS:
            out[i] = float(np.sum(np.arange(2.0**k, 2.0 ** (k + 1)) ** -alpha))
            continue
        a, b = 2.0**k - 0.5, 2.0 ** (k + 1) - 0.5
        if abs(alpha - 1.0) < 1e-12:
            integral = math.log(b / a)
        else:
            integral = (b ** (1.0 - alpha) - a ** (1.0 - alpha)) / (1.0 - alpha)
        out[i] = integral + alpha / 24.0 * (b ** (-alpha - 1.0) - a ** (-alpha - 1.0))
    return out


def _loglik(alpha: float, counts: np.ndarray, first: int, last: int) -> float:
    s = bin_masses(alpha, first, last)
    return float(np.sum(counts * np.log(s / s.sum())))


def _mle(counts: np.ndarray, first: int, last: int, lo: float = -2.0, hi: float = 12.0) -> float:
    """Golden-section search of the log-likelihood (concave in alpha: a multinomial likelihood of
    an exponential family in ``alpha``) on ``[lo, hi]``."""
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi
    c, d = b - golden * (b - a), a + golden * (b - a)
    fc, fd = _loglik(c, counts, first, last), _loglik(d, counts, first, last)
    while b - a > 1e-10:
        if fc > fd:
            b, d, fd = d, c, fc
            c = b - golden * (b - a)
            fc = _loglik(c, counts, first, last)
        else:
            a, c, fc = c, d, fd
            d = a + golden * (b - a)
            fd = _loglik(d, counts, first, last)
    return (a + b) / 2.0


def _newton(counts: np.ndarray, first: int, last: int, start: float) -> float:
    """The maximum of the log-likelihood near ``start`` (Newton steps on numerical derivatives;
    golden section if they do not settle)."""
    alpha, h = start, 1e-4
    for _ in range(20):
        up, mid, down = (_loglik(alpha + d, counts, first, last) for d in (h, 0.0, -h))
        slope, curvature = (up - down) / (2.0 * h), (up - 2.0 * mid + down) / h**2
        if not curvature < 0:
            break
        step = -slope / curvature
        alpha += step
        if abs(step) < 1e-9:
            return alpha
    return _mle(counts, first, last, start - 3.0, start + 3.0)


def _deviance(counts: np.ndarray, probs: np.ndarray) -> float:
    """Likelihood-ratio statistic ``2 sum c ln(c / (N p))`` against the saturated model."""
    n = counts.sum()
    seen = counts > 0
    return float(2.0 * np.sum(counts[seen] * np.log(counts[seen] / (n * probs[seen]))))


def default_tail_bins(steps: int) -> tuple[int, int]:
    """``(first, last)``: bins from :data:`TAIL_FIRST_BIN` to the last one below ``steps / 64``."""
    last = int(math.floor(math.log2(max(steps, 1) * TAIL_LENGTH_FRACTION))) - 1
    return TAIL_FIRST_BIN, last


@dataclass(frozen=True)
class TailFit:
    """:func:`tail_fit`'s result: ``alpha`` of ``P(L) ~ L^-alpha`` over bins ``first..last``."""

    alpha: float
    stderr: float
    first_bin: int
    last_bin: int
    #: Lengths covered, ``[2^first, 2^(last + 1))``, in steps.
    lengths: tuple[int, int]
    counts: int
    p_value: float
    #: Bound on the bias of ``alpha`` from runs cut off by the end of the run (see module).
    truncation_bias: float
    reason: str | None = None
    #: ``p_value >= P_POWER_LAW``: the counts are consistent with a power law over the range
    #: (False: ``alpha`` only summarises a steeper or curved fall-off; None: no fit).
    power_law: bool | None = None

    def as_dict(self) -> dict:
        return asdict(self)


def tail_fit(
    counts: Sequence[int], steps: int, *, first_bin: int | None = None, last_bin: int | None = None
) -> TailFit:
    """Maximum-likelihood tail exponent of a log2-binned histogram (module docstring).

    Parameters
    ----------
    counts : sequence of int, shape (bins,)
        Counts of completed runs per bin (bin ``k``: lengths ``[2^k, 2^(k+1))``).
    steps : int
        Length of the run that produced them (sets the default last bin and the bias bound).
    first_bin, last_bin : int, optional
        The fit range (default :func:`default_tail_bins`).
    """
    c = np.asarray(counts, dtype=np.int64)
    default_first, default_last = default_tail_bins(steps)
    first = default_first if first_bin is None else int(first_bin)
    last = min(default_last if last_bin is None else int(last_bin), c.size - 1)
    lengths = (2**first, 2 ** (last + 1)) if last >= first else (2**first, 2**first)
    bias = _truncation_bias(first, last, steps)

    def refused(reason: str, total: int = 0) -> TailFit:
        return TailFit(math.nan, math.nan, first, last, lengths, total, math.nan, bias, reason)

    if first < 0 or last < first:
        return refused(f"empty fit range: bins {first}..{last} (lengths {lengths[0]}..{lengths[1]})")
    inside = c[first : last + 1].astype(np.float64)
    total = int(inside.sum())
    nonempty = int(np.count_nonzero(inside))
    if nonempty < MIN_TAIL_BINS or total < MIN_TAIL_COUNTS:
        return refused(
            f"{total} counts in {nonempty} non-empty bins of {first}..{last} (lengths {lengths[0]} to "
            f"{lengths[1]}); a tail exponent needs {MIN_TAIL_COUNTS} counts in {MIN_TAIL_BINS} bins",
            total,
        )
    alpha = _mle(inside, first, last)
    h = 1e-4
    curvature = (
        _loglik(alpha + h, inside, first, last)
        - 2.0 * _loglik(alpha, inside, first, last)
        + _loglik(alpha - h, inside, first, last)
    ) / h**2
    stderr = math.sqrt(-1.0 / curvature) if curvature < 0 else math.nan
    masses = bin_masses(alpha, first, last)
    probs = masses / masses.sum()
    observed = _deviance(inside, probs)
    rng = np.random.default_rng(16)
    worse = 0
    for _ in range(_BOOTSTRAP):
        sample = rng.multinomial(total, probs).astype(np.float64)
        fitted = bin_masses(_newton(sample, first, last, alpha), first, last)
        worse += _deviance(sample, fitted / fitted.sum()) >= observed
    p_value = (worse + 1) / (_BOOTSTRAP + 1)
    return TailFit(
        alpha, stderr, first, last, lengths, total, p_value, bias, power_law=p_value >= P_POWER_LAW
    )


def _truncation_bias(first: int, last: int, steps: int) -> float:
    """Bound on ``|d alpha|`` from bins short by at most ``2^(k+1)/steps`` of their runs.

    The counts of bin ``k`` are multiplied by ``f_k`` in ``[1 - 2^(k+1)/steps, 1]``; the log of
    the ratio of two bins' counts then moves by at most ``-ln(1 - 2^(last+1)/steps)``, over a
    lever arm of at least one bin (``ln 2`` in ``ln L``).
    """
    if last < first or steps <= 0:
        return math.nan
    short = 2.0 ** (last + 1) / steps
    return -math.log1p(-short) / math.log(2.0) if short < 1 else math.inf
