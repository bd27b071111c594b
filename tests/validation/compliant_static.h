/* SPDX-License-Identifier: MIT
 * Shared by the validation tests of the compliant mesh: its static
 * deflection at a phase under a force, from the model's own tabulated law. */
#ifndef GEARSIM_TESTS_COMPLIANT_STATIC_H
#define GEARSIM_TESTS_COMPLIANT_STATIC_H

#include "gearsim/step.h"
#include "models/compliant_mesh.h"

/* Approach (m, drive flank) at which the engaged pairs of mesh m at phase
 * phi carry W (N): bisection on [0, 1e-4]. */
static inline double vt_compliant_static(const gs_gmesh_rt *m, double phi, double W)
{
    double v[8], wt[8];
    int n = gsi_compliant_pairs(m, phi, 1, v, wt, 8);
    double lo = 0, hi = 1e-4;
    for (int it = 0; it < 80; it++) {
        double mid = 0.5 * (lo + hi), F = 0;
        for (int j = 0; j < n; j++)
            F += wt[j] * gsi_compliant_pair_force(m, v[j], mid);
        if (F < W)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

#endif
