/* SPDX-License-Identifier: MIT
 * Gear meshes (docs/explanation/geometry.md): conforming linear triangles, nodes exactly
 * on the involute and on the fillet, flank tables in order, area converging
 * at second order under refinement, quality, HDF5 + XDMF round trip. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gearsim/geometry.h"
#include "gearsim/mesh.h"
#include "gearsim/mesh_io.h"
#include "gearsim/util.h"
#include "../common/gears.h"

#define DEG (GS_PI / 180.0)

/* Node angle relative to the centre of tooth t, in (-pi, pi]. */
static double rel_angle(const gs_mesh *m, gs_index v, int t, int z)
{
    double a = atan2(m->xy[2 * v + 1], m->xy[2 * v]) - 2 * GS_PI * t / z;
    return a - 2 * GS_PI * floor(a / (2 * GS_PI) + 0.5);
}

/* A conforming mesh of an annulus-like region: every edge in one or two
 * triangles, two boundary loops (teeth and core), all triangles
 * counter-clockwise. */
static void conforming(void **state)
{
    (void)state;
    for (int kind = 0; kind < 2; kind++) {
        gs_gear_params p = gear(kind, kind ? 72 : 20, 0.002, 0);
        gs_mesh *m = mesh_of(&p, 0);
        gs_index nbe;
        int loops;
        assert_int_equal(gs_mesh_check_topology(m, &nbe, &loops), GS_OK);
        assert_int_equal(loops, 2);
        assert_int_equal(nbe, m->n_boundary + m->n_fixed);
        gs_mesh_quality q;
        gs_mesh_quality_eval(m, &q);
        assert_int_equal(q.n_bad, 0);
        assert_true(q.min_area > 0);
        /* Standard gears at the default density: the layout keeps angles
         * above 15 degrees (measured 17-21) and aspect ratios below 3. */
        print_message("# %s z=%d: %lld nodes, %lld triangles, min angle %.2f deg, max angle %.2f deg, "
                      "aspect max %.2f mean %.3f\n",
                      kind ? "internal" : "external", p.teeth, (long long)m->n_nodes,
                      (long long)m->n_tris, q.min_angle_deg, q.max_angle_deg, q.max_aspect,
                      q.mean_aspect);
        assert_true(q.min_angle_deg > 15.0);
        assert_true(q.max_aspect < 3.0);
        assert_int_equal(m->n_teeth, p.teeth);
        /* core nodes: on the hub circle, fixed, tagged */
        double hub = gs_gear_hub_radius(&p);
        for (gs_index i = 0; i < m->n_fixed; i++) {
            gs_index v = m->fixed[i];
            assert_true(fabs(hypot(m->xy[2 * v], m->xy[2 * v + 1]) - hub) < 1e-13 * hub);
            assert_int_equal(m->node_tag[v], GS_NODE_CORE);
        }
        gs_mesh_free(&m);
        assert_null(m);
    }
}

/* Every flank node lies on the involute (polar equation, 1e-12 relative:
 * the nodes are computed from it and rotated to their tooth, ~1e-16); the
 * tables run from the form point to the tip corner; s = 0 is the clockwise
 * flank of an external gear and the counter-clockwise one of a ring. */
static void flank_tables(void **state)
{
    (void)state;
    for (int kind = 0; kind < 2; kind++)
        for (int refine = 0; refine < 2; refine++) {
            gs_gear_params p = gear(kind, kind ? 60 : 17, 0.003, kind ? 0.2 : 0.3);
            gs_gear_geom g;
            assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
            gs_mesh *m = mesh_of(&p, refine);
            const int z = p.teeth;
            double worst = 0;
            gs_index count = 0;
            for (int t = 0; t < z; t++)
                for (int s = 0; s < 2; s++) {
                    gs_index a = m->flank_ptr[2 * t + s], b = m->flank_ptr[2 * t + s + 1];
                    assert_true(b - a >= 2);
                    double prevR = -1;
                    for (gs_index k = a; k < b; k++) {
                        gs_index v = m->flank_nodes[k];
                        double R = hypot(m->xy[2 * v], m->xy[2 * v + 1]);
                        double rel = rel_angle(m, v, t, z);
                        double psi = gs_gear_involute_psi(&g, R);
                        /* side: external s=0 clockwise (rel < 0); ring s=0 counter-clockwise */
                        double sign = (kind == 0) == (s == 0) ? -1.0 : 1.0;
                        worst = fmax(worst, fabs(sign * rel - psi) / psi);
                        assert_int_equal(m->node_tag[v], GS_NODE_FLANK);
                        if (prevR >= 0) /* root to tip */
                            assert_true(kind ? R < prevR : R > prevR);
                        prevR = R;
                        count++;
                    }
                    gs_index v0 = m->flank_nodes[a], v1 = m->flank_nodes[b - 1];
                    assert_true(fabs(hypot(m->xy[2 * v0], m->xy[2 * v0 + 1]) - g.r_form) < 1e-13 * g.r);
                    assert_true(fabs(hypot(m->xy[2 * v1], m->xy[2 * v1 + 1]) - g.ra) < 1e-13 * g.r);
                }
            print_message("# %s z=%d refine %d: %lld flank nodes, worst involute polar error %.2e "
                          "(relative)\n",
                          kind ? "internal" : "external", z, refine, (long long)count, worst);
            assert_true(worst < 1e-12);
            gs_mesh_free(&m);
        }
}

/* Distance from P to the fillet curve: Newton-free bisection on the
 * projection condition (P - G(t)) . T(t) = 0, which pins t to ~1e-16 so the
 * distance is resolved to round-off (a distance minimisation would only get
 * sqrt(eps)). */
static double dist_to_fillet(const gs_gear_geom *g, double px, double py)
{
    double best = INFINITY, tb = 0;
    for (int i = 0; i <= 400; i++) {
        double P[2], T[2];
        gs_gear_fillet_point(g, i / 400.0, P, T);
        double dd = hypot(px - P[0], py - P[1]);
        if (dd < best) {
            best = dd;
            tb = i / 400.0;
        }
    }
    double lo = fmax(0.0, tb - 1.0 / 400), hi = fmin(1.0, tb + 1.0 / 400);
    double P[2], T[2];
    gs_gear_fillet_point(g, lo, P, T);
    double flo = (px - P[0]) * T[0] + (py - P[1]) * T[1];
    for (int it = 0; it < 200; it++) {
        double mid = 0.5 * (lo + hi);
        gs_gear_fillet_point(g, mid, P, T);
        double f = (px - P[0]) * T[0] + (py - P[1]) * T[1];
        if ((f > 0) == (flo > 0)) {
            lo = mid;
            flo = f;
        } else
            hi = mid;
    }
    gs_gear_fillet_point(g, 0.5 * (lo + hi), P, T);
    return fmin(best, hypot(px - P[0], py - P[1]));
}

/* Fillet nodes on the fillet, root nodes on the root circle, tip nodes on
 * the tip circle (1e-12 module: the curves are evaluated at the nodes). */
static void boundary_on_curves(void **state)
{
    (void)state;
    for (int kind = 0; kind < 2; kind++) {
        gs_gear_params p = gear(kind, kind ? 72 : 12, 0.002, 0); /* z = 12: undercut trochoid */
        gs_gear_geom g;
        assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
        gs_mesh *m = mesh_of(&p, 1);
        double wf = 0, wr = 0, wt = 0;
        int nf = 0;
        for (gs_index k = 0; k < m->n_boundary; k++) {
            gs_index v = m->boundary[k];
            double R = hypot(m->xy[2 * v], m->xy[2 * v + 1]);
            double a = atan2(m->xy[2 * v + 1], m->xy[2 * v]);
            int t = (int)lround(a * p.teeth / (2 * GS_PI));
            double rel = fabs(a - 2 * GS_PI * t / p.teeth);
            rel -= 2 * GS_PI * floor(rel / (2 * GS_PI) + 0.5);
            rel = fabs(rel);
            switch (m->node_tag[v]) {
            case GS_NODE_FILLET:
                wf = fmax(wf, dist_to_fillet(&g, R * cos(rel), R * sin(rel)));
                nf++;
                break;
            case GS_NODE_ROOT:
                wr = fmax(wr, fabs(R - g.rf));
                break;
            case GS_NODE_TIP:
                wt = fmax(wt, fabs(R - g.ra));
                break;
            case GS_NODE_FLANK:
                break;
            default:
                fail_msg("boundary node %lld has tag %d", (long long)v, m->node_tag[v]);
            }
        }
        print_message("# %s z=%d: %d fillet nodes at most %.2e module off the fillet; root nodes %.2e, "
                      "tip nodes %.2e module off their circles\n",
                      kind ? "internal" : "external", p.teeth, nf, wf / g.m, wr / g.m, wt / g.m);
        assert_true(nf > 0);
        assert_true(wf < 1e-12 * g.m);
        assert_true(wr < 1e-12 * g.m);
        assert_true(wt < 1e-12 * g.m);
        gs_mesh_free(&m);
    }
}

/* The meshed area converges to the area inside the exact boundary at
 * second order (chords of curves: error ~ curvature h^3 per segment). */
static void area_converges(void **state)
{
    (void)state;
    for (int kind = 0; kind < 2; kind++) {
        gs_gear_params p = gear(kind, kind ? 72 : 20, 0.002, kind ? 0 : 0.25);
        gs_gear_geom g;
        assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
        double A, J;
        gs_gear_outline_moments(&g, &A, &J);
        double exact = kind ? GS_PI * g.hub * g.hub - A : A - GS_PI * g.hub * g.hub;
        print_message("# area convergence, %s z=%d x=%.2f: exact %.15e m^2\n", kind ? "internal" : "external",
                      p.teeth, p.profile_shift, exact);
        print_message("# %6s %9s %22s %12s %7s\n", "refine", "triangles", "mesh area (m^2)", "rel. error",
                      "order");
        double prev = 0;
        enum { NR = 4 };
        double orders[NR] = {0};
        for (int r = 0; r < NR; r++) {
            gs_mesh *m = mesh_of(&p, r);
            gs_mesh_quality q;
            gs_mesh_quality_eval(m, &q);
            double err = fabs(q.area - exact) / exact;
            char ord[16] = "-";
            if (r > 0) {
                orders[r] = log2(prev / err);
                snprintf(ord, sizeof ord, "%.3f", orders[r]);
            }
            print_message("# %6d %9lld %22.15e %12.4e %7s\n", r, (long long)m->n_tris, q.area, err, ord);
            assert_int_equal(q.n_bad, 0);
            prev = err;
            gs_mesh_free(&m);
        }
        /* second order: the observed orders approach 2 (within 0.15) */
        for (int r = 2; r < NR; r++)
            assert_true(fabs(orders[r] - 2.0) < 0.15);
    }
}

/* Refinement keeps the coarser mesh's boundary nodes (nested): every flank
 * node of refine 0 is a flank node of refine 1, at the same place. */
static void refinement_nested(void **state)
{
    (void)state;
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 20, 0.002, 0);
    gs_mesh *a = mesh_of(&p, 0), *b = mesh_of(&p, 1);
    for (int t = 0; t < p.teeth; t++)
        for (int s = 0; s < 2; s++) {
            gs_index a0 = a->flank_ptr[2 * t + s], a1 = a->flank_ptr[2 * t + s + 1];
            gs_index b0 = b->flank_ptr[2 * t + s], b1 = b->flank_ptr[2 * t + s + 1];
            assert_int_equal(2 * (a1 - a0 - 1), b1 - b0 - 1);
            for (gs_index k = a0; k < a1; k++) {
                gs_index va = a->flank_nodes[k], vb = b->flank_nodes[b0 + 2 * (k - a0)];
                assert_true(hypot(a->xy[2 * va] - b->xy[2 * vb], a->xy[2 * va + 1] - b->xy[2 * vb + 1]) <
                            1e-15 * 0.03);
            }
        }
    assert_int_equal(b->n_boundary, 2 * a->n_boundary);
    gs_mesh_free(&a);
    gs_mesh_free(&b);
}

static void bad_options(void **state)
{
    (void)state;
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 20, 0.002, 0);
    struct {
        const char *field;
        gs_gear_mesh_opts o;
    } c[6];
    for (int i = 0; i < 6; i++)
        gs_gear_mesh_opts_defaults(&c[i].o);
    c[0].field = "mesh.flank";
    c[0].o.flank = 0;
    c[1].field = "mesh.across";
    c[1].o.across = -2;
    c[2].field = "mesh.rim";
    c[2].o.rim = 0;
    c[3].field = "refine";
    c[3].o.refine = 9;
    c[4].field = "mesh.grading";
    c[4].o.grading = 0.5;
    c[5].field = "refine";
    c[5].o.refine = 8; /* ~ 60 million triangles: refused before allocating */
    for (int i = 0; i < 6; i++) {
        gs_mesh *m = (gs_mesh *)0x1;
        gs_diag d;
        gs_err e = gs_gear_mesh(&p, &c[i].o, &m, &d);
        assert_int_not_equal(e, GS_OK);
        assert_null(m);
        assert_string_equal(d.field, c[i].field);
    }
    /* gear errors come through with the gear's field */
    p.teeth = 2;
    gs_mesh *m = NULL;
    gs_diag d;
    assert_int_equal(gs_gear_mesh(&p, NULL, &m, &d), GS_ERANGE);
    assert_string_equal(d.field, "teeth");
}

/* Two gears placed in mesh (gs_pair_mesh_phase at the tight centre
 * distance): no boundary node of one lies inside the other's boundary
 * polygon by more than the chord sagitta (a few 1e-4 module at this density). */
static int inside_poly(const double *px, const double *py, gs_index n, double x, double y)
{
    int in = 0;
    for (gs_index i = 0, j = n - 1; i < n; j = i++)
        if ((py[i] > y) != (py[j] > y) &&
            x < px[i] + (y - py[i]) * (px[j] - px[i]) / (py[j] - py[i]))
            in = !in;
    return in;
}

static double seg_dist(const double *px, const double *py, gs_index n, double x, double y)
{
    double best = INFINITY;
    for (gs_index i = 0; i < n; i++) {
        gs_index j = (i + 1) % n;
        double ex = px[j] - px[i], ey = py[j] - py[i];
        double t = ((x - px[i]) * ex + (y - py[i]) * ey) / (ex * ex + ey * ey);
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        best = fmin(best, hypot(x - px[i] - t * ex, y - py[i] - t * ey));
    }
    return best;
}

static void placed_in_mesh(void **state)
{
    (void)state;
    const double m = 0.002;
    gs_gear_params p1 = gear(GS_GEAR_EXTERNAL, 20, m, 0), p2 = gear(GS_GEAR_EXTERNAL, 30, m, 0);
    double a;
    assert_int_equal(gs_pair_tight_centre_distance(&p1, &p2, &a, NULL), GS_OK);
    double c1[2] = {0, 0}, c2[2] = {a * cos(0.3), a * sin(0.3)};
    double t1 = 0.1, t2 = gs_pair_mesh_phase(&p1, c1, t1, &p2, c2, 0.0);
    gs_mesh *m1 = mesh_of(&p1, 1), *m2 = mesh_of(&p2, 1);
    gs_mesh *ms[2] = {m1, m2};
    double *X[2], *Y[2], cs[2][2] = {{c1[0], c1[1]}, {c2[0], c2[1]}}, th[2] = {t1, t2};
    for (int k = 0; k < 2; k++) {
        gs_index n = ms[k]->n_boundary;
        X[k] = malloc((size_t)n * sizeof(double));
        Y[k] = malloc((size_t)n * sizeof(double));
        for (gs_index i = 0; i < n; i++) {
            gs_index v = ms[k]->boundary[i];
            double x = ms[k]->xy[2 * v], y = ms[k]->xy[2 * v + 1];
            X[k][i] = cs[k][0] + cos(th[k]) * x - sin(th[k]) * y;
            Y[k][i] = cs[k][1] + sin(th[k]) * x + cos(th[k]) * y;
        }
    }
    double worst = 0, closest = INFINITY;
    for (int k = 0; k < 2; k++)
        for (gs_index i = 0; i < ms[k]->n_boundary; i++) {
            double x = X[k][i], y = Y[k][i];
            double dd = seg_dist(X[1 - k], Y[1 - k], ms[1 - k]->n_boundary, x, y);
            if (inside_poly(X[1 - k], Y[1 - k], ms[1 - k]->n_boundary, x, y))
                worst = fmax(worst, dd);
            else
                closest = fmin(closest, dd);
        }
    print_message("# 20/30 placed in mesh: deepest overlap %.2e module, closest gap %.2e module\n",
                  worst / m, closest / m);
    assert_true(worst < 1e-3 * m);
    assert_true(closest < 1e-2 * m); /* tight mesh: the flanks touch */
    for (int k = 0; k < 2; k++) {
        free(X[k]);
        free(Y[k]);
    }
    gs_mesh_free(&m1);
    gs_mesh_free(&m2);
}

static char *slurp(const char *path)
{
    size_t len;
    return gs_read_file(path, 1 << 24, &len);
}

/* HDF5 + XDMF: what is written reads back identically; the XDMF file
 * describes it for ParaView (XDMF 3, Triangle, XY, node attribute). */
static void hdf5_round_trip(void **state)
{
    (void)state;
    char dir[] = "/tmp/gs_test_mesh_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char h5[256], xmf[256];
    snprintf(h5, sizeof h5, "%s/gears.h5", dir);
    gs_gear_params p1 = gear(GS_GEAR_EXTERNAL, 20, 0.002, 0), p2 = gear(GS_GEAR_INTERNAL, 72, 0.002, 0);
    gs_mesh *m1 = mesh_of(&p1, 0), *m2 = mesh_of(&p2, 0);
    gs_mesh_io_gear e[2] = {{"pinion", m1, &p1, {0.01, -0.02}, 0.3},
                            {"ring", m2, &p2, {0.0, 0.0}, -1.25}};
    gs_diag d;
    assert_int_equal(gs_mesh_io_write(h5, NULL, e, 2, &d), GS_OK);
    assert_int_equal(gs_mesh_io_xmf_path(h5, xmf, sizeof xmf), GS_OK);
    assert_string_equal(xmf + strlen(xmf) - 9, "gears.xmf");
    for (int k = 0; k < 2; k++) {
        gs_mesh *r = NULL;
        double c[2], rot;
        assert_int_equal(gs_mesh_io_read(h5, e[k].name, &r, c, &rot, &d), GS_OK);
        const gs_mesh *o = e[k].mesh;
        assert_int_equal(r->n_nodes, o->n_nodes);
        assert_int_equal(r->n_tris, o->n_tris);
        assert_int_equal(r->n_fixed, o->n_fixed);
        assert_int_equal(r->n_teeth, o->n_teeth);
        assert_int_equal(r->n_boundary, o->n_boundary);
        assert_memory_equal(r->xy, o->xy, (size_t)(2 * o->n_nodes) * sizeof(double));
        assert_memory_equal(r->tri, o->tri, (size_t)(3 * o->n_tris) * sizeof(gs_index));
        assert_memory_equal(r->fixed, o->fixed, (size_t)o->n_fixed * sizeof(gs_index));
        assert_memory_equal(r->node_tag, o->node_tag, (size_t)o->n_nodes);
        assert_memory_equal(r->boundary, o->boundary, (size_t)o->n_boundary * sizeof(gs_index));
        assert_memory_equal(r->flank_ptr, o->flank_ptr, (size_t)(2 * o->n_teeth + 1) * sizeof(gs_index));
        assert_memory_equal(r->flank_nodes, o->flank_nodes,
                            (size_t)o->flank_ptr[2 * o->n_teeth] * sizeof(gs_index));
        assert_true(c[0] == e[k].centre[0] && c[1] == e[k].centre[1] && rot == e[k].rotation);
        gs_mesh_free(&r);
    }
    gs_mesh *r = NULL;
    assert_int_equal(gs_mesh_io_read(h5, "sun", &r, NULL, NULL, &d), GS_ENOTFOUND);
    assert_string_equal(d.field, "name");
    assert_int_equal(gs_mesh_io_read("/nonexistent/x.h5", "ring", &r, NULL, NULL, &d), GS_EIO);
    char *x = slurp(xmf);
    assert_non_null(x);
    const char *must[] = {"<Xdmf Version=\"3.0\">", "TopologyType=\"Triangle\"",
                          "GeometryType=\"XY\"", "Center=\"Node\"", "gears.h5:/gears/pinion/triangles",
                          "gears.h5:/gears/ring/nodes_placed", "CollectionType=\"Spatial\""};
    for (size_t i = 0; i < sizeof must / sizeof must[0]; i++) {
        if (!strstr(x, must[i]))
            print_error("XDMF lacks %s\n", must[i]);
        assert_non_null(strstr(x, must[i]));
    }
    char nt[64];
    snprintf(nt, sizeof nt, "NumberOfElements=\"%lld\"", (long long)m1->n_tris);
    assert_non_null(strstr(x, nt));
    free(x);
    /* bad names */
    gs_mesh_io_gear bad[2] = {{"a/b", m1, NULL, {0, 0}, 0}, {"a", m1, NULL, {0, 0}, 0}};
    assert_int_equal(gs_mesh_io_write(h5, NULL, bad, 1, &d), GS_EINVAL);
    assert_string_equal(d.field, "gears[0].name");
    bad[0].name = "a";
    assert_int_equal(gs_mesh_io_write(h5, NULL, bad, 2, &d), GS_EINVAL);
    assert_string_equal(d.field, "gears[1].name");
    assert_int_equal(gs_mesh_io_write("/nonexistent/dir/x.h5", NULL, e, 1, &d), GS_EIO);
    assert_string_equal(d.field, "path");
    unlink(h5);
    unlink(xmf);
    rmdir(dir);
    gs_mesh_free(&m1);
    gs_mesh_free(&m2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(conforming),
        cmocka_unit_test(flank_tables),
        cmocka_unit_test(boundary_on_curves),
        cmocka_unit_test(area_converges),
        cmocka_unit_test(refinement_nested),
        cmocka_unit_test(bad_options),
        cmocka_unit_test(placed_in_mesh),
        cmocka_unit_test(hdf5_round_trip),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
