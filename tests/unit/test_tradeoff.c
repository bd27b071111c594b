/* SPDX-License-Identifier: MIT
 * The measured trade-off table (gearsim/tradeoff.h) and the scene's
 * `"fidelity": {"targets": {...}}`: the table read from CSV, the cheapest
 * setting that meets the targets (the rule of gearctl advise, on small
 * tables written here and on the shipped docs/data/tradeoff.csv), the
 * scene set to it and the choice reported, and each bad target refused
 * with the field named. The same choices as advise.py over a grid of
 * targets: tests/integration/test_fidelity_targets.py. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/scene.h"
#include "gearsim/tradeoff.h"

/* A small table: cost order differs from row order, a tie, a NaN error, the
 * reference (every error 0), another scene. */
static const char *const SMALL =
    "scene,level,h,refine,cost,err_speed,err_dte,err_force,scheme,scale,zeta\n"
    "A,lumped,1e-4,0,0.5,0.001,0.30,0.1,,1,0\n"
    "A,kinematic,1e-4,0,0.1,0.001,1,0.2,,1,0\n"
    "A,ltca,1e-4,0,2,0.001,0.04,0.12,,1,0.02\n"
    "A,calibrated,1e-4,0,2,0.001,0.03,0.11,,1,0\n"
    "A,compliant,1e-4,0,3,0.001,,0.05,,1,0\n"
    "A,contact,1e-5,2,50,0.0001,0.01,0.01,closure_energy,1,0.02\n"
    "A,reduced,1e-5,0,400,0,0,0,closure_energy,3,0.02\n"
    "B,lumped,1e-4,0,0.01,0.001,0.01,0.01,,1,0\n";

static void choose(const gs_tradeoff *t, const char *scene, const char *out, double v, gs_tradeoff_choice *c,
                   gs_err want, gs_diag *d)
{
    int o = gs_tradeoff_output(t, out);
    assert_true(o >= 0);
    gs_err e = gs_tradeoff_choose(t, scene, 1, &o, &v, c, "fidelity.targets", d);
    if (e != want)
        print_error("%s %s %g: %s\n", scene, out, v, d->message);
    assert_int_equal(e, want);
}

static void table_rule(void **state)
{
    (void)state;
    gs_tradeoff t;
    gs_diag d;
    assert_int_equal(gs_tradeoff_parse(SMALL, strlen(SMALL), &t, &d), GS_OK);
    assert_int_equal(t.n_rows, 8);
    assert_int_equal(t.n_out, 3);
    assert_true(t.cpu);
    assert_int_equal(gs_tradeoff_output(&t, "dte_rms"), gs_tradeoff_output(&t, "dte"));
    assert_int_equal(gs_tradeoff_output(&t, "peak_force"), 2);
    assert_int_equal(gs_tradeoff_output(&t, "mesh"), -1); /* not a column of this table */
    assert_true(isnan(t.rows[4].err[1]));
    gs_tradeoff_choice c;
    /* dte 0.05: ltca and calibrated both cost 2; the table's order decides
     * (advise sorts stably); kinematic and lumped are cheaper and miss. */
    choose(&t, "A", "dte", 0.05, &c, GS_OK, &d);
    assert_string_equal(t.rows[c.row].level, "ltca");
    assert_int_equal(c.n_rejected, 2);
    assert_string_equal(t.rows[c.rejected[0]].level, "kinematic");
    assert_string_equal(t.rows[c.rejected[1]].level, "lumped");
    assert_int_equal(c.n_candidates, 6); /* the reference is none */
    gs_tradeoff_choice_clear(&c);
    /* force 0.06: compliant (its dte not measured does not matter) */
    choose(&t, "A", "force", 0.06, &c, GS_OK, &d);
    assert_string_equal(t.rows[c.row].level, "compliant");
    gs_tradeoff_choice_clear(&c);
    /* dte 0.02: compliant's unmeasured dte does not meet it; contact does */
    choose(&t, "A", "dte", 0.02, &c, GS_OK, &d);
    assert_string_equal(t.rows[c.row].level, "contact");
    assert_int_equal(t.rows[c.row].refine, 2);
    assert_string_equal(t.rows[c.row].scheme, "closure_energy");
    gs_tradeoff_choice_clear(&c);
    /* nothing but the reference reaches 0.001: refused, the best named */
    choose(&t, "A", "dte", 0.001, &c, GS_ERANGE, &d);
    assert_string_equal(d.field, "fidelity.targets");
    assert_non_null(strstr(d.message, "best reached: dte 0.01"));
    gs_tradeoff_choice_clear(&c);
    /* another scene's rows are not looked at */
    choose(&t, "B", "dte", 0.05, &c, GS_OK, &d);
    assert_string_equal(t.rows[c.row].scene, "B");
    gs_tradeoff_choice_clear(&c);
    choose(&t, "C", "dte", 0.05, &c, GS_ENOTFOUND, &d);
    gs_tradeoff_choice_clear(&c);
    /* two targets: both must hold */
    int o2[2] = {gs_tradeoff_output(&t, "dte"), gs_tradeoff_output(&t, "force")};
    double v2[2] = {0.05, 0.115};
    assert_int_equal(gs_tradeoff_choose(&t, "A", 2, o2, v2, &c, "fidelity.targets", &d), GS_OK);
    assert_string_equal(t.rows[c.row].level, "calibrated");
    gs_tradeoff_choice_clear(&c);
    char label[160];
    gs_tradeoff_label(&t.rows[5], label, sizeof label);
    assert_string_equal(label, "contact h 1e-05 refine 2 (closure_energy, damping 0.02)");
    gs_tradeoff_free(&t);
    /* a table without the needed columns */
    const char *bad = "scene,level,cost,err_dte\nA,lumped,1,0.1\n";
    assert_int_equal(gs_tradeoff_parse(bad, strlen(bad), &t, &d), GS_EPARSE);
    assert_non_null(strstr(d.message, "scene, level, h and cost"));
    const char *noerr = "scene,level,h,cost\nA,lumped,1e-4,1\n";
    assert_int_equal(gs_tradeoff_parse(noerr, strlen(noerr), &t, &d), GS_EPARSE);
}

/* The shipped table: the advice of docs/tutorials (dte 5 %: ltca on both
 * scenes, the cheapest time step). */
static void shipped_table(void **state)
{
    (void)state;
    gs_tradeoff t;
    gs_diag d;
    assert_int_equal(gs_tradeoff_load(gs_tradeoff_path(), &t, &d), GS_OK);
    gs_tradeoff_choice c;
    const char *scenes[] = {"contact_drive", "planetary_contact"};
    for (int k = 0; k < 2; k++) {
        choose(&t, scenes[k], "dte", 0.05, &c, GS_OK, &d);
        assert_string_equal(t.rows[c.row].level, "ltca");
        assert_true(t.rows[c.row].h == 1e-4);
        for (int j = 0; j < c.n_rejected; j++)
            assert_true(t.rows[c.rejected[j]].err[gs_tradeoff_output(&t, "dte")] > 0.05);
        gs_tradeoff_choice_clear(&c);
    }
    gs_tradeoff_free(&t);
}

/* The builtin scene `name` with "fidelity": fid inserted. */
static gs_err parse_with(const char *name, const char *fid, gs_scene **s, gs_diag *d)
{
    const char *base = gs_scene_builtin(name);
    assert_non_null(base);
    size_t n = strlen(base) + strlen(fid) + 32;
    char *txt = malloc(n);
    assert_non_null(txt);
    const char *br = strchr(base, '{');
    snprintf(txt, n, "%.*s\"fidelity\": %s, %s", (int)(br - base) + 1, base, fid, br + 1);
    gs_err e = gs_scene_parse(txt, strlen(txt), s, d);
    free(txt);
    return e;
}

static void scene_targets(void **state)
{
    (void)state;
    gs_scene *s;
    gs_diag d;
    /* The pair and the planetary train at dte 5 %: every mesh ltca, the
     * gears rigid, the scenes' own finer time step kept; the choice says so. */
    const char *names[] = {"contact_drive", "planetary_contact", "planetary"};
    const char *tables[] = {"contact_drive", "planetary_contact", "planetary_contact"};
    for (int k = 0; k < 3; k++) {
        gs_err e = parse_with(names[k], "{\"targets\": {\"dte\": 0.05}}", &s, &d);
        if (e)
            print_error("%s: %s: %s\n", names[k], d.field, d.message);
        assert_int_equal(e, GS_OK);
        for (int m = 0; m < s->n_meshes; m++)
            assert_int_equal(s->meshes[m].model, GS_MESH_LTCA);
        for (int b = 0; b < s->n_bodies; b++)
            assert_int_not_equal(s->bodies[b].model, GS_MODEL_ELASTIC);
        assert_true(s->time_step == 1e-5);
        assert_non_null(s->fidelity_choice);
        char want[96];
        snprintf(want, sizeof want, "\"table_scene\":\"%s\"", tables[k]);
        assert_non_null(strstr(s->fidelity_choice, want));
        assert_non_null(strstr(s->fidelity_choice, "\"level\":\"ltca\""));
        assert_non_null(strstr(s->fidelity_choice, "\"why\":\"ltca h 0.0001: the cheapest"));
        gs_scene_free(&s);
    }
    /* dte 2 %: the reduced elastic bodies at 2e-5 s (the scene's 1e-5 kept) */
    assert_int_equal(parse_with("contact_drive", "{\"targets\": {\"dte_rms\": 0.02}}", &s, &d), GS_OK);
    assert_int_equal(s->meshes[0].model, GS_MESH_CONTACT);
    assert_int_equal(s->bodies[0].model, GS_MODEL_ELASTIC);
    assert_true(s->bodies[0].reduce_f_max_hz > 0);
    assert_non_null(strstr(s->fidelity_choice, "\"level\":\"reduced\""));
    gs_scene_free(&s);
    /* speed 1e-3 alone: the cheapest row of all (kinematic at 1e-4 s), and
     * its coarser step taken (the scene's 1e-5 is finer: kept) */
    assert_int_equal(parse_with("pair", "{\"targets\": {\"speed\": 0.001}}", &s, &d), GS_OK);
    assert_int_equal(s->meshes[0].model, GS_MESH_KINEMATIC);
    gs_scene_free(&s);
    /* a fidelity name still works, and leaves no choice */
    assert_int_equal(parse_with("contact_drive", "\"ltca\"", &s, &d), GS_OK);
    assert_null(s->fidelity_choice);
    gs_scene_free(&s);
}

static void bad_targets_name_the_field(void **state)
{
    (void)state;
    struct {
        const char *scene, *fid;
        gs_err code;
        const char *field, *says;
    } cases[] = {
        {"pair", "{\"targets\": {\"noise\": 0.05}}", GS_ESCHEMA, "fidelity.targets.noise", "speed, dte, force, mesh"},
        {"pair", "{\"targets\": {\"dte\": 0}}", GS_ERANGE, "fidelity.targets.dte", "positive"},
        {"pair", "{\"targets\": {\"dte\": \"5 %\"}}", GS_ERANGE, "fidelity.targets.dte", "positive"},
        {"pair", "{\"targets\": {\"dte\": 0.05, \"dte_rms\": 0.1}}", GS_ESCHEMA, "fidelity.targets.dte_rms", "twice"},
        {"pair", "{\"targets\": {}}", GS_ESCHEMA, "fidelity.targets", "at least one"},
        {"pair", "{\"target\": {\"dte\": 0.05}}", GS_ESCHEMA, "fidelity.target", ""},
        {"pair", "{}", GS_ESCHEMA, "fidelity.targets", ""},
        {"pair", "{\"targets\": {\"dte\": 1e-6}}", GS_ERANGE, "fidelity.targets", "no measured setting"},
        {"elastic_spin", "{\"targets\": {\"dte\": 0.05}}", GS_ERANGE, "fidelity.targets", "no gear mesh"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        gs_scene *s = NULL;
        gs_diag d;
        gs_err e = parse_with(cases[i].scene, cases[i].fid, &s, &d);
        if (e != cases[i].code || strcmp(d.field, cases[i].field) || !strstr(d.message, cases[i].says))
            print_error("case %zu: %d %s: %s\n", i, (int)e, d.field, d.message);
        assert_int_equal(e, cases[i].code);
        assert_string_equal(d.field, cases[i].field);
        assert_non_null(strstr(d.message, cases[i].says));
        assert_null(s);
    }
    /* a table that cannot be read: the field and the path named */
    const char *keep = getenv("GEARSIM_TRADEOFF_TABLE");
    char *saved = keep ? strdup(keep) : NULL;
    setenv("GEARSIM_TRADEOFF_TABLE", "/nonexistent/tradeoff.csv", 1);
    gs_scene *s = NULL;
    gs_diag d;
    assert_int_equal(parse_with("pair", "{\"targets\": {\"dte\": 0.05}}", &s, &d), GS_EIO);
    assert_string_equal(d.field, "fidelity.targets");
    assert_non_null(strstr(d.message, "/nonexistent/tradeoff.csv"));
    if (saved)
        setenv("GEARSIM_TRADEOFF_TABLE", saved, 1);
    else
        unsetenv("GEARSIM_TRADEOFF_TABLE");
    free(saved);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(table_rule),
        cmocka_unit_test(shipped_table),
        cmocka_unit_test(scene_targets),
        cmocka_unit_test(bad_targets_name_the_field),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
