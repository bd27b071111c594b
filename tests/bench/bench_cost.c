/* SPDX-License-Identifier: MIT
 * Benchmark: the cost of a step of elastic gears in tooth contact against
 * its floor (prints only; not a pass/fail test). The floor is one bare
 * CHOLMOD solve per gear on that gear's own factor (METHOD.md section 4:
 * the free motion needs one solve per body and step, everything else —
 * search, compliance blocks, QP, back-substitution — is what the design
 * adds on top). At -n k the floor is the largest sum of bare solves over
 * the gears one rank owns.
 *
 * For contact_drive (the 30/20 pair; on its default quadratic mesh and
 * again with linear triangles, mesh.order 1) and planetary_contact (five
 * elastic gears, six contact meshes) at their scene step: a warm-up (the ramp, the
 * first teeth into mesh), then a timed chunk through the engine, as the
 * daemon steps it, and the rank-0 breakdown (docs/performance/index.md).
 *
 *   bench_cost                    one rank
 *   mpirun -n 2 bench_cost        two ranks
 *   bench_cost quick              shorter chunks
 *   bench_cost full|quick SCENE   one of the two scenes only ("all": both)
 *   bench_cost full|quick SCENE SCHEME   with numerics.contact SCHEME
 *                                 (seed, closure, closure_energy)
 *   bench_cost count SCENE [STEPS]  instruction counts under callgrind
 *                                 (count_case; one scene)
 *   mpirun -n K bench_cost weak N   planetary_contact made a 36/24/84 train
 *                                 with N planets (3 to 6; weak scaling:
 *                                 K = N + 2 is one gear per rank)
 *
 * RESULT_PATH and the rounds' "critical path" read the engine's CPU
 * critical path (gs_step_timing cpu_path): at -n 2 on a loaded machine the
 * CPU of rank 0 counts its spinning in the collectives while the other
 * rank is descheduled; the path counts work only.
 *
 * Run by `meson test -C build --benchmark --suite bench cost` (both rank
 * counts). Wall times are ratios within one run on a shared machine. */
#define _GNU_SOURCE /* RUSAGE_THREAD */
#include <json-c/json.h>
#include <mpi.h>
#include <stdio.h>
#include <sys/resource.h>
#include <time.h>
#include <stdlib.h>
#include <string.h>

#if defined(__has_include)
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h> /* count mode: instrument from the counted steps on (no-op outside valgrind) */
#endif
#endif
#ifndef CALLGRIND_START_INSTRUMENTATION
#define CALLGRIND_START_INSTRUMENTATION
#endif
#include "fe/fe_internal.h"
#include "gearsim/engine.h"
#include "gearsim/fe.h"
#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/util.h"

/* CPU seconds of this thread: on a shared machine the wall clock also
 * counts the time other processes held the core. */
static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* User-mode CPU seconds of this thread: without the kernel's time (on a
 * virtual machine under load, interrupts and page work land there). */
static double user_now(void)
{
    struct rusage ru;
    getrusage(RUSAGE_THREAD, &ru);
    return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec;
}

typedef struct bcase {
    const char *scene;
    int warm, steps;
    int order; /* element order forced on the elastic gears; 0: the scene's (default 2) */
    int planets; /* planetary_contact with this many planets; 0: the scene's */
} bcase;

/* A copy of `tmpl` (a JSON object) with every string value equal to `from`
 * and every string in an array equal to it replaced by `to`, and "name"
 * strings containing it rewritten (sun-planet1 -> sun-planet4). */
static json_object *renamed(json_object *tmpl, const char *from, const char *to)
{
    json_object *o = NULL;
    json_object_deep_copy(tmpl, &o, NULL);
    json_object_object_foreach(o, key, val) {
        if (json_object_is_type(val, json_type_string)) {
            const char *v = json_object_get_string(val), *at = strstr(v, from);
            if (at) {
                char buf[128];
                snprintf(buf, sizeof buf, "%.*s%s%s", (int)(at - v), v, to, at + strlen(from));
                json_object_object_add(o, key, json_object_new_string(buf));
            }
        } else if (json_object_is_type(val, json_type_array)) {
            for (size_t i = 0; i < json_object_array_length(val); i++) {
                json_object *x = json_object_array_get_idx(val, i);
                if (json_object_is_type(x, json_type_string) && !strcmp(json_object_get_string(x), from))
                    json_object_array_put_idx(val, i, json_object_new_string(to));
            }
        }
    }
    return o;
}

/* Set integer field `key` of the body named `name`. */
static void set_body(json_object *root, const char *name, const char *key, double v)
{
    json_object *bodies, *nm;
    json_object_object_get_ex(root, "bodies", &bodies);
    for (size_t i = 0; i < json_object_array_length(bodies); i++) {
        json_object *b = json_object_array_get_idx(bodies, i);
        if (json_object_object_get_ex(b, "name", &nm) && !strcmp(json_object_get_string(nm), name))
            json_object_object_add(b, key, v == (int)v ? json_object_new_int((int)v) : json_object_new_double(v));
    }
}

/* planetary_contact turned into a train for 3 to 6 planets, n of them: sun
 * 36, planets 24 (as in the scene), ring 84 teeth (36 + 84 = 120 teeth are
 * shared out by 3, 4, 5 and 6 equally spaced planets; six planets of 24
 * teeth clear one another on the 75 mm carrier radius), the ring's rim
 * radius moved with its teeth (the same rim thickness). The bodies, carrier
 * joints and meshes of planet1 are copied at 360 k / n degrees. */
static void set_planets(json_object *root, int n)
{
    set_body(root, "sun", "teeth", 36);
    set_body(root, "ring", "teeth", 84);
    set_body(root, "ring", "hub_radius_mm", 115);
    static const char *const keys[] = {"bodies", "joints", "meshes"};
    for (int a = 0; a < 3; a++) {
        json_object *arr, *out = json_object_new_array();
        json_object_object_get_ex(root, keys[a], &arr);
        json_object *t1 = NULL, *t2 = NULL; /* planet1's entries (two meshes per planet) */
        bool placed = false;
        for (size_t i = 0; i < json_object_array_length(arr); i++) {
            json_object *x = json_object_array_get_idx(arr, i), *nm;
            const char *name = json_object_object_get_ex(x, a == 1 ? "body" : "name", &nm) ?
                               json_object_get_string(nm) : "";
            if (!strstr(name, "planet")) {
                json_object_array_add(out, json_object_get(x));
                continue;
            }
            if (strstr(name, "planet1"))
                *(t1 ? &t2 : &t1) = x;
            if (!placed && t1 && (a < 2 || t2)) {
                placed = true;
                for (int k = 1; k <= n; k++) {
                    char to[32];
                    snprintf(to, sizeof to, "planet%d", k % 100);
                    for (json_object *t = t1; t; t = t == t1 && a == 2 ? t2 : NULL) {
                        json_object *c = renamed(t, "planet1", to);
                        if (a == 1) {
                            json_object_object_add(c, "angle_deg", json_object_new_double(360.0 * (k - 1) / n));
                            json_object_object_add(c, "radius_mm", json_object_new_double(75.0));
                        }
                        json_object_array_add(out, c);
                    }
                }
            }
        }
        json_object_object_add(root, keys[a], out);
    }
}

/* Set mesh.order of every elastic body of a parsed scene. */
static void force_order(json_object *root, int order)
{
    json_object *bodies, *model, *mesh;
    if (order <= 0 || !json_object_object_get_ex(root, "bodies", &bodies))
        return;
    for (size_t i = 0; i < json_object_array_length(bodies); i++) {
        json_object *b = json_object_array_get_idx(bodies, i);
        if (!json_object_object_get_ex(b, "model", &model) ||
            strcmp(json_object_get_string(model), "elastic") != 0)
            continue;
        if (!json_object_object_get_ex(b, "mesh", &mesh)) {
            mesh = json_object_new_object();
            json_object_object_add(b, "mesh", mesh);
        }
        json_object_object_add(mesh, "order", json_object_new_int(order));
    }
}

/* A gear's bare FE body for the floors: its own mesh, model and factor at
 * step h, the same mesh, material and step matrix as its owner's. */
typedef struct gear_fe {
    gs_mesh *mesh;
    gs_fe_model *m;
    gs_fe_body *b;
} gear_fe;

static void gear_fe_free(gear_fe *g)
{
    gs_fe_body_free(&g->b);
    gs_fe_model_free(&g->m);
    gs_mesh_free(&g->mesh);
}

/* False on failure (what was made is freed by gear_fe_free). */
static bool gear_fe_new(const gs_scene_body *sb, double h, gear_fe *g)
{
    gs_diag d;
    *g = (gear_fe){0};
    return gs_scene_gear_mesh(sb, &g->mesh, &d) == GS_OK &&
           gs_fe_model_new(g->mesh, &sb->material, sb->gear.face_width_m, 1e-6, &g->m) == GS_OK &&
           gs_fe_body_new(g->m, &g->b) == GS_OK && gs_fe_body_set_step(g->b, h, 0.0) == GS_OK;
}

/* CPU seconds per round of `reps` rounds, each gear g[0..ng) solved once
 * per round, in that order and back again in the next round (as the step
 * takes them, src/step/step.c records); negative on failure. */
static double solves_in_turn(gear_fe *g, int ng, int reps)
{
    bool ok = true;
    double c0 = cpu_now();
    for (int r = 0; r < reps && ok; r++)
        for (int k = 0; k < ng && ok; k++)
            ok = gsi_fe_body_time_bare_solve(g[r & 1 ? ng - 1 - k : k].b, 1) >= 0;
    return ok ? (cpu_now() - c0) / reps : -1;
}

/* Seconds per bare solve on a fresh factor of body i's model at the scene's
 * step (the same mesh, material and step matrix as its owner's): wall
 * clock, and CPU time in *cpu. */
static double bare_solve(const gs_system *sys, int i, int reps, double *cpu, double *user)
{
    gear_fe g;
    double t = -1;
    if (gear_fe_new(&sys->scene->bodies[i], sys->h, &g)) {
        double c0 = cpu_now(), u0 = user_now();
        t = gsi_fe_body_time_bare_solve(g.b, reps);
        *cpu = (cpu_now() - c0) / reps;
        *user = (user_now() - u0) / reps;
    }
    gear_fe_free(&g);
    return t;
}

/* CPU seconds per round of bare solves over the gears rank `rank` owns,
 * each gear once per round as a step takes them (solves_in_turn): each
 * factor is then evicted by the others' (on the planetary train five
 * factors of about 1 MB against a 1 MB L2 cache), which the hot loop of
 * bare_solve never sees. Informative: the floor is bare_solve's. */
static double interleaved_floor(const gs_system *sys, int rank, int reps)
{
    enum { MAXG = 16 };
    gear_fe g[MAXG];
    int ng = 0;
    bool ok = true;
    for (int i = 0; i < sys->n_bodies && ok; i++) {
        const gs_body_rt *br = &sys->bodies[i];
        if (!br->ops->state_size || br->owner != rank || ng == MAXG)
            continue;
        ok = gear_fe_new(&sys->scene->bodies[i], sys->h, &g[ng++]);
    }
    double t = ok && ng > 0 ? solves_in_turn(g, ng, reps) : -1;
    for (int k = 0; k < ng; k++)
        gear_fe_free(&g[k]);
    return t;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The CPU ratio taken in rounds: a chunk of steps through the engine, then
 * the floor's bare solves (each gear `reps` times on a fresh factor, summed
 * per owning rank, the largest sum), alternately, so that the step and its
 * floor see the same load on a shared machine. Prints each round's ratio
 * and returns their median (negative on failure). */
static double rounds_ratio(gs_engine *e, const bcase *c, int size, int rounds, int64_t steps, int reps)
{
    enum { MAXG = 16, MAXR = 16 };
    gs_system *sys = gs_engine_system(e);
    gear_fe gb[MAXG];
    int owner[MAXG], ng = 0;
    gs_diag d;
    bool ok = rounds <= MAXR;
    for (int i = 0; i < sys->n_bodies && ok; i++) {
        const gs_body_rt *br = &sys->bodies[i];
        if (!br->ops->state_size || ng == MAXG)
            continue;
        owner[ng] = br->owner;
        ok = gear_fe_new(&sys->scene->bodies[i], sys->h, &gb[ng++]);
    }
    double ratio[MAXR], pratio[MAXR], med = -1;
    for (int r = 0; r < rounds && ok; r++) {
        int64_t n = steps, done = 0;
        gs_step_timing t0, t1;
        gs_engine_timing(e, &t0);
        double c0 = cpu_now();
        ok = gs_engine_run(e, GS_OP_STEP, &n, sizeof n, &d, &done) == GS_OK && done == n;
        double cs = (cpu_now() - c0) / (double)n, fr[64] = {0}, fl = 0;
        gs_engine_timing(e, &t1);
        double cp = (t1.cpu_path - t0.cpu_path) / (double)n;
        for (int g = 0; g < ng && ok; g++) {
            c0 = cpu_now();
            ok = gsi_fe_body_time_bare_solve(gb[g].b, reps) >= 0;
            if (owner[g] >= 0 && owner[g] < 64)
                fr[owner[g]] += (cpu_now() - c0) / reps;
        }
        for (int k = 0; k < size && k < 64; k++)
            fl = fl > fr[k] ? fl : fr[k];
        ratio[r] = cs / fl;
        pratio[r] = cp / fl;
    }
    if (ok) {
        printf("rounds (%d x %lld steps, then %d bare solves per gear), CPU ratio per round:", rounds,
               (long long)steps, reps);
        for (int r = 0; r < rounds; r++)
            printf(" %.2f", ratio[r]);
        printf("; critical path ratio per round:");
        for (int r = 0; r < rounds; r++)
            printf(" %.2f", pratio[r]);
        qsort(ratio, (size_t)rounds, sizeof *ratio, cmp_double);
        qsort(pratio, (size_t)rounds, sizeof *pratio, cmp_double);
        med = ratio[rounds / 2];
        printf("\nRESULT_ROUNDS scene %s order %d ranks %d: median CPU ratio %.2f (min %.2f, max %.2f); "
               "critical path: median ratio %.2f (min %.2f, max %.2f)\n",
               c->scene, sys->scene->bodies[0].mesh.order, size, med, ratio[0], ratio[rounds - 1], pratio[rounds / 2],
               pratio[0], pratio[rounds - 1]);
    }
    for (int g = 0; g < ng; g++)
        gear_fe_free(&gb[g]);
    return med;
}

/* With GEARSIM_PERF_CTL naming perf record's control fifo (perf record -D -1
 * --control fifo:PATH), profile only the timed chunk. */
static void perf_ctl(const char *cmd)
{
    const char *path = getenv("GEARSIM_PERF_CTL");
    FILE *f = path ? fopen(path, "w") : NULL;
    if (f) {
        fputs(cmd, f);
        fclose(f);
    }
}

static bool energy_every_step; /* GEARSIM_ENERGY_EVERY_STEP=1 */

/* What the concurrent floor (concurrent_floor) needs of a case, kept by
 * rank 0's run_case and broadcast after the engine has stopped. */
enum { MAXCASE = 8, MAXGEAR = 16 };
typedef struct case_rec {
    char scene[64];
    int order, ng;
    double h, path_ms;
    int body[MAXGEAR], owner[MAXGEAR];
} case_rec;
static case_rec recs[MAXCASE];
static int n_recs;

/* numerics.contact of the system's scene, by name. */
static const char *scheme_name(const gs_system *sys)
{
    static const char *const names[] = {"seed", "closure", "closure_energy"};
    return names[sys->scene->contact_scheme];
}

static int run_case(gs_engine *e, const bcase *c, int size, const char *scheme)
{
    json_object *root = json_tokener_parse(gs_scene_builtin(c->scene));
    json_object *num;
    if (scheme && json_object_object_get_ex(root, "numerics", &num))
        json_object_object_add(num, "contact", json_object_new_string(scheme));
    json_object *out = json_object_new_object();
    json_object_object_add(out, "telemetry_every", json_object_new_int(1000));
    json_object_object_add(root, "outputs", out);
    force_order(root, c->order);
    if (c->planets > 0)
        set_planets(root, c->planets);
    const char *txt = json_object_to_json_string(root);
    gs_diag d;
    if (gs_engine_run(e, GS_OP_LOAD, txt, strlen(txt), &d, NULL) != GS_OK) {
        fprintf(stderr, "bench_cost: %s: %s: %s\n", c->scene, d.field, d.message);
        json_object_put(root);
        return 1;
    }
    json_object_put(root);
    int64_t n = c->warm, done = 0;
    if (gs_engine_run(e, GS_OP_STEP, &n, sizeof n, &d, &done) != GS_OK || done != n) {
        fprintf(stderr, "bench_cost: %s: warm-up stopped at %lld\n", c->scene, (long long)done);
        return 1;
    }
    gs_system *sys = gs_engine_system(e);
    gs_step_timing t0, t1;
    enum { MAXB = 64 };
    gs_fe_stats st0[MAXB];
    bool has_st[MAXB]; /* a full elastic body on this rank */
    for (int i = 0; i < sys->n_bodies && i < MAXB; i++)
        has_st[i] = gs_elastic_fe_stats(&sys->bodies[i], &st0[i]);
    gs_engine_timing(e, &t0);
    n = c->steps;
    perf_ctl("enable\n");
    double w0 = gs_now(), c0 = cpu_now(), u0 = user_now();
    if (gs_engine_run(e, GS_OP_STEP, &n, sizeof n, &d, &done) != GS_OK || done != n) {
        fprintf(stderr, "bench_cost: %s: stopped at %lld\n", c->scene, (long long)done);
        return 1;
    }
    perf_ctl("disable\n");
    double wall = (gs_now() - w0) / (double)n, cpu = (cpu_now() - c0) / (double)n;
    double user = (user_now() - u0) / (double)n;
    gs_engine_timing(e, &t1);

    /* The floor: bare solves, timed here on rank 0 while the other ranks
     * idle (they poll with sleeps), summed per owning rank. */
    double floor_rank[64] = {0}, cfloor_rank[64] = {0}, ufloor_rank[64] = {0}, floor_all = 0;
    printf("\n## %s, %d ranks, h %g s, %d steps after %d warm-up, element order %d, contact %s\n", c->scene, size,
           sys->h, c->steps, c->warm, sys->scene->bodies[0].mesh.order, scheme_name(sys));
    printf("%-10s %5s %9s %12s %12s\n", "gear", "rank", "unknowns", "solve (ms)", "CPU (ms)");
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (!b->ops->state_size)
            continue;
        double tc = 0, tu = 0, ts = bare_solve(sys, i, 2000, &tc, &tu);
        if (ts < 0)
            return 1;
        gs_mesh *mesh = NULL;
        gs_scene_gear_mesh(&sys->scene->bodies[i], &mesh, &d);
        gs_index nn = mesh ? mesh->n_nodes : 0;
        gs_mesh_free(&mesh);
        printf("%-10s %5d %9lld %12.4f %12.4f\n", sys->scene->bodies[i].name, b->owner, (long long)(2 * nn),
               1e3 * ts, 1e3 * tc);
        if (b->owner >= 0 && b->owner < 64) {
            floor_rank[b->owner] += ts;
            cfloor_rank[b->owner] += tc;
            ufloor_rank[b->owner] += tu;
        }
        floor_all += ts;
    }
    double fl = 0, cfl = 0, ufl = 0;
    for (int r = 0; r < size && r < 64; r++) {
        ufl = ufl > ufloor_rank[r] ? ufl : ufloor_rank[r];
        fl = fl > floor_rank[r] ? fl : floor_rank[r];
        cfl = cfl > cfloor_rank[r] ? cfl : cfloor_rank[r];
    }
    double steps = (double)n;
    printf("breakdown on rank 0 (ms per step): prepare %.4f records %.4f reduce %.4f solve %.4f bcast %.4f "
           "apply %.4f sync %.4f\n",
           1e3 * (t1.prepare - t0.prepare) / steps, 1e3 * (t1.records - t0.records) / steps,
           1e3 * (t1.reduce - t0.reduce) / steps, 1e3 * (t1.solve - t0.solve) / steps,
           1e3 * (t1.bcast - t0.bcast) / steps, 1e3 * (t1.apply - t0.apply) / steps,
           1e3 * (t1.sync - t0.sync) / steps);
    /* The column cache over the timed steps: each group solve is one
     * multi-column solve (2 x 8 right-hand sides) for nodes the contact
     * reached for the first time. */
    for (int i = 0; i < sys->n_bodies && i < MAXB; i++) {
        gs_fe_stats s1;
        if (!has_st[i] || !gs_elastic_fe_stats(&sys->bodies[i], &s1))
            continue;
        printf("columns of %s over the timed steps: %llu group solves (%.2f per 100 steps), %llu nodes missed, "
               "%llu kept unasked, %llu hits; %lld nodes cached\n",
               sys->scene->bodies[i].name, (unsigned long long)(s1.group_solves - st0[i].group_solves),
               100.0 * (double)(s1.group_solves - st0[i].group_solves) / steps,
               (unsigned long long)(s1.cache_misses - st0[i].cache_misses),
               (unsigned long long)(s1.group_kept - st0[i].group_kept),
               (unsigned long long)(s1.cache_hits - st0[i].cache_hits), (long long)s1.cached_nodes);
    }
    /* Rank 0's gears solved in turn (informative, see interleaved_floor). */
    double ifl = interleaved_floor(sys, 0, 1000);
    printf("rank 0's gears solved in turn (CPU ms per round) %.4f: CPU ratio against it %.2f\n", 1e3 * ifl,
           cpu / ifl);
    /* Both floors side by side: the bar is judged on the hot loop. */
    printf("RESULT_FLOORS scene %s order %d contact %s ranks %d: CPU ms_per_step %.4f; floor (hot loop, each gear's "
           "solve repeated) %.4f ms, ratio %.2f; floor in turn (rank 0's gears one after the other, as the step "
           "takes them) %.4f ms, ratio %.2f; energies %s\n",
           c->scene, sys->scene->bodies[0].mesh.order, scheme_name(sys), size, 1e3 * cpu, 1e3 * cfl,
           cpu / cfl, 1e3 * ifl, cpu / ifl, energy_every_step ? "every step" : "on the daemon's schedule");
    printf("RESULT scene %s order %d contact %s ranks %d wall: ms_per_step %.4f floor_ms %.4f ratio %.2f; CPU (rank 0): "
           "ms_per_step %.4f floor_ms %.4f ratio %.2f; user CPU: ratio %.2f; all gears' solves %.4f ms\n",
           c->scene, sys->scene->bodies[0].mesh.order, scheme_name(sys), size, 1e3 * wall, 1e3 * fl, wall / fl, 1e3 * cpu, 1e3 * cfl, cpu / cfl, user / ufl,
           1e3 * floor_all);
    /* The engine's critical path (gs_step_timing): per phase the slowest
     * rank's CPU time, rank 0's in the serial phases; at -n 1 the CPU time
     * of the step outside the engine's hook. */
    double path = (t1.cpu_path - t0.cpu_path) / steps, work = (t1.cpu_work - t0.cpu_work) / steps;
    printf("RESULT_PATH scene %s order %d contact %s ranks %d: critical path CPU ms_per_step %.4f (rank 0's own "
           "work %.4f) floor_ms %.4f ratio %.2f\n",
           c->scene, sys->scene->bodies[0].mesh.order, scheme_name(sys), size, 1e3 * path, 1e3 * work,
           1e3 * cfl, path / cfl);
    if (n_recs < MAXCASE) {
        case_rec *r = &recs[n_recs++];
        snprintf(r->scene, sizeof r->scene, "%s", c->scene);
        r->order = c->order;
        r->h = sys->h;
        r->path_ms = 1e3 * path;
        r->ng = 0;
        for (int i = 0; i < sys->n_bodies && r->ng < MAXGEAR; i++)
            if (sys->bodies[i].ops->state_size) {
                r->body[r->ng] = i;
                r->owner[r->ng++] = sys->bodies[i].owner;
            }
    }
    if (rounds_ratio(e, c, size, 5, c->steps / 5, c->steps >= 1000 ? 400 : 200) < 0)
        return 1;
    fflush(stdout);
    gs_engine_run(e, GS_OP_UNLOAD, NULL, 0, &d, NULL);
    return 0;
}

/* The floor taken as the step takes its solves at -n k: every rank solves
 * its own gears, one after the other, while the other ranks do the same at
 * the same time (they share the caches and the memory). Run after the
 * engine has stopped, on every rank (collective); rank 0 prints, per case,
 * the slowest rank's CPU ms per round and the critical path's ratio
 * against it. Informative: the bar is judged on the hot loop. */
static void concurrent_floor(int rank, int size)
{
    MPI_Bcast(&n_recs, 1, MPI_INT, 0, MPI_COMM_WORLD);
    MPI_Bcast(recs, (int)sizeof recs, MPI_BYTE, 0, MPI_COMM_WORLD);
    for (int k = 0; k < n_recs; k++) {
        const case_rec *r = &recs[k];
        json_object *root = json_tokener_parse(gs_scene_builtin(r->scene));
        force_order(root, r->order);
        const char *txt = json_object_to_json_string(root);
        gs_scene *sc = NULL;
        gs_diag d;
        gear_fe g[MAXGEAR];
        int ng = 0, ok = gs_scene_parse(txt, strlen(txt), &sc, &d) == GS_OK;
        for (int k2 = 0; ok && k2 < r->ng; k2++)
            if (r->owner[k2] == rank)
                ok = gear_fe_new(&sc->bodies[r->body[k2]], r->h, &g[ng++]);
        json_object_put(root);
        if (ok) /* each factor touched once before the clock */
            ok = solves_in_turn(g, ng, 1) >= 0;
        MPI_Barrier(MPI_COMM_WORLD);
        double mine = ok ? solves_in_turn(g, ng, 300) : -1, worst = 0;
        ok = ok && mine >= 0;
        int all_ok = 0;
        MPI_Reduce(&mine, &worst, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
        MPI_Reduce(&ok, &all_ok, 1, MPI_INT, MPI_LAND, 0, MPI_COMM_WORLD);
        if (rank == 0 && all_ok)
            printf("RESULT_CONCURRENT scene %s order %d ranks %d: floor with every rank solving its gears in turn at "
                   "once %.4f ms (slowest rank, CPU per round); critical path %.4f ms, ratio %.2f\n",
                   r->scene, r->order ? r->order : 2, size, 1e3 * worst, r->path_ms, r->path_ms / (1e3 * worst));
        for (int k2 = 0; k2 < ng; k2++)
            gear_fe_free(&g[k2]);
        gs_scene_free(&sc);
    }
    fflush(stdout);
}

/* Instruction counts (`bench_cost count SCENE [STEPS]` under mpirun and
 * valgrind --tool=callgrind --instr-atstart=no): the scene's quick
 * warm-up uninstrumented, then every rank instruments from the counted
 * steps on (rank 0 by the client request before count_steps, the others
 * between the two gs_engine_serve calls of main: the engine's shutdown
 * operation pauses their serve loop after the warm-up). Then STEPS steps in
 * count_steps (each rank's own work: dist_substep's inclusive count less
 * the MPI calls', which spin while waiting) and STEPS bare solves of each
 * elastic gear on a fresh factor, gear g in its own function count_gear_g
 * (at most 8), so that callgrind_annotate --inclusive=yes reads each
 * gear's floor apart. No timing: the counts do not depend on the load. */
static __attribute__((noinline)) int count_steps(gs_engine *e, int64_t n)
{
    int64_t done = 0;
    gs_diag d;
    return gs_engine_run(e, GS_OP_STEP, &n, sizeof n, &d, &done) == GS_OK && done == n ? 0 : 1;
}

#define COUNT_GEAR(g)                                                                                       \
    static __attribute__((noinline)) int count_gear_##g(gs_fe_body *b, int reps)                             \
    {                                                                                                       \
        return gsi_fe_body_time_bare_solve(b, reps) >= 0 ? 0 : 1;                                           \
    }
COUNT_GEAR(0)
COUNT_GEAR(1)
COUNT_GEAR(2)
COUNT_GEAR(3)
COUNT_GEAR(4)
COUNT_GEAR(5)
COUNT_GEAR(6)
COUNT_GEAR(7)

static int count_case(gs_engine *e, const bcase *c, int64_t steps)
{
    static int (*const gear_fn[8])(gs_fe_body *, int) = {count_gear_0, count_gear_1, count_gear_2, count_gear_3,
                                                         count_gear_4, count_gear_5, count_gear_6, count_gear_7};
    json_object *root = json_tokener_parse(gs_scene_builtin(c->scene));
    json_object *out = json_object_new_object();
    json_object_object_add(out, "telemetry_every", json_object_new_int(1000));
    json_object_object_add(root, "outputs", out);
    const char *txt = json_object_to_json_string(root);
    gs_diag d;
    int rc = gs_engine_run(e, GS_OP_LOAD, txt, strlen(txt), &d, NULL) != GS_OK;
    json_object_put(root);
    if (rc || count_steps(e, c->warm)) {
        fprintf(stderr, "bench_cost count: %s: load or warm-up failed\n", c->scene);
        return 1;
    }
    gs_engine_run(e, GS_OP_SHUTDOWN, NULL, 0, &d, NULL); /* the other ranks start instrumenting (main) */
    CALLGRIND_START_INSTRUMENTATION;
    rc = count_steps(e, steps);
    gs_system *sys = gs_engine_system(e);
    printf("# count %s: %lld steps after %d; gear (rank): count_gear_g with %lld bare solves\n", c->scene,
           (long long)steps, c->warm, (long long)steps);
    for (int i = 0, g = 0; i < sys->n_bodies && g < 8 && !rc; i++) {
        const gs_scene_body *sb = &sys->scene->bodies[i];
        if (!sys->bodies[i].ops->state_size)
            continue;
        gear_fe gf;
        rc = !gear_fe_new(sb, sys->h, &gf) || gear_fn[g](gf.b, (int)steps);
        printf("count_gear_%d %s (rank %d)\n", g++, sb->name, sys->bodies[i].owner);
        gear_fe_free(&gf);
    }
    fflush(stdout);
    gs_engine_run(e, GS_OP_UNLOAD, NULL, 0, &d, NULL);
    return rc;
}

int main(int argc, char **argv)
{
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    gs_engine *e = NULL;
    if (gs_engine_new(MPI_COMM_WORLD, &e) != GS_OK) {
        MPI_Abort(MPI_COMM_WORLD, 1);
        return 1;
    }
    int rank = gs_engine_rank(e), size = gs_engine_size(e), rc = 0;
    /* The critical path (thread CPU clock reads per phase) on every rank;
     * the energies on the daemon's schedule (gs_engine_set_energy_schedule:
     * telemetry steps and chunk ends), or every step with
     * GEARSIM_ENERGY_EVERY_STEP=1. */
    bool counting = argc > 1 && strcmp(argv[1], "count") == 0; /* the daemon's setting: no clock reads */
    gs_engine_set_cpu_timing(e, !counting);
    const char *every = getenv("GEARSIM_ENERGY_EVERY_STEP");
    energy_every_step = every && every[0] == '1';
    gs_engine_set_energy_schedule(e, !energy_every_step);
    if (rank != 0) {
        rc = gs_engine_serve(e) != GS_OK;
        if (counting && rc == 0) { /* paused after the warm-up (count_case) */
            CALLGRIND_START_INSTRUMENTATION;
            rc = gs_engine_serve(e) != GS_OK;
        }
        if (!counting)
            concurrent_floor(rank, size);
    } else {
        bool quick = argc > 1 && (strcmp(argv[1], "quick") == 0 || strcmp(argv[1], "count") == 0);
        const bcase cases[] = {
            {"contact_drive", quick ? 500 : 2500, quick ? 500 : 2000, 0, 0},
            {"contact_drive", quick ? 500 : 2500, quick ? 500 : 2000, 1, 0}, /* linear triangles */
            {"planetary_contact", quick ? 200 : 1000, quick ? 200 : 800, 0, 0},
        };
        const char *thr = getenv("OPENBLAS_NUM_THREADS");
        printf("# bench_cost: cost per step against one bare solve per gear; OPENBLAS_NUM_THREADS=%s\n",
               thr ? thr : "(unset)");
        int planets = argc > 2 && strcmp(argv[1], "weak") == 0 ? atoi(argv[2]) : 0;
        const bcase weak = {"planetary_contact", 50, 50, 0, planets};
        if (planets > 0) {
            if (planets < 1 || planets > 8) {
                fprintf(stderr, "bench_cost weak N: N planets, 1 to 8\n");
                rc = 1;
            } else {
                printf("# weak scaling: planetary_contact as a 36/24/84 train with %d planets (%d elastic gears) on %d "
                       "ranks\n", planets,
                       planets + 2, size);
                rc = run_case(e, &weak, size, NULL);
            }
            gs_diag d;
            gs_engine_run(e, GS_OP_SHUTDOWN, NULL, 0, &d, NULL);
            concurrent_floor(rank, size);
            gs_engine_free(&e);
            MPI_Finalize();
            return rc;
        }
        const char *only = argc > 2 && strcmp(argv[2], "all") != 0 ? argv[2] : NULL;
        const char *scheme = argc > 3 ? argv[3] : NULL; /* numerics.contact; default the scenes' (closure_energy) */
        bool count = counting;
        int64_t csteps = count && argc > 3 ? atoll(argv[3]) : 100;
        bool counted = false; /* count: one scene (the other ranks pause once) */
        for (size_t k = 0; k < sizeof cases / sizeof cases[0] && rc == 0; k++)
            if (!only || !strcmp(only, cases[k].scene)) {
                if (count && !counted && cases[k].order == 0) {
                    rc = count_case(e, &cases[k], csteps > 0 ? csteps : 100);
                    counted = true;
                } else if (!count) {
                    rc = run_case(e, &cases[k], size, scheme);
                }
            }
        if (count && !counted) /* release the other ranks' pause */
            gs_engine_run(e, GS_OP_SHUTDOWN, NULL, 0, &(gs_diag){0}, NULL);
        gs_diag d;
        gs_engine_run(e, GS_OP_SHUTDOWN, NULL, 0, &d, NULL);
        if (!count)
            concurrent_floor(rank, size);
    }
    gs_engine_free(&e);
    MPI_Finalize();
    return rc;
}
