/* SPDX-License-Identifier: MIT
 * Batch driver of the QP solver for the cross-check against cvxopt
 * (tests/validation/test_qp_cvxopt.py).
 *
 * Usage: qp_driver [FILE]   (reads stdin without FILE)
 *
 * Input: whitespace-separated numbers, one problem after another:
 *     n n_eq n_in n_warm
 *     H (n*n, row-major)  c (n)
 *     E (n_eq*n)  e (n_eq)  G (n_in*n)  g (n_in)
 *     warm (n_warm inequality indices)
 * Numbers are read with strtod, so 17 significant digits round-trip exactly.
 *
 * Output: one JSON object per problem and line,
 *     {"id":k,"cold":S,"hot":S,"warm":S}
 * with three solves of the same problem: "cold" by gs_qp_solve without warm
 * start, "hot" by gs_qp_solve_factored warm-started from the cold solve's
 * active set (skipped, null, when the cold solve failed), "warm" by
 * gs_qp_solve from the given warm list (null when n_warm = 0). Each S is
 *     {"status":"ok"|error code,"iterations":i,"n_active":a,"warm_kept":w,
 *      "eq_dependent":d,"weak":k,"conflict_eq":ce,"conflict_in":ci,
 *      "objective":f,"x":[...],"lambda_eq":[...],"lambda_in":[...],"active":[...]}
 * Exit status 0 unless the input is malformed or memory runs out. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/qp.h"

typedef struct {
    const char *p;
} reader;

static int read_num(reader *rd, double *out)
{
    char *end;
    double v = strtod(rd->p, &end);
    if (end == rd->p)
        return 0;
    rd->p = end;
    *out = v;
    return 1;
}

static int read_int(reader *rd, int *out)
{
    double v;
    if (!read_num(rd, &v) || v != (double)(int)v)
        return 0;
    *out = (int)v;
    return 1;
}

static int read_vec(reader *rd, double *a, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!read_num(rd, &a[i]))
            return 0;
    return 1;
}

static int at_end(reader *rd)
{
    while (*rd->p == ' ' || *rd->p == '\n' || *rd->p == '\t' || *rd->p == '\r')
        rd->p++;
    return *rd->p == '\0';
}

static char *read_stream(FILE *f)
{
    size_t cap = 1 << 20, n = 0;
    char *buf = malloc(cap);
    if (!buf)
        return NULL;
    for (;;) {
        if (n + 1 == cap) {
            char *nb = realloc(buf, 2 * cap);
            if (!nb) {
                free(buf);
                return NULL;
            }
            buf = nb;
            cap *= 2;
        }
        size_t r = fread(buf + n, 1, cap - n - 1, f);
        if (r == 0)
            break;
        n += r;
    }
    buf[n] = '\0';
    return buf;
}

static void print_vec(const char *name, const double *a, int n)
{
    printf(",\"%s\":[", name);
    for (int i = 0; i < n; i++)
        printf("%s%.17g", i ? "," : "", a[i]);
    printf("]");
}

static void print_solve(const char *name, gs_err e, const gs_qp_result *r, const gs_qp_problem *p)
{
    printf(",\"%s\":{\"status\":\"%s\",\"iterations\":%d,\"n_active\":%d,\"warm_kept\":%d,"
           "\"eq_dependent\":%d,\"weak\":%d,\"conflict_eq\":%d,\"conflict_in\":%d",
           name, gs_errcode(e), r->iterations, e == GS_OK ? r->n_active : 0, r->n_warm_kept,
           r->n_eq_dependent, r->n_weak, r->conflict_eq, r->conflict_in);
    if (e == GS_OK) {
        printf(",\"objective\":%.17g", r->objective);
        print_vec("x", r->x, p->n);
        print_vec("lambda_eq", r->lambda_eq, p->n_eq);
        print_vec("lambda_in", r->lambda_in, p->n_in);
        printf(",\"active\":[");
        for (int i = 0; i < r->n_active; i++)
            printf("%s%d", i ? "," : "", r->active[i]);
        printf("]");
    }
    printf("}");
}

int main(int argc, char **argv)
{
    FILE *f = argc > 1 ? fopen(argv[1], "r") : stdin;
    if (!f) {
        fprintf(stderr, "qp_driver: cannot open %s\n", argv[1]);
        return 2;
    }
    char *text = read_stream(f);
    if (f != stdin)
        fclose(f);
    if (!text) {
        fprintf(stderr, "qp_driver: out of memory\n");
        return 2;
    }
    reader rd = {text};
    int status = 0;
    for (int id = 0; !at_end(&rd); id++) {
        int n, neq, nin, nwarm;
        if (!read_int(&rd, &n) || !read_int(&rd, &neq) || !read_int(&rd, &nin) ||
            !read_int(&rd, &nwarm) || n < 1 || neq < 0 || nin < 0 || nwarm < 0) {
            fprintf(stderr, "qp_driver: bad header of problem %d\n", id);
            status = 2;
            break;
        }
        size_t un = (size_t)n;
        double *H = malloc(un * un * sizeof(double)), *c = malloc(un * sizeof(double));
        double *E = malloc((un * neq + 1) * sizeof(double));
        double *e = malloc((neq + 1) * sizeof(double));
        double *G = malloc((un * nin + 1) * sizeof(double));
        double *g = malloc((nin + 1) * sizeof(double));
        int *warm = malloc((nwarm + 1) * sizeof(int));
        double *x = malloc(un * sizeof(double)), *leq = malloc((neq + 1) * sizeof(double));
        double *lin = malloc((nin + 1) * sizeof(double));
        int *act = malloc((nin + 1) * sizeof(int)), *act_cold = malloc((nin + 1) * sizeof(int));
        gs_qp *q = NULL;
        if (!H || !c || !E || !e || !G || !g || !warm || !x || !leq || !lin || !act || !act_cold ||
            gs_qp_new(n, neq, nin, &q) != GS_OK) {
            fprintf(stderr, "qp_driver: out of memory\n");
            status = 2;
        }
        int ok = status == 0 && read_vec(&rd, H, un * un) && read_vec(&rd, c, un) &&
                 read_vec(&rd, E, un * neq) && read_vec(&rd, e, neq) &&
                 read_vec(&rd, G, un * nin) && read_vec(&rd, g, nin);
        for (int i = 0; ok && i < nwarm; i++)
            ok = read_int(&rd, &warm[i]);
        if (!ok) {
            if (status == 0)
                fprintf(stderr, "qp_driver: bad data in problem %d\n", id);
            status = 2;
        } else {
            gs_qp_problem p = {.n = n, .H = H, .c = c, .n_eq = neq, .E = E, .e = e,
                               .n_in = nin, .G = G, .g = g};
            gs_qp_result r = {.x = x, .lambda_eq = leq, .lambda_in = lin, .active = act};
            printf("{\"id\":%d", id);
            gs_err ec = gs_qp_solve(q, &p, NULL, 0, &r);
            print_solve("cold", ec, &r, &p);
            if (ec == GS_OK) {
                int na = r.n_active;
                memcpy(act_cold, act, (size_t)na * sizeof(int));
                /* The factor of the cold solve is still in the workspace. */
                gs_err eh = gs_qp_solve_factored(q, &p, act_cold, na, &r);
                print_solve("hot", eh, &r, &p);
            } else {
                printf(",\"hot\":null");
            }
            if (nwarm > 0) {
                gs_err ew = gs_qp_solve(q, &p, warm, nwarm, &r);
                print_solve("warm", ew, &r, &p);
            } else {
                printf(",\"warm\":null");
            }
            printf("}\n");
        }
        gs_qp_free(&q);
        free(H);
        free(c);
        free(E);
        free(e);
        free(G);
        free(g);
        free(warm);
        free(x);
        free(leq);
        free(lin);
        free(act);
        free(act_cold);
        if (status)
            break;
    }
    free(text);
    return status;
}
