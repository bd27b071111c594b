/* SPDX-License-Identifier: MIT
 * Mesh model `impact`: rigid gears with backlash that separate and
 * re-engage with an impact law (METHOD.md sections 6 and 7, rung 2;
 * docs/explanation/impact.md, "The impact mesh (rattle)").
 *
 * Along the line of action the pair is a 1-D contact: s = a . q, deflection
 * x = s - s_ref (s_ref: the initial state, teeth centred in the backlash),
 * gap g = b/2 - |x| on the flank sigma = sign(x) (drive side x > 0, coast
 * side x < 0), normal relative velocity v_n = -sigma a . w (< 0: the flanks
 * approach).
 *
 *  - In the step the mesh is absent: no force, no row, no potential (free
 *    flight inside the backlash).
 *  - After the step (every rank alike), when the gap is closed (g <= 0) and
 *    the flanks approach, one frictionless impulse P along the line of
 *    action: w += -sigma P u with u = M^-1 a (M^-1 restricted to the
 *    kinematic rows of other meshes, so that they stay satisfied) and
 *    W = a . u the inverse effective mass (sum a_i^2 / I_i without such
 *    rows). P comes from the impact library (gs_impact_contact, W_tn = 0,
 *    mu = 0: Newton, Poisson and Stronge coincide). The loss is
 *    (1 - e^2) v_n^2 / (2 W).
 *  - Sustained contact: when the approach speed is below the speed the
 *    loads give the line of action in two steps (2 h |u . F|), or e = 0,
 *    the impulse is plastic (e = 0). Then the positions are projected back
 *    onto the flank, q += u (sigma b/2 - x) / W. With a plastic impulse this
 *    is exactly the kinematic mesh's midpoint step while the teeth stay
 *    engaged: the free increment plus h/2 times the impulse's velocity
 *    change is the projected increment. The projection changes no velocity
 *    and so no kinetic energy; only a potential of another mesh on these
 *    coordinates could change, and that change is booked with the loss so
 *    that the balance stays exact. */
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "gearsim/impact.h"
#include "gearsim/models.h"
#include "gearsim/util.h"
#include "mesh_common.h"

typedef struct impact_mesh {
    double *u;          /* n_coords: M^-1 a on the kinematic rows */
    double W;           /* a . u */
    bool ready;         /* u restricted to the system's kinematic rows */
    int n_eq;           /* kinematic rows of the scene (scratch size) */
    double *scratch;    /* n_eq^2 + n_eq + n_coords */
    double e;
    gs_restitution law;
} impact_mesh;

static void impact_destroy(gs_gmesh_rt *m)
{
    impact_mesh *im = m->contact;
    if (!im)
        return;
    free(im->u);
    free(im->scratch);
    free(im);
    m->contact = NULL;
}

static double minv(const gs_model_view *sys, int coord)
{
    for (int i = 0; i < sys->n_bodies; i++) {
        if (sys->bodies[i].coord == coord)
            return 1.0 / sys->bodies[i].inertia_eff;
        int tc = sys->bodies[i].tcoord; /* a translating centre: its mass */
        if (tc >= 0 && (coord == tc || coord == tc + 1))
            return 1.0 / sys->bodies[i].mass;
    }
    return 0.0;
}

static gs_err impact_init(const gs_model_view *sys, gs_gmesh_rt *m, gs_diag *d)
{
    GS_TRY(gsi_mesh_mods_supported(sys, m, "impact", 0, 0, d));
    GS_TRY(gsi_mesh_helical_supported(sys, m, "impact", 0, d));
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    char field[64];
    GS_TRY(gsi_mesh_needs_rigid(sys, m, "impact", d));
    if (!(sm->backlash > 0)) {
        snprintf(field, sizeof field, "meshes[%d].backlash_mm", m->index);
        return gs_diag_set(d, GS_ERANGE, field, "impact mesh '%s' needs a backlash > 0", sm->name);
    }
    int n = sys->n_coords, nk = 0;
    for (int i = 0; i < sc->n_meshes; i++)
        nk += sc->meshes[i].model == GS_MESH_KINEMATIC;
    impact_mesh *im = gs_calloc(1, sizeof *im);
    if (!im)
        return GS_ENOMEM;
    m->contact = im;
    im->u = gs_calloc((size_t)(n ? n : 1), sizeof(double));
    im->n_eq = nk;
    im->scratch = gs_calloc((size_t)(nk * nk + nk + n + 1), sizeof(double));
    if (!im->u || !im->scratch)
        return GS_ENOMEM; /* the system frees m->contact through destroy */
    im->e = sm->restitution;
    im->law = (gs_restitution)sm->law;
    m->half_backlash = 0.5 * sm->backlash;
    m->impacts = 0;
    m->impact_loss = 0.0;
    /* Without kinematic rows u = M^-1 a; with them it is restricted on the
     * first use, when the system's rows exist (after every mesh's init). */
    im->W = 0.0;
    for (int i = 0; i < n; i++) {
        im->u[i] = minv(sys, i) * m->a[i];
        im->W += m->a[i] * im->u[i];
    }
    im->ready = nk == 0;
    return GS_OK;
}

/* u = M^-1 a - M^-1 G^T (G M^-1 G^T)^-1 G M^-1 a: the velocity change of
 * a unit impulse along a that keeps the kinematic rows G w = 0. */
static void restrict_to_rows(const gs_model_view *sys, const double *a, impact_mesh *im)
{
    int n = sys->n_coords, k = sys->n_eq;
    im->ready = true;
    if (k == 0 || k > im->n_eq)
        return;
    double *S = im->scratch, *r = S + k * k, *mi = r + k;
    for (int i = 0; i < n; i++)
        mi[i] = minv(sys, i);
    for (int p = 0; p < k; p++) {
        const double *gp = sys->eq_rows + (size_t)p * n;
        r[p] = 0.0;
        for (int i = 0; i < n; i++)
            r[p] += gp[i] * mi[i] * a[i];
        for (int q = 0; q < k; q++) {
            const double *gq = sys->eq_rows + (size_t)q * n;
            double v = 0.0;
            for (int i = 0; i < n; i++)
                v += gp[i] * mi[i] * gq[i];
            S[p * k + q] = v;
        }
    }
    /* A singular S (redundant rows) is refused when the system is built
     * with inconsistent speeds; keep the unrestricted u then. */
    if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', k, 1, S, k, r, 1) != 0)
        return;
    im->W = 0.0;
    for (int i = 0; i < n; i++) {
        double v = 0.0;
        for (int p = 0; p < k; p++)
            v += sys->eq_rows[(size_t)p * n + i] * r[p];
        im->u[i] = mi[i] * (a[i] - v);
        im->W += a[i] * im->u[i];
    }
}

static void impact_force(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0,
                         const double *dq, double h, double *g, double *J, double *diss,
                         double *force)
{
    (void)sys, (void)m, (void)q0, (void)dq, (void)h, (void)g, (void)J;
    *diss = 0.0;
    *force = 0.0; /* free flight in the step; the impulses come after it */
}

static double impact_energy(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    (void)sys, (void)m, (void)q;
    return 0.0;
}

static double dot(const double *x, const double *y, int n)
{
    double s = 0.0;
    for (int i = 0; i < n; i++)
        s += x[i] * y[i];
    return s;
}

/* Potential energy of the other meshes (lumped springs on the same
 * coordinates) and of the supports of translating centres: what a
 * position projection could change. */
static double other_potential(const gs_model_view *sys, const gs_gmesh_rt *m)
{
    double v = 0.0;
    for (int i = 0; i < sys->n_meshes; i++)
        if (&sys->meshes[i] != m)
            v += sys->meshes[i].ops->energy(sys, &sys->meshes[i], sys->q);
    for (int i = 0; i < sys->n_joints; i++)
        v += sys->joints[i].ops->energy(sys, &sys->joints[i], sys->q);
    return v;
}

/* A planet on a pin bearing of a turning carrier in the mesh (m->n_tr):
 * its line of action turns with the carrier, so s is not linear in q. The
 * impulse's direction is then s's gradient at the current q, and u, W are
 * formed from it at every use. Returns the gradient (m->a otherwise). */
static const double *line_gradient(const gs_model_view *sys, const gs_gmesh_rt *m, impact_mesh *im)
{
    if (!m->n_tr)
        return m->a;
    int n = sys->n_coords;
    double *zero = im->scratch + im->n_eq * im->n_eq + im->n_eq; /* n doubles, kept zero */
    for (int i = 0; i < n; i++)
        zero[i] = 0.0;
    const double *a = gsi_mesh_grad(sys, m, sys->q, zero);
    im->W = 0.0;
    for (int i = 0; i < n; i++) {
        im->u[i] = minv(sys, i) * a[i];
        im->W += a[i] * im->u[i];
    }
    im->ready = false;
    return a;
}

static double impact_after_step(const gs_model_view *sys, gs_gmesh_rt *m)
{
    impact_mesh *im = m->contact;
    int n = sys->n_coords;
    double hb = m->half_backlash;
    double x = (m->n_tr ? gsi_mesh_s(sys, m, sys->q) : dot(m->a, sys->q, n)) - m->s_ref;
    if (fabs(x) < hb)
        return 0.0; /* free flight inside the backlash */
    const double *a = line_gradient(sys, m, im);
    if (!im->ready)
        restrict_to_rows(sys, a, im);
    if (!(im->W > 0.0))
        return 0.0; /* the line of action cannot move */
    double sigma = x > 0.0 ? 1.0 : -1.0;
    double vn = -sigma * dot(a, sys->w, n);
    double loss = 0.0;
    if (vn < 0.0) {
        /* Speed the loads give the line of action over a step (at the end
         * of this one): below twice that, the flanks stay in contact. */
        double h = sys->h_sub, t = sys->time + h, alpha = 0.0;
        for (int i = 0; i < sys->n_bodies; i++) {
            int c = sys->bodies[i].coord;
            if (c < 0 || im->u[c] == 0.0)
                continue;
            double M, cb;
            gs_model_body_load(sys, i, t, &M, &cb);
            alpha += im->u[c] * (M - cb * sys->w[c]);
        }
        double scale = 0.0;
        for (int i = 0; i < n; i++)
            scale += fabs(a[i] * sys->w[i]);
        double vtol = fmax(2.0 * h * fabs(alpha), 1e-12 * scale);
        bool sustained = -vn < vtol;
        double e = im->e == 0.0 || im->e * -vn < vtol ? 0.0 : im->e;
        gs_impact_contact_problem p = {
            .W = {im->W, 0.0, im->W}, .v0 = {0.0, vn}, .e = e, .mu = 0.0, .law = im->law};
        gs_impact_result r;
        gs_diag d;
        double P;
        if (gs_impact_contact(&p, &r, &d) == GS_OK)
            P = r.impulse_n;
        else
            P = -(1.0 + e) * vn / im->W; /* not reached: W > 0, e in [0, 1] */
        for (int i = 0; i < n; i++)
            sys->w[i] -= sigma * P * im->u[i];
        loss = (1.0 - e * e) * 0.5 * vn * vn / im->W;
        if (!sustained)
            m->impacts++;
    }
    /* Back onto the flank (no velocity change; see the file comment). */
    double dx = sigma * hb - x;
    if (dx != 0.0) {
        double v0 = other_potential(sys, m);
        for (int i = 0; i < n; i++)
            sys->q[i] += im->u[i] * dx / im->W;
        loss += v0 - other_potential(sys, m);
    }
    m->impact_loss += loss;
    return loss;
}

const gs_gmesh_ops gsi_gmesh_impact = {
    .name = "impact",
    .init = impact_init,
    .n_eq = 0,
    .force = impact_force,
    .energy = impact_energy,
    .destroy = impact_destroy,
    .after_step = impact_after_step,
};
