"""The CPU hooks of the transport variant: per-step codes, decoded in blocks of steps.

Counting inside the step loop, lane by lane, costs far more than the step (a CPU thread holds
:data:`INTERLEAVE` points in vector registers, and the step already uses nearly all of them):
70x with the portable hooks' scalar loop, 2-3x with the trackers kept as vectors beside the
state (the registers spill). So the CPU hooks split the work:

* after each step (``after_step``): one byte per lane, ``code = gain + 2 + 8 * in_strip`` (the
  step's facts; ``|gain| <= 2`` since ``|K f| < 2``), is stored into a small buffer of rows;
* after each renormalisation check and at the end of the launch (``store``): the buffered rows
  are decoded with the trackers as byte vectors (all lanes of a row at once), each row's events
  counted by lengths ``< 2``, ``< 4``, ``< 8`` with a popcount of the event mask; the rare events
  of length 8 or more go to the thread's histogram one by one.

Trackers: ``age`` (steps since the last visit to B), ``flen`` (steps of the run in progress) are
bytes kept at most :data:`CAP` after each block, the excess carried exactly in int64 (``*_extra``);
``fcode`` is the gain code of the run in progress. The carry arrays hold absolute global steps;
the first block of a launch converts them (the buffer knows its global steps) and ``store``
converts back. Every count equals the portable hooks' (``tests/test_transport.py``).
"""

from .step import INTERLEAVE

__all__ = ["BINS", "CAP", "STEP_CPU", "DECODE_CPU"]

#: Histogram bins: bin ``k`` counts lengths ``2^k <= L < 2^(k+1)``; 64 cover every int64 step count.
BINS = 64

#: A byte tracker above this after a block moves its excess to the int64 part (a block adds at
#: most 8 steps, so bytes stay below 256).
CAP = 64

_MASK = "unsigned int" if INTERLEAVE == 32 else "unsigned short"

_TYPES = f"""
typedef unsigned char u8v __attribute__((ext_vector_type({INTERLEAVE})));
typedef unsigned short u16v __attribute__((ext_vector_type({INTERLEAVE})));
typedef bool bv __attribute__((ext_vector_type({INTERLEAVE})));
typedef {_MASK} mask_t;
"""

#: ``after_step``: store this step's codes as a row of the buffer.
STEP_CPU = f"""
typedef double v_t __attribute__((ext_vector_type({INTERLEAVE})));
typedef unsigned char u8v __attribute__((ext_vector_type({INTERLEAVE})));
v_t gain, in_strip;
__builtin_memcpy(&gain, &s.gain, sizeof(v_t));
__builtin_memcpy(&in_strip, &s.in_strip, sizeof(v_t));
const v_t two = 2.0, ten = 10.0;
const v_t outside = gain + two, inside = gain + ten;
const v_t code = in_strip != 0.0 ? inside : outside;
const u8v row = __builtin_convertvector(code, u8v);
if (acc.rows == 0) acc.base = global_step - 1;
__builtin_memcpy(&acc.buffer.c[acc.rows * {INTERLEAVE}], &row, sizeof(u8v));
acc.rows = acc.rows + 1;
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
        fcode[k] = valid[k] ? (unsigned char)(flight_gain[k] + 2) : 2;
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
/* cumulative tallies per lane (at most 8 per block, bytes do not overflow): returns < 2, < 4, < 8;
   flight ends < 2, < 4, < 8; positive ones < 2, < 4, < 8 */
u8v t[9];
for (int i = 0; i < 9; i++) t[i] = 0;
const u8v one = 1, two = 2, four = 4, eight = 8, seven = 7;
for (int r = 0; r < rows; r++) {{
    u8v code;
    __builtin_memcpy(&code, &acc.buffer.c[r * N], N);
    const bv in_strip = __builtin_convertvector((code & eight) != 0, bv);
    const u8v gain = code & seven;
    /* returns: a visit closes the gap of age + 1 steps */
    age = age + one;
    const bv visit = in_strip & visited;
    const bv r2 = __builtin_convertvector(age < two, bv);
    const bv r4 = __builtin_convertvector(age < four, bv);
    const bv r8 = __builtin_convertvector(age < eight, bv);
    t[0] += __builtin_convertvector(visit & r2, u8v) & one;
    t[1] += __builtin_convertvector(visit & r4, u8v) & one;
    t[2] += __builtin_convertvector(visit & r8, u8v) & one;
    /* a visit after 8 or more steps (also a first visit, which only resets the tracker) */
    const mask_t long_returns = __builtin_bit_cast(mask_t, in_strip & valid & ~r8);
    /* flights: a step with another gain ends the run in progress (if it gained) */
    const bv same = __builtin_convertvector(gain == fcode, bv);
    const bv ends = ~same & __builtin_convertvector(fcode != two, bv) & valid;
    const bv up = ends & __builtin_convertvector(fcode > two, bv);
    const bv f2 = __builtin_convertvector(flen < two, bv);
    const bv f4 = __builtin_convertvector(flen < four, bv);
    const bv f8 = __builtin_convertvector(flen < eight, bv);
    t[3] += __builtin_convertvector(ends & f2, u8v) & one;
    t[4] += __builtin_convertvector(ends & f4, u8v) & one;
    t[5] += __builtin_convertvector(ends & f8, u8v) & one;
    t[6] += __builtin_convertvector(up & f2, u8v) & one;
    t[7] += __builtin_convertvector(up & f4, u8v) & one;
    t[8] += __builtin_convertvector(up & f8, u8v) & one;
    /* a run of 8 or more steps ends (also a run that gained nothing, which is not counted) */
    const mask_t long_flights = __builtin_bit_cast(mask_t, ~same & valid & ~f8);
    if ((long_returns | long_flights) != 0) {{
        unsigned char a[N], l[N], c[N];
        const u8v seen = __builtin_convertvector(visited, u8v);
        unsigned char v[N];
        __builtin_memcpy(a, &age, N);
        __builtin_memcpy(l, &flen, N);
        __builtin_memcpy(c, &fcode, N);
        __builtin_memcpy(v, &seen, N);
        for (mask_t bits = long_returns; bits; bits &= bits - 1) {{
            const int k = __builtin_ctz(bits);
            if (v[k]) acc.counts.c[{BINS - 1} - __builtin_clzll(age_extra[k] + a[k])] += 1;
            age_extra[k] = 0;
        }}
        for (mask_t bits = long_flights; bits; bits &= bits - 1) {{
            const int k = __builtin_ctz(bits);
            const int histogram = c[k] > 2 ? {BINS} : {2 * BINS};
            if (c[k] != 2) acc.counts.c[histogram + {BINS - 1} - __builtin_clzll(flen_extra[k] + l[k])] += 1;
            flen_extra[k] = 0;
        }}
    }}
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
