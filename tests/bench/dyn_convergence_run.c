/* SPDX-License-Identifier: MIT
 * One run of the dynamic convergence study (docs/validation/data.md; driven by
 * tests/bench/dyn_convergence.py): a
 * scene with `contact` meshes (a builtin name, a variant of contact_drive of
 * the trade-off table, tests/common/drive_variant.h, or a file) at one time step,
 * mesh level, contact treatment and material damping, run from rest to
 * --to; over the whole cycles of the first mesh from --from on it prints
 * one JSON line: kinematic TE mean and rms about the mean (DTE), peak and
 * mean mesh force, deepest penetration, largest strain energy against its
 * mean (locking indicators), mean speed ratio of the loaded bodies (the
 * ramp-driven input over the braked output), the worst energy balance
 * residual over the run against the energy scale, the elastic unknowns and
 * the CPU seconds of the process per simulated second.
 *
 *   dyn_convergence_run SCENE [--h 1e-5] [--order 2] [--refine 0]
 *       [--scale 1] [--contact closure_energy] [--zeta 0 --fhz 9200]
 *       [--from 0.04] [--to 0.08] [--fmax F] [--residual static|midpoint]
 *
 * --scale multiplies the flank/across/rim counts of the order's default
 * mesh (rounded; grading kept) on every elastic gear. --fmax F makes every
 * elastic gear the reduced body with the modes up to F Hz (reduction.f_max_hz;
 * --residual its residual rule, default the scene's default "static");
 * setup_cpu_s is the system's construction (modes, factor), and
 * step_cpu_per_sim_s the cost per simulated second without it;
 * column_cpu_s the reduced bodies' residual columns computed during the run
 * (once per node that comes into contact: a one-off of a long run) and
 * step_nocol_cpu_per_sim_s the steps' cost without them; residual_loss_w the
 * mean power the static residual rule took over the run; column_nodes the
 * candidate nodes whose columns were computed, candidate_nodes all of them
 * (the columns stop at those that ever come into contact). Figures are taken
 * with tests/common/dyn_window.h. "meshes" lists, for every mesh of the
 * scene, the same TE and force figures over the first mesh's whole cycles
 * (in a planetary train every mesh has the same tooth-mesh frequency).
 * Not a test: runs take minutes. */
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/bench_args.h"
#include "../common/drive_variant.h"
#include "../common/dyn_window.h"
#include "../common/json_child.h"
#include "fe/fe_internal.h"
#include "gearsim/mesh.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"
#include "gearsim/util.h"

/* Kinematic TE and |force| of every mesh, per sample of the window. */
typedef struct per_mesh {
    double *te, *force; /* n_meshes x cap, sample-major */
    long n, cap;
    int nm;
} per_mesh;

static int pm_sample(per_mesh *p, const gs_system *s)
{
    if (p->n == p->cap) {
        long cap = p->cap ? 2 * p->cap : 8192;
        double *a = realloc(p->te, sizeof *a * (size_t)cap * (size_t)p->nm);
        if (!a)
            return -1;
        p->te = a;
        double *b = realloc(p->force, sizeof *b * (size_t)cap * (size_t)p->nm);
        if (!b)
            return -1;
        p->force = b, p->cap = cap;
    }
    for (int j = 0; j < p->nm; j++) {
        const gs_gmesh_rt *m = &s->meshes[j];
        double te = -m->s_ref;
        for (int k = 0; k < s->n_coords; k++)
            te += m->a[k] * s->q[k];
        p->te[p->n * p->nm + j] = te;
        p->force[p->n * p->nm + j] = fabs(m->force);
    }
    p->n++;
    return 0;
}

/* A number printed with format `fmt` in the JSON text. */
static json_object *jnum(double v, const char *fmt)
{
    char b[64];
    snprintf(b, sizeof b, fmt, v);
    return json_object_new_double_s(v, b);
}

/* The figures of every mesh over the first `used` samples, as a JSON array. */
static json_object *pm_json(const per_mesh *p, const gs_system *s, long used)
{
    json_object *arr = json_object_new_array();
    for (int j = 0; j < p->nm && used > 0; j++) {
        double sx = 0, fs = 0, fp = 0, lo = INFINITY, hi = -INFINITY;
        for (long i = 0; i < used; i++) {
            double te = p->te[i * p->nm + j], f = p->force[i * p->nm + j];
            sx += te, fs += f, fp = fmax(fp, f);
            lo = fmin(lo, te), hi = fmax(hi, te);
        }
        double mean = sx / (double)used, sxx = 0;
        for (long i = 0; i < used; i++) {
            double d = p->te[i * p->nm + j] - mean;
            sxx += d * d;
        }
        json_object *o = json_object_new_object();
        json_object_object_add(o, "name", json_object_new_string(s->scene->meshes[s->meshes[j].index].name));
        json_object_object_add(o, "dte_rms_um", jnum(1e6 * sqrt(sxx / (double)used), "%.6f"));
        json_object_object_add(o, "mean_te_um", jnum(1e6 * mean, "%.6f"));
        json_object_object_add(o, "te_pp_um", jnum(1e6 * (hi - lo), "%.5f"));
        json_object_object_add(o, "peak_force_n", jnum(fp, "%.3f"));
        json_object_object_add(o, "mean_force_n", jnum(fs / (double)used, "%.4f"));
        json_object_array_add(arr, o);
    }
    return arr;
}

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *t = malloc((size_t)n + 1);
    if (t && fread(t, 1, (size_t)n, f) != (size_t)n) {
        free(t);
        t = NULL;
    }
    if (t)
        t[n] = 0;
    fclose(f);
    return t;
}

int main(int argc, char **argv)
{
    const char *scene = NULL, *contact = "closure_energy";
    double h = 1e-5, scale = 1, zeta = 0, fhz = 9200, t0 = 0.04, t1 = 0.08, fmax = 0;
    const char *residual = NULL;
    int order = 2, refine = 0;
    const bench_opt opts[] = {
        {"--h", 'd', &h},
        {"--order", 'i', &order},
        {"--refine", 'i', &refine},
        {"--scale", 'd', &scale},
        {"--contact", 's', &contact},
        {"--zeta", 'd', &zeta},
        {"--fhz", 'd', &fhz},
        {"--from", 'd', &t0},
        {"--to", 'd', &t1},
        {"--fmax", 'd', &fmax},
        {"--residual", 's', &residual},
    };
    if (bench_args(argc, argv, &scene, opts, sizeof opts / sizeof *opts))
        return 2;
    if (!scene || !(h > 0) || !(t1 > t0 && t0 >= 0) || !(scale > 0) || (order != 1 && order != 2)) {
        fprintf(stderr, "usage: dyn_convergence_run SCENE [--h H] [--order 1|2] [--refine R] [--scale S] "
                        "[--contact seed|closure|closure_energy] [--zeta Z --fhz F] [--from T0] [--to T1]\n");
        return 2;
    }
    /* a builtin scene, a variant of contact_drive (the trade-off table's) or a file */
    int var = !gs_scene_builtin(scene) && drive_variant_name(scene);
    const char *builtin = gs_scene_builtin(var ? "contact_drive" : scene);
    char *txt = builtin ? strdup(builtin) : slurp(scene);
    json_object *root = txt ? json_tokener_parse(txt) : NULL;
    free(txt);
    if (root && var)
        drive_variant(root, scene);
    if (!root) {
        fprintf(stderr, "%s: not a builtin scene nor a readable JSON file\n", scene);
        return 2;
    }
    /* The mesh level, damping on every elastic gear; the loads' bodies. */
    gs_gear_mesh_opts def;
    gs_gear_mesh_opts_for_order(&def, order);
    int flank = (int)lround(def.flank * scale), across = (int)lround(def.across * scale),
        rim = (int)lround(def.rim * scale);
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i), *t;
        if (!json_object_object_get_ex(b, "model", &t) || strcmp(json_object_get_string(t), "elastic"))
            continue;
        json_object *m = tj_child(b, "mesh");
        json_object_object_add(m, "order", json_object_new_int(order));
        json_object_object_add(m, "refine", json_object_new_int(refine));
        if (scale != 1) {
            json_object_object_add(m, "flank", json_object_new_int(flank));
            json_object_object_add(m, "across", json_object_new_int(across));
            json_object_object_add(m, "rim", json_object_new_int(rim));
        }
        if (fmax > 0) /* the reduced body (docs/explanation/elastic_body.md "Reduced elastic body") */
            json_object_object_add(tj_child(b, "reduction"), "f_max_hz", json_object_new_double(fmax));
        if (fmax > 0 && residual)
            json_object_object_add(tj_child(b, "reduction"), "residual", json_object_new_string(residual));
        if (zeta > 0) {
            json_object *mat = tj_child(b, "material");
            json_object_object_add(mat, "damping_ratio", json_object_new_double(zeta));
            json_object_object_add(mat, "damping_hz", json_object_new_double(fhz));
        }
    }
    json_object *num = tj_child(root, "numerics");
    json_object_object_add(num, "time_step", json_object_new_double(h));
    json_object_object_add(num, "contact", json_object_new_string(contact));
    char in_name[GS_NAME_MAX] = "", out_name[GS_NAME_MAX] = "";
    json_object *ls = json_object_object_get(root, "loads");
    for (size_t i = 0; ls && i < json_object_array_length(ls); i++) {
        json_object *l = json_object_array_get_idx(ls, i), *t, *b;
        if (!json_object_object_get_ex(l, "type", &t) || !json_object_object_get_ex(l, "body", &b))
            continue;
        if (!strcmp(json_object_get_string(t), "brake"))
            snprintf(out_name, sizeof out_name, "%s", json_object_get_string(b));
        else if (!in_name[0])
            snprintf(in_name, sizeof in_name, "%s", json_object_get_string(b));
    }
    const char *st = json_object_to_json_string(root);
    gs_scene *sc = NULL;
    gs_diag d;
    if (gs_scene_parse(st, strlen(st), &sc, &d) != GS_OK) {
        fprintf(stderr, "scene: %s: %s\n", d.field, d.message);
        return 1;
    }
    json_object_put(root);
    long unknowns = 0;
    for (int i = 0; i < sc->n_bodies; i++) {
        const gs_scene_body *b = &sc->bodies[i];
        if (b->type != GS_BODY_GEAR || b->model != GS_MODEL_ELASTIC)
            continue;
        gs_mesh *m = NULL;
        if (gs_scene_gear_mesh(b, &m, &d) == GS_OK)
            unknowns += 2 * ((long)m->n_nodes - (long)m->n_fixed);
        gs_mesh_free(&m);
    }
    double c0 = gs_cpu_now();
    gs_system *s = NULL;
    if (gs_system_new(sc, 0, 1, &s, &d) != GS_OK) {
        fprintf(stderr, "system: %s: %s\n", d.field, d.message);
        return 1;
    }
    double c_setup = gs_cpu_now() - c0;
    int in = in_name[0] ? gs_scene_find_body(s->scene, in_name) : -1;
    int out = out_name[0] ? gs_scene_find_body(s->scene, out_name) : -1;
    dyn_window w = {0};
    per_mesh pm = {.nm = s->n_meshes};
    long steps = 0;
    while (s->time < t1 - 0.5 * s->h) {
        if (gs_step_serial(s) != GS_OK) {
            fprintf(stderr, "t %.6f: %s: %s\n", s->time, s->diag.field, s->diag.message);
            return 1;
        }
        steps++;
        dw_energy(&w, s);
        if (s->time >= t0 - 0.5 * s->h && (dw_sample(&w, s, 0, in, out) != 0 || pm_sample(&pm, s) != 0)) {
            fprintf(stderr, "out of memory\n");
            return 1;
        }
    }
    double cpu = gs_cpu_now() - c0;
    /* the reduced bodies' own figures, summed */
    double col_cpu = 0, res_loss = 0;
    long col_nodes = 0, cand_nodes = 0;
    for (int i = 0; i < s->n_bodies; i++) {
        gs_fe_reduced_info ri;
        if (gs_elastic_reduced_info(&s->bodies[i], &ri)) {
            col_cpu += ri.column_cpu_s;
            res_loss += ri.residual_loss;
            col_nodes += (long)ri.cached_nodes;
            cand_nodes += (long)(ri.rows - 1) / 2;
        }
    }
    dyn_figures f;
    if (dw_finish(&w, &f) != 0) {
        fprintf(stderr, "the window [%g, %g] s holds no whole mesh cycle\n", t0, t1);
        return 1;
    }
    json_object *pmj = pm_json(&pm, s, f.used);
    printf("{\"scene\": \"%s\", \"h\": %.6g, \"order\": %d, \"refine\": %d, \"scale\": %.4g, \"flank\": %d, "
           "\"across\": %d, \"rim\": %d, \"unknowns\": %ld, \"contact\": \"%s\", \"zeta\": %.4g, \"fhz\": %.6g, "
           "\"from\": %.5g, \"to\": %.5g, \"cycles\": %d, \"mesh_hz\": %.3f, \"dte_rms_um\": %.6f, "
           "\"mean_te_um\": %.6f, \"te_pp_um\": %.5f, \"peak_force_n\": %.3f, \"mean_force_n\": %.4f, "
           "\"ratio\": %.8f, \"balance_rel\": %.3e, \"pen_max_um\": %.6f, \"force_peak_over_mean\": %.4f, "
           "\"strain_max_mj\": %.5f, \"strain_mean_mj\": %.5f, \"strain_max_over_mean\": %.4f, "
           "\"contact_work_j\": %.3e, \"steps\": %ld, \"cpu_s\": %.2f, \"cpu_per_sim_s\": %.2f, \"fmax_hz\": %.6g, "
           "\"setup_cpu_s\": %.2f, \"step_cpu_per_sim_s\": %.2f, \"column_cpu_s\": %.2f, "
           "\"step_nocol_cpu_per_sim_s\": %.2f, \"residual_loss_w\": %.4g, \"column_nodes\": %ld, "
           "\"candidate_nodes\": %ld, \"meshes\": %s}\n",
           scene, h, order, refine, scale, (int)(s->scene->bodies[0].mesh.flank),
           (int)(s->scene->bodies[0].mesh.across), (int)(s->scene->bodies[0].mesh.rim), unknowns, contact, zeta,
           fhz, t0, t1, f.cycles, f.mesh_hz, f.te_rms * 1e6, f.te_mean * 1e6, f.te_pp * 1e6, f.f_peak, f.f_mean,
           f.ratio, f.balance_rel, f.pen_max * 1e6, f.f_mean > 0 ? f.f_peak / f.f_mean : 0, f.strain_max * 1e3,
           f.strain_mean * 1e3, f.strain_mean > 0 ? f.strain_max / f.strain_mean : 0, w.contact_work, steps, cpu,
           cpu / s->time, fmax, c_setup, (cpu - c_setup) / s->time, col_cpu,
           (cpu - c_setup - col_cpu) / s->time, res_loss / s->time, col_nodes, cand_nodes,
           json_object_to_json_string_ext(pmj, JSON_C_TO_STRING_PLAIN));
    json_object_put(pmj);
    free(pm.te);
    free(pm.force);
    dw_free(&w);
    gs_system_free(&s);
    return 0;
}
