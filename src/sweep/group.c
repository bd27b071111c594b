/* SPDX-License-Identifier: MIT
 * Sweep points on groups of MPI ranks inside one MPI job
 * (include/gearsim/sweep.h, docs/explanation/modal.md "Sweeps").
 *
 * Rank 0 broadcasts GS_OP_SWEEP through the world engine; every rank then
 * duplicates the world communicator and splits it into `groups` groups of
 * consecutive ranks. Each group runs a replicated engine (src/engine) over its
 * own communicator: its first rank (the leader) drives it, the others serve
 * it. Rank 0 leads group 0 and coordinates: it sends a point to a leader
 * when that group is free (tag CMD: the point, or -1 to stop), leaders send
 * back the point's row (tag RES) and a last BYE when they stop. Rank 0
 * computes group 0's points in slices between its other work. Waiting
 * leaders poll with short sleeps (TOOLCHAIN.md gotcha 3). */
#include <json-c/json.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/step.h"
#include "gearsim/sweep.h"
#include "gearsim/util.h"

enum { TAG_CMD = 41, TAG_RES = 42, TAG_BYE = 43 };

/* A point under way on this rank's group engine. */
typedef struct point_run {
    int point;               /* -1: none */
    gs_sweep_meter *meter;
    int64_t chunk;           /* steps per slice, adapted to the rate */
} point_run;

struct gs_sweep_run {
    const gs_sweep *sw;
    gs_engine *world;
    MPI_Comm comm, group;
    int size, groups;
    int *leader;             /* world rank leading group g */
    int *busy;               /* group g: its point, -1 idle, -2 stopped */
    int *queue, nq, qi;      /* points to compute, in order; next to hand out */
    gs_engine *geng;         /* group 0's engine (rank 0 drives it) */
    point_run own;
    gs_sweep_result *res;    /* finished, not yet taken */
    int nres, rtake;
    int n_done;
    double t0;
    bool ended;
};

static int color_of(int rank, int size, int groups) { return (int)((int64_t)rank * groups / size); }

/* Called by the group engine after every step on its rank 0. */
static bool meter_hook(gs_engine *e, void *user)
{
    point_run *pr = user;
    if (pr->meter)
        gs_sweep_meter_step(pr->meter, gs_engine_system(e));
    return true;
}

static void fail(gs_sweep_result *r, gs_err e, const gs_diag *d)
{
    r->err = e;
    snprintf(r->message, sizeof r->message, "%.150s%s%.320s", d->field, d->field[0] ? ": " : "",
             d->message[0] ? d->message : gs_strerror(e));
}

/* Load point p into the group engine and arm its meter. */
static gs_err point_start(const gs_sweep *sw, gs_engine *geng, point_run *pr, int p, gs_sweep_result *r)
{
    gs_diag d;
    gs_diag_clear(&d);
    memset(r, 0, sizeof *r);
    r->point = p;
    char *text = NULL;
    gs_err e = gs_sweep_point_scene(sw, p, &text, &d);
    if (e == GS_OK)
        e = gs_engine_run(geng, GS_OP_LOAD, text, strlen(text), &d, NULL);
    free(text);
    if (e == GS_OK)
        e = gs_sweep_meter_new(sw, p, gs_engine_system(geng), &pr->meter);
    if (e != GS_OK) {
        fail(r, e, &d);
        return e;
    }
    pr->point = p;
    if (pr->chunk < 1)
        pr->chunk = 50;
    return GS_OK;
}

/* Steps of the point for about slice_s seconds; true when the point ended
 * (row or error in r). `between` (may be NULL) runs between chunks. */
static bool point_slice(gs_engine *geng, point_run *pr, double slice_s, gs_sweep_result *r,
                        void (*between)(void *), void *ctx)
{
    double t0 = gs_now();
    do {
        int64_t left = gs_sweep_meter_steps_left(pr->meter);
        int64_t n = pr->chunk < left ? pr->chunk : left;
        gs_diag d;
        gs_diag_clear(&d);
        double c0 = gs_now();
        int64_t done = 0;
        gs_err e = n > 0 ? gs_engine_run(geng, GS_OP_STEP, &n, sizeof n, &d, &done) : GS_OK;
        double dt = gs_now() - c0;
        if (dt > 0 && done > 0) {
            /* Chunks of about a fifth of the slice, growing at most twofold. */
            int64_t want = (int64_t)(0.2 * slice_s * (double)done / dt);
            pr->chunk = want > 2 * pr->chunk ? 2 * pr->chunk : want < 1 ? 1 : want;
        }
        if (e != GS_OK) {
            gs_system *sys = gs_engine_system(geng);
            if (sys && sys->diag.message[0])
                d = sys->diag;
            else
                gs_diag_set(&d, e, "", "%s", e == GS_ENOCONV ? "the step's Newton iteration did not converge"
                                                            : gs_strerror(e));
            fail(r, e, &d);
            gs_sweep_meter_free(&pr->meter);
            pr->point = -1;
            return true;
        }
        if (gs_sweep_meter_steps_left(pr->meter) <= 0) {
            gs_sweep_meter_row(pr->meter, r->row);
            gs_sweep_meter_free(&pr->meter);
            pr->point = -1;
            return true;
        }
        if (between)
            between(ctx);
    } while (gs_now() - t0 < slice_s);
    return false;
}

static void push(gs_sweep_run *r, const gs_sweep_result *x)
{
    r->res[r->nres++] = *x;
    r->n_done++;
}

/* ------------------------------------------------------------ rank 0 */

gs_err gs_sweep_run_begin(gs_engine *world, const gs_sweep *sw, const unsigned char *todo, int groups,
                          gs_sweep_run **out, gs_diag *d)
{
    *out = NULL;
    int size = gs_engine_size(world);
    if (groups < 1 || groups > size)
        return gs_diag_set(d, GS_ERANGE, "groups", "%d group(s) of ranks asked; this daemon has %d rank(s)", groups,
                           size);
    gs_sweep_run *r = gs_calloc(1, sizeof *r);
    int n = gs_sweep_points(sw);
    if (!r)
        return GS_ENOMEM;
    r->leader = gs_calloc((size_t)groups, sizeof(int));
    r->busy = gs_calloc((size_t)groups, sizeof(int));
    r->queue = gs_calloc((size_t)n + 1, sizeof(int));
    r->res = gs_calloc((size_t)n + 1, sizeof *r->res);
    if (!r->leader || !r->busy || !r->queue || !r->res) {
        free(r->leader), free(r->busy), free(r->queue), free(r->res), free(r);
        return GS_ENOMEM;
    }
    json_object *pl = json_object_new_object(), *tl = json_object_new_array();
    json_object *spec = json_tokener_parse(gs_sweep_spec_text(sw));
    for (int p = 0; p < n; p++)
        if (todo[p]) {
            r->queue[r->nq++] = p;
            json_object_array_add(tl, json_object_new_int(p));
        }
    json_object_object_add(pl, "spec", spec);
    json_object_object_add(pl, "groups", json_object_new_int(groups));
    json_object_object_add(pl, "todo", tl);
    const char *txt = json_object_to_json_string_ext(pl, JSON_C_TO_STRING_PLAIN);
    gs_err e = gs_engine_run(world, GS_OP_SWEEP, txt, strlen(txt), d, NULL);
    json_object_put(pl);
    if (e != GS_OK) {
        free(r->leader), free(r->busy), free(r->queue), free(r->res), free(r);
        return e;
    }
    r->sw = sw;
    r->world = world;
    r->size = size;
    r->groups = groups;
    r->own.point = -1;
    r->t0 = gs_now();
    MPI_Comm_dup(gs_engine_comm(world), &r->comm);
    MPI_Comm_split(r->comm, color_of(0, size, groups), 0, &r->group);
    for (int g = 0, k = 0; g < groups; g++) {
        while (color_of(k, size, groups) < g)
            k++;
        r->leader[g] = k;
        r->busy[g] = -1;
    }
    gs_engine_new(r->group, &r->geng);
    gs_engine_set_hook(r->geng, meter_hook, &r->own);
    *out = r;
    return GS_OK;
}

int gs_sweep_run_groups(const gs_sweep_run *r) { return r->groups; }

double gs_sweep_run_rate(const gs_sweep_run *r)
{
    double dt = gs_now() - r->t0;
    return dt > 0 ? r->n_done / dt : 0.0;
}

bool gs_sweep_run_finished(const gs_sweep_run *r) { return r->ended || r->n_done >= r->nq; }

static void receive_results(gs_sweep_run *r)
{
    for (;;) {
        int flag = 0;
        MPI_Status st;
        MPI_Iprobe(MPI_ANY_SOURCE, TAG_RES, r->comm, &flag, &st);
        if (!flag)
            return;
        gs_sweep_result x;
        MPI_Recv(&x, (int)sizeof x, MPI_BYTE, st.MPI_SOURCE, TAG_RES, r->comm, MPI_STATUS_IGNORE);
        push(r, &x);
        for (int g = 1; g < r->groups; g++)
            if (r->leader[g] == st.MPI_SOURCE)
                r->busy[g] = -1;
    }
}

/* Take what the groups finished and give the free ones their next point. */
static void dispatch(void *ctx)
{
    gs_sweep_run *r = ctx;
    receive_results(r);
    for (int g = 1; g < r->groups && r->qi < r->nq; g++)
        if (r->busy[g] == -1) {
            int64_t p = r->queue[r->qi++];
            r->busy[g] = (int)p;
            MPI_Send(&p, 1, MPI_INT64_T, r->leader[g], TAG_CMD, r->comm);
        }
}

void gs_sweep_run_poll(gs_sweep_run *r, double slice_s)
{
    if (r->ended)
        return;
    dispatch(r);
    if (r->own.point < 0 && r->qi < r->nq) {
        gs_sweep_result x;
        if (point_start(r->sw, r->geng, &r->own, r->queue[r->qi++], &x) != GS_OK) {
            push(r, &x);
            return;
        }
    }
    if (r->own.point >= 0) {
        gs_sweep_result x;
        memset(&x, 0, sizeof x);
        x.point = r->own.point;
        if (point_slice(r->geng, &r->own, slice_s, &x, r->groups > 1 ? dispatch : NULL, r))
            push(r, &x);
    }
}

bool gs_sweep_run_take(gs_sweep_run *r, gs_sweep_result *out)
{
    if (r->rtake >= r->nres)
        return false;
    *out = r->res[r->rtake++];
    return true;
}

void gs_sweep_run_end(gs_sweep_run *r)
{
    if (r->ended)
        return;
    r->ended = true;
    for (int g = 1; g < r->groups; g++) {
        int64_t stop = -1;
        MPI_Send(&stop, 1, MPI_INT64_T, r->leader[g], TAG_CMD, r->comm);
    }
    /* Results that crossed the stop are complete points: kept. */
    for (int g = 1; g < r->groups; g++)
        for (;;) {
            MPI_Status st;
            MPI_Probe(r->leader[g], MPI_ANY_TAG, r->comm, &st);
            if (st.MPI_TAG == TAG_BYE) {
                int bye;
                MPI_Recv(&bye, 1, MPI_INT, r->leader[g], TAG_BYE, r->comm, MPI_STATUS_IGNORE);
                break;
            }
            gs_sweep_result x;
            MPI_Recv(&x, (int)sizeof x, MPI_BYTE, r->leader[g], TAG_RES, r->comm, MPI_STATUS_IGNORE);
            push(r, &x);
        }
    gs_sweep_meter_free(&r->own.meter);
    r->own.point = -1;
    gs_diag d;
    gs_engine_run(r->geng, GS_OP_SHUTDOWN, NULL, 0, &d, NULL);
    gs_engine_free(&r->geng);
    MPI_Comm_free(&r->group);
    MPI_Comm_free(&r->comm);
}

void gs_sweep_run_free(gs_sweep_run **pr)
{
    if (!pr || !*pr)
        return;
    gs_sweep_run *r = *pr;
    gs_sweep_run_end(r);
    free(r->leader), free(r->busy), free(r->queue), free(r->res);
    free(r);
    *pr = NULL;
}

/* ------------------------------------------------------------ other ranks */

/* Wait for the next command from rank 0 without burning a core. */
static int64_t wait_cmd(MPI_Comm comm)
{
    int64_t cmd = -1;
    MPI_Request rq;
    MPI_Irecv(&cmd, 1, MPI_INT64_T, 0, TAG_CMD, comm, &rq);
    gs_mpi_wait_idle(&rq, 0.005);
    return cmd;
}

static void lead(const gs_sweep *sw, MPI_Comm comm, gs_engine *geng)
{
    point_run pr = {.point = -1};
    gs_engine_set_hook(geng, meter_hook, &pr);
    for (;;) {
        int64_t cmd = wait_cmd(comm);
        if (cmd < 0)
            break;
        gs_sweep_result x;
        bool stopped = false;
        if (point_start(sw, geng, &pr, (int)cmd, &x) == GS_OK) {
            while (!point_slice(geng, &pr, 0.05, &x, NULL, NULL)) {
                int flag = 0;
                MPI_Iprobe(0, TAG_CMD, comm, &flag, MPI_STATUS_IGNORE);
                if (flag) {
                    stopped = true; /* only a stop comes while a point runs */
                    int64_t stop;
                    MPI_Recv(&stop, 1, MPI_INT64_T, 0, TAG_CMD, comm, MPI_STATUS_IGNORE);
                    break;
                }
            }
        }
        if (stopped) {
            gs_sweep_meter_free(&pr.meter);
            break;
        }
        MPI_Send(&x, (int)sizeof x, MPI_BYTE, 0, TAG_RES, comm);
    }
    int bye = 1;
    MPI_Send(&bye, 1, MPI_INT, 0, TAG_BYE, comm);
    gs_diag d;
    gs_engine_run(geng, GS_OP_SHUTDOWN, NULL, 0, &d, NULL);
}

gs_err gs_sweep_serve(MPI_Comm world, const char *payload, size_t len)
{
    int rank, size;
    MPI_Comm_rank(world, &rank);
    MPI_Comm_size(world, &size);
    json_tokener *tok = json_tokener_new();
    json_object *pl = tok ? json_tokener_parse_ex(tok, payload, (int)len) : NULL;
    json_tokener_free(tok);
    json_object *spec = NULL, *g = NULL;
    gs_sweep *sw = NULL;
    gs_diag d;
    if (!pl || !json_object_object_get_ex(pl, "spec", &spec) || !json_object_object_get_ex(pl, "groups", &g) ||
        gs_sweep_parse(spec, "", NULL, &sw, &d) != GS_OK) {
        /* Rank 0 parsed the same text: only memory can fail here. */
        fprintf(stderr, "gearsimd: rank %d cannot take part in the sweep\n", rank);
        MPI_Abort(world, 3);
    }
    int groups = json_object_get_int(g);
    MPI_Comm comm, group;
    MPI_Comm_dup(world, &comm);
    int color = color_of(rank, size, groups);
    MPI_Comm_split(comm, color, rank, &group);
    int grank;
    MPI_Comm_rank(group, &grank);
    gs_engine *geng;
    if (gs_engine_new(group, &geng) != GS_OK)
        MPI_Abort(world, 3);
    if (grank == 0 && rank != 0)
        lead(sw, comm, geng);
    else
        gs_engine_serve(geng);
    gs_engine_free(&geng);
    MPI_Comm_free(&group);
    MPI_Comm_free(&comm);
    gs_sweep_free(&sw);
    json_object_put(pl);
    return GS_OK;
}
