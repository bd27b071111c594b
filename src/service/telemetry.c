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
 * (gsi_telemetry_flush): ZeroMQ's I/O thread then wakes once for the lot
 * rather than once for each event, its largest cost per event. The queue
 * is sent before any other event (seq stays in order), at the end of every
 * chunk, and whenever it holds TEL_QUEUE events, so a burst never nears
 * the socket's high-water mark (1000 messages). */
#define TEL_QUEUE 64
typedef struct svc_telemetry {
    tbuf tb;
    size_t q_end[TEL_QUEUE]; /* end offset of each queued event in tb */
    int q_n;
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

static void put_int(tbuf *b, long long v)
{
    reserve(b, 24);
    if (!b->oom)
        b->n += (size_t)snprintf(b->p + b->n, 24, "%lld", v);
}

/* A JSON string: quotes, backslashes and control characters escaped. */
static void put_str(tbuf *b, const char *s)
{
    PUT(b, "\"");
    for (const char *r = s; *r; r++) {
        unsigned char c = (unsigned char)*r;
        if (c == '"' || c == '\\') {
            char e[2] = {'\\', (char)c};
            put(b, e, 2);
        } else if (c < 0x20) {
            char e[8];
            snprintf(e, sizeof e, "\\u%04x", c);
            put(b, e, 6);
        } else {
            put(b, r, 1);
        }
    }
    PUT(b, "\"");
}

void gsi_telemetry_flush(gs_service *s)
{
    svc_telemetry *t = s->tel;
    if (!t)
        return;
    size_t at = 0;
    for (int i = 0; i < t->q_n; i++) {
        if (s->pub) { /* a slow subscriber never slows the simulation: drop on a full queue */
            zmq_send(s->pub, "telemetry", 9, ZMQ_SNDMORE | ZMQ_DONTWAIT);
            zmq_send(s->pub, t->tb.p + at, t->q_end[i] - at, ZMQ_DONTWAIT);
        }
        at = t->q_end[i];
    }
    t->q_n = 0;
    t->tb.n = 0;
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
    if (!s->tel && !(s->tel = calloc(1, sizeof *s->tel)))
        return false;
    svc_telemetry *t = s->tel;
    gs_system *sys = gs_engine_system(s->eng);
    tbuf *b = &t->tb;
    size_t start = b->n;
    uint64_t seq0 = s->seq;
    b->oom = false;
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
        b->n = start;
        s->seq = seq0;
        gsi_telemetry_flush(s);
        return false;
    }
    t->q_end[t->q_n++] = b->n;
    if (t->q_n == TEL_QUEUE)
        gsi_telemetry_flush(s);
    return true;
}
