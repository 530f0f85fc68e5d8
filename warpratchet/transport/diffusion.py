"""The spread of the momentum at log-spaced steps, in groups of points, for the exponent mu.

:class:`Spread` is an observer that a :class:`~warpratchet.transport.TransportEnsemble` adds to
each of its runs: at the global steps ``round(10^(k/8))`` (:func:`spread_steps`, the log-spaced
part of :func:`warpratchet.history.history_steps`, which does not depend on the run's target)
it records, for each of :data:`~warpratchet.transport.fits.GROUPS` groups of points (point ``i``
in group ``i mod G``), the count, mean and sum of squared deviations of ``p_n - p_0`` over the
chaotic points (FTLE above the threshold at ``n``, as in History rows). Pooled, they give
``var_dp_chaotic`` of a History row at that step; the groups give the jackknife error of mu
(:func:`~warpratchet.transport.fits.diffusion_fit`). The rows are part of the ensemble's
transport state, so an archived run resumes them exactly.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import check_count
from ..observables import default_lyapunov_threshold, lyapunov
from ..runloop import Observer
from .fits import GROUPS, group_moments

__all__ = ["SPREAD_PER_DECADE", "spread_steps", "spread_moments", "Spread"]

#: Rows per decade of n.
SPREAD_PER_DECADE = 8


def spread_steps(first: int, target: int, per_decade: int = SPREAD_PER_DECADE) -> list[int]:
    """The steps ``round(10^(k/per_decade))``, duplicates dropped, with ``first < n <= target``."""
    first = check_count("first", first, 0)
    target = check_count("target", target, 0)
    steps, k = set(), 0
    while (n := round(10.0 ** (k / per_decade))) <= target:
        if n > first:
            steps.add(n)
        k += 1
    return sorted(steps)


def spread_moments(
    state: dict[str, np.ndarray], step: int, threshold: float | None = None, groups: int = GROUPS
) -> np.ndarray:
    """:func:`~warpratchet.transport.fits.group_moments` of ``p_n - p_0`` over the chaotic points.

    Returns shape ``(groups, 3)``: count, mean, sum of squared deviations per group.
    """
    p0 = state["p0"]
    # p_n - p_0 exactly as A_n * n is formed in observables.acceleration: winding + (q - frac p0).
    dp = state["winding"] + (state["q"] - (p0 - np.floor(p0)))
    limit = default_lyapunov_threshold(step) if threshold is None else threshold
    chaotic = np.flatnonzero(lyapunov(state, step) > limit)
    return group_moments(dp[chaotic], chaotic % groups, groups)


class Spread(Observer):
    """Records :func:`spread_moments` of ``ensemble`` at :func:`spread_steps` (module docstring)."""

    def __init__(self, ensemble: Any) -> None:
        self.ensemble = ensemble
        self._pending: list[int] = []

    def begin(self, ensemble: Any, target_step: int) -> None:
        self._pending = spread_steps(ensemble.step, target_step)

    def next_stop(self, step: int) -> int | None:
        return next((n for n in self._pending if n > step), None)

    def after_chunk(self, ensemble: Any, seconds: float) -> None:
        step = ensemble.step
        if step in self._pending:
            self._pending = [n for n in self._pending if n > step]
            views = {
                name: ensemble.array(name) for name in ("x", "q", "winding", "p0", "dx", "dp", "log_stretch")
            }
            ensemble.record_spread(step, spread_moments(views, step, ensemble.threshold))
