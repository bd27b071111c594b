/* SPDX-License-Identifier: MIT
 * Internal: a strict RFC 8259 check of JSON text, run before json-c (whose
 * tokener accepts comments, single quotes, trailing commas, leading zeros,
 * NaN/Infinity, duplicate keys and lone surrogates). Requests and scenes go
 * through it. */
#ifndef GSI_JSONSTRICT_H
#define GSI_JSONSTRICT_H

#include <stddef.h>

#include "gearsim/error.h"

/* Deepest nesting of arrays and objects accepted (json-c's tokener depth). */
#define GSI_JSON_MAX_DEPTH 64

/* GS_OK when text[0..len) is one JSON value (RFC 8259) with surrounding
 * whitespace only, valid UTF-8, no duplicate keys in any object (compared
 * after unescaping), no NUL (raw or \u0000) in strings, only paired
 * surrogate escapes and only numbers that fit a double. Otherwise
 * GS_EPARSE (GS_ERANGE for a number beyond a double) with d->field the JSON path of the offending value under
 * `prefix` (e.g. "args.scene.bodies[0]") and a message giving the byte
 * offset and the reason. */
gs_err gsi_json_strict(const char *text, size_t len, const char *prefix, gs_diag *d);

#endif
