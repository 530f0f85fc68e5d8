"""The CPU hooks of the transport variant: per-step codes, decoded in blocks of steps.

Counting inside the step loop, lane by lane, costs far more than the step (a CPU thread holds
:data:`INTERLEAVE` points in vector registers, and the step already uses nearly all of them):
70x with the portable hooks' scalar loop, 2-3x with the trackers kept as vectors beside the
state (the registers spill). So the CPU hooks split the work:

* after each step (``after_step``): the step's facts, as they come out of it, into a buffer of
  128 rows: the top byte of each lane's ``gain`` (``|gain| <= 2`` since ``|K f| < 2``; each value
  has its own top byte) and the ``in_strip`` lanes as a 32-bit mask;
* at the renormalisation check (every 8 steps) that leaves fewer than 8 rows free, and at the end
  of the launch (``store``): the rows are decoded (the gain codes are three bits of the top
  bytes, ``_GAIN_CODES``) with the trackers as byte vectors (all lanes of a row at once), each
  row's events counted by lengths ``< 2``, ``< 4``, ``< 8`` with a popcount of the event mask;
  the rare events of length 8 or more go to the thread's histogram one by one. Where the CPU has AVX-512 and
  GFNI, each full block of 8 rows is decoded at once instead: transposed into bit planes (one byte
  per lane, bit i = row i), its visits and gain changes found with bit tricks on the planes.

Trackers: ``age`` (steps since the last visit to B), ``flen`` (steps of the run in progress) are
bytes kept at most :data:`CAP` after each block, the excess carried exactly in int64 (``*_extra``);
``fcode`` is the gain code of the run in progress. The carry arrays hold absolute global steps;
the first block of a launch converts them (the buffer knows its global steps) and ``store``
converts back. Every count equals the portable hooks' (``tests/test_transport.py``).
"""

from .step import INTERLEAVE

__all__ = ["BINS", "CAP", "STEP_CPU", "DECODE_CPU", "FINISH_CPU"]

#: Histogram bins: bin ``k`` counts lengths ``2^k <= L < 2^(k+1)``; 64 cover every int64 step count.
BINS = 64

#: A byte tracker above this after a block moves its excess to the int64 part (a decode adds at
#: most 128 steps, so bytes stay below 256).
CAP = 64

_MASK = "unsigned int" if INTERLEAVE == 32 else "unsigned short"

_TYPES = f"""
typedef unsigned char u8v __attribute__((ext_vector_type({INTERLEAVE})));
typedef unsigned short u16v __attribute__((ext_vector_type({INTERLEAVE})));
typedef bool bv __attribute__((ext_vector_type({INTERLEAVE})));
typedef {_MASK} mask_t;
"""

#: ``after_step``: store this step's facts as they come out of the step, with no conversion: the
#: top byte of each lane's ``gain`` (a double in -2..2: C0, BF, 00, 3F, 40 hex, one per value) into
#: the buffer row, and the ``in_strip`` lanes as one bit each into ``strip`` (a 32-bit mask from
#: the step's own comparisons). The decoder reads gain codes from the top bytes (_GAIN_CODES).
STEP_CPU = f"""
typedef double v_t __attribute__((ext_vector_type({INTERLEAVE})));
typedef unsigned char u8v __attribute__((ext_vector_type({INTERLEAVE})));
typedef unsigned char raw_t __attribute__((ext_vector_type({8 * INTERLEAVE})));
typedef bool bv __attribute__((ext_vector_type({INTERLEAVE})));
v_t gain, in_strip;
__builtin_memcpy(&gain, &s.gain, sizeof(v_t));
__builtin_memcpy(&in_strip, &s.in_strip, sizeof(v_t));
const raw_t raw = __builtin_bit_cast(raw_t, gain);
const u8v top = __builtin_shufflevector(raw, raw, {", ".join(str(8 * k + 7) for k in range(INTERLEAVE))});
const bv inside = __builtin_convertvector(in_strip != 0.0, bv);
if (acc.rows == 0) acc.base = global_step - 1;
__builtin_memcpy(&acc.buffer.c[acc.rows * {INTERLEAVE}], &top, sizeof(u8v));
acc.strip.c[acc.rows] = __builtin_bit_cast({_MASK}, inside);
acc.rows = acc.rows + 1;
"""

# _GAIN_CODES: a row's gain code is three bits of the gain's top byte ``t`` (C0, BF, 00, 3F, 40 hex
# for -2 .. 2): bit 0 of ``t`` (|gain| = 1), bit 6 (|gain| = 2), bit 7 (the sign), so gains 0, 1,
# 2, -1, -2 have codes 0, 1, 2, 5, 6 (a gain is never -0.0: it is ``floor(t) + lift`` with
# ``lift`` 1.0 or +0.0). The block decoding takes the three bit planes straight from the top bytes.


def _indices(values) -> str:
    return ", ".join(str(v) for v in values)


# Block decoding (a full block of 8 rows, AVX-512 with GFNI): the 8 x 32 codes become bit planes
# (byte l of plane b: bit i = bit b of lane l's code at row i), in three byte shuffles and two
# rounds of GF2P8AFFINEQB, which transposes the 8 x 8 bit matrix in each 64-bit word (with the
# word as the matrix operand, byte p holding matrix row 7 - p). Stage 1: per (row, octet of
# lanes) word, byte b = bit b of the octet's codes (bit i = lane 7 - i of the octet). Stage 2:
# gather for each (plane, octet) the 8 rows' bytes, row 7 - p at byte p. Stage 3: transpose again:
# byte k of word (plane b, octet j) = lane 8 j + 7 - k over the rows. Stage 4: lanes in order.
_STAGE2 = [
    ((7 - p) * 4 + j) * 8 + b for b in (0, 6, 7) for j in range(4) for p in range(8)
]  # output byte (b * 4 + j) * 8 + p: the gain code's planes are bits 0, 6, 7 of the top bytes
# the in_strip plane from the rows' masks (bits reversed: byte j of a row = its octet j)
_STAGE2 += [128 + (7 - p) * 4 + j for j in range(4) for p in range(8)]
_STAGE4 = [[(b * 4 + lane // 8) * 8 + 7 - lane % 8 for lane in range(32)] for b in range(4)]

_BLOCK_CPU = f"""
#if defined(__GFNI__) && defined(__AVX512BW__)
for (; r0 + 8 <= rows; r0 += 8) {{
    typedef char i8x64 __attribute__((vector_size(64)));
    typedef unsigned char u8x64 __attribute__((ext_vector_type(64)));
    typedef unsigned char u8x128 __attribute__((ext_vector_type(128)));
    typedef long long i64x8 __attribute__((vector_size(64)));
    const long long T = 0x8040201008040201LL; /* byte j = 1 << j: the transpose */
    const i64x8 transpose = {{T, T, T, T, T, T, T, T}};
    u8x64 rows01, rows23, rows45, rows67;
    __builtin_memcpy(&rows01, &acc.buffer.c[r0 * N + 0], 64);
    __builtin_memcpy(&rows23, &acc.buffer.c[r0 * N + 64], 64);
    __builtin_memcpy(&rows45, &acc.buffer.c[r0 * N + 128], 64);
    __builtin_memcpy(&rows67, &acc.buffer.c[r0 * N + 192], 64);
#define GF_T(v) ((u8x64)__builtin_ia32_vgf2p8affineqb_v64qi((i8x64)transpose, (i8x64)(v), 0))
    const u8x64 s01 = GF_T(rows01), s23 = GF_T(rows23), s45 = GF_T(rows45), s67 = GF_T(rows67);
    u8x64 strip_rows = 0;
    __builtin_memcpy(&strip_rows, &acc.strip.c[r0], 32);
    /* x = the masks' bytes, matrix T: bit i of each byte becomes bit 7 - i */
    const u8x64 strip_reversed =
        (u8x64)__builtin_ia32_vgf2p8affineqb_v64qi((i8x64)strip_rows, (i8x64)transpose, 0);
    const u8x128 lo = __builtin_shufflevector(s01, s23, {_indices(range(128))});
    const u8x128 hi = __builtin_shufflevector(s45, s67, {_indices(range(128))});
    const u8x128 gain_planes = __builtin_shufflevector(lo, hi, {_indices(_STAGE2[:96] + [0] * 32)});
    const u8x128 strip_planes =
        __builtin_shufflevector(strip_reversed, strip_reversed, {_indices(range(128))});
    const u8x128 gathered =
        __builtin_shufflevector(gain_planes, strip_planes, {_indices(list(range(96)) + _STAGE2[96:])});
    const u8x64 g01 = __builtin_shufflevector(gathered, gathered, {_indices(range(64))});
    const u8x64 g23 = __builtin_shufflevector(gathered, gathered, {_indices(range(64, 128))});
    const u8x64 t01 = GF_T(g01), t23 = GF_T(g23);
#undef GF_T
    const u8x128 planes = __builtin_shufflevector(t01, t23, {_indices(range(128))});
    const u8v G0 = __builtin_shufflevector(planes, planes, {_indices(_STAGE4[0])});
    const u8v G1 = __builtin_shufflevector(planes, planes, {_indices(_STAGE4[1])});
    const u8v G2 = __builtin_shufflevector(planes, planes, {_indices(_STAGE4[2])});
    const u8v I = __builtin_shufflevector(planes, planes, {_indices(_STAGE4[3])});
    const u8v zero = 0;
    const u8v valid_mask = valid_bytes * (u8v)0xFF;
    /* -- returns: V, bit i = a visit at row i -- */
    const u8v V = I & valid_mask;
    const bv has = __builtin_convertvector(V != zero, bv);
    const u8v f = ctz8(V);
    const u8v gap0 = age + f + one;
    const bv r8 = tally_returns(has & visited, gap0);
    rare_returns(__builtin_bit_cast(mask_t, has & ~r8), gap0);
    /* the visits after the first: gaps of 1 to 7 steps, from the rows before them */
    const u8v later = V & (V - one);
    const u8v before1 = V << 1, before2 = V << 2, before3 = V << 3; /* a visit 1, 2, 3 rows before */
    const u8v ge2 = later & ~before1;
    const u8v ge4 = ge2 & ~before2 & ~before3;
    const u8v all = popcount8(later);
    t[0] += all - popcount8(ge2);
    t[1] += all - popcount8(ge4);
    t[2] += all;
    age = has ? clz8(V) : age + eight;
    visited = visited | has;
    /* -- flights: bit i of B = the gain code changes at row i (row 0 against the block before) -- */
    const u8v p0 = fcode & one, p1 = (fcode >> 1) & one, p2 = fcode >> 2;
    const u8v B = (G0 ^ ((G0 + G0) | p0)) | (G1 ^ ((G1 + G1) | p1)) | (G2 ^ ((G2 + G2) | p2));
    const u8v up_rows = ~G2 & (G1 | G0), down_rows = G2;
    const u8v fb = ctz8(B);
    const bv ends = __builtin_convertvector(B != zero, bv) & valid;
    const u8v length0 = flen + fb;
    const bv moving = ends & __builtin_convertvector(fcode != 0, bv);
    const bv up0 = moving & __builtin_convertvector(fcode < four, bv);
    const bv c8 = tally_flights(moving, up0, length0);
    rare_flights(__builtin_bit_cast(mask_t, ends & ~c8), length0, fcode);
    /* runs that start at a boundary and end at the next one within the block (the last carries) */
    const u8v last_boundary = reverse8(lowest8(reverse8(B)));
    const u8v starts = (B ^ last_boundary) & valid_mask;
    const u8v C = ~B;
    const u8v e2 = C >> 1, e4 = e2 & (C >> 2) & (C >> 3);
    const u8v up_starts = starts & up_rows, down_starts = starts & down_rows;
    const u8v n_up = popcount8(up_starts), n_down = popcount8(down_starts);
    const u8v up2 = popcount8(up_starts & e2), up4 = popcount8(up_starts & e4);
    const u8v down2 = popcount8(down_starts & e2), down4 = popcount8(down_starts & e4);
    t[3] += (n_up - up2) + (n_down - down2);
    t[4] += (n_up - up4) + (n_down - down4);
    t[5] += n_up + n_down;
    t[6] += n_up - up2;
    t[7] += n_up - up4;
    t[8] += n_up;
    flen = ends ? clz8(B) + one : flen + eight;
    u8v last_row;
    __builtin_memcpy(&last_row, &acc.buffer.c[(r0 + 7) * N], N);
    fcode = gain_code(last_row);
}}
#endif
"""

#: Decode the buffered rows (``after_check`` and ``store``); see the module docstring.
DECODE_CPU = (
    _TYPES
    + f"""
const int rows = acc.rows;
if (rows == 0) return;
const int N = {INTERLEAVE};
long long* age_extra = (long long*)&acc.age_extra;
long long* flen_extra = (long long*)&acc.flen_extra;
if (!acc.ready) {{
    /* First block of the launch: the carry (absolute global steps) becomes the trackers at the
       step before row 0. */
    const long long b0 = acc.base;
    const long long* last_visit = (const long long*)&acc.last_visit;
    const long long* flight_gain = (const long long*)&acc.flight_gain;
    const long long* flight_start = (const long long*)&acc.flight_start;
    unsigned char visited[N], fcode[N], age[N], flen[N], valid[N];
    for (int k = 0; k < N; k++) {{
        valid[k] = k < acc.lanes;
        visited[k] = valid[k] && last_visit[k] >= 0;
        const long long a = visited[k] ? b0 - last_visit[k] : 0;
        age[k] = a < {CAP} ? (unsigned char)a : {CAP};
        age_extra[k] = a < {CAP} ? 0 : a - {CAP};
        const long long g = valid[k] ? flight_gain[k] : 0;
        fcode[k] = (unsigned char)(g < 0 ? 4 - g : g);
        const long long l = b0 - flight_start[k] + 1;
        flen[k] = l < {CAP} ? (unsigned char)l : {CAP};
        flen_extra[k] = l < {CAP} ? 0 : l - {CAP};
    }}
    __builtin_memcpy(&acc.visited, visited, N);
    __builtin_memcpy(&acc.fcode, fcode, N);
    __builtin_memcpy(&acc.age, age, N);
    __builtin_memcpy(&acc.flen, flen, N);
    __builtin_memcpy(&acc.valid, valid, N);
    acc.ready = 1;
}}
u8v age, visited_bytes, fcode, flen, valid_bytes;
__builtin_memcpy(&age, &acc.age, N);
__builtin_memcpy(&visited_bytes, &acc.visited, N);
__builtin_memcpy(&fcode, &acc.fcode, N);
__builtin_memcpy(&flen, &acc.flen, N);
__builtin_memcpy(&valid_bytes, &acc.valid, N);
const bv valid = __builtin_convertvector(valid_bytes, bv);
bv visited = __builtin_convertvector(visited_bytes, bv);
/* cumulative tallies per lane (at most 128 per decode, bytes do not overflow): returns < 2, < 4, < 8;
   flight ends < 2, < 4, < 8; positive ones < 2, < 4, < 8 */
u8v t[9];
for (int i = 0; i < 9; i++) t[i] = 0;
const u8v one = 1, two = 2, four = 4, eight = 8, seven = 7;
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
        if (seen[k]) acc.counts.c[{BINS - 1} - __builtin_clzll(age_extra[k] + l[k])] += 1;
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
        if (c[k] != 0) acc.counts.c[histogram + {BINS - 1} - __builtin_clzll(flen_extra[k] + l[k])] += 1;
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
auto popcount8 = [](u8v v) {{ return __builtin_elementwise_popcount(v); }};
/* bit tricks on bytes: trailing zeros (8 for 0), leading zeros, bit reversal, lowest set bit */
auto ctz8 = [](u8v v) {{ return __builtin_elementwise_popcount((v & (u8v)(0 - v)) - (u8v)1); }};
auto reverse8 = [](u8v v) {{
    v = ((v >> 1) & (u8v)0x55) | ((v & (u8v)0x55) << 1);
    v = ((v >> 2) & (u8v)0x33) | ((v & (u8v)0x33) << 2);
    return (v >> 4) | (v << 4);
}};
auto clz8 = [&](u8v v) {{ return ctz8(reverse8(v)); }};
auto lowest8 = [](u8v v) {{ return v & (u8v)(0 - v); }};
/* the gain code of a gain's top byte (_GAIN_CODES) */
auto gain_code = [](u8v top) {{ return (top & (u8v)1) | ((top >> 5) & (u8v)6); }};
(void)reverse8; (void)clz8; (void)lowest8; (void)ctz8; (void)popcount8; (void)gain_code;
"""
    + "int r0 = 0;\n"
    + _BLOCK_CPU
    + f"""
for (int r = r0; r < rows; r++) {{
    u8v top;
    __builtin_memcpy(&top, &acc.buffer.c[r * N], N);
    const bv in_strip = __builtin_bit_cast(bv, (mask_t)acc.strip.c[r]);
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
}}
/* bytes stay at most CAP: the excess moves to the int64 parts (exact) */
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
__builtin_memcpy(&acc.visited, &visited_bytes, N);
__builtin_memcpy(&acc.age, &age, N);
__builtin_memcpy(&acc.fcode, &fcode, N);
__builtin_memcpy(&acc.flen, &flen, N);
acc.base += rows;
acc.rows = 0;
"""
)

#: ``store`` after the last decode: the trackers back to the carry (absolute global steps; as loaded
#: if the launch decoded nothing), the tallies into the histogram bins 0-2, and both into the arrays
#: (the thread's histogram by one atomic add per non-empty bin). In C++: the same work in Warp
#: copied the 1.5 KB histogram vector at every element it read (a few microseconds per thread and
#: launch, a tenth of a launch of 300 steps).
FINISH_CPU = f"""
const int N = {INTERLEAVE};
long long last_visit[N], flight_gain[N], flight_start[N];
__builtin_memcpy(last_visit, &acc.last_visit, sizeof(last_visit));
__builtin_memcpy(flight_gain, &acc.flight_gain, sizeof(flight_gain));
__builtin_memcpy(flight_start, &acc.flight_start, sizeof(flight_start));
if (acc.ready) {{
    for (int k = 0; k < N; k++) {{
        last_visit[k] = acc.visited.c[k] ? acc.base - (acc.age_extra.c[k] + acc.age.c[k]) : -1;
        const long long code = acc.fcode.c[k]; /* gain codes 0, 1, 2, 5, 6 for 0, 1, 2, -1, -2 */
        flight_gain[k] = code >= 4 ? 4 - code : code;
        flight_start[k] = acc.base - (acc.flen_extra.c[k] + acc.flen.c[k]) + 1;
    }}
}}
for (int k = 0; k < N; k++) {{
    const int i = first + k * spacing;
    if (i < n) {{
        *wp::address(arrays.last_visit, i) = last_visit[k];
        *wp::address(arrays.flight_gain, i) = flight_gain[k];
        *wp::address(arrays.flight_start, i) = flight_start[k];
    }}
}}
/* the cumulative tallies of lengths < 2, < 4, < 8 give bins 0, 1, 2 (DECODE_CPU) */
long long c[{3 * BINS}];
__builtin_memcpy(c, &acc.counts, sizeof(c));
const long long* t = acc.tallies.c;
c[0] += t[0];
c[1] += t[1] - t[0];
c[2] += t[2] - t[1];
c[{BINS}] += t[6];
c[{BINS + 1}] += t[7] - t[6];
c[{BINS + 2}] += t[8] - t[7];
c[{2 * BINS}] += t[3] - t[6];
c[{2 * BINS + 1}] += (t[4] - t[3]) - (t[7] - t[6]);
c[{2 * BINS + 2}] += (t[5] - t[4]) - (t[8] - t[7]);
for (int b = 0; b < {3 * BINS}; b++)
    if (c[b] != 0) wp::atomic_add(wp::address(arrays.counts, b), c[b]);
"""
