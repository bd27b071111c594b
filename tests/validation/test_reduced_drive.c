/* SPDX-License-Identifier: MIT
 * The reduced elastic body in the contact step (docs/explanation/elastic_body.md "Reduced elastic
 * body", docs/validation/data.md): contact_drive (both
 * gears elastic, quadratic default mesh, closure_energy, 2 % damping at
 * 9.2 kHz) from rest over the first 4 ms of the moment ramp at h = 1e-5 s,
 * once with the full FE bodies and twice with both gears reduced to their
 * modes up to 60 kHz, with each residual rule (reduction.residual):
 *
 *   follows_full   the kinematic TE of the reduced runs stays within 3 %
 *                  of the full run's TE range at every step (midpoint
 *                  rule), within 0.3 % over the last ms (static rule,
 *                  whose first impact at 1.25 ms rebounds less; the
 *                  study's window figures agree to 0.3 % at 60 kHz), the
 *                  energy balance holds to 1e-12 of the energy scale and
 *                  the deepest penetration stays below 0.01 um.
 *                  The reduced bodies' snapshots (save, load, save) restore
 *                  the state and energies, and with the midpoint rule (the
 *                  full scheme's own treatment of the high modes, so the
 *                  same instantaneous high-frequency content) their
 *                  displacement fields at 4 ms are the full bodies' within
 *                  1 % (the static rule, without that ringing: 2.6 %);
 *   block_cache    the compliance blocks the step asks for, bit for bit
 *                  the same whether the body copies them from the last
 *                  block (whole when the rows, h and brake are the same;
 *                  the shared rows otherwise) or computes them afresh with
 *                  its residual columns computed in another order of
 *                  groups (the columns' solve reuses its arrays): over a
 *                  sequence of row sets that repeat, shift, shrink and
 *                  change h and the brake, on a damped free annulus with
 *                  mass-proportional damping (the rank-one modal term);
 *   scene_errors   bodies[i].reduction on a rigid gear and with an
 *                  unknown residual rule are refused, naming the field
 *                  (mass-proportional damping is taken: test_fe_reduced,
 *                  test_reduced_resume).
 * About 15 CPU seconds (the full bodies' steps). */
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

#include "../common/dyn_window.h"
#include "../common/json_child.h"
#include "../common/reduced_scene.h"
#include "fe/fe_internal.h"
#include "gearsim/fe.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"

/* contact_drive at h 1e-5 with 2 % damping at 9.2 kHz; reduced to f_max
 * (0: full) on every elastic gear with the residual rule `rule` (NULL: the
 * default); extra: a material field set on gear 0. */
static gs_err make_system_rule(double fmax, const char *rule, const char *extra, double extra_v, gs_system **out,
                               gs_diag *d)
{
    json_object *root = reduced_drive_scene(fmax, rule, extra, extra_v);
    assert_non_null(root);
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; fmax < 0 && i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i);
        if (i == 0) /* reduction on a rigid gear */
            json_object_object_add(b, "model", json_object_new_string("rigid"));
        json_object_object_add(tj_child(b, "reduction"), "f_max_hz", json_object_new_double(6e4));
    }
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc = NULL;
    gs_err e = gs_scene_parse(txt, strlen(txt), &sc, d);
    json_object_put(root);
    if (e != GS_OK)
        return e;
    return gs_system_new(sc, 0, 1, out, d);
}

static gs_err make_system(double fmax, const char *extra, double extra_v, gs_system **out, gs_diag *d)
{
    return make_system_rule(fmax, NULL, extra, extra_v, out, d);
}

static void follows_full(void **state)
{
    (void)state;
    const int steps = 400;
    static const char *const rules[3] = {NULL, "midpoint", "static"};
    double *te[3], *ufull[2] = {NULL, NULL};
    dyn_window w[3];
    for (int run = 0; run < 3; run++) {
        gs_system *s = NULL;
        gs_diag d;
        gs_err e = make_system_rule(run ? 6e4 : 0, rules[run], NULL, 0, &s, &d);
        if (e != GS_OK)
            print_error("%s: %s\n", d.field, d.message);
        assert_int_equal(e, GS_OK);
        te[run] = calloc((size_t)steps, sizeof(double));
        memset(&w[run], 0, sizeof w[run]);
        for (int k = 0; k < steps; k++) {
            e = gs_step_serial(s);
            if (e != GS_OK)
                print_error("t %.6f: %s: %s\n", s->time, s->diag.field, s->diag.message);
            assert_int_equal(e, GS_OK);
            dw_energy(&w[run], s);
            assert_int_equal(dw_sample(&w[run], s, 0, -1, -1), 0);
            te[run][k] = w[run].s[w[run].n - 1].te;
        }
        for (int i = 0; run == 0 && i < s->n_bodies && i < 2; i++) { /* the full bodies' fields */
            gs_body_rt *b = &s->bodies[i];
            gs_index nn = b->ops->field_nodes(b);
            ufull[i] = calloc((size_t)(2 * nn), sizeof(double));
            double *vm = calloc((size_t)nn, sizeof *vm);
            b->ops->fields(b, ufull[i], vm);
            free(vm);
        }
        for (int i = 0; run >= 1 && i < s->n_bodies; i++) {
            /* the backend's snapshot: save, load, save gives the same state and
             * energies; the fields (one solve) are finite and not zero */
            gs_body_rt *b = &s->bodies[i];
            size_t ns = b->ops->state_size(b);
            double *x = calloc(ns, sizeof *x), *y = calloc(ns, sizeof *y);
            double T0, V0, T1, V1;
            gs_model_view v;
            gs_system_view(s, &v);
            b->ops->energy(&v, b, &T0, &V0);
            b->ops->save(b, x);
            assert_int_equal(b->ops->load(b, x), GS_OK);
            b->ops->save(b, y);
            b->ops->energy(&v, b, &T1, &V1);
            assert_memory_equal(x, y, ns * sizeof *x);
            assert_true(fabs(T1 - T0) <= 1e-12 * T0 && fabs(V1 - V0) <= 1e-12 * V0);
            gs_index nn = b->ops->field_nodes(b);
            double *u = calloc((size_t)(2 * nn), sizeof *u), *vm = calloc((size_t)nn, sizeof *vm);
            b->ops->fields(b, u, vm);
            double um = 0, vmm = 0, du = 0;
            for (gs_index j = 0; j < nn; j++) {
                assert_true(isfinite(u[2 * j]) && isfinite(u[2 * j + 1]) && isfinite(vm[j]));
                um = fmax(um, hypot(u[2 * j], u[2 * j + 1]));
                vmm = fmax(vmm, vm[j]);
                if (i < 2)
                    du = fmax(du, hypot(u[2 * j] - ufull[i][2 * j], u[2 * j + 1] - ufull[i][2 * j + 1]));
            }
            print_message("%s rule, body %d: snapshot of %zu values restored; fields: largest |u| %.3f um "
                          "(reduced - full at most %.2f %% of it), von Mises %.1f MPa\n",
                          rules[run], i, ns, um * 1e6, 100 * du / um, vmm * 1e-6);
            assert_true(um > 0 && vmm > 0);
            if (run == 1)
                assert_true(du <= 0.01 * um);
            free(x), free(y), free(u), free(vm);
        }
        gs_system_free(&s);
    }
    for (int run = 1; run < 3; run++) {
        double dmax = 0, lo = INFINITY, hi = -INFINITY, pen = 0;
        for (int k = 0; k < steps; k++) {
            if (run == 1 || k >= steps * 3 / 4)
                dmax = fmax(dmax, fabs(te[run][k] - te[0][k]));
            lo = fmin(lo, te[0][k]);
            hi = fmax(hi, te[0][k]);
            pen = fmax(pen, w[run].s[k].pen);
        }
        print_message("%s rule: TE over 4 ms: %.4f to %.4f um (full), reduced - full at most %.4f um (%.2f %% of "
                      "the range) %s; balance %.2e (reduced), %.2e (full); deepest penetration %.5f um\n",
                      rules[run], lo * 1e6, hi * 1e6, dmax * 1e6, 100 * dmax / (hi - lo),
                      run == 1 ? "at every step" : "over the last ms", w[run].worst / w[run].scale,
                      w[0].worst / w[0].scale, pen * 1e6);
        assert_true(hi - lo > 1e-6); /* the teeth are loaded and vibrate */
        /* midpoint: at every step. static: the backlash closes at 1.25 ms
         * and the first impact rebounds less (the massless residual takes
         * the impact's high-mode energy as a booked loss where the full
         * body rings: 1.8 um apart just after it); the last ms agrees. */
        assert_true(dmax <= (run == 1 ? 0.03 : 0.003) * (hi - lo));
        assert_true(w[run].worst <= 1e-12 * w[run].scale);
        assert_true(pen <= 1e-8);
    }
    for (int run = 0; run < 3; run++) {
        free(te[run]);
        if (run < 2)
            free(ufull[run]);
        dw_free(&w[run]);
    }
}

/* Compliance of body b over the dofs of nodes [n0, n1) and theta, selected
 * all but every fifth dof (k of them) into C. */
static int block_of(gs_fe_reduced *b, gs_index n0, gs_index n1, double *C)
{
    gs_index dofs[256];
    int sel[256], n = 0, k = 0;
    dofs[n++] = GS_FE_DOF_THETA;
    for (gs_index v = n0; v < n1; v++)
        dofs[n++] = 2 * v, dofs[n++] = 2 * v + 1;
    for (int j = 0; j < n; j++)
        if (j % 5 != 4)
            sel[k++] = j;
    assert_int_equal(gs_fe_reduced_compliance_sub(b, n, dofs, k, sel, C), GS_OK);
    return k;
}

static void block_cache(void **state)
{
    (void)state;
    gs_mesh *mesh = NULL;
    gs_fe_model *model = NULL;
    assert_int_equal(gsi_fe_mesh_annulus(0.02, 0.04, 3, 24, &mesh), GS_OK);
    gs_material mat = gs_material_steel();
    mat.damping_s = 3e-7;
    mat.damping_m = 3000.0;
    assert_int_equal(gs_fe_model_new(mesh, &mat, 0.01, 1e-4, &model), GS_OK);
    gs_index nn = mesh->n_nodes;
    gs_fe_reduced_opts o = {60e3, false, 0, NULL, 0, true};
    gs_fe_reduced *a = NULL, *b = NULL;
    assert_int_equal(gs_fe_reduced_new(model, &o, &a), GS_OK);
    assert_int_equal(gs_fe_reduced_new(model, &o, &b), GS_OK);
    /* the reference body computes its columns from the top node down */
    double *Ca = malloc(256 * 256 * sizeof *Ca), *Cb = malloc(256 * 256 * sizeof *Cb);
    assert_int_equal(gs_fe_reduced_set_step(b, 1e-5, 0.0), GS_OK);
    for (gs_index v = nn; v >= 5; v -= 5)
        block_of(b, v - 5, v, Cb);
    /* row sets [n0, n1), with h and brake: repeat, shift, shrink, new h, brake */
    const struct {
        gs_index n0, n1;
        double h, c;
    } seq[] = {{10, 30, 1e-5, 0.0}, {10, 30, 1e-5, 0.0}, {12, 33, 1e-5, 0.0}, {12, 33, 1e-5, 0.0},
               {14, 31, 1e-5, 0.0}, {14, 31, 2e-5, 0.0}, {14, 31, 2e-5, 0.0}, {14, 31, 2e-5, 0.05},
               {16, 40, 2e-5, 0.05}, {0, 3, 2e-5, 0.05},  {0, 3, 1e-5, 0.0}};
    int nseq = (int)(sizeof seq / sizeof seq[0]), differ = 0;
    for (int q = 0; q < nseq; q++) {
        assert_true(seq[q].n1 <= nn && seq[q].n1 - seq[q].n0 < 100);
        assert_int_equal(gs_fe_reduced_set_step(a, seq[q].h, seq[q].c), GS_OK);
        int k = block_of(a, seq[q].n0, seq[q].n1, Ca);
        /* afresh: a block over other rows first, so none is copied */
        assert_int_equal(gs_fe_reduced_set_step(b, seq[q].h, seq[q].c), GS_OK);
        block_of(b, seq[q].n0 >= 50 ? 0 : 50, seq[q].n0 >= 50 ? 10 : 60, Cb);
        assert_int_equal(block_of(b, seq[q].n0, seq[q].n1, Cb), k);
        bool same = memcmp(Ca, Cb, (size_t)k * (size_t)k * sizeof *Ca) == 0;
        differ += !same;
        if (!same)
            print_message("# block %d (nodes %lld..%lld, h %g, brake %g) differs\n", q, (long long)seq[q].n0,
                          (long long)seq[q].n1, seq[q].h, seq[q].c);
        /* a real compliance: symmetric, positive diagonal */
        for (int i = 0; i < k; i++) {
            assert_true(Ca[i + (size_t)i * k] >= 0.0);
            for (int j = 0; j < i; j++)
                assert_true(Ca[i + (size_t)j * k] == Ca[j + (size_t)i * k]);
        }
    }
    assert_int_equal(differ, 0);
    free(Ca), free(Cb);
    gs_fe_reduced_free(&a);
    gs_fe_reduced_free(&b);
    gs_fe_model_free(&model);
    gs_mesh_free(&mesh);
}

static void scene_errors(void **state)
{
    (void)state;
    gs_system *s = NULL;
    gs_diag d;
    assert_int_equal(make_system(-1, NULL, 0, &s, &d), GS_ERANGE);
    assert_string_equal(d.field, "bodies[0].reduction");
    assert_int_equal(make_system_rule(6e4, "implicit", NULL, 0, &s, &d), GS_ERANGE);
    assert_string_equal(d.field, "bodies[0].reduction.residual");
    assert_non_null(strstr(d.message, "static"));
    assert_null(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(scene_errors),
        cmocka_unit_test(block_cache),
        cmocka_unit_test(follows_full),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
