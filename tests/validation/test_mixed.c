/* SPDX-License-Identifier: MIT
 * Fidelity per body and per mesh, mixed in one train (METHOD.md section 7):
 * the planetary train of planetary_contact with only the ring elastic (held
 * at its outer rim), sun and planets rigid, lumped (then compliant)
 * sun-planet meshes and contact planet-ring meshes. The contact step then carries the lumped
 * meshes' forces as well, solved as a sequential QP (src/step/contact_step.c).
 * Checked, over 40 ms of the ramp-driven, braked train (h 1e-5 s):
 *  - the energy balance E - E0 - W_in + D at round-off (1e-11 of the energy
 *    scale: the fixed point of the sequential QP is the exact discrete
 *    gradient of the sun meshes, to the Newton tolerance);
 *  - the mean sun/carrier speed ratio over the last 10 ms equals
 *    1 + z_ring / z_sun = 4 within 1e-3 (tooth-passing oscillations about
 *    the mean are of order 1e-4 here; the ratio holds as a mean);
 *  - every mesh carries load (the lumped ones report their force, the
 *    contact ones their rows).
 * Elastic gears on linear triangles (vt_scene_linear, mesh.order 1): the
 * figures were measured on them and the checks need some elastic gear;
 * the default quadratic mesh costs about 12 times as much per step. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/step.h"
#include "scene_build.h"

static void elastic_ring_rigid_sun_and_planets(const char *sun_model)
{
    json_object *root = vt_contact_scheme(vt_scene_linear("planetary_contact"), "seed");
    json_object *bs = json_object_object_get(root, "bodies"), *ms = json_object_object_get(root, "meshes");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i);
        const char *name = json_object_get_string(json_object_object_get(b, "name"));
        if (strcmp(name, "ring") != 0 && strcmp(name, "carrier") != 0)
            json_object_object_add(b, "model", json_object_new_string("rigid"));
    }
    for (size_t i = 0; i < json_object_array_length(ms); i++) {
        json_object *m = json_object_array_get_idx(ms, i);
        const char *name = json_object_get_string(json_object_object_get(m, "name"));
        if (strncmp(name, "sun-", 4) == 0)
            json_object_object_add(m, "model", json_object_new_string(sun_model));
    }
    gs_system *s = vt_system(root);
    int sun = -1, carrier = -1;
    for (int i = 0; i < s->n_bodies; i++) {
        if (!strcmp(s->scene->bodies[i].name, "sun"))
            sun = s->bodies[i].coord;
        if (!strcmp(s->scene->bodies[i].name, "carrier"))
            carrier = s->bodies[i].coord;
    }
    assert_true(sun >= 0 && carrier >= 0);
    const int n = 4000, tail = 1000;
    double worst = 0, scale = 0, ws = 0, wc = 0;
    gs_energy e;
    for (int k = 0; k < n; k++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        gs_system_energy(s, &e);
        worst = fmax(worst, fabs(e.balance_residual));
        scale = fmax(scale, fmax(e.total, fmax(e.work_in, e.dissipated)));
        if (k >= n - tail) {
            ws += s->w[sun];
            wc += s->w[carrier];
        }
    }
    double ratio = ws / wc;
    print_message("elastic ring, rigid sun and planets, %s sun meshes, contact ring meshes: balance %.2e of "
                  "%.3e J; sun/carrier %.6f (4); carrier %.4f rad/s\n",
                  sun_model, worst, scale, ratio, wc / tail);
    for (int i = 0; i < s->n_meshes; i++) {
        const gs_gmesh_rt *m = &s->meshes[i];
        print_message("  %-12s force %8.2f N rows %d\n", s->scene->meshes[i].name, m->force, m->n_rows);
        assert_true(m->force > 0);
    }
    assert_true(worst < 1e-11 * scale);
    assert_true(fabs(ratio / 4.0 - 1) < 1e-3);
    gs_system_free(&s);
}

static void lumped_beside_contact(void **state)
{
    (void)state;
    elastic_ring_rigid_sun_and_planets("lumped");
}

static void compliant_beside_contact(void **state)
{
    (void)state;
    elastic_ring_rigid_sun_and_planets("compliant");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(lumped_beside_contact),
        cmocka_unit_test(compliant_beside_contact),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
