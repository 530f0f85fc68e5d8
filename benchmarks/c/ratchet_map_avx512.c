/*
 * Hand-vectorised AVX-512 twin of warpratchet.kernels.advance_map, for benchmarks/throughput.py:
 * the CPU's ceiling for the project's exact arithmetic, against which warpratchet is measured.
 *
 * Same operations, in the same order and with the same roundings, as warpratchet.kernels._step
 * (and as the plain twin ratchet_map.c), so that the end state is bitwise warpratchet's:
 *
 *   K f and K f' of Eq. (fx) by force_kick of force.h (pieces x <= b1, x < 1 - b2, else);
 *   t = q + K f;  floor(t) by one vrndscalepd;  q = t - floor(t), folded to 0 (one more whole
 *   unit) if it rounded up to 1;  x = x + q, minus 1 if >= 1;
 *   tangent dp' = dp + (K f') dx, dx' = dx + dp';
 *   after every global step that is a multiple of RENORM_CHECK_EVERY, a tangent with
 *   |dx| > RENORM_THRESHOLD is divided by its norm and log(norm) (the C library's) is booked.
 *
 * force.h is written by throughput.py from warpratchet's piece table (warpratchet.force.c_source,
 * the operations of the Warp kernels' CPU body in its order): K f' is taken from the products
 * K*l1, -K, K*l2 (the roundings of the scalar K*slope). Each OpenMP thread takes blocks of NV
 * independent 8-wide vectors (NV*8 points), whose dependency chains hide each other's latencies;
 * NV = 6 and 8 are both built and the faster is reported. Compile with -ffp-contract=off (no FMA
 * contraction: NumPy and warpratchet round a*b + c twice).
 *
 * Built at run time by throughput.py with
 *   gcc -O3 -march=native -fopenmp -ffp-contract=off -I<folder of force.h> -DNV=<6|8> \
 *       -DRENORM_THRESHOLD=... -DRENORM_CHECK_EVERY=... -fPIC -shared
 */
#include <immintrin.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#ifndef __AVX512F__
#error "needs a CPU with AVX-512F (compile with -march=native on one)"
#endif

#define WIDTH 8
typedef __m512d vec_t;
typedef __mmask8 mask_t;
#define PD(op) _mm512_##op##_pd
#define FLOOR(t) _mm512_roundscale_pd(t, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)
#define CMP_GE(a, b) _mm512_cmp_pd_mask(a, b, _CMP_GE_OQ)
#define CLEAR(m, v) _mm512_mask_blend_pd(m, v, _mm512_setzero_pd())
#define KEEP(m, v) _mm512_maskz_mov_pd(m, v)
#define MASK_SUB(m, a, b) _mm512_mask_sub_pd(a, m, a, b)
#define ABS(v) _mm512_abs_pd(v)
#define LANES_GT(a, b) _mm512_cmp_pd_mask(a, b, _CMP_GT_OQ)

#include "blocks.h"

