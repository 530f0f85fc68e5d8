/*
 * Hand-vectorised AVX-512 twin of warpratchet.kernels.advance_map, for benchmarks/throughput.py:
 * the CPU's ceiling for the project's exact arithmetic, against which warpratchet is measured.
 *
 * Same operations, in the same order and with the same roundings, as warpratchet.kernels.step
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
#ifndef NV
#error "compile with -DNV=<vectors per block>"
#endif

#define WIDTH 8
typedef __m512d vec_t;
#define SET1 _mm512_set1_pd
#define LOADU _mm512_loadu_pd
#define STOREU _mm512_storeu_pd

#include "blocks.h"

/* Advance the BLOCK points at x..lsum (w: whole units gained, float64) by `steps` iterations. */
static void advance_block(const force_t *m, int64_t step0, int64_t steps, double *x, double *q, double *w,
                          double *dx, double *dp, double *lsum)
{
    const __m512d one = _mm512_set1_pd(1.0), zero = _mm512_setzero_pd();
    const __m512d threshold = _mm512_set1_pd(RENORM_THRESHOLD);
    __m512d X[NV], Q[NV], W[NV], DX[NV], DP[NV], L[NV];
    LOAD_LANES();
    for (int64_t s = 0; s < steps; s++) {
        for (int v = 0; v < NV; v++) {
            const __m512d xv = X[v];
            __m512d kick, k_slope; /* K f and K f' (Eq. fx) */
            force_kick(xv, m, &kick, &k_slope);
            const __m512d t = _mm512_add_pd(Q[v], kick);
            const __m512d fl = _mm512_roundscale_pd(t, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
            const __m512d frac = _mm512_sub_pd(t, fl);
            /* t just below an integer: t - floor(t) rounds to 1, fold it to 0 and one more unit */
            const __mmask8 wrap = _mm512_cmp_pd_mask(frac, one, _CMP_GE_OQ);
            Q[v] = _mm512_mask_blend_pd(wrap, frac, zero);
            W[v] = _mm512_add_pd(_mm512_add_pd(W[v], fl), _mm512_maskz_mov_pd(wrap, one));
            const __m512d xq = _mm512_add_pd(xv, Q[v]);
            X[v] = _mm512_mask_sub_pd(xq, _mm512_cmp_pd_mask(xq, one, _CMP_GE_OQ), xq, one);
            DP[v] = _mm512_add_pd(DP[v], _mm512_mul_pd(k_slope, DX[v]));
            DX[v] = _mm512_add_pd(DX[v], DP[v]);
        }
        if (((uint64_t)(step0 + s + 1) & (RENORM_CHECK_EVERY - 1)) == 0) {
            for (int v = 0; v < NV; v++) {
                const __mmask8 big = _mm512_cmp_pd_mask(_mm512_abs_pd(DX[v]), threshold, _CMP_GT_OQ);
                if (big)
                    renormalise(big, &DX[v], &DP[v], &L[v]);
            }
        }
    }
    STORE_LANES();
}

