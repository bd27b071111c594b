/* SPDX-License-Identifier: MIT
 * gearsim: pairs of involute gears and planetary sets: working pressure
 * angle, contact ratio, backlash, interference, mesh phase, assembly
 * (METHOD.md section 5; docs/explanation/geometry.md).
 *
 * Formulas for the tight-mesh centre distance and the backlash follow from
 * the tooth thicknesses on the base circle: along the line of action the
 * base pitch p_b = pi m cos(alpha) holds one tooth of each gear plus the
 * backlash (external), or a ring space holds a pinion tooth plus the
 * backlash (internal). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/geometry.h"

/* Half-profile polyline of a gear in its tooth-0 frame, counter-clockwise
 * side, from the tip centre (psi = 0) to the space centre (psi = pi/z),
 * closed into a polygon of the material of one half tooth. */
enum { PROF_N = 320 };
typedef struct {
    gs_gear_geom g;
    int n;                     /* profile points */
    double x[PROF_N + 8], y[PROF_N + 8];
    int npoly;                 /* polygon = profile + closing points */
} half_profile;

static void build_half_profile(const gs_gear_geom *g, half_profile *h)
{
    h->g = *g;
    int k = 0;
    const int ntip = 16, ninv = 160, nfil = 120, nroot = 16;
    for (int i = 0; i < ntip; i++) {
        double ps = g->psi_tip * i / ntip;
        h->x[k] = g->ra * cos(ps);
        h->y[k++] = g->ra * sin(ps);
    }
    for (int i = 0; i < ninv; i++) {
        double R = g->ra + (g->r_form - g->ra) * i / ninv, P[2], T[2];
        gs_gear_flank_point(g, R, P, T);
        h->x[k] = P[0];
        h->y[k++] = P[1];
    }
    for (int i = 0; i < nfil; i++) {
        double P[2], T[2];
        gs_gear_fillet_point(g, (double)i / nfil, P, T);
        h->x[k] = P[0];
        h->y[k++] = P[1];
    }
    for (int i = 0; i <= nroot; i++) {
        double ps = g->psi_root + (g->half_pitch - g->psi_root) * i / nroot;
        h->x[k] = g->rf * cos(ps);
        h->y[k++] = g->rf * sin(ps);
    }
    h->n = k;
    /* Close the material: through the centre (external) or round a large
     * circle outside the root (internal). */
    if (!g->internal) {
        h->x[k] = 0.0;
        h->y[k++] = 0.0;
    } else {
        double R = 2.0 * g->rf;
        h->x[k] = R * cos(g->half_pitch);
        h->y[k++] = R * sin(g->half_pitch);
        h->x[k] = R;
        h->y[k++] = 0.0;
    }
    h->npoly = k;
}

/* Depth (m) by which point X (gear frame) lies inside the gear's material,
 * 0 when outside. */
static double penetration(const half_profile *h, double X, double Y)
{
    const gs_gear_geom *g = &h->g;
    double R = hypot(X, Y);
    double lo = fmin(g->ra, g->rf), hi = fmax(g->ra, g->rf);
    if (!g->internal && R > hi)
        return 0.0;
    if (g->internal && R < lo)
        return 0.0;
    double pitch = 2.0 * g->half_pitch;
    double ang = atan2(Y, X);
    double dl = ang - pitch * floor(ang / pitch + 0.5);
    dl = fabs(dl);
    double px = R * cos(dl), py = R * sin(dl);
    /* Ray casting in +x direction. */
    int inside = 0;
    for (int i = 0, j = h->npoly - 1; i < h->npoly; j = i++) {
        if ((h->y[i] > py) != (h->y[j] > py)) {
            double xi = h->x[i] + (py - h->y[i]) * (h->x[j] - h->x[i]) / (h->y[j] - h->y[i]);
            if (px < xi)
                inside = !inside;
        }
    }
    if (!inside)
        return 0.0;
    double best = INFINITY;
    for (int i = 0; i + 1 < h->n; i++) {
        double ex = h->x[i + 1] - h->x[i], ey = h->y[i + 1] - h->y[i];
        double l2 = ex * ex + ey * ey;
        double t = l2 > 0 ? ((px - h->x[i]) * ex + (py - h->y[i]) * ey) / l2 : 0.0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        double dx = px - (h->x[i] + t * ex), dy = py - (h->y[i] + t * ey);
        double dd = hypot(dx, dy);
        if (dd < best)
            best = dd;
    }
    return best;
}

static double wrap_sym(double v, double period)
{
    return v - period * floor(v / period + 0.5);
}

double gs_pair_mesh_phase(const gs_gear_params *g1, const double c1[2], double theta1,
                          const gs_gear_params *g2, const double c2[2], double theta2_hint)
{
    double z1 = g1->teeth, z2 = g2->teeth;
    double beta = atan2(c2[1] - c1[1], c2[0] - c1[0]);
    double th2;
    if (g1->kind == GS_GEAR_EXTERNAL && g2->kind == GS_GEAR_EXTERNAL) {
        /* Aligned: a tooth of 1 on the line of centres faces a space of 2.
         * Turning 1 by eps turns 2 by -eps z1/z2. */
        double d1 = wrap_sym(beta - theta1, 2 * GS_PI / z1);
        th2 = beta + GS_PI + d1 * z1 / z2 - GS_PI / z2;
    } else if (g2->kind == GS_GEAR_INTERNAL) {
        /* Pitch point beyond the pinion on the ray ring centre -> pinion;
         * both turn the same way. */
        double bp = beta + GS_PI;
        double d1 = wrap_sym(bp - theta1, 2 * GS_PI / z1);
        th2 = bp - GS_PI / z2 - d1 * z1 / z2;
    } else {
        double d1 = wrap_sym(beta - theta1, 2 * GS_PI / z1);
        th2 = beta - GS_PI / z2 - d1 * z1 / z2;
    }
    double per = 2 * GS_PI / z2;
    return th2 + per * floor((theta2_hint - th2) / per + 0.5);
}

/* Check and order a pair: *pin is the external gear of an internal pair. */
static gs_err pair_kinds(const gs_gear_params *g1, const gs_gear_params *g2, gs_diag *d)
{
    if (fabs(g1->module_m - g2->module_m) > 1e-9 * fmax(g1->module_m, g2->module_m))
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "the gears do not mesh: modules differ (%g mm and %g mm)",
                           g1->module_m * 1e3, g2->module_m * 1e3);
    if (fabs(g1->pressure_angle - g2->pressure_angle) > 1e-9)
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "the gears do not mesh: pressure angles differ (%g and %g deg)",
                           g1->pressure_angle * 180 / GS_PI, g2->pressure_angle * 180 / GS_PI);
    if (g1->kind == GS_GEAR_INTERNAL && g2->kind == GS_GEAR_INTERNAL)
        return gs_diag_set(d, GS_EGEOMETRY, "gears", "two internal gears cannot mesh");
    const gs_gear_params *ring = g1->kind == GS_GEAR_INTERNAL ? g1 : g2->kind == GS_GEAR_INTERNAL ? g2 : NULL;
    const gs_gear_params *pin = ring == g1 ? g2 : g1;
    if (ring && ring->teeth <= pin->teeth)
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "an internal gear (%d teeth) must have more teeth than its pinion (%d)",
                           ring->teeth, pin->teeth);
    return GS_OK;
}

static gs_err each_valid(const gs_gear_params *g1, const gs_gear_params *g2, gs_gear_geom *a,
                         gs_gear_geom *b, gs_diag *d)
{
    gs_diag dd;
    gs_diag_clear(&dd);
    gs_err e = gs_gear_geometry(g1, a, &dd);
    if (e == GS_OK)
        e = gs_gear_geometry(g2, b, &dd);
    if (e != GS_OK)
        return gs_diag_set(d, e, "gears", "gear %d: %s: %s",
                           gs_gear_geometry(g1, a, NULL) != GS_OK ? 1 : 2, dd.field, dd.message);
    return GS_OK;
}

/* inv(alpha_w) of the tight mesh. */
static double tight_inv(const gs_gear_geom *pin, const gs_gear_geom *oth, int internal)
{
    double m = pin->m, ta = tan(pin->alpha);
    double x = pin->p.profile_shift + oth->p.profile_shift;
    double t = pin->p.thinning_m + oth->p.thinning_m;
    if (!internal)
        return gs_involute(pin->alpha) + (2 * ta * x - t / m) / (pin->z + oth->z);
    return gs_involute(pin->alpha) + (-2 * ta * x + t / m) / (oth->z - pin->z);
}

gs_err gs_pair_tight_centre_distance(const gs_gear_params *g1, const gs_gear_params *g2,
                                     double *a, gs_diag *d)
{
    GS_TRY(pair_kinds(g1, g2, d));
    gs_gear_geom A, B;
    GS_TRY(each_valid(g1, g2, &A, &B, d));
    int internal = A.internal || B.internal;
    const gs_gear_geom *pin = A.internal ? &B : &A, *oth = A.internal ? &A : &B;
    double inv = tight_inv(pin, oth, internal);
    if (!(inv > 0))
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "the profile shifts leave no working pressure angle (inv %g)", inv);
    double aw = gs_involute_inverse(inv);
    double a0 = internal ? oth->r - pin->r : pin->r + oth->r;
    *a = a0 * cos(pin->alpha) / cos(aw);
    return GS_OK;
}

/* Deepest penetration of the tip corners of gear `mov` into gear `fix`
 * while the pair rolls through the mesh and ~90 degrees either side. */
static double corner_sweep(const gs_gear_params *pf, const half_profile *hf,
                           const gs_gear_params *pm, const gs_gear_geom *gm, double a)
{
    double cf[2] = {0.0, 0.0}, cm[2] = {a, 0.0};
    /* Put the moving gear's tooth 0 on the line of centres direction seen
     * from its own centre, then roll. */
    double beta_m = (pf->kind == GS_GEAR_INTERNAL) ? 0.0 : GS_PI;
    if (pm->kind == GS_GEAR_INTERNAL)
        beta_m = GS_PI; /* the ring's teeth near the pinion (at the origin) */
    double worst = 0.0;
    const int n = 4000;
    for (int i = 0; i <= n; i++) {
        double tm = beta_m + (-0.5 + (double)i / n) * GS_PI;
        double tf = gs_pair_mesh_phase(pm, cm, tm, pf, cf, 0.0);
        for (int side = -1; side <= 1; side += 2) {
            double ps = side * gm->psi_tip;
            double px = gm->ra * cos(tm + ps) + cm[0], py = gm->ra * sin(tm + ps) + cm[1];
            /* into the fixed gear's frame */
            double c = cos(-tf), s = sin(-tf);
            double X = c * (px - cf[0]) - s * (py - cf[1]);
            double Y = s * (px - cf[0]) + c * (py - cf[1]);
            double dep = penetration(hf, X, Y);
            if (dep > worst)
                worst = dep;
        }
    }
    return worst;
}

static gs_err pair_analyse(const gs_gear_params *g1, const gs_gear_params *g2, double a,
                           gs_pair_info *info, gs_diag *d)
{
    memset(info, 0, sizeof *info);
    GS_TRY(pair_kinds(g1, g2, d));
    gs_gear_geom A, B;
    GS_TRY(each_valid(g1, g2, &A, &B, d));
    if (!(a > 0) || !isfinite(a))
        return gs_diag_set(d, GS_ERANGE, "gears", "centre distance must be positive (got %g m)", a);
    int internal = A.internal || B.internal;
    info->internal = internal;
    info->a = a;
    GS_TRY(gs_pair_tight_centre_distance(g1, g2, &info->a_tight, d));
    const double m = A.m, al = A.alpha;
    info->base_pitch = GS_PI * m * cos(al);
    /* External pairs overlap below the tight-mesh distance; an internal
     * pair overlaps above it (moving the pinion outwards pushes its teeth
     * into the narrowing ring spaces). */
    if (!internal && a < info->a_tight * (1.0 - 1e-9))
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "centre distance %.6g mm is below the tight-mesh distance %.6g mm: "
                           "the teeth would overlap",
                           a * 1e3, info->a_tight * 1e3);
    if (internal && a > info->a_tight * (1.0 + 1e-9))
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "centre distance %.6g mm is above the tight-mesh distance %.6g mm of this "
                           "internal pair: the teeth would overlap",
                           a * 1e3, info->a_tight * 1e3);
    double c = internal ? (fabs(A.rb - B.rb)) / a : (A.rb + B.rb) / a;
    if (c > 1.0)
        c = 1.0;
    double aw = acos(c);
    info->alpha_w = aw;
    info->r1w = A.rb / cos(aw);
    info->r2w = B.rb / cos(aw);
    const gs_gear_geom *pin = A.internal ? &B : &A, *oth = A.internal ? &A : &B;
    double ia = gs_involute(al), iw = gs_involute(aw);
    double sp = 2 * pin->rb * (pin->s_pitch / (2 * pin->r) + ia - iw);
    if (!internal) {
        double so = 2 * oth->rb * (oth->s_pitch / (2 * oth->r) + ia - iw);
        info->backlash_normal = info->base_pitch - sp - so;
    } else {
        double eo = 2 * oth->rb * (oth->half_pitch - oth->s_pitch / (2 * oth->r) + ia - iw);
        info->backlash_normal = eo - sp;
    }
    if (info->backlash_normal < 0)
        info->backlash_normal = 0; /* round-off at the tight distance */
    /* Positions along the line of action (METHOD.md section 5): each flank
     * is involute only between its form radius and its tip, so contact is
     * the intersection of the two flanks' intervals. The textbook formula
     * uses the tips alone; the form radii cut it short when the mating tip
     * reaches below the involute (e.g. a standard ring against a hobbed
     * pinion): there the fillet lies inside the involute, so the tip loses
     * contact rather than colliding (collisions are the corner sweep's job). */
    double t12 = a * sin(aw);
    double sap = sqrt(pin->ra * pin->ra - pin->rb * pin->rb);
    double sfp = sqrt(fmax(pin->r_form * pin->r_form - pin->rb * pin->rb, 0.0));
    double sao = sqrt(oth->ra * oth->ra - oth->rb * oth->rb);
    double sfo = sqrt(fmax(oth->r_form * oth->r_form - oth->rb * oth->rb, 0.0));
    double lo_t, hi_t, lo_f, hi_f, s_pin_lo, s_oth_hi;
    if (!internal) {
        /* from the pinion's tangent point towards the other's */
        lo_t = t12 - sao;
        hi_t = sap;
        lo_f = fmax(lo_t, sfp);
        hi_f = fmin(hi_t, t12 - sfo);
        s_pin_lo = lo_f;            /* distance of the lowest contact from T_pin */
        s_oth_hi = t12 - hi_f;      /* ... from T_other */
    } else {
        /* from the ring's tangent point; the pinion's is at t12 */
        lo_t = sao;
        hi_t = t12 + sap;
        lo_f = fmax(lo_t, t12 + sfp);
        hi_f = fmin(hi_t, sfo);
        s_pin_lo = lo_f - t12;
        s_oth_hi = hi_f;            /* the ring's outermost contact */
    }
    info->contact_ratio_tips = (hi_t - lo_t) / info->base_pitch;
    {
        /* the low end is set by the pinion's form radius, the high end by the other's */
        int pin_lim = lo_f > lo_t + 1e-12 * a, oth_lim = hi_f < hi_t - 1e-12 * a;
        int b_pin = pin == &A ? 1 : 2, b_oth = pin == &A ? 2 : 1;
        info->form_limited = (pin_lim ? b_pin : 0) | (oth_lim ? b_oth : 0);
    }
    double g = hi_f - lo_f;
    if (hi_t - lo_t <= 0)
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "the teeth do not reach each other at centre distance %.6g mm",
                           a * 1e3);
    double rp = hypot(pin->rb, s_pin_lo), ro = hypot(oth->rb, s_oth_hi);
    info->r1_start = pin == &A ? rp : ro;
    info->r2_start = pin == &A ? ro : rp;
    info->path_length = g;
    info->contact_ratio = g / info->base_pitch;
    if (info->contact_ratio < 1.0)
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "contact ratio %.4g is below 1 at centre distance %.6g mm%s: the "
                           "teeth lose contact",
                           info->contact_ratio, a * 1e3,
                           info->form_limited ? " (contact limited by the fillets)" : "");
    /* Tip corners swept through the whole engagement and beyond: catches
     * interference off the line of action (internal pairs with a small
     * tooth difference). Tolerance 1e-3 m: well above the polyline
     * discretisation of the profiles (~1e-5 m), well below any real
     * interference. */
    half_profile *hA = malloc(sizeof *hA), *hB = malloc(sizeof *hB);
    if (!hA || !hB) {
        free(hA);
        free(hB);
        return GS_ENOMEM;
    }
    build_half_profile(&A, hA);
    build_half_profile(&B, hB);
    double p1 = corner_sweep(g1, hA, g2, &B, a);
    double p2 = corner_sweep(g2, hB, g1, &A, a);
    free(hA);
    free(hB);
    info->interference = fmax(p1, p2);
    if (info->interference > 0.05 * m)
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "tip interference: the tips of gear %d cut %.3g module into gear %d "
                           "while rolling through the mesh%s",
                           p1 > p2 ? 2 : 1, info->interference / m, p1 > p2 ? 1 : 2,
                           internal ? " (too few teeth of difference for an internal pair, or "
                                      "reduce the ring's addendum)"
                                    : " (too few teeth: use a positive profile shift)");
    char *w = info->warning;
    size_t wl = sizeof info->warning;
    w[0] = '\0';
    if (info->interference > 1e-3 * m)
        snprintf(w, wl,
                 "slight tip-to-fillet interference: the tip corners of gear %d clip %.3g module "
                 "of gear %d's fillet; tip relief or a shorter addendum advised. ",
                 p1 > p2 ? 2 : 1, info->interference / m, p1 > p2 ? 1 : 2);
    if (info->form_limited) {
        size_t u = strlen(w);
        snprintf(w + u, wl - u,
                 "contact ratio %.4g instead of %.4g: the mating tips reach below the involute "
                 "of gear %s.",
                 info->contact_ratio, info->contact_ratio_tips,
                 info->form_limited == 3 ? "1 and 2" : info->form_limited == 1 ? "1" : "2");
    }
    return GS_OK;
}

gs_err gs_pair_contact_ratio(const gs_gear_params *g1, const gs_gear_params *g2,
                             double centre_distance_m, double *contact_ratio,
                             double *working_pressure_angle, gs_diag *d)
{
    gs_pair_info info;
    GS_TRY(gs_pair_analyse(g1, g2, centre_distance_m, &info, d));
    if (contact_ratio)
        *contact_ratio = info.contact_ratio;
    if (working_pressure_angle)
        *working_pressure_angle = info.alpha_w;
    return GS_OK;
}

gs_err gs_planetary_centre_distance(const gs_gear_params *sun, const gs_gear_params *planet,
                                    const gs_gear_params *ring, double *a, gs_diag *d)
{
    double a1, a2;
    GS_TRY(gs_pair_tight_centre_distance(sun, planet, &a1, d));
    GS_TRY(gs_pair_tight_centre_distance(planet, ring, &a2, d));
    *a = fmax(a1, a2);
    return GS_OK;
}

gs_err gs_planetary_check(const gs_gear_params *sun, const gs_gear_params *planet,
                          const gs_gear_params *ring, int n_planets, gs_diag *d)
{
    if (n_planets < 1)
        return gs_diag_set(d, GS_ERANGE, "planets", "at least one planet is needed (got %d)",
                           n_planets);
    if (sun->kind != GS_GEAR_EXTERNAL || planet->kind != GS_GEAR_EXTERNAL)
        return gs_diag_set(d, GS_EGEOMETRY, "gears", "sun and planets must be external gears");
    if (ring->kind != GS_GEAR_INTERNAL)
        return gs_diag_set(d, GS_EGEOMETRY, "gears", "the ring must be an internal gear");
    if ((sun->teeth + ring->teeth) % n_planets != 0)
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "%d equally spaced planets cannot be assembled: (z_sun + z_ring) = %d "
                           "is not a multiple of %d",
                           n_planets, sun->teeth + ring->teeth, n_planets);
    double a1, a2;
    GS_TRY(gs_pair_tight_centre_distance(sun, planet, &a1, d));
    GS_TRY(gs_pair_tight_centre_distance(planet, ring, &a2, d));
    /* A carrier radius a works for both meshes when a1 <= a <= a2 (the ring
     * pair overlaps above its tight distance). Tooth thinning opens that
     * interval by about t / (2 tan alpha) per mesh; shifted sets may differ
     * a little more (one mesh gets some backlash); beyond 0.02 module the
     * tooth counts do not fit together. */
    double open = (sun->thinning_m + 2 * planet->thinning_m + ring->thinning_m) /
                  (2 * tan(sun->pressure_angle));
    double tol = 0.02 * sun->module_m;
    if (a1 - a2 > tol || a2 - a1 > tol + 1.05 * open)
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "sun-planet and planet-ring centre distances differ (%.6g mm vs "
                           "%.6g mm): with standard gears z_ring must be z_sun + 2 z_planet "
                           "(%d + 2 x %d = %d, got %d)",
                           a1 * 1e3, a2 * 1e3, sun->teeth, planet->teeth,
                           sun->teeth + 2 * planet->teeth, ring->teeth);
    double a = fmax(a1, a2);
    double rap = gs_gear_tip_radius(planet);
    double gap = 2.0 * a * sin(GS_PI / n_planets) - 2.0 * rap;
    if (n_planets > 1 && gap <= 0)
        return gs_diag_set(d, GS_EGEOMETRY, "gears",
                           "%d planets overlap: their tip circles (radius %.6g mm) on the "
                           "carrier radius %.6g mm leave %.3g mm between neighbours",
                           n_planets, rap * 1e3, a * 1e3, gap * 1e3);
    gs_pair_info info;
    gs_diag dd;
    gs_diag_clear(&dd);
    gs_err e = gs_pair_analyse(sun, planet, a, &info, &dd);
    if (e != GS_OK)
        return gs_diag_set(d, e, "gears", "sun-planet mesh: %s", dd.message);
    e = gs_pair_analyse(planet, ring, a, &info, &dd);
    if (e != GS_OK)
        return gs_diag_set(d, e, "gears", "planet-ring mesh: %s", dd.message);
    return GS_OK;
}

/* The analysis is a pure function of the two gears and the distance, and
 * its corner sweep costs milliseconds: every parse of a scene repeats it
 * for each mesh, and a sweep parses its scene once per point. The last
 * results are kept (the library is used from one thread: the daemon's MPI
 * thread, or a tool). */
#define PAIR_CACHE 32
typedef struct pair_memo {
    gs_gear_params g1, g2;
    double a;
    gs_err err;
    gs_pair_info info;
    gs_diag diag;
    bool used;
} pair_memo;

static bool same_gear(const gs_gear_params *x, const gs_gear_params *y)
{
    return x->kind == y->kind && x->teeth == y->teeth && x->module_m == y->module_m &&
           x->pressure_angle == y->pressure_angle && x->addendum_coef == y->addendum_coef &&
           x->dedendum_coef == y->dedendum_coef && x->fillet_coef == y->fillet_coef &&
           x->profile_shift == y->profile_shift && x->thinning_m == y->thinning_m &&
           x->face_width_m == y->face_width_m && x->hub_radius_m == y->hub_radius_m;
}

gs_err gs_pair_analyse(const gs_gear_params *g1, const gs_gear_params *g2, double a,
                       gs_pair_info *info, gs_diag *d)
{
    static pair_memo memo[PAIR_CACHE];
    static int next;
    for (int i = 0; i < PAIR_CACHE; i++) {
        const pair_memo *m = &memo[i];
        if (m->used && m->a == a && same_gear(&m->g1, g1) && same_gear(&m->g2, g2)) {
            *info = m->info;
            if (d && m->err != GS_OK)
                *d = m->diag;
            return m->err;
        }
    }
    gs_diag own;
    gs_diag_clear(&own);
    gs_err e = pair_analyse(g1, g2, a, info, &own);
    if (d && e != GS_OK)
        *d = own;
    if (e != GS_ENOMEM) {
        pair_memo *m = &memo[next];
        next = (next + 1) % PAIR_CACHE;
        *m = (pair_memo){.g1 = *g1, .g2 = *g2, .a = a, .err = e, .info = *info, .diag = own, .used = true};
    }
    return e;
}
