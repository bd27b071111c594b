/* SPDX-License-Identifier: MIT
 * Scene parsing (scene.c, docs/reference/scene.md): `"fidelity": {"targets":
 * {"dte": 0.05}}` instead of a fidelity name. The scene is classified as
 * advise does (a gear pair, measured on contact_drive; a planetary train,
 * measured on planetary_contact; anything else refused), the cheapest
 * setting of the measured trade-off table that meets every target is taken
 * (gearsim/tradeoff.h, the rule of `gearctl advise`) and set on a copy of
 * the scene: its level (body and mesh models), its contact scheme, mesh
 * refinement and reduction for the elastic levels, and its time step
 * unless the scene asks for a finer one. The choice and its reasons are
 * kept as JSON text (gs_scene.fidelity_choice). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/mesh.h"
#include "gearsim/scene.h"
#include "gearsim/tradeoff.h"
#include "gearsim/util.h"
#include "scene/jsonv.h"
#include "scene/scene_internal.h"

#define FIELD "fidelity.targets"

static bool str_is(json_object *o, const char *key, const char *val)
{
    json_object *v;
    return json_object_object_get_ex(o, key, &v) && json_object_get_type(v) == json_type_string &&
           !strcmp(json_object_get_string(v), val);
}

static size_t arr_len(json_object *root, const char *key, json_object **a)
{
    *a = NULL;
    if (!json_object_object_get_ex(root, key, a) || json_object_get_type(*a) != json_type_array) {
        *a = NULL;
        return 0;
    }
    return json_object_array_length(*a);
}

/* The table's scene for this scene's kind (advise's classify_scene). */
static gs_err classify(json_object *root, const char **tscene, const char **kind, char *why, size_t cap,
                       gs_diag *d)
{
    json_object *bs, *ms, *js;
    size_t nb = arr_len(root, "bodies", &bs), nm = arr_len(root, "meshes", &ms), nj = arr_len(root, "joints", &js);
    if (nm == 0)
        return gs_diag_set(d, GS_ERANGE, FIELD,
                           "the scene has no gear mesh: the trade-off table measures meshing trains only; give a "
                           "fidelity name instead of targets");
    const char *carrier = NULL, *ring = NULL;
    for (size_t i = 0; i < nb; i++) {
        json_object *b = json_object_array_get_idx(bs, i), *n = NULL;
        if (json_object_get_type(b) != json_type_object)
            continue;
        const char *name = json_object_object_get_ex(b, "name", &n) ? json_object_get_string(n) : "?";
        if (!carrier && str_is(b, "type", "carrier"))
            carrier = name;
        if (!ring && str_is(b, "kind", "internal"))
            ring = name;
    }
    bool on_carrier = false;
    for (size_t i = 0; i < nj; i++) {
        json_object *j = json_object_array_get_idx(js, i);
        on_carrier |= json_object_get_type(j) == json_type_object && str_is(j, "type", "on_carrier");
    }
    if (carrier || ring || on_carrier) {
        *tscene = "planetary_contact";
        *kind = "planetary";
        int k = snprintf(why, cap, "a planetary train (%zu meshes", nm);
        if (carrier && k > 0 && (size_t)k < cap)
            k += snprintf(why + k, cap - (size_t)k, ", carrier %s", carrier);
        if (ring && k > 0 && (size_t)k < cap)
            k += snprintf(why + k, cap - (size_t)k, ", ring %s", ring);
        if (k > 0 && (size_t)k < cap)
            snprintf(why + k, cap - (size_t)k, ")");
        return GS_OK;
    }
    if (nm == 1) {
        json_object *m = json_object_array_get_idx(ms, 0), *g = NULL;
        *tscene = "contact_drive";
        *kind = "pair";
        if (json_object_get_type(m) == json_type_object && json_object_object_get_ex(m, "gears", &g) &&
            json_object_get_type(g) == json_type_array && json_object_array_length(g) == 2)
            snprintf(why, cap, "a gear pair (%s / %s)", json_object_get_string(json_object_array_get_idx(g, 0)),
                     json_object_get_string(json_object_array_get_idx(g, 1)));
        else
            snprintf(why, cap, "a gear pair (one mesh)");
        return GS_OK;
    }
    return gs_diag_set(d, GS_ERANGE, FIELD,
                       "the scene is a chain of %zu meshes without a carrier: the trade-off table measures a "
                       "single pair (contact_drive) and a planetary train (planetary_contact) only; give a "
                       "fidelity name instead of targets", nm);
}

static json_object *child(json_object *o, const char *key)
{
    json_object *c = NULL;
    if (!json_object_object_get_ex(o, key, &c) || json_object_get_type(c) != json_type_object) {
        c = json_object_new_object();
        json_object_object_add(o, key, c);
    }
    return c;
}

/* The row's setting on a copy of root (*out): its level through the
 * `fidelity` switch (gsi_scene_apply_fidelity: body and mesh models, the
 * model-specific mesh fields dropped), then what the switch has no name
 * for; the time step taken in *h. */
static gs_err set_row(json_object *root, const gs_tradeoff_row *r, json_object **out, double *h, gs_diag *d)
{
    static const char *const rigid[] = {"kinematic", "lumped", "compliant", "ltca", NULL};
    const char *lv = r->level;
    bool elastic = !strcmp(lv, "contact") || !strcmp(lv, "reduced") || !strcmp(lv, "contact_seed") ||
                   !strcmp(lv, "adaptive");
    bool calibrated = !strcmp(lv, "calibrated"), impact = !strcmp(lv, "impact");
    const char *base = elastic ? "contact" : calibrated || impact ? "lumped" : NULL;
    for (const char *const *k = rigid; !base && *k; k++)
        if (!strcmp(lv, *k))
            base = *k;
    if (!base)
        return gs_diag_set(d, GS_ERANGE, FIELD, "the trade-off table's level '%.31s' is not a rung a scene can be "
                           "set to", lv);
    json_object *tmp = NULL, *c = NULL;
    bool copy = false;
    if (json_object_deep_copy(root, &tmp, NULL) != 0 || !tmp)
        return GS_ENOMEM;
    json_object_object_add(tmp, "fidelity", json_object_new_string(base));
    gs_err e = gsi_scene_apply_fidelity(tmp, &c, &copy, d);
    if (e != GS_OK || !copy) {
        if (copy)
            json_object_put(c);
        json_object_put(tmp);
        return e != GS_OK ? e : GS_EINTERNAL;
    }
    json_object_put(tmp);
    json_object_object_add(c, "fidelity", json_object_new_string("as_given"));
    json_object *bs = NULL, *ms = NULL;
    size_t nb = arr_len(c, "bodies", &bs), nm = arr_len(c, "meshes", &ms);
    for (size_t i = 0; (calibrated || impact) && i < nm; i++) {
        json_object *m = json_object_array_get_idx(ms, i);
        if (json_object_get_type(m) != json_type_object)
            continue;
        if (impact) {
            json_object_object_add(m, "model", json_object_new_string("impact"));
            continue;
        }
        json_object *st = json_object_new_object();
        json_object_object_add(st, "type", json_object_new_string("calibrated"));
        json_object_object_add(m, "stiffness", st);
    }
    for (size_t i = 0; elastic && i < nb; i++) {
        json_object *b = json_object_array_get_idx(bs, i);
        if (json_object_get_type(b) != json_type_object || str_is(b, "type", "carrier"))
            continue;
        if (!strcmp(lv, "reduced")) {
            json_object *rd = json_object_new_object();
            json_object_object_add(rd, "f_max_hz", json_object_new_double(0.3 / r->h));
            json_object_object_add(b, "reduction", rd);
        }
        if (r->refine > 0 || r->scale != 1.0) {
            json_object *m = child(b, "mesh");
            json_object_object_add(m, "refine", json_object_new_int(r->refine));
            if (r->scale != 1.0) { /* the order's default counts times the scale */
                gs_gear_mesh_opts def;
                gs_gear_mesh_opts_for_order(&def, 2);
                json_object_object_add(m, "order", json_object_new_int(2));
                json_object_object_add(m, "flank", json_object_new_int((int)lround(def.flank * r->scale)));
                json_object_object_add(m, "across", json_object_new_int((int)lround(def.across * r->scale)));
                json_object_object_add(m, "rim", json_object_new_int((int)lround(def.rim * r->scale)));
            }
        }
    }
    json_object *num = child(c, "numerics");
    if (elastic && r->scheme[0])
        json_object_object_add(num, "contact", json_object_new_string(r->scheme));
    if (!strcmp(lv, "adaptive")) {
        json_object *ad = json_object_new_object();
        json_object_object_add(ad, "penetration_um", json_object_new_double(1.0));
        json_object_object_add(ad, "levels", json_object_new_int(2));
        json_object_object_add(num, "adaptive", ad);
    }
    /* The row's time step, unless the scene asks for a finer one. */
    json_object *ts = NULL;
    double given;
    if (json_object_object_get_ex(num, "time_step", &ts) && gsi_json_as_double(ts, &given) && given > 0 &&
        given <= r->h) {
        *h = given;
    } else {
        *h = r->h;
        json_object_object_add(num, "time_step", json_object_new_double(r->h));
    }
    *out = c;
    return GS_OK;
}

static json_object *setting_json(const gs_tradeoff *t, const gs_tradeoff_row *r, const gs_tradeoff_choice *c,
                                 bool failed)
{
    json_object *o = json_object_new_object();
    char label[160];
    gs_tradeoff_label(r, label, sizeof label);
    json_object_object_add(o, "level", json_object_new_string(r->level));
    json_object_object_add(o, "h", json_object_new_double(r->h));
    json_object_object_add(o, "refine", json_object_new_int(r->refine));
    if (r->scheme[0])
        json_object_object_add(o, "scheme", json_object_new_string(r->scheme));
    if (r->scale != 1.0)
        json_object_object_add(o, "scale", json_object_new_double(r->scale));
    if (r->zeta != 0.0)
        json_object_object_add(o, "zeta", json_object_new_double(r->zeta));
    json_object_object_add(o, "cost", json_object_new_double(r->cost));
    json_object_object_add(o, "label", json_object_new_string(label));
    json_object *e = json_object_new_object();
    for (int k = 0; k < c->n_targets; k++) {
        double v = r->err[c->target_out[k]];
        if (failed && v <= c->target[k])
            continue;
        json_object_object_add(e, t->out[c->target_out[k]], isnan(v) ? NULL : json_object_new_double(v));
    }
    json_object_object_add(o, failed ? "failed" : "errors", e);
    return o;
}

gs_err gsi_scene_fidelity_targets(json_object *root, json_object **out, bool *copy, char **choice, gs_diag *d)
{
    *out = root;
    *copy = false;
    *choice = NULL;
    json_object *fo = NULL;
    if (!json_object_object_get_ex(root, "fidelity", &fo) || json_object_get_type(fo) != json_type_object)
        return GS_OK;
    static const char *const keys[] = {"targets", NULL};
    GS_TRY(gsi_json_only(fo, "fidelity", keys, d));
    json_object *tg = NULL;
    GS_TRY(gsi_json_object(fo, "targets", "fidelity", true, &tg, d));
    const char *tscene = NULL, *kind = NULL;
    char why[160];
    GS_TRY(classify(root, &tscene, &kind, why, sizeof why, d));
    const char *path = gs_tradeoff_path();
    gs_tradeoff t;
    gs_err e = gs_tradeoff_load(path, &t, d);
    if (e != GS_OK) {
        char m[200];
        snprintf(m, sizeof m, "%.199s", d->message);
        return gs_diag_set(d, e, FIELD, "%s (the measured table the targets are chosen from; "
                           "$GEARSIM_TRADEOFF_TABLE names another)", m);
    }
    int n = 0, idx[GS_TRADEOFF_MAX_OUT];
    double val[GS_TRADEOFF_MAX_OUT];
    json_object_object_foreach(tg, key, v) {
        char f[96];
        snprintf(f, sizeof f, FIELD ".%.60s", key);
        int o = gs_tradeoff_output(&t, key);
        char outs[200] = "";
        for (int k = 0, w = 0; k < t.n_out; k++)
            w += snprintf(outs + w, sizeof outs - (size_t)w, "%s%s", k ? ", " : "", t.out[k]);
        if (o < 0)
            e = gs_diag_set(d, GS_ESCHEMA, f, "unknown output '%.60s'; the trade-off table measures: %s", key, outs);
        else if (!gsi_json_as_double(v, &val[n]) || !(val[n] > 0))
            e = gs_diag_set(d, GS_ERANGE, f, "the target is a relative error, a positive number (e.g. 0.05)");
        for (int k = 0; e == GS_OK && k < n; k++)
            if (idx[k] == o)
                e = gs_diag_set(d, GS_ESCHEMA, f, "output '%s' is targeted twice", t.out[o]);
        if (e == GS_OK && n == GS_TRADEOFF_MAX_OUT)
            e = gs_diag_set(d, GS_ERANGE, f, "at most %d targets", GS_TRADEOFF_MAX_OUT);
        if (e != GS_OK) {
            gs_tradeoff_free(&t);
            return e;
        }
        idx[n++] = o;
    }
    if (n == 0) {
        gs_tradeoff_free(&t);
        return gs_diag_set(d, GS_ESCHEMA, FIELD, "give at least one target, e.g. {\"dte\": 0.05}");
    }
    gs_tradeoff_choice ch;
    e = gs_tradeoff_choose(&t, tscene, n, idx, val, &ch, FIELD, d);
    json_object *c = NULL;
    double h = 0;
    if (e == GS_OK)
        e = set_row(root, &t.rows[ch.row], &c, &h, d);
    if (e != GS_OK) {
        if (c)
            json_object_put(c);
        gs_tradeoff_choice_clear(&ch);
        gs_tradeoff_free(&t);
        return e;
    }
    const gs_tradeoff_row *r = &t.rows[ch.row];
    json_object *res = json_object_new_object(), *tj = json_object_new_object(), *rj = json_object_new_array();
    for (int k = 0; k < n; k++)
        json_object_object_add(tj, t.out[idx[k]], json_object_new_double(val[k]));
    json_object_object_add(res, "targets", tj);
    json_object_object_add(res, "scene_kind", json_object_new_string(kind));
    json_object_object_add(res, "scene_description", json_object_new_string(why));
    json_object_object_add(res, "table", json_object_new_string(path));
    json_object_object_add(res, "table_scene", json_object_new_string(tscene));
    json_object_object_add(res, "cost_unit", json_object_new_string(t.cpu ? "CPU" : "wall"));
    json_object_object_add(res, "choice", setting_json(&t, r, &ch, false));
    for (int j = 0; j < ch.n_rejected; j++)
        json_object_array_add(rj, setting_json(&t, &t.rows[ch.rejected[j]], &ch, true));
    json_object_object_add(res, "rejected", rj);
    json_object_object_add(res, "time_step", json_object_new_double(h));
    char label[160], errs[200] = "", text[640];
    gs_tradeoff_label(r, label, sizeof label);
    for (int k = 0, w = 0; k < n && w >= 0 && (size_t)w < sizeof errs; k++)
        w += snprintf(errs + w, sizeof errs - (size_t)w, "%s%s %.3g <= %g", k ? ", " : "", t.out[idx[k]],
                      r->err[idx[k]], val[k]);
    snprintf(text, sizeof text,
             "%s: the cheapest of %d measured settings on %s (the scene is %s) that meets the targets: %s, "
             "at %.3g %s s per simulated s; %d cheaper settings miss them. Time step %g s%s.",
             label, ch.n_candidates, tscene, why, errs, r->cost, t.cpu ? "CPU" : "wall", ch.n_rejected, h,
             h < r->h ? " (the scene's, finer than the measured setting's)" : "");
    json_object_object_add(res, "why", json_object_new_string(text));
    *choice = gs_strdup(json_object_to_json_string_ext(res, JSON_C_TO_STRING_PLAIN));
    json_object_put(res);
    gs_tradeoff_choice_clear(&ch);
    gs_tradeoff_free(&t);
    if (!*choice) {
        json_object_put(c);
        return GS_ENOMEM;
    }
    *out = c;
    *copy = true;
    return GS_OK;
}

gs_err gs_scene_check_fidelity_choice(const char *text, size_t len, gs_diag *d)
{
    if (len == 0 || len > GS_FIDELITY_CHOICE_MAX || strlen(text) != len)
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint's fidelity choice has %zu bytes (1 to %zu)", len,
                           GS_FIDELITY_CHOICE_MAX);
    json_tokener *tok = json_tokener_new();
    if (!tok)
        return GS_ENOMEM;
    json_object *o = json_tokener_parse_ex(tok, text, (int)len), *c = NULL, *lv = NULL, *why = NULL;
    bool whole = o && json_tokener_get_error(tok) == json_tokener_success &&
                 json_tokener_get_parse_end(tok) == len;
    json_tokener_free(tok);
    gs_err e = GS_OK;
    if (!whole || json_object_get_type(o) != json_type_object)
        e = gs_diag_set(d, GS_EIO, "path", "the checkpoint's fidelity choice is not a JSON object");
    else if (!json_object_object_get_ex(o, "choice", &c) || json_object_get_type(c) != json_type_object ||
             !json_object_object_get_ex(c, "level", &lv) || json_object_get_type(lv) != json_type_string)
        e = gs_diag_set(d, GS_EIO, "path", "the checkpoint's fidelity choice names no level (choice.level)");
    else if (!json_object_object_get_ex(o, "why", &why) || json_object_get_type(why) != json_type_string)
        e = gs_diag_set(d, GS_EIO, "path", "the checkpoint's fidelity choice gives no reason (why)");
    json_object_put(o);
    return e;
}

gs_err gs_scene_adopt_fidelity_choice(gs_scene *sc, const char *text, gs_diag *d)
{
    GS_TRY(gs_scene_check_fidelity_choice(text, strlen(text), d));
    json_object *root = json_tokener_parse(sc->json), *f = NULL;
    bool given = root && json_object_object_get_ex(root, "fidelity", &f) &&
                 json_object_get_type(f) == json_type_string && !strcmp(json_object_get_string(f), "as_given");
    json_object_put(root);
    if (sc->fidelity_choice || !given)
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint holds a fidelity choice for a scene not set from "
                           "targets (its fidelity is not \"as_given\")");
    sc->fidelity_choice = gs_strdup(text);
    return sc->fidelity_choice ? GS_OK : GS_ENOMEM;
}
