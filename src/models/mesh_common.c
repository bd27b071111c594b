/* SPDX-License-Identifier: MIT
 * Pieces shared by the mesh models with a force (mesh_common.h). */
#include <math.h>
#include <stdio.h>

#include <stdlib.h>
#include <string.h>

#include "gearsim/util.h"
#include "mesh_common.h"

gs_err gsi_mesh_needs_rigid(const gs_model_view *sys, const gs_gmesh_rt *m, const char *kind, gs_diag *d)
{
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *b = &sc->bodies[sm->gear[k]];
        if (b->model == GS_MODEL_ELASTIC) {
            char field[64];
            snprintf(field, sizeof field, "meshes[%d].gears", m->index);
            return gs_diag_set(d, GS_ERANGE, field,
                               "%s mesh '%s' needs rigid gears: '%s' is elastic (use a contact "
                               "mesh for elastic teeth)", kind, sm->name, b->name);
        }
    }
    return GS_OK;
}

gs_err gsi_mesh_mods_supported(const gs_model_view *sys, const gs_gmesh_rt *m, const char *kind, int profile,
                               int errors, gs_diag *d)
{
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    for (int k = 0; k < 2; k++) {
        int bi = sm->gear[k];
        const gs_scene_body *b = &sc->bodies[bi];
        const gs_gear_mods *md = b->mods;
        char field[64];
        if (!profile && gs_gear_mods_has_profile(md)) {
            snprintf(field, sizeof field, "bodies[%d].modification", bi);
            return gs_diag_set(d, GS_ERANGE, field,
                               "a %s mesh ('%s') cannot represent the profile modifications of '%s': use a "
                               "contact, compliant or calibrated lumped mesh", kind, sm->name, b->name);
        }
        int errs = (b->pitch_error_tooth >= 0 && b->pitch_error != 0.0) || (md && md->runout_m != 0.0);
        for (int t = 0; md && t < md->n_pitch; t++)
            errs |= md->pitch_m[t] != 0.0;
        if (!errors && errs) {
            snprintf(field, sizeof field, "bodies[%d].%s", bi,
                     md && md->runout_m != 0.0 ? "runout" : "pitch_errors_um");
            return gs_diag_set(d, GS_ERANGE, field,
                               "a %s mesh ('%s') cannot represent the pitch errors or run-out of '%s': use a "
                               "contact or lumped mesh", kind, sm->name, b->name);
        }
    }
    return GS_OK;
}

gs_err gsi_mesh_helical_supported(const gs_model_view *sys, const gs_gmesh_rt *m, const char *kind, int helical,
                                  gs_diag *d)
{
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    char field[64];
    for (int k = 0; k < 2; k++) {
        int bi = sm->gear[k];
        const gs_scene_body *b = &sc->bodies[bi];
        if (!helical && b->gear.helix_angle > 0) {
            snprintf(field, sizeof field, "bodies[%d].helix_angle_deg", bi);
            return gs_diag_set(d, GS_ERANGE, field,
                               "a %s mesh ('%s') works on spur teeth and cannot take the helical gear '%s' "
                               "(helix angle %g deg): use a lumped or compliant mesh", kind, sm->name, b->name,
                               b->gear.helix_angle * 180 / GS_PI);
        }
        const gs_lead_mods *l = &b->lead;
        if (l->crowning != 0 || l->end_relief != 0 || l->slope != 0) {
            snprintf(field, sizeof field, "bodies[%d].lead", bi);
            return gs_diag_set(d, GS_ERANGE, field,
                               "a %s mesh ('%s') is planar and cannot represent the lead modifications of "
                               "'%s' (they are for the slice analysis)", kind, sm->name, b->name);
        }
    }
    if (sm->misalign_in != 0 || sm->misalign_out != 0) {
        snprintf(field, sizeof field, "meshes[%d].misalignment", m->index);
        return gs_diag_set(d, GS_ERANGE, field,
                           "a %s mesh ('%s') is planar and cannot represent a misalignment (it is for the "
                           "slice analysis)", kind, sm->name);
    }
    return GS_OK;
}

double gsi_mesh_damping(const gs_model_view *sys, const gs_gmesh_rt *m, double k_mean)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    if (sm->damping >= 0)
        return sm->damping;
    double inv = 0;
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (b->coord >= 0 && m->a[b->coord] != 0)
            inv += m->a[b->coord] * m->a[b->coord] / b->inertia_eff;
    }
    return inv > 0 ? 2 * sm->damping_ratio * sqrt(k_mean / inv) : 0;
}

/* Fraction of the segment [x0, x1] on which x > 0, and its derivative in x1:
 * the share of a step spent in contact, continuous in the step's end. */
double gsi_mesh_wet(double x0, double x1, double *dw1)
{
    *dw1 = 0.0;
    if (x0 > 0.0 && x1 > 0.0)
        return 1.0;
    if (x0 <= 0.0 && x1 <= 0.0)
        return 0.0;
    double L = x1 - x0;
    *dw1 = (x1 > 0.0 ? -x0 : x0) / (L * L);
    return x1 > 0.0 ? x1 / L : x0 / -L;
}

static double wet_share(double x0, double x1, double hb, double *dW)
{
    double W = 0.0, dw1;
    *dW = 0.0;
    for (int side = 0; side < 2; side++) {
        double sg = side ? -1.0 : 1.0;
        W += gsi_mesh_wet(sg * x0 - hb, sg * x1 - hb, &dw1);
        *dW += sg * dw1;
    }
    return W;
}

double gsi_mesh_contact_damping(const gs_model_view *sys, const gs_gmesh_rt *m, double x0, double dx, double hb,
                                double *dW)
{
    *dW = 0.0;
    if (!sys->smooth_contact)
        return fabs(x0 + 0.5 * dx) > hb ? m->damping : 0.0;
    return m->damping * wet_share(x0, x0 + dx, hb, dW);
}

void gsi_mesh_add_jacobian(const gs_gmesh_rt *m, int n, double *J, double jss, double jsp, double jps, double jpp)
{
    gsi_mesh_add_jacobian_c(m, m->c, n, J, jss, jsp, jps, jpp);
}

/* Direction of the line of action of translating gear k with the carrier
 * at angle t. */
static void tr_dir_at(const gs_gmesh_rt *m, int k, double t, double n[2])
{
    double c = cos(t), s = sin(t);
    n[0] = c * m->tr_n0[k][0] - s * m->tr_n0[k][1];
    n[1] = s * m->tr_n0[k][0] + c * m->tr_n0[k][1];
}

/* Direction of the line of action of translating gear k at q. */
static void tr_dir(const gs_gmesh_rt *m, int k, const double *q, double n[2])
{
    n[0] = m->tr_n0[k][0], n[1] = m->tr_n0[k][1];
    if (m->tr_carrier >= 0)
        tr_dir_at(m, k, q[m->tr_carrier], n);
}

/* Ramp step of width w centred on 0, and its slope. */
static double ramp(double t, double w, double *dr)
{
    *dr = 0.0;
    if (t <= -0.5 * w)
        return 0.0;
    if (t >= 0.5 * w)
        return 1.0;
    *dr = 1.0 / w;
    return t / w + 0.5;
}

/* Load share of a tooth over its contact, y in [0, eps) mesh cycles from
 * its entry: 1/2 in double contact (entry and exit), 1 in single contact,
 * with the stiffness wave's transitions (width w). Summed over the teeth it
 * is 1 at every roll. */
static double share(double y, double eps, double w, double *dy)
{
    double d0, d1, d2, d3;
    double v = 0.5 * (ramp(y, w, &d0) + ramp(y - (eps - 1.0), w, &d1) - ramp(y - 1.0, w, &d2) -
                      ramp(y - eps, w, &d3));
    *dy = 0.5 * (d0 + d1 - d2 - d3);
    return v;
}

/* Pitch-error part of gear error e at its carrier-frame angle v, and its
 * derivative in v: kp times the share-weighted pitch errors of the teeth in
 * contact. Tooth j stands on the line of centres at x = j, x = (beta - v) z / 2 pi,
 * and is in contact for |x - j| < eps / 2. */
static double pitch_part(const gs_gmesh_rt *m, int e, double v, double *dv)
{
    const double *tab = m->err[e].pitch;
    *dv = 0.0;
    if (!tab || m->pair_err) /* an ltca mesh's: by its tooth pairs (pair_part) */
        return 0.0;
    int z = m->err[e].z;
    double eps = m->contact_ratio, w = m->transition > 0 ? m->transition : 1e-3;
    double x = (m->err[e].beta - v) * z / (2.0 * GS_PI), val = 0.0, dx = 0.0;
    long j0 = (long)floor(x - 0.5 * eps - w) , j1 = (long)ceil(x + 0.5 * eps + w);
    for (long j = j0; j <= j1; j++) {
        double ej = tab[((j % z) + z) % z];
        if (ej == 0.0)
            continue;
        double ds;
        val += ej * share(x - (double)j + 0.5 * eps, eps, w, &ds);
        dx += ej * ds;
    }
    *dv = -m->err[e].kp * dx * z / (2.0 * GS_PI);
    return m->err[e].kp * val;
}

/* The errors of the tooth pairs at position i of cycle k. */
static double pair_row(const struct gs_pair_errors *pe, int i, long k)
{
    double E = 0.0;
    for (int r = 0; r < pe->np; r++) {
        const int *t = pe->tooth + 2 * ((size_t)i * pe->np + r);
        double sh = pe->share[(size_t)i * pe->np + r], e = 0.0;
        if (t[0] < 0 || sh == 0.0)
            continue;
        for (int g = 0; g < 2; g++) {
            if (!pe->pitch[g])
                continue;
            long z = pe->z[g], j = ((t[g] + k * pe->step[g]) % z + z) % z;
            e += pe->kp[g] * pe->pitch[g][j];
        }
        E += sh * e;
    }
    return E;
}

/* The pitch part of an ltca mesh at mesh phase p (cycles from phase0):
 * linear between positions, position j at (j + 1/2) / n of its cycle; with
 * dp its slope. */
static double pair_part(const struct gs_pair_errors *pe, double p, double *dp)
{
    double x = p * pe->n - 0.5, fl = floor(x), w = x - fl;
    long c = (long)fl, n = pe->n;
    long k0 = c >= 0 ? c / n : -((-c + n - 1) / n), i0 = c - k0 * n;
    long i1 = i0 + 1, k1 = k0;
    if (i1 == n)
        i1 = 0, k1++;
    double e0 = pair_row(pe, (int)i0, k0), e1 = pair_row(pe, (int)i1, k1);
    *dp = (e1 - e0) * n;
    return e0 + w * (e1 - e0);
}

static double pair_phase(const struct gs_pair_errors *pe, const double *c, const double *q)
{
    double p = -pe->phase0;
    for (int i = 0; i < pe->n_coords; i++)
        p += c[i] * q[i];
    return p;
}

/* The pitch part's quotient (E_p(p0 + dp) - E_p(p0)) / dp over a step
 * (the slope when dp is 0), and with dq its derivative in dp. */
static double pair_quot(const gs_gmesh_rt *m, const double *q0, const double *dq, double *dqd)
{
    const struct gs_pair_errors *pe = m->pair_err;
    double p0 = pair_phase(pe, m->c, q0), dp = 0.0, s0, s1;
    for (int i = 0; i < pe->n_coords; i++)
        dp += m->c[i] * dq[i];
    double e0 = pair_part(pe, p0, &s0);
    *dqd = 0.0;
    if (dp == 0.0)
        return s0;
    double e1 = pair_part(pe, p0 + dp, &s1), qt = (e1 - e0) / dp;
    *dqd = (s1 - qt) / dp;
    return qt;
}

static double err_angle(const gs_gmesh_rt *m, int e, const double *q)
{
    double v = m->err[e].coord >= 0 ? q[m->err[e].coord] : 0.0;
    return m->err[e].carrier >= 0 ? v - q[m->err[e].carrier] : v;
}

/* Run-out part: the centre offset e (cos(v + phase), sin(v + phase)) along n. */
static double runout_part(const gs_gmesh_rt *m, int e, double v)
{
    double a = v + m->err[e].phase;
    return m->err[e].runout * (m->err[e].n[0] * cos(a) + m->err[e].n[1] * sin(a));
}

double gsi_mesh_error(const gs_gmesh_rt *m, const double *q)
{
    double E = 0.0, dv;
    for (int e = 0; e < m->n_err; e++) {
        double v = err_angle(m, e, q);
        E += pitch_part(m, e, v, &dv) + runout_part(m, e, v);
    }
    if (m->pair_err)
        E += pair_part(m->pair_err, pair_phase(m->pair_err, m->c, q), &dv);
    return E;
}

/* The run-out part's difference quotient (R(v0 + dv) - R(v0)) / dv in
 * closed form without cancellation: 2 sin(dv/2)/dv times the midpoint
 * derivative; with dq its derivative in dv. */
static double runout_quot(const gs_gmesh_rt *m, int e, double v0, double dvv, double *dq)
{
    double am = v0 + 0.5 * dvv + m->err[e].phase, sinc, dsinc;
    if (fabs(dvv) > 1e-4) {
        sinc = 2.0 * sin(0.5 * dvv) / dvv;
        dsinc = (cos(0.5 * dvv) - sinc) / dvv;
    } else {
        sinc = 1.0 - dvv * dvv / 24.0;
        dsinc = -dvv / 12.0;
    }
    double T = -m->err[e].n[0] * sin(am) + m->err[e].n[1] * cos(am);
    double Tp = -m->err[e].n[0] * cos(am) - m->err[e].n[1] * sin(am);
    *dq = m->err[e].runout * (dsinc * T + 0.5 * sinc * Tp);
    return m->err[e].runout * sinc * T;
}

static double err_dv(const gs_gmesh_rt *m, int e, const double *dq)
{
    int ck = m->err[e].coord, cc = m->err[e].carrier;
    return (ck >= 0 ? dq[ck] : 0.0) - (cc >= 0 ? dq[cc] : 0.0);
}

/* Add f * g to J at the gear's and carrier's coordinates of error e (rows
 * and columns, with the carrier's sign). */
static void err_add_jacobian(const gs_gmesh_rt *m, int e, int n, double f, double *J)
{
    int idx[2] = {m->err[e].coord, m->err[e].carrier};
    double sg[2] = {1.0, -1.0};
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++)
            if (idx[a] >= 0 && idx[b] >= 0)
                J[idx[a] * n + idx[b]] += f * sg[a] * sg[b];
}

/* Add to abar the exact discrete gradient of the tooth errors over the step:
 * per gear, (E(v1) - E(v0)) / (v1 - v0) on its angle (and minus it on the
 * carrier's), the derivative when the angle does not move; the run-out part
 * in closed form without cancellation. */
static void error_grad(const gs_gmesh_rt *m, const double *q0, const double *dq, double *abar)
{
    for (int e = 0; e < m->n_err; e++) {
        int ck = m->err[e].coord, cc = m->err[e].carrier;
        double v0 = err_angle(m, e, q0);
        double dvv = err_dv(m, e, dq);
        double d0, d1, dr;
        double p0 = pitch_part(m, e, v0, &d0), gq;
        if (dvv != 0.0) {
            double p1 = pitch_part(m, e, v0 + dvv, &d1);
            gq = (p1 - p0) / dvv;
        } else {
            gq = d0;
        }
        gq += runout_quot(m, e, v0, dvv, &dr);
        if (ck >= 0)
            abar[ck] += gq;
        if (cc >= 0)
            abar[cc] -= gq;
    }
    if (m->pair_err) {
        double dqd, qt = pair_quot(m, q0, dq, &dqd);
        for (int i = 0; i < m->pair_err->n_coords; i++)
            abar[i] += m->c[i] * qt;
    }
}

void gsi_mesh_error_jacobian(const gs_gmesh_rt *m, int n, const double *q0, const double *dq, double f, double *J)
{
    for (int e = 0; e < m->n_err; e++) {
        double v0 = err_angle(m, e, q0);
        double dvv = err_dv(m, e, dq);
        double d0, d1, dg = 0.0, dr;
        if (dvv != 0.0) { /* d/d dv of (P(v0 + dv) - P(v0)) / dv */
            double p0 = pitch_part(m, e, v0, &d0), p1 = pitch_part(m, e, v0 + dvv, &d1);
            dg = (d1 - (p1 - p0) / dvv) / dvv;
        }
        runout_quot(m, e, v0, dvv, &dr);
        err_add_jacobian(m, e, n, f * (dg + dr), J);
    }
    if (m->pair_err) {
        double dqd;
        pair_quot(m, q0, dq, &dqd);
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n && m->c[i] != 0.0; j++)
                J[i * n + j] += f * dqd * m->c[i] * m->c[j];
    }
}

bool gsi_mesh_has_runout(const gs_gmesh_rt *m)
{
    for (int e = 0; e < m->n_err; e++)
        if (m->err[e].runout != 0.0)
            return true;
    return false;
}

double gsi_mesh_runout(const gs_gmesh_rt *m, const double *q)
{
    double R = 0.0;
    for (int e = 0; e < m->n_err; e++)
        if (m->err[e].runout != 0.0)
            R += runout_part(m, e, err_angle(m, e, q));
    return R;
}

void gsi_mesh_runout_grad(const gs_gmesh_rt *m, const double *q0, const double *dq, double scale, double *v)
{
    for (int e = 0; e < m->n_err; e++) {
        if (m->err[e].runout == 0.0)
            continue;
        double dr, gq = scale * runout_quot(m, e, err_angle(m, e, q0), err_dv(m, e, dq), &dr);
        if (m->err[e].coord >= 0)
            v[m->err[e].coord] += gq;
        if (m->err[e].carrier >= 0)
            v[m->err[e].carrier] -= gq;
    }
}

void gsi_mesh_runout_jacobian(const gs_gmesh_rt *m, int n, const double *q0, const double *dq, double f, double *J)
{
    for (int e = 0; e < m->n_err; e++) {
        if (m->err[e].runout == 0.0)
            continue;
        double dr;
        runout_quot(m, e, err_angle(m, e, q0), err_dv(m, e, dq), &dr);
        err_add_jacobian(m, e, n, f * dr, J);
    }
}

double gsi_mesh_s(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    double s = m->n_err ? gsi_mesh_error(m, q) : 0.0;
    for (int i = 0; i < sys->n_coords; i++)
        s += m->a[i] * q[i];
    for (int k = 0; k < m->n_tr; k++) {
        double n[2];
        tr_dir(m, k, q, n);
        s += n[0] * (q[m->tr_coord[k]] + m->tr_off[k][0]) + n[1] * (q[m->tr_coord[k] + 1] + m->tr_off[k][1]) -
             m->tr_c[k];
    }
    return s;
}

const double *gsi_mesh_grad(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0, const double *dq)
{
    if (!m->n_tr && !m->n_err)
        return m->a;
    int n = sys->n_coords;
    for (int i = 0; i < n; i++)
        m->abar[i] = m->a[i];
    for (int k = 0; k < m->n_tr; k++) {
        int x = m->tr_coord[k];
        if (m->tr_carrier < 0) { /* fixed line: linear */
            m->abar[x] += m->tr_n0[k][0];
            m->abar[x + 1] += m->tr_n0[k][1];
            continue;
        }
        /* t = n(theta) . X: t1 - t0 = nbar . dX + (n1 - n0) . Xbar exactly, with
         * n1 - n0 = 2 sin(dth / 2) R(th_mid) J n0 (J: quarter turn). */
        int c = m->tr_carrier;
        double th0 = q0[c], dth = dq[c], thm = th0 + 0.5 * dth;
        double n0[2], n1[2];
        tr_dir_at(m, k, th0, n0);
        tr_dir_at(m, k, th0 + dth, n1); /* n at the step's end */
        m->abar[x] += 0.5 * (n0[0] + n1[0]);
        m->abar[x + 1] += 0.5 * (n0[1] + n1[1]);
        double jn[2] = {-m->tr_n0[k][1], m->tr_n0[k][0]};
        double cm = cos(thm), sm = sin(thm);
        double rj[2] = {cm * jn[0] - sm * jn[1], sm * jn[0] + cm * jn[1]};
        double xb = q0[x] + 0.5 * dq[x] + m->tr_off[k][0], yb = q0[x + 1] + 0.5 * dq[x + 1] + m->tr_off[k][1];
        double sinc = gsi_half_sinc(dth);
        m->abar[c] += sinc * (rj[0] * xb + rj[1] * yb);
    }
    error_grad(m, q0, dq, m->abar);
    return m->abar;
}

double gs_gmesh_s(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    return gsi_mesh_s(sys, m, q);
}

double gs_gmesh_error(const gs_gmesh_rt *m, const double *q)
{
    return gsi_mesh_error(m, q);
}

/* The scene without the tooth errors (pitch tables, run-out) of the gears of
 * mesh `mesh`: bodies (n_bodies, to free) and mods (2) are its storage. */
gs_err gsi_mesh_clean_scene(const gs_scene *sc, int mesh, gs_scene *clean, gs_scene_body **bodies,
                            gs_gear_mods mods[2])
{
    const gs_scene_mesh *sm = &sc->meshes[mesh];
    *clean = *sc;
    *bodies = gs_calloc((size_t)sc->n_bodies, sizeof **bodies);
    if (!*bodies)
        return GS_ENOMEM;
    memcpy(*bodies, sc->bodies, (size_t)sc->n_bodies * sizeof **bodies);
    for (int k = 0; k < 2; k++) {
        gs_scene_body *b = &(*bodies)[sm->gear[k]];
        b->pitch_error_tooth = -1;
        if (!b->mods)
            continue;
        mods[k] = *b->mods;
        mods[k].n_pitch = 0;
        mods[k].pitch_m = NULL;
        mods[k].runout_m = 0.0;
        b->mods = &mods[k];
    }
    clean->bodies = *bodies;
    return GS_OK;
}
