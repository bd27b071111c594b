/* SPDX-License-Identifier: MIT
 * Internal: typed, validated access to json-c objects with diagnostics that
 * name the field by its JSON path. Shared by the scene parser and the
 * service's command argument checks. */
#ifndef GSI_JSONV_H
#define GSI_JSONV_H

#include <json-c/json.h>

#include "gearsim/error.h"
#include "gearsim/types.h"

/* Join a parent path and a key ("bodies[1]" + "teeth" -> "bodies[1].teeth"). */
void gsi_path(char *out, size_t cap, const char *parent, const char *key);
void gsi_path_index(char *out, size_t cap, const char *parent, const char *key, int i);

/* Reject keys of o that are not in the NULL-terminated list `allowed`. */
gs_err gsi_json_only(json_object *o, const char *path, const char *const *allowed, gs_diag *d);

/* Numbers: must be finite JSON numbers within [lo, hi] (inclusive unless
 * strict). Missing: *out = def and GS_OK unless required. */
gs_err gsi_json_number(json_object *o, const char *key, const char *path, double lo, double hi,
                       bool required, double def, double *out, gs_diag *d);
/* Like gsi_json_number but strictly positive. */
gs_err gsi_json_positive(json_object *o, const char *key, const char *path, double hi,
                         bool required, double def, double *out, gs_diag *d);
gs_err gsi_json_int(json_object *o, const char *key, const char *path, int64_t lo, int64_t hi,
                    bool required, int64_t def, int64_t *out, gs_diag *d);
gs_err gsi_json_bool(json_object *o, const char *key, const char *path, bool def, bool *out,
                     gs_diag *d);
/* String of at most cap-1 bytes; required or default (def may be NULL -> ""). */
gs_err gsi_json_string(json_object *o, const char *key, const char *path, bool required,
                       const char *def, char *out, size_t cap, gs_diag *d);
/* Object member that must be a JSON object (or absent: *out = NULL). */
gs_err gsi_json_object(json_object *o, const char *key, const char *path, bool required,
                       json_object **out, gs_diag *d);
gs_err gsi_json_array(json_object *o, const char *key, const char *path, bool required,
                      json_object **out, gs_diag *d);
/* A JSON value as a finite double (integers and doubles accepted). */
bool gsi_json_as_double(json_object *v, double *out);

#endif
