/* SPDX-License-Identifier: MIT
 * The variants of contact_drive the trade-off table measures (tests/bench/
 * bench_tradeoff.c; tests/bench/dyn_convergence_run.c runs them by name):
 * contact_drive_relief, both gears with pair_relief's linear tip relief
 * (10.3 um over 4.466 mm); contact_drive_errors, pitch-error tables on both
 * gears (a long-wave cumulative deviation plus a tooth-to-tooth one, about
 * 5 um peak to peak) and run-out (wheel 5 um at 30 deg, pinion 3 um at
 * 120 deg); contact_drive_pitch and contact_drive_runout, each alone. */
#ifndef GEARSIM_TESTS_DRIVE_VARIANT_H
#define GEARSIM_TESTS_DRIVE_VARIANT_H

#include <json-c/json.h>
#include <math.h>
#include <string.h>

#include "gearsim/types.h"

/* Is `name` one of the variants? */
static inline int drive_variant_name(const char *name)
{
    static const char *const v[] = {"contact_drive_relief", "contact_drive_errors", "contact_drive_pitch",
                                    "contact_drive_runout", NULL};
    for (const char *const *p = v; *p; p++)
        if (!strcmp(name, *p))
            return 1;
    return 0;
}

/* Apply the variant `scene` to contact_drive's JSON `root`. */
static inline void drive_variant(json_object *root, const char *scene)
{
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i), *t;
        if (!json_object_object_get_ex(b, "teeth", &t))
            continue;
        int z = json_object_get_int(t), wheel = z == 30;
        if (!strcmp(scene, "contact_drive_relief")) {
            json_object *tr = json_object_new_object(), *mod = json_object_new_object();
            json_object_object_add(tr, "amount_um", json_object_new_double(10.3));
            json_object_object_add(tr, "length_mm", json_object_new_double(4.466));
            json_object_object_add(tr, "shape", json_object_new_string("linear"));
            json_object_object_add(mod, "tip_relief", tr);
            json_object_object_add(b, "modification", mod);
        } else if (!strcmp(scene, "contact_drive_errors") || !strcmp(scene, "contact_drive_pitch") ||
                   !strcmp(scene, "contact_drive_runout")) {
            json_object *pe = json_object_new_array(), *ro = json_object_new_object();
            for (int k = 0; k < z; k++)
                json_object_array_add(pe, json_object_new_double(2.0 * sin(2 * GS_PI * k / z + (wheel ? 0.3 : 1.1)) +
                                                                 (k % 2 ? 0.5 : -0.5)));
            if (strcmp(scene, "contact_drive_runout"))
                json_object_object_add(b, "pitch_errors_um", pe);
            else
                json_object_put(pe);
            json_object_object_add(ro, "eccentricity_um", json_object_new_double(wheel ? 5.0 : 3.0));
            json_object_object_add(ro, "phase_deg", json_object_new_double(wheel ? 30.0 : 120.0));
            if (strcmp(scene, "contact_drive_pitch"))
                json_object_object_add(b, "runout", ro);
            else
                json_object_put(ro);
        }
    }
}

#endif
