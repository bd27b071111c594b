/* SPDX-License-Identifier: MIT
 * Scene parsing (scene.c, docs/reference/scene.md): the `fidelity` switch and the
 * `train` shorthand expanded into bodies, joints and meshes. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/mesh.h"
#include "gearsim/scene.h"
#include "gearsim/util.h"
#include "scene/jsonstrict.h"
#include "scene/jsonv.h"
#include "scene/scene_internal.h"
#include "scene/scene_mods.h"

/* `fidelity` switches a whole scene along the ladder with one field
 * (METHOD.md section 7): every gear's body model and every mesh's model
 * are set, and the model-specific mesh fields dropped (the chosen model's
 * defaults apply). Works on a copy: *out is the tree to validate (root
 * itself, or a new tree the caller frees when *copy is set). */
gs_err gsi_scene_apply_fidelity(json_object *root, json_object **out, bool *copy, gs_diag *d)
{
    static const char *const levels[] = {"as_given", "kinematic", "lumped", "contact", "compliant", "ltca"};
    *out = root;
    *copy = false;
    int lv;
    GS_TRY(gsi_scene_enum_field(root, "fidelity", "", "as_given", levels, 6, &lv, d));
    if (lv == 0)
        return GS_OK;
    json_object *c = NULL;
    if (json_object_deep_copy(root, &c, NULL) != 0 || !c)
        return GS_ENOMEM;
    json_object *bs = NULL, *ms = NULL;
    if (json_object_object_get_ex(c, "bodies", &bs) && json_object_get_type(bs) == json_type_array)
        for (size_t i = 0; i < json_object_array_length(bs); i++) {
            json_object *b = json_object_array_get_idx(bs, i), *t = NULL;
            if (json_object_get_type(b) != json_type_object)
                continue;
            bool carrier = json_object_object_get_ex(b, "type", &t) &&
                           json_object_get_type(t) == json_type_string &&
                           !strcmp(json_object_get_string(t), "carrier");
            if (!carrier)
                json_object_object_add(b, "model", json_object_new_string(lv == 3 ? "elastic" : "rigid"));
        }
    if (json_object_object_get_ex(c, "meshes", &ms) && json_object_get_type(ms) == json_type_array)
        for (size_t i = 0; i < json_object_array_length(ms); i++) {
            json_object *m = json_object_array_get_idx(ms, i);
            if (json_object_get_type(m) != json_type_object)
                continue;
            static const char *const drop[] = {"stiffness", "damping", "damping_ratio", "backlash_mm",
                                               "passes", "constrain", "friction", "friction_scheme",
                                               "restitution", "law",
                                               "patches", "bending", "transition", "max_line_load_n_per_mm",
                                               NULL};
            for (const char *const *k = drop; *k; k++)
                json_object_object_del(m, *k);
            json_object_object_add(m, "model", json_object_new_string(levels[lv]));
        }
    *out = c;
    *copy = true;
    return GS_OK;
}

/* A gear object of the train description with the shared fields filled in. */
static json_object *train_gear(json_object *tr, const char *key, const char *name, const char *model)
{
    json_object *g = NULL, *src = NULL;
    if (json_object_object_get_ex(tr, key, &src) && json_object_get_type(src) == json_object_get_type(tr))
        json_object_deep_copy(src, &g, NULL);
    if (!g)
        g = json_object_new_object();
    static const char *const shared[] = {"module_mm", "face_width_mm", "pressure_angle_deg", "thinning_mm",
                                         "material", "mesh", NULL};
    for (const char *const *k = shared; *k; k++) {
        json_object *v;
        if (!json_object_object_get_ex(g, *k, NULL) && json_object_object_get_ex(tr, *k, &v)) {
            json_object *c = NULL;
            json_object_deep_copy(v, &c, NULL);
            json_object_object_add(g, *k, c);
        }
    }
    json_object_object_add(g, "name", json_object_new_string(name));
    json_object_object_add(g, "type", json_object_new_string("gear"));
    if (!strcmp(key, "ring"))
        json_object_object_add(g, "kind", json_object_new_string("internal"));
    if (!json_object_object_get_ex(g, "model", NULL))
        json_object_object_add(g, "model", json_object_new_string(model));
    return g;
}

/* `train: {type: "planetary", ...}` expands into bodies, joints and meshes
 * (docs/reference/scene.md): sun, planets on a carrier at the tight-mesh centre
 * distance (or radius_mm), ring held or on its own axis. Everything it
 * writes is then validated like a scene written out in full, so assembly
 * errors name the generated field (bodies[..], joints[..], meshes[..]). */
gs_err gsi_scene_expand_train(json_object *c, gs_diag *d)
{
    json_object *tr;
    if (!json_object_object_get_ex(c, "train", &tr))
        return GS_OK;
    if (json_object_get_type(tr) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, "train", "'train' must be an object");
    static const char *const keys[] = {"type", "module_mm", "face_width_mm", "pressure_angle_deg",
        "thinning_mm", "material", "mesh", "sun", "planet", "ring", "planets", "angles_deg", "radius_mm",
        "carrier", "model", "mesh_model", "ring_joint", NULL};
    GS_TRY(gsi_json_only(tr, "train", keys, d));
    static const char *const types[] = {"planetary"};
    int t;
    GS_TRY(gsi_scene_enum_field(tr, "type", "train", NULL, types, 1, &t, d));
    for (const char *const *k = (const char *const[]){"bodies", "joints", "meshes", NULL}; *k; k++)
        if (json_object_object_get_ex(c, *k, NULL))
            return gs_diag_set(d, GS_ESCHEMA, *k, "give either 'train' or '%s', not both", *k);
    static const char *const models[] = {"rigid", "elastic"};
    static const char *const mmodels[] = {"kinematic", "lumped", "contact", "compliant", "ltca"};
    static const char *const rj[] = {"held", "fixed_axis"};
    int bm, mm, ringj;
    GS_TRY(gsi_scene_enum_field(tr, "model", "train", "rigid", models, 2, &bm, d));
    GS_TRY(gsi_scene_enum_field(tr, "mesh_model", "train", "lumped", mmodels, 5, &mm, d));
    GS_TRY(gsi_scene_enum_field(tr, "ring_joint", "train", "held", rj, 2, &ringj, d));
    json_object *angles = NULL;
    GS_TRY(gsi_json_array(tr, "angles_deg", "train", false, &angles, d));
    int64_t np;
    GS_TRY(gsi_json_int(tr, "planets", "train", 1, 12, angles == NULL, angles ? (int64_t)json_object_array_length(angles) : 3, &np, d));
    if (angles && (int64_t)json_object_array_length(angles) != np)
        return gs_diag_set(d, GS_ESCHEMA, "train.angles_deg", "%d angles for %d planets",
                           (int)json_object_array_length(angles), (int)np);
    for (const char *const *k = (const char *const[]){"sun", "planet", "ring", NULL}; *k; k++) {
        json_object *g;
        char f[64];
        snprintf(f, sizeof f, "train.%s", *k);
        if (!json_object_object_get_ex(tr, *k, &g) || json_object_get_type(g) != json_type_object)
            return gs_diag_set(d, GS_ESCHEMA, f, "the train needs '%s': {teeth, ...}", *k);
    }
    json_object *carrier = NULL;
    GS_TRY(gsi_json_object(tr, "carrier", "train", true, &carrier, d));
    const char *model = models[bm];
    json_object *bodies = json_object_new_array(), *joints = json_object_new_array(),
                *meshes = json_object_new_array();
    json_object_array_add(bodies, train_gear(tr, "sun", "sun", model));
    for (int i = 0; i < np; i++) {
        char n[32];
        snprintf(n, sizeof n, "planet%d", i + 1);
        json_object_array_add(bodies, train_gear(tr, "planet", n, model));
    }
    json_object_array_add(bodies, train_gear(tr, "ring", "ring", model));
    json_object *cb = NULL;
    json_object_deep_copy(carrier, &cb, NULL);
    json_object_object_add(cb, "name", json_object_new_string("carrier"));
    json_object_object_add(cb, "type", json_object_new_string("carrier"));
    json_object_array_add(bodies, cb);
    /* Carrier radius: given, or the sun-planet tight-mesh distance of the
     * gears as described (validated again below with the full scene). */
    double radius = 0;
    GS_TRY(gsi_json_number(tr, "radius_mm", "train", 0, 1e5, false, 0, &radius, d));
    if (radius <= 0) {
        gs_scene_body sb, pb;
        memset(&sb, 0, sizeof sb);
        memset(&pb, 0, sizeof pb);
        json_object *g0 = json_object_array_get_idx(bodies, 0), *g1 = json_object_array_get_idx(bodies, 1);
        gs_err e = gsi_scene_parse_body(g0, "train.sun", &sb, d);
        if (e == GS_OK)
            e = gsi_scene_parse_body(g1, "train.planet", &pb, d);
        double a = 0;
        if (e == GS_OK)
            e = gs_pair_tight_centre_distance(&sb.gear, &pb.gear, &a, d);
        gs_gear_mods_free(&sb.mods);
        gs_gear_mods_free(&pb.mods);
        if (e != GS_OK) {
            json_object_put(bodies), json_object_put(joints), json_object_put(meshes);
            return e;
        }
        /* Halfway between the sun's and the ring's tight distances would
         * share the backlash; the sun's alone keeps the sun mesh tight. */
        radius = a * 1e3;
    }
    json_object *j = json_object_new_object();
    json_object_object_add(j, "body", json_object_new_string("sun"));
    json_object_object_add(j, "type", json_object_new_string("fixed_axis"));
    json_object_array_add(joints, j);
    j = json_object_new_object();
    json_object_object_add(j, "body", json_object_new_string("carrier"));
    json_object_object_add(j, "type", json_object_new_string("fixed_axis"));
    json_object_array_add(joints, j);
    for (int i = 0; i < np; i++) {
        char n[32];
        snprintf(n, sizeof n, "planet%d", i + 1);
        double ang = 360.0 * i / (double)np;
        if (angles) {
            json_object *v = json_object_array_get_idx(angles, (size_t)i);
            if (!gsi_json_as_double(v, &ang)) {
                json_object_put(bodies), json_object_put(joints), json_object_put(meshes);
                return gs_diag_set(d, GS_ESCHEMA, "train.angles_deg", "angles must be numbers (degrees)");
            }
        }
        j = json_object_new_object();
        json_object_object_add(j, "body", json_object_new_string(n));
        json_object_object_add(j, "type", json_object_new_string("on_carrier"));
        json_object_object_add(j, "carrier", json_object_new_string("carrier"));
        json_object_object_add(j, "radius_mm", json_object_new_double(radius));
        json_object_object_add(j, "angle_deg", json_object_new_double(ang));
        json_object_array_add(joints, j);
        for (int k = 0; k < 2; k++) {
            char mn[64];
            json_object *m = json_object_new_object(), *gs = json_object_new_array();
            snprintf(mn, sizeof mn, k ? "%s-ring" : "sun-%s", n);
            json_object_object_add(m, "name", json_object_new_string(mn));
            json_object_array_add(gs, json_object_new_string(k ? n : "sun"));
            json_object_array_add(gs, json_object_new_string(k ? "ring" : n));
            json_object_object_add(m, "gears", gs);
            json_object_object_add(m, "model", json_object_new_string(mmodels[mm]));
            json_object_array_add(meshes, m);
        }
    }
    j = json_object_new_object();
    json_object_object_add(j, "body", json_object_new_string("ring"));
    json_object_object_add(j, "type", json_object_new_string(rj[ringj]));
    json_object_array_add(joints, j);
    json_object_object_add(c, "bodies", bodies);
    json_object_object_add(c, "joints", joints);
    json_object_object_add(c, "meshes", meshes);
    json_object_object_del(c, "train");
    return GS_OK;
}
