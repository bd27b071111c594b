/* SPDX-License-Identifier: MIT
 * Sweep points on groups of MPI ranks inside one MPI job
 * (include/gearsim/sweep.h, docs/explanation/modal.md "Sweeps").
 *
 * Rank 0 broadcasts GS_OP_SWEEP through the world engine; every rank then
 * duplicates the world communicator and splits it into `groups` groups of
 * consecutive ranks: all ranks, rank 0 leading group 0, or, with a
 * dedicated dispatcher, ranks 1 to n-1 (rank 0 computes nothing). Each
 * group runs a replicated engine (src/engine) over its own communicator:
 * its first rank (the leader) drives it, the others serve it.
 *
 * Rank 0 coordinates. It hands each other leader points in batches (tag
 * CMD: an array of point indices; a single -1 stops the leader), keeping a
 * few more points queued on every group than it is computing, so that no
 * group waits for rank 0; the batch grows when points are cheap. Leaders
 * send back finished points in batches of compact records (tag RES: point,
 * error, the row's values, a failed point's message), at once when their
 * queue runs low and otherwise every few hundredths of a second, and a last
 * BYE when they stop. Rank 0 computes group 0's points (unless dedicated)
 * in slices between its other work; when it has nothing to compute its
 * caller waits with a timeout (gs_sweep_run_idle) instead of spinning.
 * Waiting leaders poll with short sleeps (TOOLCHAIN.md gotcha 3). */
#include <json-c/json.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gearsim/step.h"
#include "gearsim/sweep.h"
#include "gearsim/util.h"

enum { TAG_CMD = 41, TAG_RES = 42, TAG_BYE = 43 };

/* Points handed to a group and not back, at most; and the seconds of work
 * rank 0 keeps handed to each group (well above the 5 ms its caller may
 * wait between two looks at the groups' rows). */
#define MAX_AHEAD 64
#define AHEAD_S 0.05
/* A leader sends its finished points at least this often (s). */
#define FLUSH_S 0.02
/* Records in one RES message, at most. */
#define MAX_BATCH 64

/* One finished point on the wire: the header, n_cols values, then `len`
 * bytes of message (a failed point's), padded to 8 bytes. */
typedef struct rec_head {
    int32_t point, err, len, pad;
} rec_head;

/* A point under way on this rank's group engine. */
typedef struct point_run {
    int point;               /* -1: none */
    gs_sweep_meter *meter;
    int64_t chunk;           /* steps per slice, adapted to the rate */
} point_run;

struct gs_sweep_run {
    const gs_sweep *sw;
    gs_engine *world;
    MPI_Comm comm, group;    /* group: MPI_COMM_NULL on a dedicated rank 0 */
    int size, groups, n_cols;
    bool dedicated;          /* rank 0 computes no points */
    int first_remote;        /* the first group not led by rank 0 */
    int *leader;             /* world rank leading group g */
    int *group_of;           /* world rank -> the group it leads, -1 */
    int *ahead;              /* group g: points handed to it and not back */
    int *queue, nq, qi;      /* points to compute, in order; next to hand out */
    int64_t *sbuf;           /* a batch being handed out */
    char *rbuf;              /* records being received */
    size_t rbuf_cap;
    gs_engine *geng;         /* group 0's engine (rank 0 drives it), NULL dedicated */
    point_run own;
    gs_sweep_result *res;    /* finished, not yet taken */
    int nres, rtake;
    int n_done;
    double t0;
    bool ended;
};

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

/* ------------------------------------------------------------ records */

static size_t rec_size(int n_cols, int len)
{
    return sizeof(rec_head) + (size_t)n_cols * sizeof(double) + (size_t)((len + 7) / 8 * 8);
}

/* Append x to buf at *k (room for a record of the longest message). */
static void rec_put(char *buf, size_t *k, int n_cols, const gs_sweep_result *x)
{
    rec_head h = {.point = x->point, .err = (int32_t)x->err, .len = 0};
    if (x->err != GS_OK)
        h.len = (int32_t)strnlen(x->message, sizeof x->message - 1) + 1;
    memcpy(buf + *k, &h, sizeof h);
    memcpy(buf + *k + sizeof h, x->row, (size_t)n_cols * sizeof(double));
    if (h.len)
        memcpy(buf + *k + sizeof h + (size_t)n_cols * sizeof(double), x->message, (size_t)h.len);
    *k += rec_size(n_cols, h.len);
}

/* The next record of buf[0, n) at *k into x; false at the end or on a
 * record that does not fit. */
static bool rec_get(const char *buf, size_t n, size_t *k, int n_cols, gs_sweep_result *x)
{
    rec_head h;
    if (*k + sizeof h > n)
        return false;
    memcpy(&h, buf + *k, sizeof h);
    if (h.len < 0 || h.len > (int32_t)sizeof x->message || *k + rec_size(n_cols, h.len) > n)
        return false;
    memset(x, 0, sizeof *x);
    x->point = h.point;
    x->err = (gs_err)h.err;
    memcpy(x->row, buf + *k + sizeof h, (size_t)n_cols * sizeof(double));
    if (h.len) {
        memcpy(x->message, buf + *k + sizeof h + (size_t)n_cols * sizeof(double), (size_t)h.len);
        x->message[sizeof x->message - 1] = '\0';
    }
    *k += rec_size(n_cols, h.len);
    return true;
}

/* Receive one RES message (probed: st) and push its records; the number of
 * records. */
static int recv_records(gs_sweep_run *r, const MPI_Status *st)
{
    int n = 0, cnt = 0;
    MPI_Get_count(st, MPI_BYTE, &cnt);
    if ((size_t)cnt > r->rbuf_cap) {
        char *nb = realloc(r->rbuf, (size_t)cnt);
        if (!nb)
            MPI_Abort(r->comm, 3);
        r->rbuf = nb;
        r->rbuf_cap = (size_t)cnt;
    }
    MPI_Recv(r->rbuf, cnt, MPI_BYTE, st->MPI_SOURCE, TAG_RES, r->comm, MPI_STATUS_IGNORE);
    size_t k = 0;
    gs_sweep_result x;
    while (rec_get(r->rbuf, (size_t)cnt, &k, r->n_cols, &x)) {
        push(r, &x);
        n++;
    }
    return n;
}

/* ------------------------------------------------------------ rank 0 */

/* The color of a rank: its group, or MPI_UNDEFINED for a dedicated rank 0. */
static int color_of(int rank, int size, int groups, bool dedicated)
{
    if (!dedicated)
        return (int)((int64_t)rank * groups / size);
    return rank == 0 ? MPI_UNDEFINED : (int)((int64_t)(rank - 1) * groups / (size - 1));
}

gs_err gs_sweep_run_begin(gs_engine *world, const gs_sweep *sw, const unsigned char *todo, int groups,
                          bool dedicated, gs_sweep_run **out, gs_diag *d)
{
    *out = NULL;
    int size = gs_engine_size(world);
    if (groups < 1 || groups > size)
        return gs_diag_set(d, GS_ERANGE, "groups", "%d group(s) of ranks asked; this daemon has %d rank(s)", groups,
                           size);
    if (dedicated && groups > size - 1)
        return gs_diag_set(d, GS_ERANGE, "groups", "%d group(s) of ranks asked besides a dedicated dispatcher; "
                           "this daemon has %d rank(s), so at most %d", groups, size, size - 1);
    gs_sweep_run *r = gs_calloc(1, sizeof *r);
    int n = gs_sweep_points(sw);
    if (!r)
        return GS_ENOMEM;
    r->leader = gs_calloc((size_t)groups, sizeof(int));
    r->ahead = gs_calloc((size_t)groups, sizeof(int));
    r->group_of = gs_calloc((size_t)size, sizeof(int));
    r->queue = gs_calloc((size_t)n + 1, sizeof(int));
    r->res = gs_calloc((size_t)n + 1, sizeof *r->res);
    r->sbuf = gs_calloc((size_t)MAX_AHEAD + 1, sizeof(int64_t));
    if (!r->leader || !r->ahead || !r->group_of || !r->queue || !r->res || !r->sbuf) {
        free(r->leader), free(r->ahead), free(r->group_of), free(r->queue), free(r->res), free(r->sbuf), free(r);
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
    json_object_object_add(pl, "dedicated", json_object_new_boolean(dedicated));
    json_object_object_add(pl, "todo", tl);
    const char *txt = json_object_to_json_string_ext(pl, JSON_C_TO_STRING_PLAIN);
    gs_err e = gs_engine_run(world, GS_OP_SWEEP, txt, strlen(txt), d, NULL);
    json_object_put(pl);
    if (e != GS_OK) {
        free(r->leader), free(r->ahead), free(r->group_of), free(r->queue), free(r->res), free(r->sbuf), free(r);
        return e;
    }
    r->sw = sw;
    r->world = world;
    r->size = size;
    r->groups = groups;
    r->dedicated = dedicated;
    r->first_remote = dedicated ? 0 : 1;
    r->n_cols = gs_sweep_columns(sw);
    r->own.point = -1;
    r->t0 = gs_now();
    MPI_Comm_dup(gs_engine_comm(world), &r->comm);
    MPI_Comm_split(r->comm, color_of(0, size, groups, dedicated), 0, &r->group);
    for (int k = 0; k < size; k++)
        r->group_of[k] = -1;
    for (int g = 0, k = 0; g < groups; g++) {
        while (color_of(k, size, groups, dedicated) != g)
            k++;
        r->leader[g] = k;
        r->group_of[k] = g;
    }
    if (!dedicated) {
        gs_engine_new(r->group, &r->geng);
        gs_engine_set_hook(r->geng, meter_hook, &r->own);
    }
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

bool gs_sweep_run_idle(const gs_sweep_run *r)
{
    return r->ended || (r->own.point < 0 && (r->dedicated || r->qi >= r->nq));
}

static void receive_results(gs_sweep_run *r)
{
    for (;;) {
        int flag = 0;
        MPI_Status st;
        MPI_Iprobe(MPI_ANY_SOURCE, TAG_RES, r->comm, &flag, &st);
        if (!flag)
            return;
        int g = st.MPI_SOURCE >= 0 && st.MPI_SOURCE < r->size ? r->group_of[st.MPI_SOURCE] : -1;
        int k = recv_records(r, &st);
        if (g >= 0)
            r->ahead[g] -= k;
    }
}

/* Points to keep handed to a group: enough for about AHEAD_S seconds of its
 * work at the rate seen so far (2 before any point is back), so that a
 * group never waits for rank 0. */
static int ahead_target(const gs_sweep_run *r)
{
    if (r->n_done < 1)
        return 2;
    double per_point = (gs_now() - r->t0) * r->groups / r->n_done; /* one group's seconds per point */
    double want = per_point > 0 ? AHEAD_S / per_point + 1.0 : MAX_AHEAD;
    return want < 2 ? 2 : want > MAX_AHEAD ? MAX_AHEAD : (int)want;
}

/* Take what the groups finished and top up each group's queue. */
static void dispatch(void *ctx)
{
    gs_sweep_run *r = ctx;
    receive_results(r);
    int target = ahead_target(r);
    for (int g = r->first_remote; g < r->groups && r->qi < r->nq; g++) {
        int want = target - r->ahead[g];
        /* At the end, the last points are shared out evenly. */
        int fair = (r->nq - r->qi + r->groups - 1) / r->groups;
        if (want > fair)
            want = fair;
        if (want < 1 || (r->ahead[g] > 1 && want < target / 2))
            continue; /* topped up in larger batches */
        int k = 0;
        while (k < want && r->qi < r->nq)
            r->sbuf[k++] = r->queue[r->qi++];
        r->ahead[g] += k;
        MPI_Send(r->sbuf, k, MPI_INT64_T, r->leader[g], TAG_CMD, r->comm);
    }
}

void gs_sweep_run_poll(gs_sweep_run *r, double slice_s)
{
    if (r->ended)
        return;
    dispatch(r);
    if (r->dedicated)
        return;
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
    for (int g = r->first_remote; g < r->groups; g++) {
        int64_t stop = -1;
        MPI_Send(&stop, 1, MPI_INT64_T, r->leader[g], TAG_CMD, r->comm);
    }
    /* Results that crossed the stop are complete points: kept. */
    for (int g = r->first_remote; g < r->groups; g++)
        for (;;) {
            MPI_Status st;
            MPI_Probe(r->leader[g], MPI_ANY_TAG, r->comm, &st);
            if (st.MPI_TAG == TAG_BYE) {
                int bye;
                MPI_Recv(&bye, 1, MPI_INT, r->leader[g], TAG_BYE, r->comm, MPI_STATUS_IGNORE);
                break;
            }
            recv_records(r, &st);
        }
    gs_sweep_meter_free(&r->own.meter);
    r->own.point = -1;
    if (r->geng) {
        gs_diag d;
        gs_engine_run(r->geng, GS_OP_SHUTDOWN, NULL, 0, &d, NULL);
        gs_engine_free(&r->geng);
    }
    if (r->group != MPI_COMM_NULL)
        MPI_Comm_free(&r->group);
    MPI_Comm_free(&r->comm);
}

void gs_sweep_run_free(gs_sweep_run **pr)
{
    if (!pr || !*pr)
        return;
    gs_sweep_run *r = *pr;
    gs_sweep_run_end(r);
    free(r->leader), free(r->ahead), free(r->group_of), free(r->queue), free(r->res), free(r->sbuf), free(r->rbuf);
    free(r);
    *pr = NULL;
}

/* ------------------------------------------------------------ other ranks */

/* A leader's points: handed out by rank 0, not yet started. */
typedef struct lead_queue {
    int64_t *p;
    int n, i, cap;
    bool stop;
} lead_queue;

/* Receive one CMD message (probed: st) into q. */
static void recv_cmd(MPI_Comm comm, const MPI_Status *st, lead_queue *q)
{
    int cnt = 0;
    MPI_Get_count(st, MPI_INT64_T, &cnt);
    if (q->i > 0) { /* move what is left to the front */
        memmove(q->p, q->p + q->i, (size_t)(q->n - q->i) * sizeof *q->p);
        q->n -= q->i;
        q->i = 0;
    }
    if (q->n + cnt > q->cap) {
        int cap = q->n + cnt + MAX_AHEAD;
        int64_t *np = realloc(q->p, (size_t)cap * sizeof *np);
        if (!np)
            MPI_Abort(comm, 3);
        q->p = np;
        q->cap = cap;
    }
    MPI_Recv(q->p + q->n, cnt, MPI_INT64_T, 0, TAG_CMD, comm, MPI_STATUS_IGNORE);
    if (cnt >= 1 && q->p[q->n] < 0)
        q->stop = true;
    else
        q->n += cnt;
}

/* Take every CMD message already there; with `wait`, wait for one first
 * (spinning briefly, then sleeping). */
static void take_cmds(MPI_Comm comm, lead_queue *q, bool wait)
{
    if (wait) {
        /* The batch's length is not known before it comes: probe, with
         * the sleeps of gs_mpi_wait_idle. */
        double t0 = gs_now();
        for (;;) {
            int flag = 0;
            MPI_Status st;
            MPI_Iprobe(0, TAG_CMD, comm, &flag, &st);
            if (flag)
                break;
            if (gs_now() - t0 >= 0.005) {
                struct timespec ts = {0, 500000};
                nanosleep(&ts, NULL);
            }
        }
    }
    for (;;) {
        int flag = 0;
        MPI_Status st;
        MPI_Iprobe(0, TAG_CMD, comm, &flag, &st);
        if (!flag)
            return;
        recv_cmd(comm, &st, q);
    }
}

/* Send the finished records in buf[0, *k) to rank 0. */
static void flush_results(MPI_Comm comm, char *buf, size_t *k, int *nrec, double *t_flush)
{
    if (*nrec > 0)
        MPI_Send(buf, (int)*k, MPI_BYTE, 0, TAG_RES, comm);
    *k = 0;
    *nrec = 0;
    *t_flush = gs_now();
}

static void lead(const gs_sweep *sw, MPI_Comm comm, gs_engine *geng)
{
    point_run pr = {.point = -1};
    gs_engine_set_hook(geng, meter_hook, &pr);
    int n_cols = gs_sweep_columns(sw);
    size_t cap = (size_t)MAX_BATCH * rec_size(n_cols, (int)sizeof(((gs_sweep_result *)0)->message)), k = 0;
    char *buf = malloc(cap);
    lead_queue q = {0};
    if (!buf)
        MPI_Abort(comm, 3);
    int nrec = 0;
    double t_flush = gs_now();
    for (;;) {
        take_cmds(comm, &q, q.i >= q.n && !q.stop);
        if (q.stop)
            break;
        int64_t cmd = q.p[q.i++];
        gs_sweep_result x;
        bool done = true;
        if (point_start(sw, geng, &pr, (int)cmd, &x) == GS_OK)
            while (!point_slice(geng, &pr, 0.05, &x, NULL, NULL)) {
                take_cmds(comm, &q, false);
                if (q.stop) { /* the point under way is dropped */
                    gs_sweep_meter_free(&pr.meter);
                    pr.point = -1;
                    done = false;
                    break;
                }
            }
        if (done)
            rec_put(buf, &k, n_cols, &x), nrec++;
        if (q.stop)
            break;
        /* Send now when the queue runs low (rank 0 tops it up on what comes
         * back), when the batch is full, or when the last send is old. */
        take_cmds(comm, &q, false);
        if (nrec > 0 && (q.n - q.i <= 1 || nrec >= MAX_BATCH || q.stop || gs_now() - t_flush >= FLUSH_S))
            flush_results(comm, buf, &k, &nrec, &t_flush);
    }
    flush_results(comm, buf, &k, &nrec, &t_flush);
    int bye = 1;
    MPI_Send(&bye, 1, MPI_INT, 0, TAG_BYE, comm);
    free(buf);
    free(q.p);
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
    json_object *spec = NULL, *g = NULL, *ded = NULL;
    gs_sweep *sw = NULL;
    gs_diag d;
    if (!pl || !json_object_object_get_ex(pl, "spec", &spec) || !json_object_object_get_ex(pl, "groups", &g) ||
        gs_sweep_parse_trusted(spec, &sw, &d) != GS_OK) {
        /* Rank 0 parsed the same text: only memory can fail here. */
        fprintf(stderr, "gearsimd: rank %d cannot take part in the sweep\n", rank);
        MPI_Abort(world, 3);
    }
    int groups = json_object_get_int(g);
    bool dedicated = json_object_object_get_ex(pl, "dedicated", &ded) && json_object_get_boolean(ded);
    MPI_Comm comm, group;
    MPI_Comm_dup(world, &comm);
    int color = color_of(rank, size, groups, dedicated);
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
