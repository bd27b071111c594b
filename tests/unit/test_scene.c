/* SPDX-License-Identifier: MIT
 * Scene validation: the builtin scenes parse; each bad value is refused with
 * the right code and a field path naming it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <stdio.h>
#include <math.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/scene.h"

static void builtins_parse(void **state)
{
    (void)state;
    for (const char *const *n = gs_scene_builtin_names(); *n; n++) {
        const char *t = gs_scene_builtin(*n);
        gs_scene *s;
        gs_diag d;
        gs_err e = gs_scene_parse(t, strlen(t), &s, &d);
        if (e)
            print_error("%s: %s: %s\n", *n, d.field, d.message);
        assert_int_equal(e, GS_OK);
        /* Every example moves something: a pair or train, or one free gear. */
        assert_true(s->n_bodies >= 2 || (s->n_bodies == 1 && s->bodies[0].omega0 != 0));
        gs_scene_free(&s);
        assert_null(s);
    }
}

/* Replace the first occurrence of `from` in the pair scene by `to`. */
static gs_err parse_edit(const char *base, const char *from, const char *to, gs_diag *d)
{
    const char *t = gs_scene_builtin(base);
    const char *at = strstr(t, from);
    assert_non_null(at);
    char buf[16384];
    snprintf(buf, sizeof buf, "%.*s%s%s", (int)(at - t), t, to, at + strlen(from));
    gs_scene *s = NULL;
    gs_err e = gs_scene_parse(buf, strlen(buf), &s, d);
    gs_scene_free(&s);
    return e;
}

static void bad_values_name_the_field(void **state)
{
    (void)state;
    struct {
        const char *base, *from, *to;
        gs_err code;
        const char *field;
    } cases[] = {
        {"pair", "\"teeth\":20", "\"teeth\":-3", GS_ERANGE, "bodies[0].teeth"},
        {"pair", "\"teeth\":20", "\"teeth\":\"x\"", GS_ESCHEMA, "bodies[0].teeth"},
        {"pair", "\"module_mm\":2.5", "\"module_mm\":0", GS_ERANGE, "bodies[0].module_mm"},
        {"pair", "\"module_mm\":2.5", "\"module_mm\":1e400", GS_ERANGE, "bodies[0].module_mm"},
        {"pair", "\"time_step\":1e-05", "\"time_step\":-1", GS_ERANGE, "numerics.time_step"},
        {"pair", "\"time_step\":1e-05", "\"time_step\":0", GS_ERANGE, "numerics.time_step"},
        {"pair", "\"face_width_mm\":10", "\"face_width_mm\":10,\"colour\":1", GS_ESCHEMA, "bodies[0].colour"},
        {"pair", "\"body\":\"pinion\",\"type\":\"fixed_axis\"", "\"body\":\"nobody\",\"type\":\"fixed_axis\"", GS_ENOTFOUND, "joints[0].body"},
        {"pair", "\"coefficient\":0.3", "\"coefficient\":-0.3", GS_ERANGE, "loads[1].coefficient"},
        {"pair", "\"type\":\"ramp\"", "\"type\":\"wobble\"", GS_ERANGE, "loads[0].type"},
        {"pair", "\"centre_mm\":[62.5,0]", "\"centre_mm\":[90,0]", GS_EGEOMETRY, "meshes[0].gears"},
        {"pair", "\"name\":\"wheel\"", "\"name\":\"pinion\"", GS_ESCHEMA, "bodies[1].name"},
        {"planetary", "\"teeth\":72", "\"teeth\":73", GS_EGEOMETRY, ""},
        {"planetary", "\"mass\":1.5,", "", GS_ESCHEMA, "bodies[5]"},
        {"contact_impact", "\"model\":\"contact\"", "\"model\":\"contact\",\"passes\":\"three\"", GS_ERANGE, "meshes[0].passes"},
        {"contact_impact", "\"model\":\"contact\"", "\"model\":\"contact\",\"stiffness\":1e8", GS_ESCHEMA, "meshes[0].stiffness"},
        {"pair", "\"model\":\"lumped\"", "\"model\":\"lumped\",\"constrain\":\"predicted\"", GS_ESCHEMA, "meshes[0].constrain"},
        {"pair", "\"type\":\"rectangular\",\"single\":140000000.0,\"double\":280000000.0",
         "\"type\":\"calibrated\",\"calibration\":\"chord\"", GS_ERANGE, "meshes[0].stiffness.calibration"},
        {"pair", "\"type\":\"rectangular\"", "\"type\":\"rectangular\",\"calibration\":\"secant\"", GS_ESCHEMA,
         "meshes[0].stiffness.calibration"},
        {"elastic_spin", "\"tip_load\":2000", "\"tip_load\":\"big\"", GS_ESCHEMA, "initial.gear.tip_load"},
        {"pair", "\"initial\":{}", "\"initial\":{\"pinion\":{\"tip_load\":5}}", GS_ERANGE, "initial.pinion.tip_load"},
        {"elastic_spin", "\"rim\":3}", "\"rim\":3,\"refine\":9}", GS_ERANGE, "bodies[0].mesh.refine"},
        {"elastic_spin", "\"fields_every\":100", "\"fields_every\":-1", GS_ERANGE, "outputs.fields_every"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        gs_diag d;
        gs_diag_clear(&d);
        gs_err e = parse_edit(cases[i].base, cases[i].from, cases[i].to, &d);
        print_message("case %zu: %s -> code %s, field '%s': %s\n", i, cases[i].to, gs_errcode(e), d.field, d.message);
        assert_int_equal(e, cases[i].code);
        if (cases[i].field[0])
            assert_string_equal(d.field, cases[i].field);
        assert_true(strlen(d.message) > 0);
    }
}

/* The short planetary description expands into the full scene. */
static void train_expands(void **state)
{
    (void)state;
    const char *t = "{\"name\":\"t\",\"train\":{\"type\":\"planetary\",\"module_mm\":2.5,"
                    "\"face_width_mm\":10,\"sun\":{\"teeth\":24},\"planet\":{\"teeth\":24},"
                    "\"ring\":{\"teeth\":72,\"addendum\":0.8,\"hub_radius_mm\":100},\"planets\":3,"
                    "\"carrier\":{\"mass\":1.5,\"inertia\":0.002},\"mesh_model\":\"kinematic\"},"
                    "\"loads\":[{\"body\":\"sun\",\"type\":\"constant\",\"moment\":1}]}";
    gs_scene *s;
    gs_diag d;
    gs_err e = gs_scene_parse(t, strlen(t), &s, &d);
    if (e)
        print_error("train: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    assert_int_equal(s->n_bodies, 6);
    assert_int_equal(s->n_meshes, 6);
    int p2 = gs_scene_find_body(s, "planet2");
    assert_true(p2 >= 0);
    /* tight-mesh sun-planet distance of a standard 24/24 pair: 60 mm */
    assert_true(fabs(s->bodies[p2].carrier_radius - 0.060) < 1e-9);
    assert_true(fabs(s->bodies[p2].carrier_angle - 2.0 * GS_PI / 3.0) < 1e-12);
    assert_int_equal(s->bodies[gs_scene_find_body(s, "ring")].joint, GS_JOINT_HELD);
    assert_int_equal(s->meshes[1].model, GS_MESH_KINEMATIC);
    print_message("train: %d bodies, %d meshes, carrier radius %.6f mm\n", s->n_bodies, s->n_meshes,
                  s->bodies[p2].carrier_radius * 1e3);
    gs_scene_free(&s);
    /* 5 planets cannot be assembled with 24 + 72 teeth: the error names it. */
    char bad[2048];
    snprintf(bad, sizeof bad, "%s", t);
    char *q = strstr(bad, "\"planets\":3");
    assert_non_null(q);
    q[10] = '5';
    e = gs_scene_parse(bad, strlen(bad), &s, &d);
    print_message("train with 5 planets: %s, field '%s': %s\n", gs_errcode(e), d.field, d.message);
    assert_int_equal(e, GS_EGEOMETRY);
    /* a path into the (expanded) scene: the ring's tooth count */
    assert_non_null(strstr(d.field, "bodies["));
    assert_non_null(strstr(d.field, "].teeth"));
    assert_null(s);
}

/* The mesh density of an elastic gear: without "mesh" the mesher's default
 * (quadratic, gs_gear_mesh_opts_defaults); a given order brings that order's
 * default counts (gs_gear_mesh_opts_for_order), given counts override them. */
static void mesh_defaults(void **state)
{
    (void)state;
    const char *mesh[] = {"", ",\"mesh\":{\"order\":1}", ",\"mesh\":{\"order\":2}",
                          ",\"mesh\":{\"order\":1,\"rim\":5}", ",\"mesh\":{\"flank\":6}"};
    for (int c = 0; c < 5; c++) {
        char t[1024];
        snprintf(t, sizeof t,
                 "{\"name\":\"m\",\"bodies\":[{\"name\":\"g\",\"type\":\"gear\",\"teeth\":20,"
                 "\"module_mm\":2,\"model\":\"elastic\"%s}],\"joints\":[{\"body\":\"g\","
                 "\"type\":\"fixed_axis\"}],\"initial\":{\"g\":{\"omega\":1}}}",
                 mesh[c]);
        gs_scene *s;
        gs_diag d;
        gs_err e = gs_scene_parse(t, strlen(t), &s, &d);
        if (e)
            print_error("case %d: %s: %s\n", c, d.field, d.message);
        assert_int_equal(e, GS_OK);
        const gs_mesh_density *m = &s->bodies[0].mesh;
        gs_gear_mesh_opts o;
        if (c == 0 || c == 4)
            gs_gear_mesh_opts_defaults(&o);
        else
            gs_gear_mesh_opts_for_order(&o, c == 2 ? 2 : 1);
        if (c == 3)
            o.rim = 5;
        if (c == 4)
            o.flank = 6;
        print_message("mesh case %d: order %d flank %d across %d rim %d grading %g\n", c, m->order,
                      m->flank, m->across, m->rim, m->grading);
        assert_int_equal(m->order, c == 1 || c == 3 ? 1 : 2);
        assert_int_equal(m->order, o.order);
        assert_int_equal(m->flank, o.flank);
        assert_int_equal(m->across, o.across);
        assert_int_equal(m->rim, o.rim);
        assert_int_equal(m->refine, 0);
        assert_true(m->grading == o.grading);
        gs_scene_free(&s);
    }
    /* the two orders' defaults differ (the linear default keeps its counts) */
    gs_gear_mesh_opts a, b;
    gs_gear_mesh_opts_for_order(&a, 1);
    gs_gear_mesh_opts_for_order(&b, 2);
    assert_true(a.rim != b.rim || a.grading != b.grading);
}

static void not_json(void **state)
{
    (void)state;
    const char *bad[] = {"", "{", "[1,2]", "{\"bodies\":[]}trailing", "null"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        gs_scene *s;
        gs_diag d;
        gs_err e = gs_scene_parse(bad[i], strlen(bad[i]), &s, &d);
        assert_true(e == GS_EPARSE || e == GS_ESCHEMA);
        assert_null(s);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(builtins_parse),
        cmocka_unit_test(bad_values_name_the_field),
        cmocka_unit_test(train_expands),
        cmocka_unit_test(mesh_defaults),
        cmocka_unit_test(not_json),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
