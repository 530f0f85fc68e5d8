"""Convergence diagnostics (warpratchet.convergence) on synthetic ensembles with known answers.

Robust standard error: (i) Gaussian random walks, whose true error is exact; (ii) a Levy-walk
model of sticking (sea phases alternating with Pareto-distributed sticking episodes at velocity
nu = -1), whose true error is the spread of the estimate over many independent replicas.
Drift verdict: histories of random walks, with and without a slowly decaying transient.
Tolerances are standard errors computed here (bootstrap over replicas, binomial counts), plus the
bias bounds stated at each assertion.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from warpratchet.convergence import (
    DRIFT_Z_MAX,
    diffusion_exponent,
    drift,
    drift_from_history,
    robust_stderr,
    value_at,
)

BLOCKS = 64
#: Two-sided Gaussian probabilities of |Z| < 2 and |Z| > 3.
INSIDE_2 = math.erf(2 / math.sqrt(2))
OUTSIDE_3 = 1.0 - math.erf(3 / math.sqrt(2))


def sticky_gains(rng, orbits, steps, *, a=0.04, s=0.5, nu=-1.0, sea=2000.0, t0=5.0, gamma=1.5):
    """Per-orbit momentum gains over BLOCKS equal blocks, shape (BLOCKS, orbits), of a Levy walk.

    Each orbit starts in the sea: exponential sea phases (mean ``sea`` steps, velocity ``a`` plus
    Gaussian noise ``s`` per step) alternate with sticking episodes of Pareto length
    (``P(tau > t) = (t / t0)^-gamma``) at velocity ``nu``. A block's gain is exact in distribution:
    ``a`` x (sea time) + ``nu`` x (stuck time) + ``s sqrt(sea time) Z``.
    """
    phases = int(3 * steps / (sea + t0 * gamma / (gamma - 1.0))) + 20
    dur = np.empty((orbits, 2 * phases))
    dur[:, 0::2] = rng.exponential(sea, (orbits, phases))
    dur[:, 1::2] = t0 * (1.0 - rng.random((orbits, phases))) ** (-1.0 / gamma)
    end = np.cumsum(dur, axis=1)
    assert np.all(end[:, -1] > steps), "not enough phases drawn"
    start = end - dur
    stuck = np.zeros_like(dur)
    stuck[:, 1::2] = dur[:, 1::2]
    stuck_before = np.cumsum(stuck, axis=1) - stuck
    # The phase holding each block edge, for all orbits in one sorted search (orbits offset apart).
    offset = (float(end[:, -1].max()) + 1.0) * np.arange(orbits)[:, None]
    edges = np.linspace(0.0, steps, BLOCKS + 1)
    k = np.searchsorted((end + offset).ravel(), (edges + offset).ravel(), side="right")
    k = k.reshape(orbits, BLOCKS + 1) - 2 * phases * np.arange(orbits)[:, None]
    rows = np.arange(orbits)[:, None]
    stuck_at = stuck_before[rows, k] + np.where(k % 2 == 1, edges - start[rows, k], 0.0)
    stuck_time = np.diff(stuck_at, axis=1)
    sea_time = np.clip(steps / BLOCKS - stuck_time, 0.0, None)
    gains = a * sea_time + nu * stuck_time + s * np.sqrt(sea_time) * rng.standard_normal(sea_time.shape)
    return gains.T


def bootstrap_se(rng, statistic, *samples, resamples=400):
    """Standard error of ``statistic(*samples)`` by resampling replicas (rows shared by all samples)."""
    size = samples[0].shape[0]
    values = []
    for _ in range(resamples):
        pick = rng.integers(0, size, size)
        values.append(statistic(*(x[pick] for x in samples)))
    return float(np.std(values, ddof=1))


# -- robust standard error ---------------------------------------------------------------------------
def test_robust_stderr_is_exact_for_diffusion():
    """Gaussian increments: V(T) = s^2 T exactly, true error s / sqrt(n M)."""
    rng = np.random.default_rng(11)
    orbits, steps, s, replicas = 500, 64_000, 0.7, 200
    block = steps // BLOCKS
    results = [
        robust_stderr(rng.normal(0.03 * block, s * math.sqrt(block), (BLOCKS, orbits)), steps)
        for _ in range(replicas)
    ]
    true = s / math.sqrt(steps * orbits)
    robust = np.array([r.stderr for r in results])
    vt = np.array([r.variance_time_stderr for r in results])
    naive = np.array([r.naive_stderr for r in results])
    mu = np.array([r.exponent for r in results])
    assert abs(mu.mean() - 1.0) < 3 * mu.std(ddof=1) / math.sqrt(replicas)
    # Both estimators are unbiased for V(n) here; max(vt, naive) exceeds them by at most
    # E|vt - naive| / 2 (max(x, y) = (x + y)/2 + |x - y|/2), measured from the replicas.
    bias = float(np.mean(np.abs(vt - naive))) / 2
    se = bootstrap_se(rng, np.mean, robust)
    assert -3 * se <= robust.mean() - true <= 3 * se + bias
    assert abs(vt.mean() - true) < 3 * vt.std(ddof=1) / math.sqrt(replicas)
    assert np.all(robust >= naive) and np.all(robust >= vt)


def test_robust_stderr_on_heavy_tailed_sticking():
    """Pareto sticking (gamma = 1.5): the true error is the spread over 300 independent ensembles."""
    rng = np.random.default_rng(12)
    orbits, steps, replicas = 1000, 20_000, 300
    estimate, robust = np.empty(replicas), np.empty(replicas)
    for r in range(replicas):
        gains = sticky_gains(rng, orbits, steps)
        estimate[r] = gains.sum(axis=0).mean() / steps
        robust[r] = robust_stderr(gains, steps).stderr
    # Not optimistic: +-2 robust errors cover the mean of the replicas at least as often as a
    # Gaussian 2-sigma interval (95.45%), within 3 binomial standard errors. (Using the replica
    # mean instead of the exact limit shrinks the deviations by a factor sqrt(1 - 1/300).)
    covered = np.mean(np.abs(estimate - estimate.mean()) <= 2 * robust)
    assert covered >= INSIDE_2 - 3 * math.sqrt(INSIDE_2 * (1 - INSIDE_2) / replicas)

    # The typical (median) robust error against the true spread, with the bootstrap error of the
    # ratio. Stated bias bound: conservative by at most 25% (module docstring: 1.00-1.16 measured
    # on this family of processes: fewer flights early in a run started in the sea).
    def ratio(est, rob):
        return np.median(rob) / est.std(ddof=1)

    se = bootstrap_se(rng, ratio, estimate, robust)
    value = ratio(estimate, robust)
    assert 1.0 - 3 * se <= value <= 1.25 + 3 * se, (value, se)


def test_robust_stderr_subsample_and_bad_input():
    rng = np.random.default_rng(13)
    gains = rng.normal(0.0, 1.0, (BLOCKS, 400))
    full = robust_stderr(gains, 6400)
    scaled = robust_stderr(gains, 6400, points=1600)  # the same variance, a mean over 4x the orbits
    assert scaled.stderr == pytest.approx(full.stderr / 2, rel=1e-12)
    assert full.block_steps[0] == 100 and full.block_steps[-1] == 6400
    odd = robust_stderr(rng.normal(0.0, 1.0, (12, 50)), 1200)  # 12 blocks: 12 -> 6 -> 3 -> (2) -> 1
    assert odd.block_steps == (100, 200, 400, 800)
    with pytest.raises(ValueError, match="B >= 8"):
        robust_stderr(gains[:4], 6400)
    with pytest.raises(ValueError, match="steps"):
        robust_stderr(gains, 10)
    with pytest.raises(ValueError, match="fit_levels"):
        robust_stderr(gains, 6400, fit_levels=7)
    with pytest.raises(ValueError, match="points"):
        robust_stderr(gains, 6400, points=0)


# -- drift ---------------------------------------------------------------------------------------------
STEPS = np.unique(np.round(10 ** (np.arange(8, 41) / 8)).astype(np.int64))  # 8 per decade, to 1e5


def histories(rng, series, orbits, *, a=0.05, s=0.7, bias=None):
    """History rows (A, A_stderr, var_dp) of ``series`` random-walk ensembles at STEPS.

    ``bias(t)``, if given, is added to every orbit's ``p_t - p_0`` (a transient common to all).
    """
    dt = np.diff(np.concatenate([[0], STEPS]))
    dp = np.cumsum(rng.standard_normal((series, orbits, STEPS.size)) * (s * np.sqrt(dt)), axis=2)
    dp += a * STEPS + (0.0 if bias is None else bias(STEPS))
    return dp.mean(axis=1) / STEPS, dp.std(axis=1, ddof=1) / math.sqrt(orbits) / STEPS, dp.var(axis=1, ddof=1)


def test_drift_converged_series_rarely_flagged():
    rng = np.random.default_rng(21)
    series = 2000
    A, se, var = histories(rng, series, 200)
    verdicts = [drift(STEPS, A[i], se[i], var[i]) for i in range(series)]
    assert {d.verdict for d in verdicts} <= {"converged", "drifting"}
    alarms = sum(d.verdict == "drifting" for d in verdicts)
    # Under diffusion the z of the rule is standard normal (its error is never below se(A_n), so
    # alarms are at most as frequent): <= 0.27% plus 3 binomial standard errors.
    assert alarms / series <= OUTSIDE_3 + 3 * math.sqrt(OUTSIDE_3 * (1 - OUTSIDE_3) / series)
    mu = np.array([d.exponent for d in verdicts])
    assert abs(mu.mean() - 1.0) < 3 * mu.std(ddof=1) / math.sqrt(series)


def test_drift_flags_a_slow_transient():
    """A sticking-like transient: the bias of A_n decays like n^-1/2, expected |z| = 8 at n = 1e5."""
    rng = np.random.default_rng(22)
    series, orbits, s = 1000, 200, 0.7
    se_true = s / math.sqrt(STEPS[-1] * orbits)
    shape = np.sqrt(STEPS.astype(float))  # gain c sqrt(t): bias c / sqrt(t) of A_t
    expected_delta = (shape[-1] / STEPS[-1]) - value_at(STEPS, shape / STEPS, STEPS[-1] / 2)
    c = 8 * se_true / abs(expected_delta)
    A, se, var = histories(rng, series, orbits, s=s, bias=lambda t: c * np.sqrt(t))
    verdicts = [drift(STEPS, A[i], se[i], var[i]) for i in range(series)]
    flagged = np.mean([d.verdict == "drifting" for d in verdicts])
    # The rule's error is se(A_n) x sqrt(max(1, 2^(2 - mu) - 1)); the transient lowers mu a
    # little, so take the largest factor seen. Power P(|z| > 3) at |z| = 8 / factor.
    factor = max(d.stderr / se[i, -1] for i, d in enumerate(verdicts))
    power = 0.5 * (1 + math.erf((8 / factor - DRIFT_Z_MAX) / math.sqrt(2)))
    assert factor < 1.6
    assert flagged >= power - 3 * math.sqrt(power * (1 - power) / series) - 1 / series
    assert np.median([d.delta for d in verdicts]) < 0  # A_n rises towards its limit from above


def test_drift_exponent_and_edge_cases():
    t = np.array([10, 20, 40, 80, 160], dtype=float)
    assert diffusion_exponent(t, 3.0 * t) == pytest.approx(1.0)
    assert diffusion_exponent(t, 0.2 * t**2) == pytest.approx(2.0)  # ballistic flights
    assert math.isnan(diffusion_exponent([100, 160], [300, 480]))  # record starts after n/2
    assert value_at(t, 1.0 + 5.0 / t, 50.0) == pytest.approx(1.1)  # exact for A + B/n
    short = drift([150, 200], [0.1, 0.1], [0.01, 0.01])  # n/2 = 100 is before the record
    assert short.verdict == "too short" and math.isnan(short.z)
    hist = {"step": t, "A": 0.1 + 1.0 / t, "A_stderr": np.full(5, 1e-4), "var_dp_chaotic": 2.0 * t}
    d = drift_from_history(hist)
    assert d.verdict == "drifting" and d.delta == pytest.approx(1 / 160 - 1 / 80)
    assert d.z == pytest.approx(d.delta / 1e-4)  # mu = 1: the error is se(A_n)
    assert drift_from_history(hist, stderr=1.0).verdict == "converged"
    with pytest.raises(ValueError, match="missing"):
        drift_from_history({"step": t})
    with pytest.raises(ValueError, match="increasing"):
        drift([2, 1], [0.1, 0.1], [0.01, 0.01])
    with pytest.raises(ValueError, match="z_max"):
        drift(t, t, t, z_max=0)
