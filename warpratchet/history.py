"""The history of a run: ensemble summaries at log-spaced global steps (issue 15).

One number per run hides convergence: near islands orbits stick for heavy-tailed times, and
``A_n`` of Eq. (An) can still drift when the run ends. A :class:`History` observer records, at
the global steps of :func:`history_steps` (at least 8 per decade, the run's half-way step and its
last step), one row of

=================  ==========================================================================
``step``           n, the global step of the row
``A``              mean of A_n = (p_n - p_0)/n over the chaotic points (Eq. An), per step
``A_stderr``       its standard error over points, std/sqrt(N_c)
``sigma``          mean finite-time Lyapunov exponent of the chaotic points, per step
``chaotic_fraction``  fraction of points with FTLE above the chaos threshold at n
``var_dp_all``     variance over all points of p_n - p_0 (units of momentum squared)
``var_dp_chaotic`` the same over the chaotic points
=================  ==========================================================================

The first five are exactly :func:`warpratchet.observables.summarize` at ``n`` (same threshold
rule), so the last row equals the end-of-run summary bit for bit. The variances are those of
``p_n - p_0 - A n`` too (``A n`` is one number at a given ``n``), whose growth ``~ n^mu`` says
whether transport is diffusive (``mu = 1``) or anomalous; :mod:`warpratchet.convergence` reads
the rows for the drift verdict.

The steps are global step numbers, fixed by the target alone, so a run split into chunks,
interrupted and continued to the same target records the same rows as an uninterrupted one.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .ensemble import STATE_FIELDS
from .errors import check_count, check_optional, check_real
from .observables import lyapunov, summarize
from .runloop import Observer

__all__ = ["HISTORY_FIELDS", "PER_DECADE", "history_steps", "history_row", "History"]

#: Row fields, in the order archives and JSON store them.
HISTORY_FIELDS = ("step", "A", "A_stderr", "sigma", "chaotic_fraction", "var_dp_all", "var_dp_chaotic")
#: Rows per decade of n (the issue asks for at least 8).
PER_DECADE = 8


def history_steps(first: int, target: int, per_decade: int = PER_DECADE) -> list[int]:
    """The global steps ``n`` with ``first < n <= target`` at which a history row is recorded.

    The steps ``round(10^(k/per_decade))`` for ``k = 0, 1, ...`` (duplicates dropped), plus
    ``target // 2`` (the drift of A between n/2 and n is read there exactly) and ``target``.
    """
    first = check_count("first", first, 0)
    target = check_count("target", target, 0)
    per_decade = check_count("per_decade", per_decade, 1, 1000)
    steps = {target, target // 2}
    k = 0
    while True:
        n = round(10.0 ** (k / per_decade))
        if n > target:
            break
        steps.add(n)
        k += 1
    return sorted(n for n in steps if first < n <= target)


def _variance(values: np.ndarray) -> float:
    return float(values.var(ddof=1)) if values.size > 1 else math.nan


def history_row(state: dict[str, np.ndarray], step: int, threshold: float | None = None) -> dict[str, Any]:
    """One history row (:data:`HISTORY_FIELDS`) of a state at global ``step``.

    Parameters
    ----------
    state : dict of ndarray, shape (points,) each
        The ensemble's state arrays (zero-copy views are fine: nothing is written).
    step : int
        Global step of the state, ``>= 1``.
    threshold : float, optional
        Chaos threshold on the FTLE (default: :func:`~warpratchet.observables.default_lyapunov_threshold`).
    """
    summary = summarize(state, step, threshold)
    p0 = state["p0"]
    # p_n - p_0 exactly as A_n * n is formed in observables.acceleration: winding + (q - frac p0).
    dp = state["winding"] + (state["q"] - (p0 - np.floor(p0)))
    chaotic = lyapunov(state, step) > summary.threshold
    return {
        "step": int(step),
        "A": summary.A,
        "A_stderr": summary.A_stderr,
        "sigma": summary.lyapunov,
        "chaotic_fraction": summary.chaotic_fraction,
        "var_dp_all": _variance(dp),
        "var_dp_chaotic": _variance(dp[chaotic]),
    }


class History(Observer):
    """Records :func:`history_row` at the steps of :func:`history_steps` of each run it observes.

    Parameters
    ----------
    threshold : float, optional
        Chaos threshold on the FTLE (default: the step-dependent default).
    per_decade : int, optional
        Rows per decade of n (default :data:`PER_DECADE`).

    Attributes
    ----------
    rows : dict of list
        One list per field of :data:`HISTORY_FIELDS`, all of one length, in step order. Rows
        appended by later runs (a run continued to a further target) follow on.
    """

    def __init__(self, threshold: float | None = None, per_decade: int = PER_DECADE) -> None:
        self.threshold = check_optional(check_real, "threshold", threshold, low=0.0)
        self.per_decade = check_count("per_decade", per_decade, 1, 1000)
        self.rows: dict[str, list] = {name: [] for name in HISTORY_FIELDS}
        self._pending: list[int] = []

    def begin(self, ensemble: Any, target_step: int) -> None:
        self._pending = history_steps(ensemble.step, target_step, self.per_decade)

    def next_stop(self, step: int) -> int | None:
        """The next history step after ``step`` (the run loop ends a chunk there)."""
        for n in self._pending:
            if n > step:
                return n
        return None

    def after_chunk(self, ensemble: Any, seconds: float) -> None:
        step = ensemble.step
        if step not in self._pending:
            return  # a regular chunk end between two history steps
        self._pending = [n for n in self._pending if n > step]
        views = {name: ensemble.array(name) for name in STATE_FIELDS}  # zero-copy on the CPU
        row = history_row(views, step, self.threshold)
        for name in HISTORY_FIELDS:
            self.rows[name].append(row[name])

    def as_dict(self) -> dict[str, list]:
        """The rows as a dict of equal-length lists (what ``run --json`` prints under ``history``)."""
        return {name: list(values) for name, values in self.rows.items()}
