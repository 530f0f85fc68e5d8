"""The step body: one iteration of Eq. (cpem) and of its tangent ``DM``, written once per backend.

Arithmetic (``warpratchet.reference`` repeats it operation by operation in NumPy, which is what
makes the two bitwise equal):

* force: ``f`` and ``K f'`` piece by piece, code generated from the force's piece table
  (:mod:`warpratchet.force`; Eq. fx for the paper's family, whose coefficients the kernels read
  from :class:`Coefficients` at run time, while another force's are constants of its own code);
* momentum kept as whole units ``w`` plus a fraction ``q`` in ``[0, 1)``: ``t = q + K*f``,
  ``w += floor(t)``, ``q = t - floor(t)``, and a ``q`` that rounds up to exactly 1 (``t`` just
  below an integer) is folded to 0 with ``w += 1``. A float64 momentum that grew to 10^4 would
  lose the digits that ``x' = x + p' mod 1`` needs;
* ``x' = x + q``, minus 1 if that is ``>= 1`` (exact: ``x + q < 2``);
* tangent ``(dx, dp)``: ``dp' = dp + (K*f')*dx``, ``dx' = dx + dp'`` (``det DM = 1``);
* renormalisation (``Body.renorm``, called by the kernels after every global step that is a
  multiple of ``RENORM_CHECK_EVERY``): a tangent with ``|dx| > RENORM_THRESHOLD`` is divided by
  its norm ``h = sqrt(dx^2 + dp^2)`` and ``log(h)`` is added to the log-stretch.

A Warp thread advances :data:`INTERLEAVE` independent points, its *lanes*, held in a
:class:`Lanes` struct of lane vectors. Besides the state, each step leaves two facts per lane
that kernel variants may use (an unused fact costs nothing: the compiler drops it):
``gain``, the whole units of momentum the step added (``floor(t)``, plus 1 on a fold), and
``in_strip``, 1 where the new ``x`` lies in the force's strip (the pieces with ``f' > 0``: the
strip B of Eq. (B) for the paper's family), else 0.

Two bodies, one arithmetic:

* :data:`PORTABLE`, plain Warp (a scalar step per lane), compiles for CUDA and the CPU; its
  one-point functions ``_step_point`` and ``_renorm_point`` also make ``advance_map``'s CUDA kernel,
  which runs one point per GPU thread (:mod:`warpratchet.kernels._advance`);
* :data:`CPU`, the same operations on whole lane vectors in C++ (``wp.func_native`` with clang
  vector extensions): ``floor`` is one ``vrndscalepd`` per 8 lanes (AVX-512), each three-way
  choice a pair of masked blends, and no libm call sits in the step (only ``log`` in a renormalisation,
  once per ~600 steps for a chaotic point). It is only ever compiled for the CPU. Its runs of
  steps go one vector register at a time (:data:`DEPTH_FIRST`), and a kernel without per-step
  work advances two threads' worth of lanes per call (:data:`PAIRED`).

``tests/kernels/test_kernels.py`` checks that both give bitwise the same states on the CPU.
"""

import linecache
from typing import Any, NamedTuple

import warp as wp

from ..force import Force, cpp_source, warp_source
from ._runtime import CPU_ISA

__all__ = [
    "INTERLEAVE",
    "RENORM_CHECK_EVERY",
    "RENORM_THRESHOLD",
    "LaneVector",
    "Lanes",
    "State",
    "Coefficients",
    "Body",
    "CPU",
    "PORTABLE",
    "force_bodies",
    "depth_first_steps_source",
    "cpu_steps_source",
    "load_lanes",
    "load_lane_vector",
    "store_lane_vector",
    "VECTOR_TYPES",
    "LOG_LANES",
]

#: Renormalise the tangent when ``|dx|`` passes this. Between two checks (8 steps) a vector
#: grows by at most ``(2 + K max(l1, l2))^8``, below 1e208 for every ``b1, b2 > 1e-25``.
RENORM_THRESHOLD = 1.0e100
#: Steps between two renormalisation checks (a power of two: the test is a bit mask).
RENORM_CHECK_EVERY = 8


#: Points advanced per Warp thread: 32 on the AVX-512 path (four 8-wide vectors per field in 32
#: vector registers), 16 on the AVX2 path (16 registers of 4); :data:`._runtime.CPU_ISA` chooses.
#: A power of two: clang pads a vector of any other length, which the lane structs do not.
INTERLEAVE = 32 if CPU_ISA == "avx512" else 16

#: One float64 per lane.
LaneVector = wp.types.vector(length=INTERLEAVE, dtype=wp.float64)


@wp.struct
class Lanes:
    """The lanes of one Warp thread: state and the facts of the last step."""

    x: LaneVector
    q: LaneVector
    w: LaneVector  # whole units of momentum gained since the launch (exact below 2^53)
    dx: LaneVector
    dp: LaneVector
    log_stretch: LaneVector
    gain: LaneVector  # whole units gained by the last step
    in_strip: LaneVector  # 1.0 where x after the last step lies in B, Eq. (B); else 0.0


@wp.struct
class State:
    """The per-point state arrays a kernel advances, shape ``(n,)`` each."""

    x: wp.array(dtype=wp.float64)
    q: wp.array(dtype=wp.float64)
    winding: wp.array(dtype=wp.int64)
    dx: wp.array(dtype=wp.float64)
    dp: wp.array(dtype=wp.float64)
    log_stretch: wp.array(dtype=wp.float64)


@wp.struct
class Coefficients:
    """The map: ``K``, the kinks ``b1`` and ``right = 1 - b2``, and ``l1, l2, c`` of Eq. (mmc)."""

    K: wp.float64
    b1: wp.float64
    right: wp.float64
    l1: wp.float64
    l2: wp.float64
    c: wp.float64


# -- lane layout and loads ----------------------------------------------------------------------
@wp.func
def load_lanes(a: wp.array(dtype=Any), lanes: Any, first: int, spacing: int, n: int):
    """Lanes ``first + k*spacing`` of ``a`` in a copy of ``lanes``, a lane vector of ``a``'s dtype
    (:data:`LaneVector` for the float64 state, an int64 one for a variant's counters); lanes past
    ``n`` repeat point ``n - 1``."""
    v = lanes
    for k in range(wp.static(INTERLEAVE)):
        v[k] = a[wp.min(first + k * spacing, n - 1)]
    return v


@wp.func
def load_lane_vector(a: wp.array(dtype=wp.float64), first: int, spacing: int, n: int):
    """The float64 lanes ``first + k*spacing`` of ``a`` (:func:`load_lanes`)."""
    return load_lanes(a, LaneVector(), first, spacing, n)


@wp.func
def store_lane_vector(a: wp.array(dtype=Any), v: Any, first: int, spacing: int, n: int):
    """Store the lanes that are real points (any dtype: ``v`` is a lane vector of ``a``'s)."""
    for k in range(wp.static(INTERLEAVE)):
        i = first + k * spacing
        if i < n:
            a[i] = v[k]


@wp.func
def _load(state: State, first: int, spacing: int, n: int):
    s = Lanes()
    s.x = load_lane_vector(state.x, first, spacing, n)
    s.q = load_lane_vector(state.q, first, spacing, n)
    s.dx = load_lane_vector(state.dx, first, spacing, n)
    s.dp = load_lane_vector(state.dp, first, spacing, n)
    s.log_stretch = load_lane_vector(state.log_stretch, first, spacing, n)
    return s


@wp.func
def _store(state: State, s: Lanes, first: int, spacing: int, n: int):
    store_lane_vector(state.x, s.x, first, spacing, n)
    store_lane_vector(state.q, s.q, first, spacing, n)
    store_lane_vector(state.dx, s.dx, first, spacing, n)
    store_lane_vector(state.dp, s.dp, first, spacing, n)
    store_lane_vector(state.log_stretch, s.log_stretch, first, spacing, n)
    for k in range(wp.static(INTERLEAVE)):
        i = first + k * spacing
        if i < n:
            state.winding[i] = state.winding[i] + wp.int64(s.w[k])


# The CPU body's load and store: a thread's lanes are one contiguous block of points
# (:func:`_blocks`), copied whole where the block lies inside contiguous arrays; the per-lane
# loops above (the same values) take the last, partial block and strided views.
_CPU_FIELDS = ("x", "q", "dx", "dp", "log_stretch")


def _whole_block_source(copy: str, then: str = "") -> str:
    """C++ of a whole-block copy: ``copy`` formatted per field, ``then`` after; returns whether
    the block was whole (else nothing is copied)."""
    checks = "".join(f"whole = whole && state.{f}.strides[0] == sizeof(double);\n" for f in _CPU_FIELDS)
    copies = "".join("    " + copy.format(f=f) + "\n" for f in _CPU_FIELDS)
    return (
        f"bool whole = first + {INTERLEAVE} <= n;\n{checks}"
        f"if (!whole) return false;\n{copies}{then}return true;\n"
    )


@wp.func_native(_whole_block_source("__builtin_memcpy(&s.{f}, state.{f}.data + first, sizeof(s.{f}));"))
def _load_whole_cpu(state: State, s: wp.ref[Lanes], first: int, n: int) -> bool: ...


@wp.func_native(
    "if (state.winding.strides[0] != sizeof(wp::int64)) return false;\n"
    + _whole_block_source(
        "__builtin_memcpy(state.{f}.data + first, &s.{f}, sizeof(s.{f}));",
        f"for (int k = 0; k < {INTERLEAVE}; ++k) state.winding.data[first + k] += (wp::int64)s.w.c[k];\n",
    )
)
def _store_whole_cpu(state: State, s: wp.ref[Lanes], first: int, n: int) -> bool: ...


@wp.func
def _load_cpu(state: State, first: int, spacing: int, n: int):
    """:func:`_load`'s lanes, a whole block in one copy per field."""
    s = Lanes()
    if not _load_whole_cpu(state, s, first, n):
        s = _load(state, first, spacing, n)
    return s


@wp.func
def _store_cpu(state: State, s: Lanes, first: int, spacing: int, n: int):
    """:func:`_store`, a whole block in one copy per field."""
    if not _store_whole_cpu(state, s, first, n):
        _store(state, s, first, spacing, n)


@wp.func
def _blocks(tid: int, n: int):
    """CPU layout: thread ``tid`` holds points ``tid*INTERLEAVE + k``, one contiguous block."""
    return tid * wp.static(INTERLEAVE), 1


@wp.func
def _strided(tid: int, n: int):
    """CUDA layout: lane ``k`` of thread ``tid`` is point ``tid + k*stride``, so that neighbouring
    threads touch neighbouring addresses (coalesced loads)."""
    return tid, (n + wp.static(INTERLEAVE - 1)) // wp.static(INTERLEAVE)


# -- the portable body (plain Warp) -------------------------------------------------------------
def _generated_func(source: str, name: str) -> wp.Function:
    """A ``wp.func`` from generated Python source; Warp reads a function's source back, so the
    source is registered with ``linecache`` under a name of its own."""
    filename = f"<warpratchet force {name}>"
    linecache.cache[filename] = (len(source), None, source.splitlines(True), filename)
    namespace = {"wp": wp, "Coefficients": Coefficients}
    exec(compile(source, filename, "exec"), namespace)
    func = namespace[name]
    func.__qualname__ = name
    return wp.func(func)


def _force_funcs(force: Force, tag: str) -> tuple[wp.Function, wp.Function]:
    """The force and strip of ``force`` as ``wp.func``s (:func:`warpratchet.force.warp_source`)."""
    name = f"_force_{tag}"
    source = warp_source(force, name, "Coefficients")
    return _generated_func(source, name), _generated_func(source, f"{name}_strip")


def _portable_step(force: Force, tag: str) -> tuple[wp.Function, wp.Function, wp.Function]:
    """The portable ``step`` of ``force`` (``_step_point`` over the lanes), ``steps`` (``count``
    of them) and ``_step_point`` itself."""
    force_at, strip_at = _force_funcs(force, tag)

    def step_point(
        x: wp.float64, q: wp.float64, w: wp.float64, dx: wp.float64, dp: wp.float64, p: Coefficients
    ):
        """One iteration for one point; returns ``x, q, w, dx, dp, gain, in_strip``."""
        one = wp.float64(1.0)
        zero = wp.float64(0.0)
        # Eq. (fx) and its slope, generated from the piece table; wp.where keeps the step branch free.
        f, slope = wp.static(force_at)(x, p)
        t = q + p.K * f
        fl = wp.floor(t)
        q = t - fl
        # t just below an integer can round t - floor(t) up to exactly 1: fold it back.
        wrap = q >= one
        q = wp.where(wrap, zero, q)
        lift = wp.where(wrap, one, zero)
        w = w + fl + lift
        x = x + q
        x = wp.where(x >= one, x - one, x)
        dp = dp + (p.K * slope) * dx
        dx = dx + dp
        in_strip = wp.static(strip_at)(x, p)
        return x, q, w, dx, dp, fl + lift, in_strip

    step_point.__qualname__ = f"_step_point_{tag}"
    step_point = wp.func(step_point)

    def step_portable(s: wp.ref[Lanes], p: Coefficients):
        for k in range(wp.static(INTERLEAVE)):
            x, q, w, dx, dp, gain, in_strip = wp.static(step_point)(
                s.x[k], s.q[k], s.w[k], s.dx[k], s.dp[k], p
            )
            s.x[k] = x
            s.q[k] = q
            s.w[k] = w
            s.dx[k] = dx
            s.dp[k] = dp
            s.gain[k] = gain
            s.in_strip[k] = in_strip

    step_portable.__qualname__ = f"_step_portable_{tag}"
    step_portable = wp.func(step_portable)

    def steps_portable(s: wp.ref[Lanes], p: Coefficients, count: wp.int32):
        for _i in range(count):
            wp.static(step_portable)(s, p)

    steps_portable.__qualname__ = f"_steps_portable_{tag}"
    return step_portable, wp.func(steps_portable), step_point


@wp.func
def _renorm_point(dx: wp.float64, dp: wp.float64, log_stretch: wp.float64):
    """The renormalisation check for one point; returns ``dx, dp, log_stretch``."""
    if wp.abs(dx) > wp.float64(RENORM_THRESHOLD):
        h = wp.sqrt(dx * dx + dp * dp)
        return dx / h, dp / h, log_stretch + wp.log(h)
    return dx, dp, log_stretch


@wp.func
def _renorm_portable(s: wp.ref[Lanes]):
    for k in range(wp.static(INTERLEAVE)):
        dx, dp, log_stretch = _renorm_point(s.dx[k], s.dp[k], s.log_stretch[k])
        s.dx[k] = dx
        s.dp[k] = dp
        s.log_stretch[k] = log_stretch


# -- the CPU body (clang vector extensions) -----------------------------------------------------
# One C++ vector of INTERLEAVE doubles per state field; LLVM splits it into 512-bit registers
# (AVX-512) or 256-bit ones, and the independent pieces hide each other's latencies. Written one
# operation per statement, in the order of _step_point (and -ffp-contract=off), so that every
# rounding is the scalar one. The lane vectors are copied in and out with memcpy, which LLVM turns
# into registers once the function is inlined into the step loop.
#: The C++ lane vector ``v_t`` of the CPU snippets (variants' CPU hooks use it too).
VECTOR_TYPES = f"""
typedef double v_t __attribute__((ext_vector_type({INTERLEAVE})));
"""

_LOAD_STATE_CPU = """
v_t x, q, w, dx, dp;
__builtin_memcpy(&x, &s.x, sizeof(v_t));
__builtin_memcpy(&q, &s.q, sizeof(v_t));
__builtin_memcpy(&w, &s.w, sizeof(v_t));
__builtin_memcpy(&dx, &s.dx, sizeof(v_t));
__builtin_memcpy(&dp, &s.dp, sizeof(v_t));
const v_t one = 1.0, zero = 0.0;
"""

#: One step on the local lane vectors ``x, q, w, dx, dp``; leaves the step's facts in the locals
#: ``gain`` and ``in_strip`` (dropped by the compiler where nothing reads them). ``@FORCE@`` (which
#: defines ``kick`` and ``k_slope``) and ``@STRIP@`` (``in_strip``) are the force's generated C++
#: (:func:`warpratchet.force.cpp_source`); ``gain`` goes at ``@GAIN_EARLY@`` or ``@GAIN_LATE@``,
#: the new position at ``@POSITION@`` (:func:`_arithmetic`).
_STEP_ARITHMETIC_CPU_TEMPLATE = """
@FORCE@const v_t t = q + kick;
const v_t fl = __builtin_elementwise_floor(t);
const v_t frac = t - fl;
const auto wrap = frac >= one;
q = wrap ? zero : frac;
const v_t lift = wrap ? one : zero;
@GAIN_EARLY@const v_t w_fl = w + fl;
w = w_fl + lift;
@POSITION@const v_t k_slope_dx = k_slope * dx;
dp = dp + k_slope_dx;
dx = dx + dp;
@GAIN_LATE@@STRIP@"""

#: The new position, ``x + q`` mod 1.
_POSITION = """x = x + q;
/* x - (x >= 1 ? 1 : 0): x - 0.0 is x (x >= 0), so these are the bits of the choice, with a mask
   and a subtraction where the choice needs a blend (a three-micro-op one on some Intel cores). */
const v_t unit = x >= one ? one : zero;
x = x - unit;
"""

#: The new position for a loop that the step's latency bounds, not its instruction count (one
#: block of lanes in four chains of registers: the transport kernel's steps, which record each
#: step's row): :data:`_POSITION`'s values, every lane's bits, with its choices taken between values
#: computed beside their tests, so that the chain from one position to the next is a few
#: operations shorter:
#:
#: * the new position from ``frac`` while the fold is tested: ``x + frac``, or ``x + 0`` where ``q``
#:   folds to 0 (:data:`_POSITION`'s ``x + q`` there), chosen by the test;
#: * that sum minus 1 while it is tested against 1, chosen by the test (:data:`_POSITION` subtracts
#:   1 or 0, and ``s - 0`` is ``s``);
#: * ``kept`` (:data:`_KEPT`) keeps the operands of these choices, and of the choice between the
#:   force's pieces' values, apart: LLVM would otherwise turn ``c ? s - 1 : s`` and that choice
#:   into an operation masked by the test, which waits for it.
_SHORT_CHAIN_POSITION = """const v_t moved = kept(x + frac);
const v_t stay = kept(x + zero);
const v_t sum = wrap ? stay : moved;
const v_t sum_less_one = kept(sum - one);
x = sum >= one ? sum_less_one : sum;
"""

#: ``kept(v)``: ``v``, through an empty ``asm`` that hides how it was made (a no-op on a vector
#: wider than one register, the AVX2 path's, whose choices are blends anyway).
_KEPT = """auto kept = [](auto v) {
#if defined(__x86_64__)
    if constexpr (sizeof(v) <= 64) { __asm__("" : "+v"(v)); }
#endif
    return v;
};
"""

_STORE_STATE_CPU = """
__builtin_memcpy(&s.x, &x, sizeof(v_t));
__builtin_memcpy(&s.q, &q, sizeof(v_t));
__builtin_memcpy(&s.w, &w, sizeof(v_t));
__builtin_memcpy(&s.dx, &dx, sizeof(v_t));
__builtin_memcpy(&s.dp, &dp, sizeof(v_t));
"""


_GAIN = "const v_t gain = fl + lift;\n"


def _arithmetic(force: Force, early_gain: bool = False, short_chain: bool = False) -> str:
    """The step's C++ for ``force``. ``early_gain``: ``gain`` formed as soon as ``fl`` and ``lift``
    exist, which then die there; a loop that reads ``gain`` at the step's end would otherwise keep
    both live through the rest of the step, and with 16 AVX2 registers they are spilled (the
    same value either way). ``short_chain``: :data:`_SHORT_CHAIN_POSITION`, for a loop bound by
    the step's latency (more instructions, so not where the ports bound it: the paired loops)."""
    force_code, strip_code = cpp_source(force, kept="kept" if short_chain else "")
    step = (
        _STEP_ARITHMETIC_CPU_TEMPLATE.replace("@FORCE@", force_code)
        .replace("@POSITION@", _SHORT_CHAIN_POSITION if short_chain else _POSITION)
        .replace("@STRIP@", strip_code)
        .replace("@GAIN_EARLY@", _GAIN if early_gain else "")
        .replace("@GAIN_LATE@", "" if early_gain else _GAIN)
    )
    return _KEPT + step if short_chain else step


def _step_cpu_sources(force: Force) -> tuple[str, str]:
    """C++ of the CPU ``step`` (one iteration, facts kept) and ``steps`` (``count`` iterations
    with the lanes in local vectors throughout: the loop holds no stores, so the map's constants
    are computed once, outside it, and nothing but register pressure sends a lane vector to
    memory; the facts are not kept) of ``force``."""
    arithmetic = _arithmetic(force)
    step = (
        VECTOR_TYPES
        + _LOAD_STATE_CPU
        + "{"
        + arithmetic
        + """
__builtin_memcpy(&s.gain, &gain, sizeof(v_t));
__builtin_memcpy(&s.in_strip, &in_strip, sizeof(v_t));
}"""
        + _STORE_STATE_CPU
    )
    return step, cpu_steps_source(force)


#: Lanes in one vector register of the CPU path (8 doubles in a zmm, 4 in a ymm).
REGISTER_LANES = 8 if CPU_ISA == "avx512" else 4
#: Whether the CPU ``steps`` without per-step work go register by register
#: (:func:`_depth_first_steps`). Written on whole lane vectors, each operation of the step is split
#: into INTERLEAVE / REGISTER_LANES register operations side by side, and LLVM's register
#: allocator keeps part of the position in memory, a store and a reload on the step's critical
#: path (on Zen 5; ``benchmarks/README.md``, "Zen 5: the step loop register by register").
DEPTH_FIRST = True
#: Whether a kernel without per-step work advances two blocks of lanes per Warp thread on the CPU
#: body (``Body.pair_steps``): eight independent chains of registers per step instead of four. On
#: the AVX2 path too: 16 registers cannot hold them, but the spills are off the critical path
#: (``benchmarks/README.md``, "The AVX2 path paired").
PAIRED = True
_STEP_FIELDS = ("x", "q", "w", "dx", "dp")


def depth_first_steps_source(force: Force, *, each: str, after_each: str, before: str, after: str) -> str:
    """C++ of the CPU ``steps`` of ``force`` register by register (:func:`_depth_first_steps`) with
    a variant's per-step work inside: ``each`` after every register's step (it sees the register's
    locals ``gain`` and ``in_strip``, of type ``r_t``, and its index ``r``), ``after_each`` after the
    last register's, ``before`` ahead of the loads and ``after`` behind the stores. One block of
    lanes, whose four chains leave the loop bound by the step's latency: the short-chain step."""
    arithmetic = _arithmetic(force, early_gain=True, short_chain=True)
    return before + _depth_first_steps(arithmetic + each, after_each=after_each) + after


def _depth_first_steps(arithmetic: str, blocks: int = 1, after_each: str = "") -> str:
    """C++ of the CPU ``steps`` that runs each step one vector register at a time: the lanes held
    as arrays of register-wide vectors, and within a step the arithmetic for the first register's
    lanes, then the next's (the loop over registers unrolled), each with ``v_t`` and the constants
    ``one``, ``zero`` of a register's width. The same operations on every lane as the whole-vector
    form, so the same bits; only the order of independent instructions differs, which an
    out-of-order core interleaves by itself."""
    per_block = INTERLEAVE // REGISTER_LANES
    registers = blocks * per_block
    # the Lanes arguments: s, then s2, ... (pair_steps), each block's registers after the last's
    lanes = [("s" if b == 0 else f"s{b + 1}", b * per_block) for b in range(blocks)]
    declare = "".join(f"r_t lanes_{f}[{registers}];\n" for f in _STEP_FIELDS)
    load = "".join(
        f"__builtin_memcpy(lanes_{f} + {at}, &{name}.{f}, sizeof(v_t));\n"
        for name, at in lanes
        for f in _STEP_FIELDS
    )
    store = "".join(
        f"__builtin_memcpy(&{name}.{f}, lanes_{f} + {at}, sizeof(v_t));\n"
        for name, at in lanes
        for f in _STEP_FIELDS
    )
    take = "".join(f"v_t {f} = lanes_{f}[r];\n" for f in _STEP_FIELDS)
    put = "".join(f"lanes_{f}[r] = {f};\n" for f in _STEP_FIELDS)
    return (
        VECTOR_TYPES
        + f"typedef double r_t __attribute__((ext_vector_type({REGISTER_LANES})));\n"
        + declare
        + load
        + "for (int i = 0; i < count; i++) {\n"
        + f"#pragma unroll\nfor (int r = 0; r < {registers}; r++) {{\n"
        + "typedef r_t v_t;\nconst v_t one = 1.0, zero = 0.0;\n"
        + take
        + "{"
        + arithmetic
        + "}\n"
        + put
        + "}\n"
        + after_each
        + "}\n"
        + store
    )


def cpu_steps_source(force: Force, each: str = "", before: str = "", after: str = "") -> str:
    """C++ of the CPU ``steps`` of ``force`` (``count`` iterations, the lanes in local vectors),
    with ``each`` after every iteration (it sees the locals of the step, ``gain`` and ``in_strip``
    among them), ``before`` ahead of the loads and ``after`` behind the stores: a variant's
    per-step work inside the loop, so that the lanes stay in registers between two checks."""
    # A loop that reads the step's facts gets the gain early (_arithmetic) and, one block of lanes
    # in four chains, the short-chain step; one that does not (the plain map, the indicators)
    # keeps the source it has, the gain dropped as dead code.
    arithmetic = _arithmetic(force, early_gain=bool(each), short_chain=bool(each))
    if DEPTH_FIRST and not (each or before or after):
        return _depth_first_steps(arithmetic)
    return (
        VECTOR_TYPES
        + before
        + _LOAD_STATE_CPU
        + "for (int i = 0; i < count; i++) {"
        + arithmetic
        + each
        + "}"
        + _STORE_STATE_CPU
        + after
    )


#: C++ for the CPU snippets: ``log_lanes::run(in, use, out)`` sets ``out[k] = log(in[k])`` for the
#: lanes with ``use[k]`` set (all lanes if ``use`` is null) with the libm ``log`` that ``wp.log``
#: calls. Out of line, so that the calls do not force the caller's lane vectors through memory
#: around each of them.
LOG_LANES = f"""
struct log_lanes {{
    static __attribute__((noinline)) void run(const double* in, const long long* use, double* out) {{
        for (int k = 0; k < {INTERLEAVE}; k++)
            out[k] = (use == nullptr || use[k]) ? wp::log(in[k]) : 0.0;
    }}
}};
"""

_RENORM_CPU = (
    VECTOR_TYPES
    + LOG_LANES
    + f"""
v_t dx, dp;
__builtin_memcpy(&dx, &s.dx, sizeof(v_t));
__builtin_memcpy(&dp, &s.dp, sizeof(v_t));
const v_t threshold = {RENORM_THRESHOLD!r};
const auto big = __builtin_elementwise_abs(dx) > threshold;
if (__builtin_reduce_or(big) != 0) {{
    /* A chaotic tangent passes 1e100 every ~660 steps (~80 checks), so with 32 lanes this branch
       runs at about two checks in five.
       sqrt and division are IEEE in vector form too; log goes lane by lane. */
    v_t log_stretch;
    __builtin_memcpy(&log_stretch, &s.log_stretch, sizeof(v_t));
    const v_t dx2 = dx * dx;
    const v_t dp2 = dp * dp;
    const v_t norm2 = dx2 + dp2;
    const v_t h = __builtin_elementwise_sqrt(norm2);
    double h_lanes[{INTERLEAVE}], log_h[{INTERLEAVE}];
    long long use[{INTERLEAVE}];
    __builtin_memcpy(h_lanes, &h, sizeof(v_t));
    __builtin_memcpy(use, &big, sizeof(use));
    log_lanes::run(h_lanes, use, log_h);
    v_t log_h_v;
    __builtin_memcpy(&log_h_v, log_h, sizeof(v_t));
    const v_t stretched = log_stretch + log_h_v;
    const v_t dx_unit = dx / h;
    const v_t dp_unit = dp / h;
    log_stretch = big ? stretched : log_stretch;
    dx = big ? dx_unit : dx;
    dp = big ? dp_unit : dp;
    __builtin_memcpy(&s.log_stretch, &log_stretch, sizeof(v_t));
    __builtin_memcpy(&s.dx, &dx, sizeof(v_t));
    __builtin_memcpy(&s.dp, &dp, sizeof(v_t));
}}
"""
)


def _cpu_steps(force: Force, tag: str) -> tuple[wp.Function, wp.Function]:
    """The CPU ``step`` and ``steps`` of ``force`` (:func:`_step_cpu_sources`)."""
    step_source, steps_source = _step_cpu_sources(force)

    def step_cpu(s: wp.ref[Lanes], p: Coefficients): ...

    def steps_cpu(s: wp.ref[Lanes], p: Coefficients, count: wp.int32): ...

    step_cpu.__qualname__ = f"_step_cpu_{tag}"
    steps_cpu.__qualname__ = f"_steps_cpu_{tag}"
    return wp.func_native(step_source)(step_cpu), wp.func_native(steps_source)(steps_cpu)


def _pair_steps(force: Force, tag: str) -> wp.Function:
    """The CPU ``pair_steps`` of ``force``: ``count`` steps of two threads' worth of lanes at once,
    register by register (:func:`_depth_first_steps`)."""

    def pair_steps_cpu(s: wp.ref[Lanes], s2: wp.ref[Lanes], p: Coefficients, count: wp.int32): ...

    pair_steps_cpu.__qualname__ = f"_pair_steps_cpu_{tag}"
    return wp.func_native(_depth_first_steps(_arithmetic(force), blocks=2))(pair_steps_cpu)


@wp.func_native(_RENORM_CPU)
def _renorm_cpu(s: wp.ref[Lanes]): ...


class Body(NamedTuple):
    """One implementation of the step body; kernels take every part from here."""

    name: str
    layout: wp.Function  # (tid, n) -> (first, spacing): lane k is point first + k*spacing
    load: wp.Function  # (State, first, spacing, n) -> Lanes
    store: wp.Function  # (State, Lanes, first, spacing, n)
    step: wp.Function  # (ref Lanes, Coefficients): one iteration, facts included
    renorm: wp.Function  # (ref Lanes): the renormalisation check
    steps: wp.Function  # (ref Lanes, Coefficients, count: int32): count iterations, facts not kept
    #: One point's step and check (x, q, w, dx, dp, Coefficients) -> (x, q, w, dx, dp, gain,
    #: in_strip) and (dx, dp, log_stretch) -> (dx, dp, log_stretch); the portable body only.
    point_step: wp.Function | None = None
    point_renorm: wp.Function | None = None
    #: The force's piece table (the CPU body: for variants that build steps of their own,
    #: :func:`cpu_steps_source`).
    force: Force | None = None
    #: ``(ref Lanes, ref Lanes, Coefficients, count: int32)``: ``steps`` of two blocks of lanes at
    #: once (the CPU body, :data:`PAIRED`); None elsewhere.
    pair_steps: wp.Function | None = None


def _portable_body(force: Force, tag: str) -> Body:
    step, steps, point = _portable_step(force, tag)
    return Body("portable", _strided, _load, _store, step, _renorm_portable, steps, point, _renorm_point)


def _cpu_body(force: Force, tag: str) -> Body:
    step, steps = _cpu_steps(force, tag)
    pair = _pair_steps(force, tag) if PAIRED else None
    return Body("cpu", _blocks, _load_cpu, _store_cpu, step, _renorm_cpu, steps, force=force, pair_steps=pair)


def force_bodies(force: Force) -> tuple[Body, Body]:
    """``(cpu, portable)`` step bodies of ``force``, made from its piece table.

    The paper's family reads its coefficients from :class:`Coefficients` at run time (one pair
    of bodies for every ``b1, b2``); any other force's table is constants of its own code.
    """
    tag = "paper" if force.family == "paper" else force.key
    if tag not in _BODIES:
        _BODIES[tag] = (_cpu_body(force, tag), _portable_body(force, tag))
    return _BODIES[tag]


_BODIES: dict[str, tuple[Body, Body]] = {}
#: The paper's family (Eq. fx): the bodies of every kernel built at import.
CPU, PORTABLE = force_bodies(Force.paper(0.5, 0.25))
