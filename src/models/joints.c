/* SPDX-License-Identifier: MIT
 * Compliant supports behind the joint operations (gearsim/models.h,
 * docs/MODAL.md). The bearing: V = 1/2 sum_i k_i (q_i - q_ref_i)^2 over the
 * centre's x, y and the rotation; quadratic, so the midpoint gradient
 * k (q0 + dq/2 - q_ref) is its exact discrete gradient; the damper
 * c dq / h dissipates c dq^2 / h per step. */
#include "gearsim/step.h"

static void bearing_force(const gs_system *sys, const gs_joint_rt *j, const double *q0, const double *dq, double h,
                          double *g, double *J, double *diss)
{
    int n = sys->n_coords;
    double D = 0;
    for (int i = 0; i < 3; i++) {
        int c = j->coord[i];
        if (c < 0 || (j->k[i] == 0 && j->c[i] == 0))
            continue;
        double fd = j->c[i] * dq[c] / h;
        g[c] += j->k[i] * (q0[c] + 0.5 * dq[c] - j->q_ref[i]) + fd;
        J[(size_t)c * n + c] += 0.5 * j->k[i] + j->c[i] / h;
        D += fd * dq[c];
    }
    *diss = D;
}

static double bearing_energy(const gs_system *sys, const gs_joint_rt *j, const double *q)
{
    (void)sys;
    double V = 0;
    for (int i = 0; i < 3; i++)
        if (j->coord[i] >= 0) {
            double x = q[j->coord[i]] - j->q_ref[i];
            V += 0.5 * j->k[i] * x * x;
        }
    return V;
}

const gs_joint_ops gsi_joint_bearing = {.name = "bearing", .force = bearing_force, .energy = bearing_energy};
