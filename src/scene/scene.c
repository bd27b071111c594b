/* SPDX-License-Identifier: MIT
 * Scene parsing and validation (docs/SCENE.md). Every value is checked and
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
#include "scene/scene_mods.h"

#define MAX_BODIES 64
#define MAX_MESHES 256
#define MAX_LOADS 256
#define MAX_TABLE 100000
#define DEG (GS_PI / 180.0)

static const char *const top_keys[] = {"name", "bodies", "joints", "meshes", "loads",
                                       "numerics", "initial", "outputs", "description", "fidelity",
                                       "train", NULL};
static const char *const body_keys[] = {"name", "type", "model", "kind", "teeth", "module_mm",
    "pressure_angle_deg", "addendum", "dedendum", "fillet", "profile_shift", "thinning_mm",
    "face_width_mm", "hub_radius_mm", "material", "mesh", "mass", "inertia", "pitch_error",
    "modification", "pitch_errors_um", "runout", "reduction", NULL};
/* material.damping_ratio zeta at material.damping_hz f: the stiffness-
 * proportional damping that gives zeta at f (zeta_k = beta w_k / 2, so
 * beta = zeta / (pi f)); not together with damping_s. */
static gs_err material_ratio(json_object *mat, const char *mp, gs_material *m, gs_diag *d);

static const char *const material_keys[] = {"E", "nu", "density", "plane", "damping_s", "damping_m",
                                            "damping_ratio", "damping_hz", NULL};
static const char *const meshdens_keys[] = {"flank", "across", "rim", "refine", "grading", "order",
                                             "fine_teeth", "fine_refine", NULL};
static const char *const joint_keys[] = {"body", "type", "centre_mm", "carrier", "radius_mm",
                                         "angle_deg", "pin_error_um", "stiffness", "damping",
                                         "torsional_stiffness", "torsional_damping", "bearing_stiffness",
                                         "bearing_damping", NULL};
static const char *const gmesh_keys[] = {"name", "gears", "model", "stiffness", "damping",
                                         "damping_ratio", "backlash_mm", "passes", "constrain", "friction",
                                         "restitution", "law", "patches", "bending", "transition",
                                         "max_line_load_n_per_mm", NULL};
static const char *const stiff_keys[] = {"type",      "value",     "single",      "double",
                                         "transition", "positions", "calibration", NULL};
static const char *const load_keys[] = {"name", "body", "type", "moment", "ramp_time",
                                        "coefficient", "times", "moments", NULL};
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
static gs_err enum_field(json_object *o, const char *key, const char *path, const char *def,
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
static gs_err prefix_diag(gs_err e, gs_diag *d, const char *path)
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

/* The mesher's default counts of element order `order` (0: the default
 * order): include/gearsim/mesh.h, the one table of them. */
static void mesh_density_defaults(gs_mesh_density *m, int order)
{
    gs_gear_mesh_opts o;
    gs_gear_mesh_opts_for_order(&o, order);
    *m = (gs_mesh_density){o.flank, o.across, o.rim, o.refine, o.grading, o.order, 0, 0, 0};
}

/* The residual rule of a reduced body when `residual` is not given (1: static). */
#define REDUCE_STATIC_DEFAULT 1

/* bodies[i].reduction: {"f_max_hz": F} makes an elastic gear the reduced
 * body of fe.h (docs/FE.md "Reduced elastic body"). */
static gs_err parse_reduction(json_object *o, const char *path, gs_scene_body *b, gs_diag *d)
{
    static const char *const keys[] = {"f_max_hz", "residual", NULL};
    static const char *const rules[] = {"midpoint", "static"};
    json_object *r;
    char p[256];
    b->reduce_f_max_hz = 0;
    b->reduce_static = REDUCE_STATIC_DEFAULT;
    GS_TRY(gsi_json_object(o, "reduction", path, false, &r, d));
    if (!r)
        return GS_OK;
    gsi_path(p, sizeof p, path, "reduction");
    GS_TRY(gsi_json_only(r, p, keys, d));
    if (b->type != GS_BODY_GEAR || b->model != GS_MODEL_ELASTIC)
        return gs_diag_set(d, GS_ERANGE, p, "only an elastic gear can be reduced");
    GS_TRY(gsi_json_positive(r, "f_max_hz", p, 1e8, true, 0, &b->reduce_f_max_hz, d));
    int rule = 0;
    GS_TRY(enum_field(r, "residual", p, rules[REDUCE_STATIC_DEFAULT], rules, 2, &rule, d));
    b->reduce_static = rule == 1;
    return GS_OK;
}

static gs_err parse_body(json_object *o, const char *path, gs_scene_body *b, gs_diag *d)
{
    static const char *const types[] = {"gear", "carrier"};
    static const char *const models[] = {"rigid", "elastic"};
    static const char *const kinds[] = {"external", "internal"};
    static const char *const planes[] = {"stress", "strain"};
    if (json_object_get_type(o) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, path, "a body must be an object");
    GS_TRY(gsi_json_only(o, path, body_keys, d));
    GS_TRY(gsi_json_string(o, "name", path, true, NULL, b->name, sizeof b->name, d));
    int t, m;
    GS_TRY(enum_field(o, "type", path, "gear", types, 2, &t, d));
    GS_TRY(enum_field(o, "model", path, "rigid", models, 2, &m, d));
    b->type = (gs_body_type)t;
    b->model = (gs_body_model)m;
    b->material = gs_material_steel();
    mesh_density_defaults(&b->mesh, 0);
    b->pitch_error_tooth = -1;
    double x;
    b->mass_given = json_object_object_get_ex(o, "mass", NULL);
    b->inertia_given = json_object_object_get_ex(o, "inertia", NULL);
    GS_TRY(gsi_json_positive(o, "mass", path, 1e9, false, 0, &b->mass, d));
    GS_TRY(gsi_json_positive(o, "inertia", path, 1e9, false, 0, &b->inertia, d));
    GS_TRY(parse_reduction(o, path, b, d));
    if (b->type == GS_BODY_CARRIER) {
        static const char *const gear_only[] = {"kind", "teeth", "module_mm", "pressure_angle_deg",
            "addendum", "dedendum", "fillet", "profile_shift", "thinning_mm", "face_width_mm",
            "hub_radius_mm", "material", "mesh", "pitch_error", "modification", "pitch_errors_um",
            "runout", NULL};
        for (const char *const *k = gear_only; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                char p[256];
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "a carrier has no '%s'", *k);
            }
        if (!b->mass_given || !b->inertia_given)
            return gs_diag_set(d, GS_ESCHEMA, path,
                               "a carrier needs 'mass' (kg) and 'inertia' (kg m^2)");
        if (b->model != GS_MODEL_RIGID) {
            char p[256];
            gsi_path(p, sizeof p, path, "model");
            return gs_diag_set(d, GS_ERANGE, p, "a carrier is rigid");
        }
        return GS_OK;
    }
    gs_gear_params *g = &b->gear;
    gs_gear_params_defaults(g);
    int k;
    GS_TRY(enum_field(o, "kind", path, "external", kinds, 2, &k, d));
    g->kind = (gs_gear_kind)k;
    int64_t z;
    GS_TRY(gsi_json_int(o, "teeth", path, 3, 10000, true, 0, &z, d));
    g->teeth = (int)z;
    GS_TRY(gsi_json_positive(o, "module_mm", path, 1000, true, 0, &x, d));
    g->module_m = x * 1e-3;
    GS_TRY(gsi_json_number(o, "pressure_angle_deg", path, 5, 45, false, 20, &x, d));
    g->pressure_angle = x * DEG;
    GS_TRY(gsi_json_number(o, "addendum", path, 0, 3, false, g->addendum_coef, &g->addendum_coef, d));
    GS_TRY(gsi_json_number(o, "dedendum", path, 0, 4, false, g->dedendum_coef, &g->dedendum_coef, d));
    GS_TRY(gsi_json_number(o, "fillet", path, 0, 1, false, g->fillet_coef, &g->fillet_coef, d));
    GS_TRY(gsi_json_number(o, "profile_shift", path, -2, 2, false, 0, &g->profile_shift, d));
    GS_TRY(gsi_json_number(o, "thinning_mm", path, 0, 100, false, 0, &x, d));
    g->thinning_m = x * 1e-3;
    GS_TRY(gsi_json_positive(o, "face_width_mm", path, 1e4, false, 10, &x, d));
    g->face_width_m = x * 1e-3;
    GS_TRY(gsi_json_number(o, "hub_radius_mm", path, 0, 1e5, false, 0, &x, d));
    g->hub_radius_m = x * 1e-3;
    json_object *mat;
    GS_TRY(gsi_json_object(o, "material", path, false, &mat, d));
    if (mat) {
        char mp[256];
        gsi_path(mp, sizeof mp, path, "material");
        GS_TRY(gsi_json_only(mat, mp, material_keys, d));
        /* Bounds of real solids (rubber to diamond), so that no compliance
         * or wave speed of the model overflows. */
        GS_TRY(gsi_json_number(mat, "E", mp, 1e6, 1e13, false, b->material.youngs_pa,
                               &b->material.youngs_pa, d));
        GS_TRY(gsi_json_number(mat, "nu", mp, 0, 0.49, false, b->material.poisson,
                               &b->material.poisson, d));
        GS_TRY(gsi_json_number(mat, "density", mp, 1, 1e5, false, b->material.density,
                               &b->material.density, d));
        GS_TRY(gsi_json_number(mat, "damping_s", mp, 0, 1, false, b->material.damping_s,
                               &b->material.damping_s, d));
        GS_TRY(gsi_json_number(mat, "damping_m", mp, 0, 1e6, false, b->material.damping_m,
                               &b->material.damping_m, d));
        GS_TRY(material_ratio(mat, mp, &b->material, d));
        int pl;
        GS_TRY(enum_field(mat, "plane", mp, "stress", planes, 2, &pl, d));
        b->material.plane = (gs_plane)pl;
    }
    json_object *md;
    GS_TRY(gsi_json_object(o, "mesh", path, false, &md, d));
    if (md) {
        char mp[256];
        int64_t v;
        gsi_path(mp, sizeof mp, path, "mesh");
        GS_TRY(gsi_json_only(md, mp, meshdens_keys, d));
        /* the order first: the counts not given are that order's defaults */
        GS_TRY(gsi_json_int(md, "order", mp, 1, 2, false, b->mesh.order, &v, d));
        mesh_density_defaults(&b->mesh, (int)v);
        const gs_mesh_density def = b->mesh;
        GS_TRY(gsi_json_int(md, "flank", mp, 1, 256, false, def.flank, &v, d));
        b->mesh.flank = (int)v;
        GS_TRY(gsi_json_int(md, "across", mp, 1, 128, false, def.across, &v, d));
        b->mesh.across = (int)v;
        GS_TRY(gsi_json_int(md, "rim", mp, 1, 128, false, def.rim, &v, d));
        b->mesh.rim = (int)v;
        GS_TRY(gsi_json_int(md, "refine", mp, 0, 6, false, def.refine, &v, d));
        b->mesh.refine = (int)v;
        GS_TRY(gsi_json_number(md, "grading", mp, 1, 8, false, def.grading, &b->mesh.grading, d));
        /* local refinement (quasi-static analysis only; docs/GEOMETRY.md) */
        GS_TRY(gsi_json_int(md, "fine_teeth", mp, 0, g->teeth, false, 0, &v, d));
        b->mesh.fine_teeth = (int)v;
        GS_TRY(gsi_json_int(md, "fine_refine", mp, 0, 4, false, b->mesh.fine_teeth ? 2 : 0, &v, d));
        b->mesh.fine_refine = (int)v;
        {
            char fp[300];
            gsi_path(fp, sizeof fp, mp, "fine_refine");
            if (b->mesh.fine_teeth > 0 && b->mesh.fine_refine == 0)
                return gs_diag_set(d, GS_ERANGE, fp, "1 to 4 levels when fine_teeth is set");
            if (b->mesh.fine_teeth == 0 && b->mesh.fine_refine > 0)
                return gs_diag_set(d, GS_ERANGE, fp,
                                   "fine_refine %d without fine_teeth: say how many teeth to refine",
                                   b->mesh.fine_refine);
        }
    }
    json_object *pe;
    GS_TRY(gsi_json_object(o, "pitch_error", path, false, &pe, d));
    if (pe) {
        static const char *const pe_keys[] = {"tooth", "error_um", NULL};
        char pp[256];
        int64_t t;
        gsi_path(pp, sizeof pp, path, "pitch_error");
        GS_TRY(gsi_json_only(pe, pp, pe_keys, d));
        GS_TRY(gsi_json_int(pe, "tooth", pp, 0, g->teeth - 1, true, 0, &t, d));
        GS_TRY(gsi_json_number(pe, "error_um", pp, -1000, 1000, true, 0, &x, d));
        b->pitch_error_tooth = (int)t;
        b->pitch_error = x * 1e-6;
    }
    GS_TRY(prefix_diag(gs_gear_validate(g, d), d, path));
    GS_TRY(gsi_scene_parse_mods(o, path, b, d));
    /* Size limit before anything is meshed: every gear counts, since
     * contact meshes mesh rigid gears too. */
    double unknowns = gs_scene_body_unknowns(b);
    if (unknowns > GS_SCENE_MAX_BODY_UNKNOWNS) {
        char p[256];
        gsi_path(p, sizeof p, path, b->mesh.refine > 0 ? "mesh.refine" : "mesh");
        return gs_diag_set(d, GS_ETOOBIG, p,
                           "the mesh of '%s' would have about %.3g FE unknowns (%d teeth, flank %d, "
                           "across %d, rim %d, refine %d); at most %.3g per body",
                           b->name, unknowns, g->teeth, b->mesh.flank, b->mesh.across, b->mesh.rim,
                           b->mesh.refine, GS_SCENE_MAX_BODY_UNKNOWNS);
    }
    double mass, inertia;
    GS_TRY(prefix_diag(gs_gear_mass_properties(g, b->material.density, &mass, &inertia), d, path));
    if (!b->mass_given)
        b->mass = mass;
    if (!b->inertia_given)
        b->inertia = inertia;
    return GS_OK;
}

/* Compliant supports of a joint (docs/MODAL.md): `bearing` takes stiffness,
 * damping (radial, N/m, N s/m; stiffness 0 = floating) and
 * torsional_stiffness, torsional_damping (N m/rad, N m s/rad; 0 = free);
 * on_carrier takes bearing_stiffness, bearing_damping (the planet's bearing
 * on its pin; absent = rigid pin). Other joints take none of them. */
static gs_err parse_supports(json_object *o, const char *path, gs_scene_body *b, gs_diag *d)
{
    static const char *const brg[] = {"stiffness", "damping", "torsional_stiffness", "torsional_damping", NULL};
    static const char *const pin[] = {"bearing_stiffness", "bearing_damping", NULL};
    char p[256];
    b->bearing_k = b->bearing_c = b->torsion_k = b->torsion_c = 0;
    b->pin_bearing = false;
    for (int g = 0; g < 2; g++) {
        bool allowed = g == 0 ? b->joint == GS_JOINT_BEARING : b->joint == GS_JOINT_ON_CARRIER;
        for (const char *const *k = g == 0 ? brg : pin; *k && !allowed; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "'%s' belongs to %s joint", *k,
                                   g == 0 ? "a bearing" : "an on_carrier");
            }
    }
    if (b->joint == GS_JOINT_BEARING) {
        GS_TRY(gsi_json_number(o, "stiffness", path, 0, 1e13, true, 0, &b->bearing_k, d));
        GS_TRY(gsi_json_number(o, "damping", path, 0, 1e9, false, 0, &b->bearing_c, d));
        GS_TRY(gsi_json_number(o, "torsional_stiffness", path, 0, 1e13, false, 0, &b->torsion_k, d));
        GS_TRY(gsi_json_number(o, "torsional_damping", path, 0, 1e9, false, 0, &b->torsion_c, d));
    } else if (b->joint == GS_JOINT_ON_CARRIER && json_object_object_get_ex(o, "bearing_stiffness", NULL)) {
        GS_TRY(gsi_json_positive(o, "bearing_stiffness", path, 1e13, true, 0, &b->bearing_k, d));
        GS_TRY(gsi_json_number(o, "bearing_damping", path, 0, 1e9, false, 0, &b->bearing_c, d));
        b->pin_bearing = true;
    } else if (json_object_object_get_ex(o, "bearing_damping", NULL)) {
        gsi_path(p, sizeof p, path, "bearing_damping");
        return gs_diag_set(d, GS_ESCHEMA, p, "'bearing_damping' needs 'bearing_stiffness'");
    }
    return GS_OK;
}

static gs_err parse_joint(gs_scene *s, json_object *o, const char *path, bool *seen, gs_diag *d)
{
    static const char *const types[] = {"fixed_axis", "on_carrier", "held", "bearing"};
    if (json_object_get_type(o) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, path, "a joint must be an object");
    GS_TRY(gsi_json_only(o, path, joint_keys, d));
    char name[GS_NAME_MAX], p[256];
    GS_TRY(gsi_json_string(o, "body", path, true, NULL, name, sizeof name, d));
    gsi_path(p, sizeof p, path, "body");
    int bi = gs_scene_find_body(s, name);
    if (bi < 0)
        return gs_diag_set(d, GS_ENOTFOUND, p, "no body named '%s'", name);
    if (seen[bi])
        return gs_diag_set(d, GS_ESCHEMA, p, "body '%s' has more than one joint", name);
    seen[bi] = true;
    gs_scene_body *b = &s->bodies[bi];
    int t;
    GS_TRY(enum_field(o, "type", path, NULL, types, 4, &t, d));
    b->joint = (gs_joint_type)t;
    GS_TRY(parse_supports(o, path, b, d));
    if (b->joint == GS_JOINT_FIXED_AXIS || b->joint == GS_JOINT_BEARING) {
        json_object *c;
        GS_TRY(gsi_json_array(o, "centre_mm", path, false, &c, d));
        b->centre[0] = b->centre[1] = 0;
        if (c) {
            gsi_path(p, sizeof p, path, "centre_mm");
            double x, y;
            if (json_object_array_length(c) != 2 ||
                !gsi_json_as_double(json_object_array_get_idx(c, 0), &x) ||
                !gsi_json_as_double(json_object_array_get_idx(c, 1), &y) || fabs(x) > 1e6 ||
                fabs(y) > 1e6)
                return gs_diag_set(d, GS_ESCHEMA, p, "'centre_mm' must be [x, y], finite numbers");
            b->centre[0] = x * 1e-3;
            b->centre[1] = y * 1e-3;
        }
        static const char *const no[] = {"carrier", "radius_mm", "angle_deg", "pin_error_um", NULL};
        for (const char *const *k = no; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "'%s' belongs to an on_carrier joint", *k);
            }
    } else if (b->joint == GS_JOINT_ON_CARRIER) {
        GS_TRY(gsi_json_string(o, "carrier", path, true, NULL, name, sizeof name, d));
        gsi_path(p, sizeof p, path, "carrier");
        int ci = gs_scene_find_body(s, name);
        if (ci < 0)
            return gs_diag_set(d, GS_ENOTFOUND, p, "no body named '%s'", name);
        if (s->bodies[ci].type != GS_BODY_CARRIER)
            return gs_diag_set(d, GS_ERANGE, p, "'%s' is not a carrier", name);
        if (b->type != GS_BODY_GEAR)
            return gs_diag_set(d, GS_ERANGE, path, "only gears ride on a carrier");
        b->carrier = ci;
        double r, a;
        GS_TRY(gsi_json_positive(o, "radius_mm", path, 1e6, true, 0, &r, d));
        GS_TRY(gsi_json_number(o, "angle_deg", path, -3600, 3600, false, 0, &a, d));
        b->carrier_radius = r * 1e-3;
        b->carrier_angle = a * DEG;
        json_object *pe;
        GS_TRY(gsi_json_array(o, "pin_error_um", path, false, &pe, d));
        if (pe) {
            gsi_path(p, sizeof p, path, "pin_error_um");
            double er, et;
            if (json_object_array_length(pe) != 2 ||
                !gsi_json_as_double(json_object_array_get_idx(pe, 0), &er) ||
                !gsi_json_as_double(json_object_array_get_idx(pe, 1), &et) || fabs(er) > 1000 ||
                fabs(et) > 1000)
                return gs_diag_set(d, GS_ESCHEMA, p,
                                   "'pin_error_um' must be [radial, tangential], finite numbers within 1000 um");
            /* The pin sits off its nominal position: radially outwards by er,
             * counter-clockwise along the carrier circle by et. */
            b->pin_error[0] = er * 1e-6;
            b->pin_error[1] = et * 1e-6;
            b->carrier_radius += b->pin_error[0];
            b->carrier_angle += b->pin_error[1] / b->carrier_radius;
        }
    } else {
        static const char *const no[] = {"carrier", "radius_mm", "angle_deg", "centre_mm", "pin_error_um", NULL};
        for (const char *const *k = no; *k; k++)
            if (json_object_object_get_ex(o, *k, NULL)) {
                gsi_path(p, sizeof p, path, *k);
                return gs_diag_set(d, GS_ESCHEMA, p, "a held joint has no '%s'", *k);
            }
    }
    return GS_OK;
}

static gs_err parse_gear_mesh(gs_scene *s, json_object *o, const char *path, gs_scene_mesh *m,
                              gs_diag *d)
{
    static const char *const models[] = {"kinematic", "lumped", "contact", "impact", "compliant"};
    static const char *const laws[] = {"newton", "poisson", "stronge"}; /* gs_restitution order */
    static const char *const stypes[] = {"constant", "rectangular", "calibrated"};
    static const char *const passes[] = {"two", "one"};
    static const char *const constrain[] = {"touching", "predicted"};
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
    GS_TRY(enum_field(o, "model", path, NULL, models, 5, &model, d));
    m->model = (gs_mesh_model)model;
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
        static const char *const no[] = {"passes", "constrain", "friction", NULL};
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
        GS_TRY(enum_field(o, "passes", path, "two", passes, 2, &v, d));
        m->one_pass = v;
        GS_TRY(enum_field(o, "constrain", path, "touching", constrain, 2, &v, d));
        m->predict = v;
        GS_TRY(gsi_json_number(o, "friction", path, 0, 2, false, 0, &m->friction, d));
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
        GS_TRY(enum_field(o, "law", path, "stronge", laws, 3, &m->law, d));
        return GS_OK;
    }
    if (m->model == GS_MESH_COMPLIANT) {
        /* Rigid gears, tooth pairs through the compliant patch model
         * (docs/IMPACT.md "The compliant mesh"): no stiffness to give. */
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
        GS_TRY(enum_field(o, "bending", path, "beam_foundation", bend, 3, &m->bending, d));
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
            GS_TRY(enum_field(st, "type", p, NULL, stypes, 3, &ty, d));
            m->stiffness_type = (gs_stiffness_type)ty;
            if (ty == GS_STIFF_CALIBRATED) {
                /* From the quasi-static FE analysis of the pair at load
                 * (docs/STIFFNESS.md), at the gears' scene mesh density. */
                int64_t np;
                GS_TRY(gsi_json_int(st, "positions", p, 4, 720, false, 24, &np, d));
                m->calibrate_positions = (int)np;
                static const char *const claws[] = {"tangent", "secant", "modal"};
                int cl;
                GS_TRY(enum_field(st, "calibration", p, "tangent", claws, 3, &cl, d));
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
    GS_TRY(enum_field(o, "type", path, NULL, types, 4, &t, d));
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
            return prefix_diag(e, d, p);
        if (m->model == GS_MESH_IMPACT && m->backlash == 0) {
            /* Default backlash of an impact mesh: the pair's own, from tooth
             * thinning and centre distance. */
            gs_pair_info info;
            e = gs_pair_analyse(&a->gear, &b->gear, dist, &info, d);
            if (e != GS_OK)
                return prefix_diag(e, d, p);
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

/* `fidelity` switches a whole scene along the ladder with one field
 * (METHOD.md section 7): every gear's body model and every mesh's model
 * are set, and the model-specific mesh fields dropped (the chosen model's
 * defaults apply). Works on a copy: *out is the tree to validate (root
 * itself, or a new tree the caller frees when *copy is set). */
static gs_err apply_fidelity(json_object *root, json_object **out, bool *copy, gs_diag *d)
{
    static const char *const levels[] = {"as_given", "kinematic", "lumped", "contact", "compliant"};
    *out = root;
    *copy = false;
    int lv;
    GS_TRY(enum_field(root, "fidelity", "", "as_given", levels, 5, &lv, d));
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
                                               "passes", "constrain", "friction", "restitution", "law",
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
 * (docs/SCENE.md): sun, planets on a carrier at the tight-mesh centre
 * distance (or radius_mm), ring held or on its own axis. Everything it
 * writes is then validated like a scene written out in full, so assembly
 * errors name the generated field (bodies[..], joints[..], meshes[..]). */
static gs_err expand_train(json_object *c, gs_diag *d)
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
    GS_TRY(enum_field(tr, "type", "train", NULL, types, 1, &t, d));
    for (const char *const *k = (const char *const[]){"bodies", "joints", "meshes", NULL}; *k; k++)
        if (json_object_object_get_ex(c, *k, NULL))
            return gs_diag_set(d, GS_ESCHEMA, *k, "give either 'train' or '%s', not both", *k);
    static const char *const models[] = {"rigid", "elastic"};
    static const char *const mmodels[] = {"kinematic", "lumped", "contact", "compliant"};
    static const char *const rj[] = {"held", "fixed_axis"};
    int bm, mm, ringj;
    GS_TRY(enum_field(tr, "model", "train", "rigid", models, 2, &bm, d));
    GS_TRY(enum_field(tr, "mesh_model", "train", "lumped", mmodels, 4, &mm, d));
    GS_TRY(enum_field(tr, "ring_joint", "train", "held", rj, 2, &ringj, d));
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
        gs_err e = parse_body(g0, "train.sun", &sb, d);
        if (e == GS_OK)
            e = parse_body(g1, "train.planet", &pb, d);
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
        gs_err e = expand_train(expanded, d);
        if (e != GS_OK) {
            json_object_put(expanded);
            return e;
        }
    }
    gs_err e = apply_fidelity(expanded, &tree, &copy, d);
    if (e == GS_OK)
        e = scene_from_json(tree, out, d);
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
        CHECK(parse_body(json_object_array_get_idx(arr, (size_t)i), p, &s->bodies[i], d));
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
        CHECK(parse_joint(s, json_object_array_get_idx(arr, i), p, seen, d));
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
            CHECK(parse_gear_mesh(s, json_object_array_get_idx(arr, (size_t)i), p, &s->meshes[i], d));
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
        /* Contact treatment (docs/CONTACT.md, "Contact treatments"). */
        static const char *const schemes[] = {"seed", "closure", "closure_energy"};
        int cs;
        CHECK(enum_field(o, "contact", "numerics", "seed", schemes, 3, &cs, d));
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
            bool contact = false;
            for (int i = 0; i < s->n_meshes; i++)
                contact |= s->meshes[i].model == GS_MESH_CONTACT;
            if (!contact) {
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

static gs_err material_ratio(json_object *mat, const char *mp, gs_material *m, gs_diag *d)
{
    bool has_r = json_object_object_get_ex(mat, "damping_ratio", NULL);
    bool has_f = json_object_object_get_ex(mat, "damping_hz", NULL);
    char p[300];
    if (!has_r && !has_f)
        return GS_OK;
    if (has_r != has_f) {
        gsi_path(p, sizeof p, mp, has_r ? "damping_hz" : "damping_ratio");
        return gs_diag_set(d, GS_ESCHEMA, p, "'damping_ratio' and 'damping_hz' go together");
    }
    if (json_object_object_get_ex(mat, "damping_s", NULL)) {
        gsi_path(p, sizeof p, mp, "damping_ratio");
        return gs_diag_set(d, GS_ESCHEMA, p, "give 'damping_s' or 'damping_ratio' with 'damping_hz', not both");
    }
    double zeta, f;
    GS_TRY(gsi_json_number(mat, "damping_ratio", mp, 0, 1, true, 0, &zeta, d));
    GS_TRY(gsi_json_positive(mat, "damping_hz", mp, 1e7, true, 1, &f, d));
    m->damping_s = zeta / (GS_PI * f);
    return GS_OK;
}
