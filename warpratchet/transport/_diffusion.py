"""The spread of the momentum at log-spaced steps, in groups of points, for the exponent mu.

:class:`Spread` is an observer that a :class:`~warpratchet.transport.TransportEnsemble` adds to
each of its runs: at the global steps ``round(10^(k/8))`` (:func:`spread_steps`, the log-spaced
part of :func:`warpratchet.history.history_steps`, which does not depend on the run's target)
it records, for each of :data:`~warpratchet.transport._fits.GROUPS` groups of points (point ``i``
in group ``i mod G``), the count, mean and sum of squared deviations of ``p_n - p_0`` over the
chaotic points (FTLE above the threshold at ``n``, as in History rows). Pooled, they give
``var_dp_chaotic`` of a History row at that step; the groups give the jackknife error of mu
(:func:`~warpratchet.transport._fits.diffusion_fit`). The rows are part of the ensemble's
transport state, so an archived run resumes them exactly.
"""

from __future__ import annotations

from concurrent.futures import Executor, ThreadPoolExecutor
from typing import Any

import numpy as np

from ..history import log_steps
from ..observables import lyapunov, lyapunov_threshold, momentum_gain
from ..runloop import Observer
from ._fits import GROUPS

__all__ = ["SPREAD_PER_DECADE", "SPREAD_BYTES_PER_POINT", "spread_steps", "spread_moments", "Spread"]

#: Rows per decade of n.
SPREAD_PER_DECADE = 8
#: Bytes per point a spread row allocates for its time: every point's FTLE (float64, lent to the
#: History row), gain (float64) and chaotic mask (bool); the blocks' temporaries are a few MB.
SPREAD_BYTES_PER_POINT = 8 + 8 + 1
#: Points per block of :func:`spread_moments` (its temporaries stay in the cache).
_BLOCK = 1 << 16
#: The state fields a row reads.
_FIELDS = ("winding", "q", "p0", "dx", "dp", "log_stretch")


def spread_steps(first: int, target: int, per_decade: int = SPREAD_PER_DECADE) -> list[int]:
    """The steps ``round(10^(k/per_decade))``, duplicates dropped, with ``first < n <= target``
    (the history's log-spaced grid, :func:`warpratchet.history.log_steps`)."""
    return log_steps(first, target, per_decade)


def _chaotic_gains(
    state: dict[str, np.ndarray],
    step: int,
    limit: float,
    gains: np.ndarray,
    mask: np.ndarray,
    ftle: np.ndarray | None,
    lo: int,
    hi: int,
) -> None:
    """Points ``lo <= i < hi``: ``ftle[i]`` (if given) their FTLE, ``mask[i]`` whether it is above
    ``limit``, ``gains[i]`` (+0.0 before) their ``p_n - p_0``, left alone for the others."""
    part = {name: state[name][lo:hi] for name in _FIELDS}
    exponents = lyapunov(part, step)
    if ftle is not None:
        ftle[lo:hi] = exponents
    chaotic = np.greater(exponents, limit, out=mask[lo:hi])
    np.copyto(gains[lo:hi], momentum_gain(part), where=chaotic)


def _squares(gains: np.ndarray, mask: np.ndarray, mean: np.ndarray, out: np.ndarray, lo: int, hi: int):
    """Rows ``lo <= r < hi`` of ``out``: ``(gain - group mean)^2`` of the chaotic points, the others
    left alone (``out`` may be ``gains`` itself: its other points are +0.0)."""
    np.copyto(out[lo:hi], (gains[lo:hi] - mean) ** 2, where=mask[lo:hi])


def spread_moments(
    state: dict[str, np.ndarray],
    step: int,
    threshold: float | None = None,
    rule: str = "strict",
    groups: int = GROUPS,
    pool: Executor | None = None,
    ftle: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`~warpratchet.transport._fits.group_moments` of ``p_n - p_0`` over the chaotic points.

    Returns shape ``(groups, 3)``: count, mean, sum of squared deviations per group. The FTLE and
    the gains are elementwise, computed in blocks of :data:`_BLOCK` points (on ``pool``'s threads
    if given: NumPy releases the GIL) into an array of shape ``(points / groups, groups)`` (point
    ``i`` at row ``i // groups``, column ``i mod groups``: its group), the points that are not
    chaotic as +0.0. Summed down the columns (NumPy adds row after row there), each group's sums
    are ``group_moments``' own (``bincount`` adds in the points' order too, and adding +0.0 changes
    no sum): the same bits, without gathering the chaotic points (half the cost of a row).

    ``ftle``: an array of shape ``(points,)`` that receives every point's FTLE on the way (a
    History row at the same step takes it instead of computing it again).
    """
    limit = lyapunov_threshold(step, rule) if threshold is None else threshold
    n = len(state["p0"])
    rows = -(-n // groups)
    gains = np.zeros((rows, groups))  # the padding past n: +0.0, not chaotic
    mask = np.zeros((rows, groups), dtype=bool)
    block = max(1, _BLOCK // groups)  # rows per block

    def each(work, *args, scale: int = 1) -> None:
        bounds = [(lo * scale, min(lo + block, rows) * scale) for lo in range(0, rows, block)]
        if pool is None or len(bounds) == 1:
            for lo, hi in bounds:
                work(*args, lo, hi)
        else:
            for future in [pool.submit(work, *args, lo, hi) for lo, hi in bounds]:
                future.result()

    # blocks of points, of whole rows (the padding past n stays as it is: its FTLE is not computed)
    points = gains.reshape(-1)[:n], mask.reshape(-1)[:n]
    each(_chaotic_gains, state, step, limit, *points, ftle, scale=groups)
    count = np.add.reduce(mask, axis=0, dtype=np.int64).astype(np.float64)
    total = np.add.reduce(gains, axis=0)
    mean = np.divide(total, count, out=np.zeros(groups), where=count > 0)
    # the squares overwrite the chaotic points' gains in place (the others stay +0.0): no second
    # array of the ensemble's size
    each(_squares, gains, mask, mean, gains)
    return np.stack([count, mean, np.add.reduce(gains, axis=0)], axis=1)


class Spread(Observer):
    """Records :func:`spread_moments` of ``ensemble`` at :func:`spread_steps` (module docstring).

    The rows are computed on as many threads as the ensemble runs on (the run waits for them):
    the run's own (:attr:`~warpratchet.ensemble.Ensemble.run_pool`), else a pool of its own.
    """

    def __init__(self, ensemble: Any) -> None:
        self.ensemble = ensemble
        self._pending: list[int] = []
        self._pool: ThreadPoolExecutor | None = None
        self._own_pool = False

    def begin(self, ensemble: Any, target_step: int) -> None:
        self._pending = spread_steps(ensemble.step, target_step)
        threads = getattr(ensemble, "threads", 1)
        self._pool = getattr(ensemble, "run_pool", None)
        self._own_pool = self._pool is None and bool(self._pending) and threads > 1
        if self._own_pool:
            self._pool = ThreadPoolExecutor(threads, thread_name_prefix="warpratchet-spread")

    def next_stop(self, step: int) -> int | None:
        return next((n for n in self._pending if n > step), None)

    def after_chunk(self, ensemble: Any, seconds: float) -> None:
        step = ensemble.step
        if step in self._pending:
            self._pending = [n for n in self._pending if n > step]
            views = {name: ensemble.array(name) for name in _FIELDS}
            ftle = np.empty(len(views["p0"]))
            moments = spread_moments(
                views, step, ensemble.threshold, ensemble.threshold_rule, pool=self._pool, ftle=ftle
            )
            ensemble.record_spread(step, moments, ftle)

    def end(self, ensemble: Any) -> None:
        if self._own_pool:
            self._pool.shutdown()
        self._pool, self._own_pool = None, False
