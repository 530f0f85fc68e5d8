"""``advance_map_indicators``: :data:`~warpratchet.kernels.advance_map` plus MEGNO and the FLI.

The orbit, tangent and log-stretch are bitwise those of ``advance_map`` (the same step loop).
At every global step ``8 j`` that is a multiple of ``RENORM_CHECK_EVERY``, after the
renormalisation check, with ``L_j = ln|v_8j|`` (log-stretch included; ``L_0 = 0`` since
``|v_0| = 1``), computed as ``log_stretch + 0.5 fdlog(dx^2 + dp^2)``:

* ``fli = max(fli, L_j)``: the fast Lyapunov indicator of ``M^8`` (Froeschle et al.);
* MEGNO of ``M^8`` (Cincotta & Simo 2000), ``Y(j) = (2/j) sum_{i<=j} i (L_i - L_{i-1})``,
  summed by parts to ``Y(j) = 2 L_j - (2/j) sum_{i<j} L_i``: ``megno_lsum`` carries
  ``sum_{i<j} L_i`` and ``megno_ysum`` carries ``sum_{i<=j} Y(i)``, so that the mean MEGNO is
  ``<Y>(j) = megno_ysum / j``.

Sampling every 8 steps makes these the indicators of the map ``M^8``, which has the same chaotic
and regular orbits as ``M`` and costs one logarithm per 8 steps instead of one per step.
Checkpoints sit at global step numbers, so chunking does not change the result; the
accumulators must start at zero at global step 0. ``reference.advance_indicators`` is the NumPy
twin, bit for bit.

``fdlog`` is the project's own logarithm (:mod:`._logarithm`), the same bits on the CPU body's
lane vectors, the portable body (CUDA) and in NumPy, and cheaper than the C library's ``log``
lane by lane (the measurements, where the rest of the kernel's time goes, and how the values
moved when it replaced that ``log`` are in ``benchmarks/README.md``).
"""

import warp as wp

from ._advance import Variant, advance_kernel
from ._logarithm import FDLOG_VECTOR, fdlog
from ._step import INTERLEAVE, VECTOR_TYPES, Lanes, LaneVector, load_lane_vector, store_lane_vector

__all__ = ["advance_map_indicators", "INDICATORS", "INDICATOR_FIELDS"]


@wp.struct
class _Arrays:
    fli: wp.array(dtype=wp.float64)
    megno_lsum: wp.array(dtype=wp.float64)
    megno_ysum: wp.array(dtype=wp.float64)


#: The per-point accumulators, in the kernel's argument order: ``fli, megno_lsum, megno_ysum``.
INDICATOR_FIELDS = tuple(_Arrays.vars)


@wp.struct
class _Accumulators:
    fli: LaneVector
    megno_lsum: LaneVector
    megno_ysum: LaneVector


@wp.func
def _load(arrays: _Arrays, first: int, spacing: int, n: int):
    acc = _Accumulators()
    acc.fli = load_lane_vector(arrays.fli, first, spacing, n)
    acc.megno_lsum = load_lane_vector(arrays.megno_lsum, first, spacing, n)
    acc.megno_ysum = load_lane_vector(arrays.megno_ysum, first, spacing, n)
    return acc


@wp.func
def _store(arrays: _Arrays, acc: _Accumulators, first: int, spacing: int, n: int):
    store_lane_vector(arrays.fli, acc.fli, first, spacing, n)
    store_lane_vector(arrays.megno_lsum, acc.megno_lsum, first, spacing, n)
    store_lane_vector(arrays.megno_ysum, acc.megno_ysum, first, spacing, n)


@wp.func
def _nothing(acc: wp.ref[_Accumulators], s: wp.ref[Lanes], global_step: wp.int64):
    pass


@wp.func
def _after_check(acc: wp.ref[_Accumulators], s: wp.ref[Lanes], check: wp.int64):
    j = wp.float64(check)
    half = wp.float64(0.5)
    two = wp.float64(2.0)
    for k in range(wp.static(INTERLEAVE)):
        dx = s.dx[k]
        dp = s.dp[k]
        big_l = s.log_stretch[k] + half * fdlog(dx * dx + dp * dp)
        acc.fli[k] = wp.max(acc.fli[k], big_l)
        acc.megno_ysum[k] = acc.megno_ysum[k] + two * big_l - two * acc.megno_lsum[k] / j
        acc.megno_lsum[k] = acc.megno_lsum[k] + big_l


# The same operations on whole lane vectors, for the CPU body.
_AFTER_CHECK_CPU = (
    VECTOR_TYPES
    + FDLOG_VECTOR
    + """
v_t dx, dp, log_stretch, fli, megno_lsum, megno_ysum;
__builtin_memcpy(&dx, &s.dx, sizeof(v_t));
__builtin_memcpy(&dp, &s.dp, sizeof(v_t));
__builtin_memcpy(&log_stretch, &s.log_stretch, sizeof(v_t));
__builtin_memcpy(&fli, &acc.fli, sizeof(v_t));
__builtin_memcpy(&megno_lsum, &acc.megno_lsum, sizeof(v_t));
__builtin_memcpy(&megno_ysum, &acc.megno_ysum, sizeof(v_t));
const double j = (double)check;
const v_t dx2 = dx * dx;
const v_t dp2 = dp * dp;
const v_t norm2 = dx2 + dp2;
const v_t log_norm2 = fdlog::run(norm2);
const v_t half_log = 0.5 * log_norm2;
const v_t big_l = log_stretch + half_log;
/* wp.max on the CPU: a >= b ? a : (b == b ? b : a) */
fli = (fli >= big_l) ? fli : ((big_l == big_l) ? big_l : fli);
const v_t two_l = 2.0 * big_l;
const v_t y_plus = megno_ysum + two_l;
const v_t two_lsum = 2.0 * megno_lsum;
const v_t lsum_over_j = two_lsum / j;
megno_ysum = y_plus - lsum_over_j;
megno_lsum = megno_lsum + big_l;
__builtin_memcpy(&acc.fli, &fli, sizeof(v_t));
__builtin_memcpy(&acc.megno_lsum, &megno_lsum, sizeof(v_t));
__builtin_memcpy(&acc.megno_ysum, &megno_ysum, sizeof(v_t));
"""
)


@wp.func_native(_AFTER_CHECK_CPU)
def _after_check_cpu(acc: wp.ref[_Accumulators], s: wp.ref[Lanes], check: wp.int64): ...


@wp.struct
class _PointAccumulators:
    fli: wp.float64
    megno_lsum: wp.float64
    megno_ysum: wp.float64


@wp.func
def _point_load(arrays: _Arrays, i: int):
    acc = _PointAccumulators()
    acc.fli = arrays.fli[i]
    acc.megno_lsum = arrays.megno_lsum[i]
    acc.megno_ysum = arrays.megno_ysum[i]
    return acc


@wp.func
def _point_after_check(
    acc: _PointAccumulators, dx: wp.float64, dp: wp.float64, log_stretch: wp.float64, check: wp.int64
):
    # The operations of _after_check for one lane, in the same order (the same bits).
    j = wp.float64(check)
    big_l = log_stretch + wp.float64(0.5) * fdlog(dx * dx + dp * dp)
    out = _PointAccumulators()
    out.fli = wp.max(acc.fli, big_l)
    out.megno_ysum = acc.megno_ysum + wp.float64(2.0) * big_l - wp.float64(2.0) * acc.megno_lsum / j
    out.megno_lsum = acc.megno_lsum + big_l
    return out


@wp.func
def _point_store(arrays: _Arrays, i: int, acc: _PointAccumulators):
    arrays.fli[i] = acc.fli
    arrays.megno_lsum[i] = acc.megno_lsum
    arrays.megno_ysum[i] = acc.megno_ysum


INDICATORS = Variant(
    "map_indicators",
    _Arrays,
    _Accumulators,
    _load,
    _store,
    after_step=None,
    after_check=_after_check,
    cpu_after_check=_after_check_cpu,
    point_load=_point_load,
    point_after_check=_point_after_check,
    point_store=_point_store,
)

#: ``advance_map`` plus the accumulators ``fli, megno_lsum, megno_ysum`` (module docstring);
#: one point per thread off the CPU.
advance_map_indicators = advance_kernel(INDICATORS, one_point=True)
