/* SPDX-License-Identifier: MIT
 * Scene parsing (scene.c, docs/reference/scene.md): gear meshes (model, stiffness,
 * damping, contact and impact settings) and loads. */
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

static const char *const gmesh_keys[] = {"name", "gears", "model", "stiffness", "damping",
                                         "damping_ratio", "backlash_mm", "passes", "constrain", "friction",
                                         "friction_scheme", "restitution", "law", "patches", "bending", "transition",
                                         "max_line_load_n_per_mm", "misalignment", "nearfield", NULL};
static const char *const stiff_keys[] = {"type",      "value",     "single",      "double",
                                         "transition", "positions", "calibration", NULL};
static const char *const load_keys[] = {"name", "body", "type", "moment", "ramp_time",
                                        "coefficient", "times", "moments", NULL};

/* meshes[i].misalignment: {"in_plane_um", "out_of_plane_um"}, the
 * deviation of one axis from the other over the common face width, in the
 * plane of action and across it (ISO 6336-1 f_ma splits into these); for
 * the slice analysis (docs/explanation/helical.md). */
static gs_err parse_misalignment(json_object *o, const char *path, gs_scene_mesh *m, gs_diag *d)
{
    static const char *const keys[] = {"in_plane_um", "out_of_plane_um", NULL};
    json_object *mo;
    GS_TRY(gsi_json_object(o, "misalignment", path, false, &mo, d));
    if (!mo)
        return GS_OK;
    char p[256];
    double x;
    gsi_path(p, sizeof p, path, "misalignment");
    GS_TRY(gsi_json_only(mo, p, keys, d));
    GS_TRY(gsi_json_number(mo, "in_plane_um", p, -1000, 1000, false, 0, &x, d));
    m->misalign_in = x * 1e-6;
    GS_TRY(gsi_json_number(mo, "out_of_plane_um", p, -1000, 1000, false, 0, &x, d));
    m->misalign_out = x * 1e-6;
    return GS_OK;
}

gs_err gsi_scene_parse_gear_mesh(gs_scene *s, json_object *o, const char *path, gs_scene_mesh *m,
                                 gs_diag *d)
{
    static const char *const models[] = {"kinematic", "lumped", "contact", "impact", "compliant", "ltca"};
    static const char *const laws[] = {"newton", "poisson", "stronge"}; /* gs_restitution order */
    static const char *const stypes[] = {"constant", "rectangular", "calibrated"};
    static const char *const passes[] = {"two", "one"};
    static const char *const constrain[] = {"touching", "predicted"};
    static const char *const fschemes[] = {"implicit", "explicit"};
    if (json_object_get_type(o) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, path, "a mesh must be an object");
    GS_TRY(gsi_json_only(o, path, gmesh_keys, d));
    GS_TRY(gsi_json_string(o, "name", path, true, NULL, m->name, sizeof m->name, d));
    json_object *g;
    char p[256];
    GS_TRY(gsi_json_array(o, "gears", path, true, &g, d));
    gsi_path(p, sizeof p, path, "gears");
    if (json_object_array_length(g) != 2)
        return gs_diag_set(d, GS_ESCHEMA, p, "'gears' must name exactly two gears");
    for (int i = 0; i < 2; i++) {
        json_object *v = json_object_array_get_idx(g, (size_t)i);
        if (json_object_get_type(v) != json_type_string)
            return gs_diag_set(d, GS_ESCHEMA, p, "'gears' must hold body names");
        int bi = gs_scene_find_body(s, json_object_get_string(v));
        if (bi < 0)
            return gs_diag_set(d, GS_ENOTFOUND, p, "no body named '%s'", json_object_get_string(v));
        if (s->bodies[bi].type != GS_BODY_GEAR)
            return gs_diag_set(d, GS_ERANGE, p, "'%s' is not a gear", s->bodies[bi].name);
        m->gear[i] = bi;
    }
    if (m->gear[0] == m->gear[1])
        return gs_diag_set(d, GS_ERANGE, p, "a gear cannot mesh with itself");
    int model;
    GS_TRY(gsi_scene_enum_field(o, "model", path, NULL, models, 6, &model, d));
    m->model = (gs_mesh_model)model;
    GS_TRY(parse_misalignment(o, path, m, d));
    m->damping = -1;
    m->damping_ratio = 0.05;
    m->backlash = 0;
    m->restitution = 0.7;
    m->law = 2; /* stronge */
    if (m->model != GS_MESH_IMPACT) {
        static const char *const no[] = {"restitution", "law", NULL};
        for (const char *const *k = no; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "'%s' belongs to impact meshes", *k);
            }
    }
    if (m->model != GS_MESH_CONTACT) {
        static const char *const no[] = {"passes", "constrain", "friction", "friction_scheme", "nearfield", NULL};
        for (const char *const *k = no; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "'%s' belongs to contact meshes", *k);
            }
    }
    if (m->model != GS_MESH_COMPLIANT) {
        static const char *const no[] = {"patches", "bending", "transition", "max_line_load_n_per_mm", NULL};
        for (const char *const *k = no; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "'%s' belongs to compliant meshes", *k);
            }
    }
    if (m->model == GS_MESH_KINEMATIC || m->model == GS_MESH_CONTACT) {
        static const char *const no[] = {"stiffness", "damping", "damping_ratio", "backlash_mm", NULL};
        for (const char *const *k = no; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "a %s mesh has no '%s'", models[model], *k);
            }
    }
    if (m->model == GS_MESH_CONTACT) {
        int v;
        GS_TRY(gsi_scene_enum_field(o, "passes", path, "two", passes, 2, &v, d));
        m->one_pass = v;
        GS_TRY(gsi_scene_enum_field(o, "constrain", path, "touching", constrain, 2, &v, d));
        m->predict = v;
        GS_TRY(gsi_json_number(o, "friction", path, 0, 2, false, 0, &m->friction, d));
        GS_TRY(gsi_scene_enum_field(o, "friction_scheme", path, "implicit", fschemes, 2, &m->friction_explicit, d));
        bool nf = false;
        GS_TRY(gsi_json_bool(o, "nearfield", path, false, &nf, d));
        m->nearfield = nf;
        return GS_OK;
    }
    if (m->model == GS_MESH_KINEMATIC)
        return GS_OK;
    if (m->model == GS_MESH_IMPACT) {
        /* Rigid teeth with backlash and impacts: no spring, no damper. */
        static const char *const no[] = {"stiffness", "damping", "damping_ratio", NULL};
        for (const char *const *k = no; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "an impact mesh has no '%s'", *k);
            }
        double bl;
        /* Absent: 0 here, filled from the pair's geometry in check_train. */
        GS_TRY(gsi_json_positive(o, "backlash_mm", path, 100, false, 0, &bl, d));
        m->backlash = bl * 1e-3;
        GS_TRY(gsi_json_number(o, "restitution", path, 0, 1, false, 0.7, &m->restitution, d));
        GS_TRY(gsi_scene_enum_field(o, "law", path, "stronge", laws, 3, &m->law, d));
        return GS_OK;
    }
    if (m->model == GS_MESH_COMPLIANT) {
        /* Rigid gears, tooth pairs through the compliant patch model
         * (docs/explanation/impact.md "The compliant mesh"): no stiffness to give. */
        if (json_object_object_get_ex(o, "stiffness", NULL)) {
            gsi_path(p, sizeof p, path, "stiffness");
            return gs_diag_set(d, GS_ESCHEMA, p,
                               "a compliant mesh has no 'stiffness': its force comes from the patch model");
        }
        /* scene order kept: 0 beam, 1 none, 2 beam_foundation (the default) */
        static const char *const bend[] = {"beam", "none", "beam_foundation"};
        int64_t np;
        GS_TRY(gsi_json_int(o, "patches", path, 8, 400, false, 40, &np, d));
        m->patches = (int)np;
        GS_TRY(gsi_scene_enum_field(o, "bending", path, "beam_foundation", bend, 3, &m->bending, d));
        GS_TRY(gsi_json_number(o, "transition", path, 1e-3, 0.5, false, 0.05, &m->transition, d));
        double pl, bl;
        GS_TRY(gsi_json_positive(o, "max_line_load_n_per_mm", path, 1e5, false, 1000, &pl, d));
        m->max_line_load = pl * 1e3;
        if (json_object_object_get_ex(o, "damping", NULL) && json_object_object_get_ex(o, "damping_ratio", NULL))
            return gs_diag_set(d, GS_ESCHEMA, path, "give 'damping' or 'damping_ratio', not both");
        GS_TRY(gsi_json_number(o, "damping", path, 0, 1e9, false, -1, &m->damping, d));
        GS_TRY(gsi_json_number(o, "damping_ratio", path, 0, 10, false, 0.05, &m->damping_ratio, d));
        GS_TRY(gsi_json_number(o, "backlash_mm", path, 0, 100, false, 0, &bl, d));
        m->backlash = bl * 1e-3;
        return GS_OK;
    }
    if (m->model == GS_MESH_LTCA) {
        /* Rigid gears, the loaded tooth contact analysis' tables
         * (docs/explanation/ltca.md): stiffness and backlash come from the
         * pair's geometry. Damping: given, else the gears' material damping
         * of the mesh mode, else 5 % (damping_ratio -1: not given). */
        static const char *const no[] = {"stiffness", "backlash_mm", NULL};
        for (const char *const *k = no; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p,
                                   "an ltca mesh has no '%s': the pair's quasi-static analysis gives it", *k);
            }
        if (json_object_object_get_ex(o, "damping", NULL) && json_object_object_get_ex(o, "damping_ratio", NULL))
            return gs_diag_set(d, GS_ESCHEMA, path, "give 'damping' or 'damping_ratio', not both");
        GS_TRY(gsi_json_number(o, "damping", path, 0, 1e9, false, -1, &m->damping, d));
        GS_TRY(gsi_json_number(o, "damping_ratio", path, 0, 10, false, -1, &m->damping_ratio, d));
        return GS_OK;
    }
    /* Default stiffness: ISO 6336 order of magnitude, 14 N/(mm um) single-tooth
     * stiffness per mm of face width, twice that in double contact. */
    double b1 = s->bodies[m->gear[0]].gear.face_width_m, b2 = s->bodies[m->gear[1]].gear.face_width_m;
    double k1 = 14e9 * (b1 < b2 ? b1 : b2);
    m->stiffness_type = GS_STIFF_RECTANGULAR;
    m->transition = 0.05;
    m->k_single = k1;
    m->k_double = 2 * k1;
    json_object *st;
    if (json_object_object_get_ex(o, "stiffness", &st)) {
        gsi_path(p, sizeof p, path, "stiffness");
        double x;
        if (json_object_get_type(st) == json_type_object) {
            GS_TRY(gsi_json_only(st, p, stiff_keys, d));
            int ty;
            GS_TRY(gsi_scene_enum_field(st, "type", p, NULL, stypes, 3, &ty, d));
            m->stiffness_type = (gs_stiffness_type)ty;
            if (ty == GS_STIFF_CALIBRATED) {
                /* From the quasi-static FE analysis of the pair at load
                 * (docs/explanation/stiffness.md), at the gears' scene mesh density. */
                int64_t np;
                GS_TRY(gsi_json_int(st, "positions", p, 4, 720, false, 24, &np, d));
                m->calibrate_positions = (int)np;
                static const char *const claws[] = {"tangent", "secant", "modal"};
                int cl;
                GS_TRY(gsi_scene_enum_field(st, "calibration", p, "tangent", claws, 3, &cl, d));
                m->calibrate_secant = cl == 1;
                m->calibrate_modal = cl == 2;
            } else if (json_object_object_get_ex(st, "calibration", NULL)) {
                char q[256];
                gsi_path(q, sizeof q, p, "calibration");
                return gs_diag_set(d, GS_ESCHEMA, q, "'calibration' belongs to a calibrated stiffness");
            } else if (ty == GS_STIFF_CONSTANT) {
                GS_TRY(gsi_json_positive(st, "value", p, 1e14, true, 0, &m->k_single, d));
                m->k_double = m->k_single;
            } else {
                GS_TRY(gsi_json_positive(st, "single", p, 1e14, true, 0, &m->k_single, d));
                GS_TRY(gsi_json_positive(st, "double", p, 1e14, true, 0, &m->k_double, d));
                GS_TRY(gsi_json_number(st, "transition", p, 1e-4, 0.5, false, 0.05, &m->transition, d));
            }
        } else if (gsi_json_as_double(st, &x) ||
                   json_object_get_type(st) == json_type_double) {
            GS_TRY(gsi_json_positive(o, "stiffness", path, 1e14, true, 0, &x, d));
            m->stiffness_type = GS_STIFF_CONSTANT;
            m->k_single = m->k_double = x;
        } else {
            return gs_diag_set(d, GS_ESCHEMA, p, "'stiffness' must be a number or an object");
        }
    }
    if (json_object_object_get_ex(o, "damping", NULL) &&
        json_object_object_get_ex(o, "damping_ratio", NULL))
        return gs_diag_set(d, GS_ESCHEMA, path, "give 'damping' or 'damping_ratio', not both");
    GS_TRY(gsi_json_number(o, "damping", path, 0, 1e9, false, -1, &m->damping, d));
    GS_TRY(gsi_json_number(o, "damping_ratio", path, 0, 10, false, 0.05, &m->damping_ratio, d));
    double bl;
    GS_TRY(gsi_json_number(o, "backlash_mm", path, 0, 100, false, 0, &bl, d));
    m->backlash = bl * 1e-3;
    return GS_OK;
}

gs_err gs_scene_parse_load(const gs_scene *s, json_object *o, const char *path,
                           gs_scene_load *l, gs_diag *d)
{
    static const char *const types[] = {"constant", "ramp", "brake", "table"};
    memset(l, 0, sizeof *l);
    if (!o || json_object_get_type(o) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, path, "a load must be an object");
    GS_TRY(gsi_json_only(o, path, load_keys, d));
    char name[GS_NAME_MAX], p[256];
    GS_TRY(gsi_json_string(o, "body", path, true, NULL, name, sizeof name, d));
    l->body = gs_scene_find_body(s, name);
    gsi_path(p, sizeof p, path, "body");
    if (l->body < 0)
        return gs_diag_set(d, GS_ENOTFOUND, p, "no body named '%s'", name);
    if (s->bodies[l->body].joint == GS_JOINT_HELD)
        return gs_diag_set(d, GS_ERANGE, p, "'%s' is held and cannot take a moment", name);
    int t;
    GS_TRY(gsi_scene_enum_field(o, "type", path, NULL, types, 4, &t, d));
    l->type = (gs_load_type)t;
    /* Default name body:type; a body name too long for that keeps its first
     * 40 bytes and gets its index, so that two bodies never share it. */
    char defname[GS_NAME_MAX];
    if (strlen(name) + 1 + strlen(types[t]) < sizeof defname)
        snprintf(defname, sizeof defname, "%.54s:%.8s", name, types[t]);
    else
        snprintf(defname, sizeof defname, "%.40s#%d:%.8s", name, l->body, types[t]);
    GS_TRY(gsi_json_string(o, "name", path, false, defname, l->name, sizeof l->name, d));
    const char *need[4][3] = {{"moment", NULL, NULL}, {"moment", "ramp_time", NULL},
                              {"coefficient", NULL, NULL}, {"times", "moments", NULL}};
    for (int i = 0; load_keys[i]; i++) {
        const char *k = load_keys[i];
        if (!strcmp(k, "name") || !strcmp(k, "body") || !strcmp(k, "type"))
            continue;
        bool wanted = false;
        for (int j = 0; j < 3 && need[t][j]; j++)
            wanted |= strcmp(need[t][j], k) == 0;
        if (!wanted && json_object_object_get_ex(o, k, NULL)) {
            gsi_path(p, sizeof p, path, k);
            return gs_diag_set(d, GS_ESCHEMA, p, "a %s load has no '%s'", types[t], k);
        }
    }
    switch (l->type) {
    case GS_LOAD_CONSTANT:
        return gsi_json_number(o, "moment", path, -1e9, 1e9, true, 0, &l->moment, d);
    case GS_LOAD_RAMP:
        GS_TRY(gsi_json_number(o, "moment", path, -1e9, 1e9, true, 0, &l->moment, d));
        return gsi_json_positive(o, "ramp_time", path, 1e6, true, 0, &l->ramp_time, d);
    case GS_LOAD_BRAKE:
        return gsi_json_number(o, "coefficient", path, 0, 1e9, true, 0, &l->coefficient, d);
    case GS_LOAD_TABLE: {
        json_object *tt, *mm;
        GS_TRY(gsi_json_array(o, "times", path, true, &tt, d));
        GS_TRY(gsi_json_array(o, "moments", path, true, &mm, d));
        size_t n = json_object_array_length(tt);
        gsi_path(p, sizeof p, path, "moments");
        if (n != json_object_array_length(mm))
            return gs_diag_set(d, GS_ESCHEMA, p, "'times' and 'moments' must have the same length");
        gsi_path(p, sizeof p, path, "times");
        if (n < 1 || n > MAX_TABLE)
            return gs_diag_set(d, GS_ERANGE, p, "a table needs 1 to %d entries", MAX_TABLE);
        l->times = gs_calloc(n, sizeof(double));
        l->moments = gs_calloc(n, sizeof(double));
        if (!l->times || !l->moments) {
            gs_scene_load_clear(l);
            return GS_ENOMEM;
        }
        l->n_table = (int)n;
        for (size_t i = 0; i < n; i++) {
            char pi[256];
            if (!gsi_json_as_double(json_object_array_get_idx(tt, i), &l->times[i]) ||
                (i > 0 && !(l->times[i] > l->times[i - 1]))) {
                gsi_path_index(pi, sizeof pi, path, "times", (int)i);
                gs_scene_load_clear(l);
                return gs_diag_set(d, GS_ERANGE, pi, "times must be finite and increasing");
            }
            if (!gsi_json_as_double(json_object_array_get_idx(mm, i), &l->moments[i]) ||
                fabs(l->moments[i]) > 1e9) {
                gsi_path_index(pi, sizeof pi, path, "moments", (int)i);
                gs_scene_load_clear(l);
                return gs_diag_set(d, GS_ERANGE, pi, "moments must be finite numbers");
            }
        }
        return GS_OK;
    }
    }
    return GS_OK;
}
