/* SPDX-License-Identifier: MIT
 * Benchmark: speed against accuracy along the fidelity ladder (METHOD.md
 * section 7). On the moment-induced 30/20 pair (contact_drive) and on the
 * planetary train (planetary_contact), every level — kinematic, impact (pair
 * only), lumped with the default rectangular stiffness, lumped calibrated
 * from the FE model, compliant (rigid gears, tooth pairs through the patch
 * model), elastic gears in contact with the adaptive step (numerics.adaptive)
 * and with fixed steps — at several time steps (and mesh densities for
 * contact), one process. Each run covers the ramp and the
 * steady state; the figures are taken over the second half:
 *   cost      process CPU seconds per simulated second (the reduced
 *             bodies' one-off residual columns included)
 *   speed     mean speed of the output gear (closed form M0 ratio / c)
 *   ratio     mean speed ratio error against the tooth counts
 *   dte       dynamic transmission error amplitude: rms of the first mesh's
 *             TE about its mean, m (0 for kinematic): the kinematic
 *             line-of-action TE of the gears' rigid coordinates, the
 *             deflection a lumped or ltca mesh reports less the tooth
 *             errors it adds to it (steady_half.h, sh_te)
 *   force     peak force of the first mesh, N
 *   mesh      the dominant mesh-frequency response: amplitude of the first
 *             mesh's TE at the tooth-mesh order (one Fourier
 *             coefficient over the mesh phase z_A (theta_A - theta_C), A its
 *             gear on a fixed axis, C the mate's carrier if any: order
 *             tracking, so speed fluctuations do not smear it), m
 *   balance   worst energy balance residual / energy scale
 *   mean_te   (CSV) the mean of that deflection, m: the mean TE from the
 *             initial position, backlash closing included
 * and the errors of speed, dte, force and mesh against the reference: the
 * last row of the scene, the converged setting of docs/validation/data.md
 * (reduced bodies at h 1e-5 s, damped, on the mesh o2s3 for the pair and
 * o2r2 for the planetary train: within 1-2 % of the mesh limits; the pair's
 * peak force, which that step does not converge, against the same model's
 * at h = 2.5 us, 630.6 N, when the whole table runs). Output: a Markdown table on stdout and a CSV file
 * (argv[1], default tradeoff.csv) that `gearctl bench tradeoff` plots.
 * argv[2] (optional): a comma-separated list of levels; only those rows on
 * the default mesh run (`LEVEL:R`: the level's rows at refine R;
 * `LEVEL:sS`: at the default counts times S, the study's o2sS), the errors then
 * against the last row run (a partial table: e.g. "calibrated,contact" after
 * a change of the default mesh; "" for every row). argv[3] (optional): one
 * scene (contact_drive, planetary_contact, or a variant, tests/common/drive_variant.h: contact_drive_relief,
 * contact_drive_errors, contact_drive_pitch, contact_drive_runout, run only
 * when named). Every row is also printed to
 * stderr as it completes. The elastic levels: `contact` steps with
 * numerics.contact "closure_energy", `contact_seed` and `adaptive` with the
 * seed's scheme (CSV column `scheme`); `reduced` as `contact` with every
 * elastic gear the reduced body (bodies[i].reduction, static residual) with
 * f_max = 0.3 / h (15, 30, 60 kHz at 2e-5, 1e-5, 5e-6 s: near 1 / (2 pi h),
 * docs/validation/data.md). Every elastic row runs
 * with the study's damping (ELASTIC_ZETA at ELASTIC_FHZ on the elastic
 * gears' material); the rigid-gear meshes keep their default damping. */
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "../common/drive_variant.h"
#include "../common/steady_half.h"

typedef struct spec {
    const char *scene, *level;
    double h;
    int refine;
    double scale; /* counts scale of the order's default mesh (1: the default) */
} spec;

/* The damping of every elastic row (the convergence study's): Rayleigh,
 * 2 % at 9.2 kHz on the elastic gears' material (docs/validation/data.md).
 * Undamped, the tooth and body vibration a coarse step excites does not
 * settle and the DTE rms moves with h; the rigid-gear levels keep their
 * meshes' default damping (5 % of the mesh mode). */
#define ELASTIC_ZETA 0.02
#define ELASTIC_FHZ 9200.0

/* The contact scheme (numerics.contact) of a level's elastic rows:
 * `contact` steps with the energy-exact closure, `contact_seed` and
 * `adaptive` with the seed's scheme (the adaptive step's threshold is on
 * the seed's penetration); "" for the rigid-gear levels. */
static const char *scheme_of(const char *level)
{
    if (!strcmp(level, "contact") || !strcmp(level, "reduced"))
        return "closure_energy";
    if (!strcmp(level, "contact_seed") || !strcmp(level, "adaptive"))
        return "seed";
    return "";
}

typedef struct result {
    double cost, speed, ratio, dte, force, balance, mesh, mean;
    int ok;
} result;

/* The scene at a fidelity level. */
static gs_system *build(const spec *s)
{
    int var = !strncmp(s->scene, "contact_drive_", 14);
    json_object *root = json_tokener_parse(gs_scene_builtin(var ? "contact_drive" : s->scene));
    if (!root)
        return NULL;
    if (var)
        drive_variant(root, s->scene);
    const char *lv = s->level;
    /* adaptive: elastic gears in contact with numerics.adaptive (1 um, two
     * halvings of the row's h) */
    bool adaptive = !strcmp(lv, "adaptive"), contact = *scheme_of(lv) != '\0';
    json_object *bs = json_object_object_get(root, "bodies"), *ms = json_object_object_get(root, "meshes");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i), *t;
        if (json_object_object_get_ex(b, "type", &t) && !strcmp(json_object_get_string(t), "carrier"))
            continue;
        json_object_object_add(b, "model", json_object_new_string(contact ? "elastic" : "rigid"));
        if (!strcmp(lv, "reduced")) {
            json_object *rd = json_object_new_object();
            json_object_object_add(rd, "f_max_hz", json_object_new_double(0.3 / s->h));
            json_object_object_add(b, "reduction", rd);
        }
        if (contact && (s->refine > 0 || s->scale != 1)) {
            /* refine R, or the order's default counts times the scale
             * (dyn_convergence_run's --scale: grading kept) */
            json_object *m = json_object_new_object();
            json_object_object_add(m, "refine", json_object_new_int(s->refine));
            if (s->scale != 1) {
                gs_gear_mesh_opts def;
                gs_gear_mesh_opts_for_order(&def, 2);
                json_object_object_add(m, "order", json_object_new_int(2));
                json_object_object_add(m, "flank", json_object_new_int((int)lround(def.flank * s->scale)));
                json_object_object_add(m, "across", json_object_new_int((int)lround(def.across * s->scale)));
                json_object_object_add(m, "rim", json_object_new_int((int)lround(def.rim * s->scale)));
            }
            json_object_object_add(b, "mesh", m);
        }
        if (contact || !strcmp(lv, "ltca")) {
            /* the elastic rows' material damping; an ltca mesh damps its
             * mesh mode as that material does (docs/explanation/ltca.md) */
            json_object *mat;
            if (!json_object_object_get_ex(b, "material", &mat)) {
                mat = json_object_new_object();
                json_object_object_add(b, "material", mat);
            }
            json_object_object_del(mat, "damping_s");
            json_object_object_add(mat, "damping_ratio", json_object_new_double(ELASTIC_ZETA));
            json_object_object_add(mat, "damping_hz", json_object_new_double(ELASTIC_FHZ));
        }
    }
    for (size_t i = 0; i < json_object_array_length(ms); i++) {
        json_object *m = json_object_array_get_idx(ms, i);
        static const char *const drop[] = {"stiffness", "damping", "damping_ratio", "backlash_mm", "passes",
                                           "constrain", "friction", "restitution", "law", NULL};
        for (const char *const *k = drop; *k; k++)
            json_object_object_del(m, *k);
        if (!strcmp(lv, "calibrated")) {
            json_object_object_add(m, "model", json_object_new_string("lumped"));
            json_object *st = json_object_new_object();
            json_object_object_add(st, "type", json_object_new_string("calibrated"));
            json_object_object_add(m, "stiffness", st);
        } else {
            json_object_object_add(m, "model", json_object_new_string(contact ? "contact" : lv));
        }
    }
    json_object *num = json_object_object_get(root, "numerics");
    json_object_object_add(num, "time_step", json_object_new_double(s->h));
    if (contact)
        json_object_object_add(num, "contact", json_object_new_string(scheme_of(lv)));
    if (adaptive) {
        json_object *ad = json_object_new_object();
        json_object_object_add(ad, "penetration_um", json_object_new_double(1.0));
        json_object_object_add(ad, "levels", json_object_new_int(2));
        json_object_object_add(num, "adaptive", ad);
    }
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc;
    gs_diag d;
    gs_system *sys = NULL;
    if (gs_scene_parse(txt, strlen(txt), &sc, &d) != GS_OK || gs_system_new(sc, 0, 1, &sys, &d) != GS_OK) {
        fprintf(stderr, "# %s %s h %g: %s: %s\n", s->scene, lv, s->h, d.field, d.message);
        sys = NULL;
    }
    json_object_put(root);
    return sys;
}

static result run(const spec *s, double duration, const char *out_body, const char *in_body, double ratio_expect)
{
    result r = {0};
    gs_system *sys = build(s);
    if (!sys)
        return r;
    int o = gs_scene_find_body(sys->scene, out_body), in = gs_scene_find_body(sys->scene, in_body);
    steady_half w = sh_start((int)lround(duration / s->h), o);
    int n = w.n, half = w.half;
    double th_i = 0;
    /* The mesh phase of the first mesh: its gear on a fixed axis (A), the
     * mate's carrier (C) when the mate is a planet. */
    const gs_scene_mesh *m0 = &sys->scene->meshes[0];
    int ga = m0->gear[0], gb = m0->gear[1];
    if (sys->scene->bodies[ga].joint == GS_JOINT_ON_CARRIER) {
        int t = ga;
        ga = gb;
        gb = t;
    }
    int gc = sys->scene->bodies[gb].joint == GS_JOINT_ON_CARRIER ? sys->scene->bodies[gb].carrier : -1;
    double za = sys->scene->bodies[ga].gear.teeth, xc = 0, xs = 0, c1 = 0, s1 = 0;
    double t0 = gs_cpu_now();
    for (int i = 0; i < n; i++) {
        if (i == n - half)
            th_i = gs_system_angle(sys, in);
        if (!sh_step(&w, sys, i)) {
            gs_system_free(&sys);
            return r;
        }
        if (sh_in_half(&w, i)) {
            double x = sh_te(sys);
            double ph = za * (gs_system_angle(sys, ga) - (gc >= 0 ? gs_system_angle(sys, gc) : 0.0));
            xc += x * cos(ph);
            xs += x * sin(ph);
            c1 += cos(ph);
            s1 += sin(ph);
        }
    }
    double cpu = gs_cpu_now() - t0, T = half * s->h;
    r.cost = cpu / duration;
    r.speed = fabs(gs_system_angle(sys, o) - w.th0) / T;
    r.ratio = fabs((gs_system_angle(sys, in) - th_i) / (gs_system_angle(sys, o) - w.th0)) / ratio_expect - 1;
    double mean = sh_mean(&w);
    r.dte = sh_rms(&w);
    r.mean = mean;
    r.mesh = 2.0 / half * hypot(xc - mean * c1, xs - mean * s1);
    r.force = w.fpeak;
    r.balance = w.worst / w.scale;
    r.ok = 1;
    gs_system_free(&sys);
    return r;
}

static double rel(double a, double ref)
{
    return ref != 0 ? fabs(a - ref) / fabs(ref) : fabs(a);
}

/* Is the row in the comma-separated list `list`? An entry `LEVEL` names
 * the level's rows on the default mesh (refine 0, counts scale 1),
 * `LEVEL:R` those at refine R, `LEVEL:sS` those at counts scale S
 * (refine 0: the convergence study's o2sS). */
static int row_listed(const char *list, const spec *s)
{
    size_t n = strlen(s->level);
    int plain = s->scale == 1;
    for (const char *p = list; p && *p; p = strchr(p, ',') ? strchr(p, ',') + 1 : NULL) {
        if (strncmp(p, s->level, n))
            continue;
        if ((p[n] == ',' || p[n] == '\0') && s->refine == 0 && plain)
            return 1;
        if (p[n] == ':' && p[n + 1] == 's' && s->refine == 0 && fabs(atof(p + n + 2) - s->scale) < 1e-9)
            return 1;
        if (p[n] == ':' && p[n + 1] != 's' && atoi(p + n + 1) == s->refine && plain)
            return 1;
    }
    return 0;
}

/* Is the row skipped: not in the level list, or of another scene? (The
 * variants of contact_drive run only when named.) */
static int skipped(const char *only, const char *scene, const spec *s)
{
    return (only && *only && !row_listed(only, s)) || (scene && strcmp(scene, s->scene)) ||
           (!scene && !strncmp(s->scene, "contact_drive_", 14));
}

int main(int argc, char **argv)
{
    const char *csv = argc > 1 ? argv[1] : "tradeoff.csv";
    const char *only = argc > 2 ? argv[2] : NULL, *scene = argc > 3 ? argv[3] : NULL;
    FILE *f = fopen(csv, "w");
    if (!f) {
        perror(csv);
        return 1;
    }
    fprintf(f, "scene,level,h,refine,cost,speed,ratio_err,dte,force,balance,mesh,err_speed,err_dte,err_force,err_mesh,scheme,scale,zeta,mean_te\n");
    const spec pair[] = {
        {"contact_drive", "kinematic", 1e-4, 0, 1},  {"contact_drive", "kinematic", 1e-5, 0, 1},
        {"contact_drive", "kinematic", 1e-6, 0, 1},  {"contact_drive", "impact", 1e-4, 0, 1},
        {"contact_drive", "impact", 1e-5, 0, 1},     {"contact_drive", "impact", 1e-6, 0, 1},
        {"contact_drive", "lumped", 1e-4, 0, 1},     {"contact_drive", "lumped", 1e-5, 0, 1},
        {"contact_drive", "lumped", 1e-6, 0, 1},     {"contact_drive", "calibrated", 1e-4, 0, 1},
        {"contact_drive", "calibrated", 1e-5, 0, 1}, {"contact_drive", "calibrated", 1e-6, 0, 1},
        {"contact_drive", "compliant", 1e-4, 0, 1},  {"contact_drive", "compliant", 1e-5, 0, 1},
        {"contact_drive", "compliant", 1e-6, 0, 1},  {"contact_drive", "ltca", 1e-4, 0, 1},
        {"contact_drive", "ltca", 1e-5, 0, 1},       {"contact_drive", "ltca", 1e-6, 0, 1},
        {"contact_drive", "adaptive", 2e-5, 0, 1},
        {"contact_drive", "adaptive", 1e-5, 0, 1},   {"contact_drive", "contact_seed", 2e-5, 0, 1},
        {"contact_drive", "contact_seed", 1e-5, 0, 1}, {"contact_drive", "reduced", 2e-5, 0, 1},
        {"contact_drive", "reduced", 1e-5, 0, 1},    {"contact_drive", "reduced", 5e-6, 0, 1},
        {"contact_drive", "contact", 2e-5, 0, 1},
        {"contact_drive", "contact", 1e-5, 0, 1},    {"contact_drive", "contact", 5e-6, 0, 1},
        {"contact_drive", "contact", 1e-5, 1, 1},    {"contact_drive", "contact", 5e-6, 1, 1},
        {"contact_drive", "reduced", 1e-5, 2, 1},    /* o2r2: the mesh limit's other side */
        {"contact_drive", "reduced", 1e-5, 0, 3}, /* the reference: o2s3 */
    };
    const spec plan[] = {
        {"planetary_contact", "kinematic", 1e-4, 0, 1},  {"planetary_contact", "kinematic", 1e-5, 0, 1},
        {"planetary_contact", "kinematic", 1e-6, 0, 1},  {"planetary_contact", "lumped", 1e-4, 0, 1},
        {"planetary_contact", "lumped", 1e-5, 0, 1},     {"planetary_contact", "lumped", 1e-6, 0, 1},
        {"planetary_contact", "calibrated", 1e-4, 0, 1}, {"planetary_contact", "calibrated", 1e-5, 0, 1},
        {"planetary_contact", "calibrated", 1e-6, 0, 1}, {"planetary_contact", "compliant", 1e-4, 0, 1},
        {"planetary_contact", "compliant", 1e-5, 0, 1},  {"planetary_contact", "compliant", 1e-6, 0, 1},
        {"planetary_contact", "ltca", 1e-4, 0, 1},       {"planetary_contact", "ltca", 1e-5, 0, 1},
        {"planetary_contact", "ltca", 1e-6, 0, 1},
        {"planetary_contact", "adaptive", 2e-5, 0, 1},   {"planetary_contact", "adaptive", 1e-5, 0, 1},
        {"planetary_contact", "contact_seed", 2e-5, 0, 1}, {"planetary_contact", "contact_seed", 1e-5, 0, 1},
        {"planetary_contact", "reduced", 2e-5, 0, 1},    {"planetary_contact", "reduced", 1e-5, 0, 1},
        {"planetary_contact", "reduced", 5e-6, 0, 1},    {"planetary_contact", "contact", 2e-5, 0, 1},
        {"planetary_contact", "contact", 1e-5, 0, 1},    {"planetary_contact", "contact", 5e-6, 0, 1},
        {"planetary_contact", "reduced", 1e-5, 0, 3}, /* o2s3 */
        {"planetary_contact", "reduced", 1e-5, 2, 1},    /* the reference: o2r2 */
    };
    const spec relief[] = {
        {"contact_drive_relief", "ltca", 1e-4, 0, 1}, {"contact_drive_relief", "ltca", 1e-5, 0, 1},
        {"contact_drive_relief", "reduced", 1e-5, 0, 3}, /* the reference: o2s3 */
    };
    const spec errs[] = {
        {"contact_drive_errors", "ltca", 1e-4, 0, 1}, {"contact_drive_errors", "ltca", 1e-5, 0, 1},
        {"contact_drive_errors", "reduced", 1e-5, 0, 3}, /* the reference: o2s3 */
    };
    const spec pitch[] = {
        {"contact_drive_pitch", "ltca", 1e-5, 0, 1},
        {"contact_drive_pitch", "reduced", 1e-5, 0, 3}, /* the reference: o2s3 */
    };
    const spec runout[] = {
        {"contact_drive_runout", "ltca", 1e-5, 0, 1},
        {"contact_drive_runout", "reduced", 1e-5, 0, 3}, /* the reference: o2s3 */
    };
    struct set {
        const char *title;
        const spec *s;
        int n;
        double duration;
        const char *out, *in;
        double ratio, speed_expect;
        double force_ref; /* the peak force the force errors are against, N (0: the reference row's) */
    } sets[] = {
        /* contact_drive's peak force converged in h: the reference's model
         * (reduced bodies on o2s3, f_max 30 kHz, the same damping) at h =
         * 2.5 us, within 0.4 % of 5 us (docs/data/dyn_convergence_pair_levels.csv,
         * docs/explanation/ltca.md "Peak mesh force"); the reference row's own
         * peak at 1e-5 s is 4 % above it */
        {"30/20 pair, moment-induced (contact_drive), 60 ms", pair, (int)(sizeof pair / sizeof pair[0]), 0.06,
         "pinion", "wheel", 20.0 / 30.0, 20.0 * (20.0 / 30.0) / 0.3, 630.553},
        {"planetary 24/24/72 (planetary_contact), 50 ms", plan, (int)(sizeof plan / sizeof plan[0]), 0.05,
         "carrier", "sun", 4.0, 10.0, 0},
        {"30/20 pair with tip relief (contact_drive_relief), 60 ms", relief, (int)(sizeof relief / sizeof relief[0]),
         0.06, "pinion", "wheel", 20.0 / 30.0, 20.0 * (20.0 / 30.0) / 0.3, 0},
        {"30/20 pair with pitch errors and run-out (contact_drive_errors), 60 ms", errs,
         (int)(sizeof errs / sizeof errs[0]), 0.06, "pinion", "wheel", 20.0 / 30.0, 20.0 * (20.0 / 30.0) / 0.3, 0},
        {"30/20 pair with pitch errors (contact_drive_pitch), 60 ms", pitch, (int)(sizeof pitch / sizeof pitch[0]),
         0.06, "pinion", "wheel", 20.0 / 30.0, 20.0 * (20.0 / 30.0) / 0.3, 0},
        {"30/20 pair with run-out (contact_drive_runout), 60 ms", runout, (int)(sizeof runout / sizeof runout[0]),
         0.06, "pinion", "wheel", 20.0 / 30.0, 20.0 * (20.0 / 30.0) / 0.3, 0},
    };
    printf("# bench_tradeoff: the fidelity ladder, speed against accuracy (one process)\n");
    for (size_t k = 0; k < sizeof sets / sizeof sets[0]; k++) {
        const struct set *st = &sets[k];
        result res[32];
        int last = st->n - 1, ran = 0;
        for (int i = 0; i < st->n; i++) {
            res[i].ok = 0;
            if (skipped(only, scene, &st->s[i]))
                continue;
            res[i] = run(&st->s[i], st->duration, st->out, st->in, st->ratio);
            last = i;
            ran++;
            fprintf(stderr, "# %s %s h %g refine %d scale %g: %s; cost %.4g speed %.6f ratio %.2e dte %.4e force %.1f "
                    "balance %.1e mesh %.4e mean %.5e\n", st->s[i].scene, st->s[i].level, st->s[i].h, st->s[i].refine,
                    st->s[i].scale, res[i].ok ? "done" : "failed", res[i].cost, res[i].speed, res[i].ratio,
                    res[i].dte, res[i].force, res[i].balance, res[i].mesh, res[i].mean);
        }
        if (!ran)
            continue;
        const result *ref = &res[last];
        printf("\n## %s\n\nreference: the last row (richest model, finest setting); closed-form output speed "
               "%.4f rad/s\n\n", st->title, st->speed_expect);
        double fref = st->force_ref > 0 && !(only && *only) ? st->force_ref : ref->force;
        if (fref != ref->force)
            printf("peak force errors against %.1f N, the reference's model converged in the step\n\n", fref);
        printf("| level | h (s) | refine | scale | CPU s per sim. s | output speed (rad/s) | ratio error | DTE rms (m) | "
               "peak mesh force (N) | balance / scale | mesh-order amplitude (m) | speed err vs ref | DTE err vs ref | "
               "force err vs ref | mesh-order err vs ref |\n");
        printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        for (int i = 0; i < st->n; i++) {
            const spec *s = &st->s[i];
            const result *r = &res[i];
            if (skipped(only, scene, s))
                continue;
            if (!r->ok) {
                printf("| %s | %g | %d | %g | failed | | | | | | | | | | |\n", s->level, s->h, s->refine,
                       s->scale);
                continue;
            }
            double es = rel(r->speed, ref->speed), ed = rel(r->dte, ref->dte), ef = rel(r->force, fref);
            double em = rel(r->mesh, ref->mesh);
            printf("| %s | %g | %d | %g | %.4g | %.5f | %.2e | %.3e | %.1f | %.1e | %.3e | %.2e | %.2e | %.2e | %.2e |\n",
                   s->level, s->h, s->refine, s->scale, r->cost, r->speed, r->ratio, r->dte, r->force, r->balance,
                   r->mesh, es, ed, ef, em);
            fprintf(f, "%s,%s,%g,%d,%.6g,%.8g,%.6g,%.6g,%.6g,%.3g,%.6g,%.6g,%.6g,%.6g,%.6g,%s,%g,%g,%.7g\n", s->scene,
                    s->level, s->h, s->refine, r->cost, r->speed, r->ratio, r->dte, r->force, r->balance, r->mesh, es, ed,
                    ef, em, scheme_of(s->level), s->scale,
                    *scheme_of(s->level) || !strcmp(s->level, "ltca") ? ELASTIC_ZETA : 0.0, r->mean);
        }
    }
    fclose(f);
    printf("\nCSV: %s\n", csv);
    return 0;
}
