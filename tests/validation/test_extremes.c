/* SPDX-License-Identifier: MIT
 * Extremes suite (issue 8, item 6; docs/explanation/stability.md): every rung of the
 * fidelity ladder (rigid + kinematic, rigid + lumped, rigid + impact,
 * elastic, contact) at the edges of what a scene may ask for: time steps
 * 1e-9 to 1e-3 s, speeds 0.1 to 60000 rpm, Young's modulus 1 to 1000 GPa,
 * inertia (or density) ratios 1e-3 to 1e3 between the gears, 1e6-step runs,
 * FE meshes from one element across a tooth to refined ones.
 *
 * Every case either keeps its invariants or is refused with a clear error:
 *  - kept: every step returns GS_OK, the state and energies stay finite,
 *    max |balance residual| over the run is at round-off of the energy
 *    scale (largest of |E|, kinetic, work in, dissipated seen in the run),
 *    impact meshes keep the teeth outside each other, contact meshes keep
 *    the penetration below 0.1 module;
 *  - refused: at load (gs_scene_parse / gs_system_new) or after a step
 *    (gs_system_check, sys->diag) with the expected code and a diagnostic
 *    whose field names what to change (numerics.time_step, a density).
 *
 * Fast by default (well under a minute: every rigid case, the 1e6-step
 * rigid runs, short elastic and contact runs). GEARSIM_LONG=1 selects the
 * long mode for the benchmark machine: more steps everywhere, 1e6 rigid
 * planetary steps, 1e6 steps of the one-element elastic gear, finer meshes,
 * 1e4-step contact runs (about 4 minutes on this 2-core machine,
 * docs/explanation/stability.md):
 *
 *     GEARSIM_LONG=1 meson test -C build --suite validation extremes
 *
 * Each case prints one row of the table in docs/explanation/stability.md. */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <json-c/json.h>

#include "gearsim/step.h"
#include "scene_build.h"

/* What a case asks: edits of a builtin scene (zero fields: as given). */
typedef struct xcase {
    const char *name;
    const char *scene;
    const char *mesh_model;  /* replace every mesh's model (its defaults; lumped: a constant
                              * stiffness, the mean of the pair's) */
    double h;                /* time step, s */
    double rpm;              /* initial speed of body 0; its mate turns in the tooth ratio
                              * (contact_impact: the mate stays at rest, as in the scene) */
    bool free_run;           /* remove the loads: the total energy is then constant */
    double E;                /* Young's modulus of every elastic gear, Pa */
    double inertia_ratio;    /* rigid gears: inertia of body 1 over body 0's */
    double rho0, rho1;       /* densities of bodies 0 and 1, kg/m^3 */
    int flank, across, rim, refine; /* FE mesh of the elastic gears (any set: the others
                                     * take the defaults 8, 4, 3, 0) */
    long fast, slow;         /* steps in the fast and the long mode (0: skip the case) */
    gs_err expect;           /* GS_OK: invariants kept; otherwise the refusal's code */
    const char *field;       /* the refusal's field (part of it) */
    bool at_load;            /* refused at load, before any step */
} xcase;

typedef struct xresult {
    gs_err err;
    gs_diag diag;
    long steps;
    double drift, scale, pen, pen_limit, wall;
    bool finite;
} xresult;

static bool long_mode(void)
{
    const char *v = getenv("GEARSIM_LONG");
    return v && strcmp(v, "1") == 0;
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static json_object *child(json_object *o, const char *key)
{
    json_object *c;
    if (!json_object_object_get_ex(o, key, &c)) {
        c = json_object_new_object();
        json_object_object_add(o, key, c);
    }
    return c;
}

static const char *str(json_object *o, const char *key)
{
    json_object *v;
    return json_object_object_get_ex(o, key, &v) ? json_object_get_string(v) : "";
}

/* Inertia of body 0 of a builtin scene, from its geometry. */
static double inertia0(const char *scene)
{
    const char *t = gs_scene_builtin(scene);
    gs_scene *sc;
    assert_int_equal(gs_scene_parse(t, strlen(t), &sc, NULL), GS_OK);
    double I = sc->bodies[0].inertia;
    gs_scene_free(&sc);
    return I;
}

static json_object *scene_of(const xcase *c)
{
    json_object *root = vt_contact_scheme(vt_scene(c->scene), "seed"); /* the seed's scheme, measured */
    json_object *bodies = json_object_object_get(root, "bodies");
    json_object *ms = json_object_object_get(root, "meshes");
    int nb = (int)json_object_array_length(bodies);
    if (c->mesh_model)
        for (size_t i = 0; i < json_object_array_length(ms); i++) {
            json_object *m = json_object_array_get_idx(ms, i);
            static const char *const drop[] = {"stiffness", "damping_ratio", "damping", "backlash_mm",
                                               "restitution", "law", NULL};
            for (const char *const *k = drop; *k; k++)
                json_object_object_del(m, *k);
            json_object_object_add(m, "model", json_object_new_string(c->mesh_model));
            if (!strcmp(c->mesh_model, "lumped")) /* a constant stiffness: no wave */
                json_object_object_add(m, "stiffness", json_object_new_double(2.1e8));
            if (!strcmp(c->mesh_model, "impact"))
                json_object_object_add(m, "backlash_mm", json_object_new_double(0.1));
        }
    if (c->h > 0)
        json_object_object_add(child(root, "numerics"), "time_step", json_object_new_double(c->h));
    if (c->free_run)
        json_object_object_add(root, "loads", json_object_new_array());
    bool dense = c->flank || c->across || c->rim || c->refine;
    for (int i = 0; i < nb; i++) {
        json_object *b = json_object_array_get_idx(bodies, (size_t)i);
        bool elastic = !strcmp(str(b, "model"), "elastic");
        double rho = i == 0 ? c->rho0 : i == 1 ? c->rho1 : 0;
        if (c->E > 0 && elastic)
            json_object_object_add(child(b, "material"), "E", json_object_new_double(c->E));
        if (rho > 0)
            json_object_object_add(child(b, "material"), "density", json_object_new_double(rho));
        if (dense && elastic) {
            json_object *md = json_object_new_object();
            json_object_object_add(md, "flank", json_object_new_int(c->flank ? c->flank : 8));
            json_object_object_add(md, "across", json_object_new_int(c->across ? c->across : 4));
            json_object_object_add(md, "rim", json_object_new_int(c->rim ? c->rim : 3));
            json_object_object_add(md, "refine", json_object_new_int(c->refine));
            json_object_object_add(b, "mesh", md);
        }
        if (c->inertia_ratio > 0 && i == 1)
            json_object_object_add(b, "inertia", json_object_new_double(c->inertia_ratio * inertia0(c->scene)));
    }
    if (c->rpm != 0) {
        json_object *ini = child(root, "initial");
        json_object *b0 = json_object_array_get_idx(bodies, 0);
        json_object *i0 = child(ini, str(b0, "name"));
        json_object_object_del(i0, "omega");
        json_object_object_add(i0, "speed_rpm", json_object_new_double(c->rpm));
        if (nb > 1 && strcmp(c->scene, "contact_impact") != 0) {
            json_object *b1 = json_object_array_get_idx(bodies, 1);
            json_object *i1 = child(ini, str(b1, "name"));
            double z0 = json_object_get_double(json_object_object_get(b0, "teeth"));
            double z1 = json_object_get_double(json_object_object_get(b1, "teeth"));
            json_object_object_del(i1, "omega");
            json_object_object_add(i1, "speed_rpm", json_object_new_double(-c->rpm * z0 / z1));
        }
    }
    vt_pin_linear(root); /* linear triangles: the extremes were measured on them (scene_build.h) */
    return root;
}

static void run(const xcase *c, long n, xresult *r)
{
    memset(r, 0, sizeof *r);
    r->finite = true;
    json_object *root = scene_of(c);
    const char *txt = json_object_to_json_string(root);
    double t0 = now_s();
    gs_scene *sc;
    gs_system *s = NULL;
    r->err = gs_scene_parse(txt, strlen(txt), &sc, &r->diag);
    json_object_put(root);
    if (r->err == GS_OK)
        r->err = gs_system_new(sc, 0, 1, &s, &r->diag);
    if (r->err != GS_OK) {
        r->wall = now_s() - t0;
        return;
    }
    gs_energy e;
    gs_system_energy(s, &e);
    double worst = 0, scale = fmax(fabs(e.total), e.kinetic);
    for (long i = 0; i < n; i++) {
        gs_err err = gs_step_serial(s);
        if (err != GS_OK) {
            r->err = err;
            r->diag = s->diag;
            break;
        }
        r->steps++;
        gs_system_energy(s, &e);
        if (!isfinite(e.total) || !isfinite(e.balance_residual))
            r->finite = false;
        scale = fmax(scale, fmax(fabs(e.total), fmax(e.kinetic, fmax(e.work_in, e.dissipated))));
        worst = fmax(worst, fabs(e.balance_residual));
        for (int m = 0; m < s->n_meshes; m++) {
            gs_gmesh_rt *me = &s->meshes[m];
            const gs_scene_mesh *sm = &s->scene->meshes[m];
            if (me->ops->contact) {
                r->pen = fmax(r->pen, me->penetration);
                r->pen_limit = 0.1 * s->scene->bodies[sm->gear[0]].gear.module_m;
            } else if (!strcmp(me->ops->name, "impact")) {
                r->pen = fmax(r->pen, fabs(me->deflection) - me->half_backlash);
                r->pen_limit = me->half_backlash;
            }
        }
    }
    for (int i = 0; i < s->n_coords; i++)
        if (!isfinite(s->q[i]) || !isfinite(s->w[i]))
            r->finite = false;
    r->wall = now_s() - t0;
    r->drift = scale > 0 ? worst / scale : 0;
    r->scale = scale;
    gs_system_free(&s);
}

/* Round-off bounds of the balance residual relative to the energy scale.
 * Rigid rungs: the Newton/KKT solve of a few unknowns leaves up to ~3e-16
 * of the scale per step, and it can accumulate linearly (the free lumped
 * pair: 2.5e-12 after 1e4 steps, 2.5e-11 after 1e5): 1e-15 n, at least
 * 1e-12 (measured: 2e-11 after 1e6 rattle steps). FE rungs: each step's residual is the FE solve's round-off,
 * the stiffness's condition number (up to ~1e6 for the one-element mesh
 * and the extreme moduli) times 1e-16: 1e-10 (measured: up to 2e-11),
 * times 4^refine, the growth of the condition number per uniform
 * refinement (measured on contact_impact: 3e-12, 2e-11, 1.5e-10 at
 * refine 0, 1, 2). */
static double tolerance(const xcase *c, long steps)
{
    bool fe = strstr(c->scene, "elastic") || strstr(c->scene, "contact");
    if (fe)
        return 1e-10 * ldexp(1.0, 2 * c->refine);
    return fmax(1e-12, 1e-15 * (double)steps);
}

static void row(const xcase *c, const xresult *r, double tol)
{
    char outcome[600];
    if (r->err == GS_OK)
        snprintf(outcome, sizeof outcome, "kept (drift bound %.0e)", tol);
    else
        snprintf(outcome, sizeof outcome, "refused %s `%s`%s: %s", gs_errcode(r->err), r->diag.field,
                 r->steps || !c->at_load ? " after a step" : " at load", r->diag.message);
    char pen[64] = "";
    if (r->pen_limit > 0)
        snprintf(pen, sizeof pen, "%.2e / %.2e", r->pen, r->pen_limit);
    print_message("| %s | %ld | %.2e | %.2e | %s | %.3f | %s |\n", c->name, r->steps, r->drift, r->scale, pen,
                  r->wall, outcome);
}

static void check(const xcase *c)
{
    long n = long_mode() ? c->slow : c->fast;
    if (n <= 0)
        return;
    xresult r;
    run(c, n, &r);
    double tol = tolerance(c, r.steps);
    row(c, &r, tol);
    assert_true(r.finite);
    if (c->expect == GS_OK) {
        if (r.err != GS_OK)
            print_error("%s: unexpected refusal %s: %s\n", c->name, r.diag.field, r.diag.message);
        assert_int_equal(r.err, GS_OK);
        assert_int_equal(r.steps, n);
        assert_true(r.drift <= tol);
        if (r.pen_limit > 0 && strstr(c->scene, "contact"))
            /* Penetration is of order v h (METHOD.md section 3): within
             * the 0.1 module the contact resolves. */
            assert_true(r.pen <= r.pen_limit);
        else if (r.pen_limit > 0)
            /* The impact mesh projects positions onto the flank: round-off
             * of s = a . q (1e-9 of the half backlash, as test_rattle.c). */
            assert_true(r.pen <= 1e-9 * r.pen_limit);
    } else {
        assert_int_equal(r.err, c->expect);
        assert_non_null(strstr(r.diag.field, c->field));
        assert_true(strlen(r.diag.message) > 20);
        if (c->at_load)
            assert_int_equal(r.steps, 0);
        else
            /* Refused after a step: the steps before kept the balance. */
            assert_true(r.drift <= tol);
    }
}

static void header(const char *title)
{
    print_message("\n%s (%s mode)\n\n| case | steps | drift | energy scale (J) | penetration / limit (m) | wall (s) | outcome |\n"
                  "|---|---|---|---|---|---|---|\n", title, long_mode() ? "long" : "fast");
}

static void check_all(const char *title, const xcase *cs, size_t n)
{
    header(title);
    for (size_t k = 0; k < n; k++)
        check(&cs[k]);
}

#define CHECK_ALL(title, cs) check_all(title, cs, sizeof cs / sizeof cs[0])
#define TS "numerics.time_step"

/* name, scene, mesh model, h, rpm, free, E, I ratio, rho0, rho1, flank, across, rim, refine,
 * fast steps, long steps, expect, field, at load */
static const xcase kinematic[] = {
    {"h 1e-9", "pair", "kinematic", 1e-9, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"h 1e-3", "pair", "kinematic", 1e-3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"0.1 rpm, free", "pair", "kinematic", 0, 0.1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"60000 rpm, free", "pair", "kinematic", 0, 60000, 1, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"60000 rpm, h 1e-3", "pair", "kinematic", 1e-3, 60000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"inertia ratio 1e-3", "pair", "kinematic", 0, 0, 0, 0, 1e-3, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"inertia ratio 1e3", "pair", "kinematic", 0, 0, 0, 0, 1e3, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"1e6 steps", "pair", "kinematic", 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000000, 1000000, GS_OK, NULL, 0},
    {"planetary, 1e6 steps", "planetary", "kinematic", 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000000, GS_OK, NULL, 0},
};

static const xcase lumped[] = {
    {"h 1e-9", "pair", NULL, 1e-9, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"h 1e-7", "pair", NULL, 1e-7, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"h 1e-4", "pair", NULL, 1e-4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"h 1e-3", "pair", NULL, 1e-3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000, 10000, GS_OK, NULL, 0},
    {"0.1 rpm, free", "pair", NULL, 0, 0.1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"60000 rpm, free", "pair", NULL, 0, 60000, 1, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"60000 rpm, h 1e-4", "pair", NULL, 1e-4, 60000, 1, 0, 0, 0, 0, 0, 0, 0, 0, 1000, 1000, GS_ERANGE, TS, 1},
    {"60000 rpm, h 1e-3", "pair", NULL, 1e-3, 60000, 1, 0, 0, 0, 0, 0, 0, 0, 0, 1000, 1000, GS_ERANGE, TS, 1},
    {"constant k, 60000 rpm, h 1e-3", "pair", "lumped", 1e-3, 60000, 1, 0, 0, 0, 0, 0, 0, 0, 0, 1000, 10000, GS_OK, NULL, 0},
    {"inertia ratio 1e-3", "pair", NULL, 0, 0, 0, 0, 1e-3, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"inertia ratio 1e3", "pair", NULL, 0, 0, 0, 0, 1e3, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"1e6 steps", "pair", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000000, 1000000, GS_OK, NULL, 0},
    {"planetary, 1e6 steps", "planetary", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000000, GS_OK, NULL, 0},
};

static const xcase impact[] = {
    {"h 1e-9", "rattle", NULL, 1e-9, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"h 1e-3", "rattle", NULL, 1e-3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000, 10000, GS_OK, NULL, 0},
    {"0.1 rpm", "rattle", NULL, 0, 0.1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"60000 rpm", "rattle", NULL, 0, 60000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"60000 rpm, h 1e-3", "rattle", NULL, 1e-3, 60000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000, 10000, GS_OK, NULL, 0},
    {"inertia ratio 1e-3", "rattle", NULL, 0, 0, 0, 0, 1e-3, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"inertia ratio 1e3", "rattle", NULL, 0, 0, 0, 0, 1e3, 0, 0, 0, 0, 0, 0, 10000, 100000, GS_OK, NULL, 0},
    {"1e6 steps", "rattle", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000000, 1000000, GS_OK, NULL, 0},
};

static const xcase elastic[] = {
    {"spin h 1e-9", "elastic_spin", NULL, 1e-9, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 200, 10000, GS_OK, NULL, 0},
    {"spin h 1e-3", "elastic_spin", NULL, 1e-3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 200, 10000, GS_OK, NULL, 0},
    {"spin 0.1 rpm", "elastic_spin", NULL, 0, 0.1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 200, 10000, GS_OK, NULL, 0},
    {"spin 60000 rpm", "elastic_spin", NULL, 0, 60000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 200, 10000, GS_OK, NULL, 0},
    {"spin E 1 GPa", "elastic_spin", NULL, 0, 0, 0, 1e9, 0, 0, 0, 0, 0, 0, 0, 200, 10000, GS_OK, NULL, 0},
    {"spin E 1000 GPa", "elastic_spin", NULL, 0, 0, 0, 1e12, 0, 0, 0, 0, 0, 0, 0, 200, 10000, GS_OK, NULL, 0},
    {"spin mesh 1/1/1 (one element across)", "elastic_spin", NULL, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 200, 1000000, GS_OK, NULL, 0},
    {"spin mesh refine 2", "elastic_spin", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 20, 1000, GS_OK, NULL, 0},
    {"spin mesh refine 3", "elastic_spin", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 3, 0, 100, GS_OK, NULL, 0},
    {"spin 1e5 steps", "elastic_spin", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 100000, GS_OK, NULL, 0},
    {"pair h 1e-9", "elastic_pair", NULL, 1e-9, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"pair h 1e-3", "elastic_pair", NULL, 1e-3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"pair 0.1 rpm, free", "elastic_pair", NULL, 0, 0.1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"pair 60000 rpm, free", "elastic_pair", NULL, 0, 60000, 1, 0, 0, 0, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"pair E 1 GPa", "elastic_pair", NULL, 0, 0, 0, 1e9, 0, 0, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"pair E 1000 GPa", "elastic_pair", NULL, 0, 0, 0, 1e12, 0, 0, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"pair density ratio 1e-3", "elastic_pair", NULL, 0, 0, 0, 0, 0, 0, 7.85, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"pair density ratio 1e3 (light pinion)", "elastic_pair", NULL, 0, 0, 0, 0, 0, 7.85, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"pair density ratio 1e3 (heavy wheel)", "elastic_pair", NULL, 0, 0, 0, 0, 0, 0, 7.85e6, 0, 0, 0, 0, 100, 100, GS_ERANGE, "bodies[1].material.density", 1},
    {"pair 3e4 steps (0.3 s)", "elastic_pair", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 30000, GS_OK, NULL, 0},
};

static const xcase contact[] = {
    {"impact h 1e-9", "contact_impact", NULL, 1e-9, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 50, 2000, GS_OK, NULL, 0},
    {"impact h 1e-5", "contact_impact", NULL, 1e-5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 100, 2000, GS_OK, NULL, 0},
    {"impact h 1e-4", "contact_impact", NULL, 1e-4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 50, 50, GS_ERANGE, TS, 1},
    {"impact h 1e-3", "contact_impact", NULL, 1e-3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 50, 50, GS_ERANGE, TS, 1},
    {"impact 0.1 rpm", "contact_impact", NULL, 0, 0.1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 50, 2000, GS_OK, NULL, 0},
    {"impact 60000 rpm", "contact_impact", NULL, 0, 60000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 50, 50, GS_ERANGE, TS, 0},
    {"impact 60000 rpm, h 1e-8", "contact_impact", NULL, 1e-8, 60000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 50, 500, GS_OK, NULL, 0},
    /* 4.8 kJ of a 60000 rpm wheel striking a pinion at rest: the teeth
     * deform beyond anything a small-strain model describes and the
     * penetration jumps (about 0.7 mm near step 685, not v h = 2 um). */
    {"impact 60000 rpm, h 1e-8, 2000 steps", "contact_impact", NULL, 1e-8, 60000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2000, GS_ERANGE, TS, 0},
    {"impact E 1 GPa", "contact_impact", NULL, 0, 0, 0, 1e9, 0, 0, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"impact E 1000 GPa", "contact_impact", NULL, 0, 0, 0, 1e12, 0, 0, 0, 0, 0, 0, 0, 100, 5000, GS_OK, NULL, 0},
    {"impact mesh 1/1/1 (one element across)", "contact_impact", NULL, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 100, 20000, GS_OK, NULL, 0},
    {"impact mesh refine 1", "contact_impact", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 30, 1000, GS_OK, NULL, 0},
    {"impact mesh refine 2", "contact_impact", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 100, GS_OK, NULL, 0},
    {"impact 1e4 steps", "contact_impact", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, GS_OK, NULL, 0},
    {"drive h 1e-4", "contact_drive", NULL, 1e-4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1000, 1000, GS_ERANGE, TS, 0},
    {"drive h 1e-3", "contact_drive", NULL, 1e-3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 100, 100, GS_ERANGE, TS, 0},
    {"drive 10000 rpm", "contact_drive", NULL, 0, 10000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 100, 2000, GS_OK, NULL, 0},
    {"drive 60000 rpm, h 1e-6", "contact_drive", NULL, 1e-6, 60000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 100, 100, GS_ERANGE, TS, 0},
    {"drive density ratio 1e-3", "contact_drive", NULL, 0, 0, 0, 0, 0, 0, 7.85, 0, 0, 0, 0, 100, 2000, GS_OK, NULL, 0},
    {"drive density ratio 1e3", "contact_drive", NULL, 0, 0, 0, 0, 0, 7.85, 0, 0, 0, 0, 0, 100, 1000, GS_OK, NULL, 0},
    /* The 1000 times lighter driving wheel bounces between its flanks ever
     * faster; near 19 ms it approaches at ~30 m/s, beyond what 1e-5 s
     * resolves. */
    {"drive density ratio 1e3, 2000 steps", "contact_drive", NULL, 0, 0, 0, 0, 0, 7.85, 0, 0, 0, 0, 0, 0, 2000, GS_ERANGE, TS, 0},
    {"drive E 1 GPa", "contact_drive", NULL, 0, 0, 0, 1e9, 0, 0, 0, 0, 0, 0, 0, 100, 2000, GS_OK, NULL, 0},
    {"drive 1e4 steps (seed 7.2, 0.1 s)", "contact_drive", NULL, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 10000, GS_OK, NULL, 0},
};

static void rigid_kinematic(void **state)
{
    (void)state;
    CHECK_ALL("rigid + kinematic (pair, planetary)", kinematic);
}

static void rigid_lumped(void **state)
{
    (void)state;
    CHECK_ALL("rigid + lumped (pair, planetary)", lumped);
}

static void rigid_impact(void **state)
{
    (void)state;
    CHECK_ALL("rigid + impact (rattle)", impact);
}

static void elastic_bodies(void **state)
{
    (void)state;
    CHECK_ALL("elastic (elastic_spin, elastic_pair)", elastic);
}

static void contact_meshes(void **state)
{
    (void)state;
    CHECK_ALL("contact (contact_impact, contact_drive)", contact);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rigid_kinematic),
        cmocka_unit_test(rigid_lumped),
        cmocka_unit_test(rigid_impact),
        cmocka_unit_test(elastic_bodies),
        cmocka_unit_test(contact_meshes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
