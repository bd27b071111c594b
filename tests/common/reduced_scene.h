/* SPDX-License-Identifier: MIT
 * contact_drive as the reduced-body tests run it (tests/validation/
 * test_reduced_drive.c, test_reduced_resume.c): h 1e-5 s, closure_energy,
 * 2 % damping at 9.2 kHz on every gear; reduced to f_max (0: full) on every
 * elastic gear with the residual rule `rule` (NULL: the default); extra (or
 * NULL): a material field set to extra_v on gear 0. The scene as a JSON
 * object (the caller's to edit and put), NULL when the builtin does not
 * parse. */
#ifndef GEARSIM_TESTS_REDUCED_SCENE_H
#define GEARSIM_TESTS_REDUCED_SCENE_H

#include <json-c/json.h>

#include "gearsim/scene.h"
#include "json_child.h"

static inline json_object *reduced_drive_scene(double fmax, const char *rule, const char *extra, double extra_v)
{
    json_object *root = json_tokener_parse(gs_scene_builtin("contact_drive"));
    if (!root)
        return NULL;
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i);
        json_object *mat = tj_child(b, "material");
        json_object_object_add(mat, "damping_ratio", json_object_new_double(0.02));
        json_object_object_add(mat, "damping_hz", json_object_new_double(9200));
        if (extra && i == 0)
            json_object_object_add(mat, extra, json_object_new_double(extra_v));
        if (fmax > 0)
            json_object_object_add(tj_child(b, "reduction"), "f_max_hz", json_object_new_double(fmax));
        if (fmax > 0 && rule)
            json_object_object_add(tj_child(b, "reduction"), "residual", json_object_new_string(rule));
    }
    json_object_object_add(tj_child(root, "numerics"), "time_step", json_object_new_double(1e-5));
    json_object_object_add(tj_child(root, "numerics"), "contact", json_object_new_string("closure_energy"));
    return root;
}

#endif
