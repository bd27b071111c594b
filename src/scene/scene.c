/* SPDX-License-Identifier: MIT
 * Scene parsing and validation (docs/reference/scene.md). Every value is checked and
 * defaulted here, so the layers below (geometry, models, step) can trust it. */
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

static const char *const top_keys[] = {"name", "bodies", "joints", "meshes", "loads",
                                       "numerics", "initial", "outputs", "description", "fidelity",
                                       "train", NULL};

static const char *const numerics_keys[] = {"time_step", "newton_tol", "max_newton", "adaptive", "contact", NULL};
static const char *const adaptive_keys[] = {"penetration_um", "levels", NULL};
static const char *const initial_keys[] = {"angle", "omega", "speed_rpm", "tip_load", NULL};
static const char *const outputs_keys[] = {"telemetry_every", "record_every", "fields_every",
                                            "checkpoint_every", NULL};

void gs_scene_body_centre(const gs_scene *s, int i, double c[2])
{
    const gs_scene_body *b = &s->bodies[i];
    if (b->joint == GS_JOINT_ON_CARRIER) {
        const gs_scene_body *cb = &s->bodies[b->carrier];
        c[0] = cb->centre[0] + b->carrier_radius * cos(b->carrier_angle);
        c[1] = cb->centre[1] + b->carrier_radius * sin(b->carrier_angle);
    } else if (b->joint == GS_JOINT_FIXED_AXIS || b->joint == GS_JOINT_BEARING) {
        c[0] = b->centre[0];
        c[1] = b->centre[1];
    } else {
        c[0] = c[1] = 0.0;
    }
}

int gs_scene_find_body(const gs_scene *s, const char *name)
{
    for (int i = 0; i < s->n_bodies; i++)
        if (strcmp(s->bodies[i].name, name) == 0)
            return i;
    return -1;
}

void gs_scene_load_clear(gs_scene_load *l)
{
    free(l->times);
    free(l->moments);
    l->times = l->moments = NULL;
    l->n_table = 0;
}

void gs_scene_free(gs_scene **ps)
{
    if (!ps || !*ps)
        return;
    gs_scene *s = *ps;
    for (int i = 0; i < s->n_loads; i++)
        gs_scene_load_clear(&s->loads[i]);
    for (int i = 0; s->bodies && i < s->n_bodies; i++)
        gs_gear_mods_free(&s->bodies[i].mods);
    free(s->bodies);
    free(s->meshes);
    free(s->loads);
    free(s->json);
    free(s->fidelity_choice);
    free(s);
    *ps = NULL;
}

static gs_err pick(const char *value, const char *const *names, int n, int *out)
{
    for (int i = 0; i < n; i++)
        if (strcmp(value, names[i]) == 0) {
            *out = i;
            return GS_OK;
        }
    return GS_ERANGE;
}

/* A string field that must be one of `names`; its index in *out. */
gs_err gsi_scene_enum_field(json_object *o, const char *key, const char *path, const char *def,
                            const char *const *names, int n, int *out, gs_diag *d)
{
    char buf[64];
    GS_TRY(gsi_json_string(o, key, path, def == NULL, def, buf, sizeof buf, d));
    if (pick(buf, names, n, out) != GS_OK) {
        char p[256], list[256] = "";
        gsi_path(p, sizeof p, path, key);
        for (int i = 0; i < n; i++) {
            strncat(list, names[i], sizeof list - strlen(list) - 3);
            if (i + 1 < n)
                strncat(list, ", ", sizeof list - strlen(list) - 1);
        }
        return gs_diag_set(d, GS_ERANGE, p, "'%s' must be one of: %s (got '%s')", key, list, buf);
    }
    return GS_OK;
}

/* Geometry's own diagnostics name the scene field; prefix the body path. */
gs_err gsi_scene_prefix_diag(gs_err e, gs_diag *d, const char *path)
{
    if (e != GS_OK && d) {
        char f[sizeof d->field];
        size_t n = strlen(path);
        if (n >= sizeof f)
            n = sizeof f - 1;
        memcpy(f, path, n);
        f[n] = '\0';
        if (d->field[0] && n + 1 < sizeof f) {
            f[n] = '.';
            f[n + 1] = '\0';
            size_t k = n + 1;
            for (const char *c = d->field; *c && k + 1 < sizeof f; c++)
                f[k++] = *c;
            f[k] = '\0';
        }
        memcpy(d->field, f, sizeof f);
    }
    return e;
}

double gs_scene_body_unknowns(const gs_scene_body *b)
{
    if (b->type != GS_BODY_GEAR)
        return 0.0;
    const gs_mesh_density *m = &b->mesh;
    /* a quadratic mesh has about four times the nodes of the linear one */
    /* locally refined teeth count 4^fine_refine times */
    double teeth = b->gear.teeth + (m->fine_teeth > 0 ? m->fine_teeth * (ldexp(1.0, 2 * m->fine_refine) - 1.0) : 0.0);
    return 2.0 * teeth * 1.5 * (m->flank + m->rim) * (2.0 * m->across + 2.0) *
           ldexp(1.0, 2 * m->refine) * (m->order == 2 ? 4.0 : 1.0);
}

double gs_scene_estimate_bytes(const gs_scene *s, int *largest)
{
    double bytes = GS_SCENE_BASE_BYTES, most = 0.0;
    if (largest)
        *largest = -1;
    for (int i = 0; i < s->n_bodies; i++) {
        if (s->bodies[i].model != GS_MODEL_ELASTIC)
            continue;
        double u = gs_scene_body_unknowns(&s->bodies[i]);
        bytes += GS_SCENE_BYTES_PER_UNKNOWN * u;
        if (u > most) {
            most = u;
            if (largest)
                *largest = i;
        }
    }
    return bytes;
}

static gs_err check_train(gs_scene *s, gs_diag *d)
{
    char p[256];
    for (int i = 0; i < s->n_meshes; i++) {
        gs_scene_mesh *m = &s->meshes[i];
        gs_scene_body *a = &s->bodies[m->gear[0]], *b = &s->bodies[m->gear[1]];
        gsi_path_index(p, sizeof p, "", "meshes", i);
        for (int j = 0; j < i; j++)
            if (!strcmp(s->meshes[j].name, m->name))
                return gs_diag_set(d, GS_ESCHEMA, p, "duplicate mesh name '%s'", m->name);
        if (a->gear.kind == GS_GEAR_INTERNAL && b->gear.kind == GS_GEAR_INTERNAL)
            return gs_diag_set(d, GS_EGEOMETRY, p, "two internal gears cannot mesh");
        int ca = a->joint == GS_JOINT_ON_CARRIER ? a->carrier : -1;
        int cb = b->joint == GS_JOINT_ON_CARRIER ? b->carrier : -1;
        if (ca >= 0 && cb >= 0 && ca != cb)
            return gs_diag_set(d, GS_EGEOMETRY, p, "the gears ride on different carriers");
        if (ca >= 0 && cb >= 0)
            return gs_diag_set(d, GS_EGEOMETRY, p, "two planets on one carrier cannot mesh");
        /* Centre distance from the joints, measured in the carrier frame. */
        double ctr[2][2];
        for (int k = 0; k < 2; k++) {
            gs_scene_body *g = &s->bodies[m->gear[k]];
            if (g->joint == GS_JOINT_ON_CARRIER) {
                gs_scene_body *c = &s->bodies[g->carrier];
                ctr[k][0] = c->centre[0] + g->carrier_radius * cos(g->carrier_angle);
                ctr[k][1] = c->centre[1] + g->carrier_radius * sin(g->carrier_angle);
            } else {
                ctr[k][0] = g->centre[0];
                ctr[k][1] = g->centre[1];
            }
        }
        double dist = hypot(ctr[1][0] - ctr[0][0], ctr[1][1] - ctr[0][1]);
        double eps, alpha_w;
        gs_err e = gs_pair_contact_ratio(&a->gear, &b->gear, dist, &eps, &alpha_w, d);
        if (e != GS_OK)
            return gsi_scene_prefix_diag(e, d, p);
        if (m->model == GS_MESH_IMPACT && m->backlash == 0) {
            /* Default backlash of an impact mesh: the pair's own, from tooth
             * thinning and centre distance. */
            gs_pair_info info;
            e = gs_pair_analyse(&a->gear, &b->gear, dist, &info, d);
            if (e != GS_OK)
                return gsi_scene_prefix_diag(e, d, p);
            /* Below a millionth of the module it is the round-off of a
             * tight mesh, not backlash. */
            m->backlash = info.backlash_normal;
            if (!(m->backlash > 1e-6 * a->gear.module_m)) {
                char pb[256];
                gsi_path(pb, sizeof pb, p, "backlash_mm");
                return gs_diag_set(d, GS_ERANGE, pb,
                                   "mesh '%s': the pair has no backlash at its centre distance; give "
                                   "'backlash_mm' (> 0) or thin the teeth ('thinning_mm')", m->name);
            }
        }
    }
    /* Planetary assembly: a carrier with planets all meshing one sun and one ring. */
    for (int c = 0; c < s->n_bodies; c++) {
        if (s->bodies[c].type != GS_BODY_CARRIER)
            continue;
        int n = 0, planet = -1, sun = -1, ring = -1;
        for (int i = 0; i < s->n_bodies; i++)
            if (s->bodies[i].joint == GS_JOINT_ON_CARRIER && s->bodies[i].carrier == c) {
                n++;
                planet = i;
            }
        if (n < 2 || planet < 0)
            continue;
        for (int i = 0; i < s->n_meshes; i++) {
            int o = -1;
            if (s->meshes[i].gear[0] == planet)
                o = s->meshes[i].gear[1];
            else if (s->meshes[i].gear[1] == planet)
                o = s->meshes[i].gear[0];
            if (o < 0)
                continue;
            if (s->bodies[o].gear.kind == GS_GEAR_INTERNAL)
                ring = o;
            else
                sun = o;
        }
        if (sun >= 0 && ring >= 0) {
            gs_err e = gs_planetary_check(&s->bodies[sun].gear, &s->bodies[planet].gear,
                                          &s->bodies[ring].gear, n, d);
            if (e != GS_OK) {
                /* The check names the tooth counts ("gears") or the planet
                 * count: as scene paths, the ring's teeth or the bodies. */
                if (d && !strcmp(d->field, "gears"))
                    snprintf(d->field, sizeof d->field, "bodies[%d].teeth", ring);
                else if (d)
                    snprintf(d->field, sizeof d->field, "bodies");
                return e;
            }
        }
    }
    return GS_OK;
}

gs_err gs_scene_parse(const char *text, size_t len, gs_scene **out, gs_diag *d)
{
    *out = NULL;
    gs_diag_clear(d);
    gs_err se = gsi_json_strict(text, len, "", d);
    if (se != GS_OK)
        return se;
    json_tokener *tok = json_tokener_new_ex(GSI_JSON_MAX_DEPTH);
    if (!tok)
        return GS_ENOMEM;
    json_object *root = json_tokener_parse_ex(tok, text, (int)len);
    enum json_tokener_error je = json_tokener_get_error(tok);
    if (root && je == json_tokener_success && (size_t)json_tokener_get_parse_end(tok) < len) {
        /* trailing bytes after the object: allow only whitespace */
        for (size_t i = json_tokener_get_parse_end(tok); i < len; i++)
            if (!strchr(" \t\r\n", text[i])) {
                je = json_tokener_error_parse_unexpected;
                break;
            }
    }
    json_tokener_free(tok);
    if (!root || je != json_tokener_success) {
        json_object_put(root);
        return gs_diag_set(d, GS_EPARSE, "", "the scene is not valid JSON: %s",
                           json_tokener_error_desc(je));
    }
    gs_scene *s = NULL;
    gs_err e = gs_scene_from_json(root, &s, d);
    json_object_put(root);
    *out = s;
    return e;
}

static gs_err scene_from_json(json_object *root, gs_scene **out, gs_diag *d);

gs_err gs_scene_from_json(json_object *root, gs_scene **out, gs_diag *d)
{
    *out = NULL;
    if (json_object_get_type(root) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, "", "a scene must be a JSON object");
    json_object *expanded = root, *tree;
    bool copy;
    if (json_object_object_get_ex(root, "train", NULL)) {
        expanded = NULL;
        if (json_object_deep_copy(root, &expanded, NULL) != 0 || !expanded)
            return GS_ENOMEM;
        gs_err e = gsi_scene_expand_train(expanded, d);
        if (e != GS_OK) {
            json_object_put(expanded);
            return e;
        }
    }
    char *choice = NULL;
    gs_err e = gsi_scene_fidelity_targets(expanded, &tree, &copy, &choice, d);
    if (e == GS_OK && !choice)
        e = gsi_scene_apply_fidelity(expanded, &tree, &copy, d);
    if (e == GS_OK)
        e = scene_from_json(tree, out, d);
    if (e == GS_OK)
        (*out)->fidelity_choice = choice;
    else
        free(choice);
    if (copy)
        json_object_put(tree);
    if (expanded != root)
        json_object_put(expanded);
    return e;
}

static gs_err scene_from_json(json_object *root, gs_scene **out, gs_diag *d)
{
    gs_err e = gsi_json_only(root, "", top_keys, d);
    if (e)
        return e;
    gs_scene *s = gs_calloc(1, sizeof *s);
    if (!s)
        return GS_ENOMEM;
#define CHECK(x)            \
    do {                    \
        e = (x);            \
        if (e != GS_OK)     \
            goto fail;      \
    } while (0)
    CHECK(gsi_json_string(root, "name", "", false, "scene", s->name, sizeof s->name, d));
    json_object *arr, *o;
    char p[256];
    CHECK(gsi_json_array(root, "bodies", "", true, &arr, d));
    size_t nb = json_object_array_length(arr);
    if (nb < 1 || nb > MAX_BODIES) {
        e = gs_diag_set(d, GS_ERANGE, "bodies", "a scene has 1 to %d bodies", MAX_BODIES);
        goto fail;
    }
    s->bodies = gs_calloc(nb, sizeof *s->bodies);
    if (!s->bodies) {
        e = GS_ENOMEM;
        goto fail;
    }
    s->n_bodies = (int)nb;
    for (int i = 0; i < s->n_bodies; i++) {
        gsi_path_index(p, sizeof p, "", "bodies", i);
        s->bodies[i].joint = (gs_joint_type)-1;
        CHECK(gsi_scene_parse_body(json_object_array_get_idx(arr, (size_t)i), p, &s->bodies[i], d));
        for (int j = 0; j < i; j++)
            if (!strcmp(s->bodies[j].name, s->bodies[i].name)) {
                char pn[256];
                gsi_path(pn, sizeof pn, p, "name");
                e = gs_diag_set(d, GS_ESCHEMA, pn, "duplicate body name '%s'", s->bodies[i].name);
                goto fail;
            }
    }
    CHECK(gsi_json_array(root, "joints", "", true, &arr, d));
    bool seen[MAX_BODIES] = {false};
    if (json_object_array_length(arr) > (size_t)MAX_BODIES) {
        e = gs_diag_set(d, GS_ERANGE, "joints", "too many joints");
        goto fail;
    }
    for (size_t i = 0; i < json_object_array_length(arr); i++) {
        gsi_path_index(p, sizeof p, "", "joints", (int)i);
        CHECK(gsi_scene_parse_joint(s, json_object_array_get_idx(arr, i), p, seen, d));
    }
    for (int i = 0; i < s->n_bodies; i++)
        if (!seen[i]) {
            gsi_path_index(p, sizeof p, "", "bodies", i);
            e = gs_diag_set(d, GS_ESCHEMA, p, "body '%s' has no joint", s->bodies[i].name);
            goto fail;
        }
    for (int i = 0; i < s->n_bodies; i++) {
        gs_scene_body *b = &s->bodies[i];
        if (b->type == GS_BODY_CARRIER && b->joint == GS_JOINT_ON_CARRIER) {
            gsi_path_index(p, sizeof p, "", "bodies", i);
            e = gs_diag_set(d, GS_ERANGE, p, "a carrier turns on a fixed axis or is held");
            goto fail;
        }
    }
    CHECK(gsi_json_array(root, "meshes", "", false, &arr, d));
    if (arr) {
        size_t n = json_object_array_length(arr);
        if (n > MAX_MESHES) {
            e = gs_diag_set(d, GS_ERANGE, "meshes", "at most %d meshes", MAX_MESHES);
            goto fail;
        }
        s->meshes = gs_calloc(n, sizeof *s->meshes);
        if (!s->meshes) {
            e = GS_ENOMEM;
            goto fail;
        }
        s->n_meshes = (int)n;
        for (int i = 0; i < s->n_meshes; i++) {
            gsi_path_index(p, sizeof p, "", "meshes", i);
            CHECK(gsi_scene_parse_gear_mesh(s, json_object_array_get_idx(arr, (size_t)i), p, &s->meshes[i], d));
        }
    }
    CHECK(check_train(s, d));
    CHECK(gsi_json_array(root, "loads", "", false, &arr, d));
    if (arr) {
        size_t n = json_object_array_length(arr);
        if (n > MAX_LOADS) {
            e = gs_diag_set(d, GS_ERANGE, "loads", "at most %d loads", MAX_LOADS);
            goto fail;
        }
        s->loads = gs_calloc(n, sizeof *s->loads);
        if (!s->loads) {
            e = GS_ENOMEM;
            goto fail;
        }
        for (size_t i = 0; i < n; i++) {
            gsi_path_index(p, sizeof p, "", "loads", (int)i);
            CHECK(gs_scene_parse_load(s, json_object_array_get_idx(arr, i), p, &s->loads[i], d));
            s->n_loads++;
            for (int j = 0; j < (int)i; j++)
                if (!strcmp(s->loads[j].name, s->loads[i].name)) {
                    e = gs_diag_set(d, GS_ESCHEMA, p, "duplicate load name '%s'", s->loads[i].name);
                    goto fail;
                }
        }
    }
    CHECK(gsi_json_object(root, "numerics", "", false, &o, d));
    s->time_step = 1e-5;
    s->newton_tol = 1e-13;
    s->max_newton = 50;
    /* Contact treatment (docs/explanation/contact.md, "Contact treatments"): a scene
     * with contact meshes gets the closure with its work returned unless
     * it names another; the field acts on contact meshes only. */
    bool has_contact = false;
    for (int i = 0; i < s->n_meshes; i++)
        has_contact |= s->meshes[i].model == GS_MESH_CONTACT;
    static const char *const schemes[] = {"seed", "closure", "closure_energy"};
    s->contact_scheme = has_contact ? GS_CONTACT_CLOSURE_ENERGY : GS_CONTACT_SEED;
    if (o) {
        int64_t v;
        CHECK(gsi_json_only(o, "numerics", numerics_keys, d));
        CHECK(gsi_json_positive(o, "time_step", "numerics", 1.0, false, 1e-5, &s->time_step, d));
        if (s->time_step < 1e-12) {
            e = gs_diag_set(d, GS_ERANGE, "numerics.time_step", "'time_step' must be at least 1e-12 s");
            goto fail;
        }
        CHECK(gsi_json_number(o, "newton_tol", "numerics", 1e-16, 1e-3, false, 1e-13, &s->newton_tol, d));
        CHECK(gsi_json_int(o, "max_newton", "numerics", 1, 1000, false, 50, &v, d));
        s->max_newton = (int)v;
        int cs;
        CHECK(gsi_scene_enum_field(o, "contact", "numerics", schemes[s->contact_scheme], schemes, 3, &cs, d));
        s->contact_scheme = cs;
        json_object *ad;
        CHECK(gsi_json_object(o, "adaptive", "numerics", false, &ad, d));
        if (ad) {
            CHECK(gsi_json_only(ad, "numerics.adaptive", adaptive_keys, d));
            double pum;
            CHECK(gsi_json_positive(ad, "penetration_um", "numerics.adaptive", 1e3, true, 0, &pum, d));
            s->adapt_penetration = pum * 1e-6;
            CHECK(gsi_json_int(ad, "levels", "numerics.adaptive", 1, GS_SCENE_MAX_ADAPT_LEVELS, false, 3, &v, d));
            s->adapt_levels = (int)v;
            if (!has_contact) {
                e = gs_diag_set(d, GS_ESCHEMA, "numerics.adaptive",
                                "the adaptive step acts on the penetration of contact meshes: this scene has none "
                                "(remove 'adaptive', or give a mesh model 'contact')");
                goto fail;
            }
        }
    }
    CHECK(gsi_json_object(root, "initial", "", false, &o, d));
    if (o) {
        json_object_object_foreach(o, key, val)
        {
            gsi_path(p, sizeof p, "initial", key);
            int bi = gs_scene_find_body(s, key);
            if (bi < 0) {
                e = gs_diag_set(d, GS_ENOTFOUND, p, "no body named '%s'", key);
                goto fail;
            }
            if (json_object_get_type(val) != json_type_object) {
                e = gs_diag_set(d, GS_ESCHEMA, p, "initial state of '%s' must be an object", key);
                goto fail;
            }
            CHECK(gsi_json_only(val, p, initial_keys, d));
            if (json_object_object_get_ex(val, "omega", NULL) &&
                json_object_object_get_ex(val, "speed_rpm", NULL)) {
                e = gs_diag_set(d, GS_ESCHEMA, p, "give 'omega' or 'speed_rpm', not both");
                goto fail;
            }
            gs_scene_body *b = &s->bodies[bi];
            double rpm;
            CHECK(gsi_json_number(val, "angle", p, -1e6, 1e6, false, 0, &b->angle0, d));
            b->angle_given = json_object_object_get_ex(val, "angle", NULL);
            CHECK(gsi_json_number(val, "omega", p, -1e6, 1e6, false, 0, &b->omega0, d));
            CHECK(gsi_json_number(val, "speed_rpm", p, -1e7, 1e7, false, b->omega0 * GS_RPM_PER_RAD_S, &rpm, d));
            b->omega0 = rpm / GS_RPM_PER_RAD_S;
            CHECK(gsi_json_number(val, "tip_load", p, -1e8, 1e8, false, 0, &b->tip_load, d));
            if (b->tip_load != 0 && b->model != GS_MODEL_ELASTIC) {
                char f[300];
                gsi_path(f, sizeof f, p, "tip_load");
                e = gs_diag_set(d, GS_ERANGE, f, "'%s' is rigid: a tip load needs model 'elastic'", key);
                goto fail;
            }
            if (b->joint == GS_JOINT_HELD && (b->omega0 != 0 || b->angle0 != 0)) {
                e = gs_diag_set(d, GS_ERANGE, p, "'%s' is held and cannot move", key);
                goto fail;
            }
        }
    }
    CHECK(gsi_json_object(root, "outputs", "", false, &o, d));
    s->telemetry_every = 10;
    s->record_every = 0;
    if (o) {
        int64_t v;
        CHECK(gsi_json_only(o, "outputs", outputs_keys, d));
        CHECK(gsi_json_int(o, "telemetry_every", "outputs", 1, 100000000, false, 10, &v, d));
        s->telemetry_every = (int)v;
        CHECK(gsi_json_int(o, "record_every", "outputs", 1, 100000000, false, v, &v, d));
        s->record_every = (int)v;
        CHECK(gsi_json_int(o, "fields_every", "outputs", 0, 100000000, false, 0, &v, d));
        s->fields_every = (int)v;
        CHECK(gsi_json_int(o, "checkpoint_every", "outputs", 0, 1000000000, false, 0, &v, d));
        s->checkpoint_every = (int)v;
    }
    if (s->record_every == 0)
        s->record_every = s->telemetry_every;
    s->json = gs_strdup(json_object_to_json_string_ext(root, JSON_C_TO_STRING_PLAIN));
    if (!s->json) {
        e = GS_ENOMEM;
        goto fail;
    }
    *out = s;
    return GS_OK;
fail:
#undef CHECK
    gs_scene_free(&s);
    return e;
}

gs_err gs_scene_load_file(const char *path, gs_scene **out, gs_diag *d)
{
    size_t len;
    char *text = gs_read_file(path, 64u << 20, &len);
    if (!text)
        return gs_diag_set(d, GS_EIO, "", "cannot read scene file '%s'", path);
    gs_err e = gs_scene_parse(text, len, out, d);
    free(text);
    return e;
}
