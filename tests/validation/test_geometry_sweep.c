/* SPDX-License-Identifier: MIT
 * Gear meshes over a sweep of the design space (docs/explanation/geometry.md):
 * teeth 8..200, modules 0.5 / 2 / 20 mm, pressure angles 14.5 / 20 / 25
 * degrees, profile shifts -0.5..+0.8, external and internal. Every gear that
 * can exist meshes into a valid mesh (no inverted or degenerate element,
 * conforming, flank nodes on the involute); every one that cannot is
 * rejected with a geometry error naming a scene field. Prints the quality
 * summary (minimum angle, aspect ratio) and the rejections. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/geometry.h"
#include "gearsim/mesh.h"
#include "gearsim/util.h"

#define DEG (GS_PI / 180.0)

static const int TEETH[] = {8, 10, 12, 14, 17, 20, 25, 30, 40, 60, 80, 120, 160, 200};
static const double MODULES_MM[] = {0.5, 2.0, 20.0};
static const double ALPHAS[] = {14.5, 20.0, 25.0};
static const double SHIFTS[] = {-0.5, -0.25, 0.0, 0.25, 0.5, 0.8};
#define N_ARR(a) ((int)(sizeof a / sizeof a[0]))

/* Fields a gear that cannot exist may be rejected on, and why. */
static const char *const REJECT_FIELDS[] = {"teeth", "profile_shift", "addendum", "fillet"};

typedef struct {
    int meshed, rejected, undercut;
    int by_field[4];
    double worst_min_angle, worst_aspect, sum_min_angle;
    double *min_angles;
} summary;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Polar involute equation at every flank node (1e-12 relative). */
static double flank_error(const gs_mesh *m, const gs_gear_geom *g)
{
    double worst = 0;
    for (int t = 0; t < m->n_teeth; t++)
        for (int s = 0; s < 2; s++)
            for (gs_index k = m->flank_ptr[2 * t + s]; k < m->flank_ptr[2 * t + s + 1]; k++) {
                gs_index v = m->flank_nodes[k];
                double R = hypot(m->xy[2 * v], m->xy[2 * v + 1]);
                double a = atan2(m->xy[2 * v + 1], m->xy[2 * v]) - 2 * GS_PI * t / g->z;
                a = fabs(a - 2 * GS_PI * floor(a / (2 * GS_PI) + 0.5));
                double psi = gs_gear_involute_psi(g, R);
                worst = fmax(worst, fabs(a - psi) / psi);
            }
    return worst;
}

static void sweep(void **state)
{
    (void)state;
    double t0 = gs_now();
    summary S[2][3];
    memset(S, 0, sizeof S);
    const int per = N_ARR(TEETH) * N_ARR(SHIFTS) * N_ARR(MODULES_MM);
    for (int k = 0; k < 2; k++)
        for (int a = 0; a < 3; a++) {
            S[k][a].worst_min_angle = 180;
            S[k][a].min_angles = calloc((size_t)per, sizeof(double));
        }
    struct {
        double ang;
        char what[96];
    } worst5[5];
    for (int i = 0; i < 5; i++)
        worst5[i].ang = 180;
    long total_tris = 0;
    int scale_mismatch = 0, n_gears = 0;
    for (int kind = 0; kind < 2; kind++)
        for (int ia = 0; ia < N_ARR(ALPHAS); ia++)
            for (int iz = 0; iz < N_ARR(TEETH); iz++)
                for (int ix = 0; ix < N_ARR(SHIFTS); ix++) {
                    double ref_angle = -1;
                    gs_index ref_tris = -1;
                    for (int im = 0; im < N_ARR(MODULES_MM); im++) {
                        gs_gear_params p;
                        gs_gear_params_defaults(&p);
                        p.kind = (gs_gear_kind)kind;
                        p.teeth = TEETH[iz];
                        p.module_m = MODULES_MM[im] * 1e-3;
                        p.pressure_angle = ALPHAS[ia] * DEG;
                        p.profile_shift = SHIFTS[ix];
                        p.face_width_m = 10 * p.module_m;
                        /* the tip radius of a 25 degree rack: 0.38 m does not fit
                         * its tooth at dedendum 1.25 (at most 0.318) */
                        p.fillet_coef = ALPHAS[ia] > 24 ? 0.25 : 0.38;
                        summary *s = &S[kind][ia];
                        n_gears++;
                        gs_mesh *m = NULL;
                        gs_diag d;
                        gs_diag_clear(&d);
                        gs_err e = gs_gear_mesh(&p, NULL, &m, &d);
                        if (e != GS_OK) {
                            int f = -1;
                            for (int q = 0; q < 4; q++)
                                if (!strcmp(d.field, REJECT_FIELDS[q]))
                                    f = q;
                            /* a ring of fewer than 12 teeth is out of range
                             * before any geometry is tried */
                            int ok_code = e == GS_EGEOMETRY || (e == GS_ERANGE && f == 0);
                            if (f < 0 || !ok_code)
                                print_error("%s z=%d m=%g a=%g x=%g: %s on '%s': %s\n",
                                            kind ? "internal" : "external", p.teeth, MODULES_MM[im],
                                            ALPHAS[ia], SHIFTS[ix], gs_errcode(e), d.field, d.message);
                            assert_true(ok_code);
                            assert_true(f >= 0);
                            /* standard gears always exist: x = 0, 20 degrees,
                             * external, or internal beyond the base-circle limit */
                            assert_false(ix == 2 && ia == 1 && (kind == 0 || p.teeth >= 34));
                            s->rejected++;
                            s->by_field[f]++;
                            continue;
                        }
                        gs_gear_geom g;
                        assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
                        gs_mesh_quality q;
                        gs_mesh_quality_eval(m, &q);
                        int loops = 0;
                        assert_int_equal(gs_mesh_check_topology(m, NULL, &loops), GS_OK);
                        assert_int_equal(loops, 2);
                        assert_int_equal(q.n_bad, 0);
                        assert_true(q.min_area > 0);
                        assert_true(flank_error(m, &g) < 1e-12);
                        if (im == 0) {
                            s->undercut += g.undercut;
                            s->min_angles[s->meshed] = q.min_angle_deg;
                            s->meshed++;
                            s->sum_min_angle += q.min_angle_deg;
                            s->worst_min_angle = fmin(s->worst_min_angle, q.min_angle_deg);
                            s->worst_aspect = fmax(s->worst_aspect, q.max_aspect);
                            int w = 4;
                            if (q.min_angle_deg < worst5[w].ang) {
                                while (w > 0 && q.min_angle_deg < worst5[w - 1].ang) {
                                    worst5[w] = worst5[w - 1];
                                    w--;
                                }
                                worst5[w].ang = q.min_angle_deg;
                                snprintf(worst5[w].what, sizeof worst5[w].what,
                                         "%s z=%d alpha=%.1f x=%+.2f%s: aspect %.1f",
                                         kind ? "internal" : "external", p.teeth, ALPHAS[ia],
                                         SHIFTS[ix], g.undercut ? " (undercut)" : "", q.max_aspect);
                            }
                        }
                        /* the mesh is the same shape at every module (all sizes
                         * are relative to m): same count, same angles */
                        if (ref_angle < 0) {
                            ref_angle = q.min_angle_deg;
                            ref_tris = q.n_tris;
                        } else if (q.n_tris != ref_tris || fabs(q.min_angle_deg - ref_angle) > 1e-6) {
                            scale_mismatch++;
                            if (getenv("GS_SWEEP_VERBOSE"))
                                print_message("# scale: %s z=%d a=%g x=%g m=%g: tris %lld vs %lld, min angle %.9f vs %.9f\n",
                                              kind ? "int" : "ext", p.teeth, ALPHAS[ia], SHIFTS[ix], MODULES_MM[im],
                                              (long long)q.n_tris, (long long)ref_tris, q.min_angle_deg, ref_angle);
                        }
                        total_tris += (long)q.n_tris;
                        gs_mesh_free(&m);
                    }
                }
    double dt = gs_now() - t0;
    print_message("# gear mesh sweep: %d gears (teeth 8-200 x modules 0.5/2/20 mm x alpha 14.5/20/25 x "
                  "shift -0.5..0.8 x external/internal), default density {8, 4, 3}\n",
                  n_gears);
    print_message("# %-8s %5s %6s %8s %8s | %9s %9s %9s %9s | %8s %8s %8s %8s\n", "kind", "alpha",
                  "meshed", "undercut", "rejected", "min ang", "p10 ang", "median", "max asp",
                  "teeth", "shift", "addendum", "fillet");
    for (int k = 0; k < 2; k++)
        for (int a = 0; a < 3; a++) {
            summary *s = &S[k][a];
            qsort(s->min_angles, (size_t)s->meshed, sizeof(double), cmp_double);
            double med = s->meshed ? s->min_angles[s->meshed / 2] : NAN;
            double p10 = s->meshed ? s->min_angles[s->meshed / 10] : NAN;
            print_message("# %-8s %5.1f %6d %8d %8d | %9.2f %9.2f %9.2f %9.2f | %8d %8d %8d %8d\n",
                          k ? "internal" : "external", ALPHAS[a], s->meshed, s->undercut,
                          s->rejected / N_ARR(MODULES_MM), s->worst_min_angle, p10, med, s->worst_aspect,
                          s->by_field[0] / N_ARR(MODULES_MM), s->by_field[1] / N_ARR(MODULES_MM),
                          s->by_field[2] / N_ARR(MODULES_MM), s->by_field[3] / N_ARR(MODULES_MM));
            free(s->min_angles);
        }
    print_message("# (counts per module; angles in degrees; aspect = circumradius / (2 inradius))\n");
    print_message("# worst meshes by minimum angle:\n");
    for (int i = 0; i < 5; i++)
        print_message("#   %.2f deg  %s\n", worst5[i].ang, worst5[i].what);
    print_message("# %ld triangles in %.2f s; scale invariance mismatches: %d\n", total_tris, dt,
                  scale_mismatch);
    assert_int_equal(scale_mismatch, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(sweep),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
