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
 *             creating it. With the tangent calibration (docs/explanation/stiffness.md)
 *             the spring is affine about the FE static TE,
 *             V = 1/2 k_t(phi) (|f| - delta_0(phi))_+^2, stepped with the
 *             symmetrised coordinate-increment discrete gradient, which
 *             reduces to the split above when delta_0 = 0. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/fe_modes.h"
#include "gearsim/modification.h"
#include "gearsim/stiffness.h"
#include "gearsim/models.h"
#include "gearsim/util.h"
#include "mesh_common.h"

/* Deflection beyond the backlash dead zone. */
static double dead(double x, double hb)
{
    if (x > hb)
        return x - hb;
    if (x < -hb)
        return x + hb;
    return 0.0;
}

/* A calibrated table (n_table values over one mesh cycle from phase0 in
 * the direction phase_dir), periodic piecewise-linear; its derivative in the
 * phase in *dv. */
static double table_d(const gs_gmesh_rt *m, const double *tab, double phi, double *dv)
{
    int n = m->n_table;
    double f = (phi - m->phase0) * m->phase_dir;
    f -= floor(f);
    double x = f * n;
    int i = (int)x;
    if (i >= n)
        i = n - 1;
    double t = x - i, v0 = tab[i], v1 = tab[(i + 1) % n];
    *dv = (v1 - v0) * n * m->phase_dir;
    return v0 + t * (v1 - v0);
}

/* Difference quotient of a calibrated table between phases p0 and p1,
 * (v(p1) - v(p0)) / (p1 - p0) (v'(p0) when equal), and its derivative in p1.
 * Within one interval it is the interval's slope and across one node the
 * average of the two slopes weighted by the lengths on either side, so it
 * carries no cancellation however small p1 - p0 is. */
static void table_quot(const gs_gmesh_rt *m, const double *tab, double p0, double p1, double *q, double *dq)
{
    int n = m->n_table;
    double x0 = (p0 - m->phase0) * m->phase_dir * n, x1 = (p1 - m->phase0) * m->phase_dir * n;
    double i0 = floor(x0), i1 = floor(x1);
    if (i0 == i1 || p0 == p1) {
        double dv;
        table_d(m, tab, p0, &dv);
        *q = dv;
        *dq = 0.0;
        return;
    }
    if (fabs(i1 - i0) == 1.0) {
        double lo = fmin(i0, i1), xn = lo + 1.0; /* the node crossed */
        long il = (long)lo % n;
        if (il < 0)
            il += n;
        double sl = (tab[(il + 1) % n] - tab[il]) * n * m->phase_dir; /* below */
        double sh = (tab[(il + 2) % n] - tab[(il + 1) % n]) * n * m->phase_dir; /* above */
        double s0 = x0 < x1 ? sl : sh, s1 = x0 < x1 ? sh : sl;
        double w = (xn - x0) / (x1 - x0); /* share of the step on p0's side, in [0, 1] */
        *q = w * s0 + (1.0 - w) * s1;
        *dq = (s1 - *q) / (p1 - p0);
        return;
    }
    double d0, d1;
    double v0 = table_d(m, tab, p0, &d0), v1 = table_d(m, tab, p1, &d1);
    *q = (v1 - v0) / (p1 - p0);
    *dq = (d1 - *q) / (p1 - p0);
}

/* Stiffness over the mesh cycle and its derivative in the phase. Double
 * contact over the first (eps - 1) of each base pitch of roll, single contact
 * over the rest, with linear transitions of width `transition` (a fraction of
 * the cycle) centred on each change: a tooth pair takes load over a short
 * roll, and a continuous k keeps the discrete-gradient step well posed (a
 * true jump asks for an impulsive torque that, at low speed, the step cannot
 * resolve). */
/* Helical pair (docs/explanation/helical.md): the tooth pairs in contact
 * averaged over a window of w cycles centred on phi,
 * n(phi) = (1/w) sum_k |[phi + k - w/2, phi + k + w/2] cut [0, eps_alpha]|,
 * and its derivative. With w = eps_beta it is the total length of the
 * contact lines projected on the face width, over b (the slices of the face
 * enter contact one after the other over eps_beta cycles); for a spur pair
 * with w the transition width it is the rectangular wave below. */
static double lines_in_contact(double a, double w, double phi, double *dn)
{
    double s = phi - floor(phi), sum = 0.0, der = 0.0;
    int k0 = -(int)ceil(w) - 1, k1 = (int)ceil(a + w) + 1;
    for (int k = k0; k <= k1; k++) {
        double lo = s + k - 0.5 * w, hi = s + k + 0.5 * w;
        double l = fmax(lo, 0.0), h = fmin(hi, a);
        if (h > l) {
            sum += h - l;
            der += (hi < a ? 1.0 : 0.0) - (lo > 0.0 ? 1.0 : 0.0);
        }
    }
    *dn = der / w;
    return sum / w;
}

/* The spur rectangular wave alone: small enough to inline into the step
 * (lumped_force), where the call was a tenth of the lumped planetary's step
 * (tests/bench/bench_lumped.c). */
static inline double rect_wave_d(const gs_gmesh_rt *m, double phi, double *dk)
{
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

static double stiffness_d(const gs_gmesh_rt *m, double phi, double *dk)
{
    if (m->k_table)
        return table_d(m, m->k_table, phi, dk);
    if (m->overlap_ratio > 0.0) {
        /* k_single per tooth pair in contact over the whole face, k_double
         * for two: linear in the contact-line length */
        double dn, n = lines_in_contact(m->contact_ratio, m->transition, phi, &dn);
        *dk = (m->k_double - m->k_single) * dn;
        return m->k_single + (m->k_double - m->k_single) * (n - 1.0);
    }
    return rect_wave_d(m, phi, dk);
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

static gs_err kin_init(const gs_model_view *sys, gs_gmesh_rt *m, gs_diag *d)
{
    return gsi_mesh_helical_supported(sys, m, "kinematic", 1, d);
}

static void kin_force(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0,
                      const double *dq, double h, double *g, double *J, double *diss, double *force)
{
    (void)sys, (void)m, (void)q0, (void)dq, (void)h, (void)g, (void)J;
    *diss = 0;
    *force = NAN; /* filled from the multiplier by the solver */
}

static double kin_energy(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    (void)sys, (void)m, (void)q;
    return 0.0;
}

/* Run-out modulates the mesh phase of a lumped mesh (docs/explanation/geometry.md,
 * "Run-out: the TE spectrum"): a gear's centre offset moves its flanks, and
 * the contact point on the path of contact, by its displacement R(q) along
 * the line of action (the run-out part of the tooth errors), so the
 * stiffness wave follows phi = c . q + R(q) / p_b. Kept in m->contact (the
 * mesh's model data) when a gear of a tangent-calibrated mesh has run-out
 * (lumped_init): 1 / p_b and the
 * scratch for the step's discrete gradient cbar of phi (cbar . dq =
 * phi(q0 + dq) - phi(q0) exactly, so the energy balance stays exact). */
typedef struct lumped_pm {
    double inv_pb;
    double *cbar;
} lumped_pm;

static double lumped_phase(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    const lumped_pm *pm = m->contact;
    double p = dot(m->c, q, sys->n_coords);
    return pm ? p + pm->inv_pb * gsi_mesh_runout(m, q) : p;
}

static const double *lumped_phase_grad(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0,
                                       const double *dq)
{
    const lumped_pm *pm = m->contact;
    if (!pm)
        return m->c;
    memcpy(pm->cbar, m->c, (size_t)sys->n_coords * sizeof(double));
    gsi_mesh_runout_grad(m, q0, dq, pm->inv_pb, pm->cbar);
    return pm->cbar;
}

/* The Jacobian of the phase force gp through the phase's discrete gradient. */
static void lumped_phase_jacobian(const gs_gmesh_rt *m, int n, const double *q0, const double *dq, double gp,
                                  double *J)
{
    const lumped_pm *pm = m->contact;
    if (pm)
        gsi_mesh_runout_jacobian(m, n, q0, dq, gp * pm->inv_pb, J);
}

static void lumped_destroy(gs_gmesh_rt *m)
{
    lumped_pm *pm = m->contact;
    if (pm)
        free(pm->cbar);
    free(pm);
    m->contact = NULL;
}

/* Relative load step of the tangent calibration's central difference. */
#define CAL_TANGENT_STEP 0.05

/* The modal calibration's factor per position (*out, r->positions
 * entries): (f_FE / f_2)^2, f_FE the first torsional mesh mode of the FE
 * pair's own eigenproblem at the loaded static contact of that position
 * (src/modal/fe_modes.c: the first mode whose kinetic energy is mostly in
 * the rigid rotations), f_2 the two-inertia closed form with that
 * analysis's tangent stiffness. The static mesh stiffness is measured hub
 * to hub; in the vibration most of a gear's inertia (rim and teeth) sits
 * on the contact's side of the web's torsional compliance, so the spring
 * between the moving masses is stiffer (5-10 % in frequency on the
 * validation pair, docs/explanation/modal.md): k_t times the factor puts the lumped
 * model's mesh mode at the FE one. Driver 0 only (the modal analysis loads
 * gear 0 of the mesh). */
static gs_err modal_factors(const gs_scene *sc, int mesh, int driver, double phase, const gs_stiffness_result *r,
                            double **out, gs_diag *d)
{
    *out = NULL;
    if (driver != 0)
        return gs_diag_set(d, GS_ERANGE, "calibration",
                           "the modal calibration needs the external gear first in the mesh's 'gears'");
    gs_fe_modes_opts mo;
    gs_fe_modes_opts_defaults(&mo);
    mo.nearfield = 0; /* as the calibration's static analysis (calibrate) */
    mo.positions = r->positions;
    mo.modes = 4;
    mo.torque_nm = r->torque_nm;
    mo.phase = phase;
    gs_fe_modes_result fm;
    GS_TRY(gs_fe_modes_analyse(sc, mesh, &mo, &fm, d));
    double *f = gs_calloc((size_t)r->positions, sizeof(double));
    gs_err e = f ? GS_OK : GS_ENOMEM;
    for (int j = 0; e == GS_OK && j < r->positions; j++) {
        const gs_fe_modes_point *p = &fm.pt[j];
        double hz = 0;
        for (int i = 0; i < fm.modes && hz == 0; i++)
            if (p->rotation[i] > 0.5)
                hz = p->hz[i];
        if (fabs(p->roll - r->pt[j].roll) > 1e-9 || !(hz > 0) || !(p->lumped_hz > 0))
            e = gs_diag_set(d, GS_ERANGE, "positions", "no torsional mesh mode at roll %.3f", r->pt[j].roll);
        else
            f[j] = (hz / p->lumped_hz) * (hz / p->lumped_hz);
    }
    gs_fe_modes_result_clear(&fm);
    if (e != GS_OK)
        free(f);
    else
        *out = f;
    return e;
}

/* Mesh stiffness over one cycle from the quasi-static FE analysis of the
 * pair (src/contact/stiffness.c) at the scene's load F on the driver: the
 * gear whose teeth count the mesh phase, so one driver pitch is one cycle.
 * The analysis starts at the gears' scene angles and rolls in the torque's
 * direction; entry j is at phase phase0 + phase_dir j / n. Every rank runs
 * it (deterministic); it costs a few tenths of a second per mesh at the
 * default density.
 *
 * Secant: k = F / TE. Tangent (default): k_t = dF/dTE at F, the central
 * difference over F (1 -+ 5%), and the offset delta_0 = TE - F / k_t, so that
 * the spring F = k_t (delta - delta_0) stands at the FE static TE under F
 * and oscillates about it with the tangent stiffness. A position whose
 * tangent comes out softer than its secant (delta_0 < 0: not met beyond
 * round-off on the validation pair) keeps the secant law (delta_0 = 0). */
static gs_err calibrate(const gs_model_view *sys, gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.nearfield = 0; /* the dynamic FE model it stands in for has no near-field correction */
    o.positions = sm->calibrate_positions;
    o.driver = sys->scene->bodies[sm->gear[0]].gear.kind == GS_GEAR_INTERNAL ? 1 : 0;
    int tangent = !sm->calibrate_secant;
    o.tangent = tangent;
    o.tangent_step = tangent ? CAL_TANGENT_STEP : 0.0;
    /* Entries at the middles of n equal intervals from the start, (j + 1/2) / n
     * of a cycle: the start then lies inside an interval of the piecewise-linear
     * table, not on a node, where the exact quotient (k(p1) - k(p0)) / (p1 -
     * p0) jumps between the two slopes as the step's phase increment changes
     * sign. From rest (increments near 0) with a potential already loaded
     * there (run-out, an initial deflection), Newton found no root across that
     * jump (planetary_runout failed at step 0). */
    o.phase = 0.5 / o.positions;
    gs_stiffness_result r;
    char field[64];
    snprintf(field, sizeof field, "meshes[%d].stiffness", m->index);
    gs_diag sd;
    /* The calibration is of the gears without their tooth errors (pitch
     * table, run-out): the mesh adds those itself along the line of action
     * (gsi_mesh_error), one cycle of FE would only see a few teeth's. */
    const gs_scene *sc = sys->scene;
    gs_scene clean;
    gs_gear_mods mods[2];
    gs_scene_body *bodies = NULL;
    if (m->n_err) {
        GS_TRY(gsi_mesh_clean_scene(sc, m->index, &clean, &bodies, mods));
        sc = &clean;
    }
    gs_err e = gs_stiffness_analyse(sc, m->index, &o, &r, &sd);
    double *modal = NULL;
    if (e == GS_OK && sm->calibrate_modal) {
        e = modal_factors(sc, m->index, o.driver, o.phase, &r, &modal, &sd);
        if (e != GS_OK)
            gs_stiffness_result_clear(&r);
    }
    free(bodies);
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "calibration by the %s FE analysis failed: %s (%s)",
                           sm->calibrate_modal ? "modal" : "quasi-static", sd.message, sd.field);
    m->k_table = gs_calloc((size_t)r.positions, sizeof(double));
    if (tangent)
        m->d0_table = gs_calloc((size_t)r.positions, sizeof(double));
    if (!m->k_table || (tangent && !m->d0_table)) {
        gs_stiffness_result_clear(&r);
        free(modal);
        return GS_ENOMEM;
    }
    m->n_table = r.positions;
    double sum = 0;
    for (int j = 0; j < r.positions; j++) {
        /* N/(mm um) per mm of face width -> N/m */
        double ks = r.pt[j].k * r.face_width_mm * 1e6, te = r.pt[j].te_elastic_um * 1e-6;
        if (r.modified) {
            /* Profile modifications: the static TE from the perfect gears'
             * no-load position, their geometric TE included (te_loaded =
             * te_raw - te_ref; te itself would hide the relief). */
            te = r.pt[j].te_loaded_um * 1e-6;
            ks = r.force_n / te;
        }
        m->k_table[j] = ks;
        if (tangent) {
            double kt = r.pt[j].k_tan * r.face_width_mm * 1e6 * (modal ? modal[j] : 1.0);
            if (!(kt > 0) || !isfinite(kt)) {
                gs_stiffness_result_clear(&r);
                free(modal);
                return gs_diag_set(d, GS_ERANGE, field, "the calibration gave no tangent stiffness at roll %.3f",
                                   r.pt[j].roll);
            }
            double d0 = te - r.force_n / kt;
            if (d0 > 0) {
                m->k_table[j] = kt;
                m->d0_table[j] = d0;
            }
        }
        sum += m->k_table[j];
        if (!(m->k_table[j] > 0) || !isfinite(m->k_table[j])) {
            gs_stiffness_result_clear(&r);
            free(modal);
            return gs_diag_set(d, GS_ERANGE, field, "the calibration gave no stiffness at roll %.3f", r.pt[j].roll);
        }
    }
    m->phase_dir = r.torque_nm < 0 ? -1.0 : 1.0;
    m->phase0 = lumped_phase(sys, m, sys->q) + m->phase_dir * o.phase;
    m->k_single = m->k_double = sum / r.positions; /* the mean, for the damping estimate */
    gs_stiffness_result_clear(&r);
    free(modal);
    return GS_OK;
}

static gs_err lumped_init(const gs_model_view *sys, gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    GS_TRY(gsi_mesh_helical_supported(sys, m, "lumped", 1, d));
    if (m->overlap_ratio > 0.0) {
        char field[64];
        if (sm->stiffness_type == GS_STIFF_CALIBRATED) {
            snprintf(field, sizeof field, "meshes[%d].stiffness.type", m->index);
            return gs_diag_set(d, GS_ERANGE, field,
                               "mesh '%s' is helical: the calibrated stiffness comes from the planar FE analysis "
                               "of spur teeth; give a rectangular or constant stiffness", sm->name);
        }
        if (sm->k_double < sm->k_single) {
            snprintf(field, sizeof field, "meshes[%d].stiffness.double", m->index);
            return gs_diag_set(d, GS_ERANGE, field,
                               "mesh '%s' is helical: its stiffness grows with the contact-line length, so "
                               "'double' must be at least 'single'", sm->name);
        }
        /* the load share of a pitch error follows the spur wave */
        GS_TRY(gsi_mesh_mods_supported(sys, m, "helical lumped", 0, 0, d));
    }
    GS_TRY(gsi_mesh_mods_supported(sys, m, sm->stiffness_type == GS_STIFF_CALIBRATED ? "calibrated lumped" : "lumped",
                                   sm->stiffness_type == GS_STIFF_CALIBRATED, 1, d));
    for (int k = 0; k < 2; k++) { /* a hand-filled body's single pitch error without a table */
        const gs_scene_body *b = &sys->scene->bodies[sm->gear[k]];
        if (b->pitch_error_tooth >= 0 && b->pitch_error != 0.0 && (!b->mods || b->mods->n_pitch == 0)) {
            char field[64];
            snprintf(field, sizeof field, "bodies[%d].pitch_error", sm->gear[k]);
            return gs_diag_set(d, GS_ERANGE, field, "a lumped mesh takes pitch errors as the pitch_errors_um table");
        }
    }
    /* Every lumped law: the rectangular wave and the secant table (lumped_force)
     * were left unmodulated while their quotient (f1^2 - f0^2) / (2 ds) lost
     * precision and Newton stalled (docs/explanation/geometry.md); with the same-flank
     * quotient (f0 + f1) / 2 they carry it over 2 revolutions
     * (test_tooth_errors). */
    if (gsi_mesh_has_runout(m)) {
        lumped_pm *pm = gs_calloc(1, sizeof *pm);
        m->contact = pm; /* freed by lumped_destroy */
        if (!pm || !(pm->cbar = gs_calloc((size_t)sys->n_coords, sizeof(double))))
            return GS_ENOMEM;
        const gs_gear_params *g = &sys->scene->bodies[sm->gear[sys->scene->bodies[sm->gear[0]].gear.kind ==
                                                                 GS_GEAR_INTERNAL ? 1 : 0]].gear;
        pm->inv_pb = g->teeth / (2 * GS_PI * gs_gear_base_radius(g)); /* the phase gear's base pitch */
    }
    m->k_single = sm->k_single;
    m->k_double = sm->stiffness_type == GS_STIFF_CONSTANT ? sm->k_single : sm->k_double;
    if (sm->stiffness_type == GS_STIFF_CALIBRATED)
        GS_TRY(calibrate(sys, m, d));
    m->half_backlash = 0.5 * sm->backlash;
    double e1 = m->contact_ratio - 1.0;
    m->transition = fmin(sm->transition, 0.5 * fmin(e1, 1.0 - e1));
    if (!(m->transition > 0))
        m->transition = 1e-3;
    double eps = m->contact_ratio;
    if (m->overlap_ratio > 0.0) {
        /* the window is the overlap ratio, or the spur transition if wider */
        m->transition = fmax(m->overlap_ratio, m->transition);
        m->damping = gsi_mesh_damping(sys, m, m->k_single + (m->k_double - m->k_single) * (eps - 1.0));
        return GS_OK;
    }
    m->damping = gsi_mesh_damping(sys, m, eps >= 2 ? m->k_double : m->k_single * (2 - eps) + m->k_double * (eps - 1));
    return GS_OK;
}

/* H(x) = 1/2 max(x, 0)^2, the spring energy per unit stiffness, and its
 * derivative. */
static double Hs(double x)
{
    return x > 0.0 ? 0.5 * x * x : 0.0;
}

static double Hd(double x)
{
    return x > 0.0 ? x : 0.0;
}

/* Difference quotient (H(x1) - H(x0)) / (x1 - x0) (H'(x0) when equal),
 * computed without cancellation, and its partial derivatives in x0, x1. */
static double Hq(double x0, double x1, double *d0, double *d1)
{
    if (x0 > 0.0 && x1 > 0.0) {
        *d0 = *d1 = 0.5;
        return 0.5 * (x0 + x1);
    }
    if (x0 <= 0.0 && x1 <= 0.0) {
        *d0 = *d1 = 0.0;
        return 0.0;
    }
    /* one on each side: x1 != x0 */
    double q = (Hs(x1) - Hs(x0)) / (x1 - x0);
    *d0 = (q - Hd(x0)) / (x1 - x0);
    *d1 = (Hd(x1) - q) / (x1 - x0);
    return q;
}

/* The tangent-calibrated law, V(s, phi) = k(phi) sum_sig H(sig f - c(phi)),
 * f = s - s_ref, c = half backlash + delta_0(phi), on either flank (sig = +-1;
 * the calibration's table serves both, as the secant table does). Its
 * symmetrised coordinate-increment discrete gradient
 *   g_s = 1/2 [V(s1, p0) - V(s0, p0) + V(s1, p1) - V(s0, p1)] / ds,
 *   g_p = 1/2 [V(s0, p1) - V(s0, p0) + V(s1, p1) - V(s1, p0)] / dp
 * gives g_s ds + g_p dp = V(s1, p1) - V(s0, p0) exactly; every quotient is
 * formed along its own argument (Hq; k and delta_0 piecewise linear in phi),
 * and with delta_0 = 0 it is the split of lumped_force. The damper acts over
 * the share of the step the teeth spend in contact (wet), which keeps the
 * residual continuous when a flank closes or opens inside the step (the
 * midpoint test of lumped_force switches the damping force on and off
 * there, which Newton cannot resolve once delta_0 opens a clearance). */
static void tangent_force(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0, const double *dq,
                          double h, double *g, double *J, double *diss, double *force)
{
    int n = sys->n_coords;
    const double *ab = gsi_mesh_grad(sys, m, q0, dq);
    double s0 = gsi_mesh_s(sys, m, q0) - m->s_ref, ds = dot(ab, dq, n);
    const double *cb = lumped_phase_grad(sys, m, q0, dq);
    double p0 = lumped_phase(sys, m, q0), dp = dot(cb, dq, n);
    double s1 = s0 + ds, p1 = p0 + dp, hb = m->half_backlash;
    double dk0, dk1, dd0, dd1;
    double k0 = table_d(m, m->k_table, p0, &dk0), k1 = table_d(m, m->k_table, p1, &dk1);
    double c0 = hb + table_d(m, m->d0_table, p0, &dd0), c1 = hb + table_d(m, m->d0_table, p1, &dd1);
    double kbar = 0.5 * (k0 + k1);
    /* Quotients of k and c along phi, and their derivatives in dp. */
    double Dk, Dc, dDk, dDc;
    table_quot(m, m->k_table, p0, p1, &Dk, &dDk);
    table_quot(m, m->d0_table, p0, p1, &Dc, &dDc);
    double gs = 0.0, gp = 0.0, jss = 0.0, jsp = 0.0, jps = 0.0, jpp = 0.0;
    for (int side = 0; side < 2; side++) {
        double sg = side ? -1.0 : 1.0;
        /* s-quotients at p0 and p1 */
        double a0, a1, b0, b1;
        double q0s = Hq(sg * s0 - c0, sg * s1 - c0, &a0, &a1);
        double q1s = Hq(sg * s0 - c1, sg * s1 - c1, &b0, &b1);
        gs += 0.5 * sg * (k0 * q0s + k1 * q1s);
        jss += 0.5 * (k0 * a1 + k1 * b1);
        jsp += 0.5 * sg * (dk1 * q1s - k1 * (b0 + b1) * dd1);
        /* phi-quotients at s0 and s1 */
        for (int e = 0; e < 2; e++) {
            double s = e ? s1 : s0, x0 = sg * s - c0, x1 = sg * s - c1;
            double e0, e1;
            double B = Hq(x0, x1, &e0, &e1), A = 0.5 * (Hs(x1) + Hs(x0));
            gp += 0.5 * (Dk * A - kbar * B * Dc);
            jpp += 0.5 * (dDk * A - Dk * 0.5 * Hd(x1) * dd1 - 0.5 * dk1 * B * Dc + kbar * e1 * dd1 * Dc -
                          kbar * B * dDc);
            if (e)
                jps += 0.5 * sg * (Dk * 0.5 * (Hd(x1) + Hd(x0)) - kbar * (e0 + e1) * Dc);
        }
    }
    /* Damping over the share of the step in contact: f_d = c W ds / h. */
    double W = 0.0, dWs = 0.0, dWp = 0.0;
    for (int side = 0; side < 2; side++) {
        double sg = side ? -1.0 : 1.0, dw1;
        W += gsi_mesh_wet(sg * s0 - c0, sg * s1 - c1, &dw1);
        dWs += sg * dw1;
        dWp -= dw1 * dd1;
    }
    double cd = m->damping * W;
    double fd = cd * ds / h;
    jss += (cd + m->damping * dWs * ds) / h;
    jsp += m->damping * dWp * ds / h;
    for (int i = 0; i < n; i++)
        g[i] += ab[i] * (gs + fd) + cb[i] * gp;
    gsi_mesh_add_jacobian_c(m, cb, n, J, jss, jsp, jps, jpp);
    gsi_mesh_error_jacobian(m, n, q0, dq, gs + fd, J);
    lumped_phase_jacobian(m, n, q0, dq, gp, J);
    *diss = fd * ds;
    *force = gs + fd;
}

/* Discrete gradient split (see file comment):
 *   dV = (k0+k1)/2 * (f1^2 - f0^2)/2  +  (f0^2+f1^2)/2 * (k1 - k0)/2
 * and each difference quotient is taken along its own scalar argument. */
static void lumped_force(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0,
                         const double *dq, double h, double *g, double *J, double *diss,
                         double *force)
{
    if (m->d0_table) {
        tangent_force(sys, m, q0, dq, h, g, J, diss, force);
        return;
    }
    int n = sys->n_coords;
    /* Gears on fixed axes without tooth errors: s and the phase are linear,
     * their four sums formed in one pass (each in the order of the general
     * path's, so the same numbers). */
    bool plain = !m->n_tr && !m->n_err && !m->contact;
    const double *ab = m->a, *cb = m->c;
    double s0, ds, p0, dp;
    if (plain) {
        double sq = 0.0, sd = 0.0, pq = 0.0, pd = 0.0;
        for (int i = 0; i < n; i++) {
            sq += ab[i] * q0[i];
            sd += ab[i] * dq[i];
            pq += cb[i] * q0[i];
            pd += cb[i] * dq[i];
        }
        s0 = sq - m->s_ref;
        ds = sd;
        p0 = pq;
        dp = pd;
    } else {
        ab = gsi_mesh_grad(sys, m, q0, dq);
        s0 = gsi_mesh_s(sys, m, q0) - m->s_ref;
        ds = dot(ab, dq, n);
        cb = lumped_phase_grad(sys, m, q0, dq);
        p0 = lumped_phase(sys, m, q0);
        dp = dot(cb, dq, n);
    }
    double s1 = s0 + ds;
    double hb = m->half_backlash;
    double f0 = dead(s0, hb), f1 = dead(s1, hb);
    double dk0, dk1;
    bool rect = !m->k_table && !(m->overlap_ratio > 0.0);
    double k0 = rect ? rect_wave_d(m, p0, &dk0) : stiffness_d(m, p0, &dk0);
    double k1 = rect ? rect_wave_d(m, p0 + dp, &dk1) : stiffness_d(m, p0 + dp, &dk1);
    double kbar = 0.5 * (k0 + k1);
    double dfs; /* (f1^2 - f0^2) / (2 ds), exact for the piecewise-linear f */
    bool same_flank = (s0 > hb && s1 > hb) || (s0 < -hb && s1 < -hb);
    if (same_flank)
        dfs = 0.5 * (f0 + f1); /* f1 - f0 = ds: the same quotient without the cancellation of
                                * f1^2 - f0^2 when the step moves s by far less than f */
    else if (ds != 0.0)
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
    /* Damping acts while the teeth are in contact at the midpoint; with
     * translating gears (bearing joints) over the share of the step in
     * contact instead (continuous in the step's end, as tangent_force), which
     * Newton needs when a floating member closes a flank inside a step (in
     * every mesh of a scene with bearing joints or pin errors: sys->smooth_contact). */
    double dW, cd = gsi_mesh_contact_damping(sys, m, s0, ds, hb, &dW);
    double fd = cd * ds / h;
    for (int i = 0; i < n; i++)
        g[i] += ab[i] * (gs + fd) + cb[i] * gp;
    /* Jacobian of the s-part: d(dfs)/d(ds) = 1/2 where both ends are in contact. */
    double jd = (cd + m->damping * dW * ds) / h;
    double jss = (f0 != 0.0 || f1 != 0.0 ? 0.5 * kbar : 0.0) + jd;
    /* The exact slope of dfs across the dead zone's edges: a floating member
     * makes the step a coupled problem that needs it (on one flank it is 1/2,
     * above). */
    if (sys->smooth_contact && ds != 0.0 && !same_flank)
        jss = kbar * (f1 - dfs) / ds + jd;
    /* Cross terms: d gs / d dp and d gp / d ds (f1 moves with ds). */
    double jsp = 0.5 * dk1 * dfs;
    double jps = dp != 0.0 ? 0.5 * f1 * (f1 != 0.0 ? 1.0 : 0.0) * (k1 - k0) / dp : 0.5 * f1 * dk0;
    gsi_mesh_add_jacobian_c(m, cb, n, J, jss, jsp, jps, jpp);
    if (!plain) {
        gsi_mesh_error_jacobian(m, n, q0, dq, gs + fd, J);
        lumped_phase_jacobian(m, n, q0, dq, gp, J);
    }
    *diss = fd * ds;
    *force = gs + fd;
}

static double lumped_energy(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    double s = gsi_mesh_s(sys, m, q) - m->s_ref, p = lumped_phase(sys, m, q);
    if (m->d0_table) {
        double dv;
        double c = m->half_backlash + table_d(m, m->d0_table, p, &dv);
        return stiffness(m, p) * (Hs(s - c) + Hs(-s - c));
    }
    double f = dead(s, m->half_backlash);
    return 0.5 * stiffness(m, p) * f * f;
}

const gs_gmesh_ops gsi_gmesh_kinematic = {
    .name = "kinematic", .init = kin_init, .n_eq = 1, .force = kin_force, .energy = kin_energy,
};

const gs_gmesh_ops gsi_gmesh_lumped = {
    .name = "lumped", .init = lumped_init, .n_eq = 0, .force = lumped_force, .energy = lumped_energy,
    .destroy = lumped_destroy,
};
