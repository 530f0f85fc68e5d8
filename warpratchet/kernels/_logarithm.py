"""``fdlog``: the project's own natural logarithm, bitwise the same on every body and in NumPy.

The C library's ``log`` is not one function: glibc, CUDA's libdevice and NumPy's SIMD loops round
a few arguments per million differently, and a vectorised ``log`` in the CPU body would be yet
another. The chaos indicators (:mod:`._indicators`) take a logarithm of every point every 8 steps,
so they use this one, written three times operation by operation: the CPU body's lane vectors
(:data:`FDLOG_VECTOR`, C++), the portable body (:func:`fdlog`, plain Warp, what CUDA runs) and
NumPy (:func:`warpratchet.reference.fdlog`). The three are bitwise equal by construction
(``tests/kernels/test_logarithm.py`` checks it on a wide sample and the special values).

Algorithm: fdlibm's ``__ieee754_log`` (Sun Microsystems 1993, ``e_log.c``, as in FreeBSD's msun),
with its coefficients, in one branch-free form:

1. reduction: ``x = 2^k (1 + f)`` with ``1 + f`` in ``[T/2, T)``, ``T = 1 + 0x6a09c/2^20``
   (just below ``sqrt 2``); subnormal ``x`` are first scaled by ``2^54``. This step is exact, so
   each implementation finds ``k`` and ``1 + f`` its own way with the same result: bit fields on
   the CPU (or, with AVX-512 and all lanes positive and finite, ``vgetexppd``/``vgetmantpd``),
   ``numpy.frexp`` in NumPy, comparisons with powers of two in Warp (which has no bit casts);
2. ``s = f/(2 + f)``, ``R(s^2)`` the degree-14 Remez polynomial ``Lg1 s^2 + ... + Lg7 s^14``
   (error below ``2^-58.45``), evaluated as fdlibm does in two halves of even and odd powers of
   ``z = s^2``;
3. ``log x = k ln2_hi - ((hfsq - (s (hfsq + R) + k ln2_lo)) - f)``, ``hfsq = f^2/2``, with
   ``ln2 = ln2_hi + ln2_lo`` (``k ln2_hi`` exact for ``|k| < 2000``).

fdlibm branches to save operations in scalar code: a shortcut for ``|f| < 2^-20``, and the
cheaper ``f - s (f - R)`` in place of step 3 except where ``1 + f`` is near the ends of its
interval. This version always takes step 3, fdlibm's more accurate form (for ``k = 0`` it is
fdlibm's ``f - (hfsq - s (hfsq + R))`` bit for bit), so that vector lanes need no branches.
Measured against the exact logarithm (``numpy.longdouble``) over 6 * 10^6 arguments
(log-uniform in ``[1e-300, 1e300]``, uniform in ``[0.5, 2]`` and in ``1 +- 1e-5``): at most
0.83 ulp (glibc's ``log``: 0.52), within fdlibm's stated bound of 1 ulp; it differs from glibc's
``log`` by one ulp for 1.3e-4 of the wide sample, 7.6% of ``[0.5, 2]``.

Special values, as C99's ``log``: ``log(+-0) = -inf``, ``log(+inf) = +inf``, ``log`` of a
negative number or NaN is NaN (the default quiet NaN, ``0x7ff8000000000000``, in all three).
"""

import warp as wp

__all__ = [
    "LN2_HI",
    "LN2_LO",
    "LG1",
    "LG2",
    "LG3",
    "LG4",
    "LG5",
    "LG6",
    "LG7",
    "REDUCE_ABOVE",
    "SUBNORMAL_SCALE_EXPONENT",
    "fdlog",
    "FDLOG_VECTOR",
]

#: ``ln 2`` split so that ``k * LN2_HI`` is exact for ``|k| < 2000`` (fdlibm's ``ln2_hi, ln2_lo``).
LN2_HI = float.fromhex("0x1.62e42fee00000p-1")
LN2_LO = float.fromhex("0x1.a39ef35793c76p-33")
#: fdlibm's ``Lg1 ... Lg7``: ``log(1+f) = f - hfsq + s (hfsq + R)``, ``R = sum_i Lgi s^(2i)``.
LG1 = float.fromhex("0x1.5555555555593p-1")
LG2 = float.fromhex("0x1.999999997fa04p-2")
LG3 = float.fromhex("0x1.2492494229359p-2")
LG4 = float.fromhex("0x1.c71c51d8e78afp-3")
LG5 = float.fromhex("0x1.7466496cb03dep-3")
LG6 = float.fromhex("0x1.39a09d078c69fp-3")
LG7 = float.fromhex("0x1.2f112df3e5244p-3")
#: ``T``: the reduced argument ``1 + f`` lies in ``[T/2, T)`` (fdlibm's ``0x95f64`` test).
REDUCE_ABOVE = 1.0 + 0x6A09C / 2.0**20
#: Subnormal arguments are scaled by ``2^54`` first (exact), and ``k`` lowered by 54.
SUBNORMAL_SCALE_EXPONENT = 54
_SMALLEST_NORMAL = 2.0**-1022
_SUBNORMAL_SCALE = 2.0**SUBNORMAL_SCALE_EXPONENT
_SUBNORMAL_K = -float(SUBNORMAL_SCALE_EXPONENT)
_REDUCE_BELOW = REDUCE_ABOVE / 2.0
# 2^52 + 1023: the double whose low mantissa bits are a biased exponent field, less the bias.
_EXPONENT_BIAS = 2.0**52 + 1023.0

# Powers of two for the reduction in Warp: after the round with exponent e, x lies in [2^-e, 2^e).
_HALVINGS = (512, 256, 128, 64, 32, 16, 8, 4, 2, 1)
_UP = tuple(2.0**e for e in _HALVINGS)
_DOWN = tuple(2.0**-e for e in _HALVINGS)
_E = tuple(float(e) for e in _HALVINGS)


# -- the portable body (plain Warp, scalar) -------------------------------------------------------
@wp.func
def fdlog(x: wp.float64) -> wp.float64:
    """Natural logarithm of ``x``, fdlibm's algorithm (module docstring); bitwise :data:`FDLOG_VECTOR`."""
    zero = wp.float64(0.0)
    if not (x > zero):
        if x == zero:
            return -wp.float64(wp.inf)
        return wp.float64(wp.nan)  # negative or NaN
    if x == wp.float64(wp.inf):
        return x
    # 1. x = 2^k m, exactly, by comparisons with powers of two (no bit casts in Warp).
    m = x
    k = zero
    if m < wp.float64(_SMALLEST_NORMAL):
        m = m * wp.float64(_SUBNORMAL_SCALE)
        k = wp.float64(_SUBNORMAL_K)
    for i in range(wp.static(len(_HALVINGS))):
        if m >= wp.float64(wp.static(_UP[i])):
            m = m * wp.float64(wp.static(_DOWN[i]))
            k = k + wp.float64(wp.static(_E[i]))
        elif m < wp.float64(wp.static(_DOWN[i])):
            m = m * wp.float64(wp.static(_UP[i]))
            k = k - wp.float64(wp.static(_E[i]))
    # now m in [1/2, 2): bring it into [T/2, T)
    if m >= wp.float64(REDUCE_ABOVE):
        m = m * wp.float64(0.5)
        k = k + wp.float64(1.0)
    elif m < wp.float64(_REDUCE_BELOW):
        m = m * wp.float64(2.0)
        k = k - wp.float64(1.0)
    # 2.-3. the same operations, in the same order, as FDLOG_VECTOR and reference.fdlog
    f = m - wp.float64(1.0)
    s = f / (wp.float64(2.0) + f)
    z = s * s
    w = z * z
    t1 = w * (wp.float64(LG2) + w * (wp.float64(LG4) + w * wp.float64(LG6)))
    t2 = z * (wp.float64(LG1) + w * (wp.float64(LG3) + w * (wp.float64(LG5) + w * wp.float64(LG7))))
    r = t2 + t1
    hfsq = wp.float64(0.5) * f * f
    return k * wp.float64(LN2_HI) - ((hfsq - (s * (hfsq + r) + k * wp.float64(LN2_LO))) - f)


# -- the CPU body (clang vector extensions) -------------------------------------------------------
_HALF = ", ".join(str(i) for i in range(8))
_UPPER = ", ".join(str(i) for i in range(8, 16))
_JOIN = ", ".join(str(i) for i in range(16))

#: C++ for the CPU snippets (after ``step.VECTOR_TYPES``): ``fdlog::run(x)`` on a lane vector
#: ``v_t``. One operation per statement (and ``-ffp-contract=off``), in the order of :func:`fdlog`.
#: The lanes go through in chunks of ``width`` (16 with AVX-512: two 512-bit registers, two
#: independent dependency chains; 8 elsewhere) in a loop that is kept rolled: the constants then
#: stay in registers, and the kernel's own lane vectors spill less around it than when all 32 lanes
#: are computed at once. With AVX-512, when every lane is positive and finite (in the kernels
#: ``dx^2 + dp^2`` of a tangent: in practice always), ``fast`` finds ``k`` and ``m`` with
#: ``vgetexppd`` and ``vgetmantpd`` (exact, subnormals included) and skips the special values'
#: selects: ~34 vector operations per 8 lanes instead of ~50. Without AVX-512, ``fast`` takes
#: lanes that are all normal, positive and finite: the bit fields without the subnormal scaling
#: and the special values, ``k`` as a double from the exponent field. ``chunk`` is the general
#: form (bit fields, every special value), used for every chunk of a call with another lane; the
#: paths give the same bits (``tests/kernels/test_logarithm.py`` checks each). The measurements
#: are in ``benchmarks/README.md``.
FDLOG_VECTOR = f"""
struct fdlog {{
#ifdef __AVX512F__
    enum {{ width = 16 }};  /* lanes per chunk (a local struct has no static data) */
#else
    enum {{ width = 8 }};
#endif
    typedef double c_t __attribute__((ext_vector_type(width)));
    typedef long long ci_t __attribute__((ext_vector_type(width)));
    static_assert(sizeof(v_t) % sizeof(c_t) == 0, "lanes come in whole chunks");
    static inline v_t run(const v_t x) {{
        double in[sizeof(v_t) / sizeof(double)], out[sizeof(v_t) / sizeof(double)];
        __builtin_memcpy(in, &x, sizeof(v_t));
#ifdef __AVX512F__
        const v_t zero = 0.0, inf = __builtin_inf();
        const bool regular = __builtin_reduce_and((x > zero) & (x < inf)) != 0;
#else
        const v_t smallest = {_SMALLEST_NORMAL.hex()}, inf = __builtin_inf();
        const bool regular = __builtin_reduce_and((x >= smallest) & (x < inf)) != 0;
#endif
        #pragma clang loop unroll(disable)
        for (unsigned c = 0; c < sizeof(v_t) / sizeof(c_t); c++) {{
            c_t chunk_in;
            __builtin_memcpy(&chunk_in, in + width * c, sizeof(c_t));
            const c_t chunk_out = regular ? fast(chunk_in) : chunk(chunk_in);
            __builtin_memcpy(out + width * c, &chunk_out, sizeof(c_t));
        }}
        v_t result;
        __builtin_memcpy(&result, out, sizeof(v_t));
        return result;
    }}
#ifdef __AVX512F__
    typedef double h_t __attribute__((ext_vector_type(8)));   /* one 512-bit register */
    typedef double m_t __attribute__((vector_size(64)));      /* the builtins' type */
    /* x = 2^k m0 with m0 in [1, 2), exactly (AVX-512F; subnormal x are normalised) */
    static inline h_t exponent8(const h_t x) {{
        return (h_t)__builtin_ia32_getexppd512_mask((m_t)x, (m_t)x, (unsigned char)0xff, 4);
    }}
    static inline h_t mantissa8(const h_t x) {{
        return (h_t)__builtin_ia32_getmantpd512_mask((m_t)x, 0, (m_t)x, (unsigned char)0xff, 4);
    }}
    /* fdlog of positive finite lanes: chunk() without the bit fields and special values */
    static inline c_t fast(const c_t x) {{
        const h_t x_lo = __builtin_shufflevector(x, x, {_HALF});
        const h_t x_hi = __builtin_shufflevector(x, x, {_UPPER});
        const c_t exponent = __builtin_shufflevector(exponent8(x_lo), exponent8(x_hi), {_JOIN});
        const c_t mantissa = __builtin_shufflevector(mantissa8(x_lo), mantissa8(x_hi), {_JOIN});
        return halved(mantissa, exponent);
    }}
#else
    typedef unsigned long long cu_t __attribute__((ext_vector_type(width)));
    /* fdlog of normal positive finite lanes: chunk() without the subnormal scaling and the special
       values, k from the exponent field as the double 2^52 + e (exact; AVX2 converts no int64) */
    static inline c_t fast(const c_t x) {{
        const cu_t bits = __builtin_bit_cast(cu_t, x);
        const cu_t biased = (bits >> 52) | 0x4330000000000000ULL;
        const c_t exponent = __builtin_bit_cast(c_t, biased) - {_EXPONENT_BIAS.hex()};
        const cu_t mantissa_bits = (bits & 0x000fffffffffffffULL) | 0x3ff0000000000000ULL;
        const c_t mantissa = __builtin_bit_cast(c_t, mantissa_bits);   /* in [1, 2) */
        return halved(mantissa, exponent);
    }}
#endif
    /* fdlog of 2^exponent mantissa, mantissa in [1, 2): into [T/2, T), then steps 2 and 3 */
    static inline c_t halved(const c_t mantissa, const c_t exponent) {{
        const c_t one = 1.0, half = 0.5;
        const auto high = mantissa >= {REDUCE_ABOVE.hex()};
        const c_t half_mantissa = mantissa * half;
        const c_t exponent_up = exponent + one;
        const c_t m = high ? half_mantissa : mantissa;
        const c_t k = high ? exponent_up : exponent;
        return tail(m, k);
    }}
    static inline c_t chunk(const c_t x) {{
        const c_t zero = 0.0, half = 0.5;
        const c_t inf = __builtin_inf(), nan = __builtin_nan("");
        /* 1. x = 2^k m, exactly, from the bit fields */
        const auto subnormal = x < {_SMALLEST_NORMAL.hex()};
        const c_t scaled = x * {_SUBNORMAL_SCALE.hex()};
        const c_t normal = subnormal ? scaled : x;
        const ci_t bits = __builtin_bit_cast(ci_t, normal);
        const ci_t exponent = (bits >> 52) - 1023 - (subnormal & {SUBNORMAL_SCALE_EXPONENT});
        const ci_t mantissa_bits = (bits & 0x000fffffffffffffLL) | 0x3ff0000000000000LL;
        const c_t mantissa = __builtin_bit_cast(c_t, mantissa_bits);   /* in [1, 2) */
        const auto high = mantissa >= {REDUCE_ABOVE.hex()};
        const c_t half_mantissa = mantissa * half;
        const c_t m = high ? half_mantissa : mantissa;
        const ci_t k_int = exponent - high;                             /* high is -1 where set */
        const c_t k = __builtin_convertvector(k_int, c_t);
        const c_t result = tail(m, k);
        /* special values: log(0) = -inf, log(inf) = inf, log(negative or NaN) = NaN */
        const auto regular = (x > zero) & (x < inf);
        const c_t at_zero = x == zero ? -inf : nan;
        const c_t special = x == inf ? inf : at_zero;
        return regular ? result : special;
    }}
    /* steps 2 and 3 from m = 1 + f in [T/2, T) and k */
    static inline c_t tail(const c_t m, const c_t k) {{
        const c_t one = 1.0, half = 0.5, two = 2.0;
        /* 2. s, z = s^2, R(z) in two halves */
        const c_t f = m - one;
        const c_t two_f = two + f;
        const c_t s = f / two_f;
        const c_t z = s * s;
        const c_t w = z * z;
        const c_t t1_6 = w * {LG6.hex()};
        const c_t t1_4 = {LG4.hex()} + t1_6;
        const c_t t1_4w = w * t1_4;
        const c_t t1_2 = {LG2.hex()} + t1_4w;
        const c_t t1 = w * t1_2;
        const c_t t2_7 = w * {LG7.hex()};
        const c_t t2_5 = {LG5.hex()} + t2_7;
        const c_t t2_5w = w * t2_5;
        const c_t t2_3 = {LG3.hex()} + t2_5w;
        const c_t t2_3w = w * t2_3;
        const c_t t2_1 = {LG1.hex()} + t2_3w;
        const c_t t2 = z * t2_1;
        const c_t r = t2 + t1;
        /* 3. k ln2_hi - ((hfsq - (s (hfsq + R) + k ln2_lo)) - f) */
        const c_t half_f = half * f;
        const c_t hfsq = half_f * f;
        const c_t hfsq_r = hfsq + r;
        const c_t s_hfsq_r = s * hfsq_r;
        const c_t k_lo = k * {LN2_LO.hex()};
        const c_t sum_lo = s_hfsq_r + k_lo;
        const c_t diff = hfsq - sum_lo;
        const c_t diff_f = diff - f;
        const c_t k_hi = k * {LN2_HI.hex()};
        return k_hi - diff_f;
    }}
}};
"""
