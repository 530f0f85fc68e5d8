"""The CPU hooks of the transport variant: per-step codes, decoded in blocks of steps.

Counting inside the step loop, lane by lane, costs far more than the step (a CPU thread holds
:data:`INTERLEAVE` points in vector registers, and the step already uses nearly all of them):
70x with the portable hooks' scalar loop, 2-3x with the trackers kept as vectors beside the
state (the registers spill). So the CPU hooks split the work:

* after each step: the step's facts, as they come out of it, into a buffer of 128 rows: on the
  AVX-512 path the top byte of each lane's ``gain`` (``|gain| <= 2`` since ``|K f| < 2``; each
  value has its own top byte) and the ``in_strip`` lanes (or, where that is cheaper, the others) as
  a 32-bit mask, written register by register (:func:`record_avx512`);
* at the renormalisation check (every 8 steps) that leaves fewer than 8 rows free, and at the end
  of the launch (``store``): the rows are decoded (the gain codes are three bits of the top
  bytes, ``_GAIN_CODES``) with the trackers as byte vectors (all lanes of a row at once), each
  row's events counted by lengths ``< 2``, ``< 4``, ``< 8`` with a popcount of the event mask;
  the rare events of length 8 or more go to the launch's histogram array one by one. Where the
  CPU has AVX-512 and GFNI, and on the AVX2 path, each full block of 8 rows is decoded at once
  instead (:mod:`._transport_block`).

A hook after each step, one step per call, spills the lanes around it, so on both paths the
steps between two checks run in one call with the recording inside the loop. On the AVX2 path
(16 lanes in 16 registers) a row is one byte per lane, ``gain + 8 in_strip`` (:data:`RECORD_CPU`),
and the rows past the last full block are decoded with the events as byte masks
(``_ROWS_AVX2``); the counts are the same.

Trackers: ``age`` (steps since the last visit to B), ``flen`` (steps of the run in progress) are
bytes kept at most :data:`CAP` after each block, the excess carried exactly in int64 (``*_extra``);
``fcode`` is the gain code of the run in progress. The carry arrays hold absolute global steps;
the first block of a thread converts them (the buffer knows its global steps) and ``store``
converts back, as lane vectors. Every count equals the portable hooks' (``tests/analyses/test_transport.py``).

Where the state lives: the buffer and the trackers in the launch's scratch array
(:data:`SCRATCH_BYTES`, shared by the launch's threads, which Warp runs one after the other on
the CPU), a few scalars in the thread's accumulator struct: Warp zero-initialises that struct
for every thread, which for a 4.6 KB buffer costs a noticeable part of a launch
(``benchmarks/README.md``, "The record of transport_overhead.py"). A guard in the scratch (its
owner and conflict words) turns threads that share it at once into an error.
"""

from ..force import Force, _strip_runs
from ._step import INTERLEAVE, REGISTER_LANES
from ._transport_block import BLOCK_CODED_CPU, BLOCK_CPU

__all__ = [
    "BINS",
    "CAP",
    "ROWS",
    "SCRATCH_BYTES",
    "CONFLICT_WORD",
    "CLAIM_CPU",
    "RECORD_CPU",
    "record_avx512",
    "DECODE_CPU",
    "FINISH_CPU",
]

#: Histogram bins: bin ``k`` counts lengths ``2^k <= L < 2^(k+1)``; 64 cover every int64 step count.
BINS = 64

#: A byte tracker above this after a block moves its excess to the int64 part (a decode adds at
#: most 128 steps, so bytes stay below 256).
CAP = 64

#: Steps buffered between two decodes (at a renormalisation check, every 8 steps, once fewer than
#: 8 rows are free): a decode spills the step's registers, so it is kept rare.
ROWS = 128

# The launch's scratch array (bytes; a launch's threads use it one after the other): the buffer
# (ROWS rows of INTERLEAVE gain bytes), the strip's masks (ROWS x 4 bytes), the byte trackers
# (valid, visited, age, fcode, flen: INTERLEAVE bytes each), the int64 excess (age, flen), and
# the guard: the owner (a tag of the thread using the scratch) and the conflict word.
_STRIP = ROWS * INTERLEAVE
_TRACKERS = _STRIP + 4 * ROWS
_EXTRA = _TRACKERS + 5 * INTERLEAVE
_GUARD = _EXTRA + 2 * 8 * INTERLEAVE
#: Bytes of the launch's scratch array.
SCRATCH_BYTES = _GUARD + 2 * 8
#: Index of the scratch's conflict word as int64 (``scratch.view(int64)[CONFLICT_WORD]``): nonzero
#: if two threads used the scratch at once (the counts of that launch are then wrong).
CONFLICT_WORD = _GUARD // 8 + 1

# Why a guard: the scratch is shared on the assumption that Warp runs a CPU launch's threads one
# after the other (Warp 1.19 does, for kernels without tiles). Each thread writes its tag (the
# address of its first carry element, unique across launches) into the owner word when it starts
# and checks it at every decode and at its end: two threads whose lifetimes overlap write inside
# each other's, so one of them finds another tag and sets the conflict word, which the launch
# turns into an error (kernels._transport) instead of counts that would be silently wrong.
_OWNER_TAG = "(unsigned long long)wp::address(acc.arrays.last_visit, acc.first)"
#: The thread's claim on the scratch (``load``, once before its step loop: not in the loop,
#: where the tag's address arithmetic cost the step loop 18 instructions and 12 stack accesses).
CLAIM_CPU = f"*(unsigned long long*)(acc.arrays.scratch.data + {_GUARD}) = {_OWNER_TAG};\n"
_CHECK_OWNER = f"""
{{
    unsigned long long* const guard = (unsigned long long*)(acc.arrays.scratch.data + {_GUARD});
    if (guard[0] != {_OWNER_TAG}) guard[1] = 1;
}}
"""

_MASK = "unsigned int" if INTERLEAVE == 32 else "unsigned short"

_TYPES = f"""
typedef unsigned char u8v __attribute__((ext_vector_type({INTERLEAVE})));
typedef unsigned short u16v __attribute__((ext_vector_type({INTERLEAVE})));
typedef bool bv __attribute__((ext_vector_type({INTERLEAVE})));
typedef {_MASK} mask_t;
typedef long long i64v __attribute__((ext_vector_type({INTERLEAVE})));
typedef int i32v __attribute__((ext_vector_type({INTERLEAVE})));
static constexpr i32v lane_index = {{{", ".join(str(k) for k in range(INTERLEAVE))}}};
/* the thread's points are one contiguous block of every carry array (the CPU layout): lane vectors */
#define WHOLE(acc) ((acc).lanes == {INTERLEAVE} && (acc).spacing == 1 \\
    && (acc).arrays.last_visit.strides[0] == 8 && (acc).arrays.flight_gain.strides[0] == 8 \\
    && (acc).arrays.flight_start.strides[0] == 8)
"""

#: The AVX2 body's recording (16 lanes): ``before``, ``each`` and ``after`` of the CPU body's loop
#: of steps (``step.cpu_steps_source``), so that the lanes stay in registers between two checks.
#: A row is one byte per lane, ``gain + 8 in_strip`` (exact: -2..2 outside B, 6..10 in it), four
#: conversions and three packs from the step's own locals; ``_ROWS_AVX2`` decodes it.
#: ``global_step`` is the step before the call's first one.
RECORD_CPU = (
    f"""
typedef signed char s8v __attribute__((ext_vector_type({INTERLEAVE})));
unsigned char* const scratch = acc.arrays.scratch.data;
int rows = acc.rows;
if (rows == 0) acc.base = global_step;
""",
    f"""{{
/* the row's byte per lane: gain + 8 in_strip, exact (-2..2, or 6..10 in B) */
const v_t strip8 = in_strip * 8.0;
const v_t coded = gain + strip8;
const s8v row = __builtin_convertvector(coded, s8v);
__builtin_memcpy(scratch + rows * {INTERLEAVE}, &row, sizeof(s8v));
rows = rows + 1;
}}
""",
    "acc.rows = rows;\n",
)

# The AVX-512 body's recording, its steps register by register (``step.depth_first_steps_source``):
# ``before``, ``each``, ``after_each`` and ``after`` (:func:`record_avx512`). Each step's facts are
# stored as they come out of the step, with no conversion: after each register's step, the top
# byte of each of its lanes' ``gain`` (a double in -2..2: C0, BF, 00, 3F, 40 hex, one per value)
# into the buffer row, and its lanes' strip as one bit each, byte ``r`` of the row's 32-bit mask
# ``strip``. The decoder reads gain codes from the top bytes (_GAIN_CODES).
_TOP_BYTES = ", ".join(str(8 * k + 7) for k in range(REGISTER_LANES))  # each lane's top byte


def record_avx512(force: Force) -> tuple[str, str, str, str]:
    """The AVX-512 body's recording (above) for ``force``, the masks holding the lanes in the
    strip, or those outside it where that is cheaper: where the strip is more than one run of
    pieces (the paper's wraps around x = 0), whose ``in_strip`` is an or of one test per run
    (``force.cpp_source``: a ``korb``) and its complement an and of their negations (one
    comparison masked by the other). The recording tells the decoder which in ``acc.strip_flip``
    (all ones: the rows hold the lanes outside), which the decoder's masks are xored with."""
    outside = len(_strip_runs(force)) > 1
    flip = "0xFFFFFFFFu" if outside else "0u"
    return (
        f"""
unsigned char* const scratch = acc.arrays.scratch.data;
int rows = acc.rows;
if (rows == 0) acc.base = global_step;
acc.strip_flip = {flip};
""",
        f"""{{
typedef unsigned char raw_r __attribute__((ext_vector_type({8 * REGISTER_LANES})));
typedef unsigned char top_r __attribute__((ext_vector_type({REGISTER_LANES})));
typedef bool bool_r __attribute__((ext_vector_type({REGISTER_LANES})));
const raw_r raw = __builtin_bit_cast(raw_r, gain);
const top_r top = __builtin_shufflevector(raw, raw, {_TOP_BYTES});
__builtin_memcpy(scratch + rows * {INTERLEAVE} + r * {REGISTER_LANES}, &top, sizeof(top_r));
const bool_r lanes = __builtin_convertvector(in_strip {"==" if outside else "!="} 0.0, bool_r);
scratch[{_STRIP} + 4 * rows + r] = __builtin_bit_cast(unsigned char, lanes);
}}
""",
        "rows = rows + 1;\n",
        "acc.rows = rows;\n",
    )


# _GAIN_CODES: a row's gain code is three bits of the gain's top byte ``t`` (C0, BF, 00, 3F, 40 hex
# for -2 .. 2): bit 0 of ``t`` (|gain| = 1), bit 6 (|gain| = 2), bit 7 (the sign), so gains 0, 1,
# 2, -1, -2 have codes 0, 1, 2, 5, 6 (a gain is never -0.0: it is ``floor(t) + lift`` with
# ``lift`` 1.0 or +0.0). The block decoding takes the three bit planes straight from the top bytes.


# The rows one by one (the trackers as byte vectors, the events as bool vectors), after the blocks.
_ROWS = """
for (int r = r0; r < rows; r++) {
    u8v top;
    __builtin_memcpy(&top, buffer + r * N, N);
    const bv in_strip = __builtin_bit_cast(bv, (mask_t)(strip[r] ^ acc.strip_flip));
    const u8v gain = gain_code(top);
    /* returns: a visit closes the gap of age + 1 steps */
    age = age + one;
    const bv r8 = tally_returns(in_strip & visited, age);
    rare_returns(__builtin_bit_cast(mask_t, in_strip & valid & ~r8), age);
    /* flights: a step with another gain ends the run in progress (if it gained) */
    const bv same = __builtin_convertvector(gain == fcode, bv);
    const bv ends = ~same & __builtin_convertvector(fcode != 0, bv) & valid;
    const bv up = ends & __builtin_convertvector(fcode < four, bv);
    const bv f8 = tally_flights(ends, up, flen);
    rare_flights(__builtin_bit_cast(mask_t, ~same & valid & ~f8), flen, fcode);
    age = in_strip ? (u8v)0 : age;
    visited = visited | (in_strip & valid);
    flen = same ? flen + one : one;
    fcode = gain;
}
"""

# The rows one by one from RECORD_CPU's coded bytes (the AVX2 path, 16 lanes): ``b = gain + 8 in_strip``
# (-2..2 outside B, 6..10 in it), the events as byte masks (0 or FF), so that no lane mask goes
# through a general-purpose register but the two that find the rare events. The same counts as
# _ROWS, operation for operation.
_ROWS_AVX2 = f"""
{{
typedef signed char s8v __attribute__((ext_vector_type({INTERLEAVE})));
typedef char c16 __attribute__((vector_size({INTERLEAVE})));
const u8v zero8 = 0, four_m = 4;
const u8v valid_m = zero8 - valid_bytes;
u8v seen_m = zero8 - __builtin_convertvector(__builtin_convertvector(visited, u8v) & one, u8v);
auto lanes_of = [](u8v m) {{ return (mask_t)__builtin_ia32_pmovmskb128((c16)m); }};
for (int r = r0; r < rows; r++) {{
    s8v b;
    __builtin_memcpy(&b, buffer + r * N, N);
    const u8v in_b = (u8v)(b > (s8v)5);
    const s8v g = b - (s8v)(in_b & eight);
    const u8v negative = (u8v)(g < (s8v)0);
    const u8v gain = negative ? (u8v)((s8v)4 - g) : (u8v)g; /* the code of _GAIN_CODES */
    /* returns: a visit closes the gap of age + 1 steps */
    age = age + one;
    const u8v returns = in_b & seen_m;
    const u8v a8 = (u8v)(age < eight);
    t[0] -= returns & (u8v)(age < two);
    t[1] -= returns & (u8v)(age < four);
    t[2] -= returns & a8;
    const u8v arrivals = in_b & valid_m;
    const mask_t rare_r = lanes_of(arrivals & ~a8);
    if (rare_r) {{
        unsigned char l[N], seen[N];
        __builtin_memcpy(l, &age, N);
        __builtin_memcpy(seen, &seen_m, N);
        for (mask_t bits = rare_r; bits; bits &= bits - 1) {{
            const int k = __builtin_ctz(bits);
            const int bin = {BINS - 1} - __builtin_clzll(age_extra[k] + l[k]);
            if (seen[k]) *wp::address(acc.arrays.counts, bin) += 1;
            age_extra[k] = 0;
        }}
    }}
    /* flights: a step with another gain ends the run in progress (if it gained) */
    const u8v same = (u8v)(gain == fcode);
    const u8v changed = ~same & valid_m;
    const u8v ends = changed & ~(u8v)(fcode == zero8);
    const u8v up = ends & (u8v)(fcode < four_m);
    const u8v f2 = (u8v)(flen < two), f4 = (u8v)(flen < four), f8 = (u8v)(flen < eight);
    t[3] -= ends & f2;
    t[4] -= ends & f4;
    t[5] -= ends & f8;
    t[6] -= up & f2;
    t[7] -= up & f4;
    t[8] -= up & f8;
    const mask_t rare_f = lanes_of(changed & ~f8);
    if (rare_f) rare_flights(rare_f, flen, fcode);
    age = age & ~in_b;
    seen_m = seen_m | arrivals;
    flen = same ? flen + one : one;
    fcode = gain;
}}
visited = __builtin_convertvector(seen_m & one, bv);
}}
"""

_CODED_ROWS = INTERLEAVE == 16

#: Decode the buffered rows (``after_check`` and ``store``); see the module docstring.
DECODE_CPU = (
    _TYPES
    + """
const int rows = acc.rows;
if (rows == 0) return;
"""
    + _CHECK_OWNER
    + f"""const int N = {INTERLEAVE};
unsigned char* const buffer = acc.arrays.scratch.data;
const unsigned int* const strip = (const unsigned int*)(buffer + {_STRIP}); /* 4 bytes a row */
unsigned char* const trackers = buffer + {_TRACKERS}; /* valid, visited, age, fcode, flen */
long long* const age_extra = (long long*)(buffer + {_EXTRA});
long long* const flen_extra = age_extra + N;
if (!acc.ready) {{
    /* First block of the thread: the carry (absolute global steps) becomes the trackers at the
       step before row 0 (lanes past the end: no visit, no flight). */
    const long long b0 = acc.base;
    i64v last_visit = -1, flight_gain = 0, flight_start = b0;
    if (WHOLE(acc)) {{
        __builtin_memcpy(&last_visit, wp::address(acc.arrays.last_visit, acc.first), sizeof(i64v));
        __builtin_memcpy(&flight_gain, wp::address(acc.arrays.flight_gain, acc.first), sizeof(i64v));
        __builtin_memcpy(&flight_start, wp::address(acc.arrays.flight_start, acc.first), sizeof(i64v));
    }} else {{
        for (int k = 0; k < acc.lanes; k++) {{
            const int i = acc.first + k * acc.spacing;
            last_visit[k] = *wp::address(acc.arrays.last_visit, i);
            flight_gain[k] = *wp::address(acc.arrays.flight_gain, i);
            flight_start[k] = *wp::address(acc.arrays.flight_start, i);
        }}
    }}
    const i64v zero64 = 0, cap64 = {CAP};
    const auto seen = last_visit >= zero64;
    const i64v a = seen ? b0 - last_visit : zero64;
    const i64v l = b0 - flight_start + 1;
    const i64v a_extra = a < cap64 ? zero64 : a - cap64, l_extra = l < cap64 ? zero64 : l - cap64;
    const u8v bytes[5] = {{
        __builtin_convertvector(lane_index < acc.lanes, u8v) & (u8v)1, /* valid */
        __builtin_convertvector(seen, u8v) & (u8v)1, /* visited */
        __builtin_convertvector(a - a_extra, u8v), /* age */
        __builtin_convertvector(flight_gain < zero64 ? 4 - flight_gain : flight_gain, u8v), /* fcode */
        __builtin_convertvector(l - l_extra, u8v)}}; /* flen */
    __builtin_memcpy(trackers, bytes, 5 * N);
    __builtin_memcpy(age_extra, &a_extra, sizeof(i64v));
    __builtin_memcpy(flen_extra, &l_extra, sizeof(i64v));
    acc.ready = 1;
}}
u8v age, visited_bytes, fcode, flen, valid_bytes;
__builtin_memcpy(&valid_bytes, trackers, N);
__builtin_memcpy(&visited_bytes, trackers + N, N);
__builtin_memcpy(&age, trackers + 2 * N, N);
__builtin_memcpy(&fcode, trackers + 3 * N, N);
__builtin_memcpy(&flen, trackers + 4 * N, N);
const bv valid = __builtin_convertvector(valid_bytes, bv);
bv visited = __builtin_convertvector(visited_bytes, bv);
/* cumulative tallies per lane (at most 128 per decode, bytes do not overflow): returns < 2, < 4, < 8;
   flight ends < 2, < 4, < 8; positive ones < 2, < 4, < 8 */
u8v t[9];
for (int i = 0; i < 9; i++) t[i] = 0;
const u8v one = 1, two = 2, four = 4, eight = 8;
/* Runs of 8 steps or more, one by one: a visit to B closes a gap of extra + length steps (counted
   if the point had visited B before; a first visit only resets the tracker); a run of another
   gain code ends a run of extra + length steps (counted if it gained). */
auto rare_returns = [&](mask_t bits, u8v length) {{
    if (!bits) return;
    unsigned char l[N], seen[N];
    const u8v seen_bytes = __builtin_convertvector(visited, u8v);
    __builtin_memcpy(l, &length, N);
    __builtin_memcpy(seen, &seen_bytes, N);
    for (; bits; bits &= bits - 1) {{
        const int k = __builtin_ctz(bits);
        if (seen[k]) *wp::address(acc.arrays.counts, {BINS - 1} - __builtin_clzll(age_extra[k] + l[k])) += 1;
        age_extra[k] = 0;
    }}
}};
auto rare_flights = [&](mask_t bits, u8v length, u8v code) {{
    if (!bits) return;
    unsigned char l[N], c[N];
    __builtin_memcpy(l, &length, N);
    __builtin_memcpy(c, &code, N);
    for (; bits; bits &= bits - 1) {{
        const int k = __builtin_ctz(bits);
        const int histogram = c[k] < 4 ? {BINS} : {2 * BINS};
        const int bin = histogram + {BINS - 1} - __builtin_clzll(flen_extra[k] + l[k]);
        if (c[k] != 0) *wp::address(acc.arrays.counts, bin) += 1;
        flen_extra[k] = 0;
    }}
}};
/* Runs shorter than 8 steps, in the per-lane byte tallies: returns (events) of length < 2, < 4,
   < 8; flights that end (ends; up: those that gained) likewise. Each returns "length < 8". */
auto tally_returns = [&](bv events, u8v length) {{
    const bv r8 = __builtin_convertvector(length < eight, bv);
    t[0] += __builtin_convertvector(events & __builtin_convertvector(length < two, bv), u8v) & one;
    t[1] += __builtin_convertvector(events & __builtin_convertvector(length < four, bv), u8v) & one;
    t[2] += __builtin_convertvector(events & r8, u8v) & one;
    return r8;
}};
auto tally_flights = [&](bv ends, bv up, u8v length) {{
    const bv c2 = __builtin_convertvector(length < two, bv), c4 = __builtin_convertvector(length < four, bv);
    const bv c8 = __builtin_convertvector(length < eight, bv);
    t[3] += __builtin_convertvector(ends & c2, u8v) & one;
    t[4] += __builtin_convertvector(ends & c4, u8v) & one;
    t[5] += __builtin_convertvector(ends & c8, u8v) & one;
    t[6] += __builtin_convertvector(up & c2, u8v) & one;
    t[7] += __builtin_convertvector(up & c4, u8v) & one;
    t[8] += __builtin_convertvector(up & c8, u8v) & one;
    return c8;
}};
/* the gain code of a gain's top byte (_GAIN_CODES) */
auto gain_code = [](u8v top) {{ return (top & (u8v)1) | ((top >> 5) & (u8v)6); }};
(void)gain_code;
"""
    + f"int r0 = 0;\nconst int block_rows = acc.arrays.scratch.shape[0] == {SCRATCH_BYTES} ? 8 : 1;\n"
    + (BLOCK_CODED_CPU + _ROWS_AVX2 if _CODED_ROWS else BLOCK_CPU + _ROWS)
    + f"""/* bytes stay at most CAP: the excess moves to the int64 parts (exact) */
const u8v cap = {CAP};
const mask_t long_age = __builtin_bit_cast(mask_t, __builtin_convertvector(age > cap, bv));
const mask_t long_flen = __builtin_bit_cast(mask_t, __builtin_convertvector(flen > cap, bv));
if ((long_age | long_flen) != 0) {{
    unsigned char a[N], l[N];
    __builtin_memcpy(a, &age, N);
    __builtin_memcpy(l, &flen, N);
    for (mask_t bits = long_age; bits; bits &= bits - 1) {{
        const int k = __builtin_ctz(bits);
        age_extra[k] += a[k] - {CAP};
    }}
    for (mask_t bits = long_flen; bits; bits &= bits - 1) {{
        const int k = __builtin_ctz(bits);
        flen_extra[k] += l[k] - {CAP};
    }}
    age = __builtin_elementwise_min(age, cap);
    flen = __builtin_elementwise_min(flen, cap);
}}
for (int i = 0; i < 9; i++) acc.tallies.c[i] += __builtin_reduce_add(__builtin_convertvector(t[i], u16v));
visited_bytes = __builtin_convertvector(visited, u8v);
__builtin_memcpy(trackers + N, &visited_bytes, N);
__builtin_memcpy(trackers + 2 * N, &age, N);
__builtin_memcpy(trackers + 3 * N, &fcode, N);
__builtin_memcpy(trackers + 4 * N, &flen, N);
acc.base += rows;
acc.rows = 0;
"""
)

#: ``store`` after the last decode: the trackers back to the carry (absolute global steps; left as
#: loaded if the thread decoded nothing) and the tallies into the histogram bins 0-2. The rare
#: events went straight into the launch's histogram array (plain adds, as Warp's CPU atomics:
#: a CPU launch runs its threads one after the other).
FINISH_CPU = (
    _TYPES
    + f"""
const int N = {INTERLEAVE};
const unsigned char* const trackers = acc.arrays.scratch.data + {_TRACKERS};
const long long* const age_extra = (const long long*)(acc.arrays.scratch.data + {_EXTRA});
const long long* const flen_extra = age_extra + N;
if (acc.ready) {{
"""
    + _CHECK_OWNER
    + f"""
    u8v bytes[5];
    i64v a_extra, l_extra;
    __builtin_memcpy(bytes, trackers, 5 * N);
    __builtin_memcpy(&a_extra, age_extra, sizeof(i64v));
    __builtin_memcpy(&l_extra, flen_extra, sizeof(i64v));
    i64v wide[5]; /* valid, visited, age, fcode, flen */
    for (int j = 1; j < 5; j++) wide[j] = __builtin_convertvector(bytes[j], i64v);
    const i64v last_visit = wide[1] != 0 ? acc.base - (a_extra + wide[2]) : -1;
    const i64v flight_gain = wide[3] >= 4 ? 4 - wide[3] : wide[3]; /* codes 0, 1, 2, 5, 6: 0..2, -1, -2 */
    const i64v flight_start = acc.base - (l_extra + wide[4]) + 1;
    if (WHOLE(acc)) {{
        __builtin_memcpy(wp::address(acc.arrays.last_visit, acc.first), &last_visit, sizeof(i64v));
        __builtin_memcpy(wp::address(acc.arrays.flight_gain, acc.first), &flight_gain, sizeof(i64v));
        __builtin_memcpy(wp::address(acc.arrays.flight_start, acc.first), &flight_start, sizeof(i64v));
    }} else {{
        for (int k = 0; k < acc.lanes; k++) {{
            const int i = acc.first + k * acc.spacing;
            *wp::address(acc.arrays.last_visit, i) = last_visit[k];
            *wp::address(acc.arrays.flight_gain, i) = flight_gain[k];
            *wp::address(acc.arrays.flight_start, i) = flight_start[k];
        }}
    }}
}}
/* the cumulative tallies of lengths < 2, < 4, < 8 give bins 0, 1, 2 (DECODE_CPU) */
const long long* t = acc.tallies.c;
const long long c[9] = {{
    t[0], t[1] - t[0], t[2] - t[1],
    t[6], t[7] - t[6], t[8] - t[7],
    t[3] - t[6], (t[4] - t[3]) - (t[7] - t[6]), (t[5] - t[4]) - (t[8] - t[7])}};
for (int h = 0; h < 3; h++)
    for (int b = 0; b < 3; b++)
        if (c[3 * h + b] != 0) *wp::address(acc.arrays.counts, h * {BINS} + b) += c[3 * h + b];
"""
)
