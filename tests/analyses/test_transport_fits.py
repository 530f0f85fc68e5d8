"""The exponents of issue 16 on synthetic data with known exponents (warpratchet.transport._fits).

Tolerances are the fits' own standard errors (3 of them); the calibration tests check those
errors against the scatter of independent replicas.
"""

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from warpratchet import History, MapParams
from warpratchet.observables import default_lyapunov_threshold, lyapunov
from warpratchet.transport import TransportEnsemble
from warpratchet.transport._diffusion import spread_moments, spread_steps
from warpratchet.transport._fits import (
    bin_masses,
    default_tail_bins,
    diffusion_fit,
    group_moments,
    pooled_variance,
    tail_fit,
)


def _log2_counts(lengths: np.ndarray) -> np.ndarray:
    return np.bincount(np.floor(np.log2(lengths)).astype(int), minlength=64)


@pytest.mark.parametrize("alpha", [1.5, 2.0, 2.7])
def test_tail_fit_recovers_the_exponent_of_a_discrete_power_law(alpha):
    """Zipf samples, P(L) = L^-alpha / zeta(alpha): the fit over bins 3.. is within 3 stderr."""
    lengths = np.random.default_rng(7).zipf(alpha, size=300_000)
    fit = tail_fit(_log2_counts(lengths[lengths < 2**40]), steps=10**9)
    assert (fit.first_bin, fit.last_bin) == default_tail_bins(10**9) == (3, 22)
    assert abs(fit.alpha - alpha) < 3 * fit.stderr, fit
    assert fit.p_value > 0.001 and fit.power_law is (fit.p_value >= 0.01)
    assert fit.truncation_bias < 0.03


def test_tail_fit_errors_match_the_scatter_of_replicas():
    """30 independent samples: the spread of the estimates is the reported standard error."""
    rng = np.random.default_rng(11)
    fits = [tail_fit(_log2_counts(rng.zipf(2.2, size=20_000)), steps=10**6, last_bin=12) for _ in range(30)]
    alphas = np.array([f.alpha for f in fits])
    stderr = np.mean([f.stderr for f in fits])
    # The sample standard deviation of 30 normal values is within 30% of sigma with prob. > 0.99.
    assert 0.7 < alphas.std(ddof=1) / stderr < 1.3
    assert abs(alphas.mean() - 2.2) < 3 * stderr / math.sqrt(30)


def test_tail_fit_flags_lengths_that_are_not_a_power_law():
    """Geometric lengths (an exponential tail) give a tiny p-value."""
    lengths = np.random.default_rng(3).geometric(0.02, size=200_000)
    fit = tail_fit(_log2_counts(lengths), steps=10**7, last_bin=9)
    assert fit.p_value < 0.01 and fit.power_law is False


def test_tail_fit_refuses_too_few_counts_and_says_why():
    counts = np.zeros(64, dtype=np.int64)
    counts[:2] = [1000, 500]  # returns at K = 3: 1 to 3 steps, nothing in the tail
    fit = tail_fit(counts, steps=10**6)
    assert math.isnan(fit.alpha) and "a tail exponent needs 50 counts in 3 bins" in fit.reason
    short = tail_fit(counts, steps=100)  # lengths below 100/64: no bin
    assert math.isnan(short.alpha) and "empty fit range" in short.reason


def test_bin_masses_sum_the_power_law_over_each_bin():
    for alpha in (0.5, 1.0, 2.5):
        for k in (2, 7, 10):
            direct = float(np.sum(np.arange(2**k, 2 ** (k + 1), dtype=np.float64) ** -alpha))
            assert bin_masses(alpha, k, k)[0] == pytest.approx(direct, rel=1e-8)


def _walks(rng, points, steps, velocity):
    """Walkers observed at ``steps``: Brownian (exact Gaussian increments) plus ``velocity * n``."""
    out = np.zeros((len(steps), points))
    x, previous = np.zeros(points), 0
    v = rng.standard_normal(points)
    for i, n in enumerate(steps):
        x = x + math.sqrt(n - previous) * rng.standard_normal(points)
        out[i] = x + velocity * v * n
        previous = n
    return out


def _moments(values, groups=16):
    index = np.arange(values.shape[1]) % groups
    return np.stack([group_moments(row, index, groups) for row in values], axis=1)


@pytest.mark.parametrize(("velocity", "mu"), [(0.0, 1.0), (30.0, 2.0)])
def test_diffusion_fit_recovers_mu_of_brownian_and_ballistic_spreading(velocity, mu):
    """Var ~ n (Brownian) and ~ n^2 (constant velocities, dominant from n ~ 1): mu within 3 se."""
    steps = spread_steps(0, 10**6)
    values = _walks(np.random.default_rng(5), 4000, steps, velocity)
    moments = _moments(values)
    var = np.array([pooled_variance(moments[:, i]) for i in range(len(steps))])
    np.testing.assert_allclose(var, values.var(axis=1, ddof=1), rtol=1e-10)
    fit = diffusion_fit(steps, var, moments)
    assert (fit.first_step, fit.last_step, fit.rows, fit.groups) == (10**4, 10**6, 17, 16)
    assert abs(fit.mu - mu) < 3 * fit.stderr + (2e-3 if velocity else 0.0), fit  # ballistic: 1/(900 n) bias
    assert 0 < fit.stderr < 0.05
    assert fit.reason is None and fit.chaotic_growth == 0.0  # one set of points throughout


def test_diffusion_fit_flags_a_set_that_grows_faster_than_ballistic():
    """Ballistic walkers (mu = 2 as one set) counted from the slowest 80% at n = 10^4 to all at
    10^6, as a falling threshold admits the sticky orbits last: the slope exceeds 2 (by ~0.17:
    the mean v^2 of the counted set grows ~2.2x), and the fit flags it and states the growth."""
    steps = spread_steps(0, 10**6)
    rng = np.random.default_rng(5)
    values = _walks(rng, 4000, steps, 30.0)
    speed = np.abs(values[-1])  # the fastest walkers are the last to be counted
    index = np.arange(values.shape[1]) % 16
    share = np.clip(0.8 + 0.1 * (np.log10(steps) - 4.0), 0.0, 1.0)
    moments, var = [], []
    for row, q in zip(values, share, strict=True):
        counted = speed <= np.quantile(speed, q)
        moments.append(group_moments(row[counted], index[counted], 16))
        var.append(row[counted].var(ddof=1))
    fit = diffusion_fit(steps, np.array(var), np.stack(moments, axis=1))
    assert fit.mu - 2.0 > 4 * fit.stderr and "faster than ballistic" in fit.reason
    assert fit.chaotic_growth == pytest.approx(0.2, abs=1e-3) and "20.0%" in fit.reason


def test_diffusion_fit_errors_match_the_scatter_of_replicas():
    rng = np.random.default_rng(9)
    steps = spread_steps(0, 10**5)
    fits = []
    for _ in range(30):
        moments = _moments(_walks(rng, 800, steps, 0.0))
        var = np.array([pooled_variance(moments[:, i]) for i in range(len(steps))])
        fits.append(diffusion_fit(steps, var, moments))
    mus = np.array([f.mu for f in fits])
    stderr = np.mean([f.stderr for f in fits])
    assert 0.6 < mus.std(ddof=1) / stderr < 1.4  # jackknife: ~ +-15% scatter of its own
    assert abs(mus.mean() - 1.0) < 3 * stderr / math.sqrt(30)


def test_diffusion_fit_without_rows_or_groups_says_why():
    assert "rows" in diffusion_fit([10, 100], [1.0, 10.0]).reason
    no_groups = diffusion_fit([100, 200, 400, 1000], [100.0, 200.0, 400.0, 1000.0])
    assert (
        no_groups.mu == pytest.approx(1.0) and math.isnan(no_groups.stderr) and "no error" in no_groups.reason
    )


@pytest.mark.parametrize("rule", ["strict", "positive"])
def test_the_spread_of_a_transport_run_is_historys_variance(rule):
    """V(n) pooled from the groups equals History's var_dp_chaotic at the steps both record, with
    the chaotic points of the same threshold rule (rounding apart: two summation orders)."""
    p = MapParams(3.0, 0.1, 0.01)
    history = History(threshold_rule=rule)
    ens = TransportEnsemble.sample(p, 3000, "strip", seed=1)
    ens.classify_with(threshold_rule=rule)
    ens.run(3000, [history])
    steps, var = ens.spread()
    rows = dict(zip(history.rows["step"], history.rows["var_dp_chaotic"], strict=True))
    common = [i for i, n in enumerate(steps) if n in rows]
    assert len(common) >= 20
    np.testing.assert_allclose(var[common], [rows[steps[i]] for i in common], rtol=1e-9)
    fit = ens.diffusion(decades=1.0)
    assert fit.rows == 8 and np.isfinite(fit.mu) and fit.stderr > 0  # 316 .. 2371


@pytest.mark.parametrize("points", [1, 5, (1 << 16) + 3, 3 * (1 << 16)])
def test_spread_moments_in_blocks_and_threads_equal_one_pass_bitwise(points):
    """The rows are computed in blocks of points, on threads: the same bits as over all points at once."""
    ens = TransportEnsemble.sample(MapParams(3.0, 0.1, 0.01), points, "strip", seed=2, threads=2)
    ens.run(300)
    state = ens.state()
    p0 = state["p0"]
    dp = state["winding"] + (state["q"] - (p0 - np.floor(p0)))
    for threshold in (None, 0.2):
        limit = default_lyapunov_threshold(300) if threshold is None else threshold
        chaotic = np.flatnonzero(lyapunov(state, 300) > limit)
        expected = group_moments(dp[chaotic], chaotic % 16, 16).tobytes()
        assert spread_moments(state, 300, threshold).tobytes() == expected
        with ThreadPoolExecutor(2) as pool:
            assert spread_moments(state, 300, threshold, pool=pool).tobytes() == expected


def test_history_rows_beside_spread_rows_are_a_plain_runs_bit_for_bit(monkeypatch):
    """A History row at a spread row's step takes the FTLE the spread row computed: same bits.

    (1 << 16) + 5 points on 2 threads: the spread's blocks (and threads) are not the summary's
    chunks. Each spread step's History row must have used the lent FTLE.
    """
    import warpratchet.observables as observables
    from warpratchet import Ensemble

    lent = []
    summarize = observables.summarize_with_variance

    def spy(state, step, threshold, ftle=None, **threads):
        lent.append((step, ftle is not None))
        return summarize(state, step, threshold, ftle, **threads)

    monkeypatch.setattr("warpratchet.ensemble.summarize_with_variance", spy)  # Ensemble.summary's
    known = TransportEnsemble.known_ftle
    spread_lent = []

    def known_spy(self, step):
        ftle = known(self, step)
        if ftle is not None:
            spread_lent.append(step)
        return ftle

    monkeypatch.setattr(TransportEnsemble, "known_ftle", known_spy)
    rows = []
    for cls in (Ensemble, TransportEnsemble):
        lent.clear()
        ens = cls.sample(MapParams(3.0, 0.1, 0.01), (1 << 16) + 5, "strip", seed=4, threads=2)
        history = History()
        ens.run(400, [history])
        rows.append(history.as_dict())
        # At a spread row's step the row's summary is lent the spread's FTLE; elsewhere (and in a
        # plain run) it computes its own.
        lent_at = {step for step, given in lent if given}
        assert lent and lent_at == (set(spread_steps(0, 400)) if cls is TransportEnsemble else set())
    assert set(spread_lent) == set(spread_steps(0, 400))
    assert rows[0].keys() == rows[1].keys()
    for name in rows[0]:
        assert np.asarray(rows[0][name]).tobytes() == np.asarray(rows[1][name]).tobytes(), name


def test_a_transport_runs_spread_rows_use_the_runs_own_threads(monkeypatch):
    """On 2 threads a transport run makes one pool, its launches': the spread rows and the history
    rows run on it. The spread rows are those of a spread with a pool of its own, bit for bit."""
    import warpratchet.ensemble
    import warpratchet.transport._diffusion
    from warpratchet import Ensemble

    made = []

    def pool(*args, **kwargs):
        made.append(ThreadPoolExecutor(*args, **kwargs))
        return made[-1]

    for module in (warpratchet.ensemble, warpratchet.transport._diffusion):
        monkeypatch.setattr(module, "ThreadPoolExecutor", pool)
    rows = []
    for shared in (True, False):
        if not shared:  # as if outside Ensemble.run: the spread makes its own pool
            monkeypatch.setattr(Ensemble, "run_pool", property(lambda self: None))
        made.clear()
        ens = TransportEnsemble.sample(MapParams(3.0, 0.1, 0.01), 3000, "strip", seed=4, threads=2)
        ens.run(2500, [History()])
        rows.append(ens.transport_state().spread)
        assert len(made) == (1 if shared else 2) and len(rows[-1]) == len(spread_steps(0, 2500))
    assert rows[0].tobytes() == rows[1].tobytes()


def test_bytes_per_point_count_the_carry_and_a_spread_rows_arrays():
    """TransportEnsemble's memory check counts what grows with the points: state, carry and the
    full-size arrays of a spread row (measured here with tracemalloc, which sees NumPy's)."""
    import tracemalloc

    from warpratchet.transport._diffusion import SPREAD_BYTES_PER_POINT

    ens = TransportEnsemble.sample(MapParams(3.0, 0.1, 0.01), 10, threads=1)
    carry = sum(a.numpy().itemsize for a in ens._extra_arrays())
    assert TransportEnsemble.bytes_per_point() == 56 + carry + SPREAD_BYTES_PER_POINT == 97
    n = 1 << 20
    state = {name: np.zeros(n) for name in ("winding", "q", "p0", "dp", "log_stretch")}
    state["dx"] = np.ones(n)
    tracemalloc.start()
    try:
        ftle = np.empty(n)  # as the Spread observer lends it
        spread_moments(state, 1000, ftle=ftle)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert SPREAD_BYTES_PER_POINT * n <= peak <= SPREAD_BYTES_PER_POINT * n + (8 << 20)


def test_a_transport_run_flags_mu_above_ballistic_and_not_a_diffusive_one():
    """K = 2.99 (sticky islands) gives V(n) steeper than n^2 over n = 10^3..10^5 and is flagged;
    K = 3 (no sticky islands, docs/transport.md) at the same b is diffusive and is not."""
    fits = {}
    for K in (3.0, 2.99):
        ens = TransportEnsemble.sample(MapParams(K, 0.1361, 0.05), 10_000, "strip", seed=1)
        fits[K] = ens.run(100_000).diffusion()
    assert fits[3.0].reason is None and abs(fits[3.0].mu - 1.0) < 0.2
    assert fits[2.99].mu - 2.0 > 3 * fits[2.99].stderr and "faster than ballistic" in fits[2.99].reason
    assert 0.0 < fits[2.99].chaotic_growth < 0.1
