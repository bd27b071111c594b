/* SPDX-License-Identifier: MIT
 * Shared by the tests and benchmarks: reproducible pseudo-random numbers
 * (splitmix64, the same sequence on every machine) and random SPD matrices.
 * Each including file has its own sequence: define TEST_RNG_SEED before
 * including this header. */
#ifndef GEARSIM_TESTS_RAND_H
#define GEARSIM_TESTS_RAND_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#ifndef TEST_RNG_SEED
#error "define TEST_RNG_SEED before including rand.h"
#endif

static uint64_t rng_state = TEST_RNG_SEED;

/* Uniform in [0, 1). */
static inline double urand(void)
{
    uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

/* Uniform in [a, b). */
static inline double uniform(double a, double b)
{
    return a + (b - a) * urand();
}

/* Standard normal (Box-Muller). */
static inline double nrand(void)
{
    double u = urand(), v = urand();
    return sqrt(-2.0 * log(u + 1e-300)) * cos(2.0 * 3.14159265358979323846 * v);
}

/* H = B^T B / n + alpha I with B n x n Gaussian: SPD, condition ~ 1 + 4/alpha. */
static inline void rand_spd(int n, double alpha, double *H)
{
    double *B = malloc((size_t)n * n * sizeof *B);
    for (int i = 0; i < n * n; i++)
        B[i] = nrand();
    for (int i = 0; i < n; i++)
        for (int j = 0; j <= i; j++) {
            double s = 0.0;
            for (int k = 0; k < n; k++)
                s += B[k * n + i] * B[k * n + j];
            H[i * n + j] = H[j * n + i] = s / n + (i == j ? alpha : 0.0);
        }
    free(B);
}

#endif
