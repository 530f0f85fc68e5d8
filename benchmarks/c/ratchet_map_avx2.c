/*
 * Hand-vectorised AVX2 twin of warpratchet.kernels.advance_map, for benchmarks/throughput.py:
 * the ceiling of a CPU without AVX-512 (4-wide vectors, blends instead of mask registers) for the
 * project's exact arithmetic. The AVX-512 twin is ratchet_map_avx512.c; both do the same
 * operations, in the same order and with the same roundings, as warpratchet.kernels.step:
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
 * NV = 3 and 4 are both built and the faster is reported (AVX2 has 16 vector registers: more
 * vectors spill). Compile with -ffp-contract=off (no FMA contraction: NumPy and warpratchet
 * round a*b + c twice).
 *
 * Built at run time by throughput.py with
 *   gcc -O3 -march=native -fopenmp -ffp-contract=off -I<folder of force.h> -DNV=<3|4> \
 *       -DRENORM_THRESHOLD=... -DRENORM_CHECK_EVERY=... -fPIC -shared
 */
#include <immintrin.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#ifndef __AVX2__
#error "needs a CPU with AVX2 (compile with -march=native on one)"
#endif
#ifndef NV
#error "compile with -DNV=<vectors per block>"
#endif

#define WIDTH 4
typedef __m256d vec_t;
#define SET1 _mm256_set1_pd
#define LOADU _mm256_loadu_pd
#define STOREU _mm256_storeu_pd

#include "blocks.h"

/* Advance the BLOCK points at x..lsum (w: whole units gained, float64) by `steps` iterations. */
static void advance_block(const force_t *m, int64_t step0, int64_t steps, double *x, double *q, double *w,
                          double *dx, double *dp, double *lsum)
{
    const __m256d one = _mm256_set1_pd(1.0);
    const __m256d threshold = _mm256_set1_pd(RENORM_THRESHOLD);
    const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
    __m256d X[NV], Q[NV], W[NV], DX[NV], DP[NV], L[NV];
    LOAD_LANES();
    for (int64_t s = 0; s < steps; s++) {
        for (int v = 0; v < NV; v++) {
            const __m256d xv = X[v];
            __m256d kick, k_slope; /* K f and K f' (Eq. fx) */
            force_kick(xv, m, &kick, &k_slope);
            const __m256d t = _mm256_add_pd(Q[v], kick);
            const __m256d fl = _mm256_round_pd(t, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
            const __m256d frac = _mm256_sub_pd(t, fl);
            /* t just below an integer: t - floor(t) rounds to 1, fold it to 0 and one more unit */
            const __m256d wrap = _mm256_cmp_pd(frac, one, _CMP_GE_OQ);
            Q[v] = _mm256_andnot_pd(wrap, frac);
            W[v] = _mm256_add_pd(_mm256_add_pd(W[v], fl), _mm256_and_pd(wrap, one));
            const __m256d xq = _mm256_add_pd(xv, Q[v]);
            const __m256d ge = _mm256_cmp_pd(xq, one, _CMP_GE_OQ);
            X[v] = _mm256_blendv_pd(xq, _mm256_sub_pd(xq, one), ge);
            DP[v] = _mm256_add_pd(DP[v], _mm256_mul_pd(k_slope, DX[v]));
            DX[v] = _mm256_add_pd(DX[v], DP[v]);
        }
        if (((uint64_t)(step0 + s + 1) & (RENORM_CHECK_EVERY - 1)) == 0) {
            for (int v = 0; v < NV; v++) {
                const __m256d big = _mm256_cmp_pd(_mm256_and_pd(DX[v], abs_mask), threshold, _CMP_GT_OQ);
                const int lanes = _mm256_movemask_pd(big);
                if (lanes)
                    renormalise(lanes, &DX[v], &DP[v], &L[v]);
            }
        }
    }
    STORE_LANES();
}

