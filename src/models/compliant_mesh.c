/* SPDX-License-Identifier: MIT
 * Mesh model `compliant`: rigid gears whose tooth pairs carry load through
 * the compliant contact patch model (METHOD.md sections 2, 6 and 7;
 * docs/explanation/impact.md "The compliant mesh").
 *
 * Along the line of action the pair deflects by x = s - s_ref (s = a . q
 * and the translations of gears on bearings, as the lumped model), beyond the backlash dead zone the approach is
 * delta = |x| - b/2, the same for every engaged tooth pair (rigid involute
 * gears). A pair at distance v along the path of contact carries
 * F(delta; v): its line contact (relative radius from the two flanks' radii
 * of curvature at that point, face width b) solved by gs_compliant_solve in
 * series with the compliance of both teeth: a cantilever of the exact tooth
 * section (bending, shear and compression) clamped at the root circle, and
 * by default ("bending": "beam_foundation") the fillet-foundation (gear
 * body) deflection of Sainsot, Velex & Duverger (2004) under that root
 * (external gears; a ring's teeth stay clamped). F(delta; v) is tabulated
 * at build time (stations along the path x line loads) and integrated
 * exactly to the pair potential W(delta; v) (piecewise-linear F,
 * piecewise-quadratic W). The mesh potential is
 *     V(x, phi) = sum_j w(u_j) W(delta(x); v_j),   u_j = (frac(phi) + j) p_b,
 * v_j = u_j on the drive flank (x > 0) and L - u_j on the coast flank,
 * w a linear ramp over `transition` base pitches centred on each end of the
 * path (as the lumped model's stiffness transitions), linear between
 * stations in v. The step's force is the symmetrised coordinate-increment
 * discrete gradient of V in (x, phi), so V(q1) - V(q0) = grad_bar V . dq to
 * round-off; the damper and nothing else dissipates (frictionless flanks:
 * normal and tangential contact are uncoupled for identical materials, so
 * the friction LCP of the patch model does not change the normal law). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compliant_mesh.h"
#include "mesh_common.h"
#include "gearsim/geometry.h"
#include "gearsim/modification.h"
#include "gearsim/impact.h"
#include "gearsim/models.h"
#include "gearsim/util.h"

#define LOADS 24    /* line loads per station: Pmax (i / LOADS)^2 */
#define STATIONS 25 /* along the path of contact, transitions included */
#define MAXPAIRS 8

typedef struct cmesh {
    gs_gear_geom g[2];   /* [0] the phase gear ("pinion", external), [1] the other */
    double c[2];         /* plane-strain compliances (1 - nu^2) / E */
    double eb[2], gm[2]; /* bending modulus (E, or E / (1 - nu^2) in plane strain) and G */
    int internal;
    double rho0, t12; /* pinion's radius of curvature at the start of active
                         profile; T1T2 */
    double L, pb, tw; /* path length, base pitch, transition width (m) */
    double b, e_star, pmax;
    int patches;
    int bending;           /* 0 none, 1 beam, 2 beam + fillet foundation */
    bool found[2];         /* the foundation term applies to gear k */
    double hfi[2], thf[2]; /* r_f / r_int and the root half angle theta_f */
    double lmpq[2][4];     /* Sainsot's L*, M*, P*, Q* of gear k */
    double v0, dv;           /* station k at v0 + k dv */
    int slices;              /* helical pair: slices of the face (1: spur) */
    double overlap;          /* eps_beta: phase spread of the slices, cycles */
    double *del, *frc, *wrk; /* [STATIONS][LOADS + 1]: approach, force, potential */
    double xscale;           /* approach at a moderate load: the scale of x */
} cmesh;

static double dot(const double *a, const double *b, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

/* Energy density of a section of half thickness h at distance arm from the
 * load point along the centreline, per unit force squared and face width:
 * bending (moment cb arm - e sb), shear (factor 1.2) and compression. */
static double section(double arm, double h, double e, double cb, double sb, double eb, double gm)
{
    double mom = cb * arm - e * sb;
    return mom * mom / (eb * (2.0 / 3.0) * h * h * h) + 1.2 * cb * cb / (gm * 2 * h) + sb * sb / (eb * 2 * h);
}

/* Compliance of one tooth (times 1/b: m/N) loaded along the line of action
 * at radius rc: a cantilever of the exact section from the root circle
 * (docs/explanation/impact.md "The compliant mesh"). */
static double tooth_compliance(const gs_gear_geom *g, double rc, double eb, double gm)
{
    bool ring = g->internal;
    double lo = fmax(g->rb, g->r_form), hi = ring ? fmin(g->rf, g->r_form) : rc;
    if (ring)
        lo = rc;
    double psic = gs_gear_involute_psi(g, rc), ar = acos(g->rb / rc);
    double beta = ring ? ar + psic : ar - psic;
    double yc = rc * cos(psic), e = rc * sin(psic), cb = cos(beta), sb = sin(beta);
    double sum = 0;
    const int n = 200;
    double yprev = 0, fprev = 0, yend = 0, hend = 0;
    for (int i = 0; i <= n; i++) {
        double r = lo + (hi - lo) * i / n;
        double ps = gs_gear_involute_psi(g, r), y = r * cos(ps), h = r * sin(ps);
        double f = section(fabs(y - yc), h, e, cb, sb, eb, gm);
        if (i > 0)
            sum += 0.5 * (f + fprev) * fabs(y - yprev);
        yprev = y;
        fprev = f;
        if (i == (ring ? n : 0)) {
            yend = y;
            hend = h;
        }
    }
    /* below the involute (external) / beyond it (ring): the section of the
     * involute's end kept down to the root circle */
    double y0 = yend, y1 = g->rf;
    if (ring ? y1 > y0 : y1 < y0) {
        for (int i = 0; i < n; i++) {
            double ya = y0 + (y1 - y0) * i / n, yb = y0 + (y1 - y0) * (i + 1) / n;
            sum += 0.5 *
                   (section(fabs(ya - yc), hend, e, cb, sb, eb, gm) + section(fabs(yb - yc), hend, e, cb, sb, eb, gm)) *
                   fabs(yb - ya);
        }
    }
    return sum;
}

/* Fillet-foundation (gear body) compliance, Sainsot, Velex & Duverger,
 * "Contribution of gear body to tooth deflections - a new bidimensional
 * analytical formula", J. Mech. Des. 126 (2004) 748-752: the deflection
 * along the load of a tooth whose root (the root circle, between the two
 * fillets at half angle theta_f) sits on a gear body bored at r_int,
 *     delta_f = F cos^2(a_m) / (E b) [L* (u_f/S_f)^2 + M* (u_f/S_f)
 *                                      + P* (1 + Q* tan^2 a_m)],
 * each of L*, M*, P*, Q* = A/theta_f^2 + B h_fi^2 + C h_fi/theta_f
 * + D/theta_f + E h_fi + F, h_fi = r_f / r_int, with the fitted
 * coefficients below (the paper's table, as reproduced by Chaari, Fakhfakh
 * & Haddar, Eur. J. Mech. A/Solids 28 (2009) 461-468, Table 1). */
static const double sainsot[4][6] = {
    /*        A            B           C            D          E       F */
    {-5.574e-5, -1.9986e-3, -2.3015e-4, 4.7702e-3, 0.0271, 6.8045},  /* L* */
    {60.111e-5, 28.100e-3, -83.431e-4, -9.9256e-3, 0.1624, 0.9086},  /* M* */
    {-50.952e-5, 185.50e-3, 0.0538e-4, 53.300e-3, 0.2895, 0.9236},   /* P* */
    {-6.2042e-5, 9.0889e-3, -4.0964e-4, 7.8297e-3, -0.1472, 0.6904}, /* Q* */
};

static void sainsot_coefficients(double hfi, double thf, double out[4])
{
    for (int i = 0; i < 4; i++) {
        const double *c = sainsot[i];
        out[i] = c[0] / (thf * thf) + c[1] * hfi * hfi + c[2] * hfi / thf + c[3] / thf + c[4] * hfi + c[5];
    }
}

/* delta_f / F times b (m/N times m) of gear k loaded along the line of
 * action at radius rc: the load angle a_m is the angle beta of
 * tooth_compliance (between the load and the normal to the tooth
 * centreline), u_f the distance along the centreline from the root circle
 * to where the load line crosses it, S_f = 2 r_f theta_f the tooth's
 * thickness at the root circle. */
static double foundation_compliance(const double lmpq[4], const gs_gear_geom *g, double thf, double rc, double eb)
{
    double psic = gs_gear_involute_psi(g, rc), beta = acos(g->rb / rc) - psic;
    double yc = rc * cos(psic), e = rc * sin(psic), tb = tan(beta), cb = cos(beta);
    double x = (yc - e * tb - g->rf) / (2 * g->rf * thf);
    return cb * cb / eb * (lmpq[0] * x * x + lmpq[1] * x + lmpq[2] * (1 + lmpq[3] * tb * tb));
}

void gsi_compliant_point_at(const gs_gmesh_rt *m, double v, gsi_compliant_point *pt)
{
    const cmesh *cm = m->contact;
    v = fmin(fmax(v, 0.0), cm->L);
    double rp = cm->rho0 + v, ro = cm->internal ? rp + cm->t12 : cm->t12 - rp;
    pt->rho[0] = rp;
    pt->rho[1] = ro;
    pt->radius = 1.0 / (1.0 / rp + (cm->internal ? -1.0 : 1.0) / ro);
    double rc[2] = {hypot(cm->g[0].rb, rp), hypot(cm->g[1].rb, ro)}, lnd = 0, kb = 0, kf = 0;
    for (int k = 0; k < 2; k++) {
        double r = fmin(fmax(rc[k], fmax(cm->g[k].rb, cm->g[k].internal ? cm->g[k].ra : cm->g[k].r_form)),
                        cm->g[k].internal ? cm->g[k].r_form : cm->g[k].ra);
        rc[k] = r;
        lnd += cm->c[k] * log(0.5 * gs_gear_tooth_thickness(&cm->g[k], r));
        kb += tooth_compliance(&cm->g[k], r, cm->eb[k], cm->gm[k]);
        if (cm->found[k])
            kf += foundation_compliance(cm->lmpq[k], &cm->g[k], cm->thf[k], r, cm->eb[k]);
    }
    /* Both bodies' displacements to their own datum (half the tooth
     * thickness at the contact: the tooth centreline, where the bending
     * deflection is measured), in one kernel: the compliance-weighted
     * geometric mean. */
    pt->datum = exp(lnd / (cm->c[0] + cm->c[1]));
    pt->e_star = cm->e_star;
    pt->k_beam = cm->bending > 0 ? cm->b / kb : INFINITY;
    pt->k_found = cm->bending == 2 && kf > 0 ? cm->b / kf : INFINITY;
    pt->k_bend = cm->bending == 2 ? cm->b / (kb + kf) : pt->k_beam;
    pt->face_width = cm->b;
}

/* W, F and dF/ddelta of station k at approach dl >= 0. */
static void law(const cmesh *cm, int k, double dl, double *W, double *F, double *S)
{
    const double *x = cm->del + (size_t)k * (LOADS + 1), *f = cm->frc + (size_t)k * (LOADS + 1),
                 *w = cm->wrk + (size_t)k * (LOADS + 1);
    if (dl < x[0]) { /* x[0] > 0: a relieved station's clearance */
        *W = *F = *S = 0.0;
        return;
    }
    int lo = gs_index_below(x, LOADS, dl);
    double s = (f[lo + 1] - f[lo]) / (x[lo + 1] - x[lo]), t = dl - x[lo];
    *S = s;
    *F = f[lo] + s * t;
    *W = w[lo] + f[lo] * t + 0.5 * s * t * t;
}

/* W, F, S and their v-derivatives between stations. */
static void law_v(const cmesh *cm, double v, double dl, double *W, double *F, double *S, double *Wv, double *Fv)
{
    double sidx = (v - cm->v0) / cm->dv;
    bool out = sidx < 0 || sidx > STATIONS - 1;
    sidx = fmin(fmax(sidx, 0.0), STATIONS - 1.0);
    int k = (int)sidx;
    if (k > STATIONS - 2)
        k = STATIONS - 2;
    double t = sidx - k, W0, F0, S0, W1, F1, S1;
    law(cm, k, dl, &W0, &F0, &S0);
    law(cm, k + 1, dl, &W1, &F1, &S1);
    *W = W0 + t * (W1 - W0);
    *F = F0 + t * (F1 - F0);
    *S = S0 + t * (S1 - S0);
    *Wv = out ? 0.0 : (W1 - W0) / cm->dv;
    *Fv = out ? 0.0 : (F1 - F0) / cm->dv;
}

static double ramp(double x)
{
    return x <= 0 ? 0 : (x >= 1 ? 1 : x);
}

/* Pairs at phase phi on flank sigma: v, weight and d weight / d u. */
static int pairs(const cmesh *cm, double phi, int sigma, double *v, double *wt, double *dwt, int max)
{
    double f = phi - floor(phi), h = 0.5 * cm->tw;
    int n = 0;
    for (int j = -1; n < max; j++) {
        double u = (f + j) * cm->pb;
        if (u <= -h)
            continue;
        if (u >= cm->L + h)
            break;
        double a = u / cm->tw + 0.5, b = (cm->L - u) / cm->tw + 0.5;
        double ra = ramp(a), rb = ramp(b);
        v[n] = sigma > 0 ? u : cm->L - u;
        wt[n] = ra * rb;
        dwt[n] = ((a > 0 && a < 1) ? rb / cm->tw : 0.0) - ((b > 0 && b < 1) ? ra / cm->tw : 0.0);
        n++;
    }
    return n;
}

int gsi_compliant_pairs(const gs_gmesh_rt *m, double phi, int sigma, double *v, double *weight, int max)
{
    double dw[MAXPAIRS];
    return pairs(m->contact, phi, sigma, v, weight, dw, max < MAXPAIRS ? max : MAXPAIRS);
}

double gsi_compliant_pair_force(const gs_gmesh_rt *m, double v, double delta)
{
    double W, F, S, Wv, Fv;
    law_v(m->contact, v, fmax(delta, 0.0), &W, &F, &S, &Wv, &Fv);
    return F;
}

bool gsi_compliant_info_get(const gs_gmesh_rt *m, gsi_compliant_info *info)
{
    if (strcmp(m->ops->name, "compliant") != 0 || !m->contact)
        return false;
    const cmesh *cm = m->contact;
    info->path_length = cm->L;
    info->base_pitch = cm->pb;
    info->transition = cm->tw / cm->pb;
    info->stations = STATIONS;
    info->loads = LOADS;
    info->patches = cm->patches;
    info->max_line_load = cm->pmax;
    info->bending = cm->bending;
    for (int k = 0; k < 2; k++) {
        info->h_fi[k] = cm->found[k] ? cm->hfi[k] : 0.0;
        info->theta_f[k] = cm->found[k] ? cm->thf[k] : 0.0;
        for (int i = 0; i < 4; i++)
            info->lmpq[k][i] = cm->found[k] ? cm->lmpq[k][i] : 0.0;
    }
    return true;
}

typedef struct vals {
    double V, Vx, Vxx, Vp, Vxp;
} vals;

static vals eval_section(const gs_gmesh_rt *m, double x, double phi);
static double slice_offset(const cmesh *cm, int i);

/* V and its derivatives at deflection x, phase phi. A helical pair is cut
 * into `slices` transverse slices of equal width, slice i at the roll
 * phi + eps_beta ((i + 1/2) / n - 1/2) (its contact lines cross the face at
 * the base helix angle), each carrying 1/n of the face width's potential:
 * V stays a sum of the section potentials, so the discrete gradient keeps
 * its energy identity. */
static vals eval(const gs_gmesh_rt *m, double x, double phi)
{
    const cmesh *cm = m->contact;
    if (cm->slices <= 1)
        return eval_section(m, x, phi);
    vals r = {0, 0, 0, 0, 0};
    double w = 1.0 / cm->slices;
    for (int i = 0; i < cm->slices; i++) {
        vals s = eval_section(m, x, phi + slice_offset(cm, i));
        r.V += w * s.V;
        r.Vx += w * s.Vx;
        r.Vxx += w * s.Vxx;
        r.Vp += w * s.Vp;
        r.Vxp += w * s.Vxp;
    }
    return r;
}

/* One transverse section over the whole face width. */
static vals eval_section(const gs_gmesh_rt *m, double x, double phi)
{
    const cmesh *cm = m->contact;
    vals r = {0, 0, 0, 0, 0};
    double hb = m->half_backlash;
    if (hb > 0 && fabs(x) <= hb)
        return r;
    int sg = x >= 0 ? 1 : -1;
    double dl = fabs(x) - hb;
    double v[MAXPAIRS], wt[MAXPAIRS], dw[MAXPAIRS];
    int n = pairs(cm, phi, sg, v, wt, dw, MAXPAIRS);
    for (int j = 0; j < n; j++) {
        double W, F, S, Wv, Fv;
        law_v(cm, v[j], dl, &W, &F, &S, &Wv, &Fv);
        /* dv/du = sg, du/dphi = p_b */
        r.V += wt[j] * W;
        r.Vx += sg * wt[j] * F;
        r.Vxx += wt[j] * S;
        r.Vp += cm->pb * (dw[j] * W + wt[j] * Wv * sg);
        r.Vxp += sg * cm->pb * (dw[j] * F + wt[j] * Fv * sg);
    }
    return r;
}

static gs_err build_table(gs_gmesh_rt *m, gs_diag *d, const char *field)
{
    cmesh *cm = m->contact;
    size_t sz = (size_t)STATIONS * (LOADS + 1);
    cm->del = gs_calloc(sz, sizeof(double));
    cm->frc = gs_calloc(sz, sizeof(double));
    cm->wrk = gs_calloc(sz, sizeof(double));
    double *pr = gs_calloc((size_t)cm->patches, sizeof(double));
    if (!cm->del || !cm->frc || !cm->wrk || !pr) {
        free(pr);
        return GS_ENOMEM;
    }
    cm->v0 = -0.5 * cm->tw;
    cm->dv = (cm->L + cm->tw) / (STATIONS - 1);
    gs_err e = GS_OK;
    for (int k = 0; k < STATIONS && e == GS_OK; k++) {
        gsi_compliant_point pt;
        gsi_compliant_point_at(m, cm->v0 + k * cm->dv, &pt);
        double *x = cm->del + (size_t)k * (LOADS + 1), *f = cm->frc + (size_t)k * (LOADS + 1),
               *w = cm->wrk + (size_t)k * (LOADS + 1);
        for (int i = 1; i <= LOADS; i++) {
            double P = cm->pmax * (double)i * i / ((double)LOADS * LOADS);
            double a = sqrt(4 * P * pt.radius / (GS_PI * pt.e_star));
            /* the candidate region is the Hertz width and a quarter each side */
            gs_compliant_problem pb = {.n = cm->patches,
                                       .x0 = -1.25 * a,
                                       .x1 = 1.25 * a,
                                       .radius = pt.radius,
                                       .e_star = pt.e_star,
                                       .load = P,
                                       .datum = fmax(pt.datum, 2.5 * a)};
            gs_compliant_result r = {.pressure = pr};
            gs_diag sd;
            e = gs_compliant_solve(&pb, &r, &sd);
            if (e != GS_OK) {
                gs_diag_set(d, e, field, "the patch model failed at %.3g N/mm, %.3g mm along the path: %s", P * 1e-3,
                            (cm->v0 + k * cm->dv) * 1e3, sd.message);
                break;
            }
            f[i] = P * cm->b;
            x[i] = r.approach + f[i] / pt.k_bend;
            if (!(x[i] > x[i - 1])) {
                e = gs_diag_set(d, GS_ERANGE, field, "the force-approach law is not monotonic at %.3g N/mm", P * 1e-3);
                break;
            }
            w[i] = w[i - 1] + 0.5 * (f[i] + f[i - 1]) * (x[i] - x[i - 1]);
        }
    }
    free(pr);
    if (e == GS_OK)
        cm->xscale = cm->del[(size_t)(STATIONS / 2) * (LOADS + 1) + LOADS / 3];
    return e;
}

static void cm_destroy(gs_gmesh_rt *m)
{
    cmesh *cm = m->contact;
    if (!cm)
        return;
    free(cm->del);
    free(cm->frc);
    free(cm->wrk);
    free(cm);
    m->contact = NULL;
}

/* Profile modifications: the pair at station v starts to carry load only
 * once the approach exceeds the two flanks' relief C(v) there (the sum of
 * both gears' offsets at their roll lengths rho0 + v and t12 -+ it): each
 * station's force-approach table moves by C(v). W stays piecewise quadratic
 * in the approach and linear between stations, so the exact mean slopes of
 * the discrete gradient keep holding. Both flanks of a gear must carry the
 * same modification (one table serves drive and coast), and the offset must
 * remove material (a clearance; an interference at zero approach would make
 * the potential jump at the backlash edge). */
static gs_err relieve_table(cmesh *cm, const gs_scene_mesh *sm, const gs_scene_body *bp, const gs_scene_body *bo,
                            int ip, int io, gs_diag *d)
{
    const gs_gear_mods *md[2] = {bp->mods, bo->mods};
    const int bi[2] = {ip, io};
    if (!gs_gear_mods_has_profile(md[0]) && !gs_gear_mods_has_profile(md[1]))
        return GS_OK;
    char field[64];
    for (int k = 0; k < 2; k++)
        if (md[k] && memcmp(&md[k]->flank[0], &md[k]->flank[1], sizeof md[k]->flank[0]) != 0) {
            snprintf(field, sizeof field, "bodies[%d].modification", bi[k]);
            return gs_diag_set(d, GS_ERANGE, field,
                               "the compliant mesh '%s' needs the same modification on both flanks", sm->name);
        }
    for (int k = 0; k < STATIONS; k++) {
        double v = fmin(fmax(cm->v0 + k * cm->dv, 0.0), cm->L);
        double rp = cm->rho0 + v, ro = cm->internal ? rp + cm->t12 : cm->t12 - rp;
        double off = gs_gear_flank_offset(&cm->g[0], md[0], 0, hypot(cm->g[0].rb, rp)) +
                     gs_gear_flank_offset(&cm->g[1], md[1], 0, hypot(cm->g[1].rb, ro));
        double c = -off;
        if (c < 0) {
            snprintf(field, sizeof field, "bodies[%d].modification", bi[0]);
            return gs_diag_set(d, GS_ERANGE, field,
                               "the compliant mesh '%s' represents relief only: the modifications add %.3g um "
                               "of material %.3g mm along the path of contact",
                               sm->name, -c * 1e6, v * 1e3);
        }
        double *x = cm->del + (size_t)k * (LOADS + 1);
        for (int i = 0; i <= LOADS; i++)
            x[i] += c;
    }
    return GS_OK;
}

static gs_err cm_init(const gs_model_view *sys, gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    char field[64];
    GS_TRY(gsi_mesh_needs_rigid(sys, m, "compliant", d));
    GS_TRY(gsi_mesh_mods_supported(sys, m, "compliant", 1, 0, d));
    GS_TRY(gsi_mesh_helical_supported(sys, m, "compliant", 1, d));
    cmesh *cm = gs_calloc(1, sizeof *cm);
    if (!cm)
        return GS_ENOMEM;
    m->contact = cm;
    int kp = sc->bodies[sm->gear[0]].gear.kind == GS_GEAR_INTERNAL ? 1 : 0;
    const gs_scene_body *bp = &sc->bodies[sm->gear[kp]], *bo = &sc->bodies[sm->gear[1 - kp]];
    snprintf(field, sizeof field, "meshes[%d].gears", m->index);
    gs_diag gd;
    if (gs_gear_geometry(&bp->gear, &cm->g[0], &gd) != GS_OK || gs_gear_geometry(&bo->gear, &cm->g[1], &gd) != GS_OK)
        return gs_diag_set(d, GS_EGEOMETRY, field, "%s", gd.message);
    double c0[2], c1[2];
    gs_scene_body_centre(sc, sm->gear[kp], c0);
    gs_scene_body_centre(sc, sm->gear[1 - kp], c1);
    gs_pair_info info;
    if (gs_pair_analyse(&bp->gear, &bo->gear, hypot(c1[0] - c0[0], c1[1] - c0[1]), &info, &gd) != GS_OK)
        return gs_diag_set(d, GS_EGEOMETRY, field, "%s", gd.message);
    cm->internal = info.internal;
    /* helical: slices at most a twentieth of a cycle apart, the default
     * transition width, so that the entry ramps of neighbouring slices
     * overlap */
    cm->overlap = info.overlap_ratio;
    cm->slices = info.overlap_ratio > 0 ? (int)fmin(ceil(info.overlap_ratio / 0.05), 64.0) : 1;
    cm->t12 = info.a * sin(info.alpha_w);
    cm->rho0 = sqrt(fmax(info.r1_start * info.r1_start - cm->g[0].rb * cm->g[0].rb, 0.0));
    cm->L = info.path_length;
    cm->pb = info.base_pitch;
    cm->tw = sm->transition * cm->pb;
    const gs_material *mat[2] = {&bp->material, &bo->material};
    for (int k = 0; k < 2; k++) {
        double E = mat[k]->youngs_pa, nu = mat[k]->poisson;
        cm->c[k] = (1 - nu * nu) / E;
        cm->eb[k] = mat[k]->plane == GS_PLANE_STRAIN ? E / (1 - nu * nu) : E;
        cm->gm[k] = E / (2 * (1 + nu));
    }
    cm->e_star = 1.0 / (cm->c[0] + cm->c[1]);
    cm->b = fmin(bp->gear.face_width_m, bo->gear.face_width_m);
    cm->patches = sm->patches;
    /* scene: 0 beam, 1 none, 2 beam_foundation */
    cm->bending = sm->bending == 0 ? 1 : (sm->bending == 2 ? 2 : 0);
    for (int k = 0; k < 2 && cm->bending == 2; k++) {
        /* The formula is for a gear body inside its teeth (bore r_int, here
         * the rigid core): not for a ring, whose rim lies outside. */
        if (cm->g[k].internal)
            continue;
        cm->found[k] = true;
        cm->hfi[k] = cm->g[k].rf / cm->g[k].hub;
        cm->thf[k] = cm->g[k].psi_root;
        sainsot_coefficients(cm->hfi[k], cm->thf[k], cm->lmpq[k]);
        /* the fit can only be trusted where its bracket stays positive:
         * check it along the flank, form circle to tip */
        double rlo = fmax(cm->g[k].rb, cm->g[k].r_form), rhi = cm->g[k].ra;
        for (int j = 0; j <= 8; j++) {
            double r = rlo + (rhi - rlo) * j / 8;
            if (!(foundation_compliance(cm->lmpq[k], &cm->g[k], cm->thf[k], r, cm->eb[k]) > 0)) {
                snprintf(field, sizeof field, "meshes[%d].bending", m->index);
                return gs_diag_set(d, GS_ERANGE, field,
                                   "the fillet-foundation formula (Sainsot et al. 2004) gives a non-positive "
                                   "compliance for '%s' (r_f/r_int %.3g, theta_f %.3g rad): use 'beam'",
                                   k == 0 ? bp->name : bo->name, cm->hfi[k], cm->thf[k]);
            }
        }
    }
    cm->pmax = sm->max_line_load;
    m->half_backlash = 0.5 * sm->backlash;
    m->transition = sm->transition;
    snprintf(field, sizeof field, "meshes[%d].patches", m->index);
    GS_TRY(build_table(m, d, field));
    GS_TRY(relieve_table(cm, sm, bp, bo, sm->gear[kp], sm->gear[1 - kp], d));
    /* Secant stiffness of one pair at a moderate load, averaged over the
     * path (for the default damper and the telemetry's k_single). */
    double ks = 0;
    for (int k = 0; k < STATIONS; k++) {
        size_t i = (size_t)k * (LOADS + 1) + LOADS / 3;
        ks += cm->frc[i] / cm->del[i];
    }
    ks /= STATIONS;
    m->k_single = ks;
    m->k_double = 2 * ks;
    m->damping = gsi_mesh_damping(sys, m, ks * cm->L / cm->pb); /* mean engaged pairs = contact ratio */
    return GS_OK;
}

/* Mean force of station k over approach [da, db], exactly (trapezoids of
 * the piecewise-linear law): the difference quotient of W without the
 * cancellation of W(db) - W(da). */
static double avg_force_station(const cmesh *cm, int k, double da, double db)
{
    if (da > db) {
        double t = da;
        da = db;
        db = t;
    }
    double W, Fa, S;
    law(cm, k, da, &W, &Fa, &S);
    if (!(db > da))
        return Fa;
    const double *x = cm->del + (size_t)k * (LOADS + 1);
    double sum = 0, cur = da;
    if (cur < x[0]) { /* no force inside a relieved station's clearance */
        cur = fmin(db, x[0]);
        Fa = 0.0;
    }
    while (cur < db) {
        int i = 0;
        while (i < LOADS - 1 && x[i + 1] <= cur)
            i++;
        double end = i < LOADS - 1 ? fmin(db, x[i + 1]) : db, Fe;
        if (!(end > cur))
            end = db;
        law(cm, k, end, &W, &Fe, &S);
        sum += 0.5 * (Fa + Fe) * (end - cur);
        cur = end;
        Fa = Fe;
    }
    return sum / (db - da);
}

static double avg_force(const cmesh *cm, double v, double da, double db)
{
    double sidx = fmin(fmax((v - cm->v0) / cm->dv, 0.0), STATIONS - 1.0);
    int k = (int)sidx;
    if (k > STATIONS - 2)
        k = STATIONS - 2;
    double t = sidx - k;
    return (1 - t) * avg_force_station(cm, k, da, db) + t * avg_force_station(cm, k + 1, da, db);
}

/* [V(x1, phi) - V(x0, phi)] / (x1 - x0), per flank without cancellation. */
static double grad_x_section(const gs_gmesh_rt *m, double x0, double x1, double phi)
{
    const cmesh *cm = m->contact;
    double hb = m->half_backlash, g = 0;
    for (int sg = 1; sg >= -1; sg -= 2) {
        double da = fmax(sg * x0 - hb, 0.0), db = fmax(sg * x1 - hb, 0.0);
        if (da == 0.0 && db == 0.0 && !(hb == 0.0 && sg == 1))
            continue;
        /* d delta / dx over the interval: sg while in contact throughout */
        double r = (sg * x0 >= hb && sg * x1 >= hb) ? sg : (db - da) / (x1 - x0);
        if (!isfinite(r))
            continue;
        double v[MAXPAIRS], wt[MAXPAIRS], dw[MAXPAIRS];
        int n = pairs(cm, phi, sg, v, wt, dw, MAXPAIRS);
        for (int j = 0; j < n; j++)
            g += r * wt[j] * avg_force(cm, v[j], da, db);
    }
    return g;
}

static void weight_at(const cmesh *cm, double u, double *w, double *dw)
{
    double a = u / cm->tw + 0.5, b = (cm->L - u) / cm->tw + 0.5, ra = ramp(a), rb = ramp(b);
    *w = ra * rb;
    *dw = ((a > 0 && a < 1) ? rb / cm->tw : 0.0) - ((b > 0 && b < 1) ? ra / cm->tw : 0.0);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Mean of dV/dphi over [phi0, phi1] at deflection x, exactly: each pair's
 * term w(u) W(delta; v(u)) is quadratic in u between the ramp kinks and the
 * stations, so its mean slope is the sum of the slopes at the midpoints of
 * those pieces weighted by their lengths. */
static double grad_phi_section(const gs_gmesh_rt *m, double x, double phi0, double phi1)
{
    const cmesh *cm = m->contact;
    double hb = m->half_backlash;
    if (fabs(x) <= hb && !(hb == 0.0 && x == 0.0))
        return 0.0;
    int sg = x >= 0 ? 1 : -1;
    double dl = fabs(x) - hb, base = floor(fmin(phi0, phi1)), h = 0.5 * cm->tw, sum = 0;
    for (int j = -1;; j++) {
        double ua = (phi0 - base + j) * cm->pb, ub = (phi1 - base + j) * cm->pb;
        double lo = fmin(ua, ub), hi = fmax(ua, ub);
        if (lo >= cm->L + h)
            break;
        if (hi <= -h)
            continue;
        double bp[64];
        int nb = 0;
        bp[nb++] = lo;
        const double kinks[4] = {-h, h, cm->L - h, cm->L + h};
        for (int i = 0; i < 4; i++)
            if (kinks[i] > lo && kinks[i] < hi)
                bp[nb++] = kinks[i];
        for (int k = 0; k < STATIONS && nb < 62; k++) {
            double vk = cm->v0 + k * cm->dv, uk = sg > 0 ? vk : cm->L - vk;
            if (uk > lo && uk < hi)
                bp[nb++] = uk;
        }
        bp[nb++] = hi;
        qsort(bp, (size_t)nb, sizeof bp[0], cmp_double);
        double acc = 0;
        for (int i = 0; i + 1 < nb || (nb == 2 && i == 0); i++) {
            double a = bp[i], b = bp[i + 1 < nb ? i + 1 : i], mid = 0.5 * (a + b), len = b - a;
            double w, dw, W, F, S, Wv, Fv;
            weight_at(cm, mid, &w, &dw);
            law_v(cm, sg > 0 ? mid : cm->L - mid, dl, &W, &F, &S, &Wv, &Fv);
            double slope = dw * W + w * Wv * sg;
            if (hi > lo)
                acc += slope * len / (hi - lo);
            else {
                acc = slope;
                break;
            }
            if (i + 2 >= nb)
                break;
        }
        sum += acc;
    }
    return sum * cm->pb;
}

/* The phase offset of slice i of a helical pair (see eval). */
static double slice_offset(const cmesh *cm, int i)
{
    return cm->slices <= 1 ? 0.0 : cm->overlap * ((i + 0.5) / cm->slices - 0.5);
}

/* The two mean slopes summed over the slices (each 1/n of the face). */
static double grad_x(const gs_gmesh_rt *m, double x0, double x1, double phi)
{
    const cmesh *cm = m->contact;
    if (cm->slices <= 1)
        return grad_x_section(m, x0, x1, phi);
    double g = 0;
    for (int i = 0; i < cm->slices; i++)
        g += grad_x_section(m, x0, x1, phi + slice_offset(cm, i));
    return g / cm->slices;
}

static double grad_phi(const gs_gmesh_rt *m, double x, double phi0, double phi1)
{
    const cmesh *cm = m->contact;
    if (cm->slices <= 1)
        return grad_phi_section(m, x, phi0, phi1);
    double g = 0;
    for (int i = 0; i < cm->slices; i++) {
        double o = slice_offset(cm, i);
        g += grad_phi_section(m, x, phi0 + o, phi1 + o);
    }
    return g / cm->slices;
}

/* Symmetrised coordinate-increment discrete gradient of V in (x, phi):
 *   g_x   = [V(x1,p0) - V(x0,p0) + V(x1,p1) - V(x0,p1)] / (2 dx)
 *   g_phi = [V(x0,p1) - V(x0,p0) + V(x1,p1) - V(x1,p0)] / (2 dphi)
 * so g_x dx + g_phi dphi = V(x1,p1) - V(x0,p0). Each quotient is evaluated
 * as the exact mean of the derivative over the interval (grad_x, grad_phi),
 * so it stays accurate for increments far below the deflection, near a
 * static equilibrium, where differences of V would lose all their digits. */
static void cm_force(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0, const double *dq, double h,
                     double *g, double *J, double *diss, double *force)
{
    int n = sys->n_coords;
    /* s along the true line of action, translations (bearings) included,
     * with its exact discrete gradient ab over the step (mesh_common.c) */
    const double *ab = gsi_mesh_grad(sys, m, q0, dq);
    double x0 = gsi_mesh_s(sys, m, q0) - m->s_ref, dx = dot(ab, dq, n);
    double p0 = dot(m->c, q0, n), dp = dot(m->c, dq, n);
    double x1 = x0 + dx, p1 = p0 + dp, hb = m->half_backlash;
    double gx = 0.5 * (grad_x(m, x0, x1, p0) + grad_x(m, x0, x1, p1));
    double gp = 0.5 * (grad_phi(m, x0, p0, p1) + grad_phi(m, x1, p0, p1));
    /* An approximate Jacobian (Newton backtracks; the residual is exact). */
    vals v10 = eval(m, x1, p0), v11 = eval(m, x1, p1);
    double jxx = 0.25 * (v10.Vxx + v11.Vxx), jxp = 0.25 * v11.Vxp, jpx = 0.25 * (v10.Vxp + v11.Vxp), jpp = 0.0;
    /* Damping while the teeth are in contact at the midpoint; in scenes with
     * bearings or pin errors (sys->smooth_contact, as the lumped mesh) over
     * the share of the step in contact, continuous in the step's end, which
     * Newton needs when a floating member closes a flank inside a step. */
    double dW, cd = gsi_mesh_contact_damping(sys, m, x0, dx, hb, &dW);
    double fd = cd * dx / h;
    jxx += (cd + m->damping * dW * dx) / h;
    for (int i = 0; i < n; i++)
        g[i] += ab[i] * (gx + fd) + m->c[i] * gp;
    gsi_mesh_add_jacobian(m, n, J, jxx, jxp, jpx, jpp);
    *diss = fd * dx;
    *force = gx + fd;
}

static double cm_energy(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    int n = sys->n_coords;
    return eval(m, gsi_mesh_s(sys, m, q) - m->s_ref, dot(m->c, q, n)).V;
}

const gs_gmesh_ops gsi_gmesh_compliant = {
    .name = "compliant",
    .init = cm_init,
    .n_eq = 0,
    .force = cm_force,
    .energy = cm_energy,
    .destroy = cm_destroy,
};
