/* SPDX-License-Identifier: MIT
 * Parameter sweeps: the specification, each point's scene, the response
 * measured over a point, and the table (include/gearsim/sweep.h). */
#include <errno.h>
#include <hdf5.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gearsim/step.h"
#include "gearsim/sweep.h"
#include "gearsim/util.h"
#include "io/h5attr.h"
#include "scene/jsonv.h"

#define DRIVER_RPM "driver_rpm"

typedef struct sweep_param {
    char path[128];
    int n;
    double *values;
} sweep_param;

struct gs_sweep {
    json_object *scene;         /* the base scene (owned) */
    char scene_name[GS_NAME_MAX];
    int n_params;
    sweep_param params[GS_SWEEP_MAX_PARAMS];
    int n_points;
    double settle, measure, time_step, driver_rpm; /* time_step 0: the scene's; driver_rpm NAN: none */
    int speed_param;            /* index of the driver_rpm parameter, -1 none */
    int mesh;                   /* measured mesh */
    int n_bodies;
    int n_cols;
    char cols[GS_SWEEP_MAX_COLUMNS][80];
    char *canonical;
    char *spec_text;
    double max_bytes, max_steps; /* over the points: scene memory estimate, settle + measure steps */
    int max_bytes_point, max_steps_point;
};

int gs_sweep_points(const gs_sweep *sw) { return sw->n_points; }
int gs_sweep_columns(const gs_sweep *sw) { return sw->n_cols; }
const char *gs_sweep_column(const gs_sweep *sw, int c) { return c >= 0 && c < sw->n_cols ? sw->cols[c] : ""; }
const char *gs_sweep_canonical(const gs_sweep *sw) { return sw->canonical; }
const char *gs_sweep_scene_name(const gs_sweep *sw) { return sw->scene_name; }
const char *gs_sweep_spec_text(const gs_sweep *sw) { return sw->spec_text; }

static void (*poll_fn)(void *);
static void *poll_user;

void gs_sweep_set_poll(void (*fn)(void *user), void *user)
{
    poll_fn = fn;
    poll_user = user;
}

double gs_sweep_max_scene_bytes(const gs_sweep *sw, int *point)
{
    *point = sw->max_bytes_point;
    return sw->max_bytes;
}

double gs_sweep_max_steps(const gs_sweep *sw, int *point)
{
    *point = sw->max_steps_point;
    return sw->max_steps;
}

void gs_sweep_free(gs_sweep **psw)
{
    if (!psw || !*psw)
        return;
    gs_sweep *sw = *psw;
    json_object_put(sw->scene);
    for (int i = 0; i < sw->n_params; i++)
        free(sw->params[i].values);
    free(sw->canonical);
    free(sw->spec_text);
    free(sw);
    *psw = NULL;
}

/* The values of parameter i at point p (grid, last parameter fastest). */
static double param_value(const gs_sweep *sw, int i, int p)
{
    int stride = 1;
    for (int k = sw->n_params - 1; k > i; k--)
        stride *= sw->params[k].n;
    return sw->params[i].values[(p / stride) % sw->params[i].n];
}

/* ---------------------------------------------------------- JSON paths */

/* Set the number at `path` ("a.b[2].c") in root. The containers on the way
 * must exist; the last key of an object may be new. */
static gs_err set_path(json_object *root, const char *path, double v, const char *field, gs_diag *d)
{
    char buf[128];
    snprintf(buf, sizeof buf, "%s", path);
    json_object *cur = root;
    char *p = buf;
    char done[128] = "";
    while (*p) {
        char *dot = strchr(p, '.');
        if (dot)
            *dot = '\0';
        char *br = strchr(p, '[');
        char key[128];
        snprintf(key, sizeof key, "%.*s", br ? (int)(br - p) : (int)strlen(p), p);
        bool last_seg = !dot;
        bool has_index = br != NULL;
        if (key[0]) {
            if (json_object_get_type(cur) != json_type_object)
                return gs_diag_set(d, GS_ENOTFOUND, field, "'%s' is not an object in the scene", done[0] ? done : "(scene)");
            json_object *nx;
            if (last_seg && !has_index) {
                if (json_object_object_get_ex(cur, key, &nx) && json_object_get_type(nx) != json_type_double &&
                    json_object_get_type(nx) != json_type_int)
                    return gs_diag_set(d, GS_ESCHEMA, field, "'%s' is not a number in the scene", path);
                json_object_object_add(cur, key, json_object_new_double(v));
                return GS_OK;
            }
            if (!json_object_object_get_ex(cur, key, &nx))
                return gs_diag_set(d, GS_ENOTFOUND, field, "the scene has no '%s%s%s'", done, done[0] ? "." : "", key);
            cur = nx;
            if (done[0])
                strncat(done, ".", sizeof done - strlen(done) - 1);
            strncat(done, key, sizeof done - strlen(done) - 1);
        }
        while (br) {
            char *end;
            long idx = strtol(br + 1, &end, 10);
            if (*end != ']' || end == br + 1)
                return gs_diag_set(d, GS_ESCHEMA, field, "'%s': an index is [N]", path);
            if (json_object_get_type(cur) != json_type_array || idx < 0 ||
                (size_t)idx >= json_object_array_length(cur))
                return gs_diag_set(d, GS_ENOTFOUND, field, "the scene has no '%s[%ld]'", done, idx);
            char ib[32];
            snprintf(ib, sizeof ib, "[%ld]", idx);
            strncat(done, ib, sizeof done - strlen(done) - 1);
            br = end[1] == '[' ? end + 1 : NULL;
            if (end[1] && end[1] != '[')
                return gs_diag_set(d, GS_ESCHEMA, field, "'%s': nothing may follow ']' but '.' or '['", path);
            if (last_seg && !br) {
                json_object *el = json_object_array_get_idx(cur, (size_t)idx);
                if (json_object_get_type(el) != json_type_double && json_object_get_type(el) != json_type_int)
                    return gs_diag_set(d, GS_ESCHEMA, field, "'%s' is not a number in the scene", path);
                json_object_array_put_idx(cur, (size_t)idx, json_object_new_double(v));
                return GS_OK;
            }
            cur = json_object_array_get_idx(cur, (size_t)idx);
        }
        if (!dot)
            break;
        p = dot + 1;
    }
    return gs_diag_set(d, GS_ESCHEMA, field, "'%s' does not name a number", path);
}

/* ---------------------------------------------------------- steady state */

static int driver_and_brake(const gs_scene *s, int *ld, int *brk)
{
    *ld = *brk = -1;
    for (int i = 0; i < s->n_loads; i++) {
        const gs_scene_load *l = &s->loads[i];
        if (*ld < 0 && (l->type == GS_LOAD_CONSTANT || l->type == GS_LOAD_RAMP))
            *ld = i;
        if (*brk < 0 && l->type == GS_LOAD_BRAKE)
            *brk = i;
    }
    return *ld >= 0 && *brk >= 0;
}

/* Rigid speeds per unit driver speed: a_m . w = 0 for every mesh, w_drv = 1
 * (least squares, minimum norm). */
static bool speed_ratios(const gs_system *sys, int drv, double *ratio)
{
    int n = sys->n_coords, m = sys->n_meshes + 1;
    double *A = calloc((size_t)m * n, sizeof(double)), *b = calloc((size_t)(m > n ? m : n), sizeof(double));
    if (!A || !b) {
        free(A), free(b);
        return false;
    }
    for (int i = 0; i < sys->n_meshes; i++)
        for (int j = 0; j < n; j++)
            A[(size_t)i * n + j] = sys->meshes[i].a[j];
    A[(size_t)(m - 1) * n + sys->bodies[drv].coord] = 1.0;
    b[m - 1] = 1.0;
    /* Minimum norm (SVD): translations of bodies on bearings are free of the
     * rows and take no speed. */
    double *sv = calloc((size_t)(m < n ? m : n), sizeof(double));
    lapack_int rank;
    bool ok = sv && LAPACKE_dgelsd(LAPACK_ROW_MAJOR, m, n, 1, A, n, b, 1, sv, 1e-12, &rank) == 0;
    free(sv);
    for (int j = 0; j < n; j++)
        ratio[j] = b[j];
    free(A), free(b);
    return ok;
}

/* Start the scene in steady state at driver speed rpm: the driver's moment
 * constant, every body at its rigid speed, the brake coefficient set to the
 * power balance M w_d = c w_o^2. */
static gs_err steady_state(json_object *root, double rpm, const char *field, gs_diag *d)
{
    const char *text = json_object_to_json_string_ext(root, JSON_C_TO_STRING_PLAIN);
    gs_scene *s;
    gs_diag pd;
    if (gs_scene_parse(text, strlen(text), &s, &pd) != GS_OK)
        return gs_diag_set(d, GS_ESCHEMA, field, "%s: %s", pd.field, pd.message);
    int ld, brk;
    if (!driver_and_brake(s, &ld, &brk)) {
        gs_scene_free(&s);
        return gs_diag_set(d, GS_ESCHEMA, field, "a speed sweep needs a moment load (the driver) and a brake "
                                                 "in the scene's loads");
    }
    int drv = s->loads[ld].body, out = s->loads[brk].body;
    double moment = s->loads[ld].moment;
    gs_system *k;
    gs_err e = gs_system_new(s, 0, 1, &k, &pd); /* takes s */
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "%s: %s", pd.field, pd.message);
    double *ratio = calloc((size_t)k->n_coords, sizeof(double));
    if (!ratio || k->bodies[drv].coord < 0 || !speed_ratios(k, drv, ratio)) {
        free(ratio);
        gs_system_free(&k);
        return gs_diag_set(d, GS_ESCHEMA, field, "the train has no rigid motion driven by its first moment load");
    }
    double wd = rpm / GS_RPM_PER_RAD_S;
    json_object *init;
    if (!json_object_object_get_ex(root, "initial", &init)) {
        init = json_object_new_object();
        json_object_object_add(root, "initial", init);
    }
    for (int i = 0; i < k->n_bodies; i++) {
        if (k->bodies[i].coord < 0 || k->scene->bodies[i].joint == GS_JOINT_HELD)
            continue;
        const char *name = k->scene->bodies[i].name;
        json_object *b;
        if (!json_object_object_get_ex(init, name, &b)) {
            b = json_object_new_object();
            json_object_object_add(init, name, b);
        }
        json_object_object_del(b, "speed_rpm");
        json_object_object_add(b, "omega", json_object_new_double(wd * ratio[k->bodies[i].coord]));
    }
    double wo = wd * (k->bodies[out].coord >= 0 ? ratio[k->bodies[out].coord] : 0.0);
    free(ratio);
    gs_system_free(&k);
    if (fabs(wo) < 1e-12)
        return gs_diag_set(d, GS_ESCHEMA, field, "the brake's body does not turn with the driver");
    json_object *loads = json_object_object_get(root, "loads");
    json_object *L = json_object_array_get_idx(loads, (size_t)ld), *B = json_object_array_get_idx(loads, (size_t)brk);
    json_object_object_add(L, "type", json_object_new_string("constant"));
    json_object_object_del(L, "ramp_time");
    json_object_object_add(B, "coefficient", json_object_new_double(fabs(moment * wd / (wo * wo))));
    return GS_OK;
}

gs_err gs_sweep_point_scene(const gs_sweep *sw, int p, char **text, gs_diag *d)
{
    *text = NULL;
    if (p < 0 || p >= sw->n_points)
        return gs_diag_set(d, GS_ERANGE, "point", "no point %d (the sweep has %d)", p, sw->n_points);
    json_object *root = NULL;
    if (json_object_deep_copy(sw->scene, &root, NULL) != 0)
        return GS_ENOMEM;
    gs_err e = GS_OK;
    char field[64];
    for (int i = 0; i < sw->n_params && e == GS_OK; i++) {
        if (i == sw->speed_param)
            continue;
        snprintf(field, sizeof field, "parameters[%d].path", i);
        e = set_path(root, sw->params[i].path, param_value(sw, i, p), field, d);
    }
    if (e == GS_OK && sw->time_step > 0) {
        json_object *num;
        if (!json_object_object_get_ex(root, "numerics", &num)) {
            num = json_object_new_object();
            json_object_object_add(root, "numerics", num);
        }
        json_object_object_add(num, "time_step", json_object_new_double(sw->time_step));
    }
    double rpm = sw->speed_param >= 0 ? param_value(sw, sw->speed_param, p) : sw->driver_rpm;
    if (e == GS_OK && isfinite(rpm))
        e = steady_state(root, rpm, sw->speed_param >= 0 ? "parameters" : "driver_rpm", d);
    if (e == GS_OK) {
        *text = gs_strdup(json_object_to_json_string_ext(root, JSON_C_TO_STRING_PLAIN));
        if (!*text)
            e = GS_ENOMEM;
    }
    json_object_put(root);
    return e;
}

/* ---------------------------------------------------------- parsing */

static bool path_chars_ok(const char *p)
{
    /* No empty segment: not '.x', 'x.', 'a..b' nor '.[' (the column keeps
     * the path as written, so it must be the one path it means). */
    size_t n = strlen(p);
    if (!p[0] || p[0] == '.' || p[0] == '[' || p[n - 1] == '.' || strstr(p, "..") || strstr(p, ".[") ||
        strstr(p, "[]") || strstr(p, "]]"))
        return false;
    for (; *p; p++)
        if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') || *p == '_' ||
              *p == '.' || *p == '[' || *p == ']' || *p == '-'))
            return false;
    return true;
}

static gs_err parse_param(json_object *o, const char *pp, sweep_param *sp, gs_diag *d)
{
    static const char *const keys[] = {"path", "values", "from", "to", "points", NULL};
    if (json_object_get_type(o) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, pp, "a parameter is an object {path, values} or {path, from, to, points}");
    GS_TRY(gsi_json_only(o, pp, keys, d));
    char f[200];
    GS_TRY(gsi_json_string(o, "path", pp, true, NULL, sp->path, sizeof sp->path, d));
    gsi_path(f, sizeof f, pp, "path");
    if (!path_chars_ok(sp->path))
        return gs_diag_set(d, GS_ESCHEMA, f, "a path is 'driver_rpm' or a JSON path into the scene "
                                             "(letters, digits, '_', '-', '.', '[N]'), e.g. loads[0].moment");
    json_object *vals = NULL;
    GS_TRY(gsi_json_array(o, "values", pp, false, &vals, d));
    bool range = json_object_object_get_ex(o, "from", NULL) || json_object_object_get_ex(o, "to", NULL) ||
                 json_object_object_get_ex(o, "points", NULL);
    if (!!vals == range)
        return gs_diag_set(d, GS_ESCHEMA, pp, "give either 'values' (a list) or 'from', 'to' and 'points'");
    if (vals) {
        size_t n = json_object_array_length(vals);
        gsi_path(f, sizeof f, pp, "values");
        if (n < 1 || n > GS_SWEEP_MAX_POINTS)
            return gs_diag_set(d, GS_ERANGE, f, "1 to %d values", GS_SWEEP_MAX_POINTS);
        sp->values = calloc(n, sizeof(double));
        if (!sp->values)
            return GS_ENOMEM;
        sp->n = (int)n;
        for (size_t i = 0; i < n; i++)
            if (!gsi_json_as_double(json_object_array_get_idx(vals, i), &sp->values[i]) ||
                fabs(sp->values[i]) > 1e15) {
                gsi_path_index(f, sizeof f, pp, "values", (int)i);
                return gs_diag_set(d, GS_ESCHEMA, f, "a value is a finite number");
            }
        return GS_OK;
    }
    double from, to;
    int64_t np;
    GS_TRY(gsi_json_number(o, "from", pp, -1e15, 1e15, true, 0, &from, d));
    GS_TRY(gsi_json_number(o, "to", pp, -1e15, 1e15, true, 0, &to, d));
    GS_TRY(gsi_json_int(o, "points", pp, 1, GS_SWEEP_MAX_POINTS, true, 0, &np, d));
    sp->values = calloc((size_t)np, sizeof(double));
    if (!sp->values)
        return GS_ENOMEM;
    sp->n = (int)np;
    for (int i = 0; i < sp->n; i++)
        sp->values[i] = np == 1 ? from : from + (to - from) * i / (double)(np - 1);
    return GS_OK;
}

static void add_col(gs_sweep *sw, const char *name)
{
    if (sw->n_cols < GS_SWEEP_MAX_COLUMNS)
        snprintf(sw->cols[sw->n_cols++], sizeof sw->cols[0], "%s", name);
}

/* Prefix d->field with pre (and the scene's fields with pre.scene). */
static gs_err prefixed(gs_diag *d, gs_err e, const char *pre)
{
    if (e == GS_OK || !pre || !pre[0])
        return e;
    char f[sizeof d->field];
    snprintf(f, sizeof f, "%s%s%.140s", pre, d->field[0] ? "." : "", d->field);
    memcpy(d->field, f, sizeof f);
    return e;
}

static gs_err parse(json_object *spec, const char *const *extra, bool check_points, gs_sweep *sw, gs_diag *d)
{
    const char *base[] = {"scene", "parameters", "settle", "measure", "time_step", "mesh", "driver_rpm"};
    const char *keys[32];
    int nk = 0;
    for (size_t i = 0; i < sizeof base / sizeof base[0]; i++)
        keys[nk++] = base[i];
    for (int i = 0; extra && extra[i] && nk < 31; i++)
        keys[nk++] = extra[i];
    keys[nk] = NULL;
    if (json_object_get_type(spec) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, "", "a sweep is an object");
    GS_TRY(gsi_json_only(spec, "", keys, d));
    json_object *scene, *params;
    GS_TRY(gsi_json_object(spec, "scene", "", true, &scene, d));
    GS_TRY(gsi_json_array(spec, "parameters", "", true, &params, d));
    GS_TRY(gsi_json_number(spec, "settle", "", 0, 1e3, false, 0.01, &sw->settle, d));
    GS_TRY(gsi_json_positive(spec, "measure", "", 1e3, false, 0.01, &sw->measure, d));
    GS_TRY(gsi_json_positive(spec, "time_step", "", 1.0, false, 0, &sw->time_step, d));
    sw->driver_rpm = NAN;
    if (json_object_object_get_ex(spec, "driver_rpm", NULL))
        GS_TRY(gsi_json_number(spec, "driver_rpm", "", -1e7, 1e7, true, 0, &sw->driver_rpm, d));
    char mesh[GS_NAME_MAX];
    GS_TRY(gsi_json_string(spec, "mesh", "", false, "", mesh, sizeof mesh, d));
    size_t np = json_object_array_length(params);
    if (np < 1 || np > GS_SWEEP_MAX_PARAMS)
        return gs_diag_set(d, GS_ERANGE, "parameters", "1 to %d parameters", GS_SWEEP_MAX_PARAMS);
    sw->speed_param = -1;
    double total = 1;
    for (size_t i = 0; i < np; i++) {
        char pp[64];
        gsi_path_index(pp, sizeof pp, "", "parameters", (int)i);
        GS_TRY(parse_param(json_object_array_get_idx(params, i), pp, &sw->params[i], d));
        sw->n_params = (int)i + 1;
        for (size_t k = 0; k < i; k++)
            if (!strcmp(sw->params[k].path, sw->params[i].path))
                return gs_diag_set(d, GS_ESCHEMA, pp, "'%s' is swept twice", sw->params[i].path);
        if (!strcmp(sw->params[i].path, DRIVER_RPM))
            sw->speed_param = (int)i;
        total *= sw->params[i].n;
    }
    if (total > GS_SWEEP_MAX_POINTS)
        return gs_diag_set(d, GS_ERANGE, "parameters", "the grid has %.0f points; at most %d", total,
                           GS_SWEEP_MAX_POINTS);
    if (sw->speed_param >= 0 && isfinite(sw->driver_rpm))
        return gs_diag_set(d, GS_ESCHEMA, "driver_rpm", "'driver_rpm' is swept: give it in parameters or here, not both");
    sw->n_points = (int)total;
    if (json_object_deep_copy(scene, &sw->scene, NULL) != 0)
        return GS_ENOMEM;
    const char *text = json_object_to_json_string_ext(scene, JSON_C_TO_STRING_PLAIN);
    gs_scene *s;
    gs_err e = gs_scene_parse(text, strlen(text), &s, d);
    if (e != GS_OK)
        return prefixed(d, e, "scene");
    snprintf(sw->scene_name, sizeof sw->scene_name, "%s", s->name);
    sw->n_bodies = s->n_bodies;
    sw->mesh = 0;
    if (mesh[0]) {
        sw->mesh = -1;
        for (int i = 0; i < s->n_meshes; i++)
            if (!strcmp(s->meshes[i].name, mesh))
                sw->mesh = i;
    }
    if (sw->mesh < 0 || s->n_meshes == 0) {
        gs_scene_free(&s);
        return gs_diag_set(d, GS_ENOTFOUND, "mesh", mesh[0] ? "the scene has no mesh '%s'" : "the scene has no mesh%s",
                           mesh);
    }
    if (s->n_bodies + sw->n_params + 5 > GS_SWEEP_MAX_COLUMNS) {
        gs_scene_free(&s);
        return gs_diag_set(d, GS_ERANGE, "scene.bodies", "a sweep measures at most %d bodies",
                           GS_SWEEP_MAX_COLUMNS - 5 - sw->n_params);
    }
    for (int i = 0; i < sw->n_params; i++)
        add_col(sw, sw->params[i].path);
    add_col(sw, "mesh_hz");
    add_col(sw, "dte_rms_um");
    add_col(sw, "dynamic_factor");
    add_col(sw, "lsf");
    for (int i = 0; i < s->n_bodies; i++) {
        char c[80];
        snprintf(c, sizeof c, "rpm_%s", s->bodies[i].name);
        for (char *q = c; *q; q++)
            if (*q == ',' || *q == '"' || (unsigned char)*q < 0x20)
                *q = '_';
        add_col(sw, c);
    }
    add_col(sw, "balance_rel");
    gs_scene_free(&s);
    /* What determines the table, in one canonical text. */
    json_object *c = json_object_new_object();
    json_object_object_add(c, "scene", json_object_get(sw->scene));
    json_object_object_add(c, "parameters", json_object_get(params));
    json_object_object_add(c, "settle", json_object_new_double(sw->settle));
    json_object_object_add(c, "measure", json_object_new_double(sw->measure));
    json_object_object_add(c, "time_step", json_object_new_double(sw->time_step));
    json_object_object_add(c, "mesh", json_object_new_int(sw->mesh));
    json_object_object_add(c, "driver_rpm", isfinite(sw->driver_rpm) ? json_object_new_double(sw->driver_rpm) : NULL);
    sw->canonical = gs_strdup(json_object_to_json_string_ext(c, JSON_C_TO_STRING_PLAIN | JSON_C_TO_STRING_NOSLASHESCAPE));
    json_object_put(c);
    json_object *own = json_object_new_object();
    for (size_t i = 0; i < sizeof base / sizeof base[0]; i++) {
        json_object *v;
        if (json_object_object_get_ex(spec, base[i], &v))
            json_object_object_add(own, base[i], json_object_get(v));
    }
    sw->spec_text = gs_strdup(json_object_to_json_string_ext(own, JSON_C_TO_STRING_PLAIN));
    json_object_put(own);
    if (!sw->canonical || !sw->spec_text)
        return GS_ENOMEM;
    if (!check_points)
        return GS_OK;
    /* Every point's values must make a valid scene: each parsed here, the
     * first and last built through to their steady state. */
    json_object *copy = NULL;
    int speed_stride = 1;
    for (int k = sw->n_params - 1; k > sw->speed_param && sw->speed_param >= 0; k--)
        speed_stride *= sw->params[k].n;
    for (int p = 0; p < sw->n_points; p++) {
        char *pt = NULL;
        if (poll_fn)
            poll_fn(poll_user);
        /* Points differing only in the driver's speed have the same scene
         * here: the first of them stands for the others (the first and the
         * last point are built through to their steady state). */
        if (sw->speed_param >= 0 && p != sw->n_points - 1 && (p / speed_stride) % sw->params[sw->speed_param].n != 0)
            continue;
        if (p == 0 || p == sw->n_points - 1) {
            e = gs_sweep_point_scene(sw, p, &pt, d);
        } else {
            json_object_put(copy);
            copy = NULL;
            if (json_object_deep_copy(sw->scene, &copy, NULL) != 0)
                return GS_ENOMEM;
            for (int i = 0; i < sw->n_params && e == GS_OK; i++) {
                char field[64];
                snprintf(field, sizeof field, "parameters[%d].path", i);
                if (i != sw->speed_param)
                    e = set_path(copy, sw->params[i].path, param_value(sw, i, p), field, d);
            }
            if (e == GS_OK)
                pt = gs_strdup(json_object_to_json_string_ext(copy, JSON_C_TO_STRING_PLAIN));
        }
        if (e == GS_OK) {
            gs_scene *ps;
            gs_diag pd;
            e = gs_scene_parse(pt, strlen(pt), &ps, &pd);
            if (e == GS_OK) {
                /* What the daemon's limits bound, at every point. */
                double b = gs_scene_estimate_bytes(ps, NULL);
                double h = sw->time_step > 0 ? sw->time_step : ps->time_step;
                double n = ceil(sw->settle / h - 1e-9) + ceil(sw->measure / h - 1e-9);
                if (b > sw->max_bytes)
                    sw->max_bytes = b, sw->max_bytes_point = p;
                if (n > sw->max_steps)
                    sw->max_steps = n, sw->max_steps_point = p;
            }
            gs_scene_free(&ps);
            if (e != GS_OK)
                gs_diag_set(d, e, "parameters", "point %d: %s: %s", p, pd.field, pd.message);
        } else if (!strncmp(d->field, "parameters", 10) && strncmp(d->message, "point", 5)) {
            char m[sizeof d->message];
            snprintf(m, sizeof m, "point %d: %.290s", p, d->message);
            memcpy(d->message, m, sizeof m);
        }
        free(pt);
        if (e != GS_OK)
            break;
    }
    json_object_put(copy);
    return e;
}

gs_err gs_sweep_spec_from_args(json_object *args, const char *prefix, json_object **out, gs_diag *d)
{
    static const char *const own[] = {"groups", "path", "resume", "builtin", "dispatcher", NULL};
    *out = NULL;
    char f[64];
    if (json_object_get_type(args) != json_type_object)
        return gs_diag_set(d, GS_ESCHEMA, prefix, "a sweep is an object");
    json_object *spec = json_object_new_object(), *b = NULL;
    if (!spec)
        return GS_ENOMEM;
    json_object_object_foreach(args, k, v)
    {
        bool skip = false;
        for (int i = 0; own[i]; i++)
            skip |= !strcmp(k, own[i]);
        if (!skip)
            json_object_object_add(spec, k, json_object_get(v));
    }
    if (json_object_object_get_ex(args, "builtin", &b)) {
        const char *name = json_object_get_type(b) == json_type_string ? json_object_get_string(b) : "";
        const char *text = gs_scene_builtin(name);
        if (json_object_object_get_ex(args, "scene", NULL)) {
            json_object_put(spec);
            return gs_diag_set(d, GS_ESCHEMA, prefix, "give exactly one of 'scene' (an object) or 'builtin' (a name)");
        }
        if (!text) {
            json_object_put(spec);
            gsi_path(f, sizeof f, prefix, "builtin");
            return gs_diag_set(d, GS_ENOTFOUND, f, "no builtin scene '%.64s'", name);
        }
        json_object_object_add(spec, "scene", json_tokener_parse(text));
    }
    *out = spec;
    return GS_OK;
}

static gs_err parse_new(json_object *spec, const char *const *extra, bool check_points, gs_sweep **out, gs_diag *d)
{
    *out = NULL;
    gs_sweep *sw = gs_calloc(1, sizeof *sw);
    if (!sw)
        return GS_ENOMEM;
    gs_err e = parse(spec, extra, check_points, sw, d);
    if (e != GS_OK)
        gs_sweep_free(&sw);
    *out = sw;
    return e;
}

gs_err gs_sweep_parse(json_object *spec, const char *prefix, const char *const *extra, gs_sweep **out,
                      gs_diag *d)
{
    return prefixed(d, parse_new(spec, extra, true, out, d), prefix);
}

gs_err gs_sweep_parse_trusted(json_object *spec, gs_sweep **out, gs_diag *d)
{
    return parse_new(spec, NULL, false, out, d);
}

/* ---------------------------------------------------------- the response */

struct gs_sweep_meter {
    const gs_sweep *sw;
    int p;
    int64_t n_settle, n_meas, k;
    double sx, sxx, fbig, fsum, shmax, worst, scale, fmesh;
    int np;
    double *rpm;
};

gs_err gs_sweep_meter_new(const gs_sweep *sw, int p, const gs_system *sys, gs_sweep_meter **out)
{
    gs_sweep_meter *m = gs_calloc(1, sizeof *m);
    if (!m)
        return GS_ENOMEM;
    m->rpm = gs_calloc((size_t)sys->n_bodies + 1, sizeof(double));
    if (!m->rpm) {
        free(m);
        return GS_ENOMEM;
    }
    m->sw = sw;
    m->p = p;
    m->n_settle = lround(sw->settle / sys->h);
    m->n_meas = lround(sw->measure / sys->h);
    if (m->n_meas < 1)
        m->n_meas = 1;
    m->scale = 1e-300;
    *out = m;
    return GS_OK;
}

void gs_sweep_meter_free(gs_sweep_meter **m)
{
    if (!m || !*m)
        return;
    free((*m)->rpm);
    free(*m);
    *m = NULL;
}

int64_t gs_sweep_meter_steps_total(const gs_sweep_meter *m) { return m->n_settle + m->n_meas; }
int64_t gs_sweep_meter_steps_left(const gs_sweep_meter *m) { return m->n_settle + m->n_meas - m->k; }

bool gs_sweep_meter_step(gs_sweep_meter *m, const gs_system *sys)
{
    gs_energy e;
    gs_system_energy(sys, &e);
    m->worst = fmax(m->worst, fabs(e.balance_residual));
    m->scale = fmax(m->scale, fmax(fabs(e.total), fmax(e.work_in, e.dissipated)));
    if (m->k++ >= m->n_settle) {
        const gs_gmesh_rt *g = &sys->meshes[m->sw->mesh];
        m->sx += g->deflection;
        m->sxx += g->deflection * g->deflection;
        m->fbig = fmax(m->fbig, fabs(g->force));
        m->fsum += fabs(g->force);
        double phr = 0;
        for (int j = 0; j < sys->n_coords; j++)
            phr += g->c[j] * sys->w[j];
        m->fmesh += fabs(phr);
        int pl[64];
        double sh[64];
        m->np = gs_system_planet_shares(sys, pl, sh, 64);
        double mx = 0;
        for (int i = 0; i < m->np; i++)
            mx = fmax(mx, sh[i]);
        m->shmax += mx;
        for (int i = 0; i < sys->n_bodies; i++)
            m->rpm[i] += gs_system_rpm(sys, i);
    }
    return m->k < m->n_settle + m->n_meas;
}

void gs_sweep_meter_row(const gs_sweep_meter *m, double *row)
{
    const gs_sweep *sw = m->sw;
    int c = 0;
    for (int i = 0; i < sw->n_params; i++)
        row[c++] = param_value(sw, i, m->p);
    double n = (double)m->n_meas;
    double mean = m->sx / n, var = fmax(m->sxx / n - mean * mean, 0.0);
    row[c++] = m->fmesh / n;
    row[c++] = sqrt(var) * 1e6;
    row[c++] = m->fsum > 0 ? m->fbig / (m->fsum / n) : NAN;
    row[c++] = m->np ? m->shmax / n : NAN;
    for (int i = 0; i < sw->n_bodies; i++)
        row[c++] = m->rpm[i] / n;
    row[c++] = m->worst / m->scale;
}

gs_err gs_sweep_point_serial(const gs_sweep *sw, int p, double *row, gs_diag *d)
{
    char *text;
    GS_TRY(gs_sweep_point_scene(sw, p, &text, d));
    gs_scene *s;
    gs_err e = gs_scene_parse(text, strlen(text), &s, d);
    free(text);
    if (e != GS_OK)
        return e;
    gs_system *sys;
    GS_TRY(gs_system_new(s, 0, 1, &sys, d));
    gs_sweep_meter *m;
    e = gs_sweep_meter_new(sw, p, sys, &m);
    while (e == GS_OK && gs_sweep_meter_steps_left(m) > 0) {
        e = gs_step_serial(sys);
        if (e != GS_OK)
            gs_diag_set(d, e, sys->diag.field, "%s", sys->diag.message[0] ? sys->diag.message : "the step failed");
        else
            gs_sweep_meter_step(m, sys);
    }
    if (e == GS_OK)
        gs_sweep_meter_row(m, row);
    gs_sweep_meter_free(&m);
    gs_system_free(&sys);
    return e;
}

/* ---------------------------------------------------------- the table */

size_t gs_sweep_format_row(const gs_sweep *sw, int p, const double *row, char *buf, size_t cap)
{
    size_t k = 0;
    int n = snprintf(buf, cap, "%d", p);
    k = n > 0 ? (size_t)n : 0;
    for (int c = 0; c < sw->n_cols && k < cap; c++) {
        n = isfinite(row[c]) ? snprintf(buf + k, cap - k, ",%.17g", row[c]) : snprintf(buf + k, cap - k, ",");
        k += n > 0 ? (size_t)n : 0;
    }
    if (k < cap)
        k += (size_t)snprintf(buf + k, cap - k, "\n");
    return k < cap ? k : cap - 1;
}

/* A row's longest text: the point, 25 bytes a value, the newline. */
#define ROW_CAP (16 + 25 * GS_SWEEP_MAX_COLUMNS)

/* Write all of buf (a short write is retried; any error fails). */
static bool write_all(int fd, const char *buf, size_t n)
{
    while (n > 0) {
        ssize_t w = write(fd, buf, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return false;
        buf += w;
        n -= (size_t)w;
    }
    return true;
}

/* A new file beside `path` under an unguessable O_EXCL name (a planted
 * symlink or file is never followed or reused), made 0644 for the table's
 * readers. -1 with the message in d. */
static int create_beside(const char *path, char *tmp, size_t cap, gs_diag *d)
{
    int fd = gs_tmp_create_beside(path, tmp, cap);
    if (fd < 0) {
        gs_diag_set(d, GS_EIO, "path", "cannot create a file beside '%s': %s", path, strerror(errno));
        return -1;
    }
    if (fchmod(fd, 0644) != 0) {
        gs_diag_set(d, GS_EIO, "path", "cannot set the mode of a file beside '%s': %s", path, strerror(errno));
        close(fd);
        unlink(tmp);
        return -1;
    }
    return fd;
}

gs_err gs_sweep_write_csv(const gs_sweep *sw, const double *rows, const unsigned char *done, const char *path,
                          int *keep_fd, gs_diag *d)
{
    if (keep_fd)
        *keep_fd = -1;
    char tmp[4200];
    int fd = create_beside(path, tmp, sizeof tmp, d);
    if (fd < 0)
        return GS_EIO;
    size_t cap = ROW_CAP * 64, k = 0;
    char *buf = malloc(cap);
    bool ok = buf != NULL;
    if (ok) {
        k = (size_t)snprintf(buf, cap, "point");
        for (int c = 0; c < sw->n_cols; c++)
            k += (size_t)snprintf(buf + k, cap - k, ",%s", sw->cols[c]);
        k += (size_t)snprintf(buf + k, cap - k, "\n");
    }
    for (int p = 0; ok && p <= sw->n_points; p++) {
        /* flushed in pieces of about 64 rows, and at the end */
        if (p == sw->n_points || cap - k < ROW_CAP) {
            ok = write_all(fd, buf, k);
            k = 0;
        }
        if (p < sw->n_points && done[p])
            k += gs_sweep_format_row(sw, p, rows + (size_t)p * sw->n_cols, buf + k, cap - k);
    }
    free(buf);
    if (ok && !keep_fd) {
        ok = close(fd) == 0;
        fd = -1;
    }
    if (!ok || rename(tmp, path) != 0) {
        if (fd >= 0)
            close(fd);
        unlink(tmp);
        return gs_diag_set(d, GS_EIO, "path", "cannot write '%s' (disk full?)", path);
    }
    if (keep_fd)
        *keep_fd = fd;
    return GS_OK;
}

gs_err gs_sweep_write_state(const gs_sweep *sw, bool finished, const char *path, gs_diag *d)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "points", json_object_new_int(sw->n_points));
    json_object_object_add(o, "finished", json_object_new_boolean(finished));
    json_object_object_add(o, "sweep", json_object_new_string(sw->canonical));
    const char *txt = json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN);
    char tmp[4200];
    int fd = create_beside(path, tmp, sizeof tmp, d);
    bool ok = fd >= 0 && write_all(fd, txt, strlen(txt));
    json_object_put(o);
    if (fd < 0)
        return GS_EIO;
    if (close(fd) != 0 || !ok || rename(tmp, path) != 0) {
        unlink(tmp);
        return gs_diag_set(d, GS_EIO, "path", "cannot write '%s' (disk full?)", path);
    }
    return GS_OK;
}

int gs_sweep_state(const gs_sweep *sw, const char *text)
{
    json_object *o = text ? json_tokener_parse(text) : NULL;
    if (!o)
        return 0;
    json_object *f, *c;
    int st = 2;
    if (json_object_object_get_ex(o, "finished", &f) && json_object_get_boolean(f))
        st = 3;
    else if (json_object_object_get_ex(o, "sweep", &c) && json_object_get_type(c) == json_type_string &&
             !strcmp(json_object_get_string(c), sw->canonical))
        st = 1;
    json_object_put(o);
    return st;
}

gs_err gs_sweep_append_csv(const gs_sweep *sw, int fd, const double *rows, const int *points, int n, gs_diag *d)
{
    if (n <= 0)
        return GS_OK;
    size_t cap = (size_t)n * ROW_CAP, k = 0;
    char *buf = malloc(cap);
    if (!buf)
        return GS_ENOMEM;
    for (int i = 0; i < n; i++)
        k += gs_sweep_format_row(sw, points[i], rows + (size_t)points[i] * sw->n_cols, buf + k, cap - k);
    /* One write: an interruption leaves at most an unterminated last line,
     * which gs_sweep_read_csv drops (that point is computed again). A write
     * that fails part way is cut off again, so that the next rows do not
     * continue a torn line. */
    off_t at = lseek(fd, 0, SEEK_END);
    bool ok = at >= 0 && write_all(fd, buf, k);
    int en = errno;
    free(buf);
    if (ok)
        return GS_OK;
    bool cut = at >= 0 && ftruncate(fd, at) == 0;
    return gs_diag_set(d, GS_EIO, "path", "cannot append to the table (disk full?): %s%s", strerror(en),
                       cut ? "" : "; a torn row stays at its end");
}

gs_err gs_sweep_read_csv(const gs_sweep *sw, const char *path, double *rows, unsigned char *done, gs_diag *d)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return gs_diag_set(d, GS_ENOTFOUND, "path", "cannot read '%s'", path);
    size_t cap = 65536;
    char *line = malloc(cap);
    if (!line) {
        fclose(f);
        return GS_ENOMEM;
    }
    gs_err e = GS_OK;
    /* The header must be this sweep's. */
    char want[GS_SWEEP_MAX_COLUMNS * 81 + 8];
    size_t k = (size_t)snprintf(want, sizeof want, "point");
    for (int c = 0; c < sw->n_cols; c++)
        k += (size_t)snprintf(want + k, sizeof want - k, ",%s", sw->cols[c]);
    if (!fgets(line, (int)cap, f) || strcspn(line, "\n") != strlen(want) || strncmp(line, want, strlen(want)))
        e = gs_diag_set(d, GS_ESCHEMA, "path", "'%s' is not a table of this sweep (its columns differ)", path);
    while (e == GS_OK && fgets(line, (int)cap, f)) {
        /* An unterminated last line is the tail of an interrupted append:
         * not a row (its point is computed again). */
        if (!strchr(line, '\n') && feof(f))
            break;
        char *q = line, *end;
        long p = strtol(q, &end, 10);
        if (end == q || *end != ',' || p < 0 || p >= sw->n_points) {
            e = gs_diag_set(d, GS_ESCHEMA, "path", "'%s': a row names no point of this sweep", path);
            break;
        }
        q = end;
        for (int c = 0; c < sw->n_cols; c++) {
            if (*q != ',') {
                e = gs_diag_set(d, GS_ESCHEMA, "path", "'%s': point %ld has too few columns", path, p);
                break;
            }
            q++;
            double v = NAN;
            if (*q != ',' && *q != '\n' && *q) {
                v = strtod(q, &end);
                if (end == q) {
                    e = gs_diag_set(d, GS_ESCHEMA, "path", "'%s': point %ld: a value is not a number", path, p);
                    break;
                }
                q = end;
            }
            rows[(size_t)p * sw->n_cols + c] = v;
        }
        if (e == GS_OK && *q != '\n' && *q != '\0')
            e = gs_diag_set(d, GS_ESCHEMA, "path", "'%s': point %ld has too many columns", path, p);
        if (e == GS_OK)
            done[p] = 1;
    }
    free(line);
    fclose(f);
    return e;
}

gs_err gs_sweep_write_h5(const gs_sweep *sw, const double *rows, const unsigned char *done, const char *path,
                         gs_diag *d)
{
    /* HDF5 opens by name: it is given the new file's descriptor's name. */
    char tmp[4200], via_fd[64];
    int fd = create_beside(path, tmp, sizeof tmp, d);
    if (fd < 0)
        return GS_EIO;
    snprintf(via_fd, sizeof via_fd, "/proc/self/fd/%d", fd);
    hid_t f = H5Fcreate(via_fd, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    close(fd);
    if (f < 0) {
        unlink(tmp);
        return gs_diag_set(d, GS_EIO, "path", "cannot write '%s'", path);
    }
    int n = sw->n_points, bad = 0;
    hid_t g = H5Gcreate2(f, "sweep", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    double *col = malloc((size_t)(n ? n : 1) * sizeof(double));
    int *pt = malloc((size_t)(n ? n : 1) * sizeof(int));
    unsigned char *dn = malloc((size_t)(n ? n : 1));
    if (g < 0 || !col || !pt || !dn)
        bad = 1;
    for (int p = 0; !bad && p < n; p++)
        pt[p] = p, dn[p] = done[p] ? 1 : 0;
    if (!bad) {
        bad |= gsi_h5_fixed_ds(g, "point", H5T_NATIVE_INT, pt, (hsize_t)n, 0) != 0;
        bad |= gsi_h5_fixed_ds(g, "done", H5T_NATIVE_UCHAR, dn, (hsize_t)n, 0) != 0;
        bad |= gsi_h5_string_attr(g, "scene", sw->scene_name) < 0;
        bad |= gsi_h5_string_attr(g, "spec", sw->canonical) < 0;
        int cols = sw->n_cols;
        bad |= gsi_h5_scalar_attr(g, "columns", H5T_NATIVE_INT, &cols) < 0;
    }
    for (int c = 0; !bad && c < sw->n_cols; c++) {
        for (int p = 0; p < n; p++)
            col[p] = done[p] ? rows[(size_t)p * sw->n_cols + c] : NAN;
        bad |= gsi_h5_fixed_ds(g, sw->cols[c], H5T_NATIVE_DOUBLE, col, (hsize_t)n, 0) != 0;
    }
    free(col), free(pt), free(dn);
    if (g >= 0)
        H5Gclose(g);
    if (H5Fclose(f) < 0)
        bad = 1;
    if (bad || rename(tmp, path) != 0) {
        unlink(tmp);
        return gs_diag_set(d, GS_EIO, "path", "cannot write '%s' (disk full?)", path);
    }
    return GS_OK;
}
