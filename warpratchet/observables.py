"""Per-point observables and ensemble summaries with standard errors.

Pure NumPy functions of the state arrays of :class:`warpratchet.ensemble.Ensemble` (so they
work on archived checkpoints as well as on live ensembles).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .errors import NonFiniteStateError, check_count, check_optional, check_real

__all__ = [
    "acceleration",
    "lyapunov",
    "default_lyapunov_threshold",
    "chaotic_mask",
    "mean_stderr",
    "MIN_CHAOTIC_POINTS",
    "SUMMARY_BYTES_PER_POINT",
    "AMBIGUITY_FACTOR",
    "UnreliableWarning",
    "reliability",
    "Summary",
    "summarize",
]

#: Fewest chaotic points for which A is reported as an estimate. The standard error is itself
#: estimated from the sample; its relative standard error is ``1/sqrt(2 (N - 1))`` (normal
#: samples), which is 10% at N = 51: below that, "A +- stderr" does not say how uncertain A is.
MIN_CHAOTIC_POINTS = 51
#: Working memory of :func:`summarize` per point, bytes, beyond the state it reads: the FTLE and
#: ``A_n`` (8 B each) and the temporaries of computing them (at most two more at a time), the
#: chaotic subsets (8 B each, all points at worst), the masks (1 B each). ``tests/test_limits.py``
#: measures the peak (tracemalloc) with every point chaotic and checks it stays below this.
SUMMARY_BYTES_PER_POINT = 64
#: Points whose FTLE lies within this factor of the threshold, on either side, are "ambiguous":
#: their classification could go either way (tests/test_statistics.py uses the same band).
AMBIGUITY_FACTOR = 3.0


class UnreliableWarning(UserWarning):
    """A summary whose A cannot be vouched for (too short a run, too few chaotic points)."""


def acceleration(state: dict[str, np.ndarray], step: int) -> np.ndarray:
    """Per-point mean acceleration ``A_n = (p_n - p_0)/n`` of Eq. (An), shape ``(points,)``.

    Computed as ``(winding + q - frac(p0)) / n``: every term is exact or a fraction in
    ``[0, 1)``, so no digits are lost however far the momentum has run.
    """
    if step <= 0:
        raise ValueError(f"step = {step!r}: A_n needs at least one iteration")
    p0 = state["p0"]
    return (state["winding"] + (state["q"] - (p0 - np.floor(p0)))) / step


def lyapunov(state: dict[str, np.ndarray], step: int) -> np.ndarray:
    """Per-point finite-time Lyapunov exponent ``log|DM^n v0| / n`` (``|v0| = 1``), shape ``(points,)``.

    Units: per iteration (natural log).
    """
    if step <= 0:
        raise ValueError(f"step = {step!r}: the FTLE needs at least one iteration")
    return (state["log_stretch"] + np.log(np.hypot(state["dx"], state["dp"]))) / step


def default_lyapunov_threshold(step: int) -> float:
    """Default chaos threshold on the FTLE after ``step`` iterations: ``10 (1 + ln n) / n``.

    Why this value. A regular orbit has a tangent that grows at most linearly, ``|v_n| <= a + b n``:
    in the islands around the period-1 modes the map is affine with the elliptic ``DM`` of
    Eq. (eig), so ``|v_n|`` stays bounded (``a`` of order the eigenvector condition number, a few
    units), and around higher-period orbits the shear makes it grow like ``n``. Either way the
    FTLE is below ``(ln a + ln(1 + b n))/n``, i.e. ``(1 + ln n)/n`` times a factor that is O(1)
    for any island whose ``a, b < e^9``; the factor 10 leaves that margin. Chaotic orbits
    converge to ``sigma > 0``; the smallest sigma in the paper's range (Fig. 7 inset) is
    ~0.03, far above the threshold at the paper's ``n = 120000`` (1.1e-3). For short runs the
    threshold rises (0.08 at ``n = 1000``) and weak chaos cannot be told from regular motion:
    run longer, or pass a threshold.
    """
    if step <= 0:
        raise ValueError(f"step = {step!r}: the threshold needs at least one iteration")
    return 10.0 * (1.0 + math.log(step)) / step


def chaotic_mask(ftle: np.ndarray, step: int, threshold: float | None = None) -> np.ndarray:
    """Boolean mask of chaotic points: ``ftle > threshold`` (default :func:`default_lyapunov_threshold`)."""
    if threshold is None:
        threshold = default_lyapunov_threshold(step)
    return ftle > threshold


def reliability(chaotic_points: int, A_stderr: float, classification_bound: float = 0.0) -> tuple[bool, str]:
    """Whether a mean A over ``chaotic_points`` points can be reported as an estimate, and why not.

    The rule, from the standard errors:

    1. at least :data:`MIN_CHAOTIC_POINTS` chaotic points, so that the standard error is known to
       10% (below that A is noise, and NaN with none);
    2. the classification bound (see :func:`summarize`) at most one standard error: how far A
       could move if the points near the threshold were classified the other way. A run too
       short for its threshold (the threshold ``10 (1 + ln n)/n`` is still near the chaotic
       FTLEs, e.g. 0.85 at n = 60 against sigma ~ 0.3) puts most points in that band and fails
       here; so does a threshold above the chaotic FTLEs.

    Returns
    -------
    (reliable, reason) : (bool, str)
        ``reason`` is ``""`` when reliable, else one sentence naming the numbers and what to do.
    """
    if chaotic_points < MIN_CHAOTIC_POINTS:
        return False, (
            f"only {chaotic_points} chaotic points (need {MIN_CHAOTIC_POINTS} for a standard error "
            "known to 10%); run longer or with more points"
        )
    if not classification_bound <= A_stderr:  # also NaN
        return False, (
            f"the points near the chaos threshold could move A by up to {classification_bound:.2g}, "
            f"more than its standard error {A_stderr:.2g}; run longer"
        )
    return True, ""


@dataclass(frozen=True)
class Summary:
    """Ensemble summary after ``step`` iterations (all per-iteration quantities).

    ``reliable`` is False (and ``reason`` says why) when A cannot be vouched for: see
    :func:`reliability`. Print A only together with that flag.
    """

    step: int
    #: Mean of A_n over chaotic points (the paper's A, Fig. 7) and its standard error.
    A: float
    A_stderr: float
    #: Mean, standard deviation and minimum of the FTLE over chaotic points.
    lyapunov: float
    lyapunov_std: float
    lyapunov_min: float
    chaotic_fraction: float
    chaotic_points: int
    threshold: float
    #: Largest change of A if every ambiguous point were classified the other way (>= 0).
    classification_bound: float = 0.0
    reliable: bool = True
    reason: str = ""

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def warn(self, stacklevel: int = 3) -> None:
        """Issue an :class:`UnreliableWarning` with :attr:`reason` if A is not reliable."""
        if not self.reliable:
            warnings.warn(f"A after {self.step} steps is unreliable: {self.reason}", UnreliableWarning,
                          stacklevel=stacklevel)  # fmt: skip

    def to_pandas(self) -> Any:
        """This summary as a one-row ``pandas.DataFrame`` indexed by ``step``.

        ``pandas.concat`` of several stacks them into a table. Needs pandas (not a dependency of
        warpratchet: ``pip install pandas``).
        """
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Summary.to_pandas needs pandas: pip install pandas") from None
        row = self.as_dict()
        return pd.DataFrame([row]).set_index("step")


def mean_stderr(values: np.ndarray) -> tuple[float, float]:
    """Mean of independent samples and its standard error ``std / sqrt(N)`` (ddof 1).

    NaN for both when ``values`` is empty; the error is NaN for a single value.
    """
    if values.size == 0:
        return math.nan, math.nan
    if values.size == 1:
        return float(values[0]), math.nan
    return float(values.mean()), float(values.std(ddof=1) / math.sqrt(values.size))


def summarize(state: dict[str, np.ndarray], step: int, threshold: float | None = None) -> Summary:
    """Mean ``A_n`` over chaotic points with its standard error, FTLE statistics, chaotic fraction.

    The standard error is ``std / sqrt(N_chaotic)``: points are independent samples of the
    initial distribution, so it is the honest sampling error of the ensemble mean. Quantities
    over an empty chaotic set are NaN.

    The classification bound: points with FTLE within a factor :data:`AMBIGUITY_FACTOR` of the
    threshold could be classified either way (regular orbits sit at FTLE <~ 1e-4, chaotic ones at
    sigma ~ 0.03-1; what lies between is a short run or an orbit sticking to an island). Moving
    one such point ``i`` in or out of the chaotic set moves the mean by ``|A_i - A| / N`` with
    ``N >= N_chaotic - N_ambiguous`` points left, so A could move by at most
    ``sum_i |A_i - A| / (N_chaotic - N_ambiguous)``. :func:`reliability` compares it with the
    standard error and sets ``reliable`` and ``reason``; no warning is issued here (sinks call
    this after every chunk; :meth:`Ensemble.summary` warns).

    Raises
    ------
    ParameterError
        ``step < 1``, or a ``threshold`` that is negative, NaN or infinite.
    NonFiniteStateError
        (a ``ValueError``) The state holds NaN or infinite values (a tangent that overflowed):
        a summary of it would not be a number.
    """
    step = check_count("step", step, 1)
    threshold = check_optional(check_real, "threshold", threshold, 0.0)
    if threshold is None:
        threshold = default_lyapunov_threshold(step)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):  # non-finite: refused below
        ftle = lyapunov(state, step)
        acc = acceleration(state, step)
    for values, name, why in (
        (ftle, "FTLE", "the tangent overflowed float64"),
        (acc, "A_n", "x, q, winding or p0 is not finite"),
    ):
        if not np.all(np.isfinite(values)):
            bad = int(np.count_nonzero(~np.isfinite(values)))
            raise NonFiniteStateError(
                f"{bad} of {values.size} points have a non-finite {name} ({why}): "
                "a state that is not finite has no summary"
            )
    mask = ftle > threshold
    a_mean, a_err = mean_stderr(acc[mask])
    chaotic_ftle = ftle[mask]
    chaotic_points = int(np.count_nonzero(mask))
    ambiguous = (ftle > threshold / AMBIGUITY_FACTOR) & (ftle < threshold * AMBIGUITY_FACTOR)
    n_ambiguous = int(np.count_nonzero(ambiguous))
    if n_ambiguous == 0:
        bound = 0.0
    elif chaotic_points > n_ambiguous:
        bound = float(np.abs(acc[ambiguous] - a_mean).sum()) / (chaotic_points - n_ambiguous)
    else:
        bound = math.inf
    reliable, reason = reliability(chaotic_points, a_err, bound)
    return Summary(
        step=int(step),
        A=a_mean,
        A_stderr=a_err,
        lyapunov=float(chaotic_ftle.mean()) if chaotic_ftle.size else math.nan,
        lyapunov_std=float(chaotic_ftle.std(ddof=1)) if chaotic_ftle.size > 1 else math.nan,
        lyapunov_min=float(chaotic_ftle.min()) if chaotic_ftle.size else math.nan,
        chaotic_fraction=float(mask.mean()),
        chaotic_points=chaotic_points,
        threshold=float(threshold),
        classification_bound=bound,
        reliable=reliable,
        reason=reason,
    )
