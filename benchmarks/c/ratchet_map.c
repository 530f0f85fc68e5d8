/*
 * Plain-C twin of warpratchet.kernels.advance_map, for benchmarks/throughput.py.
 *
 * Advances n points of the map of Eq. (cpem), p' = p + K f(x), x' = x + p' (mod 1), with the
 * force of force.h (Eq. fx with l1, l2, c of Eq. mmc, or another piece table), and their tangent
 * vectors under DM, for `steps` iterations starting at global step `step0`. The arithmetic is
 * the kernel's, operation by operation, so that the end state is bitwise equal to warpratchet's:
 *
 *   momentum as a fraction q in [0, 1) plus a winding count (floor of q + K f);
 *   tangent dp' = dp + (K f') dx, dx' = dx + dp';
 *   after every global step that is a multiple of RENORM_CHECK_EVERY, a tangent with
 *   |dx| > RENORM_THRESHOLD is divided by its norm and the log of the norm is booked.
 *
 * The force comes from force.h, which throughput.py writes from warpratchet's piece table
 * (warpratchet.force.c_source, isa "c"): force_kick gives K f and K f', the roundings of the
 * kernel's. Built at run time by throughput.py with
 *   gcc -O3 -march=native -fopenmp -ffp-contract=off -I<folder of force.h> -DRENORM_THRESHOLD=... \
 *       -DRENORM_CHECK_EVERY=...
 * -ffp-contract=off matters: GNU C contracts a*b + c into an FMA by default, which rounds once
 * instead of twice and would make the states differ from Warp's in the last bits.
 *
 * "Plain": one OpenMP loop over points, the steps inside, no hand vectorisation.
 */
#include <math.h>
#include <stdint.h>

#include "force.h"
#include "renorm.h"

void advance_map(int64_t n, int64_t step0, int64_t steps, double K, double b1, double right, double l1,
                 double l2, double c, double *x, double *q, int64_t *winding, double *dx, double *dp,
                 double *lsum, int threads)
{
    const force_t m = force_set(K, b1, right, l1, l2, c);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int64_t i = 0; i < n; i++) {
        double xi = x[i], qi = q[i], dxi = dx[i], dpi = dp[i], si = lsum[i];
        double w = 0.0; /* windings gained in this call; exact below 2^53 */
        for (int64_t s = 0; s < steps; s++) {
            double kick, k_slope; /* K f and K f' (Eq. fx) */
            force_kick(xi, &m, &kick, &k_slope);
            const double t = qi + kick;
            const double fl = floor(t);
            qi = t - fl;
            /* t just below an integer can round t - floor(t) up to exactly 1: fold it back */
            const int wrap = qi >= 1.0;
            qi = wrap ? 0.0 : qi;
            w = w + fl + (wrap ? 1.0 : 0.0);
            xi = xi + qi;
            xi = xi >= 1.0 ? xi - 1.0 : xi;
            dpi = dpi + k_slope * dxi;
            dxi = dxi + dpi;
            if ((uint64_t)(step0 + s + 1) % RENORM_CHECK_EVERY == 0 && fabs(dxi) > RENORM_THRESHOLD) {
                const double h = sqrt(dxi * dxi + dpi * dpi);
                si = si + log(h);
                dxi = dxi / h;
                dpi = dpi / h;
            }
        }
        x[i] = xi;
        q[i] = qi;
        dx[i] = dxi;
        dp[i] = dpi;
        lsum[i] = si;
        winding[i] = winding[i] + (int64_t)w;
    }
}
