/* SPDX-License-Identifier: MIT
 * Scene parsing (scene.c, docs/reference/scene.md): bodies (gears with their
 * material, mesh density and reduction, rigid bodies, supports) and joints. */
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

static const char *const body_keys[] = {"name", "type", "model", "kind", "teeth", "module_mm",
    "pressure_angle_deg", "addendum", "dedendum", "fillet", "profile_shift", "thinning_mm",
    "face_width_mm", "hub_radius_mm", "material", "mesh", "mass", "inertia", "pitch_error",
    "modification", "pitch_errors_um", "runout", "reduction", "helix_angle_deg", "hand", "lead", NULL};

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
 * body of fe.h (docs/explanation/elastic_body.md "Reduced elastic body"). */
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
    GS_TRY(gsi_scene_enum_field(r, "residual", p, rules[REDUCE_STATIC_DEFAULT], rules, 2, &rule, d));
    b->reduce_static = rule == 1;
    return GS_OK;
}

/* helix_angle_deg, hand and lead of a gear (docs/explanation/helical.md):
 * module_mm, pressure_angle_deg, the rack coefficients and thinning_mm are
 * then those of the normal section, turned into the transverse section
 * that the rest of the code works on. */
static gs_err parse_helix(json_object *o, const char *path, gs_scene_body *b, gs_diag *d)
{
    static const char *const hands[] = {"right", "left"};
    static const char *const lead_keys[] = {"crowning_um", "end_relief_um", "end_relief_length_mm",
                                            "end_relief_shape", "slope_um", NULL};
    static const char *const shapes[] = {"linear", "parabolic"};
    double beta;
    GS_TRY(gsi_json_number(o, "helix_angle_deg", path, 0, 45, false, 0, &beta, d));
    int hand = 0;
    if (json_object_object_get_ex(o, "hand", NULL)) {
        int h;
        GS_TRY(gsi_scene_enum_field(o, "hand", path, NULL, hands, 2, &h, d));
        hand = h == 0 ? 1 : -1;
    }
    GS_TRY(gsi_scene_prefix_diag(gs_gear_params_helical(&b->gear, beta * DEG, hand, d), d, path));
    if (beta > 0 && b->model == GS_MODEL_ELASTIC) {
        char hp[256];
        gsi_path(hp, sizeof hp, path, "helix_angle_deg");
        return gs_diag_set(d, GS_ERANGE, hp, "an elastic gear is a planar FE body of spur teeth: a helical gear "
                                             "is rigid (model \"rigid\")");
    }
    json_object *l;
    GS_TRY(gsi_json_object(o, "lead", path, false, &l, d));
    if (!l)
        return GS_OK;
    char lp[256];
    gsi_path(lp, sizeof lp, path, "lead");
    GS_TRY(gsi_json_only(l, lp, lead_keys, d));
    double x;
    GS_TRY(gsi_json_number(l, "crowning_um", lp, 0, 1000, false, 0, &x, d));
    b->lead.crowning = x * 1e-6;
    GS_TRY(gsi_json_number(l, "end_relief_um", lp, 0, 1000, false, 0, &x, d));
    b->lead.end_relief = x * 1e-6;
    GS_TRY(gsi_json_number(l, "end_relief_length_mm", lp, 0, 1e4, false, 0, &x, d));
    b->lead.end_relief_length = x * 1e-3;
    GS_TRY(gsi_scene_enum_field(l, "end_relief_shape", lp, "linear", shapes, 2, &b->lead.end_relief_parabolic, d));
    GS_TRY(gsi_json_number(l, "slope_um", lp, -1000, 1000, false, 0, &x, d));
    b->lead.slope = x * 1e-6;
    return gs_lead_mods_validate(&b->lead, b->gear.face_width_m, lp, d);
}

gs_err gsi_scene_parse_body(json_object *o, const char *path, gs_scene_body *b, gs_diag *d)
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
    GS_TRY(gsi_scene_enum_field(o, "type", path, "gear", types, 2, &t, d));
    GS_TRY(gsi_scene_enum_field(o, "model", path, "rigid", models, 2, &m, d));
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
            "runout", "helix_angle_deg", "hand", "lead", NULL};
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
    GS_TRY(gsi_scene_enum_field(o, "kind", path, "external", kinds, 2, &k, d));
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
    GS_TRY(parse_helix(o, path, b, d));
    /* The plane state of a helical gear's transverse section, unless the
     * material gives it: plane strain when the face is at least
     * GS_HELICAL_STRAIN_FACE normal modules wide (the through-face stress
     * builds up within about one tooth thickness of each free end face, so a
     * face of several tooth thicknesses is mostly in plane strain), plane
     * stress for a narrower face (docs/explanation/helical.md "Plane state of
     * the section"). A spur gear keeps plane stress. */
    if (g->helix_angle > 0 && g->face_width_m >= GS_HELICAL_STRAIN_FACE * g->normal_module_m)
        b->material.plane = GS_PLANE_STRAIN;
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
        GS_TRY(gsi_scene_enum_field(mat, "plane", mp, planes[b->material.plane], planes, 2, &pl, d));
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
        /* local refinement (quasi-static analysis only; docs/explanation/geometry.md) */
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
    GS_TRY(gsi_scene_prefix_diag(gs_gear_validate(g, d), d, path));
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
    GS_TRY(gsi_scene_prefix_diag(gs_gear_mass_properties(g, b->material.density, &mass, &inertia), d, path));
    if (!b->mass_given)
        b->mass = mass;
    if (!b->inertia_given)
        b->inertia = inertia;
    return GS_OK;
}

/* Compliant supports of a joint (docs/explanation/modal.md): `bearing` takes stiffness,
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

gs_err gsi_scene_parse_joint(gs_scene *s, json_object *o, const char *path, bool *seen, gs_diag *d)
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
    GS_TRY(gsi_scene_enum_field(o, "type", path, NULL, types, 4, &t, d));
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
