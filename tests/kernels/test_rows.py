"""``kernels.leaf_sums`` and ``kernels.RowPass``: NumPy's numbers to the bit, without NumPy's passes.

The summaries built on them are checked against ``summarize`` in ``tests/core/test_observables.py``
and, for a whole run, in ``tests/run/test_history.py``; here the sums themselves, leaf by leaf.
"""

import numpy as np
import pytest

from warpratchet import kernels


def _bits(values) -> bytes:
    return np.asarray(values, dtype=np.float64).tobytes()


def _numpy(part: np.ndarray, term: str, center: float) -> np.float64:
    if term == "value":
        return np.add.reduce(part)
    d = part - center
    return np.add.reduce(d * d if term == "square" else np.abs(d))


@pytest.mark.parametrize("term", kernels.SUM_TERMS)
def test_leaf_sums_are_numpys_add_reduce_bit_for_bit(term):
    # every length up to past two blocks of 128 (the 8 accumulators, the rest, the halving at a
    # multiple of 8) and a few long ones; magnitudes over 16 decades, so that order shows; -0.0
    rng = np.random.default_rng(len(term))
    lengths = [*range(0, 300), 1000, 4097, 65_535, 65_536, 99_999, 1 << 17]
    for n in lengths:
        values = rng.standard_normal(n) * 10.0 ** rng.integers(-8, 8, n)
        values[: min(n, 3)] = -0.0
        cuts = sorted({0, n, *rng.integers(0, n + 1, 3).tolist()})
        leaves = list(zip(cuts[:-1], cuts[1:], strict=True))
        center = float(rng.standard_normal())
        got = kernels.leaf_sums(values, leaves, term, center)
        want = [_numpy(values[lo:hi], term, center) for lo, hi in leaves]
        assert _bits(got) == _bits(want), (n, leaves)


def test_an_all_negative_zero_leaf_sums_to_positive_zero_as_in_numpy():
    for n in (1, 7, 8, 200):
        got = kernels.leaf_sums(np.full(n, -0.0), [(0, n)])
        assert _bits(got) == _bits([np.add.reduce(np.full(n, -0.0))]) == _bits([0.0])


def test_leaves_must_be_consecutive():
    with pytest.raises(ValueError, match="consecutive"):
        kernels.leaf_sums(np.ones(10), [(0, 4), (5, 10)])
