/* SPDX-License-Identifier: MIT
 * gearsim-sweep: a speed sweep of a rigid/lumped train, point after point in
 * one process (docs/MODAL.md, "Speed sweep").
 *
 *   gearsim-sweep SCENE.json --from RPM --to RPM [--points N] [--settle S]
 *                 [--measure S] [--time-step H] [--mesh NAME]
 *
 * The driver is the body of the scene's first moment load (made constant at
 * its moment); at each point every body starts at the rigid speeds of the
 * driver's speed (the meshes' kinematics, least squares over the lumped
 * line-of-action rows) and the brake coefficient is set so that the point is
 * in steady state (power balance M w_d = c w_o^2). After --settle seconds the
 * response is measured over --measure seconds. Prints one CSV row per
 * point: driver rpm, mesh frequency of the mesh (Hz), its dynamic
 * transmission error rms (um, deflection about its mean), its dynamic factor
 * (largest force / mean force), the planets' load-sharing factor (largest
 * share, 1 = equal; empty without planets) and the balance residual over the
 * energy scale. Progress per point on stderr. Exit status 0, 1 bad usage,
 * 2 an error (message naming the field). Not an MPI program. */
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/step.h"
#include "gearsim/util.h"
#include "tool.h"

static void usage(void)
{
    fprintf(stderr, "usage: gearsim-sweep SCENE.json --from RPM --to RPM [--points N] [--settle S] [--measure S]\n"
                    "                     [--time-step H] [--mesh NAME]\n");
}

static int driver_and_brake(const gs_scene *s, int *drv, int *ld, int *brk)
{
    *drv = *ld = *brk = -1;
    for (int i = 0; i < s->n_loads; i++) {
        const gs_scene_load *l = &s->loads[i];
        if (*ld < 0 && (l->type == GS_LOAD_CONSTANT || l->type == GS_LOAD_RAMP))
            *ld = i, *drv = l->body;
        if (*brk < 0 && l->type == GS_LOAD_BRAKE)
            *brk = i;
    }
    return *ld >= 0 && *brk >= 0;
}

/* Rigid speeds per unit driver speed: a_m . w = 0 for every mesh, w_drv = 1. */
static int speed_ratios(const gs_system *sys, int drv, double *ratio)
{
    int n = sys->n_coords, m = sys->n_meshes + 1;
    double *A = calloc((size_t)m * n, sizeof(double)), *b = calloc((size_t)(m > n ? m : n), sizeof(double));
    for (int i = 0; i < sys->n_meshes; i++)
        for (int j = 0; j < n; j++)
            A[(size_t)i * n + j] = sys->meshes[i].a[j];
    A[(size_t)(m - 1) * n + sys->bodies[drv].coord] = 1.0;
    b[m - 1] = 1.0;
    int ok = LAPACKE_dgels(LAPACK_ROW_MAJOR, 'N', m, n, 1, A, n, b, 1) == 0;
    for (int j = 0; j < n; j++)
        ratio[j] = b[j];
    free(A), free(b);
    return ok;
}

int main(int argc, char **argv)
{
    const char *path = NULL, *mesh_name = NULL;
    double from = NAN, to = NAN, settle = 0.01, measure = 0.01, h = 0;
    int points = 40;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (i + 1 < argc && !strcmp(a, "--from"))
            from = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--to"))
            to = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--points"))
            points = atoi(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--settle"))
            settle = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--measure"))
            measure = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--time-step"))
            h = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--mesh"))
            mesh_name = argv[++i];
        else if (a[0] != '-' && !path)
            path = a;
        else {
            usage();
            return 1;
        }
    }
    if (!path || !isfinite(from) || !isfinite(to) || points < 1 || points > 10000 || !(settle >= 0) ||
        !(measure > 0) || !(h >= 0)) {
        usage();
        return 1;
    }
    gs_scene *s0 = tool_load_scene("gearsim-sweep", path);
    if (!s0)
        return 2;
    int drv, ld, brk;
    if (!driver_and_brake(s0, &drv, &ld, &brk)) {
        fprintf(stderr, "gearsim-sweep: %s: loads: a sweep needs a moment load (the driver) and a brake\n", path);
        gs_scene_free(&s0);
        return 2;
    }
    int mi = 0;
    if (mesh_name) {
        mi = -1;
        for (int i = 0; i < s0->n_meshes; i++)
            if (!strcmp(s0->meshes[i].name, mesh_name))
                mi = i;
    }
    if (mi < 0 || mi >= s0->n_meshes) {
        fprintf(stderr, "gearsim-sweep: %s: meshes: no mesh '%s'\n", path, mesh_name ? mesh_name : "");
        gs_scene_free(&s0);
        return 2;
    }
    char *text = gs_strdup(s0->json);
    gs_scene_free(&s0);
    printf("point,driver_rpm,mesh_hz,dte_rms_um,dynamic_factor,lsf,balance_rel\n");
    for (int p = 0; p < points; p++) {
        double rpm = points == 1 ? from : from + (to - from) * p / (points - 1);
        double wd = rpm / GS_RPM_PER_RAD_S;
        gs_scene *s;
        gs_diag d;
        if (gs_scene_parse(text, strlen(text), &s, &d) != GS_OK) {
            fprintf(stderr, "gearsim-sweep: %s: %s: %s\n", path, d.field, d.message);
            return 2;
        }
        if (h > 0)
            s->time_step = h;
        gs_scene_load *L = &s->loads[ld];
        L->type = GS_LOAD_CONSTANT;
        int out_body = s->loads[brk].body;
        /* speeds from a first build of the same scene */
        gs_scene *sk;
        gs_scene_parse(text, strlen(text), &sk, &d);
        gs_system *k;
        if (gs_system_new(sk, 0, 1, &k, &d) != GS_OK) {
            fprintf(stderr, "gearsim-sweep: %s: %s: %s\n", path, d.field, d.message);
            gs_scene_free(&s);
            return 2;
        }
        double *ratio = calloc((size_t)k->n_coords, sizeof(double));
        if (!speed_ratios(k, drv, ratio)) {
            fprintf(stderr, "gearsim-sweep: %s: meshes: the train has no rigid motion driven by '%s'\n", path,
                    s->bodies[drv].name);
            return 2;
        }
        for (int i = 0; i < s->n_bodies; i++)
            if (k->bodies[i].coord >= 0)
                s->bodies[i].omega0 = wd * ratio[k->bodies[i].coord];
        double wo = s->bodies[out_body].omega0;
        gs_system_free(&k);
        free(ratio);
        if (fabs(wo) < 1e-12) {
            fprintf(stderr, "gearsim-sweep: %s: loads: the brake's body does not turn with the driver\n", path);
            return 2;
        }
        s->loads[brk].coefficient = fabs(L->moment * wd / (wo * wo));
        gs_system *sys;
        if (gs_system_new(s, 0, 1, &sys, &d) != GS_OK) {
            fprintf(stderr, "gearsim-sweep: point %d: %s: %s\n", p, d.field, d.message);
            return 2;
        }
        long n_settle = lround(settle / sys->h), n_meas = lround(measure / sys->h);
        double sx = 0, sxx = 0, fbig = 0, fsum = 0, shmax = 0, worst = 0, scale = 1e-300, fmesh = 0;
        int np = 0;
        gs_energy e;
        for (long st = 0; st < n_settle + n_meas; st++) {
            if (gs_step_serial(sys) != GS_OK) {
                fprintf(stderr, "gearsim-sweep: point %d (%.1f rpm): %s: %s\n", p, rpm, sys->diag.field,
                        sys->diag.message[0] ? sys->diag.message : "the step failed");
                return 2;
            }
            gs_system_energy(sys, &e);
            worst = fmax(worst, fabs(e.balance_residual));
            scale = fmax(scale, fmax(fabs(e.total), fmax(e.work_in, e.dissipated)));
            if (st < n_settle)
                continue;
            const gs_gmesh_rt *m = &sys->meshes[mi];
            sx += m->deflection;
            sxx += m->deflection * m->deflection;
            fbig = fmax(fbig, fabs(m->force));
            fsum += fabs(m->force);
            double phr = 0;
            for (int j = 0; j < sys->n_coords; j++)
                phr += m->c[j] * sys->w[j];
            fmesh += fabs(phr);
            int pl[16];
            double sh[16];
            np = gs_system_planet_shares(sys, pl, sh, 16);
            double mx = 0;
            for (int i = 0; i < np; i++)
                mx = fmax(mx, sh[i]);
            shmax += mx;
        }
        double mean = sx / n_meas, var = fmax(sxx / n_meas - mean * mean, 0.0);
        printf("%d,%.6f,%.6f,%.6f,%.6f,", p, rpm, fmesh / n_meas, sqrt(var) * 1e6, fbig / (fsum / n_meas));
        if (np)
            printf("%.6f,", shmax / n_meas);
        else
            printf(",");
        printf("%.3e\n", worst / scale);
        fflush(stdout);
        fprintf(stderr, "point %d/%d: %.1f rpm done\n", p + 1, points, rpm);
        gs_system_free(&sys);
    }
    free(text);
    return 0;
}
