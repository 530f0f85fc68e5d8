"""The C library's ``hypot`` and ``log`` transcribed for the CPU kernels: NumPy's bits, and a gate
that can tell.

``warpratchet.kernels._libm`` reproduces glibc's ``hypot`` and ``__log_fma`` operation by
operation. Where this machine's NumPy calls those functions (its gate, ``matches_numpy``, says
so), the kernel must give NumPy's bits on more than 10^7 arguments over every path of both
functions; where it does not, those comparisons are skipped (the kernels fall back to NumPy there)
but the gate's own tests still run, and on the platform the transcription was made from the gate
must hold.
"""

import platform
import re

import numpy as np
import numpy._core._multiarray_umath as umath
import pytest

from warpratchet.kernels import _libm
from warpratchet.kernels._libm import (
    GLIBC_FTLE_CPP,
    LOG_HARD_CASES,
    agrees,
    ftle_like_numpy,
    gate_sample,
    hypot_like_numpy,
    hypot_matches_numpy,
    log_like_numpy,
    matches_numpy,
    numpy_ftle,
)

CHUNK = 1_000_000
TINY_LIMIT = 2.0**-459  # hypot scales arguments below this up
LARGE_LIMIT = 2.0**511  # and above this down
LOG_NEAR_ONE = (1.0 - 2.0**-4, 1.0 + float.fromhex("0x1.09p-4"))  # log's near-1 interval

needs_glibc = pytest.mark.skipif(
    not matches_numpy(),
    reason="this machine's NumPy does not call glibc 2.35+'s hypot and __log_fma (matches_numpy() "
    "is False), so there is nothing to reproduce: the kernels take NumPy's values here",
)
needs_glibc_hypot = pytest.mark.skipif(
    not hypot_matches_numpy(),
    reason="this machine's NumPy does not call glibc 2.35+'s hypot (hypot_matches_numpy() is False): "
    "the kernels take NumPy's values here",
)


def _same_bits(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    """Equal bit for bit, or both NaN (a NaN's payload is the machine's)."""
    return (got.view(np.int64) == want.view(np.int64)) | (np.isnan(got) & np.isnan(want))


def _check(got, ok, want, *arguments) -> None:
    assert ok.all()
    same = _same_bits(got, want)
    if not same.all():
        i = int(np.flatnonzero(~same)[0])
        at = ", ".join(a[i].hex() for a in arguments)
        pytest.fail(
            f"{int((~same).sum())} of {same.size} differ, first at ({at}): "
            f"{got[i].hex()}, NumPy {want[i].hex()}"
        )


def _tangents(rng, norm: np.ndarray, ratio: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangents of the given norms whose smaller component is ``ratio`` times the larger, in random
    order and signs."""
    angle = np.arctan(ratio)
    big, small = norm * np.cos(angle), norm * np.sin(angle)
    swap = rng.random(norm.size) < 0.5
    signs = rng.choice([-1.0, 1.0], (2, norm.size))
    return np.where(swap, small, big) * signs[0], np.where(swap, big, small) * signs[1]


def _ratios(rng, n: int) -> np.ndarray:
    """Uniform in [0, 1] (hypot's two corrections meet at 1/sqrt 3), near its 2^-54 shortcut, and 0."""
    ratio = np.concatenate(
        [
            rng.uniform(0.0, 1.0, n - n // 4 - n // 64),
            np.exp2(rng.uniform(-58.0, -50.0, n // 4)),
            np.zeros(n // 64),
        ]
    )
    rng.shuffle(ratio)
    return ratio


NORMS = {
    # 3 * 10^6 composites of unit-ish tangents (the renormalised tangents of a run)
    "near one": lambda rng, n: 1.0 + rng.uniform(-0.07, 0.07, n),
    "very near one": lambda rng, n: 1.0 + rng.uniform(-1e-6, 1e-6, n),
    "within log's near-1 interval": lambda rng, n: rng.uniform(*LOG_NEAR_ONE, n),
    # 2 * 10^6 over every magnitude a tangent can have
    "log-uniform": lambda rng, n: np.exp(rng.uniform(np.log(1e-300), np.log(1e300), n)),
    "every table interval": lambda rng, n: np.exp(rng.uniform(-0.75, 0.75, n)),
}


@needs_glibc
@pytest.mark.parametrize("norms", list(NORMS))
def test_ftle_equals_numpy_bit_for_bit(norms):
    rng = np.random.default_rng(sorted(NORMS).index(norms))
    norm = NORMS[norms](rng, CHUNK)
    dx, dp = _tangents(rng, norm, _ratios(rng, CHUNK))
    log_stretch = rng.uniform(0.0, 1e5, CHUNK)
    step = float(rng.integers(1, 10**6))
    _check(*ftle_like_numpy(dx, dp, log_stretch, step), numpy_ftle(dx, dp, log_stretch, step), dx, dp)


def _log_arguments(rng, n: int) -> np.ndarray:
    """Every positive double's exponent (log-uniform bit patterns, subnormals included), and
    the edges of the near-1 interval to the last bits."""
    bits = rng.integers(1, 0x7FF0000000000000, n // 2, dtype=np.int64)
    edges = np.array(LOG_NEAR_ONE).view(np.int64)
    around = edges[rng.integers(0, 2, n // 2 - 2)] + rng.integers(-(2**40), 2**40, n // 2 - 2)
    ones = np.array([1.0, np.nextafter(1.0, 2.0)]).view(np.int64)
    return np.concatenate([bits, around, ones]).view(np.float64)


@needs_glibc
@pytest.mark.parametrize("seed", [0, 1])
def test_log_equals_numpy_bit_for_bit(seed):
    """``log`` alone, 2 * 10^6 arguments."""
    x = _log_arguments(np.random.default_rng(100 + seed), CHUNK)
    _check(*log_like_numpy(x), np.log(x), x)


HYPOT_MAGNITUDES = {
    "unit": lambda rng, n: np.exp(rng.uniform(-1.0, 1.0, n)),
    "across the scaled ranges": lambda rng, n: np.exp2(
        rng.choice([np.log2(TINY_LIMIT), np.log2(LARGE_LIMIT)], n) + rng.uniform(-60.0, 60.0, n)
    ),
    "everywhere": lambda rng, n: np.exp2(rng.uniform(-1074.0, 1024.0, n)),
}


@needs_glibc_hypot
@pytest.mark.parametrize("magnitudes", list(HYPOT_MAGNITUDES))
def test_hypot_equals_numpy_bit_for_bit(magnitudes):
    """``hypot`` alone, 3 * 10^6 arguments: its two corrections, shortcut and scalings."""
    rng = np.random.default_rng(200 + sorted(HYPOT_MAGNITUDES).index(magnitudes))
    norm = HYPOT_MAGNITUDES[magnitudes](rng, CHUNK)
    dx, dp = _tangents(rng, norm, _ratios(rng, CHUNK))
    _check(*hypot_like_numpy(dx, dp), np.hypot(dx, dp), dx, dp)


SPECIAL = np.array(
    [0.0, -0.0, 1.0, -1.0, 5e-324, 2.0**-1022, np.finfo(np.float64).max, -np.finfo(np.float64).max]
    + [np.inf, -np.inf, np.nan]
)


@needs_glibc
def test_special_values_are_numpy_or_reported():
    """Every pair of special components: NumPy's bits where ``ok`` (hypot 0, overflow to inf,
    subnormal norms), and ``ok`` false exactly where a component is not finite."""
    dx, dp = (a.ravel() for a in np.meshgrid(SPECIAL, SPECIAL))
    for log_stretch in (0.0, -1.0, np.inf, np.nan):
        for step in (1.0, 3.0):
            ls = np.full(dx.shape, log_stretch)
            got, ok = ftle_like_numpy(dx, dp, ls, step)
            assert np.array_equal(ok, np.isfinite(dx) & np.isfinite(dp))
            assert _same_bits(got[ok], numpy_ftle(dx, dp, ls, step)[ok]).all()


BLOCK_SIZES = [1, 2, 3, 5, 7, 255, 257, 1023, 1025, 2_500]


def _mixed_tangents(rng, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Tangents mixing the common paths with the points handled again: norms near 1 and exactly 1,
    zero, subnormal, scaled by hypot, and 3% non-finite components."""
    kinds = [
        lambda n: 1.0 + rng.uniform(-0.07, 0.07, n),
        lambda n: np.exp(rng.uniform(np.log(1e-3), np.log(1e64), n)),
        lambda n: np.exp2(rng.choice([-470.0, 520.0], n) + rng.uniform(-20.0, 20.0, n)),
        lambda n: np.exp2(rng.uniform(-1074.0, -1022.0, n)),
        lambda n: rng.choice([0.0, 1.0], n),
    ]
    kind = rng.choice(len(kinds), size, p=[0.4, 0.4, 0.08, 0.06, 0.06])
    norm = np.zeros(size)
    for k, draw in enumerate(kinds):
        norm[kind == k] = draw(int((kind == k).sum()))
    dx, dp = _tangents(rng, norm, _ratios(rng, size))
    bad = rng.random(size) < 0.03
    dx[bad] = rng.choice([np.inf, -np.inf, np.nan], int(bad.sum()))
    return dx, dp


@needs_glibc
@pytest.mark.parametrize("size", BLOCK_SIZES)
def test_blocks_mixing_every_path(size):
    """Arrays of any length (blocks and chunks not multiples of the vector width), each block
    mixing every path (:func:`_mixed_tangents`); NumPy's bits wherever covered."""
    rng = np.random.default_rng(300 + size)
    dx, dp = _mixed_tangents(rng, size)
    log_stretch = rng.uniform(0.0, 1e5, size)
    got, ok = ftle_like_numpy(dx, dp, log_stretch, 7.0)
    assert np.array_equal(ok, np.isfinite(dx) & np.isfinite(dp))
    _check(got[ok], ok[ok], numpy_ftle(dx, dp, log_stretch, 7.0)[ok], dx[ok], dp[ok])


@needs_glibc_hypot
@pytest.mark.parametrize("size", BLOCK_SIZES)
def test_hypot_blocks_mixing_every_path(size):
    """``hypot`` alone on the same mixed blocks: NumPy's bits wherever both components are finite,
    and ``ok`` false exactly where one is not."""
    dx, dp = _mixed_tangents(np.random.default_rng(300 + size), size)
    got, ok = hypot_like_numpy(dx, dp)
    assert np.array_equal(ok, np.isfinite(dx) & np.isfinite(dp))
    _check(got[ok], ok[ok], np.hypot(dx, dp)[ok], dx[ok], dp[ok])


def test_the_gate_holds_where_the_transcription_comes_from():
    """glibc 2.36 on x86-64 with FMA and AVX2 and a NumPy without its AVX-512 log: the platform
    transcribed, where the gate must hold (elsewhere it may legitimately fail)."""
    features = umath.__cpu_features__
    if not (
        platform.machine() == "x86_64"
        and platform.libc_ver() == ("glibc", "2.36")
        and features.get("FMA3")
        and features.get("AVX2")
        and not features.get("AVX512_SKX")
    ):
        pytest.skip("not glibc 2.36 on an x86-64 CPU with FMA and AVX2 and without AVX-512")
    assert matches_numpy() is True


def test_the_hypot_gate_holds_where_its_transcription_comes_from():
    """NumPy's ``hypot`` is the C library's with or without AVX-512 (only its ``log`` is its own
    there), so on glibc 2.36 for x86-64 the ``hypot`` gate must hold: a transcription broken so that
    it fails would otherwise only skip the tests above."""
    if not (platform.machine() == "x86_64" and platform.libc_ver() == ("glibc", "2.36")):
        pytest.skip("not glibc 2.36 on x86-64")
    assert hypot_matches_numpy() is True


def test_the_gate_is_cached_and_deterministic():
    assert matches_numpy() is matches_numpy()
    first, second = gate_sample(), gate_sample()
    assert all(np.array_equal(a, b) for a, b in zip(first[:3], second[:3], strict=True))
    assert first[0].size > 100_000


def _unfused(name: str) -> str:
    """The transcription with the FMA that defines ``name`` as a product, rounded, then a sum."""
    fma = re.search(rf"const double {name} = __builtin_fma\(([^,]+), ([^,]+), ([^)]+)\);", GLIBC_FTLE_CPP)
    assert fma is not None, name
    a, b, c = fma.groups()
    product = f"const double {name}_product = {a} * {b};\n    const double {name} = {name}_product + {c};"
    return GLIBC_FTLE_CPP.replace(fma.group(0), product)


# One transcription error each, of the kinds a port can make: each FMA of log that changes a
# result left unfused (LOG_HARD_CASES has arguments for each), and hypot without its correction.
PERTURBED = {
    "table log: r = z/c - 1": lambda: _unfused("rt"),
    "near-1 log: B1 + r B2": lambda: _unfused("p12"),
    "near-1 log: (B1 + r B2) + r^2 B3": lambda: _unfused("p123"),
    "near-1 log: r^3 P + lo": lambda: _unfused("near_y"),
    "near-1 log: P = Q r^3 + (B1 + r B2 + r^2 B3)": lambda: _unfused("p1to10"),
    "table log: r^3 q + lo": lambda: _unfused("y"),
    "hypot as a plain sqrt": lambda: GLIBC_FTLE_CPP.replace(
        "const double kernel = h - correction;", "const double kernel = h;"
    ),
}


@pytest.mark.parametrize("perturbation", list(PERTURBED))
def test_the_gate_detects_a_perturbed_transcription(perturbation):
    source = PERTURBED[perturbation]()
    assert source != GLIBC_FTLE_CPP
    assert not agrees(source)


@needs_glibc
def test_the_hard_cases_separate_each_fma():
    """At each of LOG_HARD_CASES, NumPy's log is the transcription's and not that of the
    transcription with the FMA the case was found for left unfused."""
    x = np.array(LOG_HARD_CASES)
    _check(*log_like_numpy(x), np.log(x), x)
    for name in ("rt", "y", "p12", "p123", "near_y", "p1to10"):
        got, _ = log_like_numpy(x, source=_unfused(name))
        assert (got != np.log(x)).any(), name


def test_ftle_like_numpy_keeps_the_shape():
    dx = np.ones((3, 4))
    got, ok = ftle_like_numpy(dx, 0.0, np.zeros((3, 4)), 2.0)
    assert got.shape == ok.shape == (3, 4) and ok.all()
    assert not got.any()
    assert _libm.ftle_like_numpy([], [], [], 1.0)[0].size == 0
