/* SPDX-License-Identifier: MIT
 * One planar frictional impact by Routh's method (METHOD.md section 6,
 * docs/explanation/impact.md). The relative contact velocity is piecewise linear in the
 * normal impulse P_n, with at most two pieces (slip, then stick or reversed
 * slip), so every event (slip stop, end of compression, end of restitution)
 * and every work integral is found in closed form on its piece. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gearsim/impact.h"

const char *gs_restitution_name(gs_restitution law)
{
    switch (law) {
    case GS_RESTITUTION_NEWTON: return "newton";
    case GS_RESTITUTION_POISSON: return "poisson";
    case GS_RESTITUTION_STRONGE: return "stronge";
    }
    return "unknown";
}

bool gs_restitution_parse(const char *name, gs_restitution *law)
{
    static const gs_restitution all[] = {GS_RESTITUTION_NEWTON, GS_RESTITUTION_POISSON,
                                         GS_RESTITUTION_STRONGE};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
        if (name && strcmp(name, gs_restitution_name(all[i])) == 0) {
            *law = all[i];
            return true;
        }
    return false;
}

const char *gs_impact_process_name(gs_impact_process p)
{
    switch (p) {
    case GS_IMPACT_NONE: return "none";
    case GS_IMPACT_FRICTIONLESS: return "frictionless";
    case GS_IMPACT_SLIDING: return "sliding";
    case GS_IMPACT_STICK_COMPRESSION: return "stick_compression";
    case GS_IMPACT_STICK_RESTITUTION: return "stick_restitution";
    case GS_IMPACT_REVERSAL_COMPRESSION: return "reversal_compression";
    case GS_IMPACT_REVERSAL_RESTITUTION: return "reversal_restitution";
    }
    return "unknown";
}

/* One linear piece of the impulse path, in the frame where the initial slip
 * is non-negative: on [p0, next p0), with d = P_n - p0,
 *   v_t = vt + st d,  v_n = vn + sn d,  P_t = pt + spt d. */
typedef struct {
    double p0, vt, vn, pt, st, sn, spt;
} piece;

typedef struct {
    piece s[2];
    int n;
    double vt0, vn0; /* at P_n = 0 */
} path;

static double piece_end(const path *pa, int k)
{
    return k + 1 < pa->n ? pa->s[k + 1].p0 : INFINITY;
}

static void path_add(path *pa, double p0, double st, double sn, double spt)
{
    piece *s = &pa->s[pa->n];
    if (pa->n == 0) {
        *s = (piece){0.0, pa->vt0, pa->vn0, 0.0, 0.0, 0.0, 0.0};
    } else {
        const piece *q = &pa->s[pa->n - 1];
        double d = p0 - q->p0;
        *s = (piece){p0, q->vt + q->st * d, q->vn + q->sn * d, q->pt + q->spt * d, 0, 0, 0};
    }
    s->st = st;
    s->sn = sn;
    s->spt = spt;
    pa->n++;
}

static int piece_of(const path *pa, double p)
{
    int k = 0;
    while (k + 1 < pa->n && p >= pa->s[k + 1].p0)
        k++;
    return k;
}

/* int_a^b v_n dP_n and int_a^b v_t dP_t, exact (the integrands are linear on each piece). */
static void path_work(const path *pa, double a, double b, double *wn, double *wt)
{
    *wn = *wt = 0.0;
    for (int k = 0; k < pa->n; k++) {
        const piece *s = &pa->s[k];
        double lo = fmax(a, s->p0), hi = fmin(b, piece_end(pa, k));
        if (!(hi > lo))
            continue;
        double d0 = lo - s->p0, d1 = hi - s->p0;
        double dn = s->vn * (d1 - d0) + 0.5 * s->sn * (d1 * d1 - d0 * d0);
        double dt = s->vt * (d1 - d0) + 0.5 * s->st * (d1 * d1 - d0 * d0);
        *wn += dn;
        *wt += s->spt * dt;
    }
}

static void path_eval(const path *pa, double p, double *vt, double *vn, double *pt)
{
    const piece *s = &pa->s[piece_of(pa, p)];
    double d = p - s->p0;
    *vt = s->vt + s->st * d;
    *vn = s->vn + s->sn * d;
    *pt = s->pt + s->spt * d;
}

/* Restitution: from the end of compression pc, the P_n at which the law is met. */
static gs_err end_of_restitution(const path *pa, double pc, double e, double vn0,
                                 gs_restitution law, double *pf, gs_diag *d)
{
    if (law == GS_RESTITUTION_POISSON || e == 0.0) {
        *pf = (1.0 + e) * pc;
        return GS_OK;
    }
    double wn_c, wt_c;
    path_work(pa, 0.0, pc, &wn_c, &wt_c);
    double target_v = -e * vn0;      /* Newton */
    double remaining = -e * e * wn_c; /* Stronge: normal work still to be released */
    for (int k = piece_of(pa, pc); k < pa->n; k++) {
        const piece *s = &pa->s[k];
        double start = fmax(pc, s->p0), end = piece_end(pa, k), L = end - start;
        double v = s->vn + s->sn * (start - s->p0);
        if (v < 0.0)
            v = 0.0; /* v_n(pc) = 0 up to round-off */
        if (law == GS_RESTITUTION_NEWTON) {
            if (s->sn > 0.0 && v + s->sn * L >= target_v) {
                *pf = start + fmax(0.0, target_v - v) / s->sn;
                return GS_OK;
            }
        } else {
            double avail = isinf(L) ? INFINITY : v * L + 0.5 * s->sn * L * L;
            if (s->sn > 0.0 && avail >= remaining) {
                /* v x + sn x^2 / 2 = remaining, in the form without cancellation */
                *pf = start + 2.0 * remaining / (v + sqrt(v * v + 2.0 * s->sn * remaining));
                return GS_OK;
            }
            remaining -= avail;
        }
    }
    return gs_diag_set(d, GS_EINTERNAL, "W", "restitution does not end (normal slope <= 0)");
}

static bool finite_all(const double *x, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(x[i]))
            return false;
    return true;
}

gs_err gs_impact_contact(const gs_impact_contact_problem *p, gs_impact_result *r, gs_diag *d)
{
    if (!p || !r)
        return gs_diag_set(d, GS_EINVAL, "", "NULL argument");
    const double Wtt = p->W[0], Wnn = p->W[2];
    if (!finite_all(p->W, 3))
        return gs_diag_set(d, GS_ERANGE, "W", "W must be finite");
    if (!finite_all(p->v0, 2))
        return gs_diag_set(d, GS_ERANGE, "velocity", "the relative velocity must be finite");
    double det = Wtt * Wnn - p->W[1] * p->W[1];
    if (!(Wtt > 0.0) || !(Wnn > 0.0) || !(det > 1e-14 * Wtt * Wnn))
        return gs_diag_set(d, GS_ERANGE, "W",
                           "W = [%g %g; %g %g] is not positive definite", Wtt, p->W[1], p->W[1],
                           Wnn);
    if (!(p->e >= 0.0 && p->e <= 1.0))
        return gs_diag_set(d, GS_ERANGE, "e", "'e' = %g is outside [0, 1]", p->e);
    if (!(p->mu >= 0.0) || !isfinite(p->mu))
        return gs_diag_set(d, GS_ERANGE, "mu", "'mu' = %g must be finite and >= 0", p->mu);
    if ((unsigned)p->law > GS_RESTITUTION_STRONGE)
        return gs_diag_set(d, GS_ERANGE, "hypothesis", "unknown restitution hypothesis");

    memset(r, 0, sizeof *r);
    memcpy(r->W, p->W, sizeof r->W);
    r->v0[0] = r->v[0] = p->v0[0];
    r->v0[1] = r->v[1] = p->v0[1];
    r->impulse_n_slip_stop = -1.0;
    const double vn0 = p->v0[1], mu = p->mu;
    if (!(vn0 < 0.0)) {
        r->process = GS_IMPACT_NONE;
        return GS_OK;
    }
    /* Work in the frame where the initial slip is >= 0; at rest, the one in
     * which slip would start if sticking is impossible (W_tn > 0). */
    double sg = p->v0[0] > 0.0 ? 1.0 : p->v0[0] < 0.0 ? -1.0 : (p->W[1] >= 0.0 ? 1.0 : -1.0);
    const double vt0 = sg * p->v0[0], Wtn = sg * p->W[1];

    path pa = {.n = 0, .vt0 = vt0, .vn0 = vn0};
    double ps = INFINITY; /* slip stop */
    bool stick = false;
    if (mu == 0.0) {
        path_add(&pa, 0.0, Wtn, Wnn, 0.0);
    } else {
        /* Sliding forward: dP_t = -mu dP_n, so v_t falls at k = mu W_tt - W_tn. */
        double k = mu * Wtt - Wtn;
        if (k > 0.0) {
            ps = vt0 / k;
            stick = fabs(Wtn) <= mu * Wtt; /* the sticking impulse ratio -W_tn/W_tt lies in the cone */
            if (ps > 0.0)
                path_add(&pa, 0.0, -k, Wnn - mu * Wtn, -mu);
            else
                path_add(&pa, 0.0, 0.0, 0.0, 0.0); /* zero-length placeholder, replaced below */
            if (stick)
                path_add(&pa, ps, 0.0, det / Wtt, -Wtn / Wtt);
            else
                path_add(&pa, ps, Wtn + mu * Wtt, Wnn + mu * Wtn, mu);
            pa.s[1].vt = 0.0; /* exactly at the slip stop */
            if (ps == 0.0) {
                pa.s[0] = pa.s[1];
                pa.n = 1;
            }
        } else {
            path_add(&pa, 0.0, -k, Wnn - mu * Wtn, -mu);
        }
    }

    /* End of compression: the first P_n where v_n reaches 0. */
    double pc = -1.0;
    for (int k = 0; k < pa.n && pc < 0.0; k++) {
        const piece *s = &pa.s[k];
        double L = piece_end(&pa, k) - s->p0;
        if (s->sn > 0.0 && (isinf(L) || s->vn + s->sn * L >= 0.0))
            pc = s->p0 + fmax(0.0, -s->vn) / s->sn;
    }
    if (pc < 0.0)
        return gs_diag_set(d, GS_EINTERNAL, "W", "compression does not end (normal slope <= 0)");
    double pf = pc;
    GS_TRY(end_of_restitution(&pa, pc, p->e, vn0, p->law, &pf, d));

    double vt, vn, pt;
    path_eval(&pa, pf, &vt, &vn, &pt);
    double wn_c, wt_c, wn_r, wt_r;
    path_work(&pa, 0.0, pc, &wn_c, &wt_c);
    path_work(&pa, pc, pf, &wn_r, &wt_r);

    r->impulse_n = pf;
    r->impulse_t = sg * pt;
    r->impulse_n_compression = pc;
    r->v[0] = sg * vt;
    r->v[1] = vn;
    r->work_n_compression = wn_c;
    r->work_n_restitution = wn_r;
    r->dissipation_n = -(wn_c + wn_r);
    r->dissipation_t = -(wt_c + wt_r);
    r->dissipation = r->dissipation_n + r->dissipation_t;
    if (mu == 0.0) {
        r->process = GS_IMPACT_FRICTIONLESS;
    } else if (ps < pf || ps == 0.0) {
        r->impulse_n_slip_stop = ps;
        bool in_compression = ps < pc || ps == 0.0;
        r->process = stick ? (in_compression ? GS_IMPACT_STICK_COMPRESSION : GS_IMPACT_STICK_RESTITUTION)
                           : (in_compression ? GS_IMPACT_REVERSAL_COMPRESSION
                                             : GS_IMPACT_REVERSAL_RESTITUTION);
    } else {
        r->process = GS_IMPACT_SLIDING;
    }
    return GS_OK;
}

static double kinetic(const gs_impact_body *b, const double v[2], double w)
{
    return b->fixed ? 0.0 : 0.5 * b->mass * (v[0] * v[0] + v[1] * v[1]) + 0.5 * b->inertia * w * w;
}

gs_err gs_impact_solve(const gs_impact_case *c, gs_impact_result *r, gs_diag *d)
{
    if (!c || !r)
        return gs_diag_set(d, GS_EINVAL, "", "NULL argument");
    char f[64];
    for (int i = 0; i < 2; i++) {
        const gs_impact_body *b = &c->body[i];
        if (!finite_all(b->centre, 2) || !finite_all(b->velocity, 2) || !isfinite(b->omega)) {
            snprintf(f, sizeof f, "bodies[%d]", i);
            return gs_diag_set(d, GS_ERANGE, f, "centre, velocity and omega must be finite");
        }
        if (b->fixed)
            continue;
        if (!(b->mass > 0.0) || !isfinite(b->mass)) {
            snprintf(f, sizeof f, "bodies[%d].mass", i);
            return gs_diag_set(d, GS_ERANGE, f, "'mass' = %g must be finite and > 0", b->mass);
        }
        if (!(b->inertia > 0.0) || !isfinite(b->inertia)) {
            snprintf(f, sizeof f, "bodies[%d].inertia", i);
            return gs_diag_set(d, GS_ERANGE, f, "'inertia' = %g must be finite and > 0",
                               b->inertia);
        }
    }
    if (c->body[0].fixed && c->body[1].fixed)
        return gs_diag_set(d, GS_ERANGE, "bodies", "at most one body may be fixed");
    if (!finite_all(c->point, 2))
        return gs_diag_set(d, GS_ERANGE, "contact.point", "the contact point must be finite");
    double nl = hypot(c->normal[0], c->normal[1]);
    if (!(nl > 0.0) || !isfinite(nl))
        return gs_diag_set(d, GS_ERANGE, "contact.normal", "the normal must be finite and non-zero");
    const double n[2] = {c->normal[0] / nl, c->normal[1] / nl}, t[2] = {-n[1], n[0]};

    gs_impact_contact_problem p = {{0, 0, 0}, {0, 0}, c->e, c->mu, c->law};
    double q[2][2], u[2] = {0, 0};
    for (int i = 0; i < 2; i++) {
        const gs_impact_body *b = &c->body[i];
        /* q = z x r: the contact point moves with v + omega q */
        q[i][0] = -(c->point[1] - b->centre[1]);
        q[i][1] = c->point[0] - b->centre[0];
        double sgn = i == 0 ? 1.0 : -1.0;
        for (int k = 0; k < 2; k++)
            u[k] += sgn * (b->velocity[k] + b->omega * q[i][k]);
        if (b->fixed)
            continue;
        double qt = q[i][0] * t[0] + q[i][1] * t[1], qn = q[i][0] * n[0] + q[i][1] * n[1];
        p.W[0] += 1.0 / b->mass + qt * qt / b->inertia;
        p.W[1] += qt * qn / b->inertia;
        p.W[2] += 1.0 / b->mass + qn * qn / b->inertia;
    }
    p.v0[0] = u[0] * t[0] + u[1] * t[1];
    p.v0[1] = u[0] * n[0] + u[1] * n[1];
    GS_TRY(gs_impact_contact(&p, r, d));

    const double P[2] = {r->impulse_t * t[0] + r->impulse_n * n[0],
                         r->impulse_t * t[1] + r->impulse_n * n[1]};
    r->energy_before = r->energy_after = 0.0;
    for (int i = 0; i < 2; i++) {
        const gs_impact_body *b = &c->body[i];
        double sgn = i == 0 ? 1.0 : -1.0;
        r->velocity[i][0] = b->velocity[0];
        r->velocity[i][1] = b->velocity[1];
        r->omega[i] = b->omega;
        if (!b->fixed) {
            r->velocity[i][0] += sgn * P[0] / b->mass;
            r->velocity[i][1] += sgn * P[1] / b->mass;
            r->omega[i] += sgn * (q[i][0] * P[0] + q[i][1] * P[1]) / b->inertia;
        }
        r->energy_before += kinetic(b, b->velocity, b->omega);
        r->energy_after += kinetic(b, r->velocity[i], r->omega[i]);
    }
    memcpy(r->tangent, t, sizeof t);
    memcpy(r->normal, n, sizeof n);
    return GS_OK;
}
