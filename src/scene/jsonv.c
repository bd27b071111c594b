/* SPDX-License-Identifier: MIT
 * Validated access to json-c values; every failure names the JSON path. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "scene/jsonv.h"

void gsi_path(char *out, size_t cap, const char *parent, const char *key)
{
    if (!parent || !parent[0])
        snprintf(out, cap, "%s", key);
    else
        snprintf(out, cap, "%s.%s", parent, key);
}

void gsi_path_index(char *out, size_t cap, const char *parent, const char *key, int i)
{
    char tmp[256];
    gsi_path(tmp, sizeof tmp, parent, key);
    snprintf(out, cap, "%s[%d]", tmp, i);
}

gs_err gsi_json_only(json_object *o, const char *path, const char *const *allowed, gs_diag *d)
{
    json_object_object_foreach(o, key, val)
    {
        (void)val;
        bool ok = false;
        for (const char *const *a = allowed; *a; a++)
            if (strcmp(*a, key) == 0) {
                ok = true;
                break;
            }
        if (!ok) {
            char p[256];
            gsi_path(p, sizeof p, path, key);
            return gs_diag_set(d, GS_ESCHEMA, p, "unknown field '%s'", key);
        }
    }
    return GS_OK;
}

bool gsi_json_as_double(json_object *v, double *out)
{
    if (!v)
        return false;
    json_type t = json_object_get_type(v);
    if (t == json_type_int) {
        *out = (double)json_object_get_int64(v);
        return true;
    }
    if (t == json_type_double) {
        double x = json_object_get_double(v);
        if (!isfinite(x))
            return false;
        *out = x;
        return true;
    }
    return false;
}

/* Look up o[key], writing its JSON path into p. *found says whether the key
 * is there (its value may be JSON null); absent and required is an error. */
static gs_err member(json_object *o, const char *key, const char *path, bool required, char *p,
                     size_t cap, json_object **v, bool *found, gs_diag *d)
{
    gsi_path(p, cap, path, key);
    *found = json_object_object_get_ex(o, key, v);
    if (!*found && required)
        return gs_diag_set(d, GS_ESCHEMA, p, "missing required field '%s'", key);
    return GS_OK;
}

gs_err gsi_json_number(json_object *o, const char *key, const char *path, double lo, double hi,
                       bool required, double def, double *out, gs_diag *d)
{
    char p[256];
    json_object *v;
    bool found;
    GS_TRY(member(o, key, path, required, p, sizeof p, &v, &found, d));
    if (!found) {
        *out = def;
        return GS_OK;
    }
    double x;
    json_type t = json_object_get_type(v);
    if (t != json_type_int && t != json_type_double)
        return gs_diag_set(d, GS_ESCHEMA, p, "'%s' must be a number", key);
    if (!gsi_json_as_double(v, &x))
        return gs_diag_set(d, GS_ERANGE, p, "'%s' must be a finite number", key);
    if (x < lo || x > hi)
        return gs_diag_set(d, GS_ERANGE, p, "'%s' = %g is outside [%g, %g]", key, x, lo, hi);
    *out = x;
    return GS_OK;
}

gs_err gsi_json_positive(json_object *o, const char *key, const char *path, double hi,
                         bool required, double def, double *out, gs_diag *d)
{
    GS_TRY(gsi_json_number(o, key, path, -INFINITY, hi, required, def, out, d));
    if (!json_object_object_get_ex(o, key, NULL))
        return GS_OK; /* absent and optional: the default stands */
    if (!(*out > 0)) {
        char p[256];
        gsi_path(p, sizeof p, path, key);
        return gs_diag_set(d, GS_ERANGE, p, "'%s' must be positive (got %g)", key, *out);
    }
    return GS_OK;
}

gs_err gsi_json_int(json_object *o, const char *key, const char *path, int64_t lo, int64_t hi,
                    bool required, int64_t def, int64_t *out, gs_diag *d)
{
    char p[256];
    json_object *v;
    bool found;
    GS_TRY(member(o, key, path, required, p, sizeof p, &v, &found, d));
    if (!found) {
        *out = def;
        return GS_OK;
    }
    int64_t x;
    if (json_object_get_type(v) == json_type_int) {
        x = json_object_get_int64(v);
    } else if (json_object_get_type(v) == json_type_double) {
        double f = json_object_get_double(v);
        if (!isfinite(f) || f != floor(f) || fabs(f) > 9e15)
            return gs_diag_set(d, GS_ESCHEMA, p, "'%s' must be an integer", key);
        x = (int64_t)f;
    } else {
        return gs_diag_set(d, GS_ESCHEMA, p, "'%s' must be an integer", key);
    }
    if (x < lo || x > hi)
        return gs_diag_set(d, GS_ERANGE, p, "'%s' = %lld is outside [%lld, %lld]", key,
                           (long long)x, (long long)lo, (long long)hi);
    *out = x;
    return GS_OK;
}

gs_err gsi_json_bool(json_object *o, const char *key, const char *path, bool def, bool *out,
                     gs_diag *d)
{
    char p[256];
    json_object *v;
    bool found;
    GS_TRY(member(o, key, path, false, p, sizeof p, &v, &found, d));
    if (!found) {
        *out = def;
        return GS_OK;
    }
    if (json_object_get_type(v) != json_type_boolean)
        return gs_diag_set(d, GS_ESCHEMA, p, "'%s' must be true or false", key);
    *out = json_object_get_boolean(v);
    return GS_OK;
}

gs_err gsi_json_string(json_object *o, const char *key, const char *path, bool required,
                       const char *def, char *out, size_t cap, gs_diag *d)
{
    char p[256];
    json_object *v;
    bool found;
    GS_TRY(member(o, key, path, required, p, sizeof p, &v, &found, d));
    if (!found) {
        snprintf(out, cap, "%s", def ? def : "");
        return GS_OK;
    }
    if (json_object_get_type(v) != json_type_string)
        return gs_diag_set(d, GS_ESCHEMA, p, "'%s' must be a string", key);
    const char *s = json_object_get_string(v);
    size_t n = (size_t)json_object_get_string_len(v);
    if (n == 0 || n >= cap || strlen(s) != n)
        return gs_diag_set(d, GS_ERANGE, p, "'%s' must be a non-empty string of at most %zu bytes",
                           key, cap - 1);
    memcpy(out, s, n + 1);
    return GS_OK;
}

static gs_err typed_member(json_object *o, const char *key, const char *path, bool required,
                           json_object **out, gs_diag *d, json_type want, const char *what)
{
    char p[256];
    *out = NULL;
    json_object *v;
    bool found;
    GS_TRY(member(o, key, path, required, p, sizeof p, &v, &found, d));
    if (!found)
        return GS_OK;
    if (json_object_get_type(v) != want)
        return gs_diag_set(d, GS_ESCHEMA, p, "'%s' must be %s", key, what);
    *out = v;
    return GS_OK;
}

gs_err gsi_json_object(json_object *o, const char *key, const char *path, bool required,
                       json_object **out, gs_diag *d)
{
    return typed_member(o, key, path, required, out, d, json_type_object, "an object");
}

gs_err gsi_json_array(json_object *o, const char *key, const char *path, bool required,
                      json_object **out, gs_diag *d)
{
    return typed_member(o, key, path, required, out, d, json_type_array, "an array");
}
