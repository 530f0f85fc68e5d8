"""``kernels.leaf_sums`` and ``kernels.RowPass``: NumPy's numbers to the bit, without NumPy's passes.

The summaries built on them are checked against ``summarize`` in ``tests/core/test_observables.py``
and, for a whole run, in ``tests/run/test_history.py``; here the sums themselves, leaf by leaf.
"""

import numpy as np
import pytest

from warpratchet import kernels
from warpratchet.kernels import _libm, _rows
from warpratchet.observables import lyapunov, momentum_gain


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


def _random_state(size: int, stretch: float) -> dict:
    """A state of ``size`` points drawn from a generator seeded by ``size``, its ``log_stretch`` in
    ``[0, stretch)``."""
    rng = np.random.default_rng(size)
    return {
        "winding": rng.integers(-5, 5, size),
        "q": rng.uniform(0.0, 1.0, size),
        "p0": rng.uniform(0.0, 1.0, size),
        "dx": rng.uniform(-2.0, 2.0, size),
        "dp": rng.uniform(-2.0, 2.0, size),
        "log_stretch": rng.uniform(0.0, stretch, size),
    }


@pytest.mark.skipif(not kernels.row_pass_available(), reason="the row pass computes no FTLE here")
@pytest.mark.parametrize("size", [1, 5, 256, 257, 1000])
def test_a_non_finite_tangent_anywhere_leaves_the_group_to_numpy(size):
    """A point whose tangent is not finite is not covered wherever it sits in a block (the group is
    NumPy's: None); a covered point whose FTLE is infinite is a non-finite summary instead."""
    state = _random_state(size, stretch=10.0)
    gain = np.empty(size)
    assert kernels.RowPass(state)([(0, size)], gain, 10, 0.0, -1.0, 1.0) is not None
    for where in sorted({0, size // 2, size - 1}):
        for field in ("dx", "dp"):
            for bad in (np.inf, -np.inf, np.nan):
                broken = dict(state, **{field: state[field].copy()})
                broken[field][where] = bad
                assert kernels.RowPass(broken)([(0, size)], gain, 10, 0.0, -1.0, 1.0) is None
        infinite = dict(state, log_stretch=state["log_stretch"].copy())
        infinite["log_stretch"][where] = np.inf
        result = kernels.RowPass(infinite)([(0, size)], gain, 10, 0.0, -1.0, 1.0)
        assert result is not None and result[4] is False  # finite: no


@pytest.mark.parametrize("size", [1, 7, 8, 9, 16, 17, 255, 257, 1000, 5003])
def test_the_pass_gathers_numpys_masks_in_order_and_stays_in_its_group(size):
    """Given FTLE values on both sides of the threshold and of the ambiguity band (and equal to their
    edges, and NaN), each group's gathered FTLE and ``A_n`` are NumPy's boolean gathers, in point
    order, however the points fall into blocks of eight; a group written after its neighbour leaves
    the neighbour's stretch as it was."""
    state = _random_state(size, stretch=10.0)
    rng = np.random.default_rng(size + 17)
    step, threshold, low, high = 10, 0.5, 0.25, 1.0
    ftle = rng.choice([0.1, 0.25, 0.3, 0.5, 0.7, 1.0, 2.0, np.nan], size) * rng.uniform(0.9, 1.1, size)
    ftle[rng.random(size) < 0.1] = threshold
    cut = size // 2
    groups = [[(0, cut)], [(cut, size)]] if cut else [[(0, size)]]
    if size > 300:  # groups of several leaves, of lengths not multiples of 8
        groups = [[(0, 101), (101, 250), (250, cut)], [(cut, cut + 3), (cut + 3, size)]]
    npass = kernels.RowPass(state, ftle)
    gain = np.empty(size)
    results = {}
    for group in reversed(groups):  # the later group first: the earlier one must not touch it
        results[group[0][0]] = npass(group, gain, step, threshold, low, high)
    acc = momentum_gain(state) / step
    for group in groups:
        lo, hi = group[0][0], group[-1][1]
        f, a = ftle[lo:hi], acc[lo:hi]
        chaotic, band = f > threshold, (f > low) & (f < high)
        got = results[lo]
        assert _bits(got[0][0]) == _bits(f[chaotic])
        assert _bits(got[1][0]) == _bits(a[chaotic])
        assert _bits(got[2][0]) == _bits(a[band])
        assert got[3] == (f[chaotic].min() if chaotic.any() else np.inf)


@pytest.mark.parametrize("size", [5, 257, 1000])
def test_where_the_kernels_log_is_not_numpys_the_pass_takes_numpys_ftle(monkeypatch, size):
    """With the libm gate off (a NumPy whose ``log`` the transcription does not match), a pass given
    no FTLE makes NumPy's, group by group, and gives the bits of a pass given ``lyapunov``'s; a
    non-finite tangent gives a non-finite FTLE there, a summary that is not finite."""
    from warpratchet.kernels import _rows

    monkeypatch.setattr(_rows, "_verdicts", {**_rows._verdicts, "libm": False})
    state = _random_state(size, stretch=0.5)
    step, threshold = 10, 0.03
    groups = [[(0, size // 2)], [(size // 2, size)]]  # the second group first: each its own FTLE
    row = (step, threshold, threshold / 3, threshold * 3)
    own = kernels.RowPass(state)
    assert own.own_ftle
    given = kernels.RowPass(state, lyapunov(state, step), buffers={})
    gains = np.empty(size), np.empty(size)
    for group in reversed(groups):
        ours, theirs = own(group, gains[0], *row), given(group, gains[1], *row)
        assert _bits(np.concatenate(ours[0] + ours[1] + ours[2])) == _bits(
            np.concatenate(theirs[0] + theirs[1] + theirs[2])
        )
        assert ours[3:5] == theirs[3:5] and ours[4] is True
        assert _bits(list(ours[5].values())) == _bits(list(theirs[5].values()))
    assert _bits(gains[0]) == _bits(gains[1]) == _bits(momentum_gain(state))
    for bad in (np.inf, np.nan):
        broken = dict(state, dx=state["dx"].copy())
        broken["dx"][size // 2] = bad
        assert kernels.RowPass(broken)([(0, size)], gains[0], *row)[4] is False


def test_the_gates_verdict_is_kept_per_machine_and_read_back(monkeypatch, tmp_path):
    """A gate (the libm one, the hypot one) runs once per machine and set of binaries: its verdict
    is kept in Warp's kernel cache under its name and a key of what it depends on, and in the
    process; a kept verdict is used as it is, a file that holds anything else is checked again."""
    import warp as wp

    from warpratchet.kernels import _rows

    kernels.init_warp()
    key = _rows._gate_key()
    assert key is not None  # Linux, with glibc's libm loaded
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    checks = []

    def gate() -> bool:
        checks.append(1)
        return True

    def verdict(name: str = "libm") -> bool:
        monkeypatch.setattr(_rows, "_verdicts", {})  # a new process
        return _rows._gate_verdict(name, gate)

    assert verdict() is True and len(checks) == 1
    kept = tmp_path / f"warpratchet-libm-{key}"
    assert kept.read_text() == "True" and list(tmp_path.iterdir()) == [kept]
    assert verdict() is True and len(checks) == 1  # read back, not checked again
    kept.write_text("False")
    assert verdict() is False and len(checks) == 1
    assert _rows._gate_verdict("libm", gate) is False and len(checks) == 1  # the process's, kept
    kept.write_text("garbage")
    assert verdict() is True and len(checks) == 2
    assert verdict("hypot") is True and len(checks) == 3  # each gate its own verdict
    assert (tmp_path / f"warpratchet-hypot-{key}").read_text() == "True"
    kept.write_text("False")  # a machine whose NumPy the transcription does not match
    monkeypatch.setattr(_rows, "_verdicts", {})
    assert kernels.row_pass_available() is False  # (monkeypatch restores the process's verdicts)


def test_the_pass_gives_momentum_gains_bits_at_every_winding():
    """The row pass converts windings to doubles in vectors where every |w| < 2^51 in a block and
    one by one elsewhere: both give ``momentum_gain``'s bits, at the edges of that range, at
    windings far past it and at -0.0, and the gathers and least FTLE are NumPy's."""
    rng = np.random.default_rng(51)
    blocks = 12  # of the pass's 256 points: some with huge windings, most without
    n = 256 * blocks + 37
    winding = rng.integers(-1000, 1000, n)
    # one past the range alone in a block, above and below (a block of negative windings); far
    # past it; its very edges (the vector path)
    winding[256 * 5 : 256 * 6] = -rng.integers(1, 1000, 256)
    edges = {1: [2**51 + 1], 3: [2**51, 2**52 + 3], 5: [-(2**51) - 1], 7: [-(2**53) + 1]}
    edges[11] = [-(2**51), 2**51 - 1]
    for b, values in edges.items():
        winding[256 * b + rng.choice(256, len(values), replace=False)] = values
    winding[-3:] = [2**51 + 5, -(2**51), 7]  # the last, partial block
    state = {
        "winding": winding,
        "q": rng.uniform(0.0, 1.0, n),
        "p0": rng.uniform(-3.0, 3.0, n) * 10.0 ** rng.integers(0, 6, n),
        "dx": np.ones(n),
        "dp": np.zeros(n),
        "log_stretch": np.zeros(n),
    }
    state["q"][:5] = -0.0
    ftle = rng.uniform(0.0, 0.2, n)
    step, threshold = 321, 0.1
    gain = np.empty(n)
    done = kernels.RowPass(state, ftle)([(0, n)], gain, step, threshold, threshold / 10, threshold * 10)
    assert _bits(gain) == _bits(momentum_gain(state))
    chaotic = ftle > threshold
    a_n = momentum_gain(state) / step
    assert _bits(done[0][0]) == _bits(ftle[chaotic])
    assert _bits(done[1][0]) == _bits(a_n[chaotic])
    assert _bits(done[2][0]) == _bits(a_n[(ftle > threshold / 10) & (ftle < threshold * 10)])
    assert done[3] == ftle[chaotic].min() and done[4]


@pytest.mark.parametrize("gate", ["as found", "off"])
def test_lyapunov_into_is_lyapunovs_bits_for_any_stretch_of_points(monkeypatch, gate):
    """``lyapunov_into`` gives :func:`~warpratchet.observables.lyapunov` of the points asked for, bit
    for bit: in the kernel where the gate allows it, else (and for a stretch with a tangent that is
    not finite) in NumPy; a zero norm gives -inf as NumPy's ``log`` does."""
    from warpratchet.kernels import _rows

    if gate == "off":
        monkeypatch.setattr(_rows, "_verdicts", {**_rows._verdicts, "libm": False})
    state = _random_state(3000, stretch=40.0)
    state["dx"][2000], state["dp"][2000] = 0.0, -0.0  # a zero norm
    state["dp"][2500] = np.nan  # a stretch with one of these goes to NumPy
    state["dx"][2550], state["dp"][2550] = -np.inf, np.nan  # hypot gives inf
    with np.errstate(divide="ignore", invalid="ignore"):
        want = lyapunov(state, 7)
    for lo, hi in ((0, 3000), (0, 1), (1000, 2001), (2400, 2600), (2999, 3000)):
        got = np.full(hi - lo, 0.5)
        assert kernels.lyapunov_into(state, 7, lo, hi, got) is got
        assert got.view(np.int64).tolist() == want[lo:hi].view(np.int64).tolist(), (lo, hi)


@pytest.mark.skipif(
    not _libm.hypot_matches_numpy(),
    reason="this machine's NumPy does not call the hypot the kernels transcribe",
)
def test_numpys_ftle_with_the_kernels_hypot_is_numpys_bit_for_bit():
    """Where the FTLE is NumPy's (its ``log`` not transcribed), its ``hypot`` comes from a kernel:
    the same bits as :func:`lyapunov` over tangents of every size, zeros and subnormals included,
    and NumPy's own functions for a stretch with a tangent that is not finite."""
    size = 20_000
    state = _random_state(size, stretch=300.0)
    rng = np.random.default_rng(7)
    for field in ("dx", "dp"):
        state[field] = state[field] * 10.0 ** rng.integers(-310, 300, size)
        state[field][rng.integers(0, size, 50)] = 0.0
    for step, (lo, hi) in ((37, (0, size)), (1, (123, 4567))):
        out = np.empty(hi - lo)
        got = _rows.numpy_ftle_into(state, step, lo, hi, out)
        with np.errstate(all="ignore"):
            want = lyapunov({k: v[lo:hi] for k, v in state.items()}, step)
        assert got is out and _bits(got) == _bits(want)
    for bad in (np.inf, np.nan):
        broken = dict(state, dp=state["dp"].copy())
        broken["dp"][size // 3] = bad
        with np.errstate(all="ignore"):
            want = lyapunov(broken, 5)
        assert _bits(_rows.numpy_ftle_into(broken, 5, 0, size, np.empty(size))) == _bits(want)
