"""The history of a run: ensemble summaries at log-spaced global steps, and block gains.

One number per run hides convergence: near islands orbits stick for heavy-tailed times, and
``A_n`` of Eq. (An) can still drift when the run ends. A :class:`History` observer records two
things, both at global steps fixed by the run's target alone:

**Rows**, at the steps of :func:`history_steps` (at least 8 per decade, the run's half-way step
and its last step):

=====================  ======================================================================
``step``               n, the global step of the row
``A``                  mean of A_n = (p_n - p_0)/n over the chaotic points (Eq. An), per step
``A_stderr``           its standard error over points, std/sqrt(N_c)
``sigma``              mean finite-time Lyapunov exponent of the chaotic points, per step
``chaotic_fraction``   fraction of points with FTLE above the chaos threshold at n
``chaotic_points``     their number, N_c
``var_dp_all``         variance over all points of p_n - p_0 (units of momentum squared)
``var_dp_chaotic``     the same over the chaotic points, ``n^2 N_c A_stderr^2``
=====================  ======================================================================

The first six are exactly :func:`warpratchet.observables.summarize` at ``n`` (same threshold
and rule), so the last row equals the end-of-run summary bit for bit. The variances are those
of ``p_n - p_0 - A n`` too (``A n`` is one number at a given ``n``); their growth ``~ n^mu`` says
whether transport is diffusive (``mu = 1``) or anomalous.

**Block gains**, at the :data:`BLOCKS` steps ``floor(target j / BLOCKS)``, ``j = 1 .. BLOCKS``
(:func:`block_steps`): the momentum gain ``p_n - p_0`` and the FTLE of a fixed random subsample of
at most :data:`BLOCK_POINTS` points (:func:`block_subsample`, seeded by the run's seed). Their
differences are the gains over ``BLOCKS`` equal time blocks that the robust standard error of
:func:`warpratchet.convergence.robust_stderr` needs (batch means over time); the subsample's
chaotic orbits are those above the threshold at the last block step. Why a subsample recorded
during the run: the blocks must be cut from one run at equal times, which no end-of-run state can
give afterwards; 4096 orbits give every block length 4096 x (blocks) samples, enough for the
variance-time fit (module :mod:`warpratchet.convergence`), for 4 MB of archive at 64 blocks.
The run need not stop at the block steps: the history copies the subsample's points when the run
begins and advances that copy itself to each block step it has passed (points are independent and
checks sit at global steps, so the copy's states are the run's, bit for bit, at the cost of
advancing 4096 more points). Where that costs more than stopping (a small ensemble run long: the
README's 10^4 points x 120 000 steps would advance 41% more points), the run stops at the block
steps instead and the records are read from the ensemble itself, the same bits
(:func:`copies_blocks` chooses).

:meth:`History.convergence` turns both into the verdict (:func:`warpratchet.verdict.assess`):
the drift of A between n/2 and n in units of its standard error and the robust error.

The steps are global step numbers fixed by the target alone, so a run split into chunks,
interrupted and continued to the same target records the same rows and blocks, bit for bit, as
an uninterrupted one (:meth:`History.restore` continues a history kept in an archive). Each row
costs about one summary (:meth:`Ensemble.summary <warpratchet.ensemble.Ensemble.summary>`: the
summary and the variance of ``p_n - p_0`` in the same memory-bound passes over the state, on the
run's threads, or on the observer's thread from a copy of the state while the run's threads go on:
:mod:`warpratchet.runloop`): the time of some tens of kernel steps, little against a long run and
much against a short run of many points (measured: ``benchmarks/README.md``, "end_to_end.py").
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .ensemble import STATE_FIELDS, Ensemble
from .errors import check_choice, check_count, check_optional, check_real, renamed_keyword
from .observables import (
    THRESHOLD_RULES,
    Summary,
    chaotic_mask,
    lyapunov,
    momentum_gain,
    summary_chunks,
)
from .runloop import Observer
from .sampling import salted_subsample
from .verdict import Assessment, assess

__all__ = [
    "log_steps",
    "HISTORY_FIELDS",
    "INT_FIELDS",
    "BLOCK_FIELDS",
    "PER_DECADE",
    "BLOCKS",
    "BLOCK_POINTS",
    "history_steps",
    "block_steps",
    "block_subsample",
    "history_row",
    "History",
]

#: Row fields, in the order archives and JSON store them.
HISTORY_FIELDS = (
    "step",
    "A",
    "A_stderr",
    "sigma",
    "chaotic_fraction",
    "chaotic_points",
    "var_dp_all",
    "var_dp_chaotic",
)
#: Row fields stored as int64.
INT_FIELDS = ("step", "chaotic_points")
#: Per-block records: the step, and ``(M,)`` arrays of the subsample's gain and FTLE.
BLOCK_FIELDS = ("block_step", "block_gain", "block_ftle")
#: Rows per decade of n (at least 8, enough to see a drift between decades).
PER_DECADE = 8
#: Equal time blocks of the robust standard error (:func:`warpratchet.convergence.robust_stderr`).
BLOCKS = 64
#: Most points in the block subsample.
BLOCK_POINTS = 4096
#: Salt of the subsample's generator, so that it differs from the sampler's and the snapshots'.
_BLOCK_SALT = 0xB10C
#: A stop of the run (a launch boundary: every point's state loaded and stored once more, and the
#: launch itself) costs about as much CPU time as this many steps of every point
#: (benchmarks/README.md, end_to_end.py).
STOP_STEPS = 20


def log_steps(first: int, target: int, per_decade: int = PER_DECADE) -> list[int]:
    """The steps ``round(10^(k/per_decade))``, ``k = 0, 1, ...`` (duplicates dropped), with
    ``first < n <= target``: the log-spaced grid of the history's rows (and of transport's spread)."""
    first = check_count("first", first, 0)
    target = check_count("target", target, 0)
    per_decade = check_count("per_decade", per_decade, 1, 1000)
    steps, k = set(), 0
    while (n := round(10.0 ** (k / per_decade))) <= target:
        if n > first:
            steps.add(n)
        k += 1
    return sorted(steps)


def history_steps(first: int, target: int, per_decade: int = PER_DECADE) -> list[int]:
    """The global steps ``n`` with ``first < n <= target`` at which a history row is recorded.

    :func:`log_steps`, plus ``target // 2`` (the drift of A between n/2 and n is read there
    exactly) and ``target``.
    """
    first = check_count("first", first, 0)
    target = check_count("target", target, 0)
    ends = {n for n in (target, target // 2) if n > first}
    return sorted(set(log_steps(first, target, per_decade)) | ends)


def block_steps(first: int, target: int, blocks: int = BLOCKS) -> list[int]:
    """The steps ``floor(target j / blocks)``, ``j = 1 .. blocks``, with ``first < n``: block ends.

    Blocks are equal to within one step (exactly equal when ``blocks`` divides ``target``).
    """
    first = check_count("first", first, 0)
    target = check_count("target", target, 0)
    blocks = check_count("blocks", blocks, 1, 1 << 16)
    return sorted({target * j // blocks for j in range(1, blocks + 1)} - {0} - set(range(first + 1)))


def block_subsample(points: int, seed: int | None, size: int = BLOCK_POINTS) -> np.ndarray:
    """Sorted indices of the block subsample: ``min(size, points)`` points drawn without replacement.

    Seeded by the run's ``seed`` (0 for none), so a resumed run draws the same points.
    """
    points = check_count("points", points, 1)
    m = min(check_count("size", size, 1), points)
    return salted_subsample(points, seed, m, _BLOCK_SALT)


def copies_blocks(points: int, subsample: int, steps: int, blocks: int) -> bool:
    """Whether a history advances its own copy of the ``subsample`` points over the ``steps`` of a run
    (``subsample x steps`` point-steps) rather than stopping the run of ``points`` points at its
    ``blocks`` block steps (each about :data:`STOP_STEPS` steps of every point): the cheaper one.
    Both give the same records, bit for bit."""
    return subsample * steps <= blocks * STOP_STEPS * points


def _none(step: int) -> None:
    return None


def _variance(state: Mapping[str, np.ndarray]) -> float:
    """Variance (ddof 1) of ``p_n - p_0`` over all points, in two passes over chunks of
    :data:`~warpratchet.observables.SUMMARY_CHUNK` points (temporaries of a few MB for any
    ensemble; one chunk keeps its gains for the second pass instead of computing them again)."""
    n = len(state["p0"])
    if n < 2:
        return math.nan
    fields = ("winding", "q", "p0")
    parts = [{k: state[k][lo:hi] for k in fields} for lo, hi in summary_chunks(n)]
    kept = momentum_gain(parts[0]) if len(parts) == 1 else None
    mean = math.fsum(float(np.add.reduce(momentum_gain(p) if kept is None else kept)) for p in parts) / n
    squares = 0.0
    for part in parts:
        d = (momentum_gain(part) if kept is None else kept) - mean
        squares += float(np.add.reduce(d * d))
    return squares / (n - 1)


def history_row(
    state: Mapping[str, np.ndarray] | None, summary: Summary, variance: float | None = None
) -> dict[str, Any]:
    """One history row (:data:`HISTORY_FIELDS`) of a state and its summary.

    Parameters
    ----------
    state : dict of ndarray, shape (points,) each, or None
        The ensemble's state arrays (zero-copy views are fine: nothing is written); read only for
        the variance, so None where ``variance`` is given.
    summary : Summary
        :func:`~warpratchet.observables.summarize` of ``state`` at its global step (``>= 1``),
        with the run's threshold or rule: the row's first six fields are the summary's.
    variance : float, optional
        The row's ``var_dp_all`` if the caller has it (:meth:`Ensemble.known_variance
        <warpratchet.ensemble.Ensemble.known_variance>`), else computed here.
    """
    if state is None and variance is None:
        raise ValueError("a history row needs the state or its variance")
    step = summary.step
    n_c = summary.chaotic_points
    # Var(p_n - p_0) over the chaotic points is n^2 Var(A_n) = n^2 N_c A_stderr^2: no second pass
    # over the FTLE (the costly part of a summary).
    chaotic = float(step) ** 2 * n_c * summary.A_stderr**2 if n_c > 1 else math.nan
    return {
        "step": int(step),
        "A": summary.A,
        "A_stderr": summary.A_stderr,
        "sigma": summary.lyapunov,
        "chaotic_fraction": summary.chaotic_fraction,
        "chaotic_points": n_c,
        "var_dp_all": _variance(state) if variance is None else variance,
        "var_dp_chaotic": chaotic,
    }


class History(Observer):
    """Records :func:`history_row` and the block gains of each run it observes (module docstring).

    Parameters
    ----------
    threshold : float, optional
        Chaos threshold on the FTLE (default: the step-dependent rule ``threshold_rule``).
    threshold_rule : str
        Threshold rule when ``threshold`` is None: ``"strict"`` (default) or ``"positive"``.
    per_decade : int, optional
        Rows per decade of n (default :data:`PER_DECADE`).
    blocks : int, optional
        Time blocks of the block gains (default :data:`BLOCKS`; at least 8).
    block_points : int, optional
        Most points in the block subsample (default :data:`BLOCK_POINTS`).

    Attributes
    ----------
    rows : dict of list
        One list per field of :data:`HISTORY_FIELDS`, all of one length, in step order. Rows
        appended by later runs (a run continued to a further target) follow on.
    block_indices : ndarray, shape (M,), or None
        The subsample (chosen when the first run begins).
    block_rows : dict of list
        ``block_step`` (int), ``block_gain`` and ``block_ftle`` (ndarray (M,) each), in step order.
    target : int or None
        The target step of the run being observed (None outside a run).

    Notes
    -----
    ``after_chunk`` is idempotent at a given step (a row or block is recorded once), so an
    archive sink may call it to make sure the row of the step it writes exists.
    """

    @renamed_keyword("rule", "threshold_rule")
    def __init__(
        self,
        threshold: float | None = None,
        threshold_rule: str = "strict",
        per_decade: int = PER_DECADE,
        blocks: int = BLOCKS,
        block_points: int = BLOCK_POINTS,
    ) -> None:
        self.threshold = check_optional(check_real, "threshold", threshold, low=0.0)
        self.threshold_rule = check_choice("threshold_rule", threshold_rule, tuple(THRESHOLD_RULES))
        self.per_decade = check_count("per_decade", per_decade, 1, 1000)
        self.blocks = check_count("blocks", blocks, 8, 1 << 16)
        self.block_points = check_count("block_points", block_points, 2)
        self.rows: dict[str, list] = {name: [] for name in HISTORY_FIELDS}
        self.block_rows: dict[str, list] = {name: [] for name in BLOCK_FIELDS}
        self.block_indices: np.ndarray | None = None
        self.target: int | None = None
        self._pending: list[int] = []
        self._block_pending: list[int] = []
        self._blocks: Ensemble | None = None  # the subsample's points, advanced to the block steps
        self._stop_at_blocks = False  # the run stops at the block steps instead (copies_blocks)

    # -- construction from a record ----------------------------------------------------------------
    @classmethod
    def restore(
        cls,
        rows: Mapping[str, Sequence],
        block_rows: Mapping[str, Sequence],
        block_indices: np.ndarray | None,
        **settings: Any,
    ) -> History:
        """A history holding recorded ``rows`` and ``block_rows`` (e.g. from an archive), ready to go on.

        ``settings`` are the constructor's keywords. Rows are kept as Python ints and floats,
        exactly as recorded.
        """
        obj = cls(**settings)
        for name in HISTORY_FIELDS:
            values = np.asarray(rows[name])
            obj.rows[name] = [int(v) if name in INT_FIELDS else float(v) for v in values]
        steps = np.asarray(block_rows["block_step"], dtype=np.int64)
        obj.block_rows["block_step"] = [int(s) for s in steps]
        for name in BLOCK_FIELDS[1:]:
            obj.block_rows[name] = [np.array(v, dtype=np.float64) for v in block_rows[name]]
        if block_indices is not None:
            obj.block_indices = np.asarray(block_indices, dtype=np.int64).copy()
        if len({len(v) for v in obj.rows.values()}) > 1 or len({len(v) for v in obj.block_rows.values()}) > 1:
            raise ValueError("history rows (or block rows) of unequal length")
        return obj

    @property
    def rule(self) -> str:
        """Former spelling of :attr:`threshold_rule`, with a :class:`DeprecationWarning`."""
        warnings.warn("History.rule is spelled History.threshold_rule", DeprecationWarning, stacklevel=2)
        return self.threshold_rule

    def settings(self) -> dict[str, Any]:
        """The constructor's keywords of this history (what :meth:`restore` needs besides the records)."""
        return {
            "threshold": self.threshold,
            "threshold_rule": self.threshold_rule,
            "per_decade": self.per_decade,
            "blocks": self.blocks,
            "block_points": self.block_points,
        }

    def subsample(self, ensemble: Any) -> np.ndarray:
        """The block subsample of ``ensemble`` (:func:`block_subsample`), chosen once and kept."""
        if self.block_indices is None:
            self.block_indices = block_subsample(ensemble.points, ensemble.seed, self.block_points)
        elif self.block_indices.size and int(self.block_indices[-1]) >= ensemble.points:
            raise ValueError(
                f"the history's block subsample needs {int(self.block_indices[-1]) + 1} points; "
                f"the ensemble has {ensemble.points}"
            )
        return self.block_indices

    # -- the observer -------------------------------------------------------------------------------
    #: Its stops depend on the step alone and it only reads the ensemble there, so a run on several
    #: threads may give it copies of the state at its steps (:class:`~warpratchet.runloop.Observer`).
    takes_state_copies = True

    def begin(self, ensemble: Any, target_step: int) -> None:
        # Idempotent for one run (an archive sink may begin its history itself).
        self.target = int(target_step)
        self.subsample(ensemble)
        done = set(self.rows["step"])
        self._pending = [
            n for n in history_steps(ensemble.step, target_step, self.per_decade) if n not in done
        ]
        done = set(self.block_rows["block_step"])
        self._block_pending = [
            n for n in block_steps(ensemble.step, target_step, self.blocks) if n not in done
        ]
        self._blocks = None
        self._stop_at_blocks = False
        steps, size = target_step - ensemble.step, len(self.block_indices)
        if self._block_pending and not copies_blocks(ensemble.points, size, steps, len(self._block_pending)):
            self._stop_at_blocks = True
        elif self._block_pending:
            # The orbit and tangent of every kernel variant are advance_map's, bit for bit.
            views = ensemble.views()
            sub = {name: np.asarray(views[name])[self.block_indices] for name in STATE_FIELDS}
            self._blocks = Ensemble.from_state(
                ensemble.params, sub, ensemble.step, device=ensemble.device, threads=1
            )

    def _stops(self) -> list[int]:
        return self._pending + self._block_pending if self._stop_at_blocks else self._pending

    def next_stop(self, step: int) -> int | None:
        """The next history row's step after ``step`` (the run loop ends a chunk there), or block
        step where the run stops at those (:func:`copies_blocks`)."""
        later = [n for n in self._stops() if n > step]
        return min(later) if later else None

    def overdue(self, step: int) -> list[int]:
        """Steps before ``step`` still waiting for their row (or block, where the run stops at
        those): a run that did not stop there."""
        return sorted(n for n in self._stops() if n < step)

    def after_chunk(self, ensemble: Any, seconds: float) -> None:
        step = ensemble.step
        if self._stop_at_blocks:
            if step in self._block_pending:
                self._block_pending = [n for n in self._block_pending if n > step]
                views = ensemble.views()  # zero-copy on the CPU
                self._append_block(step, {name: views[name][self.block_indices] for name in STATE_FIELDS})
        elif self._blocks is not None:
            for block_step in [n for n in self._block_pending if n <= step]:
                self._record_block(block_step)
        if step in self._pending:
            self._pending = [n for n in self._pending if n > step]
            # the ensemble's summary at this step: computed once for every sink that needs it
            summary = ensemble.summary(self.threshold, self.threshold_rule, warn=False)
            variance = getattr(ensemble, "known_variance", _none)(step)
            # the state only for a variance not known (off a GPU, views are a copy of the state)
            row = history_row(ensemble.views() if variance is None else None, summary, variance)
            for name in HISTORY_FIELDS:
                self.rows[name].append(row[name])

    def _record_block(self, step: int) -> None:
        """Advance the subsample's copy to ``step`` and record its gain and FTLE there."""
        self._block_pending = [n for n in self._block_pending if n > step]
        self._blocks.run(step - self._blocks.step)
        self._append_block(step, self._blocks.views())

    def _append_block(self, step: int, sub: Mapping[str, np.ndarray]) -> None:
        """Record the subsample's gain and FTLE at ``step`` from its state ``sub``."""
        self.block_rows["block_step"].append(int(step))
        self.block_rows["block_gain"].append(momentum_gain(sub))
        self.block_rows["block_ftle"].append(lyapunov(sub, step))

    def end(self, ensemble: Any) -> None:
        self.target = None
        self._blocks = None
        self._stop_at_blocks = False

    # -- results -----------------------------------------------------------------------------------
    def as_dict(self) -> dict[str, list]:
        """The rows as a dict of equal-length lists (what ``run --json`` prints under ``history``)."""
        return {name: list(values) for name, values in self.rows.items()}

    def block_gains(self, n: int) -> tuple[np.ndarray | None, str]:
        """Gains over the :attr:`blocks` blocks of ``[0, n]`` of the subsample's chaotic orbits at ``n``.

        Returns
        -------
        (gains, reason)
            ``gains`` of shape ``(blocks, M_c)`` (the orbits chaotic at ``n`` by this history's
            threshold), or None with ``reason`` saying which record is missing.
        """
        wanted = [n * j // self.blocks for j in range(1, self.blocks + 1)]
        where = {s: i for i, s in enumerate(self.block_rows["block_step"])}
        missing = [s for s in wanted if s not in where]
        if n < self.blocks or missing:
            return None, (
                f"no block record at {len(missing)} of the {self.blocks} block ends of [0, {n}] "
                "(a run continued past its first target by other than a power of two, or too short)"
            )
        cumulative = np.array([self.block_rows["block_gain"][where[s]] for s in wanted])
        ftle = self.block_rows["block_ftle"][where[n]]
        chaotic = chaotic_mask(ftle, n, self.threshold, self.threshold_rule)
        gains = np.diff(np.vstack([np.zeros(cumulative.shape[1]), cumulative]), axis=0)
        return gains[:, chaotic], ""

    def convergence(self) -> Assessment:
        """The verdict at the last row: drift of A between n/2 and n, robust error (:func:`assess`)."""
        if not self.rows["step"]:
            raise ValueError("the history has no rows yet")
        n = int(self.rows["step"][-1])
        gains, reason = self.block_gains(n)
        return assess(self.rows, gains, n, int(self.rows["chaotic_points"][-1]), missing=reason)
