"""The verdict of a run: has its ``A`` converged? (what ``run`` prints and sweep rows keep).

Pure NumPy, no Warp, no I/O. :func:`assess` combines the two diagnostics of
:mod:`warpratchet.convergence` on what a :class:`~warpratchet.history.History` records: the drift
of ``A_n`` between n/2 and n (:func:`~warpratchet.convergence.drift`, from the rows) in units of
the robust standard error (:func:`~warpratchet.convergence.robust_stderr`, from the block gains
of a subsample), never below the plain error of all chaotic points.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from .convergence import RobustStderr, drift_from_history, robust_stderr

__all__ = ["Assessment", "assess"]


@dataclass(frozen=True)
class Assessment:
    """Whether a run's ``A`` has converged: what ``run`` reports and sweep rows keep (per iteration).

    ``A_stderr_robust`` is :attr:`RobustStderr.stderr` of the block subsample, never below the
    plain ``A_stderr`` of all chaotic points (NaN when the block gains are missing, ``missing`` says
    why), ``drift`` is ``A_n - A_{n/2}``, ``drift_z`` its ratio to its standard error (built on
    the robust error where there is one), ``verdict`` one of
    :data:`warpratchet.convergence.VERDICTS`.
    """

    A_stderr_robust: float
    drift: float
    drift_z: float
    verdict: str
    #: Growth exponent ``mu`` of the block variance (robust fit), NaN without blocks.
    exponent: float
    rule: str
    missing: str = ""

    def as_dict(self) -> dict:
        return asdict(self)


def assess(
    history: Mapping[str, Sequence[float]],
    gains: np.ndarray | None,
    steps: int,
    points: int,
    *,
    missing: str = "",
) -> Assessment:
    """The verdict of a run from its history rows and block gains.

    Parameters
    ----------
    history : mapping
        Rows with keys ``step``, ``A``, ``A_stderr`` and, optionally, ``var_dp_chaotic``; the last
        row is the run's end ``n = steps``.
    gains : ndarray, shape (B, M), or None
        Gains of ``M`` chaotic orbits over ``B`` equal blocks of ``[0, n]`` (:func:`robust_stderr`),
        None if they were not recorded (``missing`` says why).
    steps : int
        ``n``.
    points : int
        Chaotic points in the mean ``A`` (the robust error is for their mean).

    Notes
    -----
    The drift's standard error is built on the robust error when there is one, else on the plain
    ``A_stderr`` of the last row (module docstring). The block gains are those of a subsample
    (:mod:`warpratchet.history`: at most 4096 orbits), which may miss the rare long flights that
    dominate the plain error of the whole ensemble: the robust error is the larger of the two.
    Fewer than 2 chaotic orbits in the subsample, or none at all, leave the robust error NaN.
    """
    robust: RobustStderr | None = None
    if gains is not None and not missing:
        g = np.asarray(gains, dtype=np.float64)
        if g.ndim == 2 and g.shape[1] >= 2 and points >= 1 and steps >= g.shape[0]:
            robust = robust_stderr(g, int(steps), points=int(points))
        else:
            missing = f"only {g.shape[1] if g.ndim == 2 else 0} chaotic orbits in the block subsample"
    # The blocks are a subsample: the robust error never goes below the plain error of all the
    # chaotic points (a subsample may miss the rare long flights that dominate it).
    plain = float(np.asarray(history["A_stderr"], dtype=np.float64)[-1])
    error = (
        math.nan if robust is None else max(robust.stderr, plain) if math.isfinite(plain) else robust.stderr
    )
    d = drift_from_history(history, stderr=None if robust is None else error)
    return Assessment(
        A_stderr_robust=error,
        drift=d.delta,
        drift_z=d.z,
        verdict=d.verdict,
        exponent=math.nan if robust is None else robust.exponent,
        rule=d.rule,
        missing=missing,
    )
