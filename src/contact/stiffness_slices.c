/* SPDX-License-Identifier: MIT
 * gearsim contact module: the loaded tooth contact analysis by slices of a
 * helical (or lead-modified, misaligned) pair (docs/explanation/helical.md
 * "Loaded tooth contact by slices").
 *
 * The planar quasi-static analysis of the transverse section (stiffness.c,
 * the same default mesh and near-field correction as a spur pair, at the
 * same line load) gives at each roll position the elastic TE and the force
 * of each tooth pair, hence the stiffness per unit face width of one tooth
 * pair as a function of its place on the path of contact,
 *     s(xi) = F_p / (te_elastic b)       (N/(mm um)),
 * sampled at xi = roll + k (k: the pair's offset in base pitches) and 0
 * where the pair carries nothing. The face is cut into n slices; slice i of
 * the tooth pair k sits at xi = roll + k + sigma eps_beta z_i / b (its own
 * roll position on the contact line). Each tooth pair is an elastic
 * foundation of stiffness s(xi_i) per unit width coupled along the face by
 * a shear layer of stiffness s_bar lambda^2 (s_bar the mean of s over the
 * path, lambda the coupling length): the energy of the deflection w(z) is
 *     1/2 int s w^2 + s_bar lambda^2 w'^2 dz,
 * free at the face ends, whose influence function for a point load on a
 * uniform tooth decays as exp(-|z| / lambda). Discretised by slices (width
 * h: foundation s_i h, coupling springs s_bar lambda^2 / h), each tooth
 * pair's stiffness matrix K is tridiagonal and an M-matrix. The rigid
 * approach delta (um along the line of action) against the gap e_i of the
 * lead modifications and the misalignment gives the obstacle problem
 *     K w = f,  w_i >= delta - e_i,  f_i >= 0,  f_i (w_i - delta + e_i) = 0
 * per tooth pair, solved by a primal-dual active set (finite for an
 * M-matrix); delta is found so that the forces sum to F (piecewise linear
 * and increasing in delta: Newton safeguarded by bisection). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact/stiffness_internal.h"
#include "gearsim/geometry.h"
#include "gearsim/util.h"

/* Default number of slices, and the fewest / most accepted. */
#define SL_DEFAULT 320
#define SL_MAX 2000
/* Tooth pairs (offsets) a position may hold. */
#define SL_TEETH 16

/* The pair stiffness s(xi) sampled on a grid xi = k0 + m / np. */
typedef struct sgrid {
    int np, nk, k0;
    double *s;         /* nk np: N/(mm um) */
    int *t2;           /* nk: driven tooth of offset k (-1 unknown) */
} sgrid;

static double sgrid_at(const sgrid *g, double xi)
{
    double u = (xi - g->k0) * g->np;
    double fl = floor(u);
    long m = (long)fl;
    long n = (long)g->nk * g->np;
    if (m < 0 || m >= n)
        return 0.0;
    double a = g->s[m], b = m + 1 < n ? g->s[m + 1] : 0.0;
    return a + (u - fl) * (b - a);
}

/* Gap of the lead modifications of one gear at z (m from the face centre). */
static double lead_gap(const gs_lead_mods *l, double z, double b)
{
    double x = 2.0 * z / b, g = l->crowning * x * x + l->slope * z / b;
    if (l->end_relief > 0.0 && l->end_relief_length > 0.0) {
        double in = fabs(z) - (0.5 * b - l->end_relief_length);
        if (in > 0.0) {
            double r = in / l->end_relief_length;
            g += l->end_relief * (l->end_relief_parabolic ? r * r : r);
        }
    }
    return g;
}

/* Tridiagonal solve (Thomas) in place: a sub, c diag, u super, r rhs -> x. */
static void tridiag(int n, const double *a, const double *c, const double *u, double *r, double *cp)
{
    double den = c[0];
    cp[0] = u[0] / den;
    r[0] /= den;
    for (int i = 1; i < n; i++) {
        den = c[i] - a[i] * cp[i - 1];
        cp[i] = u[i] / den;
        r[i] = (r[i] - a[i] * r[i - 1]) / den;
    }
    for (int i = n - 2; i >= 0; i--)
        r[i] -= cp[i] * r[i + 1];
}

/* One tooth pair: diag kd (N/um), coupling kc (N/um, constant), eligibility
 * el, obstacle dd (um). Solves the obstacle problem; w, f out; *slope the
 * derivative of sum f with respect to a uniform shift of dd. Returns the
 * sum of f. */
typedef struct tooth_ws {
    double *a, *c, *u, *r, *cp, *w, *f, *dw;
    unsigned char *act;
} tooth_ws;

static double solve_tooth(int n, const double *kd, double kl, double kc, const unsigned char *el,
                          const double *dd, tooth_ws *t, double *slope)
{
    int any = 0;
    for (int i = 0; i < n; i++) {
        t->act[i] = el[i] && dd[i] > 0.0;
        any |= el[i];
    }
    memset(t->f, 0, (size_t)n * sizeof *t->f);
    *slope = 0.0;
    if (!any)
        return 0.0;
    for (int pass = 0; pass < 2; pass++) {
        /* pass 0: the active set (w: the body under the local springs; an active
         * slice's surface sits on its obstacle); pass 1: d(sum f)/d(shift) */
        for (int it = 0; it < (pass ? 1 : 4 * n + 10); it++) {
            for (int i = 0; i < n; i++) {
                t->a[i] = i > 0 ? -kc : 0.0;
                t->u[i] = i < n - 1 ? -kc : 0.0;
                t->c[i] = kd[i] + (i > 0 ? kc : 0.0) + (i < n - 1 ? kc : 0.0) + (t->act[i] ? kl : 0.0);
                t->r[i] = t->act[i] ? kl * (pass ? 1.0 : dd[i]) : 0.0;
            }
            tridiag(n, t->a, t->c, t->u, t->r, t->cp);
            if (pass)
                break;
            memcpy(t->w, t->r, (size_t)n * sizeof *t->w);
            int changed = 0;
            for (int i = 0; i < n; i++) {
                double fi = t->act[i] ? kl * (dd[i] - t->w[i]) : 0.0;
                unsigned char na = el[i] && (t->act[i] ? fi > 0.0 : t->w[i] < dd[i]);
                t->f[i] = t->act[i] ? fi : 0.0;
                if (na != t->act[i]) {
                    t->act[i] = na;
                    changed = 1;
                }
            }
            if (!changed)
                break;
        }
    }
    double sf = 0.0, sl = 0.0;
    for (int i = 0; i < n; i++)
        if (t->act[i]) {
            sf += t->f[i];
            sl += kl * (1.0 - t->r[i]);
        }
    *slope = sl;
    return sf;
}

/* The state of one position: teeth (offsets) in reach and their slices. */
typedef struct spos {
    int nt;
    int k[SL_TEETH];
    double *kd;                /* nt n: foundation per slice, N/um */
    unsigned char *el;         /* nt n */
    double *dd, *f;            /* nt n */
    double *e;                 /* n: gap of modifications and misalignment, um */
    double kc;                 /* coupling spring, N/um */
    double kl;                 /* local (contact) spring per slice, N/um */
    int n;
} spos;

static double total_force(spos *p, double delta, tooth_ws *t, double *slope, int keep)
{
    double sum = 0.0, sl = 0.0;
    int n = p->n;
    for (int q = 0; q < p->nt; q++) {
        for (int i = 0; i < n; i++)
            p->dd[(size_t)q * n + i] = delta - p->e[i];
        double s1;
        sum += solve_tooth(n, p->kd + (size_t)q * n, p->kl, p->kc, p->el + (size_t)q * n, p->dd + (size_t)q * n, t, &s1);
        sl += s1;
        if (keep)
            memcpy(p->f + (size_t)q * n, t->f, (size_t)n * sizeof *t->f);
    }
    *slope = sl;
    return sum;
}

/* delta (um) such that the forces sum to F (N); f kept. */
static double solve_delta(spos *p, double F, tooth_ws *t, double *emin_out)
{
    double emin = INFINITY;
    int n = p->n;
    for (int q = 0; q < p->nt; q++)
        for (int i = 0; i < n; i++)
            if (p->el[(size_t)q * n + i])
                emin = fmin(emin, p->e[i]);
    *emin_out = emin;
    double lo = emin, hi = emin + 1.0, sl;
    while (total_force(p, hi, t, &sl, 0) < F)
        hi = lo + 2.0 * (hi - lo);
    double x = hi;
    for (int it = 0; it < 200; it++) {
        double P = total_force(p, x, t, &sl, 0) - F;
        if (fabs(P) <= 1e-12 * F)
            break;
        if (P > 0)
            hi = x;
        else
            lo = x;
        double xn = sl > 0 ? x - P / sl : 0.5 * (lo + hi);
        if (!(xn > lo && xn < hi))
            xn = 0.5 * (lo + hi);
        x = xn;
        if (hi - lo < 1e-14 * (1.0 + fabs(hi)))
            break;
    }
    total_force(p, x, t, &sl, 1);
    return x;
}

gs_err gsi_stiff_slices(const gs_scene *sc, const gs_scene_mesh *sm, const gs_stiffness_opts *o,
                        gs_stiffness_result *out, gs_diag *d)
{
    const int driver = o->driver;
    const gs_scene_body *bA = &sc->bodies[sm->gear[driver]], *bB = &sc->bodies[sm->gear[1 - driver]];
    const gs_gear_params *gA = &bA->gear;
    int N = out->positions, n = o->slices > 0 ? o->slices : SL_DEFAULT;
    if (n < 2 || n > SL_MAX)
        return gs_diag_set(d, GS_ERANGE, "slices", "slices must be 2..%d, not %d", SL_MAX, n);
    double bmm = out->face_width_mm, F = out->force_n;
    double beta = gA->helix_angle;
    double mn = beta > 0 ? gA->normal_module_m : gA->module_m;
    double eb = bmm * 1e-3 * sin(beta) / (GS_PI * mn);
    double sigma = (gA->hand < 0 ? -1.0 : 1.0) * (out->torque_nm > 0 ? 1.0 : -1.0);
    /* default coupling length: 1.1 m_n, the decay length of a strip load's
     * deflection along the face of a 3D tooth (tests/reference/helical_coupling) */
    double lam = o->coupling_mm > 0 ? o->coupling_mm : 1.1 * mn * 1e3;
    /* pair stiffness grid from the planar positions */
    int sg = out->torque_nm > 0 ? 1 : -1, z1 = out->teeth[0];
    int tref = out->pt[0].n_pair > 0 ? out->pt[0].pair[0].tooth[0] : 0;
    int kmin = 0, kmax = 0;
    for (int j = 0; j < N; j++)
        for (int q = 0; q < out->pt[j].n_pair; q++) {
            int k = ((sg * (out->pt[j].pair[q].tooth[0] - tref)) % z1 + z1) % z1;
            if (k > z1 / 2)
                k -= z1;
            kmin = k < kmin ? k : kmin;
            kmax = k > kmax ? k : kmax;
        }
    sgrid g = {N, kmax - kmin + 3, kmin - 1, NULL, NULL};
    g.s = gs_calloc((size_t)g.nk * N, sizeof *g.s);
    g.t2 = malloc((size_t)g.nk * sizeof *g.t2);
    double spur_kmin = out->k_min, spur_kmax = out->k_max, spur_pp = out->te_loaded_max - out->te_loaded_min;
    size_t nn = (size_t)SL_TEETH * n;
    spos p = {0};
    p.n = n;
    p.kd = malloc(nn * sizeof *p.kd);
    p.el = malloc(nn);
    p.dd = malloc(nn * sizeof *p.dd);
    p.f = malloc(nn * sizeof *p.f);
    p.e = malloc((size_t)n * sizeof *p.e);
    tooth_ws t;
    double *ws = malloc((size_t)8 * n * sizeof *ws);
    t.act = malloc((size_t)n);
    double *fz = gs_calloc((size_t)N * n, sizeof *fz), *zz = malloc((size_t)n * sizeof *zz);
    double *qbar = gs_calloc((size_t)n, sizeof *qbar);
    gs_err e = GS_OK;
    if (!g.s || !g.t2 || !p.kd || !p.el || !p.dd || !p.f || !p.e || !ws || !t.act || !fz || !zz || !qbar) {
        e = GS_ENOMEM;
        goto done;
    }
    t.a = ws;
    t.c = ws + n;
    t.u = ws + 2 * n;
    t.r = ws + 3 * n;
    t.cp = ws + 4 * n;
    t.w = ws + 5 * n;
    t.f = ws + 6 * n;
    t.dw = ws + 7 * n;
    for (int k = 0; k < g.nk; k++)
        g.t2[k] = -1;
    double sbar = 0.0;
    int ns = 0;
    for (int j = 0; j < N; j++) {
        const gs_stiffness_point *pt = &out->pt[j];
        for (int q = 0; q < pt->n_pair; q++) {
            int k = ((sg * (pt->pair[q].tooth[0] - tref)) % z1 + z1) % z1;
            if (k > z1 / 2)
                k -= z1;
            double s = pt->pair[q].force_n / (pt->te_elastic_um * bmm);
            g.s[(size_t)(k - g.k0) * N + j] = s;
            g.t2[k - g.k0] = pt->pair[q].tooth[1];
        }
    }
    /* s_bar: the mean of s over the loaded path (where s > 0) */
    for (long m = 0; m < (long)g.nk * N; m++)
        if (g.s[m] > 0) {
            sbar += g.s[m];
            ns++;
        }
    sbar = ns ? sbar / ns : 0.0;
    if (!(sbar > 0)) {
        e = gs_diag_set(d, GS_EINFEASIBLE, "meshes", "'%s': no tooth pair carried load in the planar analysis",
                        sm->name);
        goto done;
    }
    /* The local part of the pair compliance, which does not spread along the
     * face: the flattening of both flanks to one normal module below the
     * contact (Hertz line contact, plane strain) at the mean load per unit
     * length of contact line, F cos(beta_b) / (b eps_alpha); effective radius
     * of the flanks' normal section at the pitch point. um mm / N. */
    double cloc;
    {
        const gs_gear_params *gB = &bB->gear;
        double bb = gs_gear_base_helix_angle(gA), at = gA->pressure_angle;
        double r1 = 0.5 * gA->module_m * gA->teeth * sin(at) / cos(bb);
        double r2 = 0.5 * gB->module_m * gB->teeth * sin(at) / cos(bb);
        double ri = gB->kind == GS_GEAR_INTERNAL || gA->kind == GS_GEAR_INTERNAL ? -1.0 : 1.0;
        double R = 1.0 / (1.0 / fmin(r1, r2) + ri / fmax(r1, r2));
        double P = F * cos(bb) / (bmm * 1e-3 * out->contact_ratio);
        const gs_material *m1 = &bA->material, *m2 = &bB->material;
        double es = gs_hertz_line_modulus(m1->youngs_pa, m1->poisson, m2->youngs_pa, m2->poisson, GS_PLANE_STRAIN);
        double a = gs_hertz_line_half_width(P, R, es);
        double dep = mn;
        double ap = gs_hertz_line_approach(P, a, dep, m1->youngs_pa, m1->poisson, GS_PLANE_STRAIN) +
                    gs_hertz_line_approach(P, a, dep, m2->youngs_pa, m2->poisson, GS_PLANE_STRAIN);
        cloc = ap / P / 1e-9;
        if (!(cloc > 0.0))
            cloc = 0.0;
    }
    /* the foundation (bending, shear, rim): 1/s_b = 1/s - c_loc */
    sbar = 0.0;
    ns = 0;
    for (long m = 0; m < (long)g.nk * N; m++)
        if (g.s[m] > 0) {
            double x = g.s[m] * cloc;
            g.s[m] = g.s[m] / (x < 0.9 ? 1.0 - x : 0.1);
            sbar += g.s[m];
            ns++;
        }
    sbar /= ns;
    double h = bmm / n;
    p.kc = sbar * lam * lam / h;
    p.kl = cloc > 0.0 ? h / cloc : 1e12;
    out->local_compliance = cloc;
    /* the back flank (a negative moment) sees the misalignment and the slope
     * deviations with the other sign: they turn the flanks, the crowning and
     * end relief take material off both */
    double fl = out->torque_nm < 0 ? -1.0 : 1.0;
    for (int i = 0; i < n; i++) {
        double z = (-0.5 * bmm + (i + 0.5) * h) * 1e-3, b = bmm * 1e-3;
        zz[i] = z * 1e3;
        double tilt = (bA->lead.slope + bB->lead.slope + sm->misalign_in) * z / b;
        p.e[i] = 1e6 * (lead_gap(&bA->lead, z, b) + lead_gap(&bB->lead, z, b) + (fl - 1.0) * tilt +
                        sm->misalign_in * z / b);
    }
    /* the positions */
    double kmean = 0.0;
    for (int j = 0; j < N; j++) {
        gs_stiffness_point *pt = &out->pt[j];
        double rho = pt->roll;
        p.nt = 0;
        for (int k = g.k0 - (int)ceil(eb) - 1; k <= g.k0 + g.nk + (int)ceil(eb) + 1 && p.nt < SL_TEETH; k++) {
            int anyc = 0;
            double *kd = p.kd + (size_t)p.nt * n;
            unsigned char *el = p.el + (size_t)p.nt * n;
            for (int i = 0; i < n; i++) {
                double s = sgrid_at(&g, rho + k + sigma * eb * zz[i] / bmm);
                el[i] = s > 0.0;
                anyc |= el[i];
                kd[i] = fmax(s, 1e-6 * sbar) * h;
            }
            if (anyc)
                p.k[p.nt++] = k;
        }
        double emin, delta = solve_delta(&p, F, &t, &emin), emin2;
        double te0p = pt->te0_um;
        double dh = o->tangent ? solve_delta(&p, 0.5 * F, &t, &emin2) : NAN;
        if (o->tangent)
            solve_delta(&p, F, &t, &emin2); /* the forces at F again */
        pt->te_ref_um = te0p;
        pt->te0_um = te0p + emin;
        pt->te_raw_um = te0p + delta;
        pt->te_loaded_um = delta;
        pt->te_elastic_um = delta - emin;
        pt->k = F / pt->te_elastic_um / bmm;
        pt->te_half_um = o->tangent ? te0p + dh : NAN;
        pt->k_tan = o->tangent ? 0.5 * F / (delta - dh) / bmm : NAN;
        pt->delta_rad = pt->te_raw_um * 1e-6 / out->base_radius_m * (out->torque_nm > 0 ? 1.0 : -1.0);
        pt->peak_load_n_mm = 0.0;
        gs_stiffness_pair acc[SL_TEETH];
        for (int q = 0; q < p.nt; q++) {
            double s = 0.0;
            for (int i = 0; i < n; i++) {
                double fi = p.f[(size_t)q * n + i];
                s += fi;
                fz[(size_t)j * n + i] += fi / h;
                pt->peak_load_n_mm = fmax(pt->peak_load_n_mm, fi / h);
            }
            int k = p.k[q];
            acc[q].tooth[0] = ((tref + sg * k) % z1 + z1) % z1;
            acc[q].tooth[1] = k >= g.k0 && k < g.k0 + g.nk ? g.t2[k - g.k0] : -1;
            acc[q].force_n = s;
        }
        /* by decreasing force */
        for (int a = 1; a < p.nt; a++)
            for (int b2 = a; b2 > 0 && acc[b2].force_n > acc[b2 - 1].force_n; b2--) {
                gs_stiffness_pair x = acc[b2];
                acc[b2] = acc[b2 - 1];
                acc[b2 - 1] = x;
            }
        pt->pairs = 0;
        pt->n_pair = 0;
        for (int q = 0; q < p.nt; q++) {
            if (acc[q].force_n >= 0.01 * F)
                pt->pairs++;
            if (acc[q].force_n >= 1e-6 * F && pt->n_pair < GS_STIFF_MAX_PAIRS)
                pt->pair[pt->n_pair++] = acc[q];
        }
        for (int i = 0; i < n; i++)
            qbar[i] += fz[(size_t)j * n + i] / N;
        kmean += pt->k / N;
    }
    (void)kmean;
    double qmax = 0.0;
    for (int i = 0; i < n; i++)
        qmax = fmax(qmax, qbar[i]);
    out->slices = n;
    out->coupling_mm = lam;
    out->overlap_ratio = eb;
    out->k_hbeta = qmax / (F / bmm);
    out->section_k_min = spur_kmin;
    out->section_k_max = spur_kmax;
    out->section_te_pp = spur_pp;
    out->face_z_mm = zz;
    out->face_load = fz;
    zz = fz = NULL;
done:
    free(g.s);
    free(g.t2);
    free(p.kd);
    free(p.el);
    free(p.dd);
    free(p.f);
    free(p.e);
    free(ws);
    free(t.act);
    free(fz);
    free(zz);
    free(qbar);
    return e;
}
