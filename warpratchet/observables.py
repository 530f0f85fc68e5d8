"""Per-point observables and ensemble summaries with standard errors.

Pure NumPy functions of the state arrays of :class:`warpratchet.ensemble.Ensemble` (so they
work on archived checkpoints as well as on live ensembles).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

__all__ = [
    "acceleration",
    "lyapunov",
    "default_lyapunov_threshold",
    "chaotic_mask",
    "mean_stderr",
    "Summary",
    "summarize",
]


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


@dataclass(frozen=True)
class Summary:
    """Ensemble summary after ``step`` iterations (all per-iteration quantities)."""

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

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


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
    """
    if threshold is None:
        threshold = default_lyapunov_threshold(step)
    ftle = lyapunov(state, step)
    if not np.all(np.isfinite(ftle)):
        bad = int(np.count_nonzero(~np.isfinite(ftle)))
        raise FloatingPointError(f"{bad} tangent vectors overflowed; b1 or b2 is too small for float64")
    mask = ftle > threshold
    a_mean, a_err = mean_stderr(acceleration(state, step)[mask])
    chaotic_ftle = ftle[mask]
    return Summary(
        step=int(step),
        A=a_mean,
        A_stderr=a_err,
        lyapunov=float(chaotic_ftle.mean()) if chaotic_ftle.size else math.nan,
        lyapunov_std=float(chaotic_ftle.std(ddof=1)) if chaotic_ftle.size > 1 else math.nan,
        lyapunov_min=float(chaotic_ftle.min()) if chaotic_ftle.size else math.nan,
        chaotic_fraction=float(mask.mean()),
        chaotic_points=int(mask.sum()),
        threshold=float(threshold),
    )
