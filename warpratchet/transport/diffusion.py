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

from concurrent.futures import Executor, ThreadPoolExecutor
from typing import Any

import numpy as np

from ..history import log_steps
from ..observables import default_lyapunov_threshold, lyapunov
from ..runloop import Observer
from .fits import GROUPS, group_moments

__all__ = ["SPREAD_PER_DECADE", "spread_steps", "spread_moments", "Spread"]

#: Rows per decade of n.
SPREAD_PER_DECADE = 8
#: Points per block of :func:`spread_moments` (its temporaries stay in the cache).
_BLOCK = 1 << 16
#: The state fields a row reads.
_FIELDS = ("winding", "q", "p0", "dx", "dp", "log_stretch")


def spread_steps(first: int, target: int, per_decade: int = SPREAD_PER_DECADE) -> list[int]:
    """The steps ``round(10^(k/per_decade))``, duplicates dropped, with ``first < n <= target``
    (the history's log-spaced grid, :func:`warpratchet.history.log_steps`)."""
    return log_steps(first, target, per_decade)


def _chaotic_gains(
    state: dict[str, np.ndarray], step: int, limit: float, lo: int, hi: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(indices, p_n - p_0)`` of the points ``lo <= i < hi`` whose FTLE is above ``limit``."""
    part = {name: state[name][lo:hi] for name in _FIELDS}
    where = np.flatnonzero(lyapunov(part, step) > limit)
    p0 = part["p0"][where]
    # p_n - p_0 exactly as A_n * n is formed in observables.acceleration: winding + (q - frac p0).
    return where + lo, part["winding"][where] + (part["q"][where] - (p0 - np.floor(p0)))


def spread_moments(
    state: dict[str, np.ndarray],
    step: int,
    threshold: float | None = None,
    groups: int = GROUPS,
    pool: Executor | None = None,
) -> np.ndarray:
    """:func:`~warpratchet.transport.fits.group_moments` of ``p_n - p_0`` over the chaotic points.

    Returns shape ``(groups, 3)``: count, mean, sum of squared deviations per group. The FTLE and
    the gains are elementwise, computed in blocks of :data:`_BLOCK` points (on ``pool``'s threads
    if given: NumPy releases the GIL); the moments are summed over the points in their order, so
    the result does not depend on the blocks or the threads.
    """
    limit = default_lyapunov_threshold(step) if threshold is None else threshold
    n = len(state["p0"])
    bounds = [(lo, min(lo + _BLOCK, n)) for lo in range(0, n, _BLOCK)] or [(0, 0)]
    if pool is None or len(bounds) == 1:
        parts = [_chaotic_gains(state, step, limit, lo, hi) for lo, hi in bounds]
    else:
        parts = [f.result() for f in [pool.submit(_chaotic_gains, state, step, limit, *b) for b in bounds]]
    chaotic = np.concatenate([where for where, _ in parts])
    return group_moments(np.concatenate([dp for _, dp in parts]), chaotic % groups, groups)


class Spread(Observer):
    """Records :func:`spread_moments` of ``ensemble`` at :func:`spread_steps` (module docstring).

    The rows are computed on as many threads as the ensemble runs on (the run waits for them).
    """

    def __init__(self, ensemble: Any) -> None:
        self.ensemble = ensemble
        self._pending: list[int] = []
        self._pool: ThreadPoolExecutor | None = None

    def begin(self, ensemble: Any, target_step: int) -> None:
        self._pending = spread_steps(ensemble.step, target_step)
        threads = getattr(ensemble, "threads", 1)
        if self._pending and threads > 1:
            self._pool = ThreadPoolExecutor(threads, thread_name_prefix="warpratchet-spread")

    def next_stop(self, step: int) -> int | None:
        return next((n for n in self._pending if n > step), None)

    def after_chunk(self, ensemble: Any, seconds: float) -> None:
        step = ensemble.step
        if step in self._pending:
            self._pending = [n for n in self._pending if n > step]
            views = {name: ensemble.array(name) for name in _FIELDS}
            ensemble.record_spread(step, spread_moments(views, step, ensemble.threshold, pool=self._pool))

    def end(self, ensemble: Any) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
