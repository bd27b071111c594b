/* SPDX-License-Identifier: MIT
 * Shared by the validation tests: the tooth loss factor of a spur pair
 * after ISO/TR 14179-2 (Ohlendorf's H_v), mesh efficiency 1 - mu H_v. */
#ifndef GEARSIM_TESTS_ISO14179_H
#define GEARSIM_TESTS_ISO14179_H

#include <math.h>

#include "gearsim/types.h"

/* H_v = pi (u + 1) / (z1 u) (1 - eps_a + eps_1^2 + eps_2^2) of a pinion
 * with z1 teeth and a wheel with z2 (u = z2 / z1), module mod, pressure
 * angle alpha, at the standard centre distance with tip radii r + m;
 * eps_k = z_k / (2 pi) (sqrt(ra_k^2 - rb_k^2) / rb_k - tan alpha) the
 * addendum contact ratios, eps_a = eps_1 + eps_2. */
static inline double iso14179_hv(double z1, double z2, double mod, double alpha)
{
    double u = z2 / z1, e[2];
    for (int k = 0; k < 2; k++) {
        double z = k ? z2 : z1, r = 0.5 * z * mod, rb = r * cos(alpha), ra = r + mod;
        e[k] = z / (2 * GS_PI) * (sqrt(ra * ra - rb * rb) / rb - tan(alpha));
    }
    return GS_PI * (u + 1) / (z1 * u) * (1 - (e[0] + e[1]) + e[0] * e[0] + e[1] * e[1]);
}

#endif
