/* SPDX-License-Identifier: MIT
 * gearsim-stiffness: quasi-static mesh stiffness and static transmission
 * error of one gear mesh of a scene over one mesh cycle
 * (include/gearsim/stiffness.h, docs/explanation/stiffness.md).
 *
 *   gearsim-stiffness SCENE.json --mesh NAME --positions N [--torque T]
 *                     [--refine R] [--order 1|2] [--driver 0|1] [--phase P] [--cycles C] [--slices N] [--coupling-mm L] [--no-tangent] [--tangent-step H]
 *                     [--no-nearfield|--plain] [--nearfield-depth MM] [--fine] [--all-rows] [--all-dofs]
 *                     [--json] [--out FILE.h5]
 *
 * --mesh defaults to the scene's first mesh; --positions to 24; --torque
 * (N m, signed, on the driver) to the scene's load on the driver or a
 * 200 N/mm line load; --refine to the scene's mesh density; --driver to
 * gear 0 of the mesh; --order to the scene's element order (mesh.order). Without --json prints a table (one row per roll
 * position) and a summary; with --json one JSON object (keys documented in
 * docs/explanation/stiffness.md). --tangent-step H takes k_tan as the central difference
 * over T (1 -+ H) instead of the chord from T/2. The near-field (Hertz)
 * correction of the contact compliance is on by default when both gears
 * have quadratic elements (the default mesh; linear triangles keep the plain
 * FE); --no-nearfield (or --plain) gives the plain FE contact (what the
 * dynamic FE model has), --nearfield forces the correction on any mesh,
 * --nearfield-depth sets its depth (mm; default 0.2 module; implies
 * --nearfield; not with --no-nearfield). --fine meshes
 * both gears on the `fine` setting (the teeth in contact locally refined,
 * gs_gear_mesh_opts_fine; not with --refine or --order). Exit status 0 on success, 1 on an
 * error (message on stderr naming the field), 2 on bad usage. Not an MPI program. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/scene.h"
#include "gearsim/stiffness.h"
#include "tool.h"

static void usage(FILE *f)
{
    fprintf(f, "usage: gearsim-stiffness SCENE.json [--mesh NAME] [--positions N] [--torque T]\n"
               "                         [--refine R] [--order 1|2] [--driver 0|1] [--phase P] [--cycles C] [--slices N] [--coupling-mm L] [--no-tangent] [--tangent-step H]\n"
               "                         [--no-nearfield|--plain] [--nearfield-depth MM] [--fine] [--all-rows] [--all-dofs]\n"
               "                         [--json] [--out FILE.h5]\n");
}

static bool parse_long(const char *s, long lo, long hi, long *v)
{
    char *end;
    long x = strtol(s, &end, 10);
    if (*s == '\0' || *end || x < lo || x > hi)
        return false;
    *v = x;
    return true;
}

static bool parse_double(const char *s, double *v)
{
    char *end;
    double x = strtod(s, &end);
    if (*s == '\0' || *end || !isfinite(x))
        return false;
    *v = x;
    return true;
}

static void print_json(const gs_stiffness_result *r, const gs_scene *s)
{
    json_object *o = gs_stiffness_json(r, s);
    printf("%s\n", json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN));
    json_object_put(o);
}

static void print_table(const gs_stiffness_result *r, const gs_scene *s)
{
    printf("mesh %s: driver %s (z=%d), driven %s (z=%d), T = %.4g N m, F = %.1f N, b = %.3g mm, "
           "contact ratio %.3f, nodes %lld + %lld\n",
           r->mesh_name, s->bodies[r->body[0]].name, r->teeth[0], s->bodies[r->body[1]].name,
           r->teeth[1], r->torque_nm, r->force_n, r->face_width_mm, r->contact_ratio,
           (long long)r->nodes[0], (long long)r->nodes[1]);
    printf("%6s %9s %10s %10s %9s %12s %12s %5s  %s\n", "roll", "angle", "TE", "TE0", "k", "k_tan",
           "", "pairs", "pair forces (driver tooth/driven tooth: N)");
    printf("%6s %9s %10s %10s %9s %12s %12s %5s\n", "", "deg", "um", "um", "N/mm/um", "N/mm/um",
           "", "");
    for (int j = 0; j < r->positions; j++) {
        const gs_stiffness_point *p = &r->pt[j];
        printf("%6.3f %9.4f %10.4f %10.4f %9.4f %12.4f %12s %5d ", p->roll,
               p->angle_rad * 180.0 / 3.14159265358979323846, p->te_loaded_um, p->te0_um, p->k, p->k_tan,
               p->converged ? "" : "(unconv.)", p->pairs);
        for (int k = 0; k < p->n_pair; k++)
            printf(" %d/%d:%.0f", p->pair[k].tooth[0], p->pair[k].tooth[1], p->pair[k].force_n);
        printf("\n");
    }
    printf("k  min %.4f  mean %.4f  max %.4f N/(mm um)   (tangent mean %.4f)\n", r->k_min,
           r->k_mean, r->k_max, r->k_tan_mean);
    /* TE: the loaded static TE (te_loaded_um of the JSON); with modified flanks
     * the elastic part (te_elastic_um) follows on its own line. */
    printf("TE min %.4f  mean %.4f  max %.4f um   peak-to-peak %.4f um   (loaded static TE)\n",
           r->te_loaded_min, r->te_loaded_mean, r->te_loaded_max, r->te_loaded_max - r->te_loaded_min);
    if (r->modified)
        printf("elastic part, without the modifications' geometric TE: min %.4f  mean %.4f  max %.4f um"
               "   peak-to-peak %.4f um\n",
               r->te_min, r->te_mean, r->te_max, r->te_max - r->te_min);
    printf("positions with 2+ pairs: %.3f   (%.2f s, %ld solves)\n", r->frac_multi, r->seconds,
           r->solves);
    printf("CPU %.3f s: mesh and FE models %.3f, factorisation %.3f, %ld columns %.3f, "
           "%ld solves %.3f, contact %.3f (%.4f s per position)\n",
           r->cpu_seconds, r->cpu_mesh, r->cpu_factor, r->columns, r->cpu_columns, r->solves,
           r->cpu_solves, r->cpu_contact,
           r->positions > 0 ? r->cpu_seconds / r->positions : 0.0);
    if (r->slices > 0) {
        printf("slice analysis: %d slices, coupling length %.3f mm, overlap ratio %.4f, K_Hbeta %.4f\n",
               r->slices, r->coupling_mm, r->overlap_ratio, r->k_hbeta);
        printf("transverse section (spur pair, same transverse geometry): k min %.4f max %.4f, "
               "TE peak-to-peak %.4f um\n",
               r->section_k_min, r->section_k_max, r->section_te_pp);
        printf("peak load per unit face width on one contact line (N/mm):");
        for (int j = 0; j < r->positions; j++)
            printf(" %.2f", r->pt[j].peak_load_n_mm);
        printf("\n");
    }
}

int main(int argc, char **argv)
{
    const char *scene_path = NULL, *mesh = NULL, *out = NULL;
    int json = 0;
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    bool plain = false, depth_set = false;
    for (int i = 1; i < argc; i++) {
        long v;
        const char *a = argv[i];
        bool has = i + 1 < argc;
        if (!strcmp(a, "--mesh") && has)
            mesh = argv[++i];
        else if (!strcmp(a, "--out") && has)
            out = argv[++i];
        else if (!strcmp(a, "--positions") && has) {
            if (!parse_long(argv[++i], 1, 100000, &v)) {
                fprintf(stderr, "gearsim-stiffness: --positions must be 1..100000\n");
                return TOOL_USAGE;
            }
            o.positions = (int)v;
        } else if (!strcmp(a, "--cycles") && has) {
            if (!parse_long(argv[++i], 1, 10000, &v)) {
                fprintf(stderr, "gearsim-stiffness: --cycles must be 1..10000\n");
                return TOOL_USAGE;
            }
            o.cycles = (int)v;
        } else if (!strcmp(a, "--refine") && has) {
            if (!parse_long(argv[++i], 0, 6, &v)) {
                fprintf(stderr, "gearsim-stiffness: --refine must be 0..6\n");
                return TOOL_USAGE;
            }
            o.refine = (int)v;
        } else if (!strcmp(a, "--order") && has) {
            if (!parse_long(argv[++i], 1, 2, &v)) {
                fprintf(stderr, "gearsim-stiffness: --order must be 1 or 2\n");
                return TOOL_USAGE;
            }
            o.order = (int)v;
        } else if (!strcmp(a, "--driver") && has) {
            if (!parse_long(argv[++i], 0, 1, &v)) {
                fprintf(stderr, "gearsim-stiffness: --driver must be 0 or 1\n");
                return TOOL_USAGE;
            }
            o.driver = (int)v;
        } else if (!strcmp(a, "--torque") && has) {
            if (!parse_double(argv[++i], &o.torque_nm) || o.torque_nm == 0.0) {
                fprintf(stderr, "gearsim-stiffness: --torque must be a non-zero number (N m)\n");
                return TOOL_USAGE;
            }
        } else if (!strcmp(a, "--slices") && has) {
            if (!parse_long(argv[++i], 2, 2000, &v)) {
                fprintf(stderr, "gearsim-stiffness: --slices must be 2..2000\n");
                return TOOL_USAGE;
            }
            o.slices = (int)v;
        } else if (!strcmp(a, "--coupling-mm") && has) {
            if (!parse_double(argv[++i], &o.coupling_mm) || !(o.coupling_mm > 0.0 && o.coupling_mm <= 1000.0)) {
                fprintf(stderr, "gearsim-stiffness: --coupling-mm must be in (0, 1000] mm\n");
                return TOOL_USAGE;
            }
        } else if (!strcmp(a, "--phase") && has) {
            if (!parse_double(argv[++i], &o.phase)) {
                fprintf(stderr, "gearsim-stiffness: --phase must be a number (pitches)\n");
                return TOOL_USAGE;
            }
        } else if (!strcmp(a, "--tangent-step") && has) {
            if (!parse_double(argv[++i], &o.tangent_step) || !(o.tangent_step >= 0.0 && o.tangent_step <= 0.5)) {
                fprintf(stderr, "gearsim-stiffness: --tangent-step must be in [0, 0.5]\n");
                return TOOL_USAGE;
            }
        } else if (!strcmp(a, "--nearfield-depth") && has) {
            if (!parse_double(argv[++i], &o.nearfield_depth_mm) || !(o.nearfield_depth_mm > 0.0)) {
                fprintf(stderr, "gearsim-stiffness: --nearfield-depth must be a positive number (mm)\n");
                return TOOL_USAGE;
            }
            depth_set = true;
            o.nearfield = 1;
        } else if (!strcmp(a, "--nearfield"))
            o.nearfield = 1; /* on any mesh; the default (auto) on quadratic, unmodified ones */
        else if (!strcmp(a, "--no-nearfield") || !strcmp(a, "--plain"))
            plain = true;
        else if (!strcmp(a, "--fine"))
            o.fine = 1;
        else if (!strcmp(a, "--all-rows"))
            o.all_rows = 1;
        else if (!strcmp(a, "--all-dofs"))
            o.all_dofs = 1;
        else if (!strcmp(a, "--no-tangent"))
            o.tangent = 0;
        else if (!strcmp(a, "--json"))
            json = 1;
        else if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return 0;
        } else if (a[0] != '-' && !scene_path)
            scene_path = a;
        else {
            usage(stderr);
            return TOOL_USAGE;
        }
    }
    if (!scene_path) {
        usage(stderr);
        return TOOL_USAGE;
    }
    if (plain && depth_set) {
        fprintf(stderr, "gearsim-stiffness: --nearfield-depth sets the near-field correction, which --no-nearfield switches off\n");
        return TOOL_USAGE;
    }
    if (plain)
        o.nearfield = 0;
    gs_scene *s = tool_load_scene("gearsim-stiffness", scene_path);
    if (!s)
        return TOOL_FAIL;
    int mi = s->n_meshes > 0 ? 0 : -1;
    if (mesh) {
        mi = -1;
        for (int k = 0; k < s->n_meshes; k++)
            if (!strcmp(s->meshes[k].name, mesh))
                mi = k;
    }
    if (mi < 0) {
        fprintf(stderr, "gearsim-stiffness: %s: meshes: no mesh named '%s' (not_found)\n",
                scene_path, mesh ? mesh : "");
        gs_scene_free(&s);
        return TOOL_FAIL;
    }
    gs_stiffness_result r;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = gs_stiffness_analyse(s, mi, &o, &r, &d);
    if (e != GS_OK) {
        fprintf(stderr, "gearsim-stiffness: %s: %s (%s)\n", d.field, d.message, gs_errcode(e));
        gs_scene_free(&s);
        return TOOL_FAIL;
    }
    int rc = 0;
    if (out) {
        gs_diag_clear(&d);
        e = gs_stiffness_write_h5(out, s, &r, &d);
        if (e != GS_OK) {
            fprintf(stderr, "gearsim-stiffness: %s: %s (%s)\n", d.field, d.message, gs_errcode(e));
            rc = TOOL_FAIL;
        }
    }
    if (json)
        print_json(&r, s);
    else {
        print_table(&r, s);
        if (out && rc == 0)
            printf("wrote %s\n", out);
    }
    gs_stiffness_result_clear(&r);
    gs_scene_free(&s);
    return rc;
}
