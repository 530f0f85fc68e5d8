"""``observables.summarize`` in chunks: NumPy's whole-array reductions bit for bit up to one chunk,
and within the rounding bound of pairwise summation beyond it."""

import functools
import itertools
import math

import numpy as np
import pytest

from warpratchet import kernels, observables
from warpratchet.ensemble import Ensemble
from warpratchet.history import History
from warpratchet.observables import (
    AMBIGUITY_FACTOR,
    KEPT_BYTES,
    finite_time_acceleration,
    lyapunov,
    lyapunov_threshold,
    mean_stderr,
    summarize,
)
from warpratchet.params import MapParams

EPS = np.finfo(np.float64).eps


def _whole_array_summary(state: dict, step: int, threshold: float) -> dict:
    """The summary from NumPy's reductions over the whole arrays (summarize before chunking)."""
    ftle, acc = lyapunov(state, step), finite_time_acceleration(state, step)
    mask = ftle > threshold
    a, a_err = mean_stderr(acc[mask])
    ambiguous = (ftle > threshold / AMBIGUITY_FACTOR) & (ftle < threshold * AMBIGUITY_FACTOR)
    chaotic, n_ambiguous = int(mask.sum()), int(ambiguous.sum())
    deviations = float(np.abs(acc[ambiguous] - a).sum())
    return {
        "A": a,
        "A_stderr": a_err,
        "lyapunov": float(ftle[mask].mean()),
        "lyapunov_std": float(ftle[mask].std(ddof=1)),
        "lyapunov_min": float(ftle[mask].min()),
        "chaotic_fraction": float(mask.mean()),
        "chaotic_points": chaotic,
        "classification_bound": deviations / (chaotic - n_ambiguous),
    }


def _state(points: int, steps: int, seed: int) -> dict:
    # Mixed phase space (islands and sea) and a short run, so that the band of ambiguous points
    # is populated and the classification bound is finite and nonzero.
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), points, "torus", seed=seed, threads=2).run(steps)
    return ens.state()  # copies already


@pytest.mark.parametrize(("points", "steps"), [(777, 100), (40_000, 300)])
def test_up_to_one_chunk_the_summary_is_numpys_whole_array_reduction_bit_for_bit(points, steps):
    state = _state(points, steps, seed=points)
    threshold = 0.05
    got = summarize(state, steps, threshold).as_dict()
    for name, value in _whole_array_summary(state, steps, threshold).items():
        assert np.float64(got[name]).tobytes() == np.float64(value).tobytes(), name


def test_in_many_chunks_the_summary_is_one_chunks_within_the_pairwise_rounding_bound(monkeypatch):
    """Counts, minimum and fraction are exact; sums within 2 gamma sum|x| (Higham's bound for a
    pairwise sum of n terms, gamma = (ceil(log2 n) + 2) eps, for each of the two orders), plus a
    few final roundings (a division, a square root) of at most eps each on either side."""
    points, steps = 40_000, 300
    state = _state(points, steps, seed=4)
    threshold = 0.05
    one = summarize(state, steps, threshold)
    monkeypatch.setattr(observables, "SUMMARY_CHUNK", 999)  # 41 chunks, the last one short
    many = summarize(state, steps, threshold)
    for name in ("chaotic_points", "lyapunov_min", "chaotic_fraction", "threshold", "step"):
        assert getattr(many, name) == getattr(one, name), name
    ftle, acc = lyapunov(state, steps), finite_time_acceleration(state, steps)
    mask = ftle > threshold
    n = int(mask.sum())
    gamma = (math.ceil(math.log2(n)) + 2) * EPS
    final = 4 * EPS
    assert abs(many.A - one.A) <= 2 * gamma * np.abs(acc[mask]).sum() / n + final * abs(one.A)
    moved_ftle = 2 * gamma * np.abs(ftle[mask]).sum() / n + final * one.lyapunov
    assert abs(many.lyapunov - one.lyapunov) <= moved_ftle
    for name in ("A_stderr", "lyapunov_std"):  # sqrt halves the relative error of the sum of squares
        assert abs(getattr(many, name) - getattr(one, name)) <= (gamma + final) * getattr(one, name), name
    # the bound sums |A_i - A| over the ambiguous points: its terms move with A, and it is a sum
    assert 0 < one.classification_bound < math.inf
    ambiguous = (ftle > threshold / AMBIGUITY_FACTOR) & (ftle < threshold * AMBIGUITY_FACTOR)
    moved_a = 2 * gamma * np.abs(acc[mask]).sum() / n + final * abs(one.A)
    deviations = np.abs(acc[ambiguous] - one.A)
    tolerance = (ambiguous.sum() * moved_a + 2 * gamma * deviations.sum()) / (n - ambiguous.sum())
    tolerance += final * one.classification_bound
    assert abs(many.classification_bound - one.classification_bound) <= tolerance


def test_the_per_point_a_n_is_named_apart_from_a_and_acceleration_still_works():
    # A_n per point is finite_time_acceleration; A is the summary's mean and theory.acceleration.
    import warpratchet
    from warpratchet import theory

    state = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 300, "strip", seed=2, threads=1).run(60).state()
    per_point = finite_time_acceleration(state, 60)
    assert per_point.shape == (300,)
    assert warpratchet.finite_time_acceleration is finite_time_acceleration
    assert callable(theory.acceleration)  # the closed form keeps its name
    with pytest.warns(DeprecationWarning, match="observables.acceleration is spelled"):
        assert observables.acceleration is finite_time_acceleration
    with pytest.warns(DeprecationWarning, match="warpratchet.acceleration is spelled"):
        assert warpratchet.acceleration is finite_time_acceleration
    with pytest.raises(AttributeError, match="has no attribute 'accelerations'"):
        _ = observables.accelerations


def _same_bits(a: float, b: float) -> bool:
    return np.float64(a).tobytes() == np.float64(b).tobytes()


@pytest.mark.parametrize("n", [1, 7, 128, 129, 1000, 4097, 65_536, 99_999])
@pytest.mark.parametrize("leaf", [128, 1000, 1 << 14])
def test_sums_rebuilt_from_the_pairwise_trees_leaves_are_numpys_bit_for_bit(n, leaf):
    rng = np.random.default_rng(n + leaf)
    values = rng.standard_normal(n) * 10.0 ** rng.integers(-8, 8, n)
    tree = observables.pairwise_tree(0, n, leaf)
    leaves = observables.tree_leaves(tree)
    assert leaves[0][0] == 0 and leaves[-1][1] == n and all(hi - lo <= leaf for lo, hi in leaves)
    assert all(a[1] == b[0] for a, b in zip(leaves[:-1], leaves[1:], strict=True))
    sums = {(lo, hi): np.add.reduce(values[lo:hi]) for lo, hi in leaves}
    assert _same_bits(observables.tree_total(tree, sums), np.add.reduce(values))


def _reference(state: dict, step: int, threshold, rule: str = "strict", ftle=None) -> tuple:
    from warpratchet.history import _variance

    return summarize(state, step, threshold, rule, ftle), _variance(state)


@pytest.fixture(params=["as found", "off"])
def libm_gate(request, monkeypatch):
    """The row pass's FTLE: in the kernel where this machine's libm gate allows it ("as found"), or
    NumPy's own, made just before the kernel's pass ("off": a machine whose NumPy calls another
    ``log``, e.g. its own AVX-512 one)."""
    if request.param == "off":
        from warpratchet.kernels import _rows

        monkeypatch.setattr(_rows, "_verdicts", {**_rows._verdicts, "libm": False})  # restored after the test
    return request.param


@pytest.mark.parametrize(
    ("points", "steps", "threshold", "rule"),
    [
        (1, 5, None, "strict"),  # no variance, no chaotic point
        (2, 40, None, "strict"),
        (777, 100, None, "strict"),  # ambiguous points: a finite, nonzero bound
        (777, 100, None, "positive"),
        (40_000, 300, 0.05, "strict"),
        (40_000, 300, 0.0, "strict"),  # every point chaotic
        (40_000, 300, 1e9, "strict"),  # none
        (3000, 20, None, "strict"),  # many ambiguous: an infinite bound
    ],
)
@pytest.mark.parametrize(("threads", "leaf"), [(1, None), (3, 128), (2, 1000)])
def test_the_summary_with_variance_on_threads_is_summarize_and_the_history_variance_bit_for_bit(
    monkeypatch, points, steps, threshold, rule, threads, leaf, libm_gate
):
    from concurrent.futures import ThreadPoolExecutor

    if leaf is not None:
        monkeypatch.setattr(observables, "TREE_LEAF", leaf)
    state = _state(points, steps, seed=points + steps)
    want, variance = _reference(state, steps, threshold, rule)
    if threshold is None:
        threshold = lyapunov_threshold(steps, rule)
    with ThreadPoolExecutor(threads) as pool:
        got, var = observables.summarize_with_variance(
            state, steps, threshold, pool=pool if threads > 1 else None, batches=4 * threads
        )
    for name, value in want.as_dict().items():
        assert got.as_dict()[name] == value or _same_bits(got.as_dict()[name], value), name
    assert _same_bits(var, variance)
    ftle = lyapunov(state, steps)  # a caller's FTLE (a transport ensemble's) is taken as given
    given = observables.summarize_with_variance(state, steps, threshold, ftle=ftle)[0].as_dict()
    assert all(
        given[name] == value or _same_bits(given[name], value) for name, value in want.as_dict().items()
    )
    # The per-point pass in one kernel, as an ensemble on the CPU runs it: the FTLE given, and
    # not given (computed in the kernel where its functions are NumPy's here, else NumPy's just
    # before it); twice, the second time in the arrays the first one left.
    buffers = {}
    for known in [ftle, None]:
        for _ in range(2):
            with ThreadPoolExecutor(threads) as pool:
                got, var = observables.summarize_with_variance(
                    state,
                    steps,
                    threshold,
                    known,
                    pool=pool if threads > 1 else None,
                    batches=4 * threads,
                    leaf_pass=functools.partial(kernels.RowPass, buffers=buffers),
                    leaf_sums=kernels.leaf_sums,
                    buffers=buffers,
                )
            for name, value in want.as_dict().items():
                assert got.as_dict()[name] == value or _same_bits(got.as_dict()[name], value), name
            assert _same_bits(var, variance)


def test_the_summary_with_variance_leaves_what_it_cannot_do_to_summarize(libm_gate):
    state = _state(300, 50, seed=1)
    state["dx"][7] = np.inf
    assert observables.summarize_with_variance(state, 50, lyapunov_threshold(50)) is None
    ftle = lyapunov(state, 50)
    for known in [ftle, None]:
        assert (
            observables.summarize_with_variance(
                state, 50, lyapunov_threshold(50), known, leaf_pass=kernels.RowPass
            )
            is None
        )
    with pytest.raises(ValueError, match="non-finite FTLE"):
        summarize(state, 50)


def test_a_summary_keeps_what_its_chunks_fit_in_for_the_second_pass(monkeypatch):
    """``keep_bytes``: the per-point pass runs again for every chunk but the last, except those
    whose values (the gathered FTLE and ``A_n``, the ambiguous ``A_n``, the gains) fit, in order.
    An ensemble allows :data:`KEPT_BYTES` where half the memory available holds it (never with one
    chunk, nor where the memory is not known), and its summary is the same bits either way; a run
    keeps them from one row to the next and lets go at its end; a summary outside a run lets go
    at once."""
    from warpratchet import ensemble as module

    monkeypatch.setattr(observables, "SUMMARY_CHUNK", 10_000)  # 4 chunks
    state = _state(40_000, 300, seed=5)
    ftle = lyapunov(state, 300).reshape(4, 10_000)
    low, high = 0.05 / AMBIGUITY_FACTOR, 0.05 * AMBIGUITY_FACTOR
    # each chunk's values in bytes: the gains, the chaotic FTLE and A_n, the ambiguous A_n
    sizes = [
        8 * (10_000 + 2 * np.count_nonzero(f > 0.05) + np.count_nonzero((f > low) & (f < high))) for f in ftle
    ]
    for keep, passes in ((0, 7), (min(sizes[:3]) - 1, 7), (sizes[0], 6), (sum(sizes[:3]), 4)):
        chunks = []

        def leaf_pass(x, ftle, chunks=chunks):
            chunks.append(len(x["p0"]))
            return kernels.RowPass(x, ftle)

        observables.summarize_with_variance(
            state, 300, 0.05, leaf_pass=leaf_pass, leaf_sums=kernels.leaf_sums, keep_bytes=keep
        )
        assert len(chunks) == passes, keep
    ens = Ensemble.from_state(MapParams(3.0, 0.1, 0.01), state, 300, threads=2)
    summaries = []
    for spare, keep in ((None, 0), (2 * KEPT_BYTES - 1, 0), (2 * KEPT_BYTES, KEPT_BYTES), (None, 0)):
        monkeypatch.setattr(module, "available_memory", lambda spare=spare: spare)
        assert ens._keep_bytes() == keep
        ens._summaries.clear()
        summaries.append(ens.summary(0.05, warn=False).as_dict())
    assert all(summary == summaries[0] for summary in summaries)  # (no value is NaN here)
    assert not any(name.startswith("kept") for name in ens._row_buffers)  # let go where not kept
    monkeypatch.setattr(module, "available_memory", lambda: 10**12)
    seen = []  # whether the summaries held kept values at the end of a history row

    class Rows(History):
        def after_chunk(self, ensemble, seconds):
            super().after_chunk(ensemble, seconds)
            seen.append(any(name.startswith("kept") for name in ensemble._row_buffers))
            # what they hold counts as available: the next row reuses it
            monkeypatch.setattr(module, "available_memory", lambda: 2 * KEPT_BYTES - 1)

    ens.run(20, observers=[Rows()])  # a run keeps them from row to row, and lets go at its end
    assert len(seen) >= 2 and all(seen)
    assert not any(name.startswith("kept") for name in ens._row_buffers)
    monkeypatch.setattr(module, "available_memory", lambda: 10**12)
    ens.summary(0.04, warn=False)  # outside a run it keeps them for its own second pass only
    assert not any(name.startswith("kept") for name in ens._row_buffers)
    monkeypatch.setattr(observables, "SUMMARY_CHUNK", 40_000)  # one chunk: nothing to keep
    assert ens._keep_bytes() == 0


@pytest.mark.parametrize(("chunk", "threads"), [(1000, 1), (1000, 2), (4096, 3), (39_999, 2)])
def test_past_one_chunk_the_summary_with_variance_adds_the_chunks_as_summarize_does(
    monkeypatch, chunk, threads, libm_gate
):
    """More points than :data:`SUMMARY_CHUNK`: ``summarize`` adds up its chunks' sums (not NumPy's
    pairwise sum of the whole array) and the history's variance adds the chunks' sums as Python
    floats; the summary with variance, in NumPy or in the kernels, on the threads, with the chunks'
    values made again or kept for the second pass, gives the same bits (the chunk shrunk here, so
    that 40,000 points make 10, 3 or 2 chunks, the last a part)."""
    from concurrent.futures import ThreadPoolExecutor

    monkeypatch.setattr(observables, "SUMMARY_CHUNK", chunk)  # the history variance's chunks too
    monkeypatch.setattr(observables, "TREE_LEAF", 128)  # many leaves in a chunk, on the threads
    state = _state(40_000, 300, seed=11)
    ftle = lyapunov(state, 300)
    for threshold in (0.05, lyapunov_threshold(300), 0.0):
        want, variance = _reference(state, 300, threshold)
        buffers = {}
        ways = [(None, None, None)] + [(known, kernels.RowPass, kernels.leaf_sums) for known in (ftle, None)]
        for (known, leaf_pass, leaf_sums), keep in itertools.product(ways, (False, True)):
            with ThreadPoolExecutor(threads) as pool:
                got, var = observables.summarize_with_variance(
                    state,
                    300,
                    threshold,
                    known,
                    pool=pool if threads > 1 else None,
                    batches=threads,
                    leaf_pass=None if leaf_pass is None else functools.partial(leaf_pass, buffers=buffers),
                    leaf_sums=leaf_sums,
                    buffers=buffers,
                    keep_bytes=10**9 if keep else 0,
                )
            for name, value in want.as_dict().items():
                assert got.as_dict()[name] == value or _same_bits(got.as_dict()[name], value), name
            assert _same_bits(var, variance)
