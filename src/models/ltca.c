/* SPDX-License-Identifier: MIT
 * LTCA tables of a gear mesh and their potential (include/gearsim/ltca.h). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gearsim/fe_modes.h"
#include "gearsim/ltca.h"
#include "gearsim/modification.h"
#include "gearsim/stiffness.h"
#include "gearsim/util.h"
#include "models/ltca_paths.h"
#include "ltca_helical.h"
#include "mesh_common.h"

/* Front-flank loads as fractions of the reference line load of 200 N/mm
 * times the face width, and the back flank's: enough to span what the
 * dynamics reach (from near contact loss to about 2.5 times the reference)
 * on the loaded flank, and a few on the other for tooth impacts across the
 * backlash. */
static const double front_frac[] = {0.01, 0.03, 0.06, 0.1, 0.15, 0.21, 0.28, 0.37, 0.5, 0.7, 1.0, 1.5, 2.5};
static const double back_frac[] = {0.03, 0.15, 0.6};
#define N_FRONT ((int)(sizeof front_frac / sizeof front_frac[0]))
#define N_BACK ((int)(sizeof back_frac / sizeof back_frac[0]))
#define LINE_LOAD_N_PER_M 200e3

void gs_ltca_table_clear(gs_ltca_table *t)
{
    if (!t)
        return;
    free(t->d);
    free(t->f);
    free(t->v);
    free(t->pair_tooth);
    free(t->pair_share);
    memset(t, 0, sizeof *t);
}

/* ---------------------------------------------------------------------- */
/* One row: F piecewise linear in x, V its integral                        */
/* ---------------------------------------------------------------------- */

/* Segment k (0 .. m-2) holding x, the end segments continued outwards. */
static int row_seg(const double *d, int m, double x)
{
    return gs_index_below(d, m - 1, x);
}

static double seg_slope(const double *d, const double *f, int k)
{
    return (f[k + 1] - f[k]) / (d[k + 1] - d[k]);
}

double gs_ltca_row_force(const gs_ltca_table *t, int j, double x, double *slope)
{
    const double *d = t->d + (size_t)j * t->m, *f = t->f + (size_t)j * t->m;
    int k = row_seg(d, t->m, x);
    double s = seg_slope(d, f, k);
    if (slope)
        *slope = s;
    return f[k] + s * (x - d[k]);
}

double gs_ltca_row_energy(const gs_ltca_table *t, int j, double x)
{
    const double *d = t->d + (size_t)j * t->m, *f = t->f + (size_t)j * t->m, *v = t->v + (size_t)j * t->m;
    int k = row_seg(d, t->m, x);
    double dx = x - d[k];
    return v[k] + dx * (f[k] + 0.5 * seg_slope(d, f, k) * dx);
}

/* The mean of F_j over [x0, x1] (F_j(x0) when equal), piece by piece, and
 * its derivative in x1. */
static double row_mean(const gs_ltca_table *t, int j, double x0, double x1, double *dq1)
{
    const double *d = t->d + (size_t)j * t->m, *f = t->f + (size_t)j * t->m;
    int m = t->m;
    int k0 = row_seg(d, m, x0), k1 = row_seg(d, m, x1);
    if (k0 == k1) {
        double s = seg_slope(d, f, k0);
        *dq1 = 0.5 * s;
        return f[k0] + s * (0.5 * (x0 + x1) - d[k0]);
    }
    double lo = fmin(x0, x1), hi = fmax(x0, x1);
    int klo = k0 < k1 ? k0 : k1, khi = k0 < k1 ? k1 : k0;
    double sum = 0.0;
    for (int k = klo; k <= khi; k++) {
        double a = k == klo ? lo : d[k], b = k == khi ? hi : d[k + 1];
        double s = seg_slope(d, f, k);
        sum += (b - a) * (f[k] + s * (0.5 * (a + b) - d[k]));
    }
    double q = sum / (hi - lo), s1;
    double F1 = gs_ltca_row_force(t, j, x1, &s1);
    *dq1 = (F1 - q) / (x1 - x0);
    return q;
}

/* V of every row: the integral of F from the dead zone (0 there). */
static void integrate(gs_ltca_table *t)
{
    int m = t->m, z = t->zero_back;
    for (int j = 0; j < t->n; j++) {
        const double *dd = t->d + (size_t)j * m, *ff = t->f + (size_t)j * m;
        double *vv = t->v + (size_t)j * m;
        vv[z] = vv[z + 1] = 0.0;
        for (int a = z + 1; a + 1 < m; a++)
            vv[a + 1] = vv[a] + 0.5 * (ff[a] + ff[a + 1]) * (dd[a + 1] - dd[a]);
        for (int a = z; a > 0; a--)
            vv[a - 1] = vv[a] - 0.5 * (ff[a - 1] + ff[a]) * (dd[a] - dd[a - 1]);
    }
}

gs_err gs_ltca_table_set(gs_ltca_table *t, int n, int m, const double *d, const double *f, gs_diag *dg)
{
    memset(t, 0, sizeof *t);
    if (n < 2 || m < 3)
        return gs_diag_set(dg, GS_ERANGE, "ltca", "an LTCA table needs 2 positions and 3 knots at least");
    t->d = gs_calloc((size_t)n * m, sizeof(double));
    t->f = gs_calloc((size_t)n * m, sizeof(double));
    t->v = gs_calloc((size_t)n * m, sizeof(double));
    if (!t->d || !t->f || !t->v) {
        gs_ltca_table_clear(t);
        return GS_ENOMEM;
    }
    t->n = n;
    t->m = m;
    int zb = -1;
    for (int j = 0; j < n; j++) {
        double *dd = t->d + (size_t)j * m, *ff = t->f + (size_t)j * m;
        memcpy(dd, d + (size_t)j * m, (size_t)m * sizeof(double));
        memcpy(ff, f + (size_t)j * m, (size_t)m * sizeof(double));
        /* insertion sort by (force, deflection) */
        for (int a = 1; a < m; a++)
            for (int b = a; b > 0 && (ff[b] < ff[b - 1] || (ff[b] == ff[b - 1] && dd[b] < dd[b - 1])); b--) {
                double x = ff[b];
                ff[b] = ff[b - 1], ff[b - 1] = x;
                x = dd[b];
                dd[b] = dd[b - 1], dd[b - 1] = x;
            }
        int z = -1;
        for (int a = 0; a + 1 < m; a++)
            if (ff[a] == 0.0 && ff[a + 1] == 0.0)
                z = a;
        if (z < 0 || (zb >= 0 && z != zb)) {
            gs_ltca_table_clear(t);
            return gs_diag_set(dg, GS_ERANGE, "ltca", "position %d: the table has no dead zone (two zero-force "
                               "closings) at the same knot as the others", j);
        }
        zb = z;
        for (int a = 0; a + 1 < m; a++)
            if (!(dd[a + 1] > dd[a]) || !isfinite(dd[a]) || !isfinite(ff[a])) {
                gs_ltca_table_clear(t);
                return gs_diag_set(dg, GS_ERANGE, "ltca",
                                   "position %d: the static TE does not grow with the load (knots %d, %d: %g, %g m)",
                                   j, a, a + 1, dd[a], dd[a + 1]);
            }
    }
    t->zero_back = zb;
    integrate(t);
    return GS_OK;
}

/* The mean over the positions of the tangent at the scene load's knot (the
 * mean of its two segments' slopes). */
static double tangent_mean(const gs_ltca_table *t)
{
    double ks = 0;
    int k = t->knot_scene, m = t->m;
    for (int j = 0; j < t->n; j++) {
        const double *d = t->d + (size_t)j * m, *f = t->f + (size_t)j * m;
        ks += 0.5 * (seg_slope(d, f, k > 0 ? k - 1 : 0) + seg_slope(d, f, k < m - 1 ? k : m - 2));
    }
    return ks / t->n;
}

gs_err gs_ltca_table_dynamic(gs_ltca_table *t, double f_mean, gs_diag *dg)
{
    double c = t->body_compliance;
    if (c == 0.0)
        return GS_OK;
    int n = t->n, m = t->m;
    for (int j = 0; j < n; j++) {
        double *d = t->d + (size_t)j * m;
        const double *f = t->f + (size_t)j * m;
        for (int a = 0; a < m; a++)
            d[a] -= c * (f[a] - f_mean);
        for (int a = 0; a + 1 < m; a++)
            if (!(d[a + 1] > d[a]))
                return gs_diag_set(dg, GS_ERANGE, "ltca",
                                   "position %d: the body compliance %g m/N exceeds the table's between knots %d "
                                   "and %d", j, c, a, a + 1);
    }
    integrate(t);
    t->k_mean = tangent_mean(t);
    return GS_OK;
}

/* ---------------------------------------------------------------------- */
/* Phase: periodic linear interpolation between the positions              */
/* ---------------------------------------------------------------------- */

/* Cell of phase p: positions i and i + 1 (mod n) and the weight t of i + 1. */
static void cell(const gs_ltca_table *t, double p, int *i0, int *i1, double *w)
{
    double x = p * t->n - 0.5;
    double fl = floor(x);
    *w = x - fl;
    long i = (long)fmod(fl, (double)t->n);
    if (i < 0)
        i += t->n;
    *i0 = (int)i;
    *i1 = (int)((i + 1) % t->n);
}

typedef double (*row_fn)(const gs_ltca_table *t, int j, double x);

static double row_f(const gs_ltca_table *t, int j, double x)
{
    return gs_ltca_row_force(t, j, x, NULL);
}

/* The mean over [p0, p1] of dU/dp, U(p) = the interpolation of u_j = fn(j, x)
 * (its difference quotient, U(p0)'s slope when equal), cell by cell without
 * cancellation, and its derivative in p1. */
static double phase_quot(const gs_ltca_table *t, row_fn fn, double x, double p0, double p1, double *dq1)
{
    int n = t->n;
    double x0 = p0 * n - 0.5, x1 = p1 * n - 0.5;
    double c0 = floor(x0), c1 = floor(x1);
    int a, b;
    double w;
    cell(t, p0, &a, &b, &w);
    double s0 = (fn(t, b, x) - fn(t, a, x)) * n;
    if (c0 == c1 || p0 == p1) {
        *dq1 = 0.0;
        return s0;
    }
    double lo = fmin(x0, x1), hi = fmax(x0, x1), sum = 0.0;
    for (double c = floor(lo); c <= floor(hi); c += 1.0) {
        double ca = fmax(lo, c), cb = fmin(hi, c + 1.0);
        cell(t, (c + 0.5 + 0.5) / n, &a, &b, &w); /* the cell's middle */
        sum += (cb - ca) * (fn(t, b, x) - fn(t, a, x));
    }
    double q = sum / (hi - lo) * n;
    cell(t, p1, &a, &b, &w);
    double s1 = (fn(t, b, x) - fn(t, a, x)) * n;
    *dq1 = (s1 - q) / (p1 - p0);
    return q;
}

double gs_ltca_energy(const gs_ltca_table *t, double x, double p)
{
    int a, b;
    double w;
    cell(t, p, &a, &b, &w);
    return (1.0 - w) * gs_ltca_row_energy(t, a, x) + w * gs_ltca_row_energy(t, b, x);
}

double gs_ltca_force(const gs_ltca_table *t, double x, double p, double *dvdp)
{
    int a, b;
    double w;
    cell(t, p, &a, &b, &w);
    if (dvdp)
        *dvdp = (gs_ltca_row_energy(t, b, x) - gs_ltca_row_energy(t, a, x)) * t->n;
    return (1.0 - w) * gs_ltca_row_force(t, a, x, NULL) + w * gs_ltca_row_force(t, b, x, NULL);
}

void gs_ltca_closing(const gs_ltca_table *t, double p, double *back, double *front)
{
    int a, b;
    double w;
    cell(t, p, &a, &b, &w);
    int z = t->zero_back, m = t->m;
    *back = (1.0 - w) * t->d[(size_t)a * m + z] + w * t->d[(size_t)b * m + z];
    *front = (1.0 - w) * t->d[(size_t)a * m + z + 1] + w * t->d[(size_t)b * m + z + 1];
}

void gs_ltca_grad(const gs_ltca_table *t, double x0, double dx, double p0, double dp, double *gx, double *gp,
                  double jac[4])
{
    double x1 = x0 + dx, p1 = p0 + dp;
    int a0, b0, a1, b1;
    double w0, w1;
    cell(t, p0, &a0, &b0, &w0);
    cell(t, p1, &a1, &b1, &w1);
    /* gx: 1/2 sum over both phases of the interpolated row means */
    double qa0, qb0, qa1, qb1, da0, db0, da1, db1;
    qa0 = row_mean(t, a0, x0, x1, &da0);
    qb0 = row_mean(t, b0, x0, x1, &db0);
    if (a1 == a0 && b1 == b0) { /* the usual step: within one cell */
        qa1 = qa0, qb1 = qb0, da1 = da0, db1 = db0;
        double ua0 = gs_ltca_row_energy(t, a0, x0), ub0 = gs_ltca_row_energy(t, b0, x0);
        double ua1 = gs_ltca_row_energy(t, a0, x1), ub1 = gs_ltca_row_energy(t, b0, x1);
        *gx = 0.5 * ((1.0 - w0) * qa0 + w0 * qb0 + (1.0 - w1) * qa1 + w1 * qb1);
        *gp = 0.5 * ((ub0 - ua0) + (ub1 - ua1)) * t->n;
        if (jac) {
            jac[0] = 0.5 * ((1.0 - w0) * da0 + w0 * db0 + (1.0 - w1) * da1 + w1 * db1);
            jac[1] = 0.5 * (qb1 - qa1) * t->n;
            jac[2] = 0.5 * (gs_ltca_row_force(t, b0, x1, NULL) - gs_ltca_row_force(t, a0, x1, NULL)) * t->n;
            jac[3] = 0.0;
        }
        return;
    }
    qa1 = row_mean(t, a1, x0, x1, &da1);
    qb1 = row_mean(t, b1, x0, x1, &db1);
    double Q0 = (1.0 - w0) * qa0 + w0 * qb0, Q1 = (1.0 - w1) * qa1 + w1 * qb1;
    *gx = 0.5 * (Q0 + Q1);
    /* gp: 1/2 the phase quotients of V at x0 and x1 */
    double e0, e1;
    double D0 = phase_quot(t, gs_ltca_row_energy, x0, p0, p1, &e0);
    double D1 = phase_quot(t, gs_ltca_row_energy, x1, p0, p1, &e1);
    *gp = 0.5 * (D0 + D1);
    if (!jac)
        return;
    jac[0] = 0.5 * ((1.0 - w0) * da0 + w0 * db0 + (1.0 - w1) * da1 + w1 * db1);
    jac[1] = 0.5 * (qb1 - qa1) * t->n; /* w1 moves with p1 */
    double ef;
    jac[2] = 0.5 * phase_quot(t, row_f, x1, p0, p1, &ef);
    jac[3] = 0.5 * (e0 + e1);
}

/* ---------------------------------------------------------------------- */
/* Building: the quasi-static analyses                                    */
/* ---------------------------------------------------------------------- */

/* Roll positions per mesh cycle: 48, or $GEARSIM_LTCA_POSITIONS (12 ..
 * 720; a key of its own) for checks of the tables' resolution in roll. */
static int default_positions(void)
{
    const char *e = getenv("GEARSIM_LTCA_POSITIONS");
    int n = e && e[0] ? atoi(e) : 0;
    return n >= 12 && n <= 720 ? n : 48;
}

void gs_ltca_opts_defaults(gs_ltca_opts *o)
{
    o->positions = default_positions();
    o->cache_dir = NULL;
}

const char *gs_ltca_cache_dir(const gs_ltca_opts *o, char *buf, size_t size)
{
    if (o && o->cache_dir)
        return o->cache_dir[0] ? o->cache_dir : NULL;
    const char *e = getenv("GEARSIM_LTCA_CACHE");
    if (e && e[0])
        return e;
    e = getenv("XDG_CACHE_HOME");
    if (e && e[0] && snprintf(buf, size, "%s/gearsim/ltca", e) < (int)size)
        return buf;
    e = getenv("HOME");
    if (e && e[0] && snprintf(buf, size, "%s/.cache/gearsim/ltca", e) < (int)size)
        return buf;
    return NULL;
}

/* FNV-1a, 64 bits. */
static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
    const unsigned char *c = p;
    for (size_t i = 0; i < n; i++) {
        h ^= c[i];
        h *= 1099511628211ull;
    }
    return h;
}

static uint64_t fnv_d(uint64_t h, double x)
{
    return fnv(h, &x, sizeof x);
}

static uint64_t fnv_i(uint64_t h, long x)
{
    return fnv(h, &x, sizeof x);
}

static uint64_t hash_body(uint64_t h, const gs_scene *sc, int bi)
{
    const gs_scene_body *b = &sc->bodies[bi];
    const gs_gear_params *g = &b->gear;
    h = fnv_i(h, g->kind);
    h = fnv_i(h, g->teeth);
    double gp[] = {g->module_m, g->pressure_angle, g->addendum_coef, g->dedendum_coef, g->fillet_coef,
                   g->profile_shift, g->thinning_m, g->face_width_m, g->hub_radius_m};
    for (size_t i = 0; i < sizeof gp / sizeof gp[0]; i++)
        h = fnv_d(h, gp[i]);
    const gs_material *mt = &b->material;
    h = fnv_d(fnv_d(fnv_d(h, mt->youngs_pa), mt->poisson), mt->density);
    h = fnv_i(h, mt->plane);
    const gs_mesh_density *md = &b->mesh;
    long mi[] = {md->flank, md->across, md->rim, md->refine, md->order};
    for (size_t i = 0; i < sizeof mi / sizeof mi[0]; i++)
        h = fnv_i(h, mi[i]);
    h = fnv_d(h, md->grading);
    double c[2];
    gs_scene_body_centre(sc, bi, c);
    h = fnv_d(fnv_d(h, c[0]), c[1]);
    h = fnv_d(h, b->angle0);
    h = fnv_i(h, b->joint);
    if (b->mods && gs_gear_mods_has_profile(b->mods)) {
        for (int s = 0; s < 2; s++) {
            const gs_flank_mod *f = &b->mods->flank[s];
            h = fnv(h, &f->tip, sizeof f->tip);
            h = fnv(h, &f->root, sizeof f->root);
            h = fnv_i(h, f->n_dev);
            for (int k = 0; k < f->n_dev; k++)
                h = fnv_d(fnv_d(h, f->dev_roll[k]), f->dev_m[k]);
        }
    }
    return h;
}

/* The scene's moment on the driver (the analysis's default), 0 when none. */
static double driver_moment(const gs_scene *sc, int body)
{
    double T = 0;
    for (int i = 0; i < sc->n_loads; i++) {
        const gs_scene_load *l = &sc->loads[i];
        if (l->body != body)
            continue;
        if (l->type == GS_LOAD_CONSTANT || l->type == GS_LOAD_RAMP)
            T += l->moment;
        else if (l->type == GS_LOAD_TABLE)
            for (int k = 0; k < l->n_table; k++)
                if (fabs(l->moments[k]) > fabs(T))
                    T = l->moments[k];
    }
    return T;
}

static int driver_of(const gs_scene *sc, int mesh)
{
    return sc->bodies[sc->meshes[mesh].gear[0]].gear.kind == GS_GEAR_INTERNAL ? 1 : 0;
}

/* Either gear of the mesh has profile modifications (relief, deviation
 * tables). The analysis's auto setting drops the near-field correction on
 * modified flanks (it is validated against CalculiX only on unmodified
 * ones) and falls back to the plain FE of the mesh, up to 10 % too stiff;
 * the tables force it on there, so a modified pair's tables carry the same
 * contact compliance as an unmodified one's (the Hertz law with the local
 * flank curvature about the rows' load centre: docs/explanation/ltca.md). */
static int modified_pair(const gs_scene *sc, const gs_scene_mesh *sm)
{
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *b = &sc->bodies[sm->gear[k]];
        if (b->mods && gs_gear_mods_has_profile(b->mods))
            return 1;
    }
    return 0;
}

/* The analysis's near-field setting: $GEARSIM_LTCA_NEARFIELD (0 the plain
 * FE contact, what the elastic gears' dynamic contact has; 1 the
 * correction on any mesh; 2 auto), else -1: the analysis's default. */
static int nearfield_setting(void)
{
    const char *e = getenv("GEARSIM_LTCA_NEARFIELD");
    if (!e || !e[0])
        return -1;
    int v = atoi(e);
    return v >= 0 && v <= 2 ? v : -1;
}

/* A mesh of a train: an internal gear or a planet on its carrier in it.
 * Its tables carry the bodies' compliance measured on the pair with each
 * gear on its own axis (the FE modal analysis's pair), as an external
 * pair's do; the key says so (tables of earlier versions kept 0 there). */
static int train_mesh(const gs_scene *sc, const gs_scene_mesh *sm)
{
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *b = &sc->bodies[sm->gear[k]];
        if (b->gear.kind == GS_GEAR_INTERNAL || b->joint == GS_JOINT_ON_CARRIER)
            return 1;
    }
    return 0;
}

/* A brake on the body: it reacts the others in the static share. */
static int braked(const gs_scene *sc, int body)
{
    for (int i = 0; i < sc->n_loads; i++)
        if (sc->loads[i].body == body && sc->loads[i].type == GS_LOAD_BRAKE)
            return 1;
    return 0;
}

/* Row i of the meshes' line-of-action displacement over the bodies'
 * rotations (the rigid kinematics of the system's meshes, gearsim/step.h:
 * sigma r_b on each gear's rotation, less on its carrier's; sigma -1 for
 * a ring). */
static void share_row(const gs_scene *sc, int i, double *a)
{
    const gs_scene_mesh *sm = &sc->meshes[i];
    memset(a, 0, (size_t)sc->n_bodies * sizeof *a);
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *g = &sc->bodies[sm->gear[k]];
        double sr = (g->gear.kind == GS_GEAR_INTERNAL ? -1.0 : 1.0) * gs_gear_base_radius(&g->gear);
        a[sm->gear[k]] += sr;
        if (g->joint == GS_JOINT_ON_CARRIER)
            a[g->carrier] -= sr;
    }
}

/* The static share of the scene's moments that mesh `mesh` carries, N
 * along its line of action, signed as its deflection (0 when the train
 * does not stand under them): the rotations held where a brake reacts or
 * the joint holds, every mesh a spring of one stiffness, the moments of
 * driver_moment on the others. Equal springs give a symmetric train's shares by its
 * geometry alone (the planets' equal shares of the sun's moment), and the
 * mean force of a mesh no load acts on directly (a planet's on its ring)
 * with the flank it loads. */
static double static_share(const gs_scene *sc, int mesh)
{
    int nb = sc->n_bodies, nm = sc->n_meshes, nf = 0;
    double *a = gs_calloc((size_t)nb * nm, sizeof *a), *K = gs_calloc((size_t)nb * nb + nb, sizeof *K);
    int *fc = gs_calloc((size_t)nb, sizeof *fc);
    double F = 0;
    if (!a || !K || !fc)
        goto out;
    double *f = K + (size_t)nb * nb;
    for (int i = 0; i < nm; i++)
        share_row(sc, i, a + (size_t)i * nb);
    for (int b = 0; b < nb; b++) {
        double diag = 0;
        for (int i = 0; i < nm; i++)
            diag += a[(size_t)i * nb + b] * a[(size_t)i * nb + b];
        if (!braked(sc, b) && sc->bodies[b].joint != GS_JOINT_HELD && diag > 0)
            f[nf] = driver_moment(sc, b), fc[nf++] = b;
    }
    double big = 0; /* K_ff q = f (Gauss, partial pivoting) */
    for (int r = 0; r < nf; r++)
        for (int c = 0; c < nf; c++) {
            double k = 0;
            for (int i = 0; i < nm; i++)
                k += a[(size_t)i * nb + fc[r]] * a[(size_t)i * nb + fc[c]];
            K[(size_t)r * nf + c] = k;
            big = fmax(big, fabs(k));
        }
    for (int c = 0; c < nf; c++) {
        int p = c;
        for (int r = c + 1; r < nf; r++)
            if (fabs(K[(size_t)r * nf + c]) > fabs(K[(size_t)p * nf + c]))
                p = r;
        if (!(fabs(K[(size_t)p * nf + c]) > 1e-9 * big)) /* a rotation nothing reacts */
            goto out;
        for (int k = 0; k < nf; k++) {
            double t = K[(size_t)c * nf + k];
            K[(size_t)c * nf + k] = K[(size_t)p * nf + k], K[(size_t)p * nf + k] = t;
        }
        double t = f[c];
        f[c] = f[p], f[p] = t;
        for (int r = c + 1; r < nf; r++) {
            double l = K[(size_t)r * nf + c] / K[(size_t)c * nf + c];
            for (int k = c; k < nf; k++)
                K[(size_t)r * nf + k] -= l * K[(size_t)c * nf + k];
            f[r] -= l * f[c];
        }
    }
    for (int c = nf - 1; c >= 0; c--) {
        double v = f[c];
        for (int k = c + 1; k < nf; k++)
            v -= K[(size_t)c * nf + k] * f[k];
        f[c] = v / K[(size_t)c * nf + c];
    }
    for (int r = 0; r < nf; r++)
        F += a[(size_t)mesh * nb + fc[r]] * f[r];
out:
    free(a);
    free(K);
    free(fc);
    return isfinite(F) ? F : 0.0;
}

/* The moment on the driver of the tables' default case: a train's mesh,
 * its static share times the driver's base radius (the flank the train
 * loads); otherwise 0, the analysis's default (the scene's moment on the
 * driver, else 200 N/mm). */
static double default_moment(const gs_scene *sc, int mesh)
{
    if (!train_mesh(sc, &sc->meshes[mesh]))
        return 0.0;
    const gs_scene_body *g = &sc->bodies[sc->meshes[mesh].gear[driver_of(sc, mesh)]];
    return static_share(sc, mesh) * gs_gear_base_radius(&g->gear);
}

/* The options of the quasi-static analyses of the tables (analyse) at
 * moment T. */
static void analysis_opts(const gs_scene *sc, int mesh, int n, double T, gs_stiffness_opts *o)
{
    gs_stiffness_opts_defaults(o);
    o->positions = n;
    o->torque_nm = T;
    o->driver = driver_of(sc, mesh);
    o->tangent = 0;
    o->phase = 0.5 / n;
    if (nearfield_setting() >= 0)
        o->nearfield = nearfield_setting();
    else if (modified_pair(sc, &sc->meshes[mesh]))
        o->nearfield = 1;
}

/* Positions of the modal analysis that measures the body compliance. */
#define BODY_POSITIONS 12

/* The options of the modal analysis that measures the bodies' compliance
 * (body_compliance_run) at moment T. */
static void body_modes_opts(double T, gs_fe_modes_opts *mo)
{
    gs_fe_modes_opts_defaults(mo);
    mo->positions = BODY_POSITIONS;
    mo->modes = 4;
    mo->torque_nm = T;
    mo->phase = 0.5 / BODY_POSITIONS;
}

/* The settings of both analyses the tables come from, as the defaults of
 * include/gearsim/stiffness.h and fe_modes.h give them (the moments are in
 * the key already): a change of a default (the contact's near-field
 * correction in either analysis, its depth, the iterations, the slices of
 * a helical pair, the Lanczos steps) changes the key, so tables built
 * before it are not read back. */
static uint64_t hash_settings(uint64_t h, const gs_scene *sc, int mesh, int n)
{
    gs_stiffness_opts o;
    analysis_opts(sc, mesh, n, 0.0, &o);
    long si[] = {o.positions, o.driver, o.refine, o.tangent, o.max_iter, o.cycles, o.order, o.nearfield, o.fine,
                 o.all_rows, o.all_dofs, o.slices};
    double sd[] = {o.phase, o.tangent_step, o.nearfield_depth_mm, o.coupling_mm};
    h = fnv(h, "stiffness-opts", 14);
    for (size_t i = 0; i < sizeof si / sizeof si[0]; i++)
        h = fnv_i(h, si[i]);
    for (size_t i = 0; i < sizeof sd / sizeof sd[0]; i++)
        h = fnv_d(h, sd[i]);
    gs_fe_modes_opts mo;
    body_modes_opts(0.0, &mo);
    long mi[] = {mo.positions, mo.modes, mo.refine, mo.order, mo.lanczos, mo.nearfield, mo.nearfield_secant};
    h = fnv(h, "body-modes-opts", 15);
    for (size_t i = 0; i < sizeof mi / sizeof mi[0]; i++)
        h = fnv_i(h, mi[i]);
    return fnv_d(h, mo.phase);
}

uint64_t gs_ltca_key(const gs_scene *sc, int mesh, const gs_ltca_opts *o)
{
    uint64_t h = 14695981039346656037ull;
    h = fnv(h, GS_LTCA_VERSION, strlen(GS_LTCA_VERSION));
    const gs_scene_mesh *sm = &sc->meshes[mesh];
    for (int k = 0; k < 2; k++)
        h = hash_body(h, sc, sm->gear[k]);
    for (int k = 0; k < 2; k++) { /* a carrier's scene angle places a planet */
        const gs_scene_body *b = &sc->bodies[sm->gear[k]];
        if (b->joint == GS_JOINT_ON_CARRIER)
            h = fnv_d(fnv_d(fnv_d(h, sc->bodies[b->carrier].angle0), b->carrier_radius), b->carrier_angle);
    }
    h = fnv_d(h, driver_moment(sc, sm->gear[driver_of(sc, mesh)]));
    double hv[GSI_LTCA_KEY_SLICED]; /* helical gears, lead modifications, misalignment */
    for (int i = 0, nh = gsi_ltca_key_sliced(sc, mesh, hv); i < nh; i++)
        h = fnv_d(h, hv[i]);
    int n = o ? o->positions : default_positions();
    h = fnv_i(h, n);
    h = hash_settings(h, sc, mesh, n);
    if (nearfield_setting() >= 0) /* only when set: the default's keys stay */
        h = fnv_i(fnv(h, "nearfield", 9), nearfield_setting());
    if (modified_pair(sc, sm)) /* modified flanks: the correction forced on, its offsets the perfect gears' */
        h = fnv(h, "nearfield-modified", 18);
    if (train_mesh(sc, sm)) /* a train's mesh: its load share, the bodies' compliance measured */
        h = fnv_d(fnv(h, "train-share", 11), default_moment(sc, mesh));
    for (int i = 0; i < N_FRONT; i++)
        h = fnv_d(h, front_frac[i]);
    for (int i = 0; i < N_BACK; i++)
        h = fnv_d(h, back_frac[i]);
    return h;
}

/* Tooth-pair slots per position of the tables. */
#define PAIR_SLOTS 4

typedef struct table_pairs {
    int np;
    int *tooth;    /* n x np x 2 */
    double *share; /* n x np */
} table_pairs;

/* Tooth index change per mesh cycle of mesh gear k: the mesh phase grows
 * with the driver's rotation (in the carrier's frame), each pitch bringing
 * the tooth before it (index - 1) into the contact; the other gear turns
 * the other way (index + 1), a ring the same way. */
int gs_ltca_tooth_step(const gs_scene *sc, int mesh, int k)
{
    const gs_scene_mesh *sm = &sc->meshes[mesh];
    if (k == driver_of(sc, mesh))
        return -1;
    return sc->bodies[sm->gear[k]].gear.kind == GS_GEAR_INTERNAL ? -1 : 1;
}

/* The tooth pairs of one position of the analysis into the slots (teeth of
 * mesh gears 0 and 1, their shares of the force normalised to 1). A roll
 * against the phase (a negative moment) is the cycle before the table's:
 * its teeth moved on by one cycle. */
static void keep_pairs(const gs_scene *sc, int mesh, const gs_stiffness_point *pt, int back, int *tooth,
                       double *share, int np)
{
    int dr = driver_of(sc, mesh), n = 0;
    double sum = 0;
    for (int r = 0; r < pt->n_pair; r++)
        sum += pt->pair[r].force_n;
    for (int r = 0; r < np; r++) {
        tooth[2 * r] = tooth[2 * r + 1] = -1;
        share[r] = 0;
    }
    for (int r = 0; r < pt->n_pair && n < np && sum > 0; r++) {
        if (!(pt->pair[r].force_n > 0))
            continue;
        for (int g = 0; g < 2; g++) {
            int k = g == 0 ? dr : 1 - dr, z = sc->bodies[sc->meshes[mesh].gear[k]].gear.teeth;
            int t = pt->pair[r].tooth[g] + (back ? gs_ltca_tooth_step(sc, mesh, k) : 0);
            tooth[2 * n + k] = ((t % z) + z) % z;
        }
        share[n++] = pt->pair[r].force_n / sum;
    }
}

/* One analysis at moment T (0: the default) into the knots: position j of
 * the run at grid index (T > 0 ? j : n - 1 - j), deflection and force in
 * the mesh coordinate (the driver is the external gear: s grows with its
 * rotation, r_b1 per radian), column col of d and f (n x m); with zero, the
 * no-load closing into column zcol too. */
static gs_err analyse(const gs_scene *sc, int mesh, int n, double T, double *d, double *f, int m, int col,
                      int zcol, double *Tused, double *rb, double *cpu, table_pairs *tp, gs_diag *dg)
{
    gs_stiffness_opts o;
    analysis_opts(sc, mesh, n, T, &o);
    gs_stiffness_result r;
    GS_TRY(gs_stiffness_analyse(sc, mesh, &o, &r, dg));
    double sg = r.torque_nm < 0 ? -1.0 : 1.0;
    for (int j = 0; j < n; j++) {
        int i = sg > 0 ? j : n - 1 - j;
        const gs_stiffness_point *pt = &r.pt[j];
        d[(size_t)i * m + col] = sg * pt->te_raw_um * 1e-6;
        f[(size_t)i * m + col] = sg * r.force_n;
        if (zcol >= 0) {
            d[(size_t)i * m + zcol] = sg * pt->te0_um * 1e-6;
            f[(size_t)i * m + zcol] = 0.0;
        }
        if (tp)
            keep_pairs(sc, mesh, pt, sg < 0, tp->tooth + (size_t)i * tp->np * 2, tp->share + (size_t)i * tp->np,
                       tp->np);
    }
    *Tused = r.torque_nm;
    *rb = r.base_radius_m;
    *cpu += r.cpu_seconds;
    gs_stiffness_result_clear(&r);
    return GS_OK;
}

/* The share of the static mesh compliance in the gears' bodies, m/N along
 * the line of action, from the FE pair's own eigenproblem at the load T
 * (include/gearsim/fe_modes.h): at each position the first torsional mesh
 * mode f_FE (the first whose kinetic energy is mostly in the rotations)
 * and the two-inertia closed form f_2 with the same analysis's tangent
 * stiffness k_t. A compliance c in series with the teeth that carries the
 * mean load while the inertias vibrate on the teeth's side of it gives
 * 1 / k_dyn = 1 / k_t - c with k_dyn = k_t (f_FE / f_2)^2, so
 *   c_j = (1 - (f_2 / f_FE)^2) / k_t.
 * That c_j comes out the same at every position (single and double
 * contact alike, within a few per cent: docs/explanation/ltca.md) is what
 * identifies it as the bodies'; the mean over the positions is returned.
 * f_FE and k_t are both of the eigenproblem's own contact (its default
 * setting, body_modes_opts: the near-field correction where it applies), so
 * that c is the bodies' share whatever the contact; its settings are in
 * the key (hash_settings). */
static gs_err body_compliance_run(const gs_scene *sc, int mesh, double T, double *c, double *cpu, gs_diag *dg)
{
    gs_fe_modes_opts mo;
    body_modes_opts(T, &mo);
    gs_fe_modes_result fm;
    double c0 = gs_cpu_now();
    GS_TRY(gs_fe_modes_analyse(sc, mesh, &mo, &fm, dg));
    double sum = 0;
    gs_err e = GS_OK;
    for (int j = 0; j < fm.positions && e == GS_OK; j++) {
        const gs_fe_modes_point *p = &fm.pt[j];
        double hz = 0;
        for (int i = 0; i < fm.modes && hz == 0; i++)
            if (p->rotation[i] > 0.5)
                hz = p->hz[i];
        if (!(hz > 0) || !(p->lumped_hz > 0) || !(p->k_tan > 0))
            e = gs_diag_set(dg, GS_ERANGE, "ltca", "no torsional mesh mode at roll %.3f", p->roll);
        else
            sum += (1.0 - (p->lumped_hz / hz) * (p->lumped_hz / hz)) / p->k_tan;
    }
    *c = e == GS_OK ? fmax(sum / fm.positions, 0.0) : 0.0;
    gs_fe_modes_result_clear(&fm);
    *cpu += gs_cpu_now() - c0;
    return e;
}

static gs_err body_compliance(const gs_scene *sc0, int mesh, double T, double *c, double *cpu, gs_diag *dg)
{
    /* The modal analysis loads its first gear: with the driver second (a
     * ring listed first), the same pair with the gears swapped, so that it
     * sees the analysis's moment on the same gear. */
    gs_scene sc = *sc0;
    gs_scene_mesh *ms = NULL;
    if (driver_of(sc0, mesh) == 1) {
        ms = gs_calloc((size_t)sc0->n_meshes, sizeof *ms);
        if (!ms)
            return GS_ENOMEM;
        memcpy(ms, sc0->meshes, (size_t)sc0->n_meshes * sizeof *ms);
        int g = ms[mesh].gear[0];
        ms[mesh].gear[0] = ms[mesh].gear[1];
        ms[mesh].gear[1] = g;
        sc.meshes = ms;
    }
    gs_err e = body_compliance_run(&sc, mesh, T, c, cpu, dg);
    free(ms);
    return e;
}

static gs_err build(const gs_scene *sc0, int mesh, int n, gs_ltca_table *t, gs_diag *dg)
{
    gs_scene sc;
    gs_scene_body *bodies = NULL;
    gs_gear_mods mods[2];
    GS_TRY(gsi_mesh_clean_scene(sc0, mesh, &sc, &bodies, mods));
    const gs_scene_mesh *sm = &sc.meshes[mesh];
    double b = fmin(sc.bodies[sm->gear[0]].gear.face_width_m, sc.bodies[sm->gear[1]].gear.face_width_m);
    double Fref = LINE_LOAD_N_PER_M * b;
    int m = N_FRONT + N_BACK + 3; /* + the scene's load and the two closings */
    double *d = gs_calloc((size_t)n * m, sizeof(double)), *f = gs_calloc((size_t)n * m, sizeof(double));
    table_pairs tp = {PAIR_SLOTS, gs_calloc((size_t)n * PAIR_SLOTS * 2, sizeof(int)),
                         gs_calloc((size_t)n * PAIR_SLOTS, sizeof(double))};
    gs_err e = d && f && tp.tooth && tp.share ? GS_OK : GS_ENOMEM;
    double T0 = 0, rb = 0, cpu = 0, Tu;
    /* Columns: 0 the default case (the scene's load; its sign the loaded
     * flank), 1 .. N_FRONT the front loads, then the front and back
     * closings, then the back loads. */
    int col = 0;
    if (e == GS_OK)
        e = analyse(&sc, mesh, n, default_moment(&sc, mesh), d, f, m, col++, N_FRONT + 1, &T0, &rb, &cpu, &tp, dg);
    double sg = T0 < 0 ? -1.0 : 1.0, F0 = fabs(T0) / rb;
    for (int i = 0; e == GS_OK && i < N_FRONT; i++) {
        double F = front_frac[i] * Fref;
        if (fabs(F - F0) < 0.03 * F0) /* next to the scene's load: nudge it off */
            F = F < F0 ? 0.97 * F0 : 1.03 * F0;
        e = analyse(&sc, mesh, n, sg * F * rb, d, f, m, col++, -1, &Tu, &rb, &cpu, NULL, dg);
    }
    for (int i = 0; e == GS_OK && i < N_BACK; i++)
        e = analyse(&sc, mesh, n, -sg * back_frac[i] * Fref * rb, d, f, m, N_FRONT + 3 + i, i == 0 ? N_FRONT + 2 : -1,
                    &Tu, &rb, &cpu, NULL, dg);
    if (e == GS_OK)
        e = gs_ltca_table_set(t, n, m, d, f, dg);
    if (e == GS_OK) {
        t->np = tp.np;
        t->pair_tooth = tp.tooth;
        t->pair_share = tp.share;
        tp.tooth = NULL;
        tp.share = NULL;
        t->force_scene = F0;
        t->base_radius_m = rb;
        t->build_cpu_s = cpu;
        /* the scene load's knot, and the mean tangent there */
        int k = 0;
        while (k < m && fabs(t->f[k] - sg * F0) > 1e-9 * F0)
            k++;
        t->knot_scene = k < m ? k : m - 1;
        t->k_mean = tangent_mean(t);
        t->body_compliance = 0.0;
        e = body_compliance(&sc, mesh, T0, &t->body_compliance, &t->build_cpu_s, dg);
        if (e != GS_OK)
            gs_ltca_table_clear(t);
    }
    free(d);
    free(f);
    free(tp.tooth);
    free(tp.share);
    free(bodies);
    return e;
}

/* ---------------------------------------------------------------------- */
/* Cache                                                                   */
/* ---------------------------------------------------------------------- */

static int mkdirs(const char *dir)
{
    char p[4096];
    if (snprintf(p, sizeof p, "%s", dir) >= (int)sizeof p)
        return -1;
    for (char *c = p + 1; *c; c++)
        if (*c == '/') {
            *c = '\0';
            if (mkdir(p, 0755) != 0 && errno != EEXIST)
                return -1;
            *c = '/';
        }
    return mkdir(p, 0755) != 0 && errno != EEXIST ? -1 : 0;
}

static int cache_read(const char *path, uint64_t key, gs_ltca_table *t)
{
    FILE *fp = fopen(path, "r");
    if (!fp)
        return 0;
    char magic[64];
    unsigned long long k;
    int n, m, ks;
    double F0, rb, km, cpu, cb;
    int ok = fscanf(fp, "%63s %llx %d %d %d %lg %lg %lg %lg %lg", magic, &k, &n, &m, &ks, &F0, &rb, &km, &cpu,
                    &cb) == 10 &&
             !strcmp(magic, GS_LTCA_VERSION) && k == key && n >= 2 && n <= 100000 && m >= 3 &&
             m <= 1000 && ks >= 0 && ks < m;
    double *d = NULL, *f = NULL;
    if (ok) {
        d = gs_calloc((size_t)n * m, sizeof(double));
        f = gs_calloc((size_t)n * m, sizeof(double));
        ok = d && f;
        for (size_t i = 0; ok && i < (size_t)n * m; i++)
            ok = fscanf(fp, "%lg %lg", &d[i], &f[i]) == 2;
    }
    int np = 0, *pt = NULL;
    double *ps = NULL;
    if (ok) /* the tooth pairs: "pairs NP", then n x NP lines "tooth0 tooth1 share" */
        ok = fscanf(fp, " pairs %d", &np) == 1 && np >= 0 && np <= 64;
    if (ok) {
        pt = gs_calloc((size_t)n * np * 2 + 1, sizeof(int));
        ps = gs_calloc((size_t)n * np + 1, sizeof(double));
        ok = pt && ps;
        for (size_t i = 0; ok && i < (size_t)n * np; i++)
            ok = fscanf(fp, "%d %d %lg", &pt[2 * i], &pt[2 * i + 1], &ps[i]) == 3;
    }
    fclose(fp);
    gs_diag dg;
    if (ok)
        ok = gs_ltca_table_set(t, n, m, d, f, &dg) == GS_OK;
    free(d);
    free(f);
    if (!ok) {
        free(pt);
        free(ps);
        return 0;
    }
    t->np = np;
    t->pair_tooth = pt;
    t->pair_share = ps;
    t->force_scene = F0;
    t->knot_scene = ks;
    t->base_radius_m = rb;
    t->k_mean = km;
    t->body_compliance = cb;
    t->build_cpu_s = 0;
    t->from_cache = 1;
    (void)cpu;
    return 1;
}

static void cache_write(const char *dir, const char *path, uint64_t key, const gs_ltca_table *t)
{
    if (mkdirs(dir) != 0)
        return;
    char tmp[4300];
    if (snprintf(tmp, sizeof tmp, "%s.%ld.tmp", path, (long)getpid()) >= (int)sizeof tmp)
        return;
    FILE *fp = fopen(tmp, "w");
    if (!fp)
        return;
    fprintf(fp, "%s %016llx %d %d %d %.17g %.17g %.17g %.6g %.17g\n", GS_LTCA_VERSION, (unsigned long long)key,
            t->n, t->m, t->knot_scene, t->force_scene, t->base_radius_m, t->k_mean, t->build_cpu_s,
            t->body_compliance);
    for (size_t i = 0; i < (size_t)t->n * t->m; i++)
        fprintf(fp, "%.17g %.17g\n", t->d[i], t->f[i]);
    fprintf(fp, "pairs %d\n", t->np);
    for (size_t i = 0; i < (size_t)t->n * t->np; i++)
        fprintf(fp, "%d %d %.17g\n", t->pair_tooth[2 * i], t->pair_tooth[2 * i + 1], t->pair_share[i]);
    if (fclose(fp) != 0 || rename(tmp, path) != 0)
        remove(tmp);
}

gs_err gs_ltca_tables(const gs_scene *sc, int mesh, const gs_ltca_opts *o, gs_ltca_table *t, gs_diag *d)
{
    gs_ltca_opts def;
    if (!o) {
        gs_ltca_opts_defaults(&def);
        o = &def;
    }
    memset(t, 0, sizeof *t);
    uint64_t key = gs_ltca_key(sc, mesh, o);
    char buf[4096], path[4200];
    const char *dir = gs_ltca_cache_dir(o, buf, sizeof buf);
    if (dir) {
        snprintf(path, sizeof path, "%s/%016llx.ltca", dir, (unsigned long long)key);
        if (cache_read(path, key, t)) {
            t->key = key;
            return GS_OK;
        }
    }
    /* the tables shipped for the example scenes */
    const char *sh = getenv("GEARSIM_LTCA_DATA");
    char spath[4200];
    snprintf(spath, sizeof spath, "%s/%016llx.ltca", sh && sh[0] ? sh : GS_LTCA_SHIPPED, (unsigned long long)key);
    if (cache_read(spath, key, t)) {
        t->key = key;
        return GS_OK;
    }
    gs_diag sd;
    gs_err e = build(sc, mesh, o->positions, t, &sd);
    if (e != GS_OK) {
        char field[64];
        snprintf(field, sizeof field, "meshes[%d]", mesh);
        return gs_diag_set(d, e, field, "the LTCA tables of '%s' (quasi-static analysis) failed: %s (%s)",
                           sc->meshes[mesh].name, sd.message, sd.field);
    }
    t->key = key;
    if (dir)
        cache_write(dir, path, key, t);
    return GS_OK;
}
