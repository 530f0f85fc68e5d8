"""What the code and the machine can carry (warpratchet.limits): the ceilings agree with the kernels,
the kernels' range of b1, b2 is the float64 bound it states, and the memory estimates are upper
bounds of what the code allocates (measured with tracemalloc)."""

from __future__ import annotations

import json
import math
import tracemalloc
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from warpratchet import kernels, paper, reference
from warpratchet.ensemble import STATE_FIELDS, Ensemble
from warpratchet.errors import ParameterError, ResourceError
from warpratchet.limits import (
    FLOAT64_MAX,
    MAX_POINTS,
    MAX_TANGENT_GROWTH,
    RENORM_CHECK_EVERY,
    RENORM_THRESHOLD,
    available_memory,
    check_kernel_range,
    check_memory,
    format_bytes,
    kernel_range_error,
    smallest_width,
)
from warpratchet.observables import SUMMARY_BYTES_PER_POINT, SUMMARY_CHUNK, summarize, summarize_with_variance
from warpratchet.params import MapParams
from warpratchet.sumrule import IndicatorEnsemble, census
from warpratchet.sumrule._islands import CLASSIFY_HOST_BYTES_PER_POINT
from warpratchet.sweep import SWEEP_BYTES_PER_POINT, SweepSpec, maximal_path, run_sweep


# -- the ceilings are the kernels' ----------------------------------------------------------------
def test_the_constants_are_the_kernels():
    assert RENORM_THRESHOLD == kernels.RENORM_THRESHOLD
    assert RENORM_CHECK_EVERY == kernels.RENORM_CHECK_EVERY
    # Point indices up to n + INTERLEAVE - 1 are 32-bit ints in the kernels.
    assert MAX_POINTS + kernels.INTERLEAVE - 1 <= 2**31 - 1
    assert kernels.launch_dim(MAX_POINTS) * kernels.INTERLEAVE <= 2**31 - 1


def test_bytes_per_point_are_the_arrays_an_ensemble_allocates():
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), 10, threads=1)
    assert Ensemble.bytes_per_point() == sum(ens.array(n).itemsize for n in STATE_FIELDS) == 56
    ind = IndicatorEnsemble(ens.params, np.zeros(3), np.zeros(3), threads=1)
    assert IndicatorEnsemble.bytes_per_point() == 56 + sum(a.numpy().itemsize for a in ind._extra_arrays())


# -- the kernels' range of b ------------------------------------------------------------------------
@pytest.mark.parametrize("K", [1e-3, 1.0, 3.0, 3.999])
@pytest.mark.parametrize("other", [1e-150, 1e-7, 0.3, 0.9])
@pytest.mark.parametrize("name", ["b1", "b2"])
def test_the_stated_bound_is_the_float64_bound(K, other, name):
    """At the stated (rounded-up) bound the tangent's growth g^8 from the threshold fits float64;
    a tenth below, it does not (the rounding adds at most 10%)."""
    base = MapParams(K, 0.5 * (1 - other), other) if name == "b1" else MapParams(K, other, 0.5 * (1 - other))
    bound = smallest_width(name, base)

    def at(width):
        return MapParams(K, width, other) if name == "b1" else MapParams(K, other, width)

    slope = "l1" if name == "b1" else "l2"
    grows = 2 + K * getattr(at(bound), slope)
    assert grows <= MAX_TANGENT_GROWTH and RENORM_THRESHOLD * grows**RENORM_CHECK_EVERY <= FLOAT64_MAX
    below = 0.9 * bound
    assert RENORM_THRESHOLD * (2 + K * getattr(at(below), slope)) ** RENORM_CHECK_EVERY > FLOAT64_MAX
    message = kernel_range_error(at(below))
    assert message is not None
    if other >= 1e-7:  # the other width is itself carried: the message is about this one
        assert message.startswith(f"{name} = {below!r} is outside the range the kernels can carry")
        assert f"{name} >= {bound:.2g} (a tangent would overflow" in message
        assert kernel_range_error(at(bound)) is None


def test_the_papers_parameters_are_carried_and_tiny_b_is_not():
    for p in (*paper.FIG2, *paper.FIG1):
        check_kernel_range(p)  # Fig. 2: b1 = b2 = 1e-7
    with pytest.raises(ParameterError, match=r"^b1 = 1e-150 is outside the range the kernels can carry"):
        check_kernel_range(MapParams(3.0, 1e-150, 1e-150))
    with pytest.raises(ParameterError, match=r"^b2 = 5e-324 .* b2 >= 1\.4e-26"):
        check_kernel_range(MapParams(3.0, 0.1, 5e-324))


def test_below_the_bound_the_kernels_arithmetic_overflows():
    """Why the bound exists: the NumPy twin of the kernels, at b1 = b2 = 1e-150, on the strip B."""
    p = MapParams(3.0, 1e-150, 1e-150)
    rng = np.random.default_rng(0)
    x = np.mod(-p.b2 + p.b * rng.random(1000), 1.0)
    state = {"x": x, "q": rng.random(1000), "winding": np.zeros(1000, np.int64), "p0": np.zeros(1000)}
    state.update(dx=np.ones(1000), dp=np.zeros(1000), log_stretch=np.zeros(1000))
    with np.errstate(all="ignore"):
        after = reference.advance(p, state, 64)
        ftle = (after["log_stretch"] + np.log(np.hypot(after["dx"], after["dp"]))) / 64
    assert np.count_nonzero(~np.isfinite(ftle)) > 100


# -- memory -----------------------------------------------------------------------------------------
def test_available_memory_and_the_message():
    available = available_memory()
    assert available is None or available > 0
    with pytest.raises(ResourceError) as info:
        check_memory("points = 10", 3 * 2**30, "56 B per point", available=2**30)
    assert str(info.value) == (
        "points = 10 needs 3 GiB of memory (56 B per point); this machine has 1 GiB available"
    )
    check_memory("points = 10", 2**30, available=2**30)  # exactly what is there: fine
    assert format_bytes(10_000_000_000 * 8) == "74.5 GiB" and format_bytes(12) == "12 B"


def _peak(fn) -> float:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_summary_needs_at_most_its_stated_working_memory():
    """Worst case: every point chaotic (threshold 0), so the chaotic subsets are full-size."""
    n = 200_000
    ens = Ensemble.sample(MapParams(3.0, 0.1, 0.01), n, "torus", threads=1).run(64)
    live = {name: ens.array(name) for name in STATE_FIELDS}
    peak = _peak(lambda: summarize(live, ens.step, 0.0))
    assert peak <= SUMMARY_BYTES_PER_POINT * n, peak / n
    with ThreadPoolExecutor(2) as pool:  # the same summary and the variance, on threads
        peak = _peak(lambda: summarize_with_variance(live, ens.step, 0.0, pool=pool, batches=8))
    assert peak <= SUMMARY_BYTES_PER_POINT * n, peak / n


def test_a_census_needs_at_most_its_stated_host_memory():
    n = 30_000
    peak = _peak(lambda: census(MapParams(3.0, 0.1, 0.01), 13_824, points=n, threads=1))
    assert peak <= CLASSIFY_HOST_BYTES_PER_POINT * n, peak / n


def test_a_sweep_keeps_at_most_its_stated_memory_per_point():
    """The growth with the number of points (rows, parameters, the JSON of the rows)."""
    spec = SweepSpec(points=4, steps=4)

    def sweep(count):
        rows = run_sweep(maximal_path(np.linspace(0.01, 0.1, count)), spec, progress=False, threads=1)
        json.dumps(rows)

    sweep(4)  # Warp's first load is not the sweep's
    small, large = _peak(lambda: sweep(40)), _peak(lambda: sweep(440))
    assert (large - small) / 400 <= SWEEP_BYTES_PER_POINT, (large - small) / 400


def test_an_ensemble_that_does_not_fit_is_refused_before_it_is_allocated(monkeypatch):
    from warpratchet import limits

    monkeypatch.setattr(limits, "available_memory", lambda: 2**20)
    per_point = Ensemble.bytes_per_point() + SUMMARY_BYTES_PER_POINT
    with pytest.raises(ResourceError, match=r"^points = 100000 needs 11\.4 MiB of memory \(56 B of state"):
        Ensemble.sample(MapParams(3.0, 0.1, 0.01), 100_000)
    assert math.isclose(100_000 * per_point / 2**20, 11.44, rel_tol=1e-3)
    Ensemble.sample(MapParams(3.0, 0.1, 0.01), 2**20 // per_point, threads=1)  # what fits, runs
    # The summary works on SUMMARY_CHUNK points at a time: its memory does not grow past one chunk.
    big = 4 * SUMMARY_CHUNK
    need = big * Ensemble.bytes_per_point() + SUMMARY_CHUNK * SUMMARY_BYTES_PER_POINT
    monkeypatch.setattr(limits, "available_memory", lambda: need)
    Ensemble.check_fits(big)  # fits with a chunk's summary (4x the points' summary would not)
    with pytest.raises(ResourceError, match=r"^points = 4194305 needs"):
        Ensemble.check_fits(big + 1)
    monkeypatch.setattr(limits, "available_memory", lambda: 2**20)
    with pytest.raises(ResourceError, match=r"^a census of 10000 points needs"):
        census(MapParams(3.0, 0.1, 0.01), 13_824, points=10_000)
