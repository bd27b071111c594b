/* SPDX-License-Identifier: MIT
 * Compliant supports in the time integration (docs/explanation/modal.md):
 *  - floating sun (soft bearing) and a ring on a bearing, held torsionally,
 *    in the lumped planetary under load: the balance residual stays at
 *    round-off (1e-9 of the energy scale) and the sun's centre really moves;
 *  - a free response started in one mode of the modal analysis of the same
 *    scene (sun and ring on bearings, carrier and planets turning, no
 *    damping) stays in that mode (squared modal amplitude outside its group
 *    below 1e-8 of that inside), and
 *    its frequency measured from the modal coordinate is the midpoint rule's
 *    own, 2/h atan(w h / 2), to 1e-7 (the exact w differs by (w h)^2 / 12);
 *  - refused combinations name the field; impact meshes and elastic
 *    planets on pin bearings are built. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include <cmocka.h>

#include "gearsim/modal.h"
#include "gearsim/util.h"
#include "scene_build.h"

/* The builtin lumped planetary with the sun on a bearing of stiffness ks
 * (N/m, 0: floating), the ring on a bearing (1e8 N/m) held torsionally,
 * constant mesh stiffness and the given mesh damping. */
static json_object *bearing_scene(double ks, double sun_damping, double mesh_damping, bool loads)
{
    json_object *root = vt_scene("planetary");
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        const char *b = json_object_get_string(json_object_object_get(j, "body"));
        if (!strcmp(b, "sun")) {
            json_object_object_add(j, "type", json_object_new_string("bearing"));
            json_object_object_add(j, "stiffness", json_object_new_double(ks));
            json_object_object_add(j, "damping", json_object_new_double(sun_damping));
        } else if (!strcmp(b, "ring")) {
            json_object_object_add(j, "type", json_object_new_string("bearing"));
            json_object_object_add(j, "stiffness", json_object_new_double(1e8));
            json_object_object_add(j, "torsional_stiffness", json_object_new_double(2e6));
        }
    }
    json_object *meshes = json_object_object_get(root, "meshes");
    for (size_t i = 0; i < json_object_array_length(meshes); i++) {
        json_object *m = json_object_array_get_idx(meshes, i);
        json_object_object_add(m, "stiffness", json_object_new_double(2e8));
        json_object_object_add(m, "damping", json_object_new_double(mesh_damping));
    }
    if (!loads)
        json_object_object_add(root, "loads", json_object_new_array());
    return root;
}

static void floating_sun_balance(void **state)
{
    (void)state;
    json_object *root = bearing_scene(1e5, 20.0, 0.0, true);
    /* planet1's pin 10 um ahead: the floating sun moves to share the load */
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        if (!strcmp(json_object_get_string(json_object_object_get(j, "body")), "planet1")) {
            json_object *pe = json_object_new_array();
            json_object_array_add(pe, json_object_new_double(0));
            json_object_array_add(pe, json_object_new_double(10));
            json_object_object_add(j, "pin_error_um", pe);
        }
    }
    json_object *meshes = json_object_object_get(root, "meshes");
    for (size_t i = 0; i < json_object_array_length(meshes); i++)
        json_object_object_add(json_object_array_get_idx(meshes, i), "backlash_mm", json_object_new_double(0.05));
    gs_system *s = vt_system(root);
    gs_energy e;
    double worst = 0, scale = 0, xmax = 0;
    int sun = gs_scene_find_body(s->scene, "sun");
    assert_true(s->bodies[sun].tcoord >= 0);
    for (int k = 0; k < 20000; k++) {
        vt_step_balance(s, &e, &worst, &scale);
        int tc = s->bodies[sun].tcoord;
        xmax = fmax(xmax, hypot(s->q[tc], s->q[tc + 1]));
    }
    print_message("floating sun, 20000 steps: worst |balance| %.3e J of %.3e J (%.2e); sun centre moved up to %.3e m; "
                  "carrier %.2f rad/s; dissipated %.3e J\n",
                  worst, scale, worst / scale, xmax, gs_system_omega(s, gs_scene_find_body(s->scene, "carrier")),
                  e.dissipated);
    assert_true(worst < 1e-9 * scale);
    assert_true(xmax > 1e-9); /* the translations are coupled */
    gs_system_free(&s);
}

/* Modal coordinate of mode j: phi_j' M q, with the system's state mapped to
 * the modal analysis' coordinates. */
static double modal_coord(const gs_modal *m, const gs_system *s, const double *x, int j, const int *map)
{
    double v = 0;
    for (int a = 0; a < m->n; a++) {
        double mq = 0;
        for (int b = 0; b < m->n; b++)
            mq += m->M[(size_t)b * m->n + a] * x[map[b]];
        v += m->shape[(size_t)j * m->n + a] * mq;
    }
    (void)s;
    return v;
}

/* The modal analysis of the scene `root` (borrowed); its parsed scene in
 * *out (freed when out is NULL). */
static gs_modal *modal_of(json_object *root, gs_scene **out)
{
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc;
    gs_diag d;
    assert_int_equal(gs_scene_parse(txt, strlen(txt), &sc, &d), GS_OK);
    gs_modal *m;
    assert_int_equal(gs_modal_analyse(sc, &m, &d), GS_OK);
    if (out)
        *out = sc;
    else
        gs_scene_free(&sc);
    return m;
}

static void one_mode(json_object *root, int pick_kind, const char *what)
{
    gs_modal *m = modal_of(root, NULL);
    gs_system *s = vt_system(root);
    assert_int_equal(s->n_coords, m->n);
    /* modal coordinate b -> system coordinate */
    int *map = calloc((size_t)m->n, sizeof(int));
    for (int b = 0; b < m->n; b++) {
        const gs_body_rt *br = &s->bodies[m->dof_body[b]];
        map[b] = m->dof_comp[b] == 2 ? br->coord : br->tcoord + m->dof_comp[b];
        assert_true(map[b] >= 0);
    }
    /* the lowest non-zero group of the kind */
    int g = -1;
    for (int k = 0; k < m->n_groups && g < 0; k++)
        if (m->group_kind[k] == pick_kind && m->freq_hz[m->group_first[k]] > 1.0)
            g = k;
    assert_true(g >= 0);
    int j = m->group_first[g], mult = m->group_mult[g];
    double w = sqrt(m->omega2[j]);
    double h = 0.02 * 2 * 3.14159265358979323846 / w; /* 50 steps per period */
    s->h = s->h_sub = h;
    /* start: amplitude giving 1 um of the largest displacement */
    double big = 0;
    for (int b = 0; b < m->n; b++)
        big = fmax(big, fabs(m->shape[(size_t)j * m->n + b]) * (m->dof_comp[b] == 2 ? 0.05 : 1.0));
    double A = 1e-6 / big;
    double *q0 = calloc((size_t)m->n, sizeof(double));
    for (int b = 0; b < m->n; b++) {
        q0[map[b]] = s->q[map[b]];
        s->q[map[b]] += A * m->shape[(size_t)j * m->n + b];
    }
    int nsteps = 1000;
    double *eta = calloc((size_t)nsteps + 1, sizeof(double));
    double *dev = calloc((size_t)m->n, sizeof(double));
    double outside, maxin = 0, maxout = 0;
    for (int k = 0; k <= nsteps; k++) {
        if (k > 0)
            assert_int_equal(gs_step_serial(s), GS_OK);
        for (int c = 0; c < m->n; c++)
            dev[c] = s->q[c] - q0[c];
        eta[k] = modal_coord(m, s, dev, j, map);
        /* modal amplitudes inside and outside the excited group */
        double in = 0, out = 0;
        for (int i = 0; i < m->n_modes; i++) {
            double e = modal_coord(m, s, dev, i, map);
            if (i >= j && i < j + mult)
                in += e * e;
            else
                out += e * e;
        }
        maxin = fmax(maxin, in);
        maxout = fmax(maxout, out);
    }
    outside = maxout / maxin;
    double num = 0, den = 0;
    for (int k = 1; k < nsteps; k++) {
        num += (eta[k + 1] + eta[k - 1]) * eta[k];
        den += 2 * eta[k] * eta[k];
    }
    double Wh = acos(num / den) / h;
    double Wmid = 2.0 / h * atan(w * h / 2);
    print_message("%s mode %.3f Hz (x%d): measured %.6f Hz, midpoint rule %.6f Hz (rel %.2e), exact differs by "
                  "%.2e; largest squared amplitude outside the mode's group over inside %.2e\n",
                  what, w / (2 * 3.14159265358979323846), mult, Wh / (2 * 3.14159265358979323846),
                  Wmid / (2 * 3.14159265358979323846), fabs(Wh - Wmid) / Wmid, fabs(Wmid - w) / w, outside);
    assert_true(fabs(Wh - Wmid) / Wmid < 1e-7);
    assert_true(fabs(Wmid - w) / w > 1e-4); /* the check can tell the two apart */
    assert_true(outside < 1e-8);
    free(eta), free(dev), free(q0), free(map);
    gs_modal_free(&m);
    gs_system_free(&s);
}

static void rotational_mode_stays(void **state)
{
    (void)state;
    one_mode(bearing_scene(1e8, 0.0, 0.0, false), GS_MODE_ROTATIONAL, "rotational");
}

static void translational_mode_stays(void **state)
{
    (void)state;
    one_mode(bearing_scene(1e8, 0.0, 0.0, false), GS_MODE_TRANSLATIONAL, "translational");
}

/* The Lin-Parker example train (deploy/scenes/lin_parker_N.json): sun, ring,
 * carrier and every planet on radial bearings (planets on their carrier
 * pins), lumped meshes of constant stiffness. With `loads`: a ramp moment on
 * the sun and a brake on the carrier, pin bearings damped (c N s/m);
 * without, no damping anywhere (free vibration). */
static json_object *lin_parker(int N, bool loads, double pin_damping)
{
    char name[32];
    snprintf(name, sizeof name, "lin_parker_%d", N);
    json_object *root = vt_scene(name);
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; pin_damping > 0 && i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        if (json_object_object_get_ex(j, "bearing_stiffness", NULL))
            json_object_object_add(j, "bearing_damping", json_object_new_double(pin_damping));
    }
    json_object *meshes = json_object_object_get(root, "meshes");
    for (size_t i = 0; !loads && i < json_object_array_length(meshes); i++) /* undamped: free vibration */
        json_object_object_add(json_object_array_get_idx(meshes, i), "damping", json_object_new_double(0.0));
    json_object *l = json_object_new_array();
    if (loads) {
        json_object *a = json_object_new_object(), *b = json_object_new_object();
        json_object_object_add(a, "body", json_object_new_string("sun"));
        json_object_object_add(a, "type", json_object_new_string("ramp"));
        json_object_object_add(a, "moment", json_object_new_double(50.0));
        json_object_object_add(a, "ramp_time", json_object_new_double(0.01));
        json_object_object_add(b, "body", json_object_new_string("carrier"));
        json_object_object_add(b, "type", json_object_new_string("brake"));
        json_object_object_add(b, "coefficient", json_object_new_double(2.0));
        json_object_array_add(l, a);
        json_object_array_add(l, b);
    }
    json_object_object_add(root, "loads", l);
    json_object *num = json_object_new_object();
    json_object_object_add(num, "time_step", json_object_new_double(1e-5));
    json_object_object_add(root, "numerics", num);
    return root;
}

/* Planets on pin bearings in the time integration: the balance under load
 * (ramp, brake, damped pin bearings, the carrier turning through a large
 * angle) at round-off, and the planets really move off their pins. */
static void pin_bearings_run(bool compliant)
{
    json_object *root = lin_parker(4, true, 200.0);
    json_object *meshes = json_object_object_get(root, "meshes");
    for (size_t i = 0; compliant && i < json_object_array_length(meshes); i++) {
        json_object *m = json_object_array_get_idx(meshes, i);
        json_object_object_del(m, "stiffness");
        json_object_object_add(m, "model", json_object_new_string("compliant"));
    }
    gs_system *s = vt_system(root);
    int p1 = gs_scene_find_body(s->scene, "planet1"), C = gs_scene_find_body(s->scene, "carrier");
    assert_true(s->bodies[p1].tcoord >= 0 && s->bodies[C].tcoord >= 0);
    gs_energy e;
    double worst = 0, scale = 0, off = 0;
    for (int k = 0; k < 20000; k++) {
        vt_step_balance(s, &e, &worst, &scale);
        /* the planet's centre against its pin: (pose) minus carrier centre plus R(theta_C) pin */
        const gs_scene_body *pb = &s->scene->bodies[p1];
        double c[2], cc[2], th;
        gs_system_body_pose(s, p1, c, &th);
        gs_system_body_pose(s, C, cc, &th);
        double a = pb->carrier_angle + gs_system_angle(s, C);
        off = fmax(off, hypot(c[0] - cc[0] - pb->carrier_radius * cos(a), c[1] - cc[1] - pb->carrier_radius * sin(a)));
    }
    double turned = gs_system_angle(s, C);
    int pl[8];
    double sh[8], lsf = 0;
    int np = gs_system_planet_shares(s, pl, sh, 8);
    for (int i = 0; i < np; i++)
        lsf = fmax(lsf, sh[i]);
    print_message("lin_parker_4, %s meshes, planets on pin bearings, 20000 steps under load: worst |balance| %.3e J "
                  "of %.3e J (%.2e); carrier turned %.2f rad (%.1f rad/s); planet1 off its pin up to %.3e m; "
                  "dissipated %.3e J; LSF %.6f\n", compliant ? "compliant" : "lumped",
                  worst, scale, worst / scale, turned, gs_system_omega(s, C), off, e.dissipated, lsf);
    assert_int_equal(np, 4);
    assert_true(lsf < 1.01); /* a perfect train shares equally */
    assert_true(worst < 3e-12 * scale); /* round-off accumulated over 20000 steps: 3e-13 */
    assert_true(turned > 1.0);  /* large rotation: the pin term is nonlinear */
    assert_true(off > 1e-7);    /* 50 N m over four planets and 1e8 N/m: micrometres */
    assert_true(off < 1e-4);
    gs_system_free(&s);
}

static void pin_bearings_balance(void **state)
{
    (void)state;
    pin_bearings_run(false);
    pin_bearings_run(true);
}

/* A star train (carrier held, ring turning on its axis, braked) with its
 * planets on pin bearings (1e8 N/m, damped): the pins stand still, the
 * lines of action are fixed, the translations enter linearly. Balance at
 * round-off, planets move off their pins by the bearing deflection. */
static void star_on_pin_bearings(void **state)
{
    (void)state;
    json_object *root = vt_scene("planetary");
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        const char *b = json_object_get_string(json_object_object_get(j, "body"));
        if (!strcmp(b, "carrier")) {
            json_object_object_del(j, "centre_mm");
            json_object_object_add(j, "type", json_object_new_string("held"));
        } else if (!strcmp(b, "ring")) {
            json_object_object_add(j, "type", json_object_new_string("fixed_axis"));
        } else if (strncmp(b, "planet", 6) == 0) {
            json_object_object_add(j, "bearing_stiffness", json_object_new_double(1e8));
            json_object_object_add(j, "bearing_damping", json_object_new_double(100.0));
        }
    }
    json_object *loads = json_object_object_get(root, "loads");
    json_object_object_add(json_object_array_get_idx(loads, 1), "body", json_object_new_string("ring"));
    json_object_object_add(json_object_array_get_idx(loads, 1), "coefficient", json_object_new_double(0.6));
    gs_system *s = vt_system(root);
    int p1 = gs_scene_find_body(s->scene, "planet1"), ring = gs_scene_find_body(s->scene, "ring");
    int tc = s->bodies[p1].tcoord;
    assert_true(tc >= 0);
    gs_energy e;
    double worst = 0, scale = 0, off = 0;
    for (int k = 0; k < 10000; k++) {
        vt_step_balance(s, &e, &worst, &scale);
        off = fmax(off, hypot(s->q[tc], s->q[tc + 1]));
    }
    print_message("star train on pin bearings, 10000 steps: worst |balance| %.3e J of %.3e J (%.2e); ring %.2f rad/s; "
                  "planet1 off its pin up to %.3e m\n", worst, scale, worst / scale, gs_system_omega(s, ring), off);
    assert_true(worst < 3e-12 * scale);
    assert_true(gs_system_omega(s, ring) < -10.0); /* a star train reverses */
    assert_true(off > 1e-7 && off < 1e-4);
    gs_system_free(&s);
}

/* The pin_bearing joint's force alone, on lin_parker_4's coordinates: for
 * random states and increments (carrier turns up to 2 rad in one
 * increment, planets and carrier translate) the energy identity
 * V(q0 + dq) - V(q0) = g . dq holds to round-off, the damper's work
 * g_d . dq equals its reported dissipation, and the Jacobian matches central
 * differences of g. */
static void pin_bearing_discrete_gradient(void **state)
{
    (void)state;
    gs_system *s = vt_system(lin_parker(4, false, 300.0));
    int n = s->n_coords, found = 0;
    double *q0 = calloc((size_t)n, sizeof(double)), *dq = calloc((size_t)n, sizeof(double));
    double *q1 = calloc((size_t)n, sizeof(double)), *g = calloc((size_t)n, sizeof(double));
    double *gp = calloc((size_t)n, sizeof(double)), *gm = calloc((size_t)n, sizeof(double));
    double *J = calloc((size_t)n * n, sizeof(double)), *Jd = calloc((size_t)n * n, sizeof(double));
    unsigned rng = 12345u;
    double worst_e = 0, worst_d = 0, worst_j = 0;
    for (int trial = 0; trial < 200; trial++) {
        for (int i = 0; i < n; i++) {
            rng = rng * 1664525u + 1013904223u;
            double u1 = (rng >> 8) / 16777216.0 - 0.5;
            rng = rng * 1664525u + 1013904223u;
            double u2 = (rng >> 8) / 16777216.0 - 0.5;
            bool trans = false;
            for (int b = 0; b < s->n_bodies; b++)
                trans |= s->bodies[b].tcoord == i || s->bodies[b].tcoord + 1 == i;
            q0[i] = trans ? 2e-5 * u1 : 6.0 * u1;
            dq[i] = trans ? 1e-5 * u2 : (trial % 2 ? 4.0 : 1e-6) * u2;
        }
        gs_model_view v;
        gs_system_view(s, &v);
        for (int jn = 0; jn < s->n_joints; jn++) {
            const gs_joint_rt *j = &s->joints[jn];
            if (strcmp(j->ops->name, "pin_bearing") != 0)
                continue;
            found++;
            memset(g, 0, (size_t)n * sizeof(double));
            memset(J, 0, (size_t)n * n * sizeof(double));
            double diss, h = 1e-5;
            j->ops->force(&v, j, q0, dq, h, g, J, &diss);
            for (int i = 0; i < n; i++)
                q1[i] = q0[i] + dq[i];
            double dV = j->ops->energy(&v, j, q1) - j->ops->energy(&v, j, q0), gd = 0, V0 = j->ops->energy(&v, j, q0);
            for (int i = 0; i < n; i++)
                gd += g[i] * dq[i];
            /* g . dq = dV + dissipation */
            double sc = fabs(V0) + fabs(dV) + diss + 1e-30;
            worst_e = fmax(worst_e, fabs(gd - dV - diss) / sc);
            /* the undamped part alone: a copy of the joint without its damper */
            gs_joint_rt j0 = *j;
            j0.c[0] = j0.c[1] = 0.0;
            memset(g, 0, (size_t)n * sizeof(double));
            memset(Jd, 0, (size_t)n * n * sizeof(double));
            double d0;
            j0.ops->force(&v, &j0, q0, dq, h, g, Jd, &d0);
            gd = 0;
            for (int i = 0; i < n; i++)
                gd += g[i] * dq[i];
            worst_d = fmax(worst_d, fabs(d0));
            worst_e = fmax(worst_e, fabs(gd - dV) / (fabs(V0) + fabs(dV) + 1e-30));
            /* Jacobian against central differences in dq */
            for (int c = 0; c < n; c++) {
                bool trans = false;
                for (int b = 0; b < s->n_bodies; b++)
                    trans |= s->bodies[b].tcoord == c || s->bodies[b].tcoord + 1 == c;
                /* g is linear in the translations (any step) and smooth in
                 * the rotation (O(step^2) truncation) */
                double step = trans ? 1e-9 : 1e-6, keep = dq[c];
                memset(gp, 0, (size_t)n * sizeof(double));
                memset(gm, 0, (size_t)n * sizeof(double));
                double dd;
                dq[c] = keep + step;
                j->ops->force(&v, j, q0, dq, h, gp, Jd, &dd);
                dq[c] = keep - step;
                j->ops->force(&v, j, q0, dq, h, gm, Jd, &dd);
                dq[c] = keep;
                for (int r = 0; r < n; r++) {
                    double fd = (gp[r] - gm[r]) / (2 * step), an = J[(size_t)r * n + c];
                    double big = fmax(fabs(fd), fabs(an));
                    if (big > 1e-3)
                        worst_j = fmax(worst_j, fabs(fd - an) / big);
                }
            }
        }
    }
    print_message("pin_bearing joint, %d random increments: energy identity worst %.2e (relative), undamped copy "
                  "dissipates %.1e J, Jacobian vs central differences worst %.2e\n", found, worst_e, worst_d,
                  worst_j);
    assert_int_equal(found, 4 * 200);
    assert_true(worst_e < 1e-12);
    assert_true(worst_d == 0.0);
    assert_true(worst_j < 1e-5);
    free(q0), free(dq), free(q1), free(g), free(gp), free(gm), free(J), free(Jd);
    gs_system_free(&s);
}

static void pin_bearings_planet_mode(void **state)
{
    (void)state;
    one_mode(lin_parker(4, false, 0.0), GS_MODE_PLANET, "lin_parker_4 planet");
}

static void pin_bearings_rotational_mode(void **state)
{
    (void)state;
    one_mode(lin_parker(4, false, 0.0), GS_MODE_ROTATIONAL, "lin_parker_4 rotational");
}

static void pin_bearings_translational_mode(void **state)
{
    (void)state;
    one_mode(lin_parker(4, false, 0.0), GS_MODE_TRANSLATIONAL, "lin_parker_4 translational");
}

/* Load sharing with a 10 um tangential pin error on planet1
 * (deploy/scenes/planetary_floating.json): the largest planet share over the
 * mean, averaged over the last 5000 of 25000 steps (0.25 s; steady carrier
 * speed), with the floating sun and with the sun on a fixed axis. */
static double sharing_pins(bool floating, bool compliant, double pin_k, double share_out[3], double *sun_offset)
{
    json_object *root = vt_scene("planetary_floating");
    json_object *pj = json_object_object_get(root, "joints");
    for (size_t i = 0; pin_k > 0 && i < json_object_array_length(pj); i++) {
        json_object *j = json_object_array_get_idx(pj, i);
        if (!strncmp(json_object_get_string(json_object_object_get(j, "body")), "planet", 6)) {
            json_object_object_add(j, "bearing_stiffness", json_object_new_double(pin_k));
            json_object_object_add(j, "bearing_damping", json_object_new_double(100.0));
        }
    }
    json_object *meshes = json_object_object_get(root, "meshes");
    for (size_t i = 0; compliant && i < json_object_array_length(meshes); i++) {
        json_object *m = json_object_array_get_idx(meshes, i);
        json_object_object_del(m, "stiffness");
        json_object_object_add(m, "model", json_object_new_string("compliant"));
    }
    if (!floating) {
        json_object *joints = json_object_object_get(root, "joints");
        for (size_t i = 0; i < json_object_array_length(joints); i++) {
            json_object *j = json_object_array_get_idx(joints, i);
            if (!strcmp(json_object_get_string(json_object_object_get(j, "body")), "sun")) {
                json_object_object_del(j, "stiffness");
                json_object_object_del(j, "damping");
                json_object_object_add(j, "type", json_object_new_string("fixed_axis"));
            }
        }
    }
    gs_system *s = vt_system(root);
    int sun = gs_scene_find_body(s->scene, "sun");
    double acc[3] = {0, 0, 0}, off = 0, worst = 0, scale = 0;
    int n = 0;
    gs_energy e;
    for (int k = 0; k < 25000; k++) {
        vt_step_balance(s, &e, &worst, &scale);
        if (k >= 20000) {
            int pl[8];
            double sh[8];
            int np = gs_system_planet_shares(s, pl, sh, 8);
            assert_int_equal(np, 3);
            for (int i = 0; i < 3; i++)
                acc[i] += sh[i];
            n++;
            int tc = s->bodies[sun].tcoord;
            if (tc >= 0)
                off += hypot(s->q[tc], s->q[tc + 1]);
        }
    }
    assert_true(worst < 1e-9 * scale);
    double mx = 0;
    for (int i = 0; i < 3; i++) {
        share_out[i] = acc[i] / n;
        mx = fmax(mx, share_out[i]);
    }
    *sun_offset = off / n;
    gs_system_free(&s);
    return mx; /* shares are normalised to mean 1 */
}

static double sharing(bool floating, bool compliant, double share_out[3], double *sun_offset)
{
    return sharing_pins(floating, compliant, 0.0, share_out, sun_offset);
}

static void floating_sun_shares_load(void **state)
{
    (void)state;
    double fl[3], fx[3], off_fl, off_fx;
    for (int compliant = 0; compliant < 2; compliant++) {
        double lsf_float = sharing(true, compliant, fl, &off_fl), lsf_fixed = sharing(false, compliant, fx, &off_fx);
        print_message("%s meshes, pin error 10 um on planet1: floating sun LSF %.4f (shares %.4f %.4f %.4f, sun off "
                      "centre %.2f um); fixed sun LSF %.4f (shares %.4f %.4f %.4f)\n",
                      compliant ? "compliant" : "lumped", lsf_float, fl[0], fl[1], fl[2], off_fl * 1e6, lsf_fixed,
                      fx[0], fx[1], fx[2]);
        assert_true(lsf_float < 1.05);
        assert_true(lsf_fixed > 1.3);
    }
}

/* The same pin error with the sun on a fixed axis and the planets on pin
 * bearings of decreasing stiffness: softer planet supports let the planets
 * float and share the load more equally (printed; the LSF falls
 * monotonically and the softest is far below the rigid pins' 1.49). */
static void pin_bearings_share_load(void **state)
{
    (void)state;
    const double kp[3] = {1e8, 2e7, 5e6};
    double lsf[3], sh[3][3], off;
    for (int i = 0; i < 3; i++) {
        lsf[i] = sharing_pins(false, false, kp[i], sh[i], &off);
        print_message("fixed sun, planets on pin bearings %.0e N/m, pin error 10 um on planet1: LSF %.4f (shares %.4f "
                      "%.4f %.4f)\n", kp[i], lsf[i], sh[i][0], sh[i][1], sh[i][2]);
    }
    assert_true(lsf[0] > lsf[1] && lsf[1] > lsf[2]);
    assert_true(lsf[2] < 1.3);
}

/* The spur pair with both gears on bearings (1e8 N/m) and a kinematic
 * mesh (an exact ratio on a fixed line of action): constraint rows that
 * include the translations. */
static json_object *pair_on_bearings(bool loads)
{
    json_object *root = vt_scene("pair");
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        json_object_object_add(j, "type", json_object_new_string("bearing"));
        json_object_object_add(j, "stiffness", json_object_new_double(1e8));
    }
    json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    json_object *k = json_object_new_object();
    json_object_object_add(k, "name", json_object_get(json_object_object_get(m, "name")));
    json_object_object_add(k, "gears", json_object_get(json_object_object_get(m, "gears")));
    json_object_object_add(k, "model", json_object_new_string("kinematic"));
    json_object_array_put_idx(json_object_object_get(root, "meshes"), 0, k);
    if (!loads)
        json_object_object_add(root, "loads", json_object_new_array());
    return root;
}

static void kinematic_pair_on_bearings(void **state)
{
    (void)state;
    gs_system *s = vt_system(pair_on_bearings(true));
    gs_energy e;
    double worst = 0, scale = 0, drift = 0, xmax = 0;
    for (int k = 0; k < 20000; k++) {
        vt_step_balance(s, &e, &worst, &scale);
        drift = fmax(drift, fabs(s->meshes[0].deflection));
        int tc = s->bodies[0].tcoord;
        xmax = fmax(xmax, hypot(s->q[tc], s->q[tc + 1]));
    }
    print_message("kinematic pair on bearings, 20000 steps: worst |balance| %.3e J of %.3e J; line-of-action "
                  "drift %.3e m; pinion centre moved %.3e m\n", worst, scale, drift, xmax);
    assert_true(worst < 1e-9 * scale);
    assert_true(drift < 1e-12);
    assert_true(xmax > 1e-7); /* the bearings carry the mesh force: 20 N m / rb over 1e8 N/m */
    gs_system_free(&s);
    one_mode(pair_on_bearings(false), GS_MODE_MIXED, "kinematic pair, mixed");
}

/* Every joint of the scene `root` a radial bearing of stiffness kb (N/m)
 * damped by 200 N s/m. */
static void all_on_bearings(json_object *root, double kb)
{
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        json_object_object_add(j, "type", json_object_new_string("bearing"));
        json_object_object_add(j, "stiffness", json_object_new_double(kb));
        json_object_object_add(j, "damping", json_object_new_double(200.0));
    }
}

/* The calibrated lumped mesh (its stiffness over the mesh cycle from the
 * FE analysis of the pair, docs/explanation/stiffness.md) with both gears on radial
 * bearings (k_b N/m, damped): the rigid contact_drive pair. */
static json_object *calibrated_on_bearings(double kb)
{
    json_object *root = vt_scene("contact_drive");
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++)
        json_object_object_add(json_object_array_get_idx(bs, i), "model", json_object_new_string("rigid"));
    all_on_bearings(root, kb);
    json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    json_object_object_add(m, "model", json_object_new_string("lumped"));
    json_object *st = json_object_new_object();
    json_object_object_add(st, "type", json_object_new_string("calibrated"));
    json_object_object_add(st, "positions", json_object_new_int(24));
    json_object_object_add(m, "stiffness", st);
    return root;
}

/* The `pair` scene with a compliant mesh (the contact patch model in series
 * with the teeth, docs/explanation/impact.md) and both gears on bearings. */
static json_object *compliant_on_bearings(double kb)
{
    json_object *root = vt_scene("pair");
    all_on_bearings(root, kb);
    json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    json_object_object_del(m, "stiffness");
    json_object_object_add(m, "model", json_object_new_string("compliant"));
    return root;
}

/* A pair on bearings (k_b N/m) under load (ramp 20 N m, brake): the balance
 * at round-off through the mesh law and the translations, and the bearings
 * carry the mesh force: the wheel's mean centre displacement over the last
 * 5000 of 20000 steps is the mean mesh force over k_b (quasi-static: the
 * bearing modes, above 1 kHz, are far above the load's time scale) within
 * 1%. */
static void pair_on_bearings_carries(json_object *root, double kb, const char *what, const char *mesh_model)
{
    gs_system *s = vt_system(root);
    assert_string_equal(s->meshes[0].ops->name, mesh_model);
    int w = gs_scene_find_body(s->scene, "wheel");
    int tc = s->bodies[w].tcoord;
    assert_true(tc >= 0);
    gs_energy e;
    double worst = 0, scale = 0, fm = 0, xm[2] = {0, 0};
    int n = 0;
    for (int k = 0; k < 20000; k++) {
        vt_step_balance(s, &e, &worst, &scale);
        if (k >= 15000) {
            fm += s->meshes[0].force;
            xm[0] += s->q[tc], xm[1] += s->q[tc + 1];
            n++;
        }
    }
    fm /= n, xm[0] /= n, xm[1] /= n;
    double xmag = hypot(xm[0], xm[1]), xcf = fabs(fm) / kb;
    print_message("%s mesh on bearings (k_b %.0e N/m), 20000 steps: worst |balance| %.3e J of %.3e J (%.2e); "
                  "mean mesh force %.3f N; wheel centre displaced %.4e m, F / k_b %.4e m (rel %.2e)\n",
                  what, kb, worst, scale, worst / scale, fm, xmag, xcf, fabs(xmag - xcf) / xcf);
    assert_true(worst < 1e-9 * scale);
    assert_true(fabs(fm) > 100.0);
    assert_true(fabs(xmag - xcf) < 0.01 * xcf);
    gs_system_free(&s);
}

static void calibrated_mesh_on_bearings(void **state)
{
    (void)state;
    json_object *root = calibrated_on_bearings(5e7);
    pair_on_bearings_carries(root, 5e7, "calibrated", "lumped");
}

static void compliant_mesh_on_bearings(void **state)
{
    (void)state;
    pair_on_bearings_carries(compliant_on_bearings(5e7), 5e7, "compliant", "compliant");
}

/* Closed forms: a spur pair on fixed axes with a constant lumped mesh,
 * w^2 = k (rb1^2 / I1 + rb2^2 / I2) beside the rigid rotation; one gear on
 * a bearing, w^2 = k_r / m (double) and k_t / I. */
static void modal_closed_forms(void **state)
{
    (void)state;
    json_object *root = vt_scene("pair");
    json_object *m0 = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    json_object_object_add(m0, "stiffness", json_object_new_double(2e8));
    gs_scene *sc;
    gs_modal *m = modal_of(root, &sc);
    double r1 = gs_gear_base_radius(&sc->bodies[0].gear), r2 = gs_gear_base_radius(&sc->bodies[1].gear);
    double w2 = 2e8 * (r1 * r1 / sc->bodies[0].inertia + r2 * r2 / sc->bodies[1].inertia);
    assert_int_equal(m->n_modes, 2);
    assert_true(fabs(m->omega2[0]) < 1e-9 * w2);
    assert_true(fabs(m->omega2[1] / w2 - 1) < 1e-12);
    print_message("pair: %.6f Hz, closed form %.6f Hz\n", m->freq_hz[1], sqrt(w2) / (2 * 3.14159265358979323846));
    gs_modal_free(&m);
    gs_scene_free(&sc);
    json_object_put(root);

    root = vt_scene("pair");
    json_object_object_add(root, "meshes", json_object_new_array());
    json_object *j0 = json_object_array_get_idx(json_object_object_get(root, "joints"), 0);
    json_object_object_add(j0, "type", json_object_new_string("bearing"));
    json_object_object_add(j0, "stiffness", json_object_new_double(3e7));
    json_object_object_add(j0, "torsional_stiffness", json_object_new_double(5e4));
    m = modal_of(root, &sc);
    double wt = 3e7 / sc->bodies[0].mass, wr = 5e4 / sc->bodies[0].inertia;
    int found_t = 0, found_r = 0;
    for (int i = 0; i < m->n_modes; i++) {
        found_t += fabs(m->omega2[i] / wt - 1) < 1e-12;
        found_r += fabs(m->omega2[i] / wr - 1) < 1e-12;
    }
    assert_int_equal(found_t, 2);
    assert_int_equal(found_r, 1);
    gs_modal_free(&m);
    gs_scene_free(&sc);
    json_object_put(root);
}

static void refusals(void **state)
{
    (void)state;
    json_object *root = bearing_scene(1e8, 0, 0, true);
    json_object *meshes = json_object_object_get(root, "meshes");
    json_object *m0 = json_object_array_get_idx(meshes, 0);
    json_object_object_del(m0, "stiffness");
    json_object_object_del(m0, "damping");
    json_object_object_add(m0, "model", json_object_new_string("kinematic"));
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc;
    gs_diag d;
    assert_int_equal(gs_scene_parse(txt, strlen(txt), &sc, &d), GS_OK);
    gs_system *s;
    assert_int_equal(gs_system_new(sc, 0, 1, &s, &d), GS_ERANGE);
    assert_string_equal(d.field, "meshes[0].model"); /* kinematic with a planet on a turning carrier */
    json_object_put(root);
    /* planets on pin bearings: an impact mesh of one and an elastic planet
     * (lumped meshes) are built (docs/explanation/planetary.md, "Contact
     * meshes on moving members"); they were refused before the contact
     * step and the impact law had translations */
    const char *model[2] = {"impact", "lumped"};
    for (int c = 0; c < 2; c++) {
        root = lin_parker(4, false, 0.0);
        m0 = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
        json_object_object_del(m0, "stiffness");
        json_object_object_del(m0, "damping");
        json_object_object_add(m0, "model", json_object_new_string(model[c]));
        if (c == 0)
            json_object_object_add(m0, "backlash_mm", json_object_new_double(0.05));
        if (c == 1) {
            json_object *b = json_object_array_get_idx(json_object_object_get(root, "bodies"), 1);
            assert_string_equal(json_object_get_string(json_object_object_get(b, "name")), "planet1");
            json_object_object_add(b, "model", json_object_new_string("elastic"));
            json_object_object_add(vt_body_mesh(b), "order", json_object_new_int(1));
        }
        txt = json_object_to_json_string(root);
        assert_int_equal(gs_scene_parse(txt, strlen(txt), &sc, &d), GS_OK);
        gs_err e = gs_system_new(sc, 0, 1, &s, &d);
        if (e != GS_OK)
            print_message("refused (%s): %s: %s\n", model[c], d.field, d.message);
        assert_int_equal(e, GS_OK);
        gs_system_free(&s);
        json_object_put(root);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(floating_sun_balance),
        cmocka_unit_test(rotational_mode_stays),
        cmocka_unit_test(translational_mode_stays),
        cmocka_unit_test(pin_bearings_balance),
        cmocka_unit_test(pin_bearing_discrete_gradient),
        cmocka_unit_test(star_on_pin_bearings),
        cmocka_unit_test(pin_bearings_planet_mode),
        cmocka_unit_test(pin_bearings_rotational_mode),
        cmocka_unit_test(pin_bearings_translational_mode),
        cmocka_unit_test(calibrated_mesh_on_bearings),
        cmocka_unit_test(compliant_mesh_on_bearings),
        cmocka_unit_test(floating_sun_shares_load),
        cmocka_unit_test(pin_bearings_share_load),
        cmocka_unit_test(kinematic_pair_on_bearings),
        cmocka_unit_test(modal_closed_forms),
        cmocka_unit_test(refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
