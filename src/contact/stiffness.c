/* SPDX-License-Identifier: MIT
 * Quasi-static mesh stiffness and static transmission error of a gear pair
 * (include/gearsim/stiffness.h, docs/explanation/stiffness.md).
 *
 * Per load case the unknowns are the contact forces lambda (one per contact
 * row i, gap g_i) and the driver's rotation delta; the elastic displacements
 * are condensed with the static compliance C_b = K_b^{-1} of each body,
 * restricted to its boundary loop (columns computed once per node and
 * cached). Linearised at the current state (delta_k, u_k):
 *     g_i(delta, u) ~ gbar_i + a_i delta + B_i u,
 *     gbar_i = g_i(q_k) - a_i delta_k - B_i u_k,   a_i = dg_i/dtheta_driver,
 * and u = C B^T lambda. The minimum of the total potential energy
 * 1/2 u^T K u - T delta under g >= 0 has the dual
 *     minimise 1/2 lambda^T W lambda + gbar^T lambda,  W = B C B^T,
 *     subject to a^T lambda = -T (torque balance), lambda >= 0,
 * whose equality multiplier is -delta. Solved with the Goldfarb-Idnani QP;
 * then the gaps are re-evaluated at the deformed position and the step
 * repeats until delta settles (twice below 1e-7 of the elastic rotation). */
#include <hdf5.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact/stiffness_hook.h"
#include "contact/stiffness_internal.h"
#include "gearsim/contact.h"
#include "gearsim/fe.h"
#include "gearsim/fe_static.h"
#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/qp.h"
#include "gearsim/stiffness.h"
#include "io/h5attr.h"
#include "gearsim/util.h"

void gs_stiffness_opts_defaults(gs_stiffness_opts *o)
{
    o->positions = 24;
    o->torque_nm = 0.0;
    o->driver = 0;
    o->refine = -1;
    o->phase = 0.0;
    o->tangent = 1;
    o->tangent_step = 0.0;
    o->max_iter = 12;
    o->cycles = 1;
    o->order = 0;
    o->nearfield = 2;
    o->nearfield_depth_mm = 0.0;
    o->fine = 0;
    o->all_rows = 0;
    o->all_dofs = 0;
    o->slices = 0;
    o->coupling_mm = 0.0;
}

void gs_stiffness_result_clear(gs_stiffness_result *r)
{
    if (!r)
        return;
    free(r->pt);
    free(r->face_z_mm);
    free(r->face_load);
    memset(r, 0, sizeof *r);
}

double gsi_stiff_default_torque(const gs_scene *sc, int body, double rb, double b_m)
{
    for (int i = 0; i < sc->n_loads; i++) {
        const gs_scene_load *l = &sc->loads[i];
        if (l->body != body)
            continue;
        if (l->type == GS_LOAD_CONSTANT || l->type == GS_LOAD_RAMP)
            if (l->moment != 0.0)
                return l->moment;
        if (l->type == GS_LOAD_TABLE) {
            double best = 0.0;
            for (int k = 0; k < l->n_table; k++)
                if (fabs(l->moments[k]) > fabs(best))
                    best = l->moments[k];
            if (best != 0.0)
                return best;
        }
    }
    return 200.0 * (b_m * 1e3) * rb; /* 200 N/mm line load */
}

/* An analysis under way: the roll positions are solved one at a time
 * (gs_stiffness_next) so that a caller can do other work in between. */
struct gs_stiffness_run {
    const gs_scene *sc;
    const gs_scene_mesh *sm;
    gs_stiffness_opts o;
    work w;
    double *uT[2];          /* displacements at T (central tangent) */
    double T, F, bmm, pitch, thB_first, ratio, t_start, cpu_start;
    int next;               /* next roll position */
    int slice;              /* the slice analysis follows the planar one */
    gs_stiffness_result out;
};

static void run_free(gs_stiffness_run *r)
{
    gsi_stiff_work_free(&r->w);
    free(r->uT[0]);
    free(r->uT[1]);
    gs_stiffness_result_clear(&r->out);
    free(r);
}

void gs_stiffness_run_free(gs_stiffness_run **run)
{
    if (run && *run) {
        run_free(*run);
        *run = NULL;
    }
}

int gs_stiffness_run_done(const gs_stiffness_run *run) { return run ? run->next : 0; }
int gs_stiffness_run_positions(const gs_stiffness_run *run) { return run ? run->o.positions : 0; }

int gs_stiffness_run_rows(const gs_stiffness_run *run, const gs_contact_row **rows,
                          const double **force)
{
    if (!run || run->next == 0)
        return 0;
    *rows = run->w.row;
    *force = run->w.x;
    return run->out.pt[run->next - 1].rows;
}

int gs_stiffness_run_nearfield(const gs_stiffness_run *run, int *pair, double *c_tan)
{
    if (!run || run->next == 0)
        return 0;
    const work *w = &run->w;
    int nr = run->out.pt[run->next - 1].rows, np = 0;
    for (int i = 0; i < nr; i++)
        pair[i] = -1;
    if (!w->nf)
        return 0;
    for (int p = 0; p < w->n_pc; p++) {
        double c = gsi_stiff_nf_tangent(w, nr, p);
        if (!(c > 0.0))
            continue;
        for (int i = 0; i < nr; i++)
            if (w->teeth[i][0] == w->pc[p].tooth[0] && w->teeth[i][1] == w->pc[p].tooth[1])
                pair[i] = np;
        c_tan[np++] = c;
    }
    return np;
}

const work *gsi_stiffness_run_work(const gs_stiffness_run *run)
{
    return run && run->next > 0 ? &run->w : NULL;
}

const gs_mesh *gs_stiffness_run_mesh(const gs_stiffness_run *run, int k)
{
    return run && (k == 0 || k == 1) ? run->w.b[k].mesh : NULL;
}

gs_err gs_stiffness_begin(const gs_scene *sc, int mesh_index, const gs_stiffness_opts *opt,
                          gs_stiffness_run **run, gs_diag *d)
{
    if (!sc || !run)
        return gs_diag_set(d, GS_EINVAL, "", "NULL scene or run");
    *run = NULL;
    gs_stiffness_opts o;
    if (opt)
        o = *opt;
    else
        gs_stiffness_opts_defaults(&o);
    if (mesh_index < 0 || mesh_index >= sc->n_meshes)
        return gs_diag_set(d, GS_ERANGE, "meshes", "mesh index %d: the scene has %d meshes",
                           mesh_index, sc->n_meshes);
    /* Helical gears, lead modifications or a misalignment: the slice analysis
     * (stiffness_slices.c) on top of the planar analysis of the transverse
     * section (docs/explanation/helical.md). */
    int slice = 0;
    {
        const gs_scene_mesh *sm = &sc->meshes[mesh_index];
        for (int k = 0; k < 2; k++) {
            const gs_scene_body *b = &sc->bodies[sm->gear[k]];
            const gs_lead_mods *l = &b->lead;
            slice |= b->gear.helix_angle > 0 || l->crowning != 0 || l->end_relief != 0 || l->slope != 0;
        }
        slice |= sm->misalign_in != 0 || sm->misalign_out != 0;
    }
    if (slice && o.positions < 8)
        return gs_diag_set(d, GS_ERANGE, "positions",
                           "the slice analysis samples the tooth pair stiffness at the roll positions: "
                           "at least 8, not %d", o.positions);
    if (slice && o.cycles != 1)
        return gs_diag_set(d, GS_ERANGE, "cycles", "the slice analysis spans one mesh cycle (cycles 1)");
    if (slice && (o.slices < 0 || o.slices == 1 || o.slices > 2000))
        return gs_diag_set(d, GS_ERANGE, "slices", "slices must be 0 (default 320) or 2..2000, not %d", o.slices);
    if (!(o.coupling_mm >= 0.0 && o.coupling_mm <= 1000.0))
        return gs_diag_set(d, GS_ERANGE, "coupling_mm", "the coupling length must be in [0, 1000] mm");
    if (o.positions < 1 || o.positions > 100000)
        return gs_diag_set(d, GS_ERANGE, "positions", "positions must be 1..100000, not %d",
                           o.positions);
    if (o.driver != 0 && o.driver != 1)
        return gs_diag_set(d, GS_ERANGE, "driver", "driver must be gear 0 or 1 of the mesh");
    if (o.refine < -1 || o.refine > 6)
        return gs_diag_set(d, GS_ERANGE, "refine", "refine must be -1 (scene) or 0..6");
    if (o.order < 0 || o.order > 2)
        return gs_diag_set(d, GS_ERANGE, "order", "order must be 0 (scene), 1 or 2");
    if (!isfinite(o.torque_nm) || !isfinite(o.phase))
        return gs_diag_set(d, GS_ERANGE, "torque", "torque and phase must be finite");
    if (!(o.tangent_step >= 0.0 && o.tangent_step <= 0.5))
        return gs_diag_set(d, GS_ERANGE, "tangent_step", "the tangent's load step must be in [0, 0.5]");
    if (o.max_iter < 1)
        o.max_iter = 12;
    if (o.cycles < 1 || o.cycles > 10000)
        return gs_diag_set(d, GS_ERANGE, "cycles", "cycles must be 1..10000, not %d", o.cycles);
    if (o.all_rows != 0 && o.all_rows != 1)
        return gs_diag_set(d, GS_ERANGE, "all_rows", "all_rows must be 0 or 1");
    if (o.all_dofs != 0 && o.all_dofs != 1)
        return gs_diag_set(d, GS_ERANGE, "all_dofs", "all_dofs must be 0 or 1");
    if (o.fine != 0 && o.fine != 1)
        return gs_diag_set(d, GS_ERANGE, "fine", "fine must be 0 or 1");
    if (o.fine && (o.refine >= 0 || o.order > 0))
        return gs_diag_set(d, GS_EINVAL, "fine",
                           "the fine setting is a mesh of its own: not with refine or order");
    if (o.nearfield < 0 || o.nearfield > 2)
        return gs_diag_set(d, GS_ERANGE, "nearfield", "nearfield must be 0 (off), 1 (on) or 2 (auto)");
    if (!(o.nearfield_depth_mm >= 0.0 && o.nearfield_depth_mm <= 100.0))
        return gs_diag_set(d, GS_ERANGE, "nearfield_depth_mm",
                           "the near-field depth must be in [0, 100] mm (0: automatic)");
    gs_stiffness_run *r = gs_calloc(1, sizeof *r);
    if (!r)
        return GS_ENOMEM;
    r->t_start = gs_now();
    r->cpu_start = gs_cpu_now();
    r->sc = sc;
    r->o = o;
    r->slice = slice;
    const gs_scene_mesh *sm = r->sm = &sc->meshes[mesh_index];
    work *wp = &r->w;
#define w (*wp)
    gs_stiffness_result *out = &r->out;
    double **uT = r->uT;
    gs_err e = GS_OK;
    int bidx[2] = {sm->gear[o.driver], sm->gear[1 - o.driver]};
    w.si[0] = o.driver;
    w.si[1] = 1 - o.driver;
    w.win_on = !o.all_rows;
    int fc[2] = {0, 0};
    if (sc->bodies[bidx[0]].type == GS_BODY_GEAR && sc->bodies[bidx[1]].type == GS_BODY_GEAR)
        gsi_stiff_fine_centres(sc, bidx, &o, fc);
    for (int k = 0; k < 2 && e == GS_OK; k++)
        e = gsi_stiff_sbody_init(sc, bidx[k], o.refine, o.order,
                                 /* the teeth in contact over the cycles, an odd count (centred) */
                                 o.fine ? o.cycles + 2 + (o.cycles % 2 == 0) : 0,
                                 fc[k], &w.b[k], d);
    if (e != GS_OK)
        goto done;
    for (int k = 0; k < 2; k++)
        w.b[k].zone_on = !o.all_dofs;
    const gs_gear_params *gA = &w.b[0].sb->gear, *gB = &w.b[1].sb->gear;
    {
        gs_contact_opts co;
        gs_contact_opts_defaults(&co);
        co.passes = sm->one_pass ? GS_CONTACT_ONE_PASS : GS_CONTACT_TWO_PASS;
        const gs_mesh *m[2];
        m[w.si[0]] = w.b[0].mesh;
        m[w.si[1]] = w.b[1].mesh;
        gs_diag cd;
        gs_diag_clear(&cd);
        e = gs_contact_search_new(m[0], &sc->bodies[sm->gear[0]].gear, m[1],
                                  &sc->bodies[sm->gear[1]].gear, &co, &w.search, &cd);
        if (e != GS_OK) {
            gs_diag_set(d, e, "meshes", "contact search of '%s': %s", sm->name, cd.message);
            goto done;
        }
    }
    w.rb = gs_gear_base_radius(gA);
    /* auto (2): on quadratic meshes of unmodified gears, where it is
     * validated against the reference; on linear triangles it left positions
     * unconverged, and on modified flanks there is no reference (it doubled
     * the relieved TE of the Harris map against the plain FE before the
     * vertex fit's curvature bound and the rigid gaps against the flank
     * gap; 0.89 times it since: docs/explanation/stiffness.md). */
    double nf_gap = 0.0; /* conjugate flanks' gap at the kinematic angle, m */
    w.nf = o.nearfield == 2 ? gs_mesh_order(w.b[0].mesh) == 2 && gs_mesh_order(w.b[1].mesh) == 2 &&
                                  !w.b[0].xy_ref && !w.b[1].xy_ref
                            : o.nearfield;
    if (w.nf) {
        /* Depth of the FE field point below the contact: given, or a fixed
         * fraction of the smaller module (docs/explanation/stiffness.md). */
        double mmin = fmin(gA->module_m, gB->module_m);
        w.nf_depth = o.nearfield_depth_mm > 0.0 ? o.nearfield_depth_mm * 1e-3 : GS_NF_DEPTH * mmin;
        if (w.nf_depth > mmin) {
            e = gs_diag_set(d, GS_ERANGE, "nearfield_depth_mm",
                            "the near-field depth %.3g mm is beyond one module (%.3g mm)",
                            w.nf_depth * 1e3, mmin * 1e3);
            goto done;
        }
        const gs_material *m0 = &w.b[0].sb->material, *m1 = &w.b[1].sb->material;
        w.nf_estar = gs_hertz_line_modulus(m0->youngs_pa, m0->poisson, m1->youngs_pa,
                                           m1->poisson, m0->plane);
        w.nf_bw = fmin(gA->face_width_m, gB->face_width_m);
        for (int k = 0; k < 2 && e == GS_OK; k++) {
            gs_gear_geom gg;
            e = gs_gear_geometry(&w.b[k].sb->gear, &gg, d);
            w.nf_rform[k] = gg.r_form;
        }
        if (e != GS_OK)
            goto done;
        /* Unmodified gears are conjugate involutes at any centre distance
         * they mesh at: the kinematic angles (gs_pair_mesh_phase) share the
         * backlash equally, so every loaded flank pair is apart by half the
         * normal backlash along the line of action, the same for all (0 at
         * the tight-mesh distance, to 0.01 um; gsi_stiff_nf_offsets). Thinning and
         * profile shift change the backlash, not the conjugacy. */
        gs_pair_info pinfo;
        gs_diag td;
        gs_diag_clear(&td);
        double ac = hypot(w.b[1].c[0] - w.b[0].c[0], w.b[1].c[1] - w.b[0].c[1]);
        int conj = gs_pair_analyse(gA, gB, ac, &pinfo, &td) == GS_OK;
        w.nf_conj = !w.b[0].xy_ref && !w.b[1].xy_ref && conj;
        w.nf_refconj = (w.b[0].xy_ref || w.b[1].xy_ref) && conj;
        if ((w.nf_conj || w.nf_refconj) && fabs(ac - pinfo.a_tight) >= 1e-8)
            nf_gap = 0.5 * pinfo.backlash_normal;
        gs_index nmax = w.b[0].mesh->n_nodes > w.b[1].mesh->n_nodes ? w.b[0].mesh->n_nodes
                                                                   : w.b[1].mesh->n_nodes;
        w.fq = malloc((size_t)(2 * nmax) * sizeof *w.fq);
        w.uq = malloc((size_t)(2 * nmax) * sizeof *w.uq);
        if (!w.fq || !w.uq) {
            e = GS_ENOMEM;
            goto done;
        }
    }
    double bw = fmin(gA->face_width_m, gB->face_width_m);
    double T = r->T = o.torque_nm != 0.0 ? o.torque_nm : gsi_stiff_default_torque(sc, bidx[0], w.rb, bw);
    w.sgn = T > 0 ? 1.0 : -1.0;
    w.nf_dc = w.sgn * nf_gap / w.rb;
    double F = r->F = fabs(T) / w.rb, bmm = r->bmm = bw * 1e3;
    snprintf(out->mesh_name, sizeof out->mesh_name, "%s", sm->name);
    out->mesh_index = mesh_index;
    out->driver = o.driver;
    for (int k = 0; k < 2; k++) {
        out->body[k] = bidx[k];
        out->teeth[k] = w.b[k].sb->gear.teeth;
        out->refine[k] = o.refine >= 0 ? o.refine : w.b[k].sb->mesh.refine;
        out->nodes[k] = w.b[k].mesh->n_nodes;
    }
    out->torque_nm = T;
    out->force_n = F;
    out->base_radius_m = w.rb;
    out->face_width_mm = bmm;
    {
        double a = hypot(w.b[1].c[0] - w.b[0].c[0], w.b[1].c[1] - w.b[0].c[1]);
        double cr = NAN;
        if (gs_pair_contact_ratio(gA, gB, a, &cr, NULL, NULL) == GS_OK)
            out->contact_ratio = cr;
        else
            out->contact_ratio = NAN;
    }
    out->positions = o.positions;
    out->pt = gs_calloc((size_t)o.positions, sizeof *out->pt);
    if (!out->pt) {
        e = GS_ENOMEM;
        goto done;
    }
    for (int k = 0; k < 2 && o.tangent && o.tangent_step > 0.0; k++) {
        uT[k] = malloc((size_t)(2 * w.b[k].mesh->n_nodes) * sizeof *uT[k]);
        if (!uT[k]) {
            e = GS_ENOMEM;
            goto done;
        }
    }
    r->pitch = 2.0 * GS_PI / gA->teeth;
    /* The driven gear's kinematic angle: the mesh phase nearest to its
     * expected rotation (ratio z_A / z_B; opposite sense for an external
     * pair, same sense for an internal one), so the same tooth pairs follow
     * each other whatever the number of positions. */
    r->thB_first = gs_pair_mesh_phase(gA, w.b[0].c, w.b[0].sb->angle0 + w.sgn * o.phase * r->pitch,
                                      gB, w.b[1].c, w.b[1].sb->angle0);
    r->ratio = (double)gA->teeth / gB->teeth *
               (gA->kind == GS_GEAR_INTERNAL || gB->kind == GS_GEAR_INTERNAL ? 1.0 : -1.0);
done:
#undef w
    if (e != GS_OK) {
        if (d && !d->message[0])
            gs_diag_set(d, e, "meshes", "stiffness analysis failed: %s", gs_strerror(e));
        run_free(r);
        return e;
    }
    *run = r;
    return GS_OK;
}

/* No-load closing rotation: rigid bodies (u = 0) turned until the first row
 * closes, the rows re-evaluated at each new angle (with backlash the
 * linearisation at the kinematic angle alone is too crude). */
static gs_err close_rigid(work *w, double *delta0, double roll, const char *name, gs_diag *d)
{
    int nr;
    double gmin;
    for (int it = 0; it < 30; it++) {
        GS_TRY(gsi_stiff_collect(w, *delta0, INFINITY, &nr, &gmin));
        double close = INFINITY;
        for (int i = 0; i < nr; i++) {
            double a = w->row[i].dg_dtheta[w->si[0]];
            if (a * w->sgn < -1e-6 * w->rb)
                close = fmin(close, w->row[i].gap.g / fabs(a));
        }
        if (!isfinite(close))
            return gs_diag_set(d, GS_EINFEASIBLE, "meshes",
                               "'%s' at roll %.3f: no flank closes in the torque direction", name,
                               roll);
        *delta0 += w->sgn * close;
        if (fabs(close) * w->rb < 1e-12)
            break;
    }
    return GS_OK;
}

/* The bodies' kinematic angles at roll (mesh cycles from the phase). */
static void roll_angles(gs_stiffness_run *r, double roll)
{
    work *w = &r->w;
    const gs_gear_params *gA = &w->b[0].sb->gear, *gB = &w->b[1].sb->gear;
    w->theta0[0] = w->b[0].sb->angle0 + w->sgn * (r->o.phase + roll) * r->pitch;
    w->theta0[1] = gs_pair_mesh_phase(gA, w->b[0].c, w->theta0[0], gB, w->b[1].c,
                                      r->thB_first + r->ratio * w->sgn * roll * r->pitch);
}

gs_err gsi_stiffness_run_offsets(gs_stiffness_run *r, double roll)
{
    work *w = &r->w;
    if (!w->nf || r->next < 1)
        return GS_EINVAL;
    roll_angles(r, roll);
    for (int k = 0; k < 2; k++) {
        memset(w->b[k].u, 0, (size_t)(2 * w->b[k].mesh->n_nodes) * sizeof *w->b[k].u);
        w->b[k].dirty = 0;
    }
    w->restart = 0;
    return gsi_stiff_nf_offsets(w);
}

/* Roll position r->next: its no-load closing rotation, the loaded solve
 * and the tangent. */
static gs_err solve_position(gs_stiffness_run *r, gs_diag *d)
{
    work *wp = &r->w;
#define w (*wp)
    const gs_stiffness_opts o = r->o;
    const gs_scene_mesh *sm = r->sm;
    gs_stiffness_result *out = &r->out;
    double **uT = r->uT;
    double T = r->T, F = r->F, bmm = r->bmm, pitch = r->pitch;
    gs_err e = GS_OK;
    {
        int j = r->next;
        gs_stiffness_point *pt = &out->pt[j];
        double roll = (double)j / o.positions * o.cycles;
        pt->roll = roll;
        pt->angle_rad = roll * pitch;
        roll_angles(r, roll);
        for (int k = 0; k < 2; k++) {
            memset(w.b[k].u, 0, (size_t)(2 * w.b[k].mesh->n_nodes) * sizeof *w.b[k].u);
            w.b[k].dirty = 0;
        }
        w.n_go = 0;
        if (w.nf) {
            e = gsi_stiff_nf_offsets(&w);
            if (e != GS_OK)
                goto done;
        }
        /* No-load closing rotation: rigid bodies turned until the first row
         * closes, the rows re-evaluated at each new angle (with backlash the
         * linearisation at the kinematic angle alone is too crude). */
        int nr;
        double delta0 = 0.0, delta_ref = 0.0;
        if (w.b[0].xy_ref || w.b[1].xy_ref) {
            /* The perfect gears' no-load closing: the reference of the loaded
             * TE with modifications (their geometric TE included). */
            double *keep[2];
            for (int k = 0; k < 2; k++) {
                keep[k] = w.b[k].mesh->xy;
                if (w.b[k].xy_ref)
                    w.b[k].mesh->xy = w.b[k].xy_ref;
            }
            e = close_rigid(&w, &delta_ref, roll, sm->name, d);
            for (int k = 0; k < 2; k++)
                w.b[k].mesh->xy = keep[k];
            if (e != GS_OK)
                goto done;
        }
        e = close_rigid(&w, &delta0, roll, sm->name, d);
        if (e != GS_OK)
            goto done;
        if (!w.b[0].xy_ref && !w.b[1].xy_ref)
            delta_ref = delta0;
        double delta = delta0;
        int iters = 0, conv = 0;
        double pen = 0.0;
        e = gsi_stiff_solve_load(&w, T, o.max_iter, delta0, &delta, &nr, &iters, &conv, &pen, d);
        if (e != GS_OK)
            goto done;
        pt->delta_rad = delta;
        pt->te_raw_um = w.rb * w.sgn * delta * 1e6;
        pt->te0_um = w.rb * w.sgn * delta0 * 1e6;
        pt->te_elastic_um = pt->te_raw_um - pt->te0_um;
        pt->te_ref_um = w.rb * w.sgn * delta_ref * 1e6;
        pt->te_loaded_um = pt->te_raw_um - pt->te_ref_um;
        pt->k = F / pt->te_elastic_um / bmm;
        pt->rows = nr;
        pt->active = 0;
        for (int i = 0; i < nr; i++)
            pt->active += w.x[i] > 0.0;
        pt->iterations = iters;
        pt->converged = conv;
        pt->penetration_um = pen * 1e6;
        gsi_stiff_pairs_of(&w, nr, F, pt);
        for (int k = 0; k < 2 && uT[k]; k++)
            memcpy(uT[k], w.b[k].u, (size_t)(2 * w.b[k].mesh->n_nodes) * sizeof *uT[k]);
        pt->te_half_um = NAN;
        pt->k_tan = NAN;
        if (o.tangent && o.tangent_step > 0.0) {
            /* Central difference about T, each load started from the
             * solution at T. */
            double hs = o.tangent_step, dd[2];
            for (int q = 0; q < 2; q++) {
                int ih, ch;
                double ph;
                for (int k = 0; k < 2; k++)
                    memcpy(w.b[k].u, uT[k], (size_t)(2 * w.b[k].mesh->n_nodes) * sizeof *w.b[k].u);
                dd[q] = delta;
                e = gsi_stiff_solve_load(&w, (q ? 1.0 - hs : 1.0 + hs) * T, o.max_iter, delta0, &dd[q], &nr, &ih, &ch,
                                         &ph, d);
                if (e != GS_OK)
                    goto done;
                pt->converged = pt->converged && ch;
            }
            pt->k_tan = 2.0 * hs * F / (w.rb * w.sgn * (dd[0] - dd[1]) * 1e6) / bmm;
        } else if (o.tangent) {
            double dh = delta;
            int ih, ch;
            double ph;
            e = gsi_stiff_solve_load(&w, 0.5 * T, o.max_iter, delta0, &dh, &nr, &ih, &ch, &ph, d);
            if (e != GS_OK)
                goto done;
            pt->te_half_um = w.rb * w.sgn * dh * 1e6;
            pt->k_tan = 0.5 * F / (pt->te_raw_um - pt->te_half_um) / bmm;
            pt->converged = pt->converged && ch;
        }
    }
done:
#undef w
    return e;
}

gs_err gs_stiffness_next(gs_stiffness_run *r, gs_diag *d)
{
    if (!r || r->next >= r->o.positions)
        return gs_diag_set(d, GS_EINVAL, "", "no roll position left to solve");
    gs_err e;
    /* A displacement zone that grew mid-position (gsi_stiff_zone_cover): again, with
     * the larger zone (they only grow: at most once per tooth). */
    for (;;) {
        r->w.restart = 0;
        e = solve_position(r, d);
        if (!(e == GS_EINTERNAL && r->w.restart))
            break;
        r->w.zone_restarts++;
    }
    if (e == GS_OK)
        r->next++;
    else if (d && !d->message[0])
        gs_diag_set(d, e, "meshes", "stiffness analysis failed: %s", gs_strerror(e));
    return e;
}

/* The summary of the points: ranges and means of k and TE. */
static void summarise(gs_stiffness_result *out, int tangent)
{
    const int np = out->positions;
    out->k_min = out->te_min = out->te_loaded_min = INFINITY;
    out->k_max = out->te_max = out->te_loaded_max = -INFINITY;
    double ks = 0, ts = 0, kt = 0, tl = 0;
    int multi = 0;
    for (int j = 0; j < np; j++) {
        const gs_stiffness_point *pt = &out->pt[j];
        out->k_min = fmin(out->k_min, pt->k);
        out->k_max = fmax(out->k_max, pt->k);
        out->te_min = fmin(out->te_min, pt->te_elastic_um);
        out->te_max = fmax(out->te_max, pt->te_elastic_um);
        out->te_loaded_min = fmin(out->te_loaded_min, pt->te_loaded_um);
        out->te_loaded_max = fmax(out->te_loaded_max, pt->te_loaded_um);
        tl += pt->te_loaded_um;
        ks += pt->k;
        ts += pt->te_elastic_um;
        kt += pt->k_tan;
        multi += pt->pairs >= 2;
    }
    out->k_mean = ks / np;
    out->te_mean = ts / np;
    out->te_loaded_mean = tl / np;
    out->k_tan_mean = tangent ? kt / np : NAN;
    out->frac_multi = (double)multi / np;
}

gs_err gs_stiffness_end(gs_stiffness_run **run, gs_stiffness_result *out, gs_diag *d)
{
    gs_stiffness_run *r = run ? *run : NULL;
    if (!r || !out || r->next < r->o.positions)
        return gs_diag_set(d, GS_EINVAL, "", "the analysis has roll positions left");
    work *wp = &r->w;
#define w (*wp)
    const gs_stiffness_opts o = r->o;
    *out = r->out;
    memset(&r->out, 0, sizeof r->out);
    summarise(out, o.tangent);
    out->modified = w.b[0].xy_ref || w.b[1].xy_ref;
    out->solves = gs_fe_static_solves(w.b[0].fs) + gs_fe_static_solves(w.b[1].fs);
    out->seconds = gs_now() - r->t_start;
    out->cpu_seconds = gs_cpu_now() - r->cpu_start;
    out->columns = 0;
    out->window_widened = w.win_widened;
    out->zone_restarts = w.zone_restarts;
    {
        double fw = 0.0;
        long nb = 0;
        for (int k = 0; k < 2; k++) {
            fw += w.b[k].backw;
            nb += w.b[k].nback;
        }
        out->zone_fraction = nb > 0 ? fw / (double)nb : 1.0;
    }
    out->cpu_mesh = out->cpu_factor = out->cpu_columns = out->cpu_solves = 0.0;
    for (int k = 0; k < 2; k++) {
        out->columns += w.b[k].columns;
        out->cpu_mesh += w.b[k].t_mesh;
        out->cpu_factor += w.b[k].t_factor;
        out->cpu_columns += w.b[k].t_columns;
        out->cpu_solves += w.b[k].t_solves;
    }
    out->cpu_contact = out->cpu_seconds - out->cpu_mesh - out->cpu_factor - out->cpu_columns -
                       out->cpu_solves;
    if (r->slice) {
        gs_err e = gsi_stiff_slices(r->sc, r->sm, &o, out, d);
        if (e != GS_OK) {
            gs_stiffness_result_clear(out);
            gs_stiffness_run_free(run);
            return e;
        }
        summarise(out, o.tangent);
        out->cpu_seconds = gs_cpu_now() - r->cpu_start;
        out->seconds = gs_now() - r->t_start;
        out->cpu_contact = out->cpu_seconds - out->cpu_mesh - out->cpu_factor - out->cpu_columns -
                           out->cpu_solves;
    }
#undef w
    gs_stiffness_run_free(run);
    return GS_OK;
}

gs_err gs_stiffness_analyse(const gs_scene *sc, int mesh_index, const gs_stiffness_opts *opt,
                            gs_stiffness_result *out, gs_diag *d)
{
    if (!sc || !out)
        return gs_diag_set(d, GS_EINVAL, "", "NULL scene or result");
    memset(out, 0, sizeof *out);
    gs_stiffness_run *r;
    GS_TRY(gs_stiffness_begin(sc, mesh_index, opt, &r, d));
    gs_err e = GS_OK;
    while (e == GS_OK && gs_stiffness_run_done(r) < gs_stiffness_run_positions(r))
        e = gs_stiffness_next(r, d);
    if (e == GS_OK)
        return gs_stiffness_end(&r, out, d);
    gs_stiffness_run_free(&r);
    return e;
}
