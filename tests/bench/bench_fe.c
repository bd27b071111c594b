/* SPDX-License-Identifier: MIT
 * Benchmark of the elastic body (prints only, not a pass/fail test): for
 * annulus meshes of ~1e3 to ~1e5 elastic unknowns, the assembly time, the
 * first factorisation (ordering + symbolic + numeric), a refactorisation for
 * a new h, the time per free step, a bare CHOLMOD solve on the same factor,
 * and their ratio: the floor this design can reach is one solve per step.
 * Also the condensation costs: compliance columns for 20 new nodes (cache
 * misses), and a cached compliance block + back-substitution (cache hits).
 * Run: meson test -C build --suite bench --verbose (or the bench_fe binary;
 * an argument "quick" stops at ~3e4 unknowns). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fe/fe_internal.h"
#include "gearsim/fe.h"
#include "gearsim/util.h"

typedef struct {
    int n_r, n_t;
} size_case;

int main(int argc, char **argv)
{
    const size_case cases[] = {{10, 50}, {16, 160}, {25, 400}, {40, 400}, {50, 1000}};
    int ncases = (int)(sizeof cases / sizeof cases[0]);
    if (argc > 1 && strcmp(argv[1], "quick") == 0)
        ncases = 4;
    const char *thr = getenv("OPENBLAS_NUM_THREADS");
    printf("# bench_fe: annulus r 30..50 mm, steel, plane stress; OPENBLAS_NUM_THREADS=%s\n",
           thr ? thr : "(unset)");
    printf("# order 2: curved quadratic triangles on an annulus of half the counts (about the "
           "same unknowns)\n");
    printf("# %5s %8s %9s %10s %11s %11s %10s %10s %7s %11s %11s\n", "order", "unknowns", "nnz(L)",
           "assemble", "1st factor", "refactor", "step", "solve", "ratio", "C 20 new", "C+apply hit");
    gs_material mat = gs_material_steel();
    for (int cc = 0; cc < 2 * ncases; cc++) {
        int c = cc / 2, order = 1 + cc % 2;
        gs_mesh *mesh = NULL;
        gs_fe_model *m = NULL;
        gs_fe_body *b = NULL;
        if (gsi_fe_mesh_annulus_order(0.03, 0.05, cases[c].n_r / order, cases[c].n_t / order, order,
                                      &mesh) != GS_OK)
            return 1;
        double t0 = gs_now();
        if (gs_fe_model_new(mesh, &mat, 0.02, 2e-4, &m) != GS_OK)
            return 1;
        double t_asm = gs_now() - t0;
        if (gs_fe_body_new(m, &b) != GS_OK)
            return 1;
        t0 = gs_now();
        if (gs_fe_body_set_step(b, 1e-6, 0.0) != GS_OK)
            return 1;
        double t_fac1 = gs_now() - t0;
        t0 = gs_now();
        if (gs_fe_body_set_step(b, 2e-6, 0.0) != GS_OK)
            return 1;
        double t_fac2 = gs_now() - t0;
        gs_fe_model_info info;
        gs_fe_model_get_info(m, &info);
        gs_fe_stats st;
        gs_fe_body_get_stats(b, &st);

        /* a disturbed, spinning state */
        double *u = calloc((size_t)(2 * mesh->n_nodes), sizeof *u);
        for (gs_index k = 0; k < 2 * mesh->n_nodes; k++)
            u[k] = 1e-7 * ((k * 7919) % 13 - 6);
        gs_fe_body_set_state(b, 0.0, 300.0, u, NULL);
        free(u);
        int reps = info.n_elastic > 50000 ? 40 : info.n_elastic > 5000 ? 200 : 2000;
        gs_fe_body_step(b, 1.0, NULL); /* warm-up */
        t0 = gs_now();
        for (int k = 0; k < reps; k++)
            gs_fe_body_step(b, 1.0, NULL);
        double t_step = (gs_now() - t0) / reps;
        double t_solve = gsi_fe_body_time_bare_solve(b, reps);

        /* condensation: 20 rim nodes (a tooth flank's worth) */
        gs_index dofs[41];
        double C[41 * 41], f[41];
        dofs[0] = GS_FE_DOF_THETA;
        f[0] = 1.0;
        for (int k = 0; k < 20; k++) {
            gs_index node = mesh->n_nodes - 1 - k;
            dofs[1 + 2 * k] = gs_fe_dof_node(node, 0);
            dofs[2 + 2 * k] = gs_fe_dof_node(node, 1);
            f[1 + 2 * k] = 1.0;
            f[2 + 2 * k] = -1.0;
        }
        t0 = gs_now();
        gs_fe_body_compliance(b, 41, dofs, C);
        double t_miss = gs_now() - t0;
        const int hreps = 20;
        t0 = gs_now();
        for (int k = 0; k < hreps; k++) {
            gs_fe_body_compliance(b, 41, dofs, C);
            gs_fe_body_begin_step(b, 0.0, NULL);
            gs_fe_body_apply(b, 41, dofs, f);
            gs_fe_body_end_step(b);
        }
        double t_hit = (gs_now() - t0) / hreps - t_step; /* cached C + apply, beyond the step */

        printf("  %5d %8lld %9.3g %8.2f ms %8.2f ms %8.2f ms %7.3f ms %7.3f ms %7.2f %8.2f ms %8.3f ms\n",
               order, (long long)info.n_elastic, st.factor_nnz, 1e3 * t_asm, 1e3 * t_fac1, 1e3 * t_fac2,
               1e3 * t_step, 1e3 * t_solve, t_step / t_solve, 1e3 * t_miss, 1e3 * t_hit);
        fflush(stdout);
        gs_fe_body_free(&b);
        gs_fe_model_free(&m);
        gs_mesh_free(&mesh);
    }
    return 0;
}
