"""The transport CPU hooks' block decoding: 8 buffered rows at once, as bit planes.

A C++ snippet, :data:`BLOCK_CPU`, inserted into :data:`~._transport_cpu.DECODE_CPU` before its row
by row loop (it uses that snippet's trackers, tallies and helpers): each full block of 8 rows is
transposed into bit planes (one byte per lane, bit i = row i), and its visits to B and gain
changes are found with bit tricks on the planes. On the AVX2 path (16 lanes, rows as coded bytes)
:data:`BLOCK_CODED_CPU` does the same from planes built with byte masks, popcounts and bit
reversals as nibble table lookups; on an AVX-512 CPU without GFNI the block compiles to nothing
and every row goes through the loop. A launch with ``block_rows=1`` takes the row loop alone on
any CPU, so the tests check both against the NumPy twin, count for count
(``tests/analyses/test_transport.py``).

Why blocks of 8 rows: 16-row blocks (two 8-row transposes interleaved, 512-bit bit tricks) take
fewer instructions per row, but a 512-bit operation takes two 256-bit slots on the CPUs measured,
so per row they cost as much; bit-plane work costs the same per bit at any block size. The
measurements, and where a block's time goes, are in ``benchmarks/README.md`` ("The transport
decoder's blocks of 8 rows").
"""

__all__ = ["BLOCK_CPU", "BLOCK_CODED_CPU"]


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

#: The bit planes of 8 buffered rows (a lambda for both block sizes): ``planes8(r, out)`` sets
#: ``out[0..2]`` to the gain code's planes and ``out[3]`` to the in_strip plane of rows r .. r+7
#: (byte l of each: bit i = lane l at row r + i).
_PLANES8 = f"""
typedef char i8x64 __attribute__((vector_size(64)));
typedef unsigned char u8x64 __attribute__((ext_vector_type(64)));
typedef unsigned char u8x128 __attribute__((ext_vector_type(128)));
typedef long long i64x8 __attribute__((vector_size(64)));
const long long T = 0x8040201008040201LL; /* byte j = 1 << j: the transpose */
const i64x8 transpose = {{T, T, T, T, T, T, T, T}};
typedef unsigned int u32x16 __attribute__((ext_vector_type(16)));
const unsigned int f = acc.strip_flip; /* 8 rows' masks, 32 bytes, xored with it */
const u8x64 strip_flip = __builtin_bit_cast(u8x64, (u32x16){{f, f, f, f, f, f, f, f}});
auto planes8 = [&](const int r, u8v* out) {{
    u8x64 rows01, rows23, rows45, rows67;
    __builtin_memcpy(&rows01, buffer + r * N + 0, 64);
    __builtin_memcpy(&rows23, buffer + r * N + 64, 64);
    __builtin_memcpy(&rows45, buffer + r * N + 128, 64);
    __builtin_memcpy(&rows67, buffer + r * N + 192, 64);
#define GF_T(v) ((u8x64)__builtin_ia32_vgf2p8affineqb_v64qi((i8x64)transpose, (i8x64)(v), 0))
    const u8x64 s01 = GF_T(rows01), s23 = GF_T(rows23), s45 = GF_T(rows45), s67 = GF_T(rows67);
    u8x64 strip_rows = 0;
    __builtin_memcpy(&strip_rows, strip + r, 32);
    strip_rows = strip_rows ^ strip_flip; /* the rows' lanes in the strip (record_avx512) */
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
    out[0] = __builtin_shufflevector(planes, planes, {_indices(_STAGE4[0])});
    out[1] = __builtin_shufflevector(planes, planes, {_indices(_STAGE4[1])});
    out[2] = __builtin_shufflevector(planes, planes, {_indices(_STAGE4[2])});
    out[3] = __builtin_shufflevector(planes, planes, {_indices(_STAGE4[3])});
}};
"""

#: Bit tricks on the bytes of a lane vector: population count, bit reversal (one GF2P8AFFINEQB
#: with the reversal matrix), lowest set bit, trailing zeros (8 for 0).
_BYTE_BITS = """
typedef char i8x32 __attribute__((vector_size(32)));
typedef long long i64x4 __attribute__((vector_size(32)));
const i64x4 reversal = {T, T, T, T}; /* as the matrix operand: bit i of each byte becomes bit 7 - i */
auto popcount8 = [](u8v v) { return __builtin_elementwise_popcount(v); };
auto reverse8 = [&](u8v v) {
    return (u8v)__builtin_ia32_vgf2p8affineqb_v32qi((i8x32)v, (i8x32)reversal, 0);
};
auto lowest8 = [](u8v v) { return v & (u8v)(0 - v); };
auto ctz8 = [&](u8v v) { return popcount8(lowest8(v) - (u8v)1); };
"""

#: 8-row blocks (module docstring), for 32 lanes; needs ``planes8`` and the bit tricks.
_BLOCK8 = """
for (; block_rows >= 8 && r0 + 8 <= rows; r0 += 8) {
    u8v P[4];
    planes8(r0, P);
    const u8v G0 = P[0], G1 = P[1], G2 = P[2], I = P[3];
    const u8v zero = 0;
    const u8v valid_mask = zero - valid_bytes;
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
    age = has ? ctz8(reverse8(V)) : age + eight; /* steps after the last visit */
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
    const u8v last_reversed = lowest8(reverse8(B)); /* the last boundary, bits reversed */
    const u8v last_boundary = reverse8(last_reversed);
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
    /* rows from the last boundary: ctz8 of the reversed block, from its lowest bit found above */
    flen = ends ? popcount8(last_reversed - one) + one : flen + eight;
"""
# the gain code of the block's last row, from the rows' top bytes (AVX-512) or the planes (AVX2)
_LAST_TOP = """    u8v last_row;
    __builtin_memcpy(&last_row, buffer + (r0 + 7) * N, N);
    fcode = gain_code(last_row);
}
"""
_LAST_PLANES = """    fcode = (G0 >> 7) | ((G1 >> 7) << 1) | ((G2 >> 7) << 2);
}
"""

#: The block decoding (module docstring), for 32 lanes: blocks of 8 rows where the CPU has AVX-512
#: with GFNI and ``block_rows`` (a C++ int of the decoder, 8 or 1) is 8; the row loop takes the rest.
BLOCK_CPU = (
    "#if defined(__GFNI__) && defined(__AVX512BW__)\n"
    + _PLANES8
    + _BYTE_BITS
    + _BLOCK8
    + _LAST_TOP
    + "#endif\n"
)

#: The bit planes of 8 coded rows of 16 lanes (the AVX2 path's rows, ``gain + 8 in_strip``), two
#: rows a 256-bit vector: each row's gain code bits (|gain| = 1, |gain| = 2, gain < 0) and its
#: visit to B as byte masks, and-ed with the row's bit and or-ed into the planes.
_PLANES16 = f"""
typedef signed char s8x32 __attribute__((ext_vector_type(32)));
typedef unsigned char u8x32 __attribute__((ext_vector_type(32)));
auto planes8 = [&](const int r, u8v* out) {{
    u8x32 p0 = 0, p1 = 0, p2 = 0, pi = 0;
    for (int j = 0; j < 4; j++) {{
        s8x32 b;
        __builtin_memcpy(&b, buffer + (r + 2 * j) * N, 32);
        const u8x32 in_b = (u8x32)(b > (s8x32)5);
        const s8x32 g = b - (s8x32)(in_b & (u8x32)8);
        const s8x32 a = __builtin_elementwise_abs(g);
        /* row 2 j in the low half, row 2 j + 1 in the high half */
        const u8x32 bit = __builtin_shufflevector((u8v)(unsigned char)(1 << (2 * j)),
            (u8v)(unsigned char)(2 << (2 * j)), {_indices(range(32))});
        p0 |= (u8x32)(a == (s8x32)1) & bit;
        p1 |= (u8x32)(a == (s8x32)2) & bit;
        p2 |= (u8x32)(g < (s8x32)0) & bit;
        pi |= in_b & bit;
    }}
    const u8x32 planes[4] = {{p0, p1, p2, pi}};
    for (int k = 0; k < 4; k++)
        out[k] = __builtin_shufflevector(planes[k], planes[k], {_indices(range(16))})
            | __builtin_shufflevector(planes[k], planes[k], {_indices(range(16, 32))});
}};
"""

#: Bit tricks on the bytes of a lane vector without GFNI (popcount and bit reversal as the
#: compiler lowers them on AVX2: nibble table lookups).
_BYTE_BITS16 = """
auto popcount8 = [](u8v v) { return __builtin_elementwise_popcount(v); };
auto reverse8 = [](u8v v) { return __builtin_elementwise_bitreverse(v); };
auto lowest8 = [](u8v v) { return v & (u8v)(0 - v); };
auto ctz8 = [&](u8v v) { return popcount8(lowest8(v) - (u8v)1); };
"""

#: The block decoding of the AVX2 path's coded rows (16 lanes): the same bit tricks as
#: :data:`BLOCK_CPU` on planes built from the coded bytes.
BLOCK_CODED_CPU = _PLANES16 + _BYTE_BITS16 + _BLOCK8 + _LAST_PLANES
