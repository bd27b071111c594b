/* SPDX-License-Identifier: MIT
 * The telemetry event written straight into one reused buffer: the same
 * members, in the same order, with the same values as gsi_publish of
 * gsi_state_json (the `state` reply's body), without building a JSON tree.
 * Numbers are the shortest text that reads back as the identical double
 * (gs_fmt_double); a non-finite one is null, as gsi_json_scrub makes it. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zmq.h>

#include "gearsim/numfmt.h"
#include "gearsim/util.h"
#include "service/service_internal.h"

typedef struct tbuf {
    char *p;
    size_t n, cap;
    bool oom;
} tbuf;

/* The telemetry events of a chunk are queued here and sent together
 * (gsi_telemetry_flush). ZeroMQ's I/O thread wakes, encrypts and writes
 * once per message, its largest cost per event: a subscriber to the topic
 * `batch` gets the whole queue as one message, {"v":1,"type":"batch",
 * "session":..,"events":[..]}, each event the very text a single telemetry
 * message carries. A subscriber to `telemetry` (or to everything) still
 * gets one message per event: the PUB socket is an XPUB, which tells the
 * daemon which topics someone subscribed to, and each form is written only
 * while someone wants it. The queue is sent before any other event (seq
 * stays in order), at the end of every chunk, when it holds TEL_QUEUE
 * events or would pass TEL_BYTES of text with one more, and when its oldest event is TEL_LAG_S old,
 * so a live view never lags more than that behind the simulation and a
 * burst never nears the socket's high-water mark. TEL_BYTES keeps a
 * message's buffers (ZeroMQ's copy and CurveZMQ's encrypted one) below
 * glibc's 64 KiB free that consolidates and trims the I/O thread's heap
 * (an madvise and a TLB flush per message, measured). */
#define TEL_QUEUE 64
#define TEL_BYTES 60000
#define TEL_LAG_S 0.05
typedef struct svc_telemetry {
    tbuf tb;                   /* the batch header, then the events with ',' between them */
    size_t head;               /* length of the header: {"v":1,..,"events":[ */
    size_t q_end[TEL_QUEUE];   /* end offset of each queued event in tb */
    int q_n;
    double t_first;            /* gs_now() when the first queued event was written */
    int subs_single, subs_batch; /* subscriptions that match `telemetry`, `batch` (XPUB) */
} svc_telemetry;

static void reserve(tbuf *b, size_t more)
{
    if (b->oom || b->n + more + 1 <= b->cap)
        return;
    char *q = gs_grow(b->p, &b->cap, b->n + more + 1, 1);
    if (!q)
        b->oom = true;
    else
        b->p = q;
}

static void put(tbuf *b, const char *s, size_t len)
{
    reserve(b, len);
    if (b->oom)
        return;
    memcpy(b->p + b->n, s, len);
    b->n += len;
}

#define PUT(b, lit) put((b), (lit), sizeof(lit) - 1)

static void put_num(tbuf *b, double x)
{
    reserve(b, GS_FMT_DOUBLE_MAX);
    if (!b->oom)
        b->n += (size_t)gs_fmt_double(b->p + b->n, x);
}

/* A member's key (and what precedes it), then its number. */
static void put_kn(tbuf *b, const char *key, double x)
{
    put(b, key, strlen(key));
    put_num(b, x);
}

/* An integer's decimal digits (as printf's %lld writes them). */
static void put_int(tbuf *b, long long v)
{
    char r[24];
    int n = 0;
    unsigned long long u = v < 0 ? 0ull - (unsigned long long)v : (unsigned long long)v;
    do
        r[sizeof r - 1 - n++] = (char)('0' + u % 10);
    while ((u /= 10) != 0);
    if (v < 0)
        r[sizeof r - 1 - n++] = '-';
    put(b, r + sizeof r - n, (size_t)n);
}

/* A JSON string: quotes, backslashes and control characters escaped; the
 * runs between them copied whole. */
static void put_str(tbuf *b, const char *s)
{
    PUT(b, "\"");
    const char *r = s;
    for (;;) {
        const char *q = r;
        while (*q && *q != '"' && *q != '\\' && (unsigned char)*q >= 0x20)
            q++;
        put(b, r, (size_t)(q - r));
        unsigned char c = (unsigned char)*q;
        if (!c)
            break;
        if (c == '"' || c == '\\') {
            char e[2] = {'\\', (char)c};
            put(b, e, 2);
        } else {
            char e[8];
            snprintf(e, sizeof e, "\\u%04x", c);
            put(b, e, 6);
        }
        r = q + 1;
    }
    PUT(b, "\"");
}

/* A batch message up to its events: {"v":1,"type":"batch","session":..,"events":[ */
static void put_batch_head(tbuf *b, const char *session)
{
    PUT(b, "{\"v\":1,\"type\":\"batch\",\"session\":");
    put_str(b, session);
    PUT(b, ",\"events\":[");
}

/* The subscriptions the XPUB passed on since the last call: byte 1 then
 * the topic prefix (subscribe) or byte 0 then it (the last subscriber of
 * that prefix left). ZeroMQ passes each prefix once however many
 * subscribers share it, so the counts are of distinct prefixes. The empty
 * prefix (everything) asks for single events only: batches go out only
 * while someone subscribed to them by name. A prefix
 * longer than the topic cannot match it (read truncated, still counted
 * right: its length is the returned size). */
static void read_subscriptions(gs_service *s, svc_telemetry *t)
{
    unsigned char m[16];
    int n;
    while ((n = zmq_recv(s->pub, m, sizeof m, ZMQ_DONTWAIT)) >= 1) {
        int d = m[0] == 1 ? 1 : m[0] == 0 ? -1 : 0;
        size_t len = (size_t)n - 1;
        if (len <= 9 && memcmp(m + 1, "telemetry", len) == 0)
            t->subs_single += d;
        if (len >= 1 && len <= 5 && memcmp(m + 1, "batch", len) == 0) /* not "": everything */
            t->subs_batch += d;
    }
}

static svc_telemetry *tel_get(gs_service *s)
{
    if (!s->tel)
        s->tel = calloc(1, sizeof *s->tel);
    return s->tel;
}

void gsi_telemetry_flush(gs_service *s)
{
    svc_telemetry *t = tel_get(s);
    if (!t)
        return;
    if (s->pub)
        read_subscriptions(s, t);
    if (t->q_n == 0)
        return;
    /* A slow subscriber never slows the simulation: drop on a full queue. */
    if (s->pub && t->subs_single > 0) {
        size_t at = t->head;
        for (int i = 0; i < t->q_n; i++) {
            zmq_send(s->pub, "telemetry", 9, ZMQ_SNDMORE | ZMQ_DONTWAIT);
            zmq_send(s->pub, t->tb.p + at, t->q_end[i] - at, ZMQ_DONTWAIT);
            at = t->q_end[i] + 1; /* past the ',' */
        }
    }
    if (s->pub && t->subs_batch > 0) {
        t->tb.n = t->q_end[t->q_n - 1];
        PUT(&t->tb, "]}");
        if (!t->tb.oom) {
            zmq_send(s->pub, "batch", 5, ZMQ_SNDMORE | ZMQ_DONTWAIT);
            zmq_send(s->pub, t->tb.p, t->tb.n, ZMQ_DONTWAIT);
        }
    }
    t->q_n = 0;
    t->tb.n = 0;
}

void gsi_telemetry_publish_one(gs_service *s, const char *txt)
{
    svc_telemetry *t = tel_get(s);
    if (!s->pub || !t)
        return;
    if (t->subs_single > 0) {
        zmq_send(s->pub, "telemetry", 9, ZMQ_SNDMORE | ZMQ_DONTWAIT);
        zmq_send(s->pub, txt, strlen(txt), ZMQ_DONTWAIT);
    }
    if (t->subs_batch > 0) { /* a batch of one */
        tbuf b = {0};
        put_batch_head(&b, s->session);
        put(&b, txt, strlen(txt));
        PUT(&b, "]}");
        if (!b.oom) {
            zmq_send(s->pub, "batch", 5, ZMQ_SNDMORE | ZMQ_DONTWAIT);
            zmq_send(s->pub, b.p, b.n, ZMQ_DONTWAIT);
        }
        free(b.p);
    }
}

void gsi_telemetry_free(gs_service *s)
{
    if (s->tel)
        free(s->tel->tb.p);
    free(s->tel);
    s->tel = NULL;
}

bool gsi_telemetry_queue(gs_service *s)
{
    svc_telemetry *t = tel_get(s);
    if (!t)
        return false;
    gs_system *sys = gs_engine_system(s->eng);
    tbuf *b = &t->tb;
    b->oom = false;
    if (t->q_n == 0) {
        b->n = 0;
        put_batch_head(b, s->session);
        t->head = b->n;
        t->t_first = gs_now();
    } else {
        PUT(b, ",");
    }
    uint64_t seq0 = s->seq;
    PUT(b, "{\"v\":1,\"type\":\"telemetry\",\"seq\":");
    put_int(b, (long long)++s->seq);
    PUT(b, ",\"session\":");
    put_str(b, s->session);
    PUT(b, ",\"step\":");
    put_int(b, (long long)sys->step);
    put_kn(b, ",\"time\":", sys->time);
    gs_energy e;
    gs_system_energy(sys, &e);
    put_kn(b, ",\"energy\":{\"kinetic\":", e.kinetic);
    put_kn(b, ",\"potential\":", e.potential);
    put_kn(b, ",\"elastic\":", e.elastic);
    put_kn(b, ",\"total\":", e.total);
    put_kn(b, ",\"work_in\":", e.work_in);
    put_kn(b, ",\"dissipated\":", e.dissipated);
    put_kn(b, ",\"balance_residual\":", e.balance_residual);
    put_kn(b, ",\"contact_work\":", e.contact_work);
    PUT(b, "},\"bodies\":[");
    for (int i = 0; i < sys->n_bodies; i++) {
        if (i)
            PUT(b, ",");
        PUT(b, "{\"name\":");
        put_str(b, sys->scene->bodies[i].name);
        put_kn(b, ",\"angle\":", gs_system_angle(sys, i));
        put_kn(b, ",\"omega\":", gs_system_omega(sys, i));
        put_kn(b, ",\"rpm\":", gs_system_rpm(sys, i));
        int tc = sys->bodies[i].tcoord;
        if (tc >= 0) {
            put_kn(b, ",\"offset\":[", sys->q[tc]);
            put_kn(b, ",", sys->q[tc + 1]);
            PUT(b, "]");
        }
        PUT(b, "}");
    }
    PUT(b, "],\"meshes\":[");
    for (int i = 0; i < sys->n_meshes; i++) {
        const gs_gmesh_rt *m = &sys->meshes[i];
        if (i)
            PUT(b, ",");
        PUT(b, "{\"name\":");
        put_str(b, sys->scene->meshes[i].name);
        put_kn(b, ",\"force\":", isfinite(m->force) ? m->force : 0.0);
        put_kn(b, ",\"deflection\":", m->deflection);
        put_kn(b, ",\"penetration\":", m->penetration);
        if (m->ops->contact) {
            PUT(b, ",\"contacts\":");
            put_int(b, m->n_active);
            PUT(b, ",\"rows\":");
            put_int(b, m->n_rows);
            put_kn(b, ",\"friction_loss\":", m->friction_loss);
            put_kn(b, ",\"contact_work\":", m->contact_work);
        }
        if (m->ops->after_step) {
            PUT(b, ",\"impacts\":");
            put_int(b, (long long)m->impacts);
            put_kn(b, ",\"impact_loss\":", m->impact_loss);
        }
        PUT(b, "}");
    }
    PUT(b, "]");
    int planet[64];
    double share[64];
    int np = gs_system_planet_shares(sys, planet, share, 64);
    if (np > 0) {
        PUT(b, ",\"planets\":[");
        for (int i = 0; i < np; i++) {
            if (i)
                PUT(b, ",");
            PUT(b, "{\"name\":");
            put_str(b, sys->scene->bodies[planet[i]].name);
            put_kn(b, ",\"share\":", share[i]);
            PUT(b, "}");
        }
        PUT(b, "]");
    }
    if (s->adv.active) {
        PUT(b, ",\"parent_id\":");
        put_str(b, s->adv.parent_id);
    }
    PUT(b, "}");
    if (b->oom) { /* not queued: the caller publishes through the JSON tree */
        s->seq = seq0;
        if (t->q_n > 0)
            b->n = t->q_end[t->q_n - 1];
        gsi_telemetry_flush(s);
        return false;
    }
    t->q_end[t->q_n++] = b->n;
    size_t last = b->n - (t->q_n > 1 ? t->q_end[t->q_n - 2] : t->head);
    if (t->q_n == TEL_QUEUE || b->n + last >= TEL_BYTES || gs_now() - t->t_first >= TEL_LAG_S)
        gsi_telemetry_flush(s);
    return true;
}
