/* SPDX-License-Identifier: MIT
 * Unit tests of the sweep library (src/sweep/sweep.c) on the builtin
 * `pair` scene: the grid of two parameters (the last fastest) and each
 * point's scene holding its values; the steady-state start (the brake set to
 * the power balance, the driver's moment made constant, the speeds in the
 * tooth ratio); refusals naming the field (unknown path, a path through a
 * number, a value the scene refuses at some point, both values and a range,
 * a parameter swept twice); a point computed in one process, its row
 * (parameters, mean speeds, balance at round-off) and the CSV written and
 * read back bit for bit; rows appended to a CSV kept open, an interrupted
 * append's torn last line dropped on reading, a symlink planted at the old
 * temporary name not followed; the resume state file; the command's
 * arguments made a specification (the daemon's keys dropped, builtin). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gearsim/scene.h"
#include "gearsim/sweep.h"
#include "gearsim/util.h"

/* A sweep of the builtin pair with the given parameters (JSON text). */
static gs_err make(const char *params, const char *extra, gs_sweep **sw, gs_diag *d)
{
    char buf[1024];
    snprintf(buf, sizeof buf, "{\"parameters\": %s, \"settle\": 0.0005, \"measure\": 0.0005%s}", params,
             extra ? extra : "");
    json_object *spec = json_tokener_parse(buf);
    assert_non_null(spec);
    json_object_object_add(spec, "scene", json_tokener_parse(gs_scene_builtin("pair")));
    gs_diag_clear(d);
    gs_err e = gs_sweep_parse(spec, "args", NULL, sw, d);
    json_object_put(spec);
    return e;
}

static double number_at(json_object *root, const char *arr, int i, const char *key)
{
    json_object *a = json_object_object_get(root, arr);
    return json_object_get_double(json_object_object_get(json_object_array_get_idx(a, (size_t)i), key));
}

static void test_grid(void **state)
{
    (void)state;
    gs_sweep *sw;
    gs_diag d;
    assert_int_equal(make("[{\"path\": \"bodies[0].inertia\", \"values\": [1e-4, 2e-4]},"
                          " {\"path\": \"loads[0].moment\", \"from\": 10, \"to\": 30, \"points\": 3}]",
                          NULL, &sw, &d), GS_OK);
    assert_int_equal(gs_sweep_points(sw), 6);
    assert_string_equal(gs_sweep_column(sw, 0), "bodies[0].inertia");
    assert_string_equal(gs_sweep_column(sw, 1), "loads[0].moment");
    /* point 4 = inertia index 1, moment index 1 */
    char *t;
    assert_int_equal(gs_sweep_point_scene(sw, 4, &t, &d), GS_OK);
    json_object *o = json_tokener_parse(t);
    assert_true(number_at(o, "bodies", 0, "inertia") == 2e-4);
    assert_true(number_at(o, "loads", 0, "moment") == 20.0);
    json_object_put(o);
    free(t);
    assert_int_not_equal(gs_sweep_point_scene(sw, 6, &t, &d), GS_OK);
    gs_sweep_free(&sw);
}

static void test_steady_state(void **state)
{
    (void)state;
    gs_sweep *sw;
    gs_diag d;
    assert_int_equal(make("[{\"path\": \"driver_rpm\", \"values\": [1000, 3000]}]", NULL, &sw, &d), GS_OK);
    char *t;
    assert_int_equal(gs_sweep_point_scene(sw, 1, &t, &d), GS_OK);
    gs_scene *s;
    assert_int_equal(gs_scene_parse(t, strlen(t), &s, &d), GS_OK);
    free(t);
    int ld = -1, brk = -1;
    for (int i = 0; i < s->n_loads; i++) {
        if (ld < 0 && (s->loads[i].type == GS_LOAD_CONSTANT || s->loads[i].type == GS_LOAD_RAMP))
            ld = i;
        if (brk < 0 && s->loads[i].type == GS_LOAD_BRAKE)
            brk = i;
    }
    assert_true(ld >= 0 && brk >= 0);
    assert_int_equal(s->loads[ld].type, GS_LOAD_CONSTANT);
    const gs_scene_body *bd = &s->bodies[s->loads[ld].body], *bo = &s->bodies[s->loads[brk].body];
    double wd = 3000 / GS_RPM_PER_RAD_S;
    assert_true(fabs(bd->omega0 / wd - 1) < 1e-12);
    /* external pair: speeds in the inverse tooth ratio, opposite senses */
    double ratio = -(double)bd->gear.teeth / bo->gear.teeth;
    assert_true(fabs(bo->omega0 / (wd * ratio) - 1) < 1e-9);
    /* power balance: M w_d = c w_o^2 */
    assert_true(fabs(s->loads[brk].coefficient * bo->omega0 * bo->omega0 / (s->loads[ld].moment * wd) - 1) < 1e-9);
    gs_scene_free(&s);
    gs_sweep_free(&sw);
}

static void test_refusals(void **state)
{
    (void)state;
    static const struct {
        const char *params, *extra, *field;
    } cases[] = {
        {"[{\"path\": \"nothing.here\", \"values\": [1]}]", NULL, "args.parameters[0].path"},
        {"[{\"path\": \"loads[0].moment.x\", \"values\": [1]}]", NULL, "args.parameters[0].path"},
        {"[{\"path\": \"loads[9].moment\", \"values\": [1]}]", NULL, "args.parameters[0].path"},
        {"[{\"path\": \"bodies[0].inertia\", \"values\": [1e-4, -1, 2e-4]}]", NULL, "args.parameters"},
        {"[{\"path\": \"driver_rpm\", \"values\": [1], \"from\": 1, \"to\": 2, \"points\": 2}]", NULL,
         "args.parameters[0]"},
        {"[{\"path\": \"driver_rpm\", \"values\": [1]}, {\"path\": \"driver_rpm\", \"values\": [2]}]", NULL,
         "args.parameters[1]"},
        {"[{\"path\": \"driver_rpm\", \"values\": []}]", NULL, "args.parameters[0].values"},
        {"[{\"path\": \"a b\", \"values\": [1]}]", NULL, "args.parameters[0].path"},
        {"[]", NULL, "args.parameters"},
        {"[{\"path\": \"driver_rpm\", \"values\": [1]}]", ", \"mesh\": \"none\"", "args.mesh"},
        {"[{\"path\": \"driver_rpm\", \"values\": [1]}]", ", \"driver_rpm\": 5", "args.driver_rpm"},
        {"[{\"path\": \"driver_rpm\", \"values\": [1]}]", ", \"extra\": 5", "args.extra"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        gs_sweep *sw = NULL;
        gs_diag d;
        gs_err e = make(cases[i].params, cases[i].extra, &sw, &d);
        if (e == GS_OK || strcmp(d.field, cases[i].field) != 0)
            fail_msg("case %zu: %s: field '%s' (%s), expected '%s'", i, gs_errcode(e), d.field, d.message,
                     cases[i].field);
        assert_null(sw);
    }
}

static void test_point_and_table(void **state)
{
    (void)state;
    gs_sweep *sw;
    gs_diag d;
    assert_int_equal(make("[{\"path\": \"driver_rpm\", \"values\": [1500, 2500]}]", NULL, &sw, &d), GS_OK);
    int nc = gs_sweep_columns(sw);
    double *rows = calloc((size_t)(2 * nc), sizeof(double)), *back = calloc((size_t)(2 * nc), sizeof(double));
    unsigned char done[2] = {0, 1}, got[2] = {0, 0};
    assert_int_equal(gs_sweep_point_serial(sw, 1, rows + nc, &d), GS_OK);
    assert_true(rows[nc] == 2500.0);
    /* the driver: the body of the scene's first moment load */
    gs_scene *s;
    const char *pair = gs_scene_builtin("pair");
    assert_int_equal(gs_scene_parse(pair, strlen(pair), &s, &d), GS_OK);
    char want[80] = "";
    for (int i = 0; i < s->n_loads && !want[0]; i++)
        if (s->loads[i].type == GS_LOAD_CONSTANT || s->loads[i].type == GS_LOAD_RAMP)
            snprintf(want, sizeof want, "rpm_%s", s->bodies[s->loads[i].body].name);
    gs_scene_free(&s);
    int bal = -1, drv = -1;
    for (int c = 0; c < nc; c++) {
        if (!strcmp(gs_sweep_column(sw, c), "balance_rel"))
            bal = c;
        if (!strcmp(gs_sweep_column(sw, c), want))
            drv = c;
    }
    assert_true(bal > 0 && drv > 0);
    assert_true(rows[nc + bal] < 1e-9);
    /* steady state: the driver's mean speed is the point's (the mesh's
     * vibration averages out over the measured time) */
    assert_true(fabs(rows[nc + drv] / 2500.0 - 1) < 1e-3);
    char path[] = "/tmp/gs_test_sweep_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    assert_int_equal(gs_sweep_write_csv(sw, rows, done, path, NULL, &d), GS_OK);
    assert_int_equal(gs_sweep_read_csv(sw, path, back, got, &d), GS_OK);
    assert_int_equal(got[0], 0);
    assert_int_equal(got[1], 1);
    for (int c = 0; c < nc; c++)
        assert_true(back[nc + c] == rows[nc + c] || (isnan(back[nc + c]) && isnan(rows[nc + c])));
    unlink(path);
    free(rows);
    free(back);
    gs_sweep_free(&sw);
}

static void test_append_and_state(void **state)
{
    (void)state;
    gs_sweep *sw, *other;
    gs_diag d;
    assert_int_equal(make("[{\"path\": \"driver_rpm\", \"values\": [1500, 2000, 2500]}]", NULL, &sw, &d), GS_OK);
    assert_int_equal(make("[{\"path\": \"driver_rpm\", \"values\": [1500, 2500]}]", NULL, &other, &d), GS_OK);
    int nc = gs_sweep_columns(sw);
    double *rows = calloc((size_t)(3 * nc), sizeof(double)), *back = calloc((size_t)(3 * nc), sizeof(double));
    for (int i = 0; i < 3 * nc; i++)
        rows[i] = i % 5 == 3 ? NAN : 1.0 / (i + 3.0) - 7e-9 * i;
    unsigned char none[3] = {0, 0, 0}, got[3] = {0, 0, 0};
    char dir[] = "/tmp/gs_test_sweep_XXXXXX", path[600], tmp[640], victim[640];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/t.csv", dir);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    snprintf(victim, sizeof victim, "%s/victim", dir);
    FILE *f = fopen(victim, "w");
    assert_non_null(f);
    fputs("victim\n", f);
    fclose(f);
    assert_int_equal(symlink(victim, tmp), 0);
    /* header only, kept open; the planted link at the old name untouched */
    int fd = -1;
    assert_int_equal(gs_sweep_write_csv(sw, rows, none, path, &fd, &d), GS_OK);
    assert_true(fd >= 0);
    struct stat st;
    assert_int_equal(lstat(path, &st), 0);
    assert_true(S_ISREG(st.st_mode) && (st.st_mode & 0777) == 0644);
    assert_int_equal(lstat(tmp, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    assert_int_equal(lstat(victim, &st), 0);
    assert_int_equal((int)st.st_size, 7);
    /* points 2 and 0 appended, then an append torn after a few bytes */
    int pts[2] = {2, 0};
    assert_int_equal(gs_sweep_append_csv(sw, fd, rows, pts, 2, &d), GS_OK);
    char row1[4096];
    size_t n = gs_sweep_format_row(sw, 1, rows + nc, row1, sizeof row1);
    assert_true(n > 20 && row1[n - 1] == '\n');
    assert_int_equal(write(fd, row1, 12), 12);
    close(fd);
    assert_int_equal(gs_sweep_read_csv(sw, path, back, got, &d), GS_OK);
    assert_true(got[0] && !got[1] && got[2]);
    for (int p = 0; p < 3; p += 2)
        for (int c = 0; c < nc; c++) {
            double a = back[p * nc + c], b = rows[p * nc + c];
            assert_true(a == b || (isnan(a) && isnan(b)));
        }
    /* a row with a column too many (a torn row glued to the next) is refused */
    assert_int_equal(gs_sweep_write_csv(sw, rows, none, path, NULL, &d), GS_OK);
    f = fopen(path, "a");
    assert_non_null(f);
    fwrite(row1, 1, n - 1, f);
    fputs(",1\n", f);
    fclose(f);
    assert_int_equal(gs_sweep_read_csv(sw, path, back, got, &d), GS_ESCHEMA);
    assert_non_null(strstr(d.message, "too many columns"));
    assert_string_equal(d.field, "path");
    /* the state file */
    char sp[640];
    snprintf(sp, sizeof sp, "%s/t.sweep.json", dir);
    size_t len;
    for (int fin = 0; fin < 2; fin++) {
        assert_int_equal(gs_sweep_write_state(sw, fin, sp, &d), GS_OK);
        char *text = gs_read_file(sp, 1 << 20, &len);
        assert_int_equal(gs_sweep_state(sw, text), fin ? 3 : 1);
        assert_int_equal(gs_sweep_state(other, text), fin ? 3 : 2);
        free(text);
    }
    assert_int_equal(gs_sweep_state(sw, NULL), 0);
    assert_int_equal(gs_sweep_state(sw, "not json"), 0);
    unlink(sp);
    unlink(path);
    unlink(tmp);
    unlink(victim);
    assert_int_equal(rmdir(dir), 0); /* nothing else was left in it */
    free(rows);
    free(back);
    gs_sweep_free(&sw);
    gs_sweep_free(&other);
}

static void test_spec_from_args(void **state)
{
    (void)state;
    json_object *args = json_tokener_parse("{\"builtin\": \"pair\", \"groups\": 2, \"path\": \"x\", \"resume\": true,"
                                           " \"parameters\": [{\"path\": \"driver_rpm\", \"values\": [1500]}]}");
    json_object *spec;
    gs_diag d;
    assert_int_equal(gs_sweep_spec_from_args(args, "args", &spec, &d), GS_OK);
    assert_true(json_object_object_get_ex(spec, "scene", NULL) && json_object_object_get_ex(spec, "parameters", NULL));
    assert_int_equal(json_object_object_length(spec), 2);
    gs_sweep *sw;
    assert_int_equal(gs_sweep_parse(spec, "args", NULL, &sw, &d), GS_OK);
    assert_string_equal(gs_sweep_scene_name(sw), "spur pair 20/30");
    gs_sweep_free(&sw);
    json_object_put(spec);
    json_object_object_add(args, "builtin", json_object_new_string("nope"));
    assert_int_equal(gs_sweep_spec_from_args(args, "args", &spec, &d), GS_ENOTFOUND);
    assert_string_equal(d.field, "args.builtin");
    assert_null(spec);
    json_object_object_add(args, "scene", json_object_new_object());
    assert_int_equal(gs_sweep_spec_from_args(args, "args", &spec, &d), GS_ESCHEMA);
    assert_string_equal(d.field, "args");
    json_object_put(args);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_grid),
        cmocka_unit_test(test_steady_state),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_point_and_table),
        cmocka_unit_test(test_append_and_state),
        cmocka_unit_test(test_spec_from_args),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
