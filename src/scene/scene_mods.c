/* SPDX-License-Identifier: MIT
 * Scene fields of a gear's profile modifications and tooth errors
 * (docs/reference/scene.md: `modification`, `pitch_errors_um`, `runout`), parsed into
 * a gs_gear_mods owned by the scene body. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gearsim/modification.h"
#include "gearsim/scene.h"
#include "gearsim/util.h"
#include "scene/jsonv.h"
#include "scene/scene_mods.h"

#define DEG (GS_PI / 180.0)

static const char *const relief_keys[] = {"amount_um", "start_diameter_mm", "length_mm",
                                          "start_roll_deg", "shape", NULL};
static const char *const flank_keys[] = {"tip_relief", "root_relief", "deviation", NULL};
static const char *const mod_keys[] = {"tip_relief", "root_relief", "deviation", "cw", "ccw", NULL};
static const char *const dev_keys[] = {"roll_deg", "um", NULL};
static const char *const runout_keys[] = {"eccentricity_um", "phase_deg", NULL};

/* One relief: amount and where it starts (exactly one of a diameter, a roll
 * length from its end - the tip, or the form point for root relief - or a
 * roll angle). */
static gs_err parse_relief(json_object *o, const char *path, const gs_gear_geom *g, int tip,
                           gs_relief *r, gs_diag *d)
{
    GS_TRY(gsi_json_only(o, path, relief_keys, d));
    double a;
    GS_TRY(gsi_json_number(o, "amount_um", path, 0, 1e5, true, 0, &a, d));
    r->amount_m = a * 1e-6;
    char shape[32];
    GS_TRY(gsi_json_string(o, "shape", path, false, "linear", shape, sizeof shape, d));
    if (strcmp(shape, "linear") && strcmp(shape, "parabolic")) {
        char p[256];
        gsi_path(p, sizeof p, path, "shape");
        return gs_diag_set(d, GS_ERANGE, p, "'shape' must be one of: linear, parabolic (got '%s')",
                           shape);
    }
    r->parabolic = strcmp(shape, "parabolic") == 0;
    int given = json_object_object_get_ex(o, "start_diameter_mm", NULL) +
                json_object_object_get_ex(o, "length_mm", NULL) +
                json_object_object_get_ex(o, "start_roll_deg", NULL);
    if (given != 1)
        return gs_diag_set(d, GS_ESCHEMA, path,
                           "give exactly one of 'start_diameter_mm', 'length_mm' (roll length "
                           "from the %s) or 'start_roll_deg'",
                           tip ? "tip" : "form point");
    double x;
    double Lend = gs_gear_roll_length(g, tip ? g->ra : g->r_form);
    if (json_object_object_get_ex(o, "start_diameter_mm", NULL)) {
        GS_TRY(gsi_json_positive(o, "start_diameter_mm", path, 1e6, true, 0, &x, d));
        r->start_radius_m = 0.5e-3 * x;
    } else if (json_object_object_get_ex(o, "length_mm", NULL)) {
        GS_TRY(gsi_json_positive(o, "length_mm", path, 1e5, true, 0, &x, d));
        /* Towards the root of the flank from the tip, towards the tip from
         * the form point; roll length grows with radius outside a ring and
         * falls with it inside one. */
        int up = (tip != 0) == (g->internal != 0);
        double L = Lend + (up ? 1.0 : -1.0) * x * 1e-3;
        if (!(L > 0)) {
            char p[256];
            gsi_path(p, sizeof p, path, "length_mm");
            return gs_diag_set(d, GS_ERANGE, p, "roll length %g mm reaches below the base circle", x);
        }
        r->start_radius_m = gs_gear_roll_radius(g, L);
    } else {
        GS_TRY(gsi_json_positive(o, "start_roll_deg", path, 89, true, 0, &x, d));
        r->start_radius_m = gs_gear_roll_radius(g, g->rb * x * DEG);
    }
    return GS_OK;
}

static gs_err parse_deviation(json_object *o, const char *path, gs_flank_mod *f, gs_diag *d)
{
    GS_TRY(gsi_json_only(o, path, dev_keys, d));
    json_object *ra, *ua;
    GS_TRY(gsi_json_array(o, "roll_deg", path, true, &ra, d));
    GS_TRY(gsi_json_array(o, "um", path, true, &ua, d));
    size_t n = json_object_array_length(ra);
    if (n < 1 || n > GS_MOD_TABLE_MAX || json_object_array_length(ua) != n)
        return gs_diag_set(d, GS_ESCHEMA, path,
                           "'roll_deg' and 'um' must have the same length, 1 to %d points",
                           GS_MOD_TABLE_MAX);
    for (size_t i = 0; i < n; i++) {
        double xr, xu;
        if (!gsi_json_as_double(json_object_array_get_idx(ra, i), &xr) ||
            !gsi_json_as_double(json_object_array_get_idx(ua, i), &xu)) {
            char p[256];
            gsi_path_index(p, sizeof p, path, "roll_deg", (int)i);
            return gs_diag_set(d, GS_ESCHEMA, p, "finite numbers expected");
        }
        f->dev_roll[i] = xr * DEG;
        f->dev_m[i] = xu * 1e-6;
    }
    f->n_dev = (int)n;
    return GS_OK;
}

static gs_err parse_flank(json_object *o, const char *path, const char *const *keys,
                          const gs_gear_geom *g, gs_flank_mod *f, gs_diag *d)
{
    GS_TRY(gsi_json_only(o, path, keys, d));
    json_object *v;
    char p[256];
    GS_TRY(gsi_json_object(o, "tip_relief", path, false, &v, d));
    if (v) {
        gsi_path(p, sizeof p, path, "tip_relief");
        GS_TRY(parse_relief(v, p, g, 1, &f->tip, d));
    }
    GS_TRY(gsi_json_object(o, "root_relief", path, false, &v, d));
    if (v) {
        gsi_path(p, sizeof p, path, "root_relief");
        GS_TRY(parse_relief(v, p, g, 0, &f->root, d));
    }
    GS_TRY(gsi_json_object(o, "deviation", path, false, &v, d));
    if (v) {
        gsi_path(p, sizeof p, path, "deviation");
        GS_TRY(parse_deviation(v, p, f, d));
    }
    return GS_OK;
}

gs_err gsi_scene_parse_mods(json_object *o, const char *path, gs_scene_body *b, gs_diag *d)
{
    json_object *mo = NULL, *pe = NULL, *ro = NULL;
    GS_TRY(gsi_json_object(o, "modification", path, false, &mo, d));
    GS_TRY(gsi_json_array(o, "pitch_errors_um", path, false, &pe, d));
    GS_TRY(gsi_json_object(o, "runout", path, false, &ro, d));
    int single = b->pitch_error_tooth >= 0;
    if (!mo && !pe && !ro && !single)
        return GS_OK;
    gs_gear_geom g;
    GS_TRY(gs_gear_geometry(&b->gear, &g, d));
    gs_gear_mods *m = gs_gear_mods_new();
    if (!m)
        return GS_ENOMEM;
    b->mods = m;
    char p[256];
    if (mo) {
        gsi_path(p, sizeof p, path, "modification");
        gs_flank_mod both;
        memset(&both, 0, sizeof both);
        GS_TRY(parse_flank(mo, p, mod_keys, &g, &both, d));
        static const char *const side[2] = {"cw", "ccw"};
        for (int s = 0; s < 2; s++) {
            json_object *fo;
            m->flank[s] = both;
            GS_TRY(gsi_json_object(mo, side[s], p, false, &fo, d));
            if (fo) {
                char ps[256];
                gsi_path(ps, sizeof ps, p, side[s]);
                memset(&m->flank[s], 0, sizeof m->flank[s]);
                GS_TRY(parse_flank(fo, ps, flank_keys, &g, &m->flank[s], d));
            }
        }
    }
    if (pe && single) {
        gsi_path(p, sizeof p, path, "pitch_errors_um");
        return gs_diag_set(d, GS_ESCHEMA, p, "give either 'pitch_error' or 'pitch_errors_um'");
    }
    if (pe || single) {
        int z = b->gear.teeth;
        gsi_path(p, sizeof p, path, "pitch_errors_um");
        if (pe && (int)json_object_array_length(pe) != z)
            return gs_diag_set(d, GS_ESCHEMA, p, "one value per tooth: %d expected, got %d", z,
                               (int)json_object_array_length(pe));
        m->pitch_m = gs_calloc((size_t)z, sizeof *m->pitch_m);
        if (!m->pitch_m)
            return GS_ENOMEM;
        m->n_pitch = z;
        if (single)
            m->pitch_m[b->pitch_error_tooth] = b->pitch_error;
        for (int k = 0; pe && k < z; k++) {
            double x;
            if (!gsi_json_as_double(json_object_array_get_idx(pe, k), &x)) {
                gsi_path_index(p, sizeof p, path, "pitch_errors_um", k);
                return gs_diag_set(d, GS_ESCHEMA, p, "a finite number (um) expected");
            }
            m->pitch_m[k] = x * 1e-6;
        }
    }
    if (ro) {
        gsi_path(p, sizeof p, path, "runout");
        GS_TRY(gsi_json_only(ro, p, runout_keys, d));
        double e, ph;
        GS_TRY(gsi_json_number(ro, "eccentricity_um", p, 0, 1e5, true, 0, &e, d));
        GS_TRY(gsi_json_number(ro, "phase_deg", p, -360, 360, false, 0, &ph, d));
        m->runout_m = e * 1e-6;
        m->runout_phase = ph * DEG;
    }
    char pm[256];
    gsi_path(pm, sizeof pm, path, "modification");
    return gs_gear_mods_check(&g, m, pm, path, d);
}
