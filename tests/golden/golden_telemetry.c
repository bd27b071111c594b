/* SPDX-License-Identifier: MIT
 * Golden telemetry of every shipped scene: each scene of deploy/scenes/ is
 * loaded into a one-rank engine as the daemon loads it (GS_OP_LOAD of the
 * file's text, the daemon's energy schedule on), stepped a fixed number of
 * steps, and at every telemetry step (outputs.telemetry_every, as the
 * daemon's step hook publishes) and at the end of the run the telemetry's
 * values are written one per line, exactly (%a): time, the energies, every
 * body's angle, speed and centre offset, every mesh's force, deflection,
 * penetration and contact and impact figures, the planets' load shares. At
 * the end, the length and a 64-bit FNV-1a hash of the engine's snapshot (the
 * whole state, elastic bodies included) are written as well. A scene the
 * engine refuses to load gets its diagnostic as its entry.
 *
 *   golden_telemetry SCENES_DIR GOLDEN            compare (exit 1 on any difference)
 *   golden_telemetry SCENES_DIR GOLDEN --write    rewrite GOLDEN
 *
 * Compare fails naming the first differing scene, step and field, for a
 * scene of SCENES_DIR without a golden entry and for a golden entry whose
 * scene is gone. Regenerate (after a change meant to alter the numbers):
 *   ninja -C build golden-telemetry-update */
#include <dirent.h>
#include <math.h>
#include <mpi.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/engine.h"
#include "gearsim/step.h"

/* Steps per scene: a few hundred, fewer for the scenes whose elastic gears
 * make a step cost tens of milliseconds. The count written in the golden file
 * is the one compared against. */
static const struct { const char *scene; int64_t steps; } step_table[] = {
    {"contact_drive", 30},     {"contact_impact", 30},   {"elastic_pair", 40},
    {"elastic_spin", 40},      {"pair_relief", 30},      {"planetary_contact", 6},
    {"planetary_runout", 30},  {"stiffness_pair", 30},
};
enum { DEFAULT_STEPS = 300 };

typedef struct buf {
    char *s;
    size_t n, cap;
} buf;

static void bprintf(buf *b, const char *fmt, ...)
{
    va_list ap;
    for (;;) {
        va_start(ap, fmt);
        int k = vsnprintf(b->s ? b->s + b->n : NULL, b->s ? b->cap - b->n : 0, fmt, ap);
        va_end(ap);
        if (k < 0)
            abort();
        if (b->s && b->n + (size_t)k < b->cap) {
            b->n += (size_t)k;
            return;
        }
        b->cap = 2 * (b->cap + (size_t)k + 64);
        b->s = realloc(b->s, b->cap);
        if (!b->s)
            abort();
    }
}

typedef struct ctx {
    buf *out;
    const char *name;
} ctx;

static void state_lines(buf *o, const char *nm, gs_system *sys)
{
    int64_t st = sys->step;
    bprintf(o, "%s %lld time %a\n", nm, (long long)st, sys->time);
    gs_energy e;
    gs_system_energy(sys, &e);
    bprintf(o, "%s %lld energy.kinetic %a\n", nm, (long long)st, e.kinetic);
    bprintf(o, "%s %lld energy.potential %a\n", nm, (long long)st, e.potential);
    bprintf(o, "%s %lld energy.elastic %a\n", nm, (long long)st, e.elastic);
    bprintf(o, "%s %lld energy.total %a\n", nm, (long long)st, e.total);
    bprintf(o, "%s %lld energy.work_in %a\n", nm, (long long)st, e.work_in);
    bprintf(o, "%s %lld energy.dissipated %a\n", nm, (long long)st, e.dissipated);
    bprintf(o, "%s %lld energy.balance_residual %a\n", nm, (long long)st, e.balance_residual);
    bprintf(o, "%s %lld energy.contact_work %a\n", nm, (long long)st, e.contact_work);
    for (int i = 0; i < sys->n_bodies; i++) {
        const char *bn = sys->scene->bodies[i].name;
        bprintf(o, "%s %lld body.%s.angle %a\n", nm, (long long)st, bn, gs_system_angle(sys, i));
        bprintf(o, "%s %lld body.%s.omega %a\n", nm, (long long)st, bn, gs_system_omega(sys, i));
        bprintf(o, "%s %lld body.%s.rpm %a\n", nm, (long long)st, bn, gs_system_rpm(sys, i));
        int tc = sys->bodies[i].tcoord;
        if (tc >= 0)
            bprintf(o, "%s %lld body.%s.offset %a %a\n", nm, (long long)st, bn, sys->q[tc], sys->q[tc + 1]);
    }
    for (int i = 0; i < sys->n_meshes; i++) {
        const gs_gmesh_rt *m = &sys->meshes[i];
        const char *mn = sys->scene->meshes[i].name;
        bprintf(o, "%s %lld mesh.%s.force %a\n", nm, (long long)st, mn, isfinite(m->force) ? m->force : 0.0);
        bprintf(o, "%s %lld mesh.%s.deflection %a\n", nm, (long long)st, mn, m->deflection);
        bprintf(o, "%s %lld mesh.%s.penetration %a\n", nm, (long long)st, mn, m->penetration);
        if (m->ops->contact) {
            bprintf(o, "%s %lld mesh.%s.contacts %d\n", nm, (long long)st, mn, m->n_active);
            bprintf(o, "%s %lld mesh.%s.rows %d\n", nm, (long long)st, mn, m->n_rows);
            bprintf(o, "%s %lld mesh.%s.friction_loss %a\n", nm, (long long)st, mn, m->friction_loss);
            bprintf(o, "%s %lld mesh.%s.contact_work %a\n", nm, (long long)st, mn, m->contact_work);
        }
        if (m->ops->after_step) {
            bprintf(o, "%s %lld mesh.%s.impacts %lld\n", nm, (long long)st, mn, (long long)m->impacts);
            bprintf(o, "%s %lld mesh.%s.impact_loss %a\n", nm, (long long)st, mn, m->impact_loss);
        }
    }
    int planet[64];
    double share[64];
    int np = gs_system_planet_shares(sys, planet, share, 64);
    for (int i = 0; i < np; i++)
        bprintf(o, "%s %lld planet.%s.share %a\n", nm, (long long)st, sys->scene->bodies[planet[i]].name,
                share[i]);
}

/* The daemon's step hook publishes on these steps. */
static bool hook(gs_engine *e, void *user)
{
    ctx *c = user;
    gs_system *sys = gs_engine_system(e);
    if (sys->step % sys->scene->telemetry_every == 0)
        state_lines(c->out, c->name, sys);
    return true;
}

static char *read_file(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    buf b = {0};
    char chunk[65536];
    size_t k;
    while ((k = fread(chunk, 1, sizeof chunk, f)) > 0)
        bprintf(&b, "%.*s", (int)k, chunk);
    fclose(f);
    *len = b.n;
    if (!b.s)
        b.s = calloc(1, 1);
    return b.s;
}

static int64_t steps_for(const char *name)
{
    for (size_t i = 0; i < sizeof step_table / sizeof step_table[0]; i++)
        if (strcmp(step_table[i].scene, name) == 0)
            return step_table[i].steps;
    return DEFAULT_STEPS;
}

/* One scene's entry: its header line, then its lines. */
static void run_scene(const char *dir, const char *name, int64_t steps, buf *o)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.json", dir, name);
    size_t len = 0;
    char *txt = read_file(path, &len);
    bprintf(o, "scene %s steps %lld\n", name, (long long)steps);
    if (!txt) {
        bprintf(o, "%s unreadable\n", name);
        return;
    }
    gs_engine *e = NULL;
    if (gs_engine_new(MPI_COMM_SELF, &e) != GS_OK) {
        fprintf(stderr, "golden_telemetry: no engine\n");
        exit(2);
    }
    gs_diag d = {0};
    gs_err err = gs_engine_run(e, GS_OP_LOAD, txt, len, &d, NULL);
    free(txt);
    if (err != GS_OK) {
        bprintf(o, "%s load_refused %s: %s\n", name, d.field, d.message);
        gs_engine_free(&e);
        return;
    }
    ctx c = {o, name};
    gs_engine_set_hook(e, hook, &c);
    gs_engine_set_energy_schedule(e, true);
    int64_t n = steps, done = 0;
    err = gs_engine_run(e, GS_OP_STEP, &n, sizeof n, &d, &done);
    gs_system *sys = gs_engine_system(e);
    if (err != GS_OK)
        bprintf(o, "%s step_refused after %lld: %s: %s\n", name, (long long)done, d.field, d.message);
    if (sys->step % sys->scene->telemetry_every != 0)
        state_lines(o, name, sys); /* the end of the run */
    char *snap = NULL;
    size_t sl = 0;
    if (gs_engine_snapshot(e, &snap, &sl) == GS_OK) {
        uint64_t h = 0xcbf29ce484222325ULL;
        for (size_t i = 0; i < sl; i++)
            h = (h ^ (unsigned char)snap[i]) * 0x100000001b3ULL;
        bprintf(o, "%s end snapshot %zu bytes fnv1a %016llx\n", name, sl, (unsigned long long)h);
        free(snap);
    } else {
        bprintf(o, "%s end snapshot refused\n", name);
    }
    gs_engine_free(&e);
}

static int cmp_str(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* The scene names of dir (file names *.json without the extension), sorted. */
static int list_scenes(const char *dir, char ***out)
{
    DIR *dp = opendir(dir);
    if (!dp) {
        fprintf(stderr, "golden_telemetry: cannot open %s\n", dir);
        exit(2);
    }
    char **v = NULL;
    int n = 0;
    struct dirent *de;
    while ((de = readdir(dp))) {
        size_t l = strlen(de->d_name);
        if (l > 5 && strcmp(de->d_name + l - 5, ".json") == 0) {
            v = realloc(v, (size_t)(n + 1) * sizeof *v);
            v[n++] = strndup(de->d_name, l - 5);
        }
    }
    closedir(dp);
    qsort(v, (size_t)n, sizeof *v, cmp_str);
    *out = v;
    return n;
}

/* The golden file's entry for scene `name`: the text from its header line to
 * the next header (NULL when absent); *steps from the header. */
static const char *golden_entry(const char *g, const char *name, int64_t *steps, size_t *len)
{
    for (const char *p = g; p && *p;) {
        long long st;
        char nm[256];
        if (strncmp(p, "scene ", 6) == 0 && sscanf(p, "scene %255s steps %lld", nm, &st) == 2 &&
            strcmp(nm, name) == 0) {
            const char *end = strstr(p + 1, "\nscene ");
            *len = end ? (size_t)(end + 1 - p) : strlen(p);
            *steps = st;
            return p;
        }
        p = strchr(p, '\n');
        if (p)
            p++;
    }
    return NULL;
}

/* First differing line of two entries; prints it and returns false. */
static bool same(const char *name, const char *want, size_t wl, const char *got, size_t gl)
{
    size_t i = 0, j = 0;
    int line = 1;
    while (i < wl || j < gl) {
        size_t ie = i, je = j;
        while (ie < wl && want[ie] != '\n')
            ie++;
        while (je < gl && got[je] != '\n')
            je++;
        if (ie - i != je - j || memcmp(want + i, got + j, ie - i) != 0) {
            fprintf(stderr, "golden_telemetry: scene %s differs at its line %d\n  golden: %.*s\n  now:    %.*s\n",
                    name, line, (int)(ie - i), i < wl ? want + i : "(end of entry)", (int)(je - j),
                    j < gl ? got + j : "(end of entry)");
            return false;
        }
        i = ie + (ie < wl);
        j = je + (je < gl);
        line++;
    }
    return true;
}

int main(int argc, char **argv)
{
    if (argc < 3 || (argc == 4 && strcmp(argv[3], "--write") != 0) || argc > 4) {
        fprintf(stderr, "usage: golden_telemetry SCENES_DIR GOLDEN [--write]\n");
        return 2;
    }
    bool write = argc == 4;
    MPI_Init(&argc, &argv);
    char **names;
    int n = list_scenes(argv[1], &names);
    int bad = 0;
    if (write) {
        buf o = {0};
        bprintf(&o, "# Golden telemetry of the shipped scenes (tests/golden/golden_telemetry.c);\n"
                    "# regenerate: ninja -C build golden-telemetry-update\n");
        for (int i = 0; i < n; i++)
            run_scene(argv[1], names[i], steps_for(names[i]), &o);
        FILE *f = fopen(argv[2], "w");
        if (!f || fwrite(o.s, 1, o.n, f) != o.n || fclose(f) != 0) {
            fprintf(stderr, "golden_telemetry: cannot write %s\n", argv[2]);
            bad = 1;
        } else {
            printf("wrote %s: %d scenes\n", argv[2], n);
        }
        free(o.s);
    } else {
        size_t gl;
        char *g = read_file(argv[2], &gl);
        if (!g) {
            fprintf(stderr, "golden_telemetry: cannot read %s\n", argv[2]);
            return 1;
        }
        for (int i = 0; i < n; i++) {
            int64_t steps;
            size_t el;
            const char *ent = golden_entry(g, names[i], &steps, &el);
            if (!ent) {
                fprintf(stderr, "golden_telemetry: scene %s (%s/%s.json) has no golden entry in %s\n",
                        names[i], argv[1], names[i], argv[2]);
                bad++;
                continue;
            }
            buf o = {0};
            run_scene(argv[1], names[i], steps, &o);
            if (same(names[i], ent, el, o.s, o.n))
                printf("ok %s (%lld steps)\n", names[i], (long long)steps);
            else
                bad++;
            free(o.s);
        }
        /* Golden entries whose scene is gone. */
        for (const char *p = g; p && *p;) {
            char nm[256];
            long long st;
            if (strncmp(p, "scene ", 6) == 0 && sscanf(p, "scene %255s steps %lld", nm, &st) == 2) {
                bool found = false;
                for (int i = 0; i < n; i++)
                    found |= strcmp(names[i], nm) == 0;
                if (!found) {
                    fprintf(stderr, "golden_telemetry: golden entry %s has no scene in %s\n", nm, argv[1]);
                    bad++;
                }
            }
            p = strchr(p, '\n');
            if (p)
                p++;
        }
        free(g);
        if (n == 0) {
            fprintf(stderr, "golden_telemetry: no scenes in %s\n", argv[1]);
            bad++;
        }
    }
    for (int i = 0; i < n; i++)
        free(names[i]);
    free(names);
    MPI_Finalize();
    if (bad)
        fprintf(stderr, "golden_telemetry: %d scene(s) differ or are missing\n", bad);
    return bad ? 1 : 0;
}
