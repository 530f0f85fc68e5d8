/*
 * A loop bound by the floating-point pipes, for benchmarks/core_sharing.py: each OpenMP thread
 * runs CHAINS independent chains of 4-wide fused multiply-adds (enough chains to cover the FMA
 * latency with the pipes full), so a thread's rate is its core's FMA throughput. Two threads on
 * separate cores each keep that rate; two threads that share one core's pipes (SMT siblings, or
 * two vCPUs a hypervisor puts on one core) each get about half.
 *
 * Built at run time by core_sharing.py with  gcc -O2 -mavx2 -mfma -fopenmp -fPIC -shared
 */
#include <immintrin.h>
#include <omp.h>
#include <time.h>

#define CHAINS 10

static double thread_cpu_seconds(void) {
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

/* Each thread's vector FMAs per second of its own CPU time into rates[thread] (threads entries);
 * returns a value of the chains, so that the compiler keeps them. */
double fma_rates(long iterations, int threads, double* rates) {
    double kept = 0.0;
#pragma omp parallel num_threads(threads) reduction(+ : kept)
    {
        __m256d a[CHAINS];
        const __m256d m = _mm256_set1_pd(0.999999), c = _mm256_set1_pd(1e-7);
        for (int k = 0; k < CHAINS; k++) a[k] = _mm256_set1_pd(1.0 + k);
        const double start = thread_cpu_seconds();
        for (long i = 0; i < iterations; i++) {
#pragma GCC unroll 10
            for (int k = 0; k < CHAINS; k++) a[k] = _mm256_fmadd_pd(a[k], m, c);
        }
        const double seconds = thread_cpu_seconds() - start;
        rates[omp_get_thread_num()] = (double)iterations * CHAINS / seconds;
        for (int k = 0; k < CHAINS; k++) kept += a[k][0];
    }
    return kept;
}
