/* SPDX-License-Identifier: MIT
 * Building the system from a scene: joint coordinates (METHOD.md section 1),
 * body ownership over ranks, mesh kinematics along the lines of action,
 * loads, and the energy bookkeeping. */
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/step.h"
#include "gearsim/modification.h"
#include "gearsim/util.h"
#include "step_internal.h"

void gs_system_free(gs_system **ps)
{
    if (!ps || !*ps)
        return;
    gs_system *s = *ps;
    for (int i = 0; s->bodies && i < s->n_bodies; i++) {
        if (s->bodies[i].ops)
            s->bodies[i].ops->destroy(&s->bodies[i]);
        gs_mesh_free(&s->bodies[i].mesh); /* not taken: init failed before */
    }
    for (int i = 0; s->meshes && i < s->n_meshes; i++) {
        if (s->meshes[i].ops && s->meshes[i].ops->destroy)
            s->meshes[i].ops->destroy(&s->meshes[i]);
        free(s->meshes[i].a);
        free(s->meshes[i].c);
        free(s->meshes[i].k_table);
        free(s->meshes[i].d0_table);
        free(s->meshes[i].abar);
    }
    free(s->joints);
    gsi_contact_free(s);
    gsi_plan_free(&s->plan, s->n_bodies);
    free(s->buf);
    free(s->rec_mask);
    free(s->rec_sel);
    free(s->rec_cbuf);
    free(s->bodies);
    free(s->meshes);
    free(s->eq_rows);
    free(s->q);
    free(s->w);
    free(s->work);
    gs_scene_free(&s->scene);
    free(s);
    *ps = NULL;
}

/* Work weight of a body for balancing ranks: an elastic gear costs about
 * in proportion to its unknowns (the free-motion solve scales with them:
 * the 30/20 pair's bare solves are 11.1 M and 8.8 M instructions for
 * 21 302 and 17 144 unknowns), counted on the mesh its model is built
 * from; a rigid body almost nothing. The element counts per tooth alone
 * miss the hub below the teeth (they put the 72-tooth ring of
 * planetary_contact at three planets, its unknowns are 1.7; its thin band
 * solves about as fast as a planet, 9.1 against 9.3 M instructions, so the
 * unknowns still overweigh it). */
static double body_weight(const gs_body_rt *br, const gs_scene_body *b)
{
    if (b->model == GS_MODEL_ELASTIC) {
        if (br->mesh)
            return 2.0 * (double)br->mesh->n_nodes;
        /* no mesh: the body's init reports why; any weight will do */
        const gs_mesh_density *m = &b->mesh;
        double per_tooth = (double)m->flank * m->across + (double)m->rim * (m->across + m->flank);
        return 1.0 + b->gear.teeth * per_tooth * (double)(1 << (2 * m->refine));
    }
    return b->joint == GS_JOINT_HELD ? 0.1 : 1.0;
}

/* Longest processing time first: bodies by decreasing weight (ties by
 * index), each to the least loaded bin (ties: the lowest). Then the bins go
 * to ranks by increasing load (ties: the lower bin), so that rank 0, which
 * alone selects the contact rows and solves the QP, holds the lightest share
 * of the bodies (docs/performance/index.md). Deterministic: the same
 * scene and rank count give the same map. */
static void assign_owners(gs_system *s)
{
    double load[1024] = {0}, weight[64];
    int rank_of[1024];
    int nr = s->nranks > 1024 ? 1024 : s->nranks;
    int order[64];
    int n = s->n_bodies < 64 ? s->n_bodies : 64;
    for (int i = 0; i < n; i++) {
        order[i] = i;
        weight[i] = body_weight(&s->bodies[i], &s->scene->bodies[i]);
    }
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && weight[order[j]] > weight[order[j - 1]]; j--) {
            int t = order[j];
            order[j] = order[j - 1];
            order[j - 1] = t;
        }
    for (int k = 0; k < n; k++) {
        int i = order[k], best = 0;
        for (int r = 1; r < nr; r++)
            if (load[r] < load[best])
                best = r;
        s->bodies[i].owner = best;
        load[best] += weight[i];
    }
    for (int r = 0; r < nr; r++) { /* bin r's place among the bins by load */
        rank_of[r] = 0;
        for (int q = 0; q < nr; q++)
            rank_of[r] += load[q] < load[r] || (load[q] == load[r] && q < r);
    }
    for (int k = 0; k < n; k++)
        s->bodies[order[k]].owner = rank_of[s->bodies[order[k]].owner];
}

/* A planet on a pin bearing: its pin's offset from the carrier's nominal
 * centre at carrier angle 0 (pin0) and at the carrier's initial angle (off),
 * where the planet's centre starts. */
static void pin_offsets(const gs_system *s, int planet, double pin0[2], double off[2])
{
    const gs_scene_body *b = &s->scene->bodies[planet];
    pin0[0] = b->carrier_radius * cos(b->carrier_angle);
    pin0[1] = b->carrier_radius * sin(b->carrier_angle);
    int kc = s->bodies[b->carrier].coord;
    double t = kc >= 0 ? s->scene->bodies[b->carrier].angle0 : 0.0, c = cos(t), sn = sin(t);
    off[0] = c * pin0[0] - sn * pin0[1];
    off[1] = sn * pin0[0] + c * pin0[1];
}

/* Line-of-action displacement of a mesh, measured in the frame of the carrier
 * that one of its gears rides on (or the housing): s = sum_k sigma_k r_bk
 * (theta_k - theta_C), sigma = +1 for an external gear, -1 for a ring. It is
 * exact for involute gears on fixed axes in that frame. */
static gs_err mesh_kinematics(gs_system *s, gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene *sc = s->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    int n = s->n_coords;
    m->a = gs_calloc((size_t)n, sizeof(double));
    m->c = gs_calloc((size_t)n, sizeof(double));
    if (!m->a || !m->c)
        return GS_ENOMEM;
    int carrier = -1;
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *g = &sc->bodies[sm->gear[k]];
        if (g->joint == GS_JOINT_ON_CARRIER)
            carrier = g->carrier;
    }
    int cc = carrier >= 0 ? s->bodies[carrier].coord : -1;
    int pinion = sc->bodies[sm->gear[0]].gear.kind == GS_GEAR_INTERNAL ? 1 : 0;
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *g = &sc->bodies[sm->gear[k]];
        double sigma = g->gear.kind == GS_GEAR_INTERNAL ? -1.0 : 1.0;
        double rb = gs_gear_base_radius(&g->gear);
        int ck = s->bodies[sm->gear[k]].coord;
        if (ck >= 0)
            m->a[ck] += sigma * rb;
        if (cc >= 0)
            m->a[cc] -= sigma * rb;
        if (k == pinion) {
            double z = g->gear.teeth / (2 * GS_PI);
            if (ck >= 0)
                m->c[ck] += z;
            if (cc >= 0)
                m->c[cc] -= z;
        }
    }
    double c0[2], c1[2];
    gs_scene_body_centre(sc, sm->gear[0], c0);
    gs_scene_body_centre(sc, sm->gear[1], c1);
    double alpha_w;
    {
        gs_pair_info pi;
        GS_TRY(gs_pair_analyse(&sc->bodies[sm->gear[0]].gear, &sc->bodies[sm->gear[1]].gear,
                               hypot(c1[0] - c0[0], c1[1] - c0[1]), &pi, d));
        m->contact_ratio = pi.contact_ratio;
        m->overlap_ratio = pi.overlap_ratio;
        alpha_w = pi.alpha_w;
    }
    /* Translations along the true line of action (gearsim/modal.h): the
     * line through the pitch point at the operating pressure angle, on the
     * flanks that a counter-clockwise moment on an external gear A (or a
     * clockwise one on the pinion of a ring) loads; s grows with
     * n . (X_A - X_B) (external) and n . (X_P - X_R) (internal). */
    m->tr_carrier = -1;
    {
        int A = sm->gear[0], B = sm->gear[1];
        bool internal = sc->bodies[A].gear.kind == GS_GEAR_INTERNAL || sc->bodies[B].gear.kind == GS_GEAR_INTERNAL;
        int R = A, P = B;
        if (internal && sc->bodies[B].gear.kind == GS_GEAR_INTERNAL)
            R = B, P = A;
        int first = internal ? R : A, second = internal ? P : B;
        double p0[2], p1[2];
        gs_scene_body_centre(sc, first, p0);
        gs_scene_body_centre(sc, second, p1);
        double u[2] = {p1[0] - p0[0], p1[1] - p0[1]}, dist = hypot(u[0], u[1]);
        u[0] /= dist, u[1] /= dist;
        double sa = sin(alpha_w), ca = cos(alpha_w);
        double nv[2] = {(internal ? -sa : sa) * u[0] - ca * u[1], (internal ? -sa : sa) * u[1] + ca * u[0]};
        /* external: s += n.(X_A - X_B); internal: s += -n.(X_R - X_P) */
        int body[2] = {first, second};
        double sign[2] = {internal ? -1.0 : 1.0, internal ? 1.0 : -1.0};
        for (int k = 0; k < 2; k++) {
            /* A planet's pin error in a lumped or compliant mesh: its centre stands off the
             * tight-mesh position by e, a deflection sign n . e at the start
             * (positive: pressed in, negative: a gap). */
            const gs_scene_body *pb = &sc->bodies[body[k]];
            if ((sm->model == GS_MESH_LUMPED || sm->model == GS_MESH_COMPLIANT || sm->model == GS_MESH_LTCA) &&
                pb->joint == GS_JOINT_ON_CARRIER &&
                (pb->pin_error[0] != 0 || pb->pin_error[1] != 0)) {
                double r = pb->carrier_radius, a = pb->carrier_angle;
                double r0 = r - pb->pin_error[0], a0 = a - pb->pin_error[1] / r;
                double ex = r * cos(a) - r0 * cos(a0), ey = r * sin(a) - r0 * sin(a0);
                m->s_pin += sign[k] * (nv[0] * ex + nv[1] * ey);
            }
            int tc = s->bodies[body[k]].tcoord;
            if (tc < 0)
                continue;
            if (cc < 0) { /* a fixed line: linear in the translations */
                m->a[tc] += sign[k] * nv[0];
                m->a[tc + 1] += sign[k] * nv[1];
                continue;
            }
            m->tr_coord[m->n_tr] = tc;
            m->tr_n0[m->n_tr][0] = sign[k] * nv[0];
            m->tr_n0[m->n_tr][1] = sign[k] * nv[1];
            if (pb->joint == GS_JOINT_ON_CARRIER) { /* a planet on its pin bearing (gearsim/step.h) */
                double pin0[2], off[2];
                pin_offsets(s, body[k], pin0, off);
                m->tr_off[m->n_tr][0] = off[0];
                m->tr_off[m->n_tr][1] = off[1];
                m->tr_c[m->n_tr] = m->tr_n0[m->n_tr][0] * pin0[0] + m->tr_n0[m->n_tr][1] * pin0[1];
            }
            m->n_tr++;
        }
        /* Tooth errors of a lumped mesh (pitch table, run-out): a known
         * displacement along the line of action, a function of each gear's
         * angle in the carrier frame (mesh_common.c, gsi_mesh_s). */
        for (int k = 0; (sm->model == GS_MESH_LUMPED || sm->model == GS_MESH_LTCA) && k < 2; k++) {
            const gs_scene_body *gb = &sc->bodies[body[k]];
            const gs_gear_mods *md = gb->mods;
            if (!md || (md->n_pitch != gb->gear.teeth && md->runout_m == 0.0))
                continue;
            double pk[2], po[2];
            gs_scene_body_centre(sc, body[k], pk);
            gs_scene_body_centre(sc, body[1 - k], po);
            int e = m->n_err++;
            m->err[e].coord = s->bodies[body[k]].coord;
            m->err[e].carrier = cc;
            m->err[e].z = gb->gear.teeth;
            m->err[e].beta = atan2(po[1] - pk[1], po[0] - pk[0]);
            m->err[e].kp = (gb->gear.kind == GS_GEAR_INTERNAL ? -1.0 : 1.0) * gs_gear_base_radius(&gb->gear) /
                           gs_gear_pitch_radius(&gb->gear);
            m->err[e].pitch = md->n_pitch == gb->gear.teeth ? md->pitch_m : NULL;
            m->err[e].runout = md->runout_m;
            m->err[e].phase = md->runout_phase;
            m->err[e].n[0] = sign[k] * nv[0];
            m->err[e].n[1] = sign[k] * nv[1];
        }
        bool translates = false;
        for (int k = 0; k < 2; k++)
            translates |= s->bodies[body[k]].tcoord >= 0;
        bool has_tr = sm->model == GS_MESH_LUMPED || sm->model == GS_MESH_COMPLIANT ||
                      sm->model == GS_MESH_LTCA || sm->model == GS_MESH_CONTACT ||
                      sm->model == GS_MESH_IMPACT; /* s with translations */
        if (translates && (sm->model == GS_MESH_KINEMATIC ? m->n_tr > 0 : !has_tr)) {
            char f[64];
            snprintf(f, sizeof f, "meshes[%d].model", m->index);
            return gs_diag_set(d, GS_ERANGE, f,
                               "mesh '%s': a gear on a bearing (joint or planet pin) meshes through kinematic "
                               "meshes on a fixed line only (not with a planet on a turning carrier); use a "
                               "lumped, compliant, ltca, contact or impact mesh", sm->name);
        }
        if (m->n_tr || m->n_err) {
            if (m->n_tr)
                m->tr_carrier = cc;
            m->abar = gs_calloc((size_t)n, sizeof(double));
            if (!m->abar)
                return GS_ENOMEM;
        }
    }
    bool moves = false;
    for (int i = 0; i < n; i++)
        moves |= m->a[i] != 0.0;
    if (!moves) {
        char f[64];
        snprintf(f, sizeof f, "meshes[%d]", m->index);
        return gs_diag_set(d, GS_ERANGE, f, "mesh '%s' connects bodies that cannot move", sm->name);
    }
    return GS_OK;
}

/* Make the initial speeds satisfy the kinematic rows: the M-orthogonal
 * projection w - M^-1 G^T (G M^-1 G^T)^-1 G w, the nearest consistent state
 * in kinetic energy. */
static gs_err project_speeds(gs_system *s)
{
    int n = s->n_coords, m = s->n_eq;
    if (m == 0)
        return GS_OK;
    double *minv = gs_calloc((size_t)n, sizeof(double));
    double *S = gs_calloc((size_t)(m * m), sizeof(double));
    double *r = gs_calloc((size_t)m, sizeof(double));
    if (!minv || !S || !r) {
        free(minv), free(S), free(r);
        return GS_ENOMEM;
    }
    for (int i = 0; i < s->n_bodies; i++)
        if (s->bodies[i].coord >= 0)
            minv[s->bodies[i].coord] = 1.0 / s->bodies[i].inertia_eff;
    double gw = 0, wn = 0;
    for (int a = 0; a < m; a++) {
        const double *ga = s->eq_rows + (size_t)a * n;
        for (int b = 0; b < m; b++) {
            const double *gb = s->eq_rows + (size_t)b * n;
            double v = 0;
            for (int i = 0; i < n; i++)
                v += ga[i] * minv[i] * gb[i];
            S[a * m + b] = v;
        }
        for (int i = 0; i < n; i++)
            r[a] += ga[i] * s->w[i];
        gw = fmax(gw, fabs(r[a]));
    }
    for (int i = 0; i < n; i++)
        wn = fmax(wn, fabs(s->w[i]));
    gs_err e = GS_OK;
    if (gw > 0) {
        /* Redundant rows (a closed loop of kinematic meshes) make S singular:
         * least squares via dgelsd-free path: use the pseudo-inverse by SVD-less
         * regularisation is not exact, so refuse such trains clearly. */
        if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'U', m, 1, S, m, r, 1) != 0) {
            e = GS_ESINGULAR;
        } else {
            for (int i = 0; i < n; i++) {
                double v = 0;
                for (int a = 0; a < m; a++)
                    v += s->eq_rows[(size_t)a * n + i] * r[a];
                s->w[i] -= minv[i] * v;
            }
            if (gw > 1e-12 * (wn > 0 ? wn : 1))
                snprintf(s->warning, sizeof s->warning,
                         "initial speeds did not satisfy the kinematic meshes and were projected onto them");
        }
    }
    free(minv), free(S), free(r);
    return e;
}

/* Gears in contact meshes whose initial angle the scene does not give are
 * turned into mesh with their partners (backlash shared equally between the
 * flanks, gs_pair_mesh_phase): from gears whose angle is given or that are
 * held, along the meshes, in scene order; a group with no such gear starts
 * from its first gear at angle 0. Without this every tooth 0 points along +x
 * and a pair on the x axis would start tooth on tooth. */
static void phase_contact_gears(gs_system *s)
{
    const gs_scene *sc = s->scene;
    bool placed[64] = {false}, in_contact[64] = {false};
    for (int i = 0; i < sc->n_meshes; i++)
        if (sc->meshes[i].model == GS_MESH_CONTACT)
            in_contact[sc->meshes[i].gear[0]] = in_contact[sc->meshes[i].gear[1]] = true;
    for (int i = 0; i < s->n_bodies && i < 64; i++)
        placed[i] = !in_contact[i] || sc->bodies[i].angle_given || s->bodies[i].coord < 0;
    for (;;) {
        bool changed = true;
        while (changed) {
            changed = false;
            for (int i = 0; i < sc->n_meshes; i++) {
                const gs_scene_mesh *m = &sc->meshes[i];
                if (m->model != GS_MESH_CONTACT || placed[m->gear[0]] == placed[m->gear[1]])
                    continue;
                int from = placed[m->gear[0]] ? m->gear[0] : m->gear[1];
                int to = from == m->gear[0] ? m->gear[1] : m->gear[0];
                double cf[2], ct[2], tf, tt;
                gs_system_body_pose(s, from, cf, &tf);
                gs_system_body_pose(s, to, ct, &tt);
                double a = gs_pair_mesh_phase(&sc->bodies[from].gear, cf, tf, &sc->bodies[to].gear, ct, tt);
                s->q[s->bodies[to].coord] = a;
                s->scene->bodies[to].angle0 = a;
                placed[to] = true;
                changed = true;
            }
        }
        int seed = -1;
        for (int i = 0; i < s->n_bodies && i < 64 && seed < 0; i++)
            if (!placed[i])
                seed = i;
        if (seed < 0)
            return;
        placed[seed] = true; /* its scene angle (0) */
    }
}

gs_err gs_system_new(gs_scene *scene, int rank, int nranks, gs_system **out, gs_diag *d)
{
    *out = NULL;
    gs_system *s = gs_calloc(1, sizeof *s);
    if (!s) {
        gs_scene_free(&scene);
        return GS_ENOMEM;
    }
    for (int i = 0; i < scene->n_bodies; i++) {
        const gs_scene_body *sb = &scene->bodies[i];
        const char *why = NULL;
        for (int j = 0; !why && sb->joint == GS_JOINT_BEARING && j < scene->n_bodies; j++)
            if (scene->bodies[j].joint == GS_JOINT_ON_CARRIER && scene->bodies[j].carrier == i &&
                !scene->bodies[j].pin_bearing)
                why = "a carrier on a bearing joint needs its planets on pin bearings (bearing_stiffness "
                      "on each planet's on_carrier joint; rigid pins would carry the carrier's translation: "
                      "modal analysis only)";
        if (why) {
            gs_diag_set(d, GS_ERANGE, "joints", "body '%s': %s (docs/explanation/modal.md)", sb->name, why);
            gs_scene_free(&scene);
            free(s);
            return GS_ERANGE;
        }
    }
    s->scene = scene;
    s->rank = rank;
    s->nranks = nranks < 1 ? 1 : nranks;
    s->n_bodies = scene->n_bodies;
    s->n_meshes = scene->n_meshes;
    s->h = scene->time_step;
    s->h_sub = s->h;
    s->max_newton = scene->max_newton;
    s->newton_tol = scene->newton_tol;
    s->contact_scheme = scene->contact_scheme;
    s->adapt_levels = scene->adapt_levels;
    s->adapt_penetration = scene->adapt_penetration;
    gs_err e = GS_ENOMEM;
    s->bodies = gs_calloc((size_t)s->n_bodies, sizeof *s->bodies);
    s->meshes = gs_calloc((size_t)(s->n_meshes ? s->n_meshes : 1), sizeof *s->meshes);
    if (!s->bodies || !s->meshes)
        goto fail;
    for (int i = 0; i < s->n_bodies; i++) {
        gs_body_rt *b = &s->bodies[i];
        const gs_scene_body *sb = &scene->bodies[i];
        b->index = i;
        b->coord = sb->joint == GS_JOINT_HELD ? -1 : s->n_coords++;
        b->inertia_eff = sb->inertia;
        b->mass = sb->mass;
        gs_scene_body_centre(scene, i, b->centre);
        b->carrier = sb->joint == GS_JOINT_ON_CARRIER ? sb->carrier : -1;
        b->carrier_radius = sb->carrier_radius;
        b->carrier_angle = sb->carrier_angle;
        if (sb->type == GS_BODY_CARRIER)
            for (int j = 0; j < s->n_bodies; j++) {
                const gs_scene_body *p = &scene->bodies[j];
                if (p->joint == GS_JOINT_ON_CARRIER && p->carrier == i && !p->pin_bearing)
                    b->inertia_eff += p->mass * p->carrier_radius * p->carrier_radius;
            }
        const char *model = sb->model == GS_MODEL_ELASTIC ? "elastic" : "rigid";
        b->ops = gs_body_ops_find(model);
        if (!b->ops) {
            char f[64];
            snprintf(f, sizeof f, "bodies[%d].model", i);
            e = gs_diag_set(d, GS_ERANGE, f, "body model '%s' is not available in this build", model);
            b->ops = NULL;
            goto fail;
        }
    }
    /* Centre displacements of bodies on bearing joints and of planets on pin
     * bearings (inertial, from the initial centre): two more coordinates
     * each, after every rotation; and their supports. */
    for (int i = 0; i < s->n_bodies; i++) {
        s->bodies[i].tcoord = -1;
        if (scene->bodies[i].joint == GS_JOINT_BEARING || scene->bodies[i].pin_bearing) {
            s->bodies[i].tcoord = s->n_coords;
            s->n_coords += 2;
            s->n_joints++;
        }
    }
    if (s->n_joints) {
        s->joints = gs_calloc((size_t)s->n_joints, sizeof *s->joints);
        if (!s->joints) {
            e = GS_ENOMEM;
            goto fail;
        }
        for (int i = 0, k = 0; i < s->n_bodies; i++) {
            const gs_scene_body *sb = &scene->bodies[i];
            if (s->bodies[i].tcoord < 0)
                continue;
            gs_joint_rt *j = &s->joints[k++];
            j->body = i;
            j->coord[0] = s->bodies[i].tcoord;
            j->coord[1] = s->bodies[i].tcoord + 1;
            j->carrier = j->carrier_t = -1;
            if (sb->pin_bearing) { /* the planet's radial bearing on its carrier pin */
                j->ops = gs_joint_ops_find("pin_bearing");
                j->coord[2] = -1;
                j->carrier = s->bodies[sb->carrier].coord;
                j->carrier_t = s->bodies[sb->carrier].tcoord;
                pin_offsets(s, i, j->pin0, j->d0);
                s->bodies[i].pin_off[0] = j->d0[0];
                s->bodies[i].pin_off[1] = j->d0[1];
                j->k[0] = j->k[1] = sb->bearing_k;
                j->c[0] = j->c[1] = sb->bearing_c;
                continue;
            }
            j->ops = gs_joint_ops_find("bearing");
            j->coord[2] = s->bodies[i].coord;
            j->k[0] = j->k[1] = sb->bearing_k;
            j->c[0] = j->c[1] = sb->bearing_c;
            j->k[2] = sb->torsion_k;
            j->c[2] = sb->torsion_c;
            j->q_ref[2] = sb->angle0;
        }
    }
    /* Every rank meshes every elastic gear (the contact search needs them
     * all): once, here, for the owner map's weights; the model takes it. */
    for (int i = 0; i < s->n_bodies; i++)
        if (scene->bodies[i].model == GS_MODEL_ELASTIC && scene->bodies[i].type == GS_BODY_GEAR) {
            gs_diag md;
            if (gs_scene_gear_mesh(&scene->bodies[i], &s->bodies[i].mesh, &md) != GS_OK)
                s->bodies[i].mesh = NULL; /* the model's init meshes again and says why */
        }
    assign_owners(s);
    e = gsi_plan_new(s);
    if (e != GS_OK)
        goto fail;
    for (int i = 0; i < s->n_bodies; i++) {
        gs_model_view v;
        gs_system_view(s, &v);
        e = s->bodies[i].ops->init(&v, &s->bodies[i], d);
        if (e != GS_OK) {
            for (int j = i; j < s->n_bodies; j++)
                s->bodies[j].ops = NULL;
            goto fail;
        }
    }
    e = GS_ENOMEM;
    int n = s->n_coords;
    s->q = gs_calloc((size_t)(n ? n : 1), sizeof(double));
    s->w = gs_calloc((size_t)(n ? n : 1), sizeof(double));
    if (!s->q || !s->w)
        goto fail;
    for (int i = 0; i < s->n_bodies; i++)
        if (s->bodies[i].coord >= 0) {
            s->q[s->bodies[i].coord] = scene->bodies[i].angle0;
            s->w[s->bodies[i].coord] = scene->bodies[i].omega0;
        }
    phase_contact_gears(s);
    for (int i = 0; i < s->n_meshes; i++) {
        gs_gmesh_rt *m = &s->meshes[i];
        m->index = i;
        static const char *const names[] = {"kinematic", "lumped", "contact", "impact", "compliant", "ltca"};
        m->ops = gs_gmesh_ops_find(names[scene->meshes[i].model]);
        e = mesh_kinematics(s, m, d);
        if (e != GS_OK)
            goto fail;
        /* the translations' terms too (zero at the start but for round-off
         * with planets on pin bearings); tooth errors stay out of s_ref */
        gs_model_view v;
        gs_system_view(s, &v);
        double sref = gs_gmesh_s(&v, m, s->q) - gs_gmesh_error(m, s->q);
        m->s_ref = sref - m->s_pin;
        s->smooth_contact |= s->n_joints > 0 || m->s_pin != 0.0;
        v.smooth_contact = s->smooth_contact;
        e = m->ops->init(&v, m, d);
        if (e != GS_OK)
            goto fail;
        s->n_eq += m->ops->n_eq;
        s->n_contact += m->ops->contact;
    }
    /* Impact meshes change velocities after the step (velocity jumps of
     * rigid gears); the contact step has no place for them yet. */
    for (int i = 0; s->n_contact && i < s->n_meshes; i++)
        if (s->meshes[i].ops->after_step) {
            char f[64];
            snprintf(f, sizeof f, "meshes[%d].model", i);
            e = gs_diag_set(d, GS_ERANGE, f,
                            "mesh '%s': %s meshes cannot be combined with contact meshes in one scene "
                            "(use lumped or compliant meshes beside contact ones)",
                            scene->meshes[i].name, s->meshes[i].ops->name);
            goto fail;
        }
    e = GS_ENOMEM;
    s->eq_rows = gs_calloc((size_t)(s->n_eq * n + 1), sizeof(double));
    if (!s->eq_rows)
        goto fail;
    for (int i = 0, r = 0; i < s->n_meshes; i++)
        if (s->meshes[i].ops->n_eq == 1)
            memcpy(s->eq_rows + (size_t)(r++) * n, s->meshes[i].a, (size_t)n * sizeof(double));
    int kk = n + s->n_eq;
    s->work = gs_calloc((size_t)(kk * kk + 10 * kk + n * n + 16), sizeof(double));
    if (!s->work)
        goto fail;
    e = project_speeds(s);
    if (e != GS_OK) {
        gs_diag_set(d, e, "meshes", "the kinematic meshes over-constrain the train (a closed loop of exact ratios)");
        goto fail;
    }
    /* The scene's numerics against the initial state: refuse a time step
     * that cannot resolve it before anything runs. */
    e = gs_system_check(s, d);
    if (e != GS_OK)
        goto fail;
    /* A first plan, so that sizes are known before the first step. */
    e = gs_step_prepare(s);
    if (e != GS_OK) {
        gs_diag_set(d, e, "meshes", "the contact search failed on the initial state");
        goto fail;
    }
    gs_energy en;
    gs_system_energy(s, &en);
    s->energy0 = en.total;
    *out = s;
    return GS_OK;
fail:
    gs_system_free(&s);
    return e;
}

/* Module of a mesh's gears (the smaller, should they differ), m. */
static double mesh_module(const gs_system *s, const gs_scene_mesh *sm)
{
    const gs_scene_body *b = s->scene->bodies;
    return fmin(b[sm->gear[0]].gear.module_m, b[sm->gear[1]].gear.module_m);
}

gs_err gs_system_check(const gs_system *s, gs_diag *d)
{
    gs_diag_clear(d);
    double h = s->h;
    long long step = (long long)s->step;
    for (int i = 0; i < s->n_bodies; i++) {
        int c = s->bodies[i].coord, tc = s->bodies[i].tcoord;
        if ((c >= 0 && !(isfinite(s->q[c]) && isfinite(s->w[c]))) ||
            (tc >= 0 && !(isfinite(s->q[tc]) && isfinite(s->q[tc + 1]) && isfinite(s->w[tc]) && isfinite(s->w[tc + 1]))))
            return gs_diag_set(d, GS_ERANGE, "numerics.time_step",
                               "the state of '%s' is no longer finite at step %lld (t = %.6g s): "
                               "the step diverged; reduce the time step (now %.3g s) or check the "
                               "scene's loads and stiffnesses", s->scene->bodies[i].name, step, s->time, h);
    }
    for (int i = 0; i < s->n_meshes; i++) {
        const gs_gmesh_rt *m = &s->meshes[i];
        const gs_scene_mesh *sm = &s->scene->meshes[i];
        char f[64];
        if (!isfinite(m->force) || !isfinite(m->penetration)) {
            snprintf(f, sizeof f, "meshes[%d]", i);
            return gs_diag_set(d, GS_ERANGE, f,
                               "the force of mesh '%s' is no longer finite at step %lld (t = %.6g s): "
                               "the step diverged; reduce numerics.time_step (now %.3g s)", sm->name, step,
                               s->time, h);
        }
        double v = 0, rate = 0;
        for (int j = 0; j < s->n_coords; j++) {
            v += m->a[j] * s->w[j];
            rate += m->c[j] * s->w[j];
        }
        v = fabs(v);
        rate = fabs(rate);
        if (m->ops->contact) {
            /* The search looks for approaching nodes within 0.1 module of
             * the mate (gs_contact_opts.band_m); penetration grows as the
             * approach speed times h. */
            double lim = 0.1 * mesh_module(s, sm);
            /* with numerics.adaptive, the finest substep it may take */
            double hc = s->h / (double)((int64_t)1 << s->adapt_levels);
            if (v * hc > lim)
                return gs_diag_set(d, GS_ERANGE, "numerics.time_step",
                                   "contact mesh '%s' (t = %.6g s): the gears approach at %.3g m/s, so a step of "
                                   "%.3g s takes the teeth %.3g m into each other, beyond the %.3g m (0.1 module) "
                                   "the contact resolves: reduce the time step below %.2g s or start the gears "
                                   "in the tooth ratio", sm->name, s->time, v, hc, v * hc, lim, 0.5 * lim / v);
            if (m->penetration > lim)
                return gs_diag_set(d, GS_ERANGE, "numerics.time_step",
                                   "contact mesh '%s' (step %lld, t = %.4g s): teeth %.3g m inside each other, beyond "
                                   "the %.3g m (0.1 module) the contact resolves: reduce the time step (now %.3g s) "
                                   "below %.2g s; if that does not help, the impact is too violent for the "
                                   "small-strain FE model", sm->name, step, s->time, m->penetration, lim, hc,
                                   0.5 * hc * lim / m->penetration);
        } else if (m->n_table > 0 || (strcmp(m->ops->name, "lumped") == 0 && m->k_single != m->k_double)) {
            /* A stiffness that varies over the mesh cycle: a step beyond half
             * a cycle samples the wave below its Nyquist rate. */
            if (rate * h > 0.5)
                return gs_diag_set(d, GS_ERANGE, "numerics.time_step",
                                   "lumped mesh '%s' (t = %.6g s): the teeth pass at %.4g Hz, so a step of %.3g s "
                                   "spans %.3g tooth-mesh cycles and skips the tooth stiffness wave: reduce the time step below %.2g s (half a cycle) or give the mesh a "
                                   "constant stiffness", sm->name, s->time, rate, h, rate * h, 0.5 / rate);
        }
    }
    return GS_OK;
}

void gs_system_body_load(const gs_system *sys, int b, double t, double *moment, double *brake)
{
    gs_model_loads(sys->scene->loads, sys->scene->n_loads, b, t, moment, brake);
}

gs_err gs_system_set_load(gs_system *sys, const gs_scene_load *l)
{
    gs_scene *sc = sys->scene;
    for (int i = 0; i < sc->n_loads; i++)
        if (!strcmp(sc->loads[i].name, l->name)) {
            gs_scene_load_clear(&sc->loads[i]);
            sc->loads[i] = *l;
            return GS_OK;
        }
    if (sc->n_loads >= 256)
        return GS_ETOOBIG;
    gs_scene_load *nl = realloc(sc->loads, (size_t)(sc->n_loads + 1) * sizeof *nl);
    if (!nl)
        return GS_ENOMEM;
    sc->loads = nl;
    sc->loads[sc->n_loads++] = *l;
    return GS_OK;
}

gs_err gs_system_remove_load(gs_system *sys, const char *name)
{
    gs_scene *sc = sys->scene;
    for (int i = 0; i < sc->n_loads; i++)
        if (!strcmp(sc->loads[i].name, name)) {
            gs_scene_load_clear(&sc->loads[i]);
            memmove(&sc->loads[i], &sc->loads[i + 1], (size_t)(sc->n_loads - i - 1) * sizeof *sc->loads);
            sc->n_loads--;
            return GS_OK;
        }
    return GS_ENOTFOUND;
}

bool gs_system_has_body_state(const gs_system *sys)
{
    for (int i = 0; i < sys->n_bodies; i++)
        if (sys->bodies[i].ops->state_size)
            return true;
    return false;
}

void gs_system_energy_report(const gs_system *sys, double *buf)
{
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        bool mine = b->ops->state_size && b->owner == sys->rank;
        double *o = buf + GS_ENERGY_REPORT * i;
        o[0] = mine ? b->T : 0.0;
        o[1] = mine ? b->V : 0.0;
        o[2] = mine ? b->work_s : 0.0;
        o[3] = mine ? b->D_step : 0.0;
        o[4] = mine ? b->L : 0.0;
    }
}

void gs_system_energy_adopt(gs_system *sys, const double *buf)
{
    for (int i = 0; i < sys->n_bodies; i++) {
        gs_body_rt *b = &sys->bodies[i];
        if (!b->ops->state_size)
            continue;
        const double *o = buf + GS_ENERGY_REPORT * i;
        b->T = o[0];
        b->V = o[1];
        b->work_s = o[2];
        b->D_step = o[3];
        b->L = o[4];
    }
}

void gs_system_book_damping(gs_system *sys)
{
    for (int i = 0; i < sys->n_bodies; i++) {
        sys->dissipated += sys->bodies[i].D_step;
        sys->bodies[i].D_step = 0.0;
    }
}

void gs_system_view(const gs_system *s, gs_model_view *v)
{
    v->scene = s->scene;
    v->rank = s->rank;
    v->n_coords = s->n_coords;
    v->n_bodies = s->n_bodies;
    v->n_meshes = s->n_meshes;
    v->bodies = s->bodies;
    v->meshes = s->meshes;
    v->n_eq = s->n_eq;
    v->eq_rows = s->eq_rows;
    v->q = s->q;
    v->w = s->w;
    v->time = s->time;
    v->h_sub = s->h_sub;
    v->smooth_contact = s->smooth_contact;
    v->energy_deferred = s->energy_deferred;
    v->momentum = s->contact_scheme == GS_CONTACT_CLOSURE_ENERGY;
    v->n_dof = s->plan.n_dof;
    v->n_nodes = s->plan.n_nodes;
    v->nodes = s->plan.nodes;
    v->loads = s->scene->loads;
    v->n_loads = s->scene->n_loads;
    v->n_joints = s->n_joints;
    v->joints = s->joints;
}

void gs_system_energy(const gs_system *sys, gs_energy *e)
{
    gs_model_view v;
    gs_system_view(sys, &v);
    double T = 0, V = 0, Ve = 0;
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (b->ops->state_size) {
            T += b->T;
            V += b->V;
            Ve += b->V;
            continue;
        }
        if (b->coord < 0)
            continue;
        double t, vb;
        b->ops->energy(&v, b, &t, &vb);
        T += t;
        V += vb;
    }
    for (int i = 0; i < sys->n_meshes; i++)
        V += sys->meshes[i].ops->energy(&v, &sys->meshes[i], sys->q);
    for (int i = 0; i < sys->n_bodies; i++) { /* translating centres */
        int tc = sys->bodies[i].tcoord;
        if (tc >= 0)
            T += 0.5 * sys->bodies[i].mass * (sys->w[tc] * sys->w[tc] + sys->w[tc + 1] * sys->w[tc + 1]);
    }
    for (int i = 0; i < sys->n_joints; i++)
        V += sys->joints[i].ops->energy(&v, &sys->joints[i], sys->q);
    e->kinetic = T;
    e->potential = V;
    e->elastic = Ve;
    e->total = T + V;
    e->work_in = sys->work_in;
    e->dissipated = sys->dissipated;
    e->contact_work = sys->contact_work;
    e->balance_residual = e->total - sys->energy0 - sys->work_in + sys->dissipated - sys->contact_work;
}

void gs_system_body_pose(const gs_system *sys, int body, double c[2], double *theta)
{
    const gs_body_rt *b = &sys->bodies[body];
    int tc = b->tcoord;
    if (b->carrier >= 0 && tc >= 0) {
        /* on a pin bearing: where it started plus its own displacement */
        const gs_body_rt *cb = &sys->bodies[b->carrier];
        c[0] = cb->centre[0] + b->pin_off[0] + sys->q[tc];
        c[1] = cb->centre[1] + b->pin_off[1] + sys->q[tc + 1];
    } else if (b->carrier >= 0) {
        /* The planet's polar position turns with the carrier. */
        const gs_body_rt *cb = &sys->bodies[b->carrier];
        int kc = cb->coord;
        double a = b->carrier_angle + (kc >= 0 ? sys->q[kc] : 0.0);
        c[0] = cb->centre[0] + b->carrier_radius * cos(a);
        c[1] = cb->centre[1] + b->carrier_radius * sin(a);
    } else {
        c[0] = b->centre[0];
        c[1] = b->centre[1];
        if (tc >= 0) {
            c[0] += sys->q[tc];
            c[1] += sys->q[tc + 1];
        }
    }
    int k = b->coord;
    *theta = k >= 0 ? sys->q[k] : 0.0;
}

double gs_system_angle(const gs_system *sys, int body)
{
    int c = sys->bodies[body].coord;
    return c < 0 ? 0.0 : sys->q[c];
}

double gs_system_omega(const gs_system *sys, int body)
{
    int c = sys->bodies[body].coord;
    return c < 0 ? 0.0 : sys->w[c];
}

double gs_system_rpm(const gs_system *sys, int body)
{
    return gs_system_omega(sys, body) * GS_RPM_PER_RAD_S;
}

int gs_system_planet_shares(const gs_system *sys, int *planet, double *share, int max)
{
    const gs_scene *sc = sys->scene;
    int n = 0;
    double sum = 0;
    for (int i = 0; i < sc->n_meshes && n < max; i++) {
        const gs_scene_mesh *m = &sc->meshes[i];
        for (int k = 0; k < 2; k++) {
            const gs_scene_body *p = &sc->bodies[m->gear[k]], *o = &sc->bodies[m->gear[1 - k]];
            /* a planet against an external gear on a fixed axis: a sun mesh */
            if (p->joint == GS_JOINT_ON_CARRIER && o->joint != GS_JOINT_ON_CARRIER &&
                o->gear.kind == GS_GEAR_EXTERNAL) {
                planet[n] = m->gear[k];
                share[n] = fabs(sys->meshes[i].force);
                sum += share[n];
                n++;
            }
        }
    }
    for (int i = 0; i < n; i++)
        share[i] = sum > 0 ? share[i] * n / sum : 1.0;
    return n;
}
