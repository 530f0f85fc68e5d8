/*
 * The part both hand-vectorised twins share: the step loop of a block of lane vectors, the rare
 * renormalisation (lane by lane), loading and storing a block's lane vectors, a block of points
 * copied into lane arrays (padded with copies of the last point) and back, and the OpenMP driver
 * over blocks. The including file first defines its instruction set's primitives:
 *
 *   WIDTH              doubles per vector;  vec_t, mask_t: a vector and a lane mask;
 *   PD(op)             the packed-double intrinsic of op (add, sub, mul, set1, loadu, storeu);
 *   FLOOR(t)           floor(t) lane by lane, in one instruction;
 *   CMP_GE(a, b)       the mask of the lanes with a >= b;
 *   CLEAR(m, v)        v with the lanes in m set to 0;   KEEP(m, v): v in the lanes in m, 0 elsewhere;
 *   MASK_SUB(m, a, b)  a - b in the lanes in m, a elsewhere;
 *   ABS(v)             |v|;   LANES_GT(a, b): the bits (lane k -> bit k) of the lanes with a > b.
 *
 * Each primitive is one or two intrinsics of its instruction set and rounds nothing beyond the
 * operation it names, so both twins do the same operations, in the same order and with the same
 * roundings, as warpratchet.kernels._step.
 */
#ifndef RATCHET_BLOCKS_H
#define RATCHET_BLOCKS_H

#include "force.h"
#include "renorm.h"

#ifndef NV
#error "compile with -DNV=<vectors per block>"
#endif

#define BLOCK (WIDTH * NV)
#define SET1 PD(set1)
#define LOADU PD(loadu)
#define STOREU PD(storeu)
#define ADD PD(add)
#define SUB PD(sub)
#define MUL PD(mul)

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

/* Advance the BLOCK points at x..lsum (w: whole units gained, float64) by `steps` iterations. */
static void advance_block(const force_t *m, int64_t step0, int64_t steps, double *x, double *q, double *w,
                          double *dx, double *dp, double *lsum)
{
    const vec_t one = SET1(1.0);
    const vec_t threshold = SET1(RENORM_THRESHOLD);
    vec_t X[NV], Q[NV], W[NV], DX[NV], DP[NV], L[NV];
    LOAD_LANES();
    for (int64_t s = 0; s < steps; s++) {
        for (int v = 0; v < NV; v++) {
            const vec_t xv = X[v];
            vec_t kick, k_slope; /* K f and K f' (Eq. fx) */
            force_kick(xv, m, &kick, &k_slope);
            const vec_t t = ADD(Q[v], kick);
            const vec_t fl = FLOOR(t);
            const vec_t frac = SUB(t, fl);
            /* t just below an integer: t - floor(t) rounds to 1, fold it to 0 and one more unit */
            const mask_t wrap = CMP_GE(frac, one);
            Q[v] = CLEAR(wrap, frac);
            W[v] = ADD(ADD(W[v], fl), KEEP(wrap, one));
            const vec_t xq = ADD(xv, Q[v]);
            X[v] = MASK_SUB(CMP_GE(xq, one), xq, one);
            DP[v] = ADD(DP[v], MUL(k_slope, DX[v]));
            DX[v] = ADD(DX[v], DP[v]);
        }
        if (((uint64_t)(step0 + s + 1) & (RENORM_CHECK_EVERY - 1)) == 0) {
            for (int v = 0; v < NV; v++) {
                const int lanes = LANES_GT(ABS(DX[v]), threshold);
                if (lanes)
                    renormalise(lanes, &DX[v], &DP[v], &L[v]);
            }
        }
    }
    STORE_LANES();
}

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
