/*
 * The part both hand-vectorised twins share: the rare renormalisation (lane by lane), loading and
 * storing a block's lane vectors, a block of points copied into lane arrays (padded with copies
 * of the last point), advanced by the twin's advance_block and copied back, and the OpenMP
 * driver over blocks. The including file first defines WIDTH (doubles per vector), vec_t, its
 * intrinsics SET1, LOADU and STOREU, and NV; it defines advance_block after.
 */
#ifndef RATCHET_BLOCKS_H
#define RATCHET_BLOCKS_H

#include "force.h"
#include "renorm.h"

#define BLOCK (WIDTH * NV)

/* |dx| > threshold in the lanes set in big: renormalise those (log lane by lane, the C library's). */
static void renormalise(int big, vec_t *dx, vec_t *dp, vec_t *lsum)
{
    double a[WIDTH], b[WIDTH], l[WIDTH];
    STOREU(a, *dx);
    STOREU(b, *dp);
    STOREU(l, *lsum);
    for (int k = 0; k < WIDTH; k++) {
        if (big >> k & 1) {
            const double h = sqrt(a[k] * a[k] + b[k] * b[k]);
            l[k] = l[k] + log(h);
            a[k] = a[k] / h;
            b[k] = b[k] / h;
        }
    }
    *dx = LOADU(a);
    *dp = LOADU(b);
    *lsum = LOADU(l);
}

/* The lane vectors X..L of advance_block from the arrays x..lsum, and back. */
#define LOAD_LANES()                        \
    for (int v = 0; v < NV; v++) {          \
        X[v] = LOADU(x + WIDTH * v);        \
        Q[v] = LOADU(q + WIDTH * v);        \
        W[v] = LOADU(w + WIDTH * v);        \
        DX[v] = LOADU(dx + WIDTH * v);      \
        DP[v] = LOADU(dp + WIDTH * v);      \
        L[v] = LOADU(lsum + WIDTH * v);     \
    }
#define STORE_LANES()                       \
    for (int v = 0; v < NV; v++) {          \
        STOREU(x + WIDTH * v, X[v]);        \
        STOREU(q + WIDTH * v, Q[v]);        \
        STOREU(w + WIDTH * v, W[v]);        \
        STOREU(dx + WIDTH * v, DX[v]);      \
        STOREU(dp + WIDTH * v, DP[v]);      \
        STOREU(lsum + WIDTH * v, L[v]);     \
    }

static void advance_block(const force_t *m, int64_t step0, int64_t steps, double *x, double *q, double *w,
                          double *dx, double *dp, double *lsum);

/* The block of points [i, i + count) (count <= BLOCK), padded with copies of the last one. */
static void advance_points(const force_t *m, int64_t step0, int64_t steps, int64_t i, int64_t count,
                           double *x, double *q, int64_t *winding, double *dx, double *dp, double *lsum)
{
    double bx[BLOCK], bq[BLOCK], bw[BLOCK], bdx[BLOCK], bdp[BLOCK], bl[BLOCK];
    for (int k = 0; k < BLOCK; k++) {
        const int64_t j = i + (k < count ? k : count - 1);
        bx[k] = x[j];
        bq[k] = q[j];
        bw[k] = 0.0;
        bdx[k] = dx[j];
        bdp[k] = dp[j];
        bl[k] = lsum[j];
    }
    advance_block(m, step0, steps, bx, bq, bw, bdx, bdp, bl);
    for (int k = 0; k < count; k++) {
        x[i + k] = bx[k];
        q[i + k] = bq[k];
        winding[i + k] = winding[i + k] + (int64_t)bw[k]; /* whole units, exact below 2^53 */
        dx[i + k] = bdx[k];
        dp[i + k] = bdp[k];
        lsum[i + k] = bl[k];
    }
}

void advance_map(int64_t n, int64_t step0, int64_t steps, double K, double b1, double right, double l1, double l2,
                 double c, double *x, double *q, int64_t *winding, double *dx, double *dp, double *lsum, int threads)
{
    const force_t m = force_set(K, b1, right, l1, l2, c);
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads)
    for (int64_t i = 0; i < n; i += BLOCK) {
        const int64_t count = n - i < BLOCK ? n - i : BLOCK;
        advance_points(&m, step0, steps, i, count, x, q, winding, dx, dp, lsum);
    }
}

#endif
