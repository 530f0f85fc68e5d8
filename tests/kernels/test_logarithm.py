"""``fdlog``, the project's own logarithm: accuracy, special values, and its three twins bit for bit.

The NumPy version (``warpratchet.reference.fdlog``) is measured against the exact logarithm
(``numpy.longdouble``, 64-bit significand: its own error is ~2^-11 of a float64 ulp) and against
the C library's (``math.log``); the CPU body's lane-vector version and the portable Warp version
(what CUDA runs) must equal it bit for bit on the same arguments.
"""

import math

import numpy as np
import pytest
import warp as wp

from warpratchet import kernels, reference
from warpratchet.kernels._logarithm import FDLOG_VECTOR, fdlog
from warpratchet.kernels._runtime import CPU_MODULE_OPTIONS, MODULE_OPTIONS
from warpratchet.kernels._step import (
    INTERLEAVE,
    VECTOR_TYPES,
    LaneVector,
    load_lane_vector,
    store_lane_vector,
)

kernels.init_warp()
BODIES = [  # (step body, device)
    pytest.param("cpu", "cpu", id="cpu-body"),
    pytest.param("portable", "cpu", id="portable-body-cpu"),
    pytest.param(
        "portable",
        "cuda:0",
        id="portable-body-cuda",
        marks=pytest.mark.skipif(not wp.is_cuda_available(), reason="no CUDA device on this machine"),
    ),
]

SPECIAL = np.array(
    [0.0, -0.0, -1.0, -np.inf, np.inf, np.nan, 1.0, 2.0, 0.5, 5e-324, 2.0**-1022, np.finfo(np.float64).max]
)


def _sample(n: int = 400_000, seed: int = 0) -> np.ndarray:
    """Log-uniform over [1e-300, 1e300] (the range the kernels can meet), uniform in [0.5, 2]
    (k = 0 and +-1, where log is near 0 and hardest), uniform in 1 +- 1e-5, subnormals, and
    every power of two (the reduction's edges)."""
    rng = np.random.default_rng(seed)
    return np.concatenate(
        [
            np.exp(rng.uniform(math.log(1e-300), math.log(1e300), n)),
            rng.uniform(0.5, 2.0, n),
            1.0 + rng.uniform(-1e-5, 1e-5, n // 4),
            rng.uniform(0.0, 1.0, 1000) * 2.0**-1022,
            np.ldexp(1.0, np.arange(-1074, 1024)),
        ]
    )


def _ulps(got: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """|got - exact| in units of the last place of the float64 nearest to ``exact``."""
    unit = np.spacing(np.abs(exact.astype(np.float64))).astype(np.longdouble)
    return np.abs((got.astype(np.longdouble) - exact) / unit).astype(np.float64)


@pytest.mark.skipif(
    np.finfo(np.longdouble).nmant < 63, reason="numpy.longdouble is not 80-bit here: no exact reference"
)
def test_fdlog_is_within_one_ulp_of_the_exact_logarithm():
    """fdlibm's bound (< 1 ulp); measured 0.83 ulp at most, glibc's log 0.52 (kernels/_logarithm.py)."""
    x = _sample()
    exact = np.log(x.astype(np.longdouble))
    errors = _ulps(reference.fdlog(x), exact)
    assert errors.max() < 1.0, f"max error {errors.max():.3f} ulp at x = {x[errors.argmax()]!r}"


def test_fdlog_is_the_c_librarys_log_to_one_ulp():
    """Both within 1 ulp of the exact value, so at most one representable number apart."""
    x = _sample(100_000)
    got = reference.fdlog(x)
    libm = np.array([math.log(value) for value in x])
    apart = np.abs(got - libm) / np.spacing(np.abs(libm))
    assert apart.max() <= 1.0


def test_fdlog_special_values():
    got = reference.fdlog(SPECIAL)
    assert got[0] == -np.inf and got[1] == -np.inf  # log(+-0)
    assert np.isnan(got[2]) and np.isnan(got[3]) and np.isnan(got[5])  # negative, -inf, NaN
    assert got[4] == np.inf
    assert got[6] == 0.0 and not np.signbit(got[6])  # log(1) = +0 exactly
    assert got[7] == -got[8] == math.log(2.0)
    assert got[9] == math.log(5e-324) and got[10] == math.log(2.0**-1022)  # subnormal, smallest normal
    assert got[11] == math.log(np.finfo(np.float64).max)


# The kernels' two versions, each applied to an array.
@wp.func_native(
    VECTOR_TYPES
    + FDLOG_VECTOR
    + """
v_t x;
__builtin_memcpy(&x, &v, sizeof(v_t));
const v_t y = fdlog::run(x);
__builtin_memcpy(&v, &y, sizeof(v_t));
"""
)
def _fdlog_lanes(v: wp.ref[LaneVector]): ...


def _log_lanes(x: wp.array(dtype=wp.float64), out: wp.array(dtype=wp.float64)):
    first = wp.tid() * wp.static(INTERLEAVE)
    v = load_lane_vector(x, first, 1, x.shape[0])
    _fdlog_lanes(v)
    store_lane_vector(out, v, first, 1, x.shape[0])


def _log_points(x: wp.array(dtype=wp.float64), out: wp.array(dtype=wp.float64)):
    i = wp.tid()
    out[i] = fdlog(x[i])


wp.set_module_options(CPU_MODULE_OPTIONS, "test_logarithm.cpu")
wp.set_module_options(MODULE_OPTIONS, "test_logarithm.portable")
_LANES = wp.kernel(_log_lanes, module="test_logarithm.cpu")
_POINTS = wp.kernel(_log_points, module="test_logarithm.portable")
# The CPU body's general form, as a CPU without AVX-512 compiles it (this machine may have it).
_NO_AVX512_OPTIONS = {**CPU_MODULE_OPTIONS}
_NO_AVX512_OPTIONS["cpu_compiler_flags"] += " -target-feature -avx512f"
wp.set_module_options(_NO_AVX512_OPTIONS, "test_logarithm.cpu_no_avx512")
_LANES_NO_AVX512 = wp.kernel(_log_lanes, module="test_logarithm.cpu_no_avx512")


@pytest.mark.parametrize(("body", "device"), BODIES)
def test_kernel_fdlog_equals_numpy_bit_for_bit(body, device):
    """The CPU body's lane vectors and the portable Warp function give reference.fdlog's bits.

    A NaN result (negative, -inf or NaN argument) must be a NaN, with any payload: IEEE 754 leaves
    the payload and sign of a generated NaN to the machine (x86's has the sign bit set, CUDA's
    ``wp.float64(wp.nan)`` widens float32's 0x7fffffff), and the kernels never take the log of
    anything but a tangent norm above 1e100. Every other result must match bit for bit.
    """
    x = np.concatenate([_sample(200_000, seed=1), SPECIAL])
    source = wp.array(x, dtype=wp.float64, device=device)
    out = wp.zeros_like(source)
    if body == "cpu":
        wp.launch(_LANES, dim=kernels.launch_dim(x.size), inputs=[source, out], device=device)
    else:
        wp.launch(_POINTS, dim=x.size, inputs=[source, out], device=device)
    got, expected = out.numpy(), reference.fdlog(x)
    nan = np.isnan(expected)
    assert np.count_nonzero(nan) == 3 and np.array_equal(np.isnan(got), nan)  # -1, -inf, NaN
    mismatched = np.flatnonzero((got.view(np.int64) != expected.view(np.int64)) & ~nan)
    assert mismatched.size == 0, f"{mismatched.size} differ, first at x = {x[mismatched[0]]!r}"


def _with_a_special_lane_per_thread(x: np.ndarray) -> np.ndarray:
    """``x`` with a NaN, 0 or inf before every INTERLEAVE - 1 of its values: each Warp thread's
    lanes then hold a special value, so the CPU body takes its general path for all of them."""
    groups = -(-x.size // (INTERLEAVE - 1))
    padded = np.concatenate([x, np.ones(groups * (INTERLEAVE - 1) - x.size)]).reshape(groups, -1)
    specials = np.resize(np.array([np.nan, 0.0, np.inf, -1.0]), (groups, 1))
    return np.concatenate([specials, padded], axis=1).ravel()


@pytest.mark.parametrize(
    ("kernel", "special_lanes"),
    [
        pytest.param(_LANES, True, id="general-form"),
        pytest.param(_LANES_NO_AVX512, False, id="without-avx512"),
    ],
)
def test_cpu_fdlog_general_form_equals_numpy_bit_for_bit(kernel, special_lanes):
    """The CPU body computes lanes that are all positive and finite (all normal, without AVX-512)
    by a shorter path; its general form (a call with a special lane) gives the same bits, and so
    do both paths as a CPU without AVX-512 compiles them (the sample mixes normal and subnormal
    arguments, so some threads take each path there)."""
    x = np.concatenate([_sample(100_000, seed=2), SPECIAL])
    if special_lanes:
        x = _with_a_special_lane_per_thread(x)
    source = wp.array(x, dtype=wp.float64, device="cpu")
    out = wp.zeros_like(source)
    wp.launch(kernel, dim=kernels.launch_dim(x.size), inputs=[source, out], device="cpu")
    got, expected = out.numpy(), reference.fdlog(x)
    mismatched = np.flatnonzero(got.view(np.int64) != expected.view(np.int64))
    assert mismatched.size == 0, f"{mismatched.size} differ, first at x = {x[mismatched[0]]!r}"
