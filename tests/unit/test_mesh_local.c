/* SPDX-License-Identifier: MIT
 * Local refinement of gear meshes (gs_gear_mesh_opts.fine_teeth,
 * fine_refine; docs/explanation/geometry.md "Local refinement"): conforming meshes,
 * boundary nodes on the exact involute, the fine teeth where asked and at
 * the density of the uniform mesh of their level, element quality, the
 * area against the exact outline, the `fine` setting's size, and the bad
 * inputs (mesher options, scene fields, a dynamic model). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/fe.h"
#include "gearsim/geometry.h"
#include "gearsim/mesh.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"
#include "../common/gears.h"

static gs_mesh *mesh_opts(const gs_gear_params *p, const gs_gear_mesh_opts *o)
{
    gs_mesh *m = NULL;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = gs_gear_mesh(p, o, &m, &d);
    if (e != GS_OK)
        print_error("gs_gear_mesh: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return m;
}

/* Level of the flanks of tooth t: fine_refine on the fine_teeth teeth
 * centred on fine_centre (their bodies one less), beyond them the sectors'
 * level, fine_refine - 1 - distance, down to 0. */
static int level_of(int t, int z, int n, int R, int centre)
{
    int c0 = ((centre - (n - 1) / 2) % z + z) % z;
    int off = ((t - c0) % z + z) % z;
    int dist = off < n ? 0 : (off - (n - 1) < z - off ? off - (n - 1) : z - off);
    if (dist == 0)
        return R;
    return R - 1 - dist > 0 ? R - 1 - dist : 0;
}

static gs_index edges_of(const gs_mesh *m, gs_index *n_boundary_edges)
{
    int loops = 0;
    assert_int_equal(gs_mesh_check_topology(m, n_boundary_edges, &loops), GS_OK);
    assert_int_equal(loops, 2);
    return 0;
}

/* Conforming (every edge in one or two elements, the edges in one element
 * being exactly those of the two boundary loops, so every interior edge is
 * shared by exactly two), no inverted or flat element, quality bounds, every
 * flank node (mid-side nodes included) on the exact involute to 1e-12 m,
 * and each tooth's flank carrying the nodes of the uniform mesh at its
 * level: the fine teeth are where asked. External and internal gears,
 * linear and quadratic elements. */
static void local_conforming(void **state)
{
    (void)state;
    for (int kind = 0; kind < 2; kind++)
        for (int order = 1; order <= 2; order++) {
            const int z = kind ? 60 : 20, n = 3, R = 2, centre = kind ? 59 : 5;
            gs_gear_params p = gear(kind, z, 0.0025, 0);
            gs_gear_geom g;
            assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
            gs_gear_mesh_opts o;
            gs_gear_mesh_opts_for_order(&o, order);
            o.fine_teeth = n;
            o.fine_refine = R;
            o.fine_centre = centre;
            gs_mesh *m = mesh_opts(&p, &o);
            assert_int_equal(gs_mesh_order(m), order);
            gs_index nbe = 0;
            edges_of(m, &nbe);
            /* boundary edges: the toothed loop and the core circle (order 2:
             * the loops list mid-side nodes too, two per edge) */
            assert_int_equal(nbe * order, m->n_boundary + m->n_fixed);
            gs_mesh_quality q;
            gs_mesh_quality_eval(m, &q);
            assert_int_equal(q.n_bad, 0);
            assert_true(q.min_area > 0);
            print_message("# %s z=%d order %d, %d teeth %d levels finer on tooth %d: %lld nodes, "
                          "%lld elements, min angle %.1f deg, max aspect %.2f\n",
                          kind ? "internal" : "external", z, order, n, R, centre,
                          (long long)m->n_nodes, (long long)m->n_tris, q.min_angle_deg,
                          q.max_aspect);
            /* measured 13.9-17.0 deg, aspect 2.95-3.88 (the uniform default:
             * 17-21 deg, below 3); three levels finer (the fine setting) goes
             * down to ~9 deg, aspect ~9, in the 2:1 fans under the band
             * circle (docs/explanation/geometry.md "Local refinement") */
            assert_true(q.min_angle_deg > 12.0);
            assert_true(q.max_aspect < 5.0);
            /* flank nodes on the involute */
            double worst = 0;
            gs_index nfl = 0;
            for (int t = 0; t < z; t++)
                for (int s = 0; s < 2; s++)
                    for (gs_index k = m->flank_ptr[2 * t + s]; k < m->flank_ptr[2 * t + s + 1]; k++) {
                        gs_index v = m->flank_nodes[k];
                        double x = m->xy[2 * v], y = m->xy[2 * v + 1], Rr = hypot(x, y);
                        double a = atan2(y, x) - 2 * GS_PI * t / z;
                        a -= 2 * GS_PI * floor(a / (2 * GS_PI) + 0.5);
                        worst = fmax(worst, fabs(fabs(a) - gs_gear_involute_psi(&g, Rr)) * Rr);
                        assert_int_equal(m->node_tag[v], GS_NODE_FLANK);
                        nfl++;
                    }
            print_message("#   %lld flank nodes, at most %.2e m off the involute\n", (long long)nfl,
                          worst);
            assert_true(worst < 1e-12); /* 1e-9 mm */
            /* each tooth at the flank density of the uniform mesh of its level */
            gs_index per_level[5] = {0};
            for (int lv = 0; lv <= R; lv++) {
                gs_gear_mesh_opts u;
                gs_gear_mesh_opts_for_order(&u, order);
                u.refine = lv;
                gs_mesh *um = mesh_opts(&p, &u);
                per_level[lv] = um->flank_ptr[1] - um->flank_ptr[0];
                gs_mesh_free(&um);
            }
            int n_fine = 0;
            for (int t = 0; t < z; t++) {
                int lv = level_of(t, z, n, R, centre);
                n_fine += lv == R;
                for (int s = 0; s < 2; s++)
                    assert_int_equal(m->flank_ptr[2 * t + s + 1] - m->flank_ptr[2 * t + s],
                                     per_level[lv]);
            }
            assert_int_equal(n_fine, n);
            /* the centre tooth is fine, the tooth opposite is at the base */
            assert_int_equal(m->flank_ptr[2 * centre + 1] - m->flank_ptr[2 * centre], per_level[R]);
            int opp = (centre + z / 2) % z;
            assert_int_equal(m->flank_ptr[2 * opp + 1] - m->flank_ptr[2 * opp], per_level[0]);
            gs_mesh_free(&m);
        }
}

/* The area of the quadratic local mesh against the exact outline: a gap or
 * an overlap at a transition would show at the size of an element (1e-3
 * relative); the curved elements put it at the base mesh's 1e-6. */
static void local_area(void **state)
{
    (void)state;
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 20, 2.5e-3, 0.0);
    p.face_width_m = 0.01;
    gs_gear_geom g;
    assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
    double Aout, Jout;
    gs_gear_outline_moments(&g, &Aout, &Jout);
    double Aex = Aout - GS_PI * g.hub * g.hub;
    double err[2];
    for (int loc = 0; loc < 2; loc++) {
        gs_gear_mesh_opts o;
        gs_gear_mesh_opts_defaults(&o);
        if (loc) {
            o.fine_teeth = 3;
            o.fine_refine = 2;
        }
        gs_mesh *mesh = mesh_opts(&p, &o);
        gs_material mat = gs_material_steel();
        gs_fe_model *m = NULL;
        assert_int_equal(gs_fe_model_new(mesh, &mat, p.face_width_m, 0.0, &m), GS_OK);
        gs_fe_model_info info;
        gs_fe_model_get_info(m, &info);
        err[loc] = fabs(info.area_m2 - Aex) / Aex;
        print_message("# z20 order 2 %s: area error %.3e\n", loc ? "3 teeth 2 levels finer" : "uniform",
                      err[loc]);
        gs_fe_model_free(&m);
        gs_mesh_free(&mesh);
    }
    assert_true(err[1] < 1e-5);
    assert_true(err[1] <= err[0] * 1.0001);
}

/* The `fine` setting (gs_gear_mesh_opts_fine) on the 20/30 pair: its size
 * (the 144 832 unknowns of docs/validation/calculix.md), about the uniform refine 1
 * of the same counts, while its fine teeth have the flanks of refine 3 (2.4
 * million unknowns uniformly). */
static void fine_setting_size(void **state)
{
    (void)state;
    gs_gear_mesh_opts f;
    gs_gear_mesh_opts_fine(&f);
    assert_int_equal(f.order, 2);
    assert_true(f.fine_teeth > 0 && f.fine_refine > 0);
    gs_index total = 0, uniform1 = 0;
    for (int k = 0; k < 2; k++) {
        gs_gear_params p = gear(GS_GEAR_EXTERNAL, k ? 30 : 20, 2.5e-3, 0.0);
        gs_mesh *m = mesh_opts(&p, &f);
        gs_mesh_quality q;
        gs_mesh_quality_eval(m, &q);
        assert_int_equal(q.n_bad, 0);
        total += 2 * m->n_nodes;
        gs_gear_mesh_opts u = f;
        u.fine_teeth = 0;
        u.fine_refine = 0;
        u.refine = 1;
        gs_mesh *um = mesh_opts(&p, &u);
        uniform1 += 2 * um->n_nodes;
        /* the fine teeth have the flanks of the uniform mesh 3 levels finer */
        gs_index fine_flank = 0;
        for (int t = 0; t < p.teeth; t++) {
            gs_index c = m->flank_ptr[2 * t + 1] - m->flank_ptr[2 * t];
            fine_flank = c > fine_flank ? c : fine_flank;
        }
        assert_int_equal(fine_flank, 2 * (8 << f.fine_refine) + 1); /* corner + mid-side nodes */
        gs_mesh_free(&m);
        gs_mesh_free(&um);
    }
    print_message("# fine setting, 20/30 pair: %lld unknowns (uniform refine 1 of the same "
                  "counts: %lld)\n",
                  (long long)total, (long long)uniform1);
    assert_int_equal(total, 144832);
    assert_true(total < 1.1 * uniform1);
}

static void bad_local_options(void **state)
{
    (void)state;
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 20, 0.002, 0);
    struct {
        const char *field;
        int fine_teeth, fine_refine, refine;
    } c[] = {
        {"mesh.fine_teeth", -1, 2, 0},
        {"mesh.fine_refine", 3, 0, 0},
        {"mesh.fine_refine", 3, 5, 0},
        {"mesh.fine_refine", 0, 2, 0},
        {"mesh.fine_refine", 3, 3, 6},
        {"mesh.fine_refine", 20, 4, 4}, /* too big: refused before allocating */
    };
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        gs_gear_mesh_opts o;
        gs_gear_mesh_opts_defaults(&o);
        o.fine_teeth = c[i].fine_teeth;
        o.fine_refine = c[i].fine_refine;
        o.refine = c[i].refine;
        gs_mesh *m = (gs_mesh *)0x1;
        gs_diag d;
        gs_diag_clear(&d);
        assert_int_not_equal(gs_gear_mesh(&p, &o, &m, &d), GS_OK);
        assert_null(m);
        assert_string_equal(d.field, c[i].field);
    }
}

static const char *scene_fmt =
    "{\"bodies\": [{\"name\": \"a\", \"type\": \"gear\", \"teeth\": 20, \"module_mm\": 2.5,"
    " \"model\": \"elastic\", \"mesh\": %s},"
    " {\"name\": \"b\", \"type\": \"gear\", \"teeth\": 30, \"module_mm\": 2.5}],"
    " \"joints\": [{\"body\": \"a\", \"type\": \"fixed_axis\", \"centre_mm\": [0, 0]},"
    " {\"body\": \"b\", \"type\": \"fixed_axis\", \"centre_mm\": [62.5, 0]}],"
    " \"meshes\": [{\"name\": \"ab\", \"gears\": [\"a\", \"b\"], \"model\": \"contact\"}]}";

/* Scene fields: bad values named; a dynamic model refuses local refinement
 * (every tooth comes round) naming the field. */
static void scene_fields(void **state)
{
    (void)state;
    struct {
        const char *mesh, *field;
    } bad[] = {
        {"{\"fine_teeth\": 21}", "bodies[0].mesh.fine_teeth"},
        {"{\"fine_teeth\": -1}", "bodies[0].mesh.fine_teeth"},
        {"{\"fine_teeth\": 3, \"fine_refine\": 0}", "bodies[0].mesh.fine_refine"},
        {"{\"fine_teeth\": 3, \"fine_refine\": 5}", "bodies[0].mesh.fine_refine"},
        {"{\"fine_refine\": 2}", "bodies[0].mesh.fine_refine"},
        {"{\"fine_teeth\": \"three\"}", "bodies[0].mesh.fine_teeth"},
    };
    char buf[2048];
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(buf, sizeof buf, scene_fmt, bad[i].mesh);
        gs_scene *sc = NULL;
        gs_diag d;
        gs_diag_clear(&d);
        assert_int_not_equal(gs_scene_parse(buf, strlen(buf), &sc, &d), GS_OK);
        assert_null(sc);
        print_message("# %s: %s: %s\n", bad[i].mesh, d.field, d.message);
        assert_string_equal(d.field, bad[i].field);
    }
    /* accepted by the scene (the quasi-static analysis uses it) ... */
    snprintf(buf, sizeof buf, scene_fmt, "{\"fine_teeth\": 3}");
    gs_scene *sc = NULL;
    gs_diag d;
    gs_diag_clear(&d);
    assert_int_equal(gs_scene_parse(buf, strlen(buf), &sc, &d), GS_OK);
    assert_int_equal(sc->bodies[0].mesh.fine_teeth, 3);
    assert_int_equal(sc->bodies[0].mesh.fine_refine, 2); /* the default with fine_teeth */
    /* ... refused by the dynamic model, naming the field */
    gs_system *sys = NULL;
    gs_diag_clear(&d);
    assert_int_not_equal(gs_system_new(sc, 0, 1, &sys, &d), GS_OK);
    assert_null(sys);
    print_message("# dynamic model: %s: %s\n", d.field, d.message);
    assert_string_equal(d.field, "bodies[0].mesh.fine_teeth");
    assert_non_null(strstr(d.message, "quasi-static"));
    /* gs_system_new owns (and has freed) the scene */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(local_conforming),
        cmocka_unit_test(local_area),
        cmocka_unit_test(fine_setting_size),
        cmocka_unit_test(bad_local_options),
        cmocka_unit_test(scene_fields),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
