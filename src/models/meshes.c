/* SPDX-License-Identifier: MIT
 * Gear mesh models acting on the rigid coordinates through the
 * line-of-action displacement s = a . q (METHOD.md sections 2 and 7):
 *
 *  kinematic  the exact ratio as an equality row a . dq = 0;
 *  lumped     a spring and damper along the line of action with backlash and
 *             a stiffness that follows the mesh cycle (rectangular single /
 *             double tooth wave by contact ratio). Its force is the discrete
 *             gradient of V = 1/2 k(phi) f(s)^2 split over the two arguments,
 *             so that V(q1) - V(q0) = grad_bar V . dq holds exactly and the
 *             stiffness jumps exchange energy with the motion instead of
 *             creating it. */
#include <math.h>
#include <stdio.h>

#include "gearsim/stiffness.h"
#include "gearsim/step.h"
#include "gearsim/util.h"

/* Deflection beyond the backlash dead zone. */
static double dead(double x, double hb)
{
    if (x > hb)
        return x - hb;
    if (x < -hb)
        return x + hb;
    return 0.0;
}

/* Stiffness over the mesh cycle and its derivative in the phase. Double
 * contact over the first (eps - 1) of each base pitch of roll, single contact
 * over the rest, with linear transitions of width `transition` (a fraction of
 * the cycle) centred on each change: a tooth pair takes load over a short
 * roll, and a continuous k keeps the discrete-gradient step well posed (a
 * true jump asks for an impulsive torque that, at low speed, the step cannot
 * resolve). */
static double stiffness_d(const gs_gmesh_rt *m, double phi, double *dk)
{
    if (m->k_table) {
        /* Calibrated: periodic piecewise-linear over one mesh cycle. */
        int n = m->n_table;
        double f = (phi - m->phase0) * m->phase_dir;
        f -= floor(f);
        double x = f * n;
        int i = (int)x;
        if (i >= n)
            i = n - 1;
        double t = x - i, k0 = m->k_table[i], k1 = m->k_table[(i + 1) % n];
        *dk = (k1 - k0) * n * m->phase_dir;
        return k0 + t * (k1 - k0);
    }
    double e1 = m->contact_ratio - 1.0, dlt = m->transition;
    *dk = 0.0;
    if (m->k_double == m->k_single || e1 <= 0.0)
        return m->k_single;
    if (e1 >= 1.0)
        return m->k_double;
    double f = phi - floor(phi), w, dw = 0.0;
    if (f < 0.5 * dlt) {
        w = 0.5 + f / dlt;
        dw = 1.0 / dlt;
    } else if (f < e1 - 0.5 * dlt) {
        w = 1.0;
    } else if (f < e1 + 0.5 * dlt) {
        w = 0.5 - (f - e1) / dlt;
        dw = -1.0 / dlt;
    } else if (f < 1.0 - 0.5 * dlt) {
        w = 0.0;
    } else {
        w = 0.5 + (f - 1.0) / dlt;
        dw = 1.0 / dlt;
    }
    double dkk = m->k_double - m->k_single;
    *dk = dkk * dw;
    return m->k_single + dkk * w;
}

static double stiffness(const gs_gmesh_rt *m, double phi)
{
    double dk;
    return stiffness_d(m, phi, &dk);
}

static double dot(const double *a, const double *b, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

static gs_err kin_init(gs_system *sys, gs_gmesh_rt *m, gs_diag *d)
{
    (void)sys;
    (void)m;
    (void)d;
    return GS_OK;
}

static void kin_force(const gs_system *sys, const gs_gmesh_rt *m, const double *q0,
                      const double *dq, double h, double *g, double *J, double *diss, double *force)
{
    (void)sys, (void)m, (void)q0, (void)dq, (void)h, (void)g, (void)J;
    *diss = 0;
    *force = NAN; /* filled from the multiplier by the solver */
}

static double kin_energy(const gs_system *sys, const gs_gmesh_rt *m, const double *q)
{
    (void)sys, (void)m, (void)q;
    return 0.0;
}

/* Mesh stiffness over one cycle from the quasi-static FE analysis of the
 * pair (src/contact/stiffness.c) at the scene's load on the driver: the gear
 * whose teeth count the mesh phase, so one driver pitch is one cycle. The
 * analysis starts at the gears' scene angles and rolls in the torque's
 * direction; entry j is at phase phase0 + phase_dir j / n. Every rank runs
 * it (deterministic); it costs about a tenth of a second per mesh at the
 * default density. */
static gs_err calibrate(gs_system *sys, gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.positions = sm->calibrate_positions;
    o.driver = sys->scene->bodies[sm->gear[0]].gear.kind == GS_GEAR_INTERNAL ? 1 : 0;
    o.tangent = 0;
    gs_stiffness_result r;
    char field[64];
    snprintf(field, sizeof field, "meshes[%d].stiffness", m->index);
    gs_diag sd;
    gs_err e = gs_stiffness_analyse(sys->scene, m->index, &o, &r, &sd);
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "calibration by the quasi-static FE analysis failed: %s (%s)",
                           sd.message, sd.field);
    m->k_table = gs_calloc((size_t)r.positions, sizeof(double));
    if (!m->k_table) {
        gs_stiffness_result_clear(&r);
        return GS_ENOMEM;
    }
    m->n_table = r.positions;
    double sum = 0;
    for (int j = 0; j < r.positions; j++) {
        /* N/(mm um) per mm of face width -> N/m */
        m->k_table[j] = r.pt[j].k * r.face_width_mm * 1e6;
        sum += m->k_table[j];
        if (!(m->k_table[j] > 0) || !isfinite(m->k_table[j])) {
            gs_stiffness_result_clear(&r);
            return gs_diag_set(d, GS_ERANGE, field, "the calibration gave no stiffness at roll %.3f", r.pt[j].roll);
        }
    }
    int n = sys->n_coords;
    double phase = 0;
    for (int i = 0; i < n; i++)
        phase += m->c[i] * sys->q[i];
    m->phase0 = phase;
    m->phase_dir = r.torque_nm < 0 ? -1.0 : 1.0;
    m->k_single = m->k_double = sum / r.positions; /* the mean, for the damping estimate */
    gs_stiffness_result_clear(&r);
    return GS_OK;
}

static gs_err lumped_init(gs_system *sys, gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    m->k_single = sm->k_single;
    m->k_double = sm->stiffness_type == GS_STIFF_CONSTANT ? sm->k_single : sm->k_double;
    if (sm->stiffness_type == GS_STIFF_CALIBRATED)
        GS_TRY(calibrate(sys, m, d));
    m->half_backlash = 0.5 * sm->backlash;
    double e1 = m->contact_ratio - 1.0;
    m->transition = fmin(sm->transition, 0.5 * fmin(e1, 1.0 - e1));
    if (!(m->transition > 0))
        m->transition = 1e-3;
    if (sm->damping >= 0) {
        m->damping = sm->damping;
    } else {
        /* Damping ratio of the mesh mode: c = 2 zeta sqrt(k_mean m_eq),
         * m_eq = 1 / sum a_i^2 / I_i over the coordinates the mesh moves. */
        double inv = 0;
        for (int i = 0; i < sys->n_bodies; i++) {
            const gs_body_rt *b = &sys->bodies[i];
            if (b->coord >= 0 && m->a[b->coord] != 0)
                inv += m->a[b->coord] * m->a[b->coord] / b->inertia_eff;
        }
        double eps = m->contact_ratio;
        double km = eps >= 2 ? m->k_double : m->k_single * (2 - eps) + m->k_double * (eps - 1);
        m->damping = inv > 0 ? 2 * sm->damping_ratio * sqrt(km / inv) : 0;
    }
    return GS_OK;
}

/* Discrete gradient split (see file comment):
 *   dV = (k0+k1)/2 * (f1^2 - f0^2)/2  +  (f0^2+f1^2)/2 * (k1 - k0)/2
 * and each difference quotient is taken along its own scalar argument. */
static void lumped_force(const gs_system *sys, const gs_gmesh_rt *m, const double *q0,
                         const double *dq, double h, double *g, double *J, double *diss,
                         double *force)
{
    int n = sys->n_coords;
    double s0 = dot(m->a, q0, n) - m->s_ref, ds = dot(m->a, dq, n);
    double p0 = dot(m->c, q0, n), dp = dot(m->c, dq, n);
    double s1 = s0 + ds;
    double hb = m->half_backlash;
    double f0 = dead(s0, hb), f1 = dead(s1, hb);
    double dk0, dk1;
    double k0 = stiffness_d(m, p0, &dk0), k1 = stiffness_d(m, p0 + dp, &dk1);
    double kbar = 0.5 * (k0 + k1);
    double dfs; /* (f1^2 - f0^2) / (2 ds), exact for the piecewise-linear f */
    if (ds != 0.0)
        dfs = (f1 * f1 - f0 * f0) / (2.0 * ds);
    else
        dfs = f0; /* limit f f'(s), f' = 1 outside the dead zone, f = 0 inside */
    double gs = kbar * dfs;
    double Q = 0.25 * (f0 * f0 + f1 * f1), gp, jpp;
    if (dp != 0.0) {
        gp = Q * (k1 - k0) / dp;
        jpp = Q * (dk1 * dp - (k1 - k0)) / (dp * dp);
    } else {
        gp = Q * dk0; /* the limit: 1/2 f^2 k'(phi) */
        jpp = 0.0;
    }
    /* Damping acts while the teeth are in contact at the midpoint. */
    double smid = s0 + 0.5 * ds;
    bool touching = fabs(smid) > hb;
    double cd = touching ? m->damping : 0.0;
    double fd = cd * ds / h;
    for (int i = 0; i < n; i++)
        g[i] += m->a[i] * (gs + fd) + m->c[i] * gp;
    /* Jacobian of the s-part: d(dfs)/d(ds) = 1/2 where both ends are in contact. */
    double jss = (f0 != 0.0 || f1 != 0.0 ? 0.5 * kbar : 0.0) + cd / h;
    /* Cross terms: d gs / d dp and d gp / d ds (f1 moves with ds). */
    double jsp = 0.5 * dk1 * dfs;
    double jps = dp != 0.0 ? 0.5 * f1 * (f1 != 0.0 ? 1.0 : 0.0) * (k1 - k0) / dp : 0.5 * f1 * dk0;
    for (int i = 0; i < n; i++) {
        if (m->a[i] == 0.0 && m->c[i] == 0.0)
            continue;
        for (int j = 0; j < n; j++)
            J[i * n + j] += m->a[i] * (jss * m->a[j] + jsp * m->c[j]) +
                            m->c[i] * (jps * m->a[j] + jpp * m->c[j]);
    }
    *diss = fd * ds;
    *force = gs + fd;
}

static double lumped_energy(const gs_system *sys, const gs_gmesh_rt *m, const double *q)
{
    int n = sys->n_coords;
    double f = dead(dot(m->a, q, n) - m->s_ref, m->half_backlash);
    return 0.5 * stiffness(m, dot(m->c, q, n)) * f * f;
}

const gs_gmesh_ops gsi_gmesh_kinematic = {
    .name = "kinematic", .init = kin_init, .n_eq = 1, .force = kin_force, .energy = kin_energy,
};

const gs_gmesh_ops gsi_gmesh_lumped = {
    .name = "lumped", .init = lumped_init, .n_eq = 0, .force = lumped_force, .energy = lumped_energy,
};
