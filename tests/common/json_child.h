/* SPDX-License-Identifier: MIT
 * The child object `key` of a JSON object, created empty when missing: for
 * the tools and tests that edit a scene before parsing it
 * (tests/bench/dyn_convergence_run.c, tests/validation/test_reduced_drive.c). */
#ifndef GEARSIM_TESTS_JSON_CHILD_H
#define GEARSIM_TESTS_JSON_CHILD_H

#include <json-c/json.h>

static inline json_object *tj_child(json_object *o, const char *key)
{
    json_object *c;
    if (!json_object_object_get_ex(o, key, &c)) {
        c = json_object_new_object();
        json_object_object_add(o, key, c);
    }
    return c;
}

#endif
