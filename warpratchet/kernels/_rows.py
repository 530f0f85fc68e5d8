"""``RowPass`` and ``leaf_sums``: a history row's per-point work and sums in CPU kernels, bit for bit
NumPy's.

A row's summary (:func:`warpratchet.observables.summarize_with_variance`) needs, for every point,
the FTLE ``(log_stretch + log(hypot(dx, dp))) / n`` of Eq. (lyap), the gain
``p_n - p_0 = winding + (q - frac(p0))`` and ``A_n = (p_n - p_0)/n`` of Eq. (An), and then the
chaotic points' FTLE and ``A_n`` and the ambiguous points' ``A_n``, each gathered in point order.
In NumPy that is some twenty passes over the ensemble and three boolean gathers; here it is one
pass over each group of the summary's leaves (a group's gathered values stay in the group's own
stretch of the output, so groups run in any order, on any thread). Every value is formed by
the same IEEE operations in the same order as NumPy's (no contraction: ``-ffp-contract=off``), so
the row is the same to the bit. ``leaf_sums`` adds up a leaf as ``np.add.reduce`` does (NumPy's
pairwise order); the leaves' totals are put together in :mod:`warpratchet.observables`.

The FTLE's ``hypot`` and ``log`` are the ones NumPy calls: on a CPU whose NumPy takes them from
glibc, :mod:`._libm`'s transcriptions of glibc's functions, used only where
:func:`._libm.matches_numpy` has found them equal to NumPy's on this machine; elsewhere (another
C library, NumPy's own SIMD ``log``) NumPy's ``log(hypot(dx, dp))`` is computed before the pass
(the ``hypot`` in a kernel where that is NumPy's), and the pass adds the log-stretch and divides
as NumPy does; or, where that ``hypot`` is not NumPy's, NumPy's FTLE itself. A point the
transcription does not cover (a non-finite tangent) is reported, and its group is left to NumPy.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import os
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import warp as wp

from ..observables import _buffer, _lyapunov_into
from . import _libm
from ._libm import GLIBC_FTLE_CPP, matches_numpy
from ._runtime import CPU_MODULE_OPTIONS, arrays_struct, init_warp

__all__ = ["ROW_FIELDS", "SUM_TERMS", "RowPass", "leaf_sums", "lyapunov_into", "row_pass_available"]

#: The state fields a row reads (:data:`warpratchet.state.STATE_FIELDS` less ``x``).
ROW_FIELDS = ("winding", "q", "p0", "dx", "dp", "log_stretch")

#: A group's status bits: a value not finite (the summary is NumPy's, which says which), and a
#: point whose FTLE the transcribed functions do not cover (the group is NumPy's).
NOT_FINITE = 1
NOT_COVERED = 2
# Points per block of the pass (two blocks of values stay in L1).
BLOCK = 256

_MODULE = "warpratchet.kernels.rows"


# ``ftle`` empty: computed in the pass
RowInputs = arrays_struct(
    "RowInputs",
    {"winding": wp.int64, **dict.fromkeys(("q", "p0", "dx", "dp", "log_stretch", "ftle"), wp.float64)},
)
RowOutputs = arrays_struct(
    "RowOutputs",
    {
        **dict.fromkeys(("gain", "chaotic_ftle", "chaotic_acc", "ambiguous_acc"), wp.float64),
        **dict.fromkeys(("chaotic_count", "ambiguous_count"), wp.int64),
        "least": wp.float64,
        "status": wp.int32,
        "gain_sums": wp.float64,
    },
)


# NumPy's ``np.add.reduce`` of a contiguous float64 array, operation by operation: the identity
# 0.0 plus the pairwise sum of numpy/_core/src/umath/loops_utils.h.src (blocks of at most 128
# values in 8 accumulators, longer stretches halved at a multiple of 8). ``mode`` 1 sums
# ``(v - center)^2`` and 2 sums ``|v - center|``, each term rounded as NumPy's
# ``subtract``/``multiply``/``absolute`` round it before the sum.
_TERMS_CPU = {
    "value": "v",
    "square": "((v - center) * (v - center))",
    "absolute": "__builtin_elementwise_abs(v - center)",
}


def _pairwise_source(term: str, expression: str) -> str:
    # One function per term, so that the mode is no branch in the loops. The 8 accumulators are
    # two vectors of 4 (accumulator j is lane j % 4 of vector j / 4), each lane adding what its
    # accumulator adds, in its order; the expressions work on a double or a vector alike.
    # ``(v - center) * (v - center)`` is one subtraction rounded, then its square: NumPy's order.
    return f"""
static double {term}(const double* a, wp::int64 n, double center) {{
    if (n < 8) {{
        double res = 0.0;
        for (wp::int64 i = 0; i < n; ++i) {{ const double v = a[i]; res += {expression}; }}
        return res;
    }}
    if (n <= 128) {{
        typedef double lanes __attribute__((ext_vector_type(4)));
        lanes v, r0, r1;
        __builtin_memcpy(&v, a, sizeof(lanes));
        r0 = {expression};
        __builtin_memcpy(&v, a + 4, sizeof(lanes));
        r1 = {expression};
        wp::int64 i = 8;
        for (; i < n - (n % 8); i += 8) {{
            __builtin_memcpy(&v, a + i, sizeof(lanes));
            r0 += {expression};
            __builtin_memcpy(&v, a + i + 4, sizeof(lanes));
            r1 += {expression};
        }}
        double res = ((r0[0] + r0[1]) + (r0[2] + r0[3])) + ((r1[0] + r1[1]) + (r1[2] + r1[3]));
        for (; i < n; ++i) {{ const double v = a[i]; res += {expression}; }}
        return res;
    }}
    wp::int64 n2 = n / 2;
    n2 -= n2 % 8;
    const double left = {term}(a, n2, center);
    const double right = {term}(a + n2, n - n2, center);
    return left + right;
}}
"""


_PAIRWISE_CPU = (
    "struct numpy_sum {\n"
    + "".join(_pairwise_source(term, expression) for term, expression in _TERMS_CPU.items())
    + "};\n"
)


# A group of points, a block at a time: first every point's values, in a loop without branches
# that clang vectorises; then the gathers, where each value is written at the next free index of
# the group's stretch whether it is kept or not (the index moves on only if it is): no branch on
# the data, and the write never passes the point being read, so no group touches another's.
_GROUP_CPU = (
    GLIBC_FTLE_CPP
    + _PAIRWISE_CPU
    + f"""
const int leaves = (int)(bounds.shape[0] - 1);
const double step = row.step;
const double threshold = row.threshold;
const double low = row.low;
const double high = row.high;
const wp::int64 lo = bounds.data[0];
const bool given = inputs.ftle.shape[0] != 0;
const wp::int64* winding = inputs.winding.data;
const double* q = inputs.q.data;
const double* p0 = inputs.p0.data;
const double* dx = inputs.dx.data;
const double* dp = inputs.dp.data;
const double* log_stretch = inputs.log_stretch.data;
double* gain = outputs.gain.data;
double* chaotic_ftle = outputs.chaotic_ftle.data;
double* chaotic_acc = outputs.chaotic_acc.data;
double* ambiguous_acc = outputs.ambiguous_acc.data;
wp::int64 m = lo;
wp::int64 k = lo;
double least = INFINITY;
int status = 0;
double f_block[{BLOCK}], a_block[{BLOCK}], w_block[{BLOCK}];
for (int leaf = 0; leaf < leaves; ++leaf) {{
const wp::int64 hi = bounds.data[leaf + 1];
for (wp::int64 first = bounds.data[leaf]; first < hi; first += {BLOCK}) {{
    const int size = (int)(hi - first < {BLOCK} ? hi - first : {BLOCK});
    int covered = 1;
    if (given && row.log_norm) {{
        /* given log(hypot(dx, dp)): NumPy's sum with the log-stretch, then its division */
        const double* __restrict ls = log_stretch + first;
        const double* __restrict ln = inputs.ftle.data + first;
        for (int j = 0; j < size; ++j) {{
            const double sum = ls[j] + ln[j];
            f_block[j] = sum / step;
        }}
    }} else if (given) {{
        __builtin_memcpy(f_block, inputs.ftle.data + first, size * sizeof(double));
    }} else {{
        covered = glibc_ftle_block(dx + first, dp + first, log_stretch + first, step, f_block, size);
    }}
    if (!covered) status |= {NOT_COVERED};
    /* winding as a double: exact for any |w| < 2^53; where every |w| < 2^51 (momenta below
       ~2 x 10^15), as (2^52 + 2^51 + w) - (2^52 + 2^51), exact too, and in vectors without
       AVX-512's int64 conversion */
    wp::uint64 spread = 0;
    for (int j = 0; j < size; ++j) spread |= (wp::uint64)(winding[first + j] + (1LL << 51));
    if (spread >> 52) {{
        for (int j = 0; j < size; ++j) w_block[j] = (double)winding[first + j];
    }} else {{
        for (int j = 0; j < size; ++j) {{
            const wp::int64 bits = winding[first + j] + 0x4338000000000000LL;
            w_block[j] = __builtin_bit_cast(double, bits) - 6755399441055744.0;
        }}
    }}
    const double* __restrict pb = p0 + first;
    const double* __restrict qb = q + first;
    double* __restrict gb = gain + first;
    const double* __restrict fb = f_block;
    double* __restrict ab = a_block;
    const double* __restrict wb = w_block;
    for (int j = 0; j < size; ++j) {{
        /* momentum_gain's operations, in its order */
        const double p = pb[j];
        const double frac = p - __builtin_floor(p);
        const double rest = qb[j] - frac;
        const double g = wb[j] + rest;
        gb[j] = g;
        ab[j] = g / step;
    }}
    /* finite: x - x is 0 for a finite x, NaN otherwise; the least chaotic FTLE in four chains
       (no value is NaN where every value is finite, and the result is used only then) */
    int bad = 0;
    double l0 = INFINITY, l1 = INFINITY, l2 = INFINITY, l3 = INFINITY;
    int j = 0;
    for (; j + 4 <= size; j += 4) {{
        for (int u = 0; u < 4; ++u) {{
            const double f = fb[j + u];
            const double a = ab[j + u];
            bad |= (int)!((f - f) == 0.0) | (int)!((a - a) == 0.0);
        }}
        const double f0 = fb[j] > threshold ? fb[j] : INFINITY;
        const double f1 = fb[j + 1] > threshold ? fb[j + 1] : INFINITY;
        const double f2 = fb[j + 2] > threshold ? fb[j + 2] : INFINITY;
        const double f3 = fb[j + 3] > threshold ? fb[j + 3] : INFINITY;
        l0 = f0 < l0 ? f0 : l0;
        l1 = f1 < l1 ? f1 : l1;
        l2 = f2 < l2 ? f2 : l2;
        l3 = f3 < l3 ? f3 : l3;
    }}
    for (; j < size; ++j) {{
        const double f = fb[j];
        const double a = ab[j];
        bad |= (int)!((f - f) == 0.0) | (int)!((a - a) == 0.0);
        const double c = f > threshold ? f : INFINITY;
        l0 = c < l0 ? c : l0;
    }}
    if (bad) status |= {NOT_FINITE};
    l0 = l1 < l0 ? l1 : l0;
    l2 = l3 < l2 ? l3 : l2;
    l0 = l2 < l0 ? l2 : l0;
    least = l0 < least ? l0 : least;
    double* __restrict c_ftle = chaotic_ftle;
    double* __restrict c_acc = chaotic_acc;
    double* __restrict a_acc = ambiguous_acc;
    int j0 = 0;
#if defined(__AVX512F__)
    /* eight points at a time: the kept values compressed to the front of a register, in order,
       and the whole register stored at the next free index (its other lanes are overwritten by the
       next values kept, or lie past the last); never past the points read, so inside the group */
    {{
        typedef double d8 __attribute__((ext_vector_type(8)));
        typedef bool b8 __attribute__((ext_vector_type(8)));
        const d8 zero8 = 0.0;
        for (; j0 + 8 <= size; j0 += 8) {{
            d8 f8, a8;
            __builtin_memcpy(&f8, fb + j0, sizeof(d8));
            __builtin_memcpy(&a8, ab + j0, sizeof(d8));
            const b8 above = __builtin_convertvector(f8 > threshold, b8);
            const b8 inside = __builtin_convertvector((f8 > low) & (f8 < high), b8);
            const unsigned char chaotic = __builtin_bit_cast(unsigned char, above);
            const unsigned char band = __builtin_bit_cast(unsigned char, inside);
            const d8 kept_f = __builtin_ia32_compressdf512_mask(f8, zero8, chaotic);
            const d8 kept_a = __builtin_ia32_compressdf512_mask(a8, zero8, chaotic);
            const d8 kept_b = __builtin_ia32_compressdf512_mask(a8, zero8, band);
            __builtin_memcpy(c_ftle + m, &kept_f, sizeof(d8));
            __builtin_memcpy(c_acc + m, &kept_a, sizeof(d8));
            __builtin_memcpy(a_acc + k, &kept_b, sizeof(d8));
            m += __builtin_popcount(chaotic);
            k += __builtin_popcount(band);
        }}
    }}
#endif
    for (int j = j0; j < size; ++j) {{
        const double f = fb[j];
        const double a = ab[j];
        c_ftle[m] = f;
        c_acc[m] = a;
        m += f > threshold ? 1 : 0;
        a_acc[k] = a;
        k += ((f > low) & (f < high)) ? 1 : 0;
    }}
}}
/* the leaf's gains are still in cache: their sum, as np.add.reduce gives it */
const wp::int64 leaf_lo = bounds.data[leaf];
outputs.gain_sums.data[leaf] = 0.0 + numpy_sum::value(gain + leaf_lo, hi - leaf_lo, 0.0);
}}
outputs.chaotic_count.data[0] = m - lo;
outputs.ambiguous_count.data[0] = k - lo;
outputs.least.data[0] = least;
outputs.status.data[0] = status;
"""
)


@wp.struct
class RowScalars:
    step: wp.float64
    threshold: wp.float64
    low: wp.float64
    high: wp.float64
    log_norm: wp.int32  # 1: the given array holds log(hypot(dx, dp)), not the FTLE


@wp.func_native(_GROUP_CPU)
def _group_cpu(inputs: RowInputs, outputs: RowOutputs, bounds: wp.array(dtype=wp.int64), row: RowScalars): ...


def _row_kernel(inputs: RowInputs, outputs: RowOutputs, bounds: wp.array(dtype=wp.int64), row: RowScalars):
    _group_cpu(inputs, outputs, bounds, row)


wp.set_module_options(CPU_MODULE_OPTIONS, _MODULE)
_row = wp.kernel(_row_kernel, name="row_pass", module=_MODULE)


def _wrap(values: np.ndarray, dtype: Any) -> wp.array:
    return wp.array(values, dtype=dtype, device="cpu", copy=False)


@wp.func_native(
    _PAIRWISE_CPU
    + """
const wp::int64 lo = bounds.data[leaf];
const wp::int64 hi = bounds.data[leaf + 1];
const double* a = values.data + lo;
const double total = mode == 0 ? numpy_sum::value(a, hi - lo, center)
                   : mode == 1 ? numpy_sum::square(a, hi - lo, center)
                               : numpy_sum::absolute(a, hi - lo, center);
sums.data[leaf] = 0.0 + total;
"""
)
def _leaf_sum_cpu(
    values: wp.array(dtype=wp.float64),
    bounds: wp.array(dtype=wp.int64),
    sums: wp.array(dtype=wp.float64),
    leaf: int,
    center: wp.float64,
    mode: int,
): ...


def _leaf_sums_kernel(
    values: wp.array(dtype=wp.float64),
    bounds: wp.array(dtype=wp.int64),
    sums: wp.array(dtype=wp.float64),
    center: wp.float64,
    mode: int,
):
    _leaf_sum_cpu(values, bounds, sums, wp.tid(), center, mode)


_leaf_sums = wp.kernel(_leaf_sums_kernel, name="leaf_sums", module=_MODULE)

#: The terms :func:`leaf_sums` adds up.
SUM_TERMS = tuple(_TERMS_CPU)


def leaf_sums(
    values: np.ndarray, leaves: list[tuple[int, int]], term: str = "value", center: float = 0.0
) -> np.ndarray:
    """``np.add.reduce`` of each leaf ``values[lo:hi]`` (contiguous float64) of ``leaves``, bit for bit,
    or of ``(values[lo:hi] - center)**2`` (``term="square"``) or ``abs(values[lo:hi] - center)``
    (``"absolute"``) as NumPy's ``subtract``, ``multiply`` / ``absolute`` and ``add.reduce`` give
    them, without the temporary arrays. Returns an array of the sums, shape ``(len(leaves),)``."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    bounds = np.array([lo for lo, _ in leaves] + [leaves[-1][1]] if leaves else [0], dtype=np.int64)
    if leaves and any(a[1] != b[0] for a, b in zip(leaves[:-1], leaves[1:], strict=True)):
        raise ValueError("leaves must be consecutive stretches (lo, hi) of the values")
    sums = np.empty(len(leaves))
    if leaves:
        init_warp()
        args = [_wrap(values, wp.float64), _wrap(bounds, wp.int64), _wrap(sums, wp.float64)]
        wp.launch(
            _leaf_sums, dim=len(leaves), inputs=[*args, float(center), SUM_TERMS.index(term)], device="cpu"
        )
    return sums


_verdicts: dict[str, bool] = {}  # the gates' verdicts in this process
_verdicts_lock = threading.Lock()


def _gate_key() -> str | None:
    """What the gate's verdict depends on, hashed: the transcription and its sample (``_libm``'s
    source), the libm and NumPy binaries this process loaded, the CPU (glibc and NumPy choose
    their code by its features), Warp and the compiler flags. None where it cannot be known."""
    try:
        with open("/proc/self/maps") as maps:
            loaded = sorted(
                {line.split()[-1] for line in maps if "/libm" in line or "_multiarray_umath" in line}
            )
        with open("/proc/cpuinfo") as cpuinfo:
            cpu = [
                line for line in itertools.islice(cpuinfo, 64) if line.startswith(("model name", "flags"))
            ][:2]
        with open(_libm.__file__, "rb") as source:
            parts = [hashlib.sha256(source.read()).hexdigest(), wp.config.version, CPU_MODULE_OPTIONS, *cpu]
        for path in loaded:
            info = os.stat(path)
            parts.append((path, info.st_size, info.st_mtime_ns))
    except (OSError, IndexError):
        return None
    if not any("/libm" in path for path in loaded) or len(cpu) < 2:
        return None
    return hashlib.sha256(repr(parts).encode()).hexdigest()[:32]


def _gate_verdict(name: str, check: Callable[[], bool]) -> bool:
    """``check()`` (a gate of :mod:`._libm`), kept in Warp's kernel cache under ``name`` and
    :func:`_gate_key`, and in this process: a gate compares a few hundred thousand arguments with
    NumPy, and the same binaries on the same CPU give the same verdict."""
    with _verdicts_lock:
        if name in _verdicts:
            return _verdicts[name]
        init_warp()
        key = _gate_key()
        cache = wp.config.kernel_cache_dir or ""
        path = None if key is None else os.path.join(cache, f"warpratchet-{name}-{key}")
        verdict = None
        if path is not None and os.path.isfile(path):
            with contextlib.suppress(OSError):
                with open(path) as kept:
                    verdict = {"True": True, "False": False}.get(kept.read())
        if verdict is None:
            verdict = bool(check())
            if path is not None:
                with contextlib.suppress(OSError):  # a cache that cannot be written is only slower
                    partial = f"{path}.{os.getpid()}.tmp"
                    with open(partial, "w") as kept:
                        kept.write(str(verdict))
                    os.replace(partial, path)
        _verdicts[name] = verdict
        return verdict


def row_pass_available() -> bool:
    """Whether :class:`RowPass` computes the FTLE in its kernel here (:func:`._libm.matches_numpy`);
    known once per process (and per machine: :func:`_gate_verdict`). Without it a row pass takes
    NumPy's own FTLE, made just before its kernel pass."""
    return _gate_verdict("libm", matches_numpy)


def row_hypot_available() -> bool:
    """Whether the kernels' ``hypot`` gives NumPy's bits here (:func:`._libm.hypot_matches_numpy`),
    known as :func:`row_pass_available` is."""
    return _gate_verdict("hypot", _libm.hypot_matches_numpy)


def numpy_log_norm_into(state: dict[str, np.ndarray], lo: int, hi: int, out: np.ndarray) -> bool:
    """NumPy's ``log(hypot(dx, dp))`` of the points ``lo:hi`` of ``state`` into ``out`` (contiguous),
    with the ``hypot`` in a kernel, where that is NumPy's here (:func:`row_hypot_available`:
    the costlier of the two, the C library's scalar function called point by point); False, and
    ``out`` meaningless, where it is not, or where a tangent is not finite."""
    if row_hypot_available() and _libm.hypot_into(state["dx"][lo:hi], state["dp"][lo:hi], out):
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            np.log(out, out=out)
        return True
    return False


def numpy_ftle_into(state: dict[str, np.ndarray], step: int, lo: int, hi: int, out: np.ndarray) -> np.ndarray:
    """NumPy's FTLE of the points ``lo:hi`` of ``state`` into ``out`` (contiguous), its operations in
    its order (:func:`warpratchet.observables._lyapunov_into`), the ``log(hypot)`` by
    :func:`numpy_log_norm_into` where it can."""
    if numpy_log_norm_into(state, lo, hi, out):
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            np.add(state["log_stretch"][lo:hi], out, out=out)
            return np.divide(out, step, out=out)
    return _lyapunov_into(state, step, lo, hi, out)


def lyapunov_into(state: dict[str, np.ndarray], step: int, lo: int, hi: int, out: np.ndarray) -> np.ndarray:
    """:func:`warpratchet.observables.lyapunov` of the points ``lo:hi`` of ``state`` into ``out``
    (contiguous, shape ``(hi - lo,)``), bit for bit: in a kernel where its ``hypot`` and ``log`` are
    NumPy's here (:func:`row_pass_available`), else, and for a stretch with a tangent that is not
    finite, with NumPy's own functions."""
    if row_pass_available():
        x = {name: state[name][lo:hi] for name in ("dx", "dp", "log_stretch")}
        _, ok = _libm.ftle_like_numpy(x["dx"], x["dp"], x["log_stretch"], float(step), out=out)
        if ok.all():
            return out
    return numpy_ftle_into(state, step, lo, hi, out)


class RowPass:
    """The per-point pass of one history row over a state's arrays (module docstring).

    Parameters
    ----------
    state : dict of ndarray, shape (points,) each
        At least :data:`ROW_FIELDS`, contiguous host arrays (an ensemble's zero-copy views).
    ftle : ndarray, shape (points,), optional
        Every point's FTLE if known already; else computed here: in the kernel where its functions
        are NumPy's (:func:`row_pass_available`), else with NumPy's own functions, a group at a
        time just before the kernel's pass over it.
    buffers : dict, optional
        Where the pass's output arrays are kept for the next pass of this size or smaller (the
        caller's; a summary's chunks share them).

    Calling it with a group of consecutive leaves ``[(lo, hi), ...]`` of the summary's tree, the
    row's ``step`` (n >= 1), ``threshold`` and the ambiguity band ``(low, high)`` fills the group's
    stretch of ``gain`` and returns, for the group, the chaotic points' FTLE and ``A_n`` and the
    ambiguous points' ``A_n`` (each a list of one array, in point order), the least chaotic FTLE
    (inf if none), whether every value was finite, and each leaf's ``np.add.reduce`` of its
    gains (``leaf -> sum``); or None where a point's FTLE is not covered (the caller computes
    that group itself). Groups may run at once on different threads.
    """

    def __init__(
        self, state: dict[str, np.ndarray], ftle: np.ndarray | None = None, buffers: dict | None = None
    ) -> None:
        n = len(state["p0"])
        self.points = n
        self.inputs = RowInputs()
        for name in ROW_FIELDS:
            dtype = wp.int64 if name == "winding" else wp.float64
            setattr(self.inputs, name, _wrap(np.ascontiguousarray(state[name]), dtype))
        buffers = {} if buffers is None else buffers
        # kept at the largest size asked for: a summary's chunks differ in size
        self.buffers = {
            name: _buffer(buffers, f"row pass {name}", n)
            for name in ("chaotic_ftle", "chaotic_acc", "ambiguous_acc")
        }
        # Where the kernel's hypot and log would not be NumPy's, NumPy's log(hypot) (or its FTLE) is
        # computed in this pass's own buffer group by group (__call__), and the kernel takes it.
        self.state = state
        self.own_ftle = ftle is None and not row_pass_available()
        if self.own_ftle:
            ftle = self.ftle = _buffer(buffers, "row pass ftle", n)
        empty = np.empty(0) if ftle is None else np.ascontiguousarray(ftle, dtype=np.float64)
        self.inputs.ftle = _wrap(empty, wp.float64)

    def __call__(
        self,
        group: list[tuple[int, int]],
        gain: np.ndarray,
        step: int,
        threshold: float,
        low: float,
        high: float,
    ) -> tuple | None:
        lo, hi = group[0][0], group[-1][1]
        log_norm = 0
        if self.own_ftle:
            # the sum and the division in the kernel's pass (NumPy's operations), else NumPy's FTLE
            log_norm = int(numpy_log_norm_into(self.state, lo, hi, self.ftle[lo:hi]))
            if not log_norm:
                _lyapunov_into(self.state, step, lo, hi, self.ftle[lo:hi])
        counts = np.zeros(2, dtype=np.int64)
        least = np.empty(1)
        status = np.zeros(1, dtype=np.int32)
        outputs = RowOutputs()
        outputs.gain = _wrap(gain, wp.float64)
        for name, values in self.buffers.items():
            setattr(outputs, name, _wrap(values, wp.float64))
        outputs.chaotic_count = _wrap(counts[:1], wp.int64)
        outputs.ambiguous_count = _wrap(counts[1:], wp.int64)
        outputs.least = _wrap(least, wp.float64)
        outputs.status = _wrap(status, wp.int32)
        gain_sums = np.empty(len(group))
        outputs.gain_sums = _wrap(gain_sums, wp.float64)
        bounds = _wrap(np.array([lo for lo, _ in group] + [hi], dtype=np.int64), wp.int64)
        row = RowScalars()
        row.step, row.threshold, row.low, row.high = float(step), float(threshold), float(low), float(high)
        row.log_norm = log_norm
        args = [self.inputs, outputs, bounds, row]
        wp.launch(_row, dim=1, inputs=args, device="cpu")
        if status[0] & NOT_COVERED:
            return None
        chaotic, ambiguous = (int(c) for c in counts)
        return (
            [self.buffers["chaotic_ftle"][lo : lo + chaotic]],
            [self.buffers["chaotic_acc"][lo : lo + chaotic]],
            [self.buffers["ambiguous_acc"][lo : lo + ambiguous]],
            float(least[0]),
            not status[0] & NOT_FINITE,
            dict(zip(group, gain_sums, strict=True)),
        )
