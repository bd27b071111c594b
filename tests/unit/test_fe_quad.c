/* SPDX-License-Identifier: MIT
 * Unit tests of the quadratic (6-node) triangle and of quadratic gear meshes
 * (src/fe/fe_element.c, src/mesh/mesh_quad.c): patch test on distorted and
 * curved elements, exact quadratic displacement fields (energy and stress
 * against closed forms), the consistent mass matrix (closed form of the
 * straight element, area and polar inertia integrated exactly), mid-side
 * nodes on the exact outline, and the order of convergence of the curved
 * boundary (area of an annulus and of a gear against closed forms). */
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

#include "fe/fe_internal.h"
#include "gearsim/fe.h"
#include "gearsim/geometry.h"
#include "gearsim/mesh.h"
#include "gearsim/mesh_io.h"
#include "../common/gears.h"
#include "../common/rect.h"

static const double T = 0.02; /* thickness, m */

/* Quadratic rectangle [0,lx] x [-ly/2,ly/2], no fixed node, interior corner
 * nodes moved pseudo-randomly; with `bend` the interior mid-side nodes are
 * moved off their chords too (curved isoparametric elements). */
static gs_mesh *quad_rectangle(double lx, double ly, int nx, int ny, double distort, double bend)
{
    gs_mesh *m = free_rectangle(lx, ly, nx, ny, distort);
    gs_index n0 = m->n_nodes;
    assert_int_equal(gs_mesh_make_quadratic(m), GS_OK);
    assert_int_equal(gs_mesh_order(m), 2);
    if (bend > 0) {
        /* mid-side nodes of interior edges: those not on x = 0, lx, y = +-ly/2 */
        for (gs_index k = n0; k < m->n_nodes; k++) {
            double x = m->xy[2 * k], y = m->xy[2 * k + 1];
            if (fabs(x) < 1e-12 || fabs(x - lx) < 1e-12 || fabs(fabs(y) - 0.5 * ly) < 1e-12)
                continue;
            m->xy[2 * k] += bend * lx / nx * sin(3.1 * k);
            m->xy[2 * k + 1] += bend * ly / ny * cos(1.3 * k);
        }
    }
    return m;
}

static bool on_rect_boundary(const double *p, double lx, double ly)
{
    return fabs(p[0]) < 1e-12 || fabs(p[0] - lx) < 1e-12 || fabs(fabs(p[1]) - 0.5 * ly) < 1e-12;
}

/* Patch test: a linear displacement field gives zero nodal forces at every
 * interior node (distorted and curved elements) and the exact constant
 * stress in every element. */
static void patch_test(void **state)
{
    (void)state;
    for (int curved = 0; curved <= 1; curved++) {
        const double lx = 0.3, ly = 0.2;
        gs_mesh *mesh = quad_rectangle(lx, ly, 4, 3, 0.2, curved ? 0.08 : 0.0);
        gs_material mat = gs_material_steel();
        gs_fe_model *m = NULL;
        assert_int_equal(gs_fe_model_new(mesh, &mat, T, 1.0, &m), GS_OK);
        gs_fe_model_info info;
        gs_fe_model_get_info(m, &info);
        assert_int_equal(info.n_tris, 24);
        gs_index n = info.n_elastic + 1;
        double *K = calloc((size_t)(n * n), sizeof *K);
        double *u = calloc((size_t)n, sizeof *u);
        double *un = calloc((size_t)(2 * mesh->n_nodes), sizeof *un);
        assert_int_equal(gs_fe_model_dense(m, K, NULL), GS_OK);
        const double ex = 1e-4, ey = -3e-5, gxy = 5e-5;
        for (gs_index i = 0; i < mesh->n_nodes; i++) {
            double x = mesh->xy[2 * i], y = mesh->xy[2 * i + 1];
            un[2 * i] = ex * x + 0.5 * gxy * y + 1e-5;
            un[2 * i + 1] = ey * y + 0.5 * gxy * x - 2e-5;
            u[gs_fe_model_dof(m, i, 0)] = un[2 * i];
            u[gs_fe_model_dof(m, i, 1)] = un[2 * i + 1];
        }
        double kmax = 0, fmax_int = 0;
        for (gs_index i = 0; i < n * n; i++)
            kmax = fmax(kmax, fabs(K[i]));
        for (gs_index i = 0; i < mesh->n_nodes; i++) {
            if (on_rect_boundary(mesh->xy + 2 * i, lx, ly))
                continue;
            for (int c = 0; c < 2; c++) {
                gs_index r = gs_fe_model_dof(m, i, c);
                double f = 0;
                for (gs_index j = 0; j < n - 1; j++)
                    f += K[r + j * n] * u[j];
                fmax_int = fmax(fmax_int, fabs(f));
            }
        }
        /* scale: |K| |u| */
        printf("# patch (%s): max interior force %.3e of scale %.3e\n",
               curved ? "curved" : "straight", fmax_int, kmax * 1e-4 * 0.3);
        assert_true(fmax_int < 1e-11 * kmax * 1e-4 * 0.3);
        double *st = calloc((size_t)(3 * mesh->n_tris), sizeof *st);
        assert_int_equal(gs_fe_model_stress(m, un, st, NULL, NULL), GS_OK);
        double sxx = m->Dmat[0] * ex + m->Dmat[1] * ey, syy = m->Dmat[3] * ex + m->Dmat[4] * ey;
        double txy = m->Dmat[8] * gxy;
        for (gs_index e = 0; e < mesh->n_tris; e++) {
            assert_true(fabs(st[3 * e] - sxx) < 1e-8 * fabs(sxx));
            assert_true(fabs(st[3 * e + 1] - syy) < 1e-8 * fabs(sxx));
            assert_true(fabs(st[3 * e + 2] - txy) < 1e-8 * fabs(sxx));
        }
        free(st);
        free(K);
        free(u);
        free(un);
        gs_fe_model_free(&m);
        gs_mesh_free(&mesh);
    }
}

/* Integral of x^p y^q over [0,lx] x [-ly/2, ly/2]. */
static double mono(double lx, double ly, int p, int q)
{
    double h = 0.5 * ly;
    return pow(lx, p + 1) / (p + 1) * (pow(h, q + 1) - pow(-h, q + 1)) / (q + 1);
}

/* A quadratic field u_x = a x^2 + c x y, u_y = b y^2 on straight-sided
 * quadratic elements is represented exactly: the strain energy equals the
 * closed-form integral and the centroid stresses are exact. */
static void exact_quadratic_field(void **state)
{
    (void)state;
    const double lx = 0.3, ly = 0.2, a = 2e-3, b = -1e-3, c = 1.5e-3;
    gs_mesh *mesh = quad_rectangle(lx, ly, 3, 4, 0.25, 0.0);
    gs_material mat = gs_material_steel();
    mat.plane = GS_PLANE_STRAIN;
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 1.0, &m), GS_OK);
    double *un = calloc((size_t)(2 * mesh->n_nodes), sizeof *un);
    for (gs_index i = 0; i < mesh->n_nodes; i++) {
        double x = mesh->xy[2 * i], y = mesh->xy[2 * i + 1];
        un[2 * i] = a * x * x + c * x * y;
        un[2 * i + 1] = b * y * y;
    }
    /* eps_xx = 2a x + c y, eps_yy = 2b y, gamma = c x */
    const double *D = m->Dmat;
    double E = 0.5 * T *
               (D[0] * (4 * a * a * mono(lx, ly, 2, 0) + 4 * a * c * mono(lx, ly, 1, 1) +
                        c * c * mono(lx, ly, 0, 2)) +
                2 * D[1] * (4 * a * b * mono(lx, ly, 1, 1) + 2 * b * c * mono(lx, ly, 0, 2)) +
                D[4] * 4 * b * b * mono(lx, ly, 0, 2) + D[8] * c * c * mono(lx, ly, 2, 0));
    double Efe = gs_fe_model_energy(m, un);
    printf("# quadratic field: energy %.15e vs closed form %.15e (rel %.2e)\n", Efe, E,
           fabs(Efe - E) / E);
    assert_true(fabs(Efe - E) < 1e-12 * E);
    double *st = calloc((size_t)(3 * mesh->n_tris), sizeof *st);
    assert_int_equal(gs_fe_model_stress(m, un, st, NULL, NULL), GS_OK);
    double smax = 0, err = 0;
    for (gs_index e = 0; e < mesh->n_tris; e++) {
        double xc = 0, yc = 0;
        for (int i = 0; i < 3; i++) {
            xc += mesh->xy[2 * mesh->tri[3 * e + i]] / 3;
            yc += mesh->xy[2 * mesh->tri[3 * e + i] + 1] / 3;
        }
        double eps[3] = {2 * a * xc + c * yc, 2 * b * yc, c * xc};
        for (int r = 0; r < 3; r++) {
            double s = D[3 * r] * eps[0] + D[3 * r + 1] * eps[1] + D[3 * r + 2] * eps[2];
            err = fmax(err, fabs(st[3 * e + r] - s));
            smax = fmax(smax, fabs(s));
        }
    }
    assert_true(err < 1e-10 * smax);
    free(st);
    free(un);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

/* The consistent mass of one straight quadratic triangle is the closed form
 * rho t A / 180 [6 -1 -1 0 -4 0; ...; 32 16 16; ...]; a rectangle's mass,
 * centroid and polar inertia come out exactly. */
static void consistent_mass(void **state)
{
    (void)state;
    gs_mesh *mesh = quad_rectangle(0.3, 0.2, 1, 1, 0.0, 0.0);
    gs_material mat = gs_material_steel();
    {
        double x[6], y[6], ke[144], me[36];
        gsi_fe_props pr;
        for (int i = 0; i < 3; i++) {
            x[i] = mesh->xy[2 * mesh->tri[i]];
            y[i] = mesh->xy[2 * mesh->tri[i] + 1];
            x[3 + i] = mesh->xy[2 * mesh->mid[i]];
            y[3 + i] = mesh->xy[2 * mesh->mid[i] + 1];
        }
        double D[9] = {0};
        assert_int_equal(gsi_fe_tri6.matrices(x, y, D, T, mat.density, ke, me, &pr), GS_OK);
        static const double ref[6][6] = {{6, -1, -1, 0, -4, 0},  {-1, 6, -1, 0, 0, -4},
                                         {-1, -1, 6, -4, 0, 0},  {0, 0, -4, 32, 16, 16},
                                         {-4, 0, 0, 16, 32, 16}, {0, -4, 0, 16, 16, 32}};
        double f = mat.density * T * pr.area / 180.0;
        for (int i = 0; i < 6; i++)
            for (int j = 0; j < 6; j++)
                assert_true(fabs(me[6 * i + j] - f * ref[i][j]) < 1e-13 * 32 * f);
        assert_true(fabs(pr.area - 0.5 * 0.3 * 0.2) < 1e-15);
    }
    gs_mesh_free(&mesh);
    const double lx = 0.3, ly = 0.2;
    mesh = quad_rectangle(lx, ly, 3, 2, 0.2, 0.05); /* curved interior edges too */
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 1.0, &m), GS_OK);
    gs_fe_model_info info;
    gs_fe_model_get_info(m, &info);
    double rt = mat.density * T;
    double Iex = rt * (mono(lx, ly, 2, 0) + mono(lx, ly, 0, 2));
    printf("# mass: area %.15e (%.15e), inertia %.15e (%.15e)\n", info.area_m2, lx * ly,
           info.inertia_elastic, Iex);
    assert_true(fabs(info.area_m2 - lx * ly) < 1e-14 * lx * ly);
    assert_true(fabs(info.mass_kg - rt * lx * ly) < 1e-13 * rt * lx * ly);
    assert_true(fabs(info.centroid[0] - 0.5 * lx) < 1e-13 * lx);
    assert_true(fabs(info.centroid[1]) < 1e-13 * lx);
    assert_true(fabs(info.inertia_elastic - Iex) < 1e-13 * Iex);
    /* the coupling vector: s . (rigid translation) = mass x (J centroid) */
    double *s = calloc((size_t)info.n_elastic, sizeof *s);
    gs_fe_model_coupling(m, s);
    double sx = 0, sy = 0;
    for (gs_index k = 0; k < info.n_elastic / 2; k++) {
        sx += s[2 * k];
        sy += s[2 * k + 1];
    }
    assert_true(fabs(sx + info.mass_kg * info.centroid[1]) < 1e-12 * info.mass_kg * lx);
    assert_true(fabs(sy - info.mass_kg * info.centroid[0]) < 1e-12 * info.mass_kg * lx);
    free(s);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

/* Area of an annulus meshed with chords (order 1) and with quadratic edges
 * whose mid-side nodes are put on the circles (order 2): errors fall as h^2
 * and h^4. */
static void curved_area_order(void **state)
{
    (void)state;
    const double r0 = 0.03, r1 = 0.05, A = GS_PI * (r1 * r1 - r0 * r0);
    double err1[3], err2[3];
    for (int l = 0; l < 3; l++) {
        int nt = 12 << l, nr = 2 << l;
        gs_mesh *mesh = NULL;
        assert_int_equal(gsi_fe_mesh_annulus(r0, r1, nr, nt, &mesh), GS_OK);
        gs_material mat = gs_material_steel();
        gs_fe_model *m = NULL;
        gs_fe_model_info info;
        assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0.0, &m), GS_OK);
        gs_fe_model_get_info(m, &info);
        err1[l] = fabs(info.area_m2 - A) / A;
        gs_fe_model_free(&m);
        gs_index n0 = mesh->n_nodes;
        assert_int_equal(gs_mesh_make_quadratic(mesh), GS_OK);
        for (gs_index k = n0; k < mesh->n_nodes; k++) { /* onto the circles */
            double x = mesh->xy[2 * k], y = mesh->xy[2 * k + 1], r = hypot(x, y);
            for (gs_index e = 0; e < mesh->n_tris; e++)
                for (int i = 0; i < 3; i++)
                    if (mesh->mid[3 * e + i] == k) {
                        const double *p = mesh->xy + 2 * mesh->tri[3 * e + i];
                        const double *q = mesh->xy + 2 * mesh->tri[3 * e + (i + 1) % 3];
                        double rp = hypot(p[0], p[1]), rq = hypot(q[0], q[1]);
                        if (fabs(rp - rq) < 1e-12 && (fabs(rp - r0) < 1e-12 || fabs(rp - r1) < 1e-12)) {
                            mesh->xy[2 * k] = x * rp / r;
                            mesh->xy[2 * k + 1] = y * rp / r;
                        }
                    }
        }
        assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0.0, &m), GS_OK);
        gs_fe_model_get_info(m, &info);
        err2[l] = fabs(info.area_m2 - A) / A;
        printf("# annulus %d x %d: area error order 1 %.3e, order 2 %.3e\n", nr, nt, err1[l],
               err2[l]);
        gs_fe_model_free(&m);
        gs_mesh_free(&mesh);
    }
    double p1 = log2(err1[1] / err1[2]), p2 = log2(err2[1] / err2[2]);
    printf("# observed orders: %.2f (linear), %.2f (quadratic)\n", p1, p2);
    assert_true(p1 > 1.9 && p1 < 2.1);
    assert_true(p2 > 3.8 && p2 < 4.2);
}

/* Gear meshes of order 2: every flank node (corner or mid-side) on the
 * involute, fillet nodes on the fillet; the area of the elastic part
 * converges to the exact outline's at order 3 to 4 (h^2 for order 1). */
static void gear_quadratic_mesh(void **state)
{
    (void)state;
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 20, 2.5e-3, 0.0);
    p.face_width_m = 0.02;
    gs_gear_geom g;
    assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
    double Aout, Jout;
    gs_gear_outline_moments(&g, &Aout, &Jout);
    double Aex = Aout - GS_PI * g.hub * g.hub;
    double e1[3], e2[3];
    for (int ord = 1; ord <= 2; ord++)
        for (int r = 0; r < 3; r++) {
            gs_gear_mesh_opts o;
            gs_gear_mesh_opts_defaults(&o);
            o.refine = r;
            o.order = ord;
            gs_mesh *mesh = NULL;
            gs_diag d;
            gs_diag_clear(&d);
            assert_int_equal(gs_gear_mesh(&p, &o, &mesh, &d), GS_OK);
            assert_int_equal(gs_mesh_order(mesh), ord);
            int loops = 0;
            assert_int_equal(gs_mesh_check_topology(mesh, NULL, &loops), GS_OK);
            assert_int_equal(loops, 2);
            double worst = 0;
            for (gs_index i = 0; i < mesh->n_nodes; i++) {
                if (mesh->node_tag[i] != GS_NODE_FLANK)
                    continue;
                double x = mesh->xy[2 * i], y = mesh->xy[2 * i + 1], R = hypot(x, y);
                double pitch = 2 * GS_PI / g.z, a = atan2(y, x);
                double loc = fabs(a - pitch * round(a / pitch));
                worst = fmax(worst, fabs(loc - gs_gear_involute_psi(&g, R)) * R);
            }
            assert_true(worst < 1e-12);
            /* flank tables alternate corners and mid-side nodes */
            gs_index nfl = mesh->flank_ptr[1] - mesh->flank_ptr[0];
            if (ord == 2)
                assert_true(nfl % 2 == 1);
            gs_material mat = gs_material_steel();
            gs_fe_model *m = NULL;
            assert_int_equal(gs_fe_model_new(mesh, &mat, p.face_width_m, 0.0, &m), GS_OK);
            gs_fe_model_info info;
            gs_fe_model_get_info(m, &info);
            double err = fabs(info.area_m2 - Aex) / Aex;
            (ord == 1 ? e1 : e2)[r] = err;
            printf("# gear z20 order %d refine %d: %lld nodes, area error %.3e, involute %.1e m\n",
                   ord, r, (long long)mesh->n_nodes, err, worst);
            gs_fe_model_free(&m);
            gs_mesh_free(&mesh);
        }
    double p1 = log2(e1[1] / e1[2]), p2 = log2(e2[1] / e2[2]);
    printf("# gear area orders: %.2f (linear), %.2f (quadratic)\n", p1, p2);
    /* h^4 on smooth arcs (annulus test); the outline has curvature jumps
     * inside edges (trochoid round / generated flank, fillet / root arc),
     * where a parabola is an O(h^3) fit, so the mesh-wide order lies
     * between 3 and 4 (measured 3.6 then 3.3) */
    assert_true(p1 > 1.7);
    assert_true(p2 > 2.8);
    assert_true(e2[0] < 0.1 * e1[0]);
}

/* A quadratic gear mesh written with gs_mesh_io and read back keeps its
 * mid-side nodes; the XDMF declares Triangle_6 cells over the 6-column
 * connectivity (what ParaView reads as curved quadratic triangles). */
static void mesh_file_triangle6(void **state)
{
    (void)state;
    char dir[] = "/tmp/gs_test_quad_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char h5[128], xmf[128];
    snprintf(h5, sizeof h5, "%s/m.h5", dir);
    snprintf(xmf, sizeof xmf, "%s/m.xmf", dir);
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 17, 2e-3, 0.2);
    p.face_width_m = 0.01;
    gs_gear_mesh_opts o;
    gs_gear_mesh_opts_defaults(&o);
    o.order = 2;
    gs_mesh *m = NULL;
    assert_int_equal(gs_gear_mesh(&p, &o, &m, NULL), GS_OK);
    gs_mesh_io_gear g = {"pinion", m, &p, {0.0, 0.0}, 0.0};
    assert_int_equal(gs_mesh_io_write(h5, xmf, &g, 1, NULL), GS_OK);
    gs_mesh *back = NULL;
    assert_int_equal(gs_mesh_io_read(h5, "pinion", &back, NULL, NULL, NULL), GS_OK);
    assert_int_equal(gs_mesh_order(back), 2);
    assert_int_equal(back->n_tris, m->n_tris);
    assert_memory_equal(back->mid, m->mid, (size_t)(3 * m->n_tris) * sizeof *m->mid);
    FILE *f = fopen(xmf, "r");
    assert_non_null(f);
    char buf[4096];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = 0;
    fclose(f);
    assert_non_null(strstr(buf, "TopologyType=\"Triangle_6\""));
    assert_non_null(strstr(buf, "/triangles6<"));
    gs_mesh_free(&back);
    gs_mesh_free(&m);
    remove(h5);
    remove(xmf);
    rmdir(dir);
}

/* Bad element order is refused with the field named. */
static void order_errors(void **state)
{
    (void)state;
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 20, 2e-3, 0.0);
    gs_gear_mesh_opts o;
    gs_gear_mesh_opts_defaults(&o);
    o.order = 3;
    gs_mesh *m = NULL;
    gs_diag d;
    gs_diag_clear(&d);
    assert_int_equal(gs_gear_mesh(&p, &o, &m, &d), GS_ERANGE);
    assert_string_equal(d.field, "mesh.order");
    assert_null(m);
    gs_mesh *r = NULL;
    assert_int_equal(gs_mesh_rectangle(1, 1, 2, 2, &r), GS_OK);
    assert_int_equal(gs_mesh_make_quadratic(r), GS_OK);
    assert_int_equal(gs_mesh_make_quadratic(r), GS_EINVAL); /* already quadratic */
    /* a clamp stays a clamp: the mid-side nodes on x = 0 are fixed */
    assert_int_equal(r->n_fixed, 3 + 2);
    gs_mesh_free(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(patch_test),
        cmocka_unit_test(exact_quadratic_field),
        cmocka_unit_test(consistent_mass),
        cmocka_unit_test(curved_area_order),
        cmocka_unit_test(gear_quadratic_mesh),
        cmocka_unit_test(mesh_file_triangle6),
        cmocka_unit_test(order_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
