/* SPDX-License-Identifier: MIT
 * Compliant supports behind the joint operations (gearsim/models.h,
 * docs/explanation/modal.md). The bearing: V = 1/2 sum_i k_i (q_i - q_ref_i)^2 over the
 * centre's x, y and the rotation; quadratic, so the midpoint gradient
 * k (q0 + dq/2 - q_ref) is its exact discrete gradient; the damper
 * c dq / h dissipates c dq^2 / h per step. */
#include <math.h>

#include "gearsim/models.h"
#include "mesh_common.h"

static void bearing_force(const gs_model_view *sys, const gs_joint_rt *j, const double *q0, const double *dq, double h,
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

static double bearing_energy(const gs_model_view *sys, const gs_joint_rt *j, const double *q)
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

/* A planet's radial bearing on its carrier pin (Lin and Parker's planar
 * model, in inertial coordinates): V = 1/2 k |e|^2 with the stretch
 * e = X_p - X_C + d0 - R(theta_C) pin0 (gearsim/models.h). Over the step
 * de = dX_p - dX_C - (R(theta_1) - R(theta_0)) pin0, and
 * (R(theta_1) - R(theta_0)) pin0 = dtheta t with
 * t = 2 sin(dtheta / 2) / dtheta R(theta_mid) J pin0 (J: quarter turn), so
 * the force F = k ebar + c de / h acting on X_p, -F on X_C and -F . t on
 * theta_C is an exact discrete gradient: V1 - V0 = k ebar . de; the damper
 * on the relative motion dissipates c |de|^2 / h. */
static void pin_rot(double t, const double v[2], double out[2])
{
    double c = cos(t), s = sin(t);
    out[0] = c * v[0] - s * v[1];
    out[1] = s * v[0] + c * v[1];
}

/* The stretch e at q. */
static void pin_stretch(const gs_joint_rt *j, const double *q, double e[2])
{
    double r[2] = {j->pin0[0], j->pin0[1]};
    if (j->carrier >= 0)
        pin_rot(q[j->carrier], j->pin0, r);
    for (int i = 0; i < 2; i++)
        e[i] = q[j->coord[i]] + j->d0[i] - r[i] - (j->carrier_t >= 0 ? q[j->carrier_t + i] : 0.0);
}

static void pin_bearing_force(const gs_model_view *sys, const gs_joint_rt *j, const double *q0, const double *dq, double h,
                              double *g, double *J, double *diss)
{
    int n = sys->n_coords, c = j->carrier, xc = j->carrier_t;
    double k = j->k[0], cd = j->c[0];
    double e0[2], t[2] = {0, 0}, t1[2] = {0, 0}, dt[2] = {0, 0}, dth = c >= 0 ? dq[c] : 0.0;
    pin_stretch(j, q0, e0);
    if (c >= 0) {
        double th0 = q0[c], thm = th0 + 0.5 * dth, jp[2] = {-j->pin0[1], j->pin0[0]}, rj[2], r1[2];
        pin_rot(thm, jp, rj);
        pin_rot(th0 + dth, jp, t1); /* d/d dtheta of R(theta_1) pin0 */
        double sinc = gsi_half_sinc(dth);
        t[0] = sinc * rj[0], t[1] = sinc * rj[1];
        if (fabs(dth) > 1e-6) { /* dt / d dtheta, for the Jacobian */
            dt[0] = (t1[0] - t[0]) / dth, dt[1] = (t1[1] - t[1]) / dth;
        } else {
            pin_rot(thm, j->pin0, r1);
            dt[0] = -0.5 * r1[0], dt[1] = -0.5 * r1[1];
        }
    }
    double de[2], F[2], D = 0;
    for (int i = 0; i < 2; i++) {
        de[i] = dq[j->coord[i]] - (xc >= 0 ? dq[xc + i] : 0.0) - dth * t[i];
        F[i] = k * (e0[i] + 0.5 * de[i]) + cd * de[i] / h;
        D += cd * de[i] * de[i] / h;
    }
    double a = 0.5 * k + cd / h;
    for (int i = 0; i < 2; i++) {
        int xp = j->coord[i];
        g[xp] += F[i];
        J[(size_t)xp * n + xp] += a;
        if (xc >= 0) {
            g[xc + i] -= F[i];
            J[(size_t)xp * n + xc + i] -= a;
            J[(size_t)(xc + i) * n + xp] -= a;
            J[(size_t)(xc + i) * n + xc + i] += a;
        }
        if (c >= 0) {
            J[(size_t)xp * n + c] -= a * t1[i];
            J[(size_t)c * n + xp] -= a * t[i];
            if (xc >= 0) {
                J[(size_t)(xc + i) * n + c] += a * t1[i];
                J[(size_t)c * n + xc + i] += a * t[i];
            }
        }
    }
    if (c >= 0) {
        g[c] -= F[0] * t[0] + F[1] * t[1];
        J[(size_t)c * n + c] += a * (t1[0] * t[0] + t1[1] * t[1]) - (F[0] * dt[0] + F[1] * dt[1]);
    }
    *diss = D;
}

static double pin_bearing_energy(const gs_model_view *sys, const gs_joint_rt *j, const double *q)
{
    (void)sys;
    double e[2];
    pin_stretch(j, q, e);
    return 0.5 * j->k[0] * (e[0] * e[0] + e[1] * e[1]);
}

const gs_joint_ops gsi_joint_pin_bearing = {
    .name = "pin_bearing", .force = pin_bearing_force, .energy = pin_bearing_energy};
