/* SPDX-License-Identifier: MIT
 * The measured trade-off table and the choice of a setting from it
 * (include/gearsim/tradeoff.h): the same reading and the same rule as
 * `gearctl advise` (clients/python/gearsim/advise.py), checked against it
 * by tests/integration/test_fidelity_targets.py. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "gearsim/tradeoff.h"
#include "gearsim/util.h"
#include "scene/tradeoff_paths.h"

const char *gs_tradeoff_path(void)
{
    const char *e = getenv("GEARSIM_TRADEOFF_TABLE");
    if (e && e[0])
        return e;
    struct stat st;
    if (stat(GS_TRADEOFF_INSTALLED, &st) == 0)
        return GS_TRADEOFF_INSTALLED;
    if (stat(GS_TRADEOFF_SOURCE, &st) == 0)
        return GS_TRADEOFF_SOURCE;
    return GS_TRADEOFF_INSTALLED;
}

/* A number as advise reads one: the whole field, finite; else NaN. */
static double num(const char *s)
{
    if (!s || !*s)
        return NAN;
    char *end;
    double v = strtod(s, &end);
    while (*end == ' ')
        end++;
    return *end == '\0' && isfinite(v) ? v : NAN;
}

/* Split one CSV line (no embedded newlines; "..." fields with "" for a
 * quote) in place into at most cap fields; returns their count. */
static int split(char *line, char **f, int cap)
{
    int n = 0;
    char *p = line;
    for (;;) {
        if (n == cap)
            return n + 1;
        if (*p == '"') {
            char *w = ++p;
            f[n++] = w;
            while (*p && !(*p == '"' && p[1] != '"'))
                *w++ = (*p == '"' ? (p++, '"') : *p), p++;
            if (*p == '"')
                p++;
            *w = '\0';
            while (*p && *p != ',')
                p++;
        } else {
            f[n++] = p;
            while (*p && *p != ',')
                p++;
        }
        if (*p != ',') {
            *p = '\0';
            return n;
        }
        *p++ = '\0';
    }
}

#define MAX_COLS 64

gs_err gs_tradeoff_parse(const char *csv, size_t len, gs_tradeoff *t, gs_diag *d)
{
    memset(t, 0, sizeof *t);
    char *buf = malloc(len + 1);
    if (!buf)
        return GS_ENOMEM;
    memcpy(buf, csv, len);
    buf[len] = '\0';
    char *save = NULL, *line = strtok_r(buf, "\n", &save);
    char *hdr[MAX_COLS];
    int nh = line ? split(line, hdr, MAX_COLS) : 0;
    if (nh > MAX_COLS) {
        free(buf);
        return gs_diag_set(d, GS_EPARSE, "table", "the trade-off table has more than %d columns", MAX_COLS);
    }
    int c_scene = -1, c_level = -1, c_h = -1, c_cost = -1, c_refine = -1, c_scheme = -1, c_scale = -1, c_zeta = -1;
    int c_err[GS_TRADEOFF_MAX_OUT];
    for (int i = 0; i < nh; i++) {
        char *h = hdr[i];
        size_t hl = strlen(h);
        if (hl && h[hl - 1] == '\r')
            h[hl - 1] = '\0';
        if (!strcmp(h, "scene"))
            c_scene = i;
        else if (!strcmp(h, "level"))
            c_level = i;
        else if (!strcmp(h, "h"))
            c_h = i;
        else if (!strcmp(h, "cost"))
            c_cost = i;
        else if (!strcmp(h, "refine"))
            c_refine = i;
        else if (!strcmp(h, "scheme"))
            c_scheme = i;
        else if (!strcmp(h, "scale"))
            c_scale = i;
        else if (!strcmp(h, "zeta"))
            c_zeta = i;
        else if (!strncmp(h, "err_", 4) && h[4] && t->n_out < GS_TRADEOFF_MAX_OUT && strlen(h + 4) < 24) {
            snprintf(t->out[t->n_out], sizeof t->out[0], "%s", h + 4);
            c_err[t->n_out++] = i;
        }
    }
    t->cpu = c_zeta >= 0;
    if (c_scene < 0 || c_level < 0 || c_h < 0 || c_cost < 0) {
        free(buf);
        return gs_diag_set(d, GS_EPARSE, "table", "the trade-off table needs the columns scene, level, h and cost");
    }
    if (t->n_out == 0) {
        free(buf);
        return gs_diag_set(d, GS_EPARSE, "table", "the trade-off table has no err_<output> columns");
    }
    int cap = 0;
    while ((line = strtok_r(NULL, "\n", &save))) {
        size_t ll = strlen(line);
        if (ll && line[ll - 1] == '\r')
            line[--ll] = '\0';
        if (!ll)
            continue;
        char *f[MAX_COLS];
        int nf = split(line, f, MAX_COLS);
        if (nf > MAX_COLS)
            nf = MAX_COLS;
        if (t->n_rows >= GS_TRADEOFF_MAX_ROWS)
            break;
        if (t->n_rows == cap) {
            int nc = cap ? 2 * cap : 64;
            gs_tradeoff_row *r = realloc(t->rows, (size_t)nc * sizeof *r);
            if (!r) {
                free(buf);
                gs_tradeoff_free(t);
                return GS_ENOMEM;
            }
            t->rows = r;
            cap = nc;
        }
        gs_tradeoff_row *r = &t->rows[t->n_rows++];
        memset(r, 0, sizeof *r);
#define FIELD(c) ((c) >= 0 && (c) < nf ? f[c] : "")
        snprintf(r->scene, sizeof r->scene, "%s", FIELD(c_scene));
        snprintf(r->level, sizeof r->level, "%s", FIELD(c_level));
        snprintf(r->scheme, sizeof r->scheme, "%s", FIELD(c_scheme));
        r->h = num(FIELD(c_h));
        r->cost = num(FIELD(c_cost));
        double rf = num(FIELD(c_refine)), sc = num(FIELD(c_scale)), z = num(FIELD(c_zeta));
        r->refine = isfinite(rf) ? (int)rf : 0;
        r->scale = isfinite(sc) && sc != 0.0 ? sc : 1.0;
        r->zeta = isfinite(z) ? z : 0.0;
        for (int o = 0; o < t->n_out; o++)
            r->err[o] = num(FIELD(c_err[o]));
#undef FIELD
    }
    free(buf);
    return GS_OK;
}

gs_err gs_tradeoff_load(const char *path, gs_tradeoff *t, gs_diag *d)
{
    memset(t, 0, sizeof *t);
    FILE *f = fopen(path, "rb");
    if (!f)
        return gs_diag_set(d, GS_EIO, "table", "cannot read the trade-off table %.200s", path);
    char *buf = NULL;
    size_t len = 0, cap = 0;
    for (;;) {
        if (len + 4096 > cap) {
            cap = cap ? 2 * cap : 65536;
            char *nb = cap <= (64u << 20) ? realloc(buf, cap) : NULL;
            if (!nb) {
                free(buf);
                fclose(f);
                return gs_diag_set(d, GS_ETOOBIG, "table", "the trade-off table %.200s is too large", path);
            }
            buf = nb;
        }
        size_t k = fread(buf + len, 1, cap - len, f);
        len += k;
        if (k == 0)
            break;
    }
    fclose(f);
    gs_err e = gs_tradeoff_parse(buf ? buf : "", len, t, d);
    free(buf);
    return e;
}

void gs_tradeoff_free(gs_tradeoff *t)
{
    free(t->rows);
    memset(t, 0, sizeof *t);
}

int gs_tradeoff_output(const gs_tradeoff *t, const char *name)
{
    static const char *const alias[][2] = {
        {"dte_rms", "dte"}, {"peak_force", "force"}, {"mesh_order", "mesh"}, {"output_speed", "speed"}};
    for (int o = 0; o < t->n_out; o++)
        if (!strcmp(t->out[o], name))
            return o;
    for (size_t a = 0; a < sizeof alias / sizeof alias[0]; a++)
        if (!strcmp(alias[a][0], name))
            for (int o = 0; o < t->n_out; o++)
                if (!strcmp(t->out[o], alias[a][1]))
                    return o;
    return -1;
}

void gs_tradeoff_label(const gs_tradeoff_row *r, char *out, size_t cap)
{
    int k = snprintf(out, cap, "%s h %g", r->level, r->h);
    if (r->refine && k >= 0 && (size_t)k < cap)
        k += snprintf(out + k, cap - (size_t)k, " refine %d", r->refine);
    if (r->scale != 1.0 && k >= 0 && (size_t)k < cap)
        k += snprintf(out + k, cap - (size_t)k, " counts x %g", r->scale);
    if (r->scheme[0] && k >= 0 && (size_t)k < cap)
        snprintf(out + k, cap - (size_t)k, r->zeta != 0.0 ? " (%s, damping %g)" : " (%s)", r->scheme, r->zeta);
}

/* The reference: every error 0 (its own is not known: no candidate), but
 * the peak force's, which may be against the reference's model converged
 * further in the step. */
static bool is_reference(const gs_tradeoff *t, const gs_tradeoff_row *r)
{
    for (int o = 0; o < t->n_out; o++)
        if (!(r->err[o] == 0.0) && strcmp(t->out[o], "force") != 0)
            return false;
    return true;
}

static bool meets(const gs_tradeoff_row *r, const gs_tradeoff_choice *c)
{
    for (int k = 0; k < c->n_targets; k++) {
        double e = r->err[c->target_out[k]];
        if (!(e <= c->target[k]))
            return false;
    }
    return true;
}

gs_err gs_tradeoff_choose(const gs_tradeoff *t, const char *scene, int n, const int *out, const double *target,
                          gs_tradeoff_choice *c, const char *field, gs_diag *d)
{
    memset(c, 0, sizeof *c);
    c->row = -1;
    if (n < 1 || n > GS_TRADEOFF_MAX_OUT)
        return gs_diag_set(d, GS_ESCHEMA, field, "give 1 to %d targets", GS_TRADEOFF_MAX_OUT);
    c->n_targets = n;
    for (int k = 0; k < n; k++) {
        c->target_out[k] = out[k];
        c->target[k] = target[k];
    }
    /* Candidates in cost order; equal costs keep the table's order (a
     * stable sort, as advise's). */
    int *cand = malloc(sizeof(int) * (size_t)(t->n_rows + 1));
    if (!cand)
        return GS_ENOMEM;
    int nc = 0, nscene = 0;
    for (int i = 0; i < t->n_rows; i++) {
        const gs_tradeoff_row *r = &t->rows[i];
        if (strcmp(r->scene, scene) || !isfinite(r->cost))
            continue;
        nscene++;
        if (is_reference(t, r))
            continue;
        int j = nc++;
        while (j > 0 && t->rows[cand[j - 1]].cost > r->cost) {
            cand[j] = cand[j - 1];
            j--;
        }
        cand[j] = i;
    }
    c->n_candidates = nc;
    if (nscene == 0) {
        free(cand);
        return gs_diag_set(d, GS_ENOTFOUND, field, "the trade-off table %.160s has no %s rows", gs_tradeoff_path(),
                           scene);
    }
    if (nc == 0) {
        free(cand);
        return gs_diag_set(d, GS_ENOTFOUND, field, "the trade-off table has no %s row besides the reference", scene);
    }
    int pick = -1;
    for (int j = 0; j < nc && pick < 0; j++)
        if (meets(&t->rows[cand[j]], c))
            pick = j;
    if (pick < 0) {
        /* As advise: the best error reached on each target, by some setting. */
        char best[200] = "";
        size_t bl = 0;
        for (int k = 0; k < n; k++) {
            double e = INFINITY;
            for (int j = 0; j < nc; j++)
                e = fmin(e, isnan(t->rows[cand[j]].err[out[k]]) ? INFINITY : t->rows[cand[j]].err[out[k]]);
            int w = snprintf(best + bl, sizeof best - bl, "%s%s %.3g", k ? ", " : "", t->out[out[k]], e);
            if (w > 0 && bl + (size_t)w < sizeof best)
                bl += (size_t)w;
        }
        free(cand);
        char want[160] = "";
        size_t wl = 0;
        for (int k = 0; k < n; k++) {
            int w = snprintf(want + wl, sizeof want - wl, "%s%s <= %g", k ? ", " : "", t->out[out[k]], target[k]);
            if (w > 0 && wl + (size_t)w < sizeof want)
                wl += (size_t)w;
        }
        return gs_diag_set(d, GS_ERANGE, field,
                           "no measured setting meets the targets (%s) on %s; best reached: %s (gearctl advise "
                           "lists the closest settings)", want, scene, best);
    }
    c->row = cand[pick];
    c->rejected = malloc(sizeof(int) * (size_t)(pick + 1));
    if (!c->rejected) {
        free(cand);
        return GS_ENOMEM;
    }
    for (int j = 0; j < pick; j++)
        if (t->rows[cand[j]].cost < t->rows[c->row].cost)
            c->rejected[c->n_rejected++] = cand[j];
    free(cand);
    return GS_OK;
}

void gs_tradeoff_choice_clear(gs_tradeoff_choice *c)
{
    free(c->rejected);
    memset(c, 0, sizeof *c);
    c->row = -1;
}
