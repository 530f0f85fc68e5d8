"""The C library's ``hypot`` and ``log`` as NumPy calls them here, transcribed for the CPU kernels.

The history rows report each point's finite-time Lyapunov exponent as NumPy computes it,
``(log_stretch + log(hypot(dx, dp))) / step``, and must keep those bits when the computation moves
into a kernel. NumPy's ``hypot`` and (on a CPU without AVX-512) ``log`` are the C library's scalar
functions, so a kernel reproduces them only by doing what that library does, operation by
operation, FMAs included. :data:`GLIBC_FTLE_CPP` is that transcription, of glibc 2.35+ for
x86-64 as NumPy's manylinux wheels call it on an x86-64 CPU with FMA and AVX2:

* ``hypot``: ``sysdeps/ieee754/dbl-64/e_hypot.c`` (the 2021 rewrite, glibc 2.35), built without
  FMA (its ``kernel`` takes the non-FMA branch: ``h = sqrt(ax^2 + ay^2)`` and one correction
  step whose formula depends on ``h <= 2 ay``), with its scaling of large (``ax > 2^511``) and
  tiny (``ay < 2^-459``) arguments and its ``ax + ay`` shortcut where ``ay <= ax 2^-54``;
* ``log``: ``sysdeps/ieee754/dbl-64/e_log.c`` (ARM's optimized-routines logarithm, a 128-entry
  table ``__log_data.tab`` of ``1/c, log c`` pairs and a degree-6 polynomial; a degree-12
  polynomial with a split ``r = rhi + rlo`` for ``|x - 1| < 0.0625``), in the variant that the
  ifunc selects on FMA CPUs (``__log_fma``, built with ``-mfma``): the compiler contracted some of
  the source's ``a*b + c`` into FMAs and left others, so the transcription writes
  ``__builtin_fma`` exactly where that machine code has ``vfmadd``/``vfnmadd`` and plain
  operations elsewhere (the kernels compile with ``-ffp-contract=off``). The table and the
  coefficients are the library's own bits.

Both are branch-free (every path computed, the result selected), so that a loop over points can
be vectorised. The kernels take the FTLE of a block of points with ``glibc_ftle_block``, in
passes over chunks of ``CHUNK`` points that clang vectorises 4 wide (8 with AVX-512) and
whose short bodies let the processor overlap one vector's latency with the next: ``hypot``'s
common case (neither scaled nor negligible) on every point; a count of the norms on ``log``'s
near-1 path; the path most of the chunk takes (the table path, its lookups per-lane loads, or
the near-1 polynomial) on every point, with the sum and the division; the other path on the
remaining points, gathered into a buffer. ``hypot`` in full where it scales or meets a
non-finite component, and ``log`` in full at a zero, subnormal or infinite norm (only such points
have one), run only for the points that need them. Every point's bits are those of the
branch-free functions. Non-finite ``dx`` or ``dp`` are not transcribed: ``glibc_ftle_point`` and
``glibc_ftle_block`` report them (their result ``false``) for the caller to take NumPy's value
instead; every other argument, ``log``'s zero, subnormal and infinite ones included, gives
NumPy's bits.

Another machine may call other functions: NumPy on a CPU with AVX-512 has its own vectorised
``log``, an older glibc another ``hypot``, another C library other code again. There the
transcription is merely close, so callers first ask :func:`matches_numpy`, which compares the
kernel with NumPy bit for bit on a fixed sample chosen to separate the variants (both paths of
``log`` and the boundary between them, every table interval, ``hypot``'s two correction
formulas, its shortcut and its scaled ranges), and fall back to NumPy where it answers ``False``.
``tests/kernels/test_libm.py`` checks the transcription on more than 10^7 arguments and that the
gate's sample tells apart transcriptions with one FMA fewer (:data:`LOG_HARD_CASES`: most of
``log``'s FMAs change no result a sample can find, and their placement rests on reading the
library's machine code) or without ``hypot``'s correction.
"""

import functools

import numpy as np
import warp as wp

from ..observables import lyapunov
from ._runtime import CPU_MODULE_OPTIONS, arrays_struct, check_cpu_isa_runs, init_warp

__all__ = [
    "GLIBC_FTLE_CPP",
    "LOG_HARD_CASES",
    "LOG_TABLE",
    "ftle_like_numpy",
    "hypot_into",
    "hypot_like_numpy",
    "hypot_matches_numpy",
    "log_like_numpy",
    "matches_numpy",
]

#: glibc's ``__log_data.tab``: for each of the 128 intervals of ``[0x1.6p-1, 0x1.6p0)``, ``1/c``
#: and ``log c`` for a ``c`` near its centre (the bits of the library's table).
LOG_TABLE = tuple(
    (float.fromhex(invc), float.fromhex(logc))
    for invc, logc in (
        ("0x1.734f0c3e0de9fp+0", "-0x1.7cc7f79e69000p-2"),
        ("0x1.713786a2ce91fp+0", "-0x1.76feec20d0000p-2"),
        ("0x1.6f26008fab5a0p+0", "-0x1.713e31351e000p-2"),
        ("0x1.6d1a61f138c7dp+0", "-0x1.6b85b38287800p-2"),
        ("0x1.6b1490bc5b4d1p+0", "-0x1.65d5590807800p-2"),
        ("0x1.69147332f0cbap+0", "-0x1.602d076180000p-2"),
        ("0x1.6719f18224223p+0", "-0x1.5a8ca86909000p-2"),
        ("0x1.6524f99a51ed9p+0", "-0x1.54f4356035000p-2"),
        ("0x1.63356aa8f24c4p+0", "-0x1.4f637c36b4000p-2"),
        ("0x1.614b36b9ddc14p+0", "-0x1.49da7fda85000p-2"),
        ("0x1.5f66452c65c4cp+0", "-0x1.445923989a800p-2"),
        ("0x1.5d867b5912c4fp+0", "-0x1.3edf439b0b800p-2"),
        ("0x1.5babccb5b90dep+0", "-0x1.396ce448f7000p-2"),
        ("0x1.59d61f2d91a78p+0", "-0x1.3401e17bda000p-2"),
        ("0x1.5805612465687p+0", "-0x1.2e9e2ef468000p-2"),
        ("0x1.56397cee76bd3p+0", "-0x1.2941b3830e000p-2"),
        ("0x1.54725e2a77f93p+0", "-0x1.23ec58cda8800p-2"),
        ("0x1.52aff42064583p+0", "-0x1.1e9e129279000p-2"),
        ("0x1.50f22dbb2bddfp+0", "-0x1.1956d2b48f800p-2"),
        ("0x1.4f38f4734ded7p+0", "-0x1.141679ab9f800p-2"),
        ("0x1.4d843cfde2840p+0", "-0x1.0edd094ef9800p-2"),
        ("0x1.4bd3ec078a3c8p+0", "-0x1.09aa518db1000p-2"),
        ("0x1.4a27fc3e0258ap+0", "-0x1.047e65263b800p-2"),
        ("0x1.4880524d48434p+0", "-0x1.feb224586f000p-3"),
        ("0x1.46dce1b192d0bp+0", "-0x1.f474a7517b000p-3"),
        ("0x1.453d9d3391854p+0", "-0x1.ea4443d103000p-3"),
        ("0x1.43a2744b4845ap+0", "-0x1.e020d44e9b000p-3"),
        ("0x1.420b54115f8fbp+0", "-0x1.d60a22977f000p-3"),
        ("0x1.40782da3ef4b1p+0", "-0x1.cc00104959000p-3"),
        ("0x1.3ee8f5d57fe8fp+0", "-0x1.c202956891000p-3"),
        ("0x1.3d5d9a00b4ce9p+0", "-0x1.b81178d811000p-3"),
        ("0x1.3bd60c010c12bp+0", "-0x1.ae2c9ccd3d000p-3"),
        ("0x1.3a5242b75dab8p+0", "-0x1.a45402e129000p-3"),
        ("0x1.38d22cd9fd002p+0", "-0x1.9a877681df000p-3"),
        ("0x1.3755bc5847a1cp+0", "-0x1.90c6d69483000p-3"),
        ("0x1.35dce49ad36e2p+0", "-0x1.87120a645c000p-3"),
        ("0x1.34679984dd440p+0", "-0x1.7d68fb4143000p-3"),
        ("0x1.32f5cceffcb24p+0", "-0x1.73cb83c627000p-3"),
        ("0x1.3187775a10d49p+0", "-0x1.6a39a9b376000p-3"),
        ("0x1.301c8373e3990p+0", "-0x1.60b3154b7a000p-3"),
        ("0x1.2eb4ebb95f841p+0", "-0x1.5737d76243000p-3"),
        ("0x1.2d50a0219a9d1p+0", "-0x1.4dc7b8fc23000p-3"),
        ("0x1.2bef9a8b7fd2ap+0", "-0x1.4462c51d20000p-3"),
        ("0x1.2a91c7a0c1babp+0", "-0x1.3b08abc830000p-3"),
        ("0x1.293726014b530p+0", "-0x1.31b996b490000p-3"),
        ("0x1.27dfa5757a1f5p+0", "-0x1.2875490a44000p-3"),
        ("0x1.268b39b1d3bbfp+0", "-0x1.1f3b9f879a000p-3"),
        ("0x1.2539d838ff5bdp+0", "-0x1.160c8252ca000p-3"),
        ("0x1.23eb7aac9083bp+0", "-0x1.0ce7f57f72000p-3"),
        ("0x1.22a012ba940b6p+0", "-0x1.03cdc49fea000p-3"),
        ("0x1.2157996cc4132p+0", "-0x1.f57bdbc4b8000p-4"),
        ("0x1.201201dd2fc9bp+0", "-0x1.e370896404000p-4"),
        ("0x1.1ecf4494d480bp+0", "-0x1.d17983ef94000p-4"),
        ("0x1.1d8f5528f6569p+0", "-0x1.bf9674ed8a000p-4"),
        ("0x1.1c52311577e7cp+0", "-0x1.adc79202f6000p-4"),
        ("0x1.1b17c74cb26e9p+0", "-0x1.9c0c3e7288000p-4"),
        ("0x1.19e010c2c1ab6p+0", "-0x1.8a646b372c000p-4"),
        ("0x1.18ab07bb670bdp+0", "-0x1.78d01b3ac0000p-4"),
        ("0x1.1778a25efbcb6p+0", "-0x1.674f145380000p-4"),
        ("0x1.1648d354c31dap+0", "-0x1.55e0e6d878000p-4"),
        ("0x1.151b990275fddp+0", "-0x1.4485cdea1e000p-4"),
        ("0x1.13f0ea432d24cp+0", "-0x1.333d94d6aa000p-4"),
        ("0x1.12c8b7210f9dap+0", "-0x1.22079f8c56000p-4"),
        ("0x1.11a3028ecb531p+0", "-0x1.10e4698622000p-4"),
        ("0x1.107fbda8434afp+0", "-0x1.ffa6c6ad20000p-5"),
        ("0x1.0f5ee0f4e6bb3p+0", "-0x1.dda8d4a774000p-5"),
        ("0x1.0e4065d2a9fcep+0", "-0x1.bbcece4850000p-5"),
        ("0x1.0d244632ca521p+0", "-0x1.9a1894012c000p-5"),
        ("0x1.0c0a77ce2981ap+0", "-0x1.788583302c000p-5"),
        ("0x1.0af2f83c636d1p+0", "-0x1.5715e67d68000p-5"),
        ("0x1.09ddb98a01339p+0", "-0x1.35c8a49658000p-5"),
        ("0x1.08cabaf52e7dfp+0", "-0x1.149e364154000p-5"),
        ("0x1.07b9f2f4e28fbp+0", "-0x1.e72c082eb8000p-6"),
        ("0x1.06ab58c358f19p+0", "-0x1.a55f152528000p-6"),
        ("0x1.059eea5ecf92cp+0", "-0x1.63d62cf818000p-6"),
        ("0x1.04949cdd12c90p+0", "-0x1.228fb8caa0000p-6"),
        ("0x1.038c6c6f0ada9p+0", "-0x1.c317b20f90000p-7"),
        ("0x1.02865137932a9p+0", "-0x1.419355daa0000p-7"),
        ("0x1.0182427ea7348p+0", "-0x1.81203c2ec0000p-8"),
        ("0x1.008040614b195p+0", "-0x1.0040979240000p-9"),
        ("0x1.fe01ff726fa1ap-1", "0x1.feff384900000p-9"),
        ("0x1.fa11cc261ea74p-1", "0x1.7dc41353d0000p-7"),
        ("0x1.f6310b081992ep-1", "0x1.3cea3c4c28000p-6"),
        ("0x1.f25f63ceeadcdp-1", "0x1.b9fc114890000p-6"),
        ("0x1.ee9c8039113e7p-1", "0x1.1b0d8ce110000p-5"),
        ("0x1.eae8078cbb1abp-1", "0x1.58a5bd001c000p-5"),
        ("0x1.e741aa29d0c9bp-1", "0x1.95c8340d88000p-5"),
        ("0x1.e3a91830a99b5p-1", "0x1.d276aef578000p-5"),
        ("0x1.e01e009609a56p-1", "0x1.07598e598c000p-4"),
        ("0x1.dca01e577bb98p-1", "0x1.253f5e30d2000p-4"),
        ("0x1.d92f20b7c9103p-1", "0x1.42edd8b380000p-4"),
        ("0x1.d5cac66fb5ccep-1", "0x1.606598757c000p-4"),
        ("0x1.d272caa5ede9dp-1", "0x1.7da76356a0000p-4"),
        ("0x1.cf26e3e6b2ccdp-1", "0x1.9ab434e1c6000p-4"),
        ("0x1.cbe6da2a77902p-1", "0x1.b78c7bb0d6000p-4"),
        ("0x1.c8b266d37086dp-1", "0x1.d431332e72000p-4"),
        ("0x1.c5894bd5d5804p-1", "0x1.f0a3171de6000p-4"),
        ("0x1.c26b533bb9f8cp-1", "0x1.067152b914000p-3"),
        ("0x1.bf583eeece73fp-1", "0x1.147858292b000p-3"),
        ("0x1.bc4fd75db96c1p-1", "0x1.2266ecdca3000p-3"),
        ("0x1.b951e0c864a28p-1", "0x1.303d7a6c55000p-3"),
        ("0x1.b65e2c5ef3e2cp-1", "0x1.3dfc33c331000p-3"),
        ("0x1.b374867c9888bp-1", "0x1.4ba366b7a8000p-3"),
        ("0x1.b094b211d304ap-1", "0x1.5933928d1f000p-3"),
        ("0x1.adbe885f2ef7ep-1", "0x1.66acd2418f000p-3"),
        ("0x1.aaf1d31603da2p-1", "0x1.740f8ec669000p-3"),
        ("0x1.a82e63fd358a7p-1", "0x1.815c0f51af000p-3"),
        ("0x1.a5740ef09738bp-1", "0x1.8e92954f68000p-3"),
        ("0x1.a2c2a90ab4b27p-1", "0x1.9bb3602f84000p-3"),
        ("0x1.a01a01393f2d1p-1", "0x1.a8bed1c2c0000p-3"),
        ("0x1.9d79f24db3c1bp-1", "0x1.b5b515c01d000p-3"),
        ("0x1.9ae2505c7b190p-1", "0x1.c2967ccbcc000p-3"),
        ("0x1.9852ef297ce2fp-1", "0x1.cf635d5486000p-3"),
        ("0x1.95cbaeea44b75p-1", "0x1.dc1bd3446c000p-3"),
        ("0x1.934c69de74838p-1", "0x1.e8c01b8cfe000p-3"),
        ("0x1.90d4f2f6752e6p-1", "0x1.f5509c0179000p-3"),
        ("0x1.8e6528effd79dp-1", "0x1.00e6c121fb800p-2"),
        ("0x1.8bfce9fcc007cp-1", "0x1.071b80e93d000p-2"),
        ("0x1.899c0dabec30ep-1", "0x1.0d46b9e867000p-2"),
        ("0x1.87427aa2317fbp-1", "0x1.13687334bd000p-2"),
        ("0x1.84f00acb39a08p-1", "0x1.1980d67234800p-2"),
        ("0x1.82a49e8653e55p-1", "0x1.1f8ffe0cc8000p-2"),
        ("0x1.8060195f40260p-1", "0x1.2595fd7636800p-2"),
        ("0x1.7e22563e0a329p-1", "0x1.2b9300914a800p-2"),
        ("0x1.7beb377dcb5adp-1", "0x1.3187210436000p-2"),
        ("0x1.79baa679725c2p-1", "0x1.377266dec1800p-2"),
        ("0x1.77907f2170657p-1", "0x1.3d54ffbaf3000p-2"),
        ("0x1.756cadbd6130cp-1", "0x1.432eee32fe000p-2"),
    )
)

#: ``log``'s ``ln 2`` split (``Ln2hi`` with 11 trailing zero bits, so ``k Ln2hi`` is exact) and its
#: polynomials: ``LOG_A`` for the table path (``A[0..4]``), ``LOG_B`` near 1 (``B[0..10]``).
LOG_LN2 = (float.fromhex("0x1.62e42fefa3800p-1"), float.fromhex("0x1.ef35793c76730p-45"))
LOG_A = tuple(
    float.fromhex(c)
    for c in (
        "-0x1.0000000000001p-1",
        "0x1.555555551305bp-2",
        "-0x1.fffffffeb4590p-3",
        "0x1.999b324f10111p-3",
        "-0x1.55575e506c89fp-3",
    )
)
LOG_B = tuple(
    float.fromhex(c)
    for c in (
        "-0x1.0000000000000p-1",
        "0x1.5555555555577p-2",
        "-0x1.ffffffffffdcbp-3",
        "0x1.999999995dd0cp-3",
        "-0x1.55555556745a7p-3",
        "0x1.24924a344de30p-3",
        "-0x1.fffffa4423d65p-4",
        "0x1.c7184282ad6cap-4",
        "-0x1.999eb43b068ffp-4",
        "0x1.78182f7afd085p-4",
        "-0x1.5521375d145cdp-4",
    )
)
_TABLE_CPP = ",\n    ".join(f"{invc.hex()}, {logc.hex()}" for invc, logc in LOG_TABLE)
_A = [c.hex() for c in LOG_A]
_B = [c.hex() for c in LOG_B]
#: Points per pass of ``glibc_ftle_block`` (its buffers stay in L1).
CHUNK = 256

#: C++ statements for the start of a ``wp.func_native`` body (lambdas and a constant table):
#:
#: * ``double glibc_hypot(double x, double y)``: glibc's ``hypot`` of finite ``x, y``;
#: * ``double glibc_log(double x)``: glibc's ``__log_fma`` of ``x >= 0`` (``+0`` gives ``-inf``,
#:   ``+inf`` gives ``+inf``, subnormals included); a negative or NaN ``x`` gives a NaN;
#: * ``bool glibc_ftle_point(double dx, double dp, double log_stretch, double step, double* out)``:
#:   ``*out = (log_stretch + log(hypot(dx, dp))) / step`` in NumPy's order of operations; ``false``
#:   (and ``*out`` meaningless) where ``dx`` or ``dp`` is not finite;
#: * ``bool glibc_ftle_block(const double* dx, const double* dp, const double* log_stretch,
#:   double step, double* out, int n)``: ``glibc_ftle_point`` of ``n`` points (the arrays must not
#:   overlap ``out``), faster; ``true`` iff every ``dx`` and ``dp`` is finite.
#:
#: Each statement is one rounding, in the order of glibc's machine code; ``__builtin_fma`` marks
#: where that code fuses a product into a sum.
GLIBC_FTLE_CPP = f"""
static const double glibc_log_table[256] = {{
    {_TABLE_CPP}
}};
auto glibc_hypot_kernel = [](const double a, const double b) -> double {{
    /* e_hypot.c's kernel(a, b) without FMA, a >= b >= 0 (neither scaled nor negligible) */
    const double a2 = a * a;
    const double b2 = b * b;
    const double h2 = a2 + b2;
    const double h = __builtin_sqrt(h2);
    const double two_b = b + b;
    const bool near = h <= two_b;
    /* h <= 2 b: t1 = a (2 d - a), t2 = (d - 2 (a - b)) d, d = h - b */
    const double d_near = h - b;
    const double two_d_near = d_near + d_near;
    const double t1_near_a = two_d_near - a;
    const double t1_near = t1_near_a * a;
    const double a_b = a - b;
    const double two_a_b = a_b + a_b;
    const double t2_near_d = d_near - two_a_b;
    const double t2_near = t2_near_d * d_near;
    /* else: t1 = 2 d (a - 2 b), t2 = (4 d - b) b + d^2, d = h - a */
    const double d_far = h - a;
    const double two_d_far = d_far + d_far;
    const double a_2b = a - two_b;
    const double t1_far = two_d_far * a_2b;
    const double four_d = 4.0 * d_far;
    const double d_far2 = d_far * d_far;
    const double four_d_b = four_d - b;
    const double t2_far_b = four_d_b * b;
    const double t2_far = t2_far_b + d_far2;
    const double t1 = near ? t1_near : t1_far;
    const double t2 = near ? t2_near : t2_far;
    const double t = t1 + t2;
    const double two_h = h + h;
    const double correction = t / two_h;
    const double kernel = h - correction;
    return kernel;
}};
auto glibc_hypot = [&](const double x, const double y) -> double {{
    /* e_hypot.c: ax >= ay; scaled by 2^-600 where ax > 2^511, by 2^600 where ay < 2^-459 */
    const double abs_x = __builtin_fabs(x), abs_y = __builtin_fabs(y);
    const bool swap = abs_y > abs_x;
    const double ax = swap ? abs_y : abs_x;
    const double ay = swap ? abs_x : abs_y;
    const bool large = ax > 0x1p511;
    const bool tiny = ay < 0x1p-459;
    const double eps_ax = ax * 0x1p-54;
    const double ay_over_eps = ay * 0x1p54;
    const bool negligible = large ? (ay <= eps_ax) : (tiny ? (ax >= ay_over_eps) : (ay <= eps_ax));
    const double sum = ax + ay;
    const double scale_in = large ? 0x1p-600 : (tiny ? 0x1p600 : 1.0);
    const double scale_out = large ? 0x1p600 : (tiny ? 0x1p-600 : 1.0);
    const double a = ax * scale_in;
    const double b = ay * scale_in;
    const double scaled = glibc_hypot_kernel(a, b) * scale_out;
    return negligible ? sum : scaled;
}};
typedef unsigned long long glibc_u64;
auto glibc_log_near_one = [](const double x) -> double {{
    /* |x - 1| < ~0.06: log1p's polynomial, r split into rhi + rlo */
    const double r = x - 1.0;
    const double p12 = __builtin_fma(r, {_B[2]}, {_B[1]});
    const double p45 = __builtin_fma(r, {_B[5]}, {_B[4]});
    const double p78 = __builtin_fma(r, {_B[8]}, {_B[7]});
    const double r2 = r * r;
    const double p123 = __builtin_fma(r2, {_B[3]}, p12);
    const double p456 = __builtin_fma(r2, {_B[6]}, p45);
    const double r3 = r * r2;
    const double p789 = __builtin_fma(r2, {_B[9]}, p78);
    const double p7to10 = __builtin_fma(r3, {_B[10]}, p789);
    const double p4to10 = __builtin_fma(p7to10, r3, p456);
    const double p1to10 = __builtin_fma(p4to10, r3, p123);
    const double r_w = __builtin_fma(r, 0x1p27, r);
    const double rhi = __builtin_fma(-0x1p27, r, r_w);
    const double rhi2 = rhi * rhi;
    const double rlo = r - rhi;
    const double near_hi = __builtin_fma(rhi2, {_B[0]}, r);
    const double r_hi = r - near_hi;
    const double near_lo0 = __builtin_fma(rhi2, {_B[0]}, r_hi);
    const double r_rhi = r + rhi;
    const double b0_rlo = {_B[0]} * rlo;
    const double near_lo = __builtin_fma(b0_rlo, r_rhi, near_lo0);
    const double near_y = __builtin_fma(p1to10, r3, near_lo);
    const double near_one = near_hi + near_y;
    return near_one;
}};
auto glibc_log_general = [](const glibc_u64 iy) -> double {{
    typedef glibc_u64 u64;
    /* elsewhere: x = 2^k z, z in [0x1.6p-1, 0x1.6p0), log x = k ln2 + log c + log1p(z/c - 1);
       iy is x's bits (a subnormal x's after scaling by 2^52) */
    const u64 tmp = iy - 0x3fe6000000000000ULL;
    const unsigned i = (unsigned)(tmp >> 45) & 127u;
    const double kd = (double)((long long)tmp >> 52);
    const double z = __builtin_bit_cast(double, iy - (tmp & 0xfff0000000000000ULL));
    const double invc = glibc_log_table[2 * i];
    const double logc = glibc_log_table[2 * i + 1];
    const double rt = __builtin_fma(z, invc, -1.0);
    const double w = __builtin_fma(kd, {LOG_LN2[0].hex()}, logc);
    const double hi = w + rt;
    const double w_hi = w - hi;
    const double w_hi_r = w_hi + rt;
    const double lo = __builtin_fma(kd, {LOG_LN2[1].hex()}, w_hi_r);
    const double rt2 = rt * rt;
    const double q12 = __builtin_fma(rt, {_A[2]}, {_A[1]});
    const double rt3 = rt * rt2;
    const double q34 = __builtin_fma(rt, {_A[4]}, {_A[3]});
    const double lo_a0 = __builtin_fma(rt2, {_A[0]}, lo);
    const double q1to4 = __builtin_fma(q34, rt2, q12);
    const double y = __builtin_fma(rt3, q1to4, lo_a0);
    const double general = y + hi;
    return general;
}};
auto glibc_log_near_path = [](const double x) -> bool {{
    /* glibc's test ix - 0x3fee000000000000 < 0x3090000000000 on x's bits ix, as doubles */
    return (x >= 0x1.ep-1) & (x < 0x1.109p0);
}};
auto glibc_log = [&](const double x) -> double {{
    typedef glibc_u64 u64;
    const u64 ix = __builtin_bit_cast(u64, x);
    const double near_one = glibc_log_near_one(x);
    /* a subnormal x is scaled by 2^52 first */
    const u64 scaled_bits = __builtin_bit_cast(u64, x * 0x1p52) - (52ULL << 52);
    const bool subnormal = (x > 0.0) & (x < 0x1p-1022);
    const u64 iy = subnormal ? scaled_bits : ix;
    const double general = glibc_log_general(iy);
    /* which path; then log(1) = +0 and the special values */
    const bool near_path = glibc_log_near_path(x);
    const double value = near_path ? near_one : general;
    const double one = ix == 0x3ff0000000000000ULL ? 0.0 : value;
    const bool regular = (x >= 0x1p-1074) & (x <= 0x1.fffffffffffffp1023);
    const double special = x == 0.0 ? -__builtin_inf() : (x > 0.0 ? x : __builtin_nan(""));
    return regular ? one : special;
}};
auto glibc_ftle_point = [&](const double dx, const double dp, const double log_stretch,
                            const double step, double* out) -> bool {{
    const double h = glibc_hypot(dx, dp);
    const double log_h = glibc_log(h);
    const double sum = log_stretch + log_h;
    *out = sum / step;
    const double finite = 0x1.fffffffffffffp1023;
    return (__builtin_fabs(dx) <= finite) & (__builtin_fabs(dp) <= finite);
}};
auto glibc_hypot_common = [](const double abs_x, const double abs_y) -> bool {{
    /* hypot neither scales (both components in [2^-459, 2^511]) nor meets a NaN */
    return (abs_x <= 0x1p511) & (abs_y <= 0x1p511) & (abs_x >= 0x1p-459) & (abs_y >= 0x1p-459);
}};
auto glibc_ftle_block = [&](const double* __restrict dx, const double* __restrict dp,
                            const double* __restrict log_stretch, const double step,
                            double* __restrict out, const int n) -> bool {{
    /* the passes count points (clang vectorises a sum, not an &= of comparisons) */
    const double finite = 0x1.fffffffffffffp1023;
    double h[{CHUNK}], rest_x[{CHUNK}], rest_f[{CHUNK}];
    int rest_at[{CHUNK}];
    int uncovered = 0;
    for (int first = 0; first < n; first += {CHUNK}) {{
        const int size = n - first < {CHUNK} ? n - first : {CHUNK};
        const double* x = dx + first;
        const double* y = dp + first;
        const double* ls = log_stretch + first;
        double* f = out + first;
        /* hypot's common case for every point; the others again, in full */
        int unusual = 0, irregular = 0;
#pragma clang loop interleave_count(2)
        for (int j = 0; j < size; ++j) {{
            const double abs_x = __builtin_fabs(x[j]), abs_y = __builtin_fabs(y[j]);
            const bool swap = abs_y > abs_x;
            const double ax = swap ? abs_y : abs_x;
            const double ay = swap ? abs_x : abs_y;
            const double eps_ax = ax * 0x1p-54;
            const double sum = ax + ay;
            const double kernel = glibc_hypot_kernel(ax, ay);
            h[j] = ay <= eps_ax ? sum : kernel;
            unusual += !((ax <= 0x1p511) & (ay >= 0x1p-459));
        }}
        if (unusual) {{
            /* a non-finite component is one of these; so is every zero, subnormal or infinite norm
               (the common case's norms lie in [2^-459, 2^512)) */
            for (int j = 0; j < size; ++j) {{
                const double abs_x = __builtin_fabs(x[j]), abs_y = __builtin_fabs(y[j]);
                if (!glibc_hypot_common(abs_x, abs_y)) h[j] = glibc_hypot(x[j], y[j]);
                uncovered += !((abs_x <= finite) & (abs_y <= finite));
                irregular += !((h[j] >= 0x1p-1022) & (h[j] <= finite));
            }}
        }}
        /* log: the path most of the block takes on every point, the other on the rest, gathered;
           zero, subnormal and non-finite norms again, in full */
        long long near = 0;
        for (int j = 0; j < size; ++j) near += glibc_log_near_path(h[j]);
        const bool mostly_near = 2 * near > size;
        int m = 0;
        if (near != (mostly_near ? size : 0)) {{
            for (int j = 0; j < size; ++j) {{
                rest_at[m] = j;
                rest_x[m] = h[j];
                m += glibc_log_near_path(h[j]) != mostly_near;
            }}
        }}
        if (mostly_near) {{
#pragma clang loop interleave_count(2)
            for (int j = 0; j < size; ++j) {{
                const double log_h = h[j] == 1.0 ? 0.0 : glibc_log_near_one(h[j]);
                const double sum = ls[j] + log_h;
                f[j] = sum / step;
            }}
            for (int k = 0; k < m; ++k) {{
                const double log_h = glibc_log_general(__builtin_bit_cast(glibc_u64, rest_x[k]));
                const double sum = ls[rest_at[k]] + log_h;
                rest_f[k] = sum / step;
            }}
        }} else {{
#pragma clang loop interleave_count(2)
            for (int j = 0; j < size; ++j) {{
                const double log_h = glibc_log_general(__builtin_bit_cast(glibc_u64, h[j]));
                const double sum = ls[j] + log_h;
                f[j] = sum / step;
            }}
            for (int k = 0; k < m; ++k) {{
                const double log_h = rest_x[k] == 1.0 ? 0.0 : glibc_log_near_one(rest_x[k]);
                const double sum = ls[rest_at[k]] + log_h;
                rest_f[k] = sum / step;
            }}
        }}
        for (int k = 0; k < m; ++k) f[rest_at[k]] = rest_f[k];
        if (irregular) {{
            for (int j = 0; j < size; ++j) {{
                if (!((h[j] >= 0x1p-1022) & (h[j] <= finite))) {{
                    const double sum = ls[j] + glibc_log(h[j]);
                    f[j] = sum / step;
                }}
            }}
        }}
    }}
    return uncovered == 0;
}};
"""

#: Points per kernel thread: the thread's loop over them is what clang vectorises.
BLOCK = 1024
#: What the array kernel computes: the composite, ``hypot`` alone or ``log`` alone.
FTLE, HYPOT, LOG = 0, 1, 2

_KERNELS: dict[str, wp.Kernel] = {}


_Arrays = arrays_struct("_Arrays", {**dict.fromkeys(("a", "b", "c", "out"), wp.float64), "ok": wp.uint8})


def _kernel(source: str) -> wp.Kernel:
    """The array kernel of ``source`` (:data:`GLIBC_FTLE_CPP` or, in tests, a variant of it)."""
    kernel = _KERNELS.get(source)
    if kernel is not None:
        return kernel
    tag = f"{len(_KERNELS)}"
    body = (
        source
        + f"""
const long long count = arrays.a.shape[0];
const long long first = (long long)block * {BLOCK};
const long long last = first + {BLOCK} < count ? first + {BLOCK} : count;
const double* a = arrays.a.data;
const double* b = arrays.b.data;
const double* c = arrays.c.data;
double* out = arrays.out.data;
unsigned char* ok = arrays.ok.data;
const double step_value = step;
const double finite = 0x1.fffffffffffffp1023;
if (quantity == {FTLE}) {{
    glibc_ftle_block(a + first, b + first, c + first, step_value, out + first, (int)(last - first));
    for (long long i = first; i < last; i++) {{
        ok[i] = (__builtin_fabs(a[i]) <= finite) & (__builtin_fabs(b[i]) <= finite);
    }}
}} else for (long long i = first; i < last; i++) {{
    double value;
    bool good;
    if (quantity == {HYPOT}) {{
        value = glibc_hypot(a[i], b[i]);
        good = (__builtin_fabs(a[i]) <= finite) & (__builtin_fabs(b[i]) <= finite);
    }} else {{
        value = glibc_log(a[i]);
        good = a[i] >= 0.0;
    }}
    out[i] = value;
    ok[i] = good;
}}
"""
    )

    def block_native(arrays: _Arrays, step: wp.float64, quantity: wp.int32, block: wp.int64): ...

    block_native.__qualname__ = f"_glibc_block_{tag}"
    native = wp.func_native(body)(block_native)

    def glibc_blocks(arrays: _Arrays, step: wp.float64, quantity: wp.int32):
        native(arrays, step, quantity, wp.int64(wp.tid()))

    module = f"warpratchet.kernels.libm_{tag}"
    wp.set_module_options(CPU_MODULE_OPTIONS, module)
    kernel = wp.kernel(glibc_blocks, name=f"glibc_{tag}", module=module)
    _KERNELS[source] = kernel
    return kernel


def _run(quantity: int, a, b, c, step: float, source: str, out=None) -> tuple[np.ndarray, np.ndarray]:
    """The array kernel of ``source`` on ``a, b, c`` (broadcast together), on the CPU; into ``out``
    (contiguous float64 of their size) if given."""
    init_warp()
    check_cpu_isa_runs()
    arrays = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (a, b, c)))
    shape = arrays[0].shape
    a, b, c = (np.ascontiguousarray(x.reshape(-1)) for x in arrays)
    out = np.empty(a.size, dtype=np.float64) if out is None else out.reshape(-1)
    ok = np.empty(a.size, dtype=np.uint8)
    if a.size:
        packed = _Arrays()
        for name, x in (("a", a), ("b", b), ("c", c), ("out", out)):
            setattr(packed, name, wp.array(x, dtype=wp.float64, device="cpu", copy=False))
        packed.ok = wp.array(ok, dtype=wp.uint8, device="cpu", copy=False)
        wp.launch(
            _kernel(source),
            dim=(a.size + BLOCK - 1) // BLOCK,
            inputs=[packed, wp.float64(step), wp.int32(quantity)],
            device="cpu",
        )
    return out.reshape(shape), ok.astype(bool).reshape(shape)


def ftle_like_numpy(dx, dp, log_stretch, step: float, *, source: str = GLIBC_FTLE_CPP, out=None):
    """``(log_stretch + log(hypot(dx, dp))) / step`` by :data:`GLIBC_FTLE_CPP`, on the CPU.

    Parameters
    ----------
    dx, dp, log_stretch : array_like of float64
        The points' tangents and log-stretches (broadcast together).
    step : float
        The step the exponent is taken at.
    source : str
        The C++ to run (a variant, in tests).
    out : numpy.ndarray of float64, optional
        Where the exponents go (contiguous, of the arguments' broadcast shape).

    Returns
    -------
    out : numpy.ndarray of float64
        The exponents; not NumPy's where ``ok`` is false.
    ok : numpy.ndarray of bool
        Where ``out`` is the transcription's: ``dx`` and ``dp`` finite.
    """
    return _run(FTLE, dx, dp, log_stretch, step, source, out)


def hypot_like_numpy(x, y, *, source: str = GLIBC_FTLE_CPP):
    """``glibc_hypot(x, y)`` on arrays, and where it applies (``x`` and ``y`` finite)."""
    return _run(HYPOT, x, y, 0.0, 1.0, source)


def hypot_into(x: np.ndarray, y: np.ndarray, out: np.ndarray) -> bool:
    """``glibc_hypot(x, y)`` of two contiguous float64 arrays into ``out`` (of their size); whether
    it applies to every point (``x`` and ``y`` finite: elsewhere ``out`` is not NumPy's)."""
    # the kernel's third argument is read by the FTLE only: ``y`` stands in for it
    _, ok = _run(HYPOT, x, y, y, 1.0, GLIBC_FTLE_CPP, out)
    return bool(ok.all())


def log_like_numpy(x, *, source: str = GLIBC_FTLE_CPP):
    """``glibc_log(x)`` on an array, and where it applies (``x >= 0``)."""
    return _run(LOG, x, 0.0, 0.0, 1.0, source)


def numpy_ftle(dx, dp, log_stretch, step: float) -> np.ndarray:
    """What the transcription reproduces: :func:`warpratchet.observables.lyapunov`, NumPy's
    ``(log_stretch + log(hypot(dx, dp))) / step`` (here quiet about the special values)."""
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        return lyapunov({"log_stretch": log_stretch, "dx": dx, "dp": dp}, step)


#: Arguments where ``log`` rounds differently if one of its FMAs is left unfused: ``r = z/c - 1``
#: and the last ``r^3 q + lo`` of the table path; in the near-1 path ``B1 + r B2``, then
#: ``+ r^2 B3``, the last Horner step and the final ``r^3 P + lo``. Found by comparing such variants
#: with the transcription on 2.2 * 10^8 arguments, most in ``[0.6875, 1.375]``; of ``log``'s other
#: FMAs, five
#: give the same bits either way (their product is exact) and twelve changed no result there (the
#: product is too small to move the final rounding), so a random sample cannot tell them apart.
LOG_HARD_CASES = tuple(
    float.fromhex(x)
    for x in (
        "0x1.643d3c6f0968bp-1",  # r = z/c - 1
        "0x1.bfa54ebad6922p-1",
        "0x1.2034112d79ccbp+0",  # r^3 q + lo (table path)
        "0x1.e13219288ff3fp-1",  # B1 + r B2
        "0x1.08987fc30f03bp+0",
        "0x1.0fdb538af9a9dp+0",
        "0x1.0e3f6e9017163p+0",  # (B1 + r B2) + r^2 B3
        "0x1.0fac84f461246p+0",
        "0x1.e466f6ddc762cp-1",  # r^3 P + lo
        "0x1.0ffc3d1f47110p+0",
        "0x1.077aab2423e21p+0",
        "0x1.e315df54bf109p-1",  # (B4 + ...) r^3 + (B1 + r B2 + r^2 B3)
        "0x1.0f8fa7c97bac0p+0",
    )
)


def gate_sample(seed: int = 2718) -> tuple[np.ndarray, np.ndarray]:
    """The tangents :func:`matches_numpy` compares on, ``dx, dp``.

    Norms near 1 (both of ``log``'s paths, and the edges between them), over ``[0.5, 2]`` (every
    table interval, ``k = -1, 0, 1``) and log-uniform over the whole normal range into the
    subnormals; ratios ``|dp/dx|`` across ``hypot``'s two corrections (they meet at
    ``1/sqrt 3``), around its shortcut (``2^-54``) and zero; both signs and both orders; and
    :data:`LOG_HARD_CASES` as ``(x, 0)``.
    """
    rng = np.random.default_rng(seed)
    norm = np.concatenate(
        [
            1.0 + rng.uniform(-0.07, 0.07, 100_000),
            1.0 + rng.uniform(-1e-5, 1e-5, 20_000),
            np.exp(rng.uniform(-0.7, 0.7, 60_000)),
            np.exp(rng.uniform(np.log(1e-320), np.log(1e308), 60_000)),
        ]
    )
    n = norm.size
    ratio = np.concatenate(
        [
            rng.uniform(0.0, 1.0, n - n // 8 - n // 64),
            np.exp2(rng.uniform(-58.0, -50.0, n // 8)),
            np.zeros(n // 64),
        ]
    )
    rng.shuffle(ratio)
    angle = np.arctan(ratio)
    big, small = norm * np.cos(angle), norm * np.sin(angle)
    swap = rng.random(n) < 0.5
    signs = rng.choice([-1.0, 1.0], (2, n))
    hard = np.array(LOG_HARD_CASES)
    dx = np.concatenate([np.where(swap, small, big) * signs[0], hard])
    dp = np.concatenate([np.where(swap, big, small) * signs[1], np.zeros_like(hard)])
    return dx, dp


def _same_bits(got: np.ndarray, ok: np.ndarray, want: np.ndarray) -> bool:
    """``got`` is ``want`` bit for bit (a NaN any NaN: its payload is the machine's), all ``ok``."""
    same = (got.view(np.int64) == want.view(np.int64)) | (np.isnan(got) & np.isnan(want))
    return bool(ok.all() and same.all())


def agrees(source: str = GLIBC_FTLE_CPP) -> bool:
    """Whether ``source`` gives NumPy's bits on :func:`gate_sample`: ``hypot``, ``log`` of the
    norms and the composite (``log_stretch = 0`` and ``step = 1``, where every bit of the
    logarithm shows, and arbitrary ones)."""
    dx, dp = gate_sample()
    norm = np.hypot(dx, dp)
    rng = np.random.default_rng(1)
    log_stretch = np.where(rng.random(dx.size) < 0.5, 0.0, rng.uniform(-10.0, 1e4, dx.size))
    step = 6000.0
    return (
        _same_bits(*hypot_like_numpy(dx, dp, source=source), norm)
        and _same_bits(*log_like_numpy(norm, source=source), np.log(norm))
        and _same_bits(*ftle_like_numpy(dx, dp, 0.0, 1.0, source=source), numpy_ftle(dx, dp, 0.0, 1.0))
        and _same_bits(
            *ftle_like_numpy(dx, dp, log_stretch, step, source=source), numpy_ftle(dx, dp, log_stretch, step)
        )
    )


@functools.cache
def hypot_matches_numpy() -> bool:
    """Whether the transcription's ``hypot`` alone gives this machine's NumPy's bits on
    :func:`gate_sample`. Where NumPy's ``log`` is its own (a CPU with AVX-512) and
    :func:`matches_numpy` says no, NumPy's ``hypot`` is still the C library's, and the kernel's
    can take its place."""
    dx, dp = gate_sample()
    return _same_bits(*hypot_like_numpy(dx, dp), np.hypot(dx, dp))


@functools.cache
def matches_numpy() -> bool:
    """Whether :data:`GLIBC_FTLE_CPP` gives this machine's NumPy's bits (module docstring): the
    kernels use it only then."""
    return agrees()
