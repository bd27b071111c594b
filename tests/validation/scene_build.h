/* SPDX-License-Identifier: MIT
 * Shared by the validation tests: a system from an (edited) builtin scene.
 * Include after cmocka.h. */
#ifndef GEARSIM_TESTS_SCENE_BUILD_H
#define GEARSIM_TESTS_SCENE_BUILD_H

#include <json-c/json.h>
#include <math.h>
#include <string.h>

#include "gearsim/contact.h"
#include "gearsim/modal.h"
#include "gearsim/step.h"

/* The builtin scene `name` as a JSON tree to edit (the caller passes it on
 * to vt_system). */
static inline json_object *vt_scene(const char *name)
{
    json_object *root = json_tokener_parse(gs_scene_builtin(name));
    assert_non_null(root);
    return root;
}

/* The mesh object of scene body b, added empty when the body has none. */
static inline json_object *vt_body_mesh(json_object *b)
{
    json_object *m;
    if (!json_object_object_get_ex(b, "mesh", &m)) {
        m = json_object_new_object();
        json_object_object_add(b, "mesh", m);
    }
    return m;
}

/* vt_pin_linear: every gear of a scene tree meshed with linear triangles
 * (mesh.order 1 and the linear default counts; a train's gears through
 * train.mesh). For the long dynamic runs whose figures were measured on the
 * linear mesh and which need some elastic gear, not the default quadratic
 * one (about 12 times the cost per contact step, docs/performance/index.md); the
 * default mesh's dynamics are checked in test_elastic_train (free spin),
 * test_fe_dynamic, test_calibrated, test_ranks and test_resume.
 * vt_scene_linear: the builtin scene `name` so pinned. */
static inline void vt_pin_linear(json_object *root)
{
    json_object *bs, *tr;
    if (json_object_object_get_ex(root, "train", &tr)) {
        json_object *m = json_object_new_object();
        json_object_object_add(m, "order", json_object_new_int(1));
        json_object_object_add(tr, "mesh", m);
    }
    if (json_object_object_get_ex(root, "bodies", &bs))
        for (size_t i = 0; i < json_object_array_length(bs); i++) {
            json_object *b = json_object_array_get_idx(bs, i), *t;
            if (json_object_object_get_ex(b, "type", &t) && strcmp(json_object_get_string(t), "gear") != 0)
                continue;
            json_object_object_add(vt_body_mesh(b), "order", json_object_new_int(1));
        }
}

static inline json_object *vt_scene_linear(const char *name)
{
    json_object *root = vt_scene(name);
    vt_pin_linear(root);
    return root;
}

/* numerics.contact of a scene tree set to `scheme` (numerics added when
 * absent): the tests whose figures were measured with the seed's scheme
 * name "seed", the default of a scene with contact meshes being
 * "closure_energy". */
static inline json_object *vt_contact_scheme(json_object *root, const char *scheme)
{
    json_object *num;
    if (!json_object_object_get_ex(root, "numerics", &num)) {
        num = json_object_new_object();
        json_object_object_add(root, "numerics", num);
    }
    json_object_object_add(num, "contact", json_object_new_string(scheme));
    return root;
}

/* Parse the scene; consumes root. Fails the test with the diagnostic. */
static inline gs_scene *vt_scene_parse(json_object *root)
{
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc;
    gs_diag d;
    gs_err e = gs_scene_parse(txt, strlen(txt), &sc, &d);
    if (e != GS_OK)
        print_error("scene: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    json_object_put(root);
    return sc;
}

/* Parse and build the system on one rank; consumes root. Fails the test
 * with the diagnostic on any error. */
static inline gs_system *vt_system(json_object *root)
{
    gs_scene *sc = vt_scene_parse(root);
    gs_diag d;
    gs_system *sys;
    gs_err e = gs_system_new(sc, 0, 1, &sys, &d);
    if (e != GS_OK)
        print_error("system: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return sys;
}

/* One serial step (fails the test on error), leaving the energies after it
 * in *e: raises *worst to the largest |balance residual| and *scale to the
 * largest energy figure (total, work in, dissipated) seen so far. */
static inline void vt_step_balance(gs_system *s, gs_energy *e, double *worst, double *scale)
{
    assert_int_equal(gs_step_serial(s), GS_OK);
    gs_system_energy(s, e);
    *worst = fmax(*worst, fabs(e->balance_residual));
    *scale = fmax(*scale, fmax(e->total, fmax(e->work_in, e->dissipated)));
}

/* The joint of `body` in a scene tree (fails the test without one). */
static inline json_object *vt_joint_of(json_object *root, const char *body)
{
    json_object *js = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(js); i++) {
        json_object *j = json_object_array_get_idx(js, i);
        if (!strcmp(json_object_get_string(json_object_object_get(j, "body")), body))
            return j;
    }
    fail_msg("no joint for %s", body);
    return NULL;
}

/* The scene's loads replaced by one moment table on `body`: moments mo
 * (N m) at times t (s), n points. */
static inline void vt_moment_table(json_object *root, const char *body, const double *t, const double *mo, int n)
{
    json_object *loads = json_object_new_array(), *l = json_object_new_object();
    json_object_object_add(l, "body", json_object_new_string(body));
    json_object *tt = json_object_new_array(), *mm = json_object_new_array();
    for (int k = 0; k < n; k++) {
        json_object_array_add(tt, json_object_new_double(t[k]));
        json_object_array_add(mm, json_object_new_double(mo[k]));
    }
    json_object_object_add(l, "type", json_object_new_string("table"));
    json_object_object_add(l, "times", tt);
    json_object_object_add(l, "moments", mm);
    json_object_array_add(loads, l);
    json_object_object_add(root, "loads", loads);
}

/* The contact forces on body b's centre in the last step, scene frame: the
 * rows' reactions on its translation, sum of lambda dg/dc over the rows of
 * its meshes (the generalised force G^T lambda the step gave it). */
static inline void vt_centre_force(const gs_system *s, int b, double F[2])
{
    F[0] = F[1] = 0.0;
    for (int i = 0; i < gs_step_contact_rows(s); i++) {
        int mi;
        double lam;
        const gs_contact_row *r = gs_step_contact_row(s, i, &mi, &lam);
        for (int k = 0; k < 2; k++)
            if (s->scene->meshes[mi].gear[k] == b) {
                F[0] += lam * r->dg_dc[k][0];
                F[1] += lam * r->dg_dc[k][1];
            }
    }
}

/* The modal analysis (gs_modal_analyse) of a scene tree (consumed); fails
 * the test with the diagnostic. */
static inline gs_modal *vt_modal(json_object *root)
{
    gs_scene *sc = vt_scene_parse(root);
    gs_diag d;
    gs_modal *m;
    gs_err e = gs_modal_analyse(sc, &m, &d);
    if (e != GS_OK)
        print_message("modal: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    gs_scene_free(&sc);
    return m;
}

#endif
