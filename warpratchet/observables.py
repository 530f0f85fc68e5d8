"""Per-point observables and ensemble summaries with standard errors.

Pure NumPy functions of the state arrays of :class:`warpratchet.ensemble.Ensemble` (so they
work on archived checkpoints as well as on live ensembles).
"""

from __future__ import annotations

import ctypes
import math
import threading
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .errors import (
    NonFiniteStateError,
    check_count,
    check_optional,
    check_real,
    renamed_globals,
    renamed_keyword,
)

__all__ = [
    "momentum_gain",
    "finite_time_acceleration",
    "lyapunov",
    "THRESHOLD_RULES",
    "lyapunov_threshold",
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
    "SUMMARY_CHUNK",
    "summary_chunks",
]

#: Fewest chaotic points for which A is reported as an estimate. The standard error is itself
#: estimated from the sample; its relative standard error is ``1/sqrt(2 (N - 1))`` (normal
#: samples), which is 10% at N = 51: below that, "A +- stderr" does not say how uncertain A is.
MIN_CHAOTIC_POINTS = 51
#: Working memory of :func:`summarize` per point of a chunk (:data:`SUMMARY_CHUNK` points at a
#: time), bytes, beyond the state it reads: the FTLE and ``A_n`` (8 B each) and the temporaries of
#: computing them (at most two more at a time), the chaotic subsets (8 B each, all points at
#: worst), the masks (1 B each). ``tests/core/test_limits.py`` measures the peak (tracemalloc) with
#: every point chaotic and checks it stays below this.
SUMMARY_BYTES_PER_POINT = 64
#: Points whose FTLE lies within this factor of the threshold, on either side, are "ambiguous":
#: their classification could go either way (tests/core/test_statistics.py uses the same band).
AMBIGUITY_FACTOR = 3.0


class UnreliableWarning(UserWarning):
    """A summary whose A cannot be vouched for (too short a run, too few chaotic points)."""


def momentum_gain(state: Mapping[str, np.ndarray]) -> np.ndarray:
    """Per-point momentum gained since step 0, ``p_n - p_0``, shape ``(points,)``.

    Computed as ``winding + (q - frac(p0))``: every term is exact or a fraction in ``[0, 1)``, so
    no digits are lost however far the momentum has run. History rows, block gains and transport's
    spread rows take it from here, so they match ``A_n * n`` bit for bit.
    """
    p0 = state["p0"]
    return state["winding"] + (state["q"] - (p0 - np.floor(p0)))


def finite_time_acceleration(state: dict[str, np.ndarray], step: int) -> np.ndarray:
    """Per-point finite-time acceleration ``A_n = (p_n - p_0)/n`` of Eq. (An), shape ``(points,)``:
    :func:`momentum_gain` over ``n``.

    Named apart from the ratchet acceleration ``A``: :attr:`Summary.A` is the mean of ``A_n`` over
    the chaotic points, :func:`warpratchet.theory.acceleration` its closed form (Eqs. Aa, Ab).
    ``acceleration`` is this function's former name (a :class:`DeprecationWarning`).
    """
    if step <= 0:
        raise ValueError(f"step = {step!r}: A_n needs at least one iteration")
    return momentum_gain(state) / step


#: ``acceleration``, the former name of :func:`finite_time_acceleration`, still works (DeprecationWarning).
__getattr__ = renamed_globals(__name__, {"acceleration": "finite_time_acceleration"}, globals())


def lyapunov(state: dict[str, np.ndarray], step: int) -> np.ndarray:
    """Per-point finite-time Lyapunov exponent ``log|DM^n v0| / n`` (``|v0| = 1``), shape ``(points,)``.

    Units: per iteration (natural log).
    """
    if step <= 0:
        raise ValueError(f"step = {step!r}: the FTLE needs at least one iteration")
    return (state["log_stretch"] + np.log(np.hypot(state["dx"], state["dp"]))) / step


def _momentum_gain_into(
    state: Mapping[str, np.ndarray], lo: int, hi: int, out: np.ndarray, scratch: np.ndarray
) -> np.ndarray:
    """:func:`momentum_gain` of points ``lo:hi`` of ``state`` into ``out`` (shape ``(hi - lo,)``):
    its operations in its order, so its bits, with ``scratch`` (the same shape) for the temporary."""
    p0 = state["p0"][lo:hi]
    np.subtract(p0, np.floor(p0, out=scratch), out=scratch)
    np.subtract(state["q"][lo:hi], scratch, out=scratch)
    return np.add(state["winding"][lo:hi], scratch, out=out)


def _lyapunov_into(
    state: Mapping[str, np.ndarray], step: int, lo: int, hi: int, out: np.ndarray
) -> np.ndarray:
    """:func:`lyapunov` of points ``lo:hi`` of ``state`` into ``out`` (shape ``(hi - lo,)``): its
    operations in its order, so its bits, without temporaries. Non-finite values are left to the
    caller (no warning)."""
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        np.hypot(state["dx"][lo:hi], state["dp"][lo:hi], out=out)
        np.log(out, out=out)
        np.add(state["log_stretch"][lo:hi], out, out=out)
        return np.divide(out, step, out=out)


#: Rules for the FTLE threshold when none is given: ``threshold = factor (1 + ln n)/n`` with the
#: factor of the rule (:func:`lyapunov_threshold`). The names are
#: :data:`warpratchet.spec.THRESHOLD_RULES` (RunSpec's ``threshold_rule``).
THRESHOLD_RULES = {"strict": 10.0, "positive": 1.0}


def rule_formula(rule: str) -> str:
    """A rule's threshold as a formula of ``n``: ``"10 (1 + ln n)/n"``, ``"(1 + ln n)/n"``."""
    factor = THRESHOLD_RULES[rule]
    return "(1 + ln n)/n" if factor == 1.0 else f"{factor:g} (1 + ln n)/n"


@renamed_keyword("rule", "threshold_rule")
def lyapunov_threshold(step: int, threshold_rule: str = "strict") -> float:
    """Chaos threshold on the FTLE after ``step`` iterations by a named rule: ``factor (1 + ln n)/n``.

    Why ``(1 + ln n)/n``. A regular orbit has a tangent that grows at most linearly,
    ``|v_n| <= a + b n``: in the islands around the period-1 modes the map is affine with the
    elliptic ``DM`` of Eq. (eig), so ``|v_n|`` stays bounded (``a`` of order the eigenvector
    condition number, a few units), and around higher-period orbits the shear makes it grow like
    ``n``. Either way the FTLE is below ``(ln a + ln(1 + b n))/n``, i.e. ``(1 + ln n)/n`` times a
    factor that is O(1) for islands with small ``a, b``.

    The rules:

    * ``"strict"`` (the default, :func:`default_lyapunov_threshold`): factor 10, a margin for any
      island whose ``a, b < e^9``. Chaotic orbits converge to ``sigma > 0``; the smallest sigma in
      the paper's range (Fig. 7 inset) is ~0.03, far above the threshold at the paper's
      ``n = 120000`` (1.1e-3). For short runs the threshold rises (0.08 at ``n = 1000``) and weak
      chaos cannot be told from regular motion: run longer, or pass a threshold.
    * ``"positive"``: factor 1, an FTLE just distinguishable from the linear growth of a regular
      tangent: the paper's "positive finite-time Lyapunov exponents" (caption of Fig. 7). With
      initial conditions on the torus it reproduces the Lyapunov range of Fig. 9 (docs/validation.md,
      Fig. 9); it also counts weakly chaotic orbits locked to an island for the whole run.
    """
    if step <= 0:
        raise ValueError(f"step = {step!r}: the threshold needs at least one iteration")
    try:
        factor = THRESHOLD_RULES[threshold_rule]
    except (KeyError, TypeError):
        choices = ", ".join(THRESHOLD_RULES)
        raise ValueError(f"threshold_rule = {threshold_rule!r} is not one of {choices}") from None
    return factor * (1.0 + math.log(step)) / step


def default_lyapunov_threshold(step: int) -> float:
    """Default chaos threshold on the FTLE after ``step`` iterations: ``10 (1 + ln n) / n``.

    The rule ``"strict"`` of :func:`lyapunov_threshold` (which says why).
    """
    return lyapunov_threshold(step, "strict")


@renamed_keyword("rule", "threshold_rule")
def chaotic_mask(
    ftle: np.ndarray, step: int, threshold: float | None = None, threshold_rule: str = "strict"
) -> np.ndarray:
    """Boolean mask of chaotic points: ``ftle > threshold`` (default: ``threshold_rule``'s threshold)."""
    if threshold is None:
        threshold = lyapunov_threshold(step, threshold_rule)
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
            f"only {chaotic_points} chaotic point{'' if chaotic_points == 1 else 's'} "
            f"(need {MIN_CHAOTIC_POINTS} for a standard error "
            "known to 10%); run longer or with more points"
        )
    if classification_bound == math.inf:  # summarize: no more chaotic points than ambiguous ones
        return False, (
            "at least as many points lie near the chaos threshold as are counted chaotic: their "
            f"classification could move A without bound, beyond its standard error {A_stderr:.2g}; run longer"
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


#: Points that :func:`summarize` reduces at a time: its temporaries stay a few tens of MB (about
#: ten float64 arrays of this length) whatever the ensemble's size.
SUMMARY_CHUNK = 1 << 20


#: Most bytes of chunks' values that a history row's summary keeps for its second pass, where its
#: caller has the memory (:func:`summarize_with_variance`'s ``keep_bytes``): the summary's own
#: working memory (one chunk's, :data:`SUMMARY_BYTES_PER_POINT`) once more, so that a run's memory
#: stays close to its state's at any size.
KEPT_BYTES = SUMMARY_CHUNK * SUMMARY_BYTES_PER_POINT


def summary_chunks(points: int) -> list[tuple[int, int]]:
    """The points ``(lo, hi)`` of each chunk of :data:`SUMMARY_CHUNK` that :func:`summarize` reduces
    at a time, in order (one chunk, empty, for no points)."""
    return [(lo, min(points, lo + SUMMARY_CHUNK)) for lo in range(0, max(points, 1), SUMMARY_CHUNK)]


def _per_point(
    state: dict[str, np.ndarray],
    step: int,
    lo: int,
    hi: int,
    ftle: np.ndarray | None = None,
    gain: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """FTLE (``ftle[lo:hi]`` if given) and ``A_n`` (``gain[lo:hi] / step`` if given: the bits of
    :func:`finite_time_acceleration`) of points ``lo:hi`` (views of ``state``, no copies)."""
    part = {name: state[name][lo:hi] for name in ("winding", "q", "p0", "dx", "dp", "log_stretch")}
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):  # non-finite: refused by the caller
        exponents = lyapunov(part, step) if ftle is None else ftle[lo:hi]
        return exponents, finite_time_acceleration(part, step) if gain is None else gain[lo:hi] / step


@renamed_keyword("rule", "threshold_rule")
def summarize(
    state: dict[str, np.ndarray],
    step: int,
    threshold: float | None = None,
    threshold_rule: str = "strict",
    ftle: np.ndarray | None = None,
    gain: np.ndarray | None = None,
) -> Summary:
    """Mean ``A_n`` over chaotic points with its standard error, FTLE statistics, chaotic fraction.

    Chaotic: FTLE above ``threshold``, or, when it is None, above :func:`lyapunov_threshold` of
    ``threshold_rule`` (``"strict"``: ``10 (1 + ln n)/n``; ``"positive"``: ``(1 + ln n)/n``).

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

    Memory: ``state`` is only read (views of a live ensemble will do), in chunks of
    :data:`SUMMARY_CHUNK` points, in two passes (means, then deviations from them), so no
    temporary is larger than a chunk. Rounding: each sum is NumPy's pairwise sum within a chunk,
    then NumPy's sum of the chunk sums, and means and standard deviations are formed from them
    as ``numpy.mean`` and ``numpy.std`` do; up to :data:`SUMMARY_CHUNK` points that is one chunk,
    and the results are bitwise those of NumPy's reductions over the whole arrays. Larger
    ensembles add the chunk sums in a different order than NumPy's pairwise sum of the whole
    array would: the same error bound (``O(log N)`` roundings), different last bits.

    ``ftle``: :func:`lyapunov` of ``state`` at ``step`` if the caller has it already (shape
    ``(points,)``; the costly part of a summary), else computed here; ``gain`` likewise
    :func:`momentum_gain` of ``state``.

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
        threshold = lyapunov_threshold(step, threshold_rule)
    n = len(state["log_stretch"])
    for name, given in (("ftle", ftle), ("gain", gain)):
        if given is not None and np.shape(given) != (n,):
            raise ValueError(f"{name} has shape {np.shape(given)}, expected ({n},)")
    bounds = summary_chunks(n)
    # One chunk: keep its per-point values for the second pass instead of computing them again.
    kept = {}
    known = ftle  # the caller's FTLE (the loops below name each chunk's ftle)
    first = []
    for lo, hi in bounds:
        ftle, acc = _per_point(state, step, lo, hi, known, gain)
        first.append(chunk_sums(ftle, acc, threshold))
        if len(bounds) == 1:
            kept[lo] = ftle, acc
    second = []
    a_mean, ftle_mean = summary_means(first)
    if needs_squares(first):
        for lo, hi in bounds:
            ftle, acc = kept.get(lo) or _per_point(state, step, lo, hi, known, gain)
            second.append(chunk_squares(ftle, acc, threshold, a_mean, ftle_mean))
    return summary_from_sums(step, threshold, n, first, second)


#: Most values in a leaf of :func:`summarize_with_variance`'s summation trees: a leaf's temporaries
#: (a few arrays of this length) stay in a core's cache. The sums over the gathered values take
#: leaves of :data:`SUM_LEAF` values (one temporary each, fewer calls).
TREE_LEAF = 1 << 14
SUM_LEAF = 1 << 16


def pairwise_tree(lo: int, n: int, leaf: int | None = None) -> tuple:
    """NumPy's pairwise summation tree of the ``n`` values from index ``lo``, cut into leaves of at
    most ``leaf`` (>= 128; default :data:`TREE_LEAF`) values: a leaf ``(lo, hi)``, or a pair
    ``(left, right)`` of trees.

    NumPy's sum of a contiguous float64 array (its ``pairwise_sum``) adds more than 128 values as
    the sum of two halves, the first ``n // 2`` rounded down to a multiple of 8; so the leaves'
    ``np.add.reduce``, added up the tree (:func:`tree_total`), give ``np.add.reduce`` of all ``n``
    values bit for bit, whichever threads summed the leaves.
    """
    leaf = TREE_LEAF if leaf is None else leaf
    if n <= leaf:
        return (lo, lo + n)
    half = n // 2 - (n // 2) % 8
    return (pairwise_tree(lo, half, leaf), pairwise_tree(lo + half, n - half, leaf))


def tree_leaves(tree: tuple) -> list[tuple[int, int]]:
    """The leaves ``(lo, hi)`` of a :func:`pairwise_tree`, in order."""
    if isinstance(tree[0], int):
        return [tree]
    return tree_leaves(tree[0]) + tree_leaves(tree[1])


def tree_total(tree: tuple, sums: Mapping[tuple[int, int], np.float64]) -> np.float64:
    """The sum of a :func:`pairwise_tree`'s values from the sums of its leaves (``leaf -> sum``)."""
    if isinstance(tree[0], int):
        return sums[tree]
    return tree_total(tree[0], sums) + tree_total(tree[1], sums)


def _buffer(buffers: dict, name: str, size: int) -> np.ndarray:
    """``size`` float64 values of ``buffers[name]``, which grows to hold them."""
    kept = buffers.get(name)
    if kept is None or kept.size < size:
        kept = buffers[name] = np.empty(size)
    return kept[:size]


def _copy(values: np.ndarray, buffers: dict, name: str) -> np.ndarray:
    """A copy of the float64 ``values`` in ``buffers[name]`` (:func:`_buffer`)."""
    copy = _buffer(buffers, name, values.size)
    copy[...] = values
    return copy


def _contiguous(parts: list[np.ndarray], buffers: dict, name: str) -> np.ndarray:
    """The concatenation of ``parts``: the one part itself; parts that lie in one array in order,
    the first at its start (a kernel's groups), moved down in place; else in ``buffers[name]``."""
    if len(parts) == 1:
        return parts[0]
    base, size = parts[0].base, sum(p.size for p in parts)
    starts = [p.ctypes.data for p in parts]
    if (
        base is not None
        and base.dtype == np.float64
        and all(p.base is base and p.flags.c_contiguous for p in parts)
        and starts[0] == base.ctypes.data
        and all(a + p.nbytes <= b for a, b, p in zip(starts[:-1], starts[1:], parts[:-1], strict=True))
    ):
        end = starts[0] + parts[0].nbytes
        for start, part in zip(starts[1:], parts[1:], strict=True):
            ctypes.memmove(end, start, part.nbytes)  # may overlap: memmove, not memcpy
            end += part.nbytes
        return base[:size]
    return np.concatenate(parts, out=_buffer(buffers, name, size))


def _pieces(items: Sequence, count: int) -> list[Sequence]:
    """``items`` (a list, a range) cut into at most ``count`` contiguous, non-empty pieces of
    near-equal length."""
    cuts = np.linspace(0, len(items), min(count, len(items)) + 1).astype(int)
    return [items[a:b] for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]


def _batched(pool: Any, jobs: list, batches: int) -> list:
    """The results of the zero-argument callables ``jobs``, in order: on ``pool`` in ``batches``
    contiguous batches, or here without a pool."""
    if pool is None:
        return [job() for job in jobs]
    futures = [pool.submit(lambda part=part: [job() for job in part]) for part in _pieces(jobs, batches)]
    return [result for future in futures for result in future.result()]


def summarize_with_variance(
    state: dict[str, np.ndarray],
    step: int,
    threshold: float,
    ftle: np.ndarray | None = None,
    *,
    pool: Any = None,
    batches: int = 1,
    leaf_pass: Callable | None = None,
    leaf_sums: Callable | None = None,
    buffers: dict | None = None,
    keep_bytes: int = 0,
) -> tuple[Summary, float] | None:
    """:func:`summarize` and the variance (ddof 1) of every point's :func:`momentum_gain` (a history
    row's ``var_dp_all``), bit for bit, in fewer passes and on ``pool``'s threads.

    The points are taken in :func:`summarize`'s chunks of :data:`SUMMARY_CHUNK`, and within a chunk
    leaf by leaf of :func:`pairwise_tree` (cache-sized): the per-point values (FTLE, ``p_n - p_0``,
    ``A_n``, the masks) are computed, the chaotic and ambiguous points' values gathered in order,
    and each sum is NumPy's pairwise sum of the chunk rebuilt from its leaves' sums
    (:func:`tree_total`); the chunks' sums are then put together as :func:`summarize` and the
    history's variance put them together. So every number is theirs. With more than one chunk the
    per-point pass runs again for every chunk but the last (for the deviations from the means of
    all chunks), so that the memory stays that of one chunk; of the chunks whose gathered values
    and gains fit in ``keep_bytes`` bytes (taken in order, every chunk but the last), a copy is
    kept instead, in ``buffers`` under names that start with ``"kept"``. ``batches``: how many
    pieces each pass of a chunk is cut into for the pool. ``threshold``: the FTLE threshold itself
    (a rule's is :func:`lyapunov_threshold`). Returns None where a value is not finite
    (:func:`summarize` says which, in its error).

    The work may be done elsewhere, to the same bits: ``leaf_pass(state, ftle)``, given a chunk's
    arrays (views) and its FTLE (or None), returns the per-point pass of that chunk: for a group of
    its leaves, the per-point values and its leaves' sums of the gains
    (:class:`warpratchet.kernels.RowPass`'s contract; a group it returns None for is computed
    here); and ``leaf_sums``, each leaf's ``np.add.reduce`` of the values or of their squared or
    absolute deviations from a value (:func:`warpratchet.kernels.leaf_sums`).
    ``buffers``: a dict the caller keeps from one call to the next, where the arrays are kept for
    reuse (fresh pages cost more than the arithmetic on them).
    """
    step = check_count("step", step, 1)
    threshold = check_real("threshold", threshold, 0.0)
    n = len(state["log_stretch"])
    if ftle is not None and np.shape(ftle) != (n,):
        return None
    buffers = {} if buffers is None else buffers
    low, high = threshold / AMBIGUITY_FACTOR, threshold * AMBIGUITY_FACTOR
    bounds = summary_chunks(n)

    def run(jobs: list) -> list:
        return [total for totals in _batched(pool, jobs, batches) for total in totals]

    def sums_of(values: np.ndarray, leaves: list, term: str = "value", center: float = 0.0) -> list:
        """Jobs that give the sums of ``values``' terms over ``leaves``, a list of sums each."""
        if leaf_sums is not None:  # one call per batch of leaves
            return [
                lambda part=part: list(leaf_sums(values, part, term, center))
                for part in _pieces(leaves, batches)
            ]

        def job(lo: int, hi: int) -> list:
            part = values[lo:hi]
            if term == "value":
                return [np.add.reduce(part)]
            # one scratch array per thread: jobs of one thread run one after another
            d = np.subtract(part, center, out=_buffer(buffers, f"scratch {threading.get_ident()}", hi - lo))
            return [np.add.reduce(np.multiply(d, d, out=d) if term == "square" else np.abs(d, out=d))]

        return [lambda lo=lo, hi=hi: job(lo, hi) for lo, hi in leaves]

    def numpy_pass(
        x: Mapping[str, np.ndarray], ftle: np.ndarray | None, gain: np.ndarray, group: list[tuple[int, int]]
    ) -> tuple:
        """The per-point values of the leaves ``group`` of the chunk ``x`` in NumPy (``leaf_pass``'s
        contract without the gains' sums); ``gain`` filled there."""
        size = sum(hi - lo for lo, hi in group)
        longest = max(hi - lo for lo, hi in group)
        chaotic_ftle, chaotic_acc, ambiguous_acc = np.empty(size), np.empty(size), np.empty(size)
        f_buf, a_buf = np.empty(longest), np.empty(longest)
        m = k = 0
        least, finite = math.inf, True
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):  # non-finite: None
            for lo, hi in group:
                f, a, g = f_buf[: hi - lo], a_buf[: hi - lo], gain[lo:hi]
                if ftle is None:
                    _lyapunov_into(x, step, lo, hi, f)
                else:
                    f = ftle[lo:hi]
                _momentum_gain_into(x, lo, hi, g, a)
                np.divide(g, step, out=a)
                finite = finite and bool(np.isfinite(f).all() and np.isfinite(a).all())
                mask = f > threshold
                values = f[mask]
                chaotic_ftle[m : m + values.size] = values
                chaotic_acc[m : m + values.size] = a[mask]
                if values.size:
                    least = min(least, float(values.min()))
                m += values.size
                values = a[(f > low) & (f < high)]
                ambiguous_acc[k : k + values.size] = values
                k += values.size
        return [chaotic_ftle[:m]], [chaotic_acc[:m]], [ambiguous_acc[:k]], least, finite

    def first_pass(lo: int, hi: int) -> tuple | None:
        """A chunk's per-point pass and its :func:`chunk_sums` (sums over the gathered values):
        ``(chunk_sums, the gains' total, gathered arrays, gains)``, or None if not finite."""
        size = hi - lo
        x = {name: state[name][lo:hi] for name in ("winding", "q", "p0", "dx", "dp", "log_stretch")}
        f_given = None if ftle is None else ftle[lo:hi]
        gain = _buffer(buffers, "gain", size)
        tree = pairwise_tree(0, size)
        chunk_pass = None if leaf_pass is None else leaf_pass(x, f_given)

        def group_pass(group: list[tuple[int, int]]) -> tuple:
            done = None if chunk_pass is None else chunk_pass(group, gain, step, threshold, low, high)
            if done is not None:
                return done
            done = numpy_pass(x, f_given, gain, group)
            if leaf_sums is not None:
                return (*done, dict(zip(group, leaf_sums(gain, group), strict=True)))
            return (*done, {(lo, hi): np.add.reduce(gain[lo:hi]) for lo, hi in group})

        groups = _pieces(tree_leaves(tree), batches)
        firsts = _batched(pool, [lambda g=g: group_pass(g) for g in groups], batches)
        if not all(part[4] for part in firsts):
            return None
        # one contiguous array each: the sums below read every value two or three times, in leaves
        # that span the groups' parts
        c_ftle, c_acc, a_acc = (
            _contiguous([p for part in firsts for p in part[i]], buffers, name)
            for i, name in enumerate(("chaotic_ftle", "chaotic_acc", "ambiguous_acc"))
        )
        gain_sums = {leaf: total for part in firsts for leaf, total in part[5].items()}
        # coarser cuts of the same trees: the leaves' sums add up to the same totals
        m_tree = pairwise_tree(0, c_ftle.size, SUM_LEAF)
        m_leaves = tree_leaves(m_tree)
        done = run(sums_of(c_acc, m_leaves) + sums_of(c_ftle, m_leaves))
        sum_a = tree_total(m_tree, dict(zip(m_leaves, done[: len(m_leaves)], strict=True)))
        sum_f = tree_total(m_tree, dict(zip(m_leaves, done[len(m_leaves) :], strict=True)))
        least = min(part[3] for part in firsts)
        sums = (sum_a, sum_f, c_ftle.size, least, a_acc.size)
        return sums, tree_total(tree, gain_sums), (c_ftle, c_acc, a_acc), gain

    def second_pass(gathered: tuple, gain: np.ndarray, means: tuple | None, mean: float) -> tuple:
        """A chunk's :func:`chunk_squares` (None without ``means``) and its gains' squared deviations
        from ``mean`` (None for fewer than 2 points in all)."""
        c_ftle, c_acc, a_acc = gathered
        m_leaves = tree_leaves(m_tree := pairwise_tree(0, c_ftle.size, SUM_LEAF))
        k_leaves = tree_leaves(k_tree := pairwise_tree(0, a_acc.size, SUM_LEAF))
        g_leaves = tree_leaves(g_tree := pairwise_tree(0, gain.size, SUM_LEAF))
        jobs = []
        if means is not None:
            a_mean, ftle_mean = means
            jobs += sums_of(c_acc, m_leaves, "square", a_mean)
            jobs += sums_of(c_ftle, m_leaves, "square", ftle_mean)
            jobs += sums_of(a_acc, k_leaves, "absolute", a_mean)
        if n >= 2:  # history's variance: the mean as a Python float, then the squared deviations
            jobs += sums_of(gain, g_leaves, "square", mean)
        done = run(jobs)
        squares = None
        if means is not None:
            parts = done[: len(m_leaves)], done[len(m_leaves) : 2 * len(m_leaves)]
            deviations = done[2 * len(m_leaves) : 2 * len(m_leaves) + len(k_leaves)]
            squares = (
                tree_total(m_tree, dict(zip(m_leaves, parts[0], strict=True))),
                tree_total(m_tree, dict(zip(m_leaves, parts[1], strict=True))),
                tree_total(k_tree, dict(zip(k_leaves, deviations, strict=True))),
            )
        gains = None
        if n >= 2:
            gains = tree_total(g_tree, dict(zip(g_leaves, done[len(done) - len(g_leaves) :], strict=True)))
        return squares, gains

    firsts = []
    last = len(bounds) - 1
    kept, kept_bytes = set(), 0
    for index, (lo, hi) in enumerate(bounds):
        done = first_pass(lo, hi)
        if done is None:
            return None
        sums, total, gathered, gain = done
        size = sum(values.nbytes for values in (*gathered, gain))
        if index < last and kept_bytes + size <= keep_bytes:  # the buffers are the next chunk's
            copies = [
                _copy(values, buffers, f"kept {index} {i}") for i, values in enumerate((*gathered, gain))
            ]
            done = (sums, total, tuple(copies[:3]), copies[3])
            kept.add(index)
            kept_bytes += size
        firsts.append(done)
    first = [part[0] for part in firsts]
    means = summary_means(first) if needs_squares(first) else None
    # history's variance (history._variance): the mean from the chunks' sums as Python floats
    mean = math.fsum(float(part[1]) for part in firsts) / n if n >= 2 else math.nan
    # The last chunk's gathered values and gains are still in the buffers; every other chunk's
    # are kept or made again (one chunk's memory). Its sums are then put together in the chunks'
    # order.
    seconds: list = [None] * len(bounds)
    for index in reversed(range(len(bounds))):
        part = firsts[index] if index in kept or index == last else first_pass(*bounds[index])
        seconds[index] = second_pass(part[2], part[3], means, mean)
    second, squares = [], 0.0
    for chunk_squares, gains in seconds:
        if chunk_squares is not None:
            second.append(chunk_squares)
        if gains is not None:
            squares += float(gains)
    variance = squares / (n - 1) if n >= 2 else math.nan
    return summary_from_sums(step, threshold, n, first, second), variance


def chunk_sums(ftle: np.ndarray, acc: np.ndarray, threshold: float) -> tuple:
    """The first pass of :func:`summarize` over one chunk of points (their FTLE and ``A_n``):
    ``(sum of A_n, sum of FTLE, count, least FTLE)`` over the chaotic points, and the count of
    ambiguous points. Sums are NumPy's pairwise sums of the chunk's chaotic points.

    Raises NonFiniteStateError if a value is not finite."""
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
    chaotic_ftle = ftle[mask]
    least = float(chaotic_ftle.min()) if chaotic_ftle.size else math.inf
    ambiguous = int(np.count_nonzero(_ambiguous(ftle, threshold)))
    return np.add.reduce(acc[mask]), np.add.reduce(chaotic_ftle), int(chaotic_ftle.size), least, ambiguous


def _total(parts: list) -> np.float64:
    """NumPy's sum of chunk sums (one chunk: that chunk's sum itself)."""
    if len(parts) == 1:
        return parts[0]
    return np.add.reduce(np.array(parts, dtype=np.float64))


def summary_means(first: list[tuple]) -> tuple[float, float]:
    """Mean ``A_n`` and mean FTLE over the chaotic points from the :func:`chunk_sums` of every chunk
    in order, formed as ``numpy.mean`` forms them (sum / count)."""
    chaotic_points = sum(part[2] for part in first)
    if not chaotic_points:
        return math.nan, math.nan
    return (float(_total([p[0] for p in first]) / chaotic_points),
            float(_total([p[1] for p in first]) / chaotic_points))  # fmt: skip


def needs_squares(first: list[tuple]) -> bool:
    """Whether :func:`summary_from_sums` reads a second pass (:func:`chunk_squares`)."""
    return sum(p[2] for p in first) > 1 or sum(p[4] for p in first) > 0


def chunk_squares(
    ftle: np.ndarray, acc: np.ndarray, threshold: float, a_mean: float, ftle_mean: float
) -> tuple:
    """The second pass of :func:`summarize` over one chunk: the sums of squared deviations of the
    chaotic points' ``A_n`` and FTLE from their means (:func:`summary_means`), and of the
    ambiguous points' ``|A_n - A|``."""
    mask = ftle > threshold
    d_a = acc[mask] - a_mean
    d_ftle = ftle[mask] - ftle_mean
    deviations = np.abs(acc[_ambiguous(ftle, threshold)] - a_mean)
    return np.add.reduce(d_a * d_a), np.add.reduce(d_ftle * d_ftle), np.add.reduce(deviations)


def summary_from_sums(
    step: int, threshold: float, n: int, first: list[tuple], second: list[tuple]
) -> Summary:
    """The :class:`Summary` of ``n`` points from the :func:`chunk_sums` and :func:`chunk_squares`
    of their chunks in order (``second`` may be empty unless :func:`needs_squares`): the numbers of
    :func:`summarize` bit for bit, since it is how :func:`summarize` forms them."""
    chaotic_points = sum(p[2] for p in first)
    n_ambiguous = sum(p[4] for p in first)
    ftle_min = min((p[3] for p in first), default=math.inf)
    a_mean, ftle_mean = summary_means(first)
    if chaotic_points > 1:
        squares_a = _total([p[0] for p in second])
        a_err = float(np.sqrt(squares_a / (chaotic_points - 1)) / math.sqrt(chaotic_points))
        ftle_std = float(np.sqrt(_total([p[1] for p in second]) / (chaotic_points - 1)))
    else:
        a_err = ftle_std = math.nan
    if n_ambiguous == 0:
        bound = 0.0
    elif chaotic_points > n_ambiguous:
        bound = float(_total([p[2] for p in second])) / (chaotic_points - n_ambiguous)
    else:
        bound = math.inf
    reliable, reason = reliability(chaotic_points, a_err, bound)
    return Summary(
        step=int(step),
        A=a_mean,
        A_stderr=a_err,
        lyapunov=ftle_mean,
        lyapunov_std=ftle_std,
        lyapunov_min=ftle_min if chaotic_points else math.nan,
        chaotic_fraction=float(np.float64(chaotic_points) / n) if n else math.nan,
        chaotic_points=chaotic_points,
        threshold=float(threshold),
        classification_bound=bound,
        reliable=reliable,
        reason=reason,
    )


def _ambiguous(ftle: np.ndarray, threshold: float) -> np.ndarray:
    """Points whose FTLE lies within :data:`AMBIGUITY_FACTOR` of the threshold, either side."""
    return (ftle > threshold / AMBIGUITY_FACTOR) & (ftle < threshold * AMBIGUITY_FACTOR)
