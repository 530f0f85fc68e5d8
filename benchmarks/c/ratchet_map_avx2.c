/*
 * Hand-vectorised AVX2 twin of warpratchet.kernels.advance_map, for benchmarks/throughput.py:
 * the ceiling of a CPU without AVX-512 (4-wide vectors, blends instead of mask registers) for the
 * project's exact arithmetic. The AVX-512 twin is ratchet_map_avx512.c; both do the same
 * operations, in the same order and with the same roundings, as warpratchet.kernels._step:
 *
 *   K f and K f' of Eq. (fx) by force_kick of force.h (pieces x <= b1, x < 1 - b2, else);
 *   t = q + K f;  floor(t) by one vroundpd;  q = t - floor(t), folded to 0 (one more whole unit)
 *   if it rounded up to 1;  x = x + q, minus 1 if >= 1;
 *   tangent dp' = dp + (K f') dx, dx' = dx + dp';
 *   after every global step that is a multiple of RENORM_CHECK_EVERY, a tangent with
 *   |dx| > RENORM_THRESHOLD is divided by its norm and log(norm) (the C library's) is booked.
 *
 * force.h is written by throughput.py from warpratchet's piece table (warpratchet.force.c_source,
 * the operations of the Warp kernels' CPU body in its order): K f' is taken from the products
 * K*l1, -K, K*l2 (the roundings of the scalar K*slope). Each OpenMP thread takes blocks of NV
 * independent 4-wide vectors (4*NV points), whose dependency chains hide each other's latencies;
 * NV = 3, 4 and 8 are built and the fastest is reported (AVX2 has 16 vector registers: more
 * vectors spill, which a core with deep out-of-order windows, such as Zen 5's, hides). On a CPU
 * with AVX-512 it is built with -mno-avx512f, so that it keeps to an AVX2 CPU's 16 registers.
 * Compile with -ffp-contract=off (no FMA contraction: NumPy and warpratchet round a*b + c twice).
 *
 * Built at run time by throughput.py with
 *   gcc -O3 -march=native -fopenmp -ffp-contract=off [-mno-avx512f] -I<folder of force.h> -DNV=<3|4|8> \
 *       -DRENORM_THRESHOLD=... -DRENORM_CHECK_EVERY=... -fPIC -shared
 */
#include <immintrin.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#ifndef __AVX2__
#error "needs a CPU with AVX2 (compile with -march=native on one)"
#endif

#define WIDTH 4
typedef __m256d vec_t;
typedef __m256d mask_t; /* all ones in the lanes set */
#define PD(op) _mm256_##op##_pd
#define FLOOR(t) _mm256_round_pd(t, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)
#define CMP_GE(a, b) _mm256_cmp_pd(a, b, _CMP_GE_OQ)
#define CLEAR(m, v) _mm256_andnot_pd(m, v)
#define KEEP(m, v) _mm256_and_pd(m, v)
#define MASK_SUB(m, a, b) _mm256_blendv_pd(a, _mm256_sub_pd(a, b), m)
#define ABS(v) _mm256_and_pd(v, _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL)))
#define LANES_GT(a, b) _mm256_movemask_pd(_mm256_cmp_pd(a, b, _CMP_GT_OQ))

#include "blocks.h"

