/* SPDX-License-Identifier: MIT
 * gearsim_client: connection file, request/reply with retries, events. */
#include "gearsim_client.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <zmq.h>

#define ENDPOINT_MAX 512
#define MAX_FRAME (64u << 20)

struct gsc_client {
    void *ctx;
    void *cmd;             /* DEALER */
    void *sub;             /* SUB, after gsc_subscribe */
    char command_ep[ENDPOINT_MAX];
    char telemetry_ep[ENDPOINT_MAX];
    char session[128];
    char last_id[64];
    unsigned long counter;
    int all_topics;
    long long last_seq;    /* -1: none yet */
    long gaps;
    int batched;           /* the daemon sends telemetry in batches (connection file) */
    json_object *batch;    /* the events of the last batch received, */
    size_t batch_next;     /* the next of them to hand out */
    /* CURVE (Z85): the daemon's key and this client's pair, from the
     * connection file (a loopback daemon's own pair); empty when off. */
    char curve_server[41], curve_public[41], curve_secret[41];
    char conn_path[1024];  /* the connection file, watched while waiting */
    int pid;               /* rank 0's process id (0: unknown) */
    char stopped[1600];    /* why the daemon is gone, "" while it runs */
    double last_check;     /* now_ms() of the last look */
};

/* Make sock a CURVE client when the connection file named a server key. */
static int apply_curve(const gsc_client *c, void *sock)
{
    if (!c->curve_server[0])
        return 0;
    if (zmq_setsockopt(sock, ZMQ_CURVE_SERVERKEY, c->curve_server, 40) ||
        zmq_setsockopt(sock, ZMQ_CURVE_PUBLICKEY, c->curve_public, 40) ||
        zmq_setsockopt(sock, ZMQ_CURVE_SECRETKEY, c->curve_secret, 40))
        return -1;
    return 0;
}

static void set_err(gsc_error *err, const char *code, const char *field, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

static void set_err(gsc_error *err, const char *code, const char *field, const char *fmt, ...)
{
    if (!err)
        return;
    snprintf(err->code, sizeof err->code, "%s", code);
    snprintf(err->field, sizeof err->field, "%s", field ? field : "");
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->message, sizeof err->message, fmt, ap);
    va_end(ap);
}

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

const char *gsc_default_connection_file(char *buf, size_t n)
{
    const char *xdg = getenv("XDG_RUNTIME_DIR");
    if (xdg && *xdg)
        snprintf(buf, n, "%s/gearsim/gearsimd.json", xdg);
    else
        snprintf(buf, n, "/tmp/gearsim-%u/gearsimd.json", (unsigned)getuid());
    return buf;
}

static int copy_string(json_object *o, const char *key, char *dst, size_t n)
{
    json_object *v;
    if (!json_object_object_get_ex(o, key, &v) || json_object_get_type(v) != json_type_string)
        return -1;
    snprintf(dst, n, "%s", json_object_get_string(v));
    return 0;
}

int gsc_client_new(const char *connection_file, gsc_client **out, gsc_error *err)
{
    char defpath[1024];
    *out = NULL;
    if (!connection_file)
        connection_file = gsc_default_connection_file(defpath, sizeof defpath);
    json_object *info = json_object_from_file(connection_file);
    if (!info) {
        set_err(err, "io_error", "", "cannot read connection file %s: %s", connection_file,
                json_util_get_last_err());
        return -1;
    }
    gsc_client *c = calloc(1, sizeof *c);
    if (!c) {
        json_object_put(info);
        set_err(err, "no_memory", "", "out of memory");
        return -1;
    }
    c->last_seq = -1;
    if (copy_string(info, "command", c->command_ep, sizeof c->command_ep) ||
        copy_string(info, "telemetry", c->telemetry_ep, sizeof c->telemetry_ep)) {
        json_object_put(info);
        free(c);
        set_err(err, "bad_json", "", "connection file %s lacks the command/telemetry endpoints",
                connection_file);
        return -1;
    }
    copy_string(info, "session", c->session, sizeof c->session);
    json_object *bv;
    c->batched = json_object_object_get_ex(info, "telemetry_batch", &bv) && json_object_get_boolean(bv);
    snprintf(c->conn_path, sizeof c->conn_path, "%s", connection_file);
    json_object *pv, *sv;
    if (json_object_object_get_ex(info, "pid", &pv) && json_object_get_type(pv) == json_type_int)
        c->pid = json_object_get_int(pv);
    if (json_object_object_get_ex(info, "stopped", &sv) && json_object_get_type(sv) == json_type_string) {
        set_err(err, "daemon_stopped", "", "the daemon stopped: %s", json_object_get_string(sv));
        json_object_put(info);
        free(c);
        return -1;
    }
    if (copy_string(info, "curve_server_key", c->curve_server, sizeof c->curve_server) == 0 &&
        (copy_string(info, "curve_client_public_key", c->curve_public, sizeof c->curve_public) ||
         copy_string(info, "curve_client_secret_key", c->curve_secret, sizeof c->curve_secret) ||
         strlen(c->curve_server) != 40 || strlen(c->curve_public) != 40 || strlen(c->curve_secret) != 40)) {
        json_object_put(info);
        free(c);
        set_err(err, "invalid_argument", "", "the daemon requires CURVE and connection file %s holds no "
                "client key pair (a daemon on another host: use gearctl with --curve-key)", connection_file);
        return -1;
    }
    json_object_put(info);
    c->ctx = zmq_ctx_new();
    c->cmd = c->ctx ? zmq_socket(c->ctx, ZMQ_DEALER) : NULL;
    int linger = 0, v6 = 1; /* IPv6 on: the daemon may listen on ::1 */
    if (!c->cmd || zmq_setsockopt(c->cmd, ZMQ_LINGER, &linger, sizeof linger) ||
        zmq_setsockopt(c->cmd, ZMQ_IPV6, &v6, sizeof v6) || apply_curve(c, c->cmd) ||
        zmq_connect(c->cmd, c->command_ep)) {
        set_err(err, "io_error", "", "cannot connect to %s: %s", c->command_ep, zmq_strerror(zmq_errno()));
        gsc_client_free(&c);
        return -1;
    }
    *out = c;
    return 0;
}

void gsc_client_free(gsc_client **pc)
{
    if (!pc || !*pc)
        return;
    gsc_client *c = *pc;
    if (c->sub)
        zmq_close(c->sub);
    json_object_put(c->batch);
    if (c->cmd)
        zmq_close(c->cmd);
    if (c->ctx)
        zmq_ctx_term(c->ctx);
    free(c);
    *pc = NULL;
}

const char *gsc_client_session(const gsc_client *c) { return c->session; }
const char *gsc_last_id(const gsc_client *c) { return c->last_id; }
long gsc_event_gaps(const gsc_client *c) { return c->gaps; }

/* Receive one whole message; returns its last frame as a NUL-terminated
 * malloc'd string (NULL on error), and the number of frames in *nframes. */
static char *recv_message(void *sock, int *nframes, char *first, size_t first_n)
{
    char *last = NULL;
    int more = 1, n = 0;
    if (first && first_n)
        first[0] = '\0';
    while (more) {
        zmq_msg_t m;
        zmq_msg_init(&m);
        if (zmq_msg_recv(&m, sock, 0) < 0) {
            zmq_msg_close(&m);
            free(last);
            return NULL;
        }
        size_t len = zmq_msg_size(&m);
        if (n == 0 && first && first_n) {
            size_t k = len < first_n - 1 ? len : first_n - 1;
            memcpy(first, zmq_msg_data(&m), k);
            first[k] = '\0';
        }
        free(last);
        last = len <= MAX_FRAME ? malloc(len + 1) : NULL;
        if (last) {
            memcpy(last, zmq_msg_data(&m), len);
            last[len] = '\0';
        }
        more = zmq_msg_more(&m);
        zmq_msg_close(&m);
        n++;
    }
    *nframes = n;
    return last;
}

static json_object *parse(const char *text)
{
    if (!text)
        return NULL;
    json_tokener *tok = json_tokener_new();
    if (!tok)
        return NULL;
    json_object *o = json_tokener_parse_ex(tok, text, (int)strlen(text));
    if (json_tokener_get_error(tok) != json_tokener_success) {
        json_object_put(o);
        o = NULL;
    }
    json_tokener_free(tok);
    return o;
}

static int local_endpoint(const char *ep)
{
    return !strncmp(ep, "ipc://", 6) || !strncmp(ep, "tcp://127.", 10) || !strncmp(ep, "tcp://[::1]", 11) ||
           !strncmp(ep, "tcp://localhost", 15);
}

/* Is the daemon gone (docs/RELIABILITY.md, "When a rank dies")? Its
 * connection file removed, marked `stopped` (a rank died) or taken by
 * another session, or (on this host) its process gone: c->stopped says
 * why. Looked at about once a second. */
static int daemon_gone(gsc_client *c)
{
    if (c->stopped[0])
        return 1;
    double t = now_ms();
    if (t - c->last_check < 1000)
        return 0;
    c->last_check = t;
    if (c->conn_path[0]) {
        if (access(c->conn_path, F_OK) != 0) {
            snprintf(c->stopped, sizeof c->stopped, "the daemon stopped: its connection file %.1024s was removed",
                     c->conn_path);
            return 1;
        }
        json_object *o = json_object_from_file(c->conn_path), *v;
        if (o && json_object_object_get_ex(o, "stopped", &v) && json_object_get_type(v) == json_type_string)
            snprintf(c->stopped, sizeof c->stopped, "the daemon stopped: %s", json_object_get_string(v));
        else if (o && json_object_object_get_ex(o, "session", &v) && c->session[0] &&
                 strcmp(json_object_get_string(v), c->session) != 0)
            snprintf(c->stopped, sizeof c->stopped, "the daemon stopped: %.1024s now belongs to another daemon",
                     c->conn_path);
        json_object_put(o);
        if (c->stopped[0])
            return 1;
    }
    if (c->pid > 0 && local_endpoint(c->command_ep)) {
        char p[64], buf[512];
        snprintf(p, sizeof p, "/proc/%d/stat", c->pid);
        FILE *f = fopen(p, "r");
        size_t n = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
        if (f)
            fclose(f);
        buf[n] = '\0';
        const char *rp = strrchr(buf, ')');
        if (!f || !rp || rp[1] != ' ' || rp[2] == 'Z' || rp[2] == 'X') {
            snprintf(c->stopped, sizeof c->stopped, "the daemon stopped: its process %d is gone (killed, or a "
                     "rank died and MPI aborted the job)", c->pid);
            return 1;
        }
    }
    return 0;
}

/* Wait for the reply whose id is c->last_id; NULL after timeout_ms. Replies
 * to other ids (late answers to abandoned requests) are dropped. */
static json_object *wait_reply(gsc_client *c, int timeout_ms)
{
    double deadline = now_ms() + timeout_ms;
    for (;;) {
        double left = deadline - now_ms();
        if (left <= 0)
            return NULL;
        zmq_pollitem_t it = {c->cmd, 0, ZMQ_POLLIN, 0};
        int r = zmq_poll(&it, 1, (long)(left < 1000 ? left : 1000) + 1);
        if (r <= 0) {
            if (daemon_gone(c))
                return NULL;
            continue;
        }
        int nf;
        char *text = recv_message(c->cmd, &nf, NULL, 0);
        json_object *reply = parse(text);
        free(text);
        json_object *id;
        if (reply && json_object_object_get_ex(reply, "id", &id) &&
            json_object_get_type(id) == json_type_string &&
            strcmp(json_object_get_string(id), c->last_id) == 0)
            return reply;
        json_object_put(reply);
    }
}

int gsc_request(gsc_client *c, const char *cmd, json_object *args, int timeout_ms, int retries,
                json_object **result, gsc_error *err)
{
    if (result)
        *result = NULL;
    snprintf(c->last_id, sizeof c->last_id, "c%ld-%lu", (long)getpid(), ++c->counter);
    json_object *req = json_object_new_object();
    json_object_object_add(req, "v", json_object_new_int(1));
    json_object_object_add(req, "id", json_object_new_string(c->last_id));
    json_object_object_add(req, "cmd", json_object_new_string(cmd));
    if (args)
        json_object_object_add(req, "args", json_object_get(args));
    const char *text = json_object_to_json_string_ext(req, JSON_C_TO_STRING_PLAIN);
    size_t len = strlen(text);
    json_object *reply = NULL;
    for (int attempt = 0; attempt <= retries && !reply; attempt++) {
        if (zmq_send(c->cmd, text, len, 0) < 0) {
            set_err(err, "io_error", "", "send failed: %s", zmq_strerror(zmq_errno()));
            json_object_put(req);
            return -1;
        }
        reply = wait_reply(c, timeout_ms);
        if (!reply && c->stopped[0])
            break;
    }
    json_object_put(req);
    if (!reply && c->stopped[0]) {
        set_err(err, "daemon_stopped", "", "%s", c->stopped);
        return -1;
    }
    if (!reply) {
        set_err(err, "timeout", "", "no reply to %s (%s) after %d attempts of %d ms", cmd, c->last_id,
                retries + 1, timeout_ms);
        return -1;
    }
    json_object *ok, *v;
    if (json_object_object_get_ex(reply, "ok", &ok) && json_object_get_boolean(ok)) {
        if (result && json_object_object_get_ex(reply, "result", &v))
            *result = json_object_get(v);
        json_object_put(reply);
        return 0;
    }
    gsc_error tmp;
    if (!err)
        err = &tmp;
    set_err(err, "internal", "", "error reply without an error object");
    if (json_object_object_get_ex(reply, "error", &v)) {
        copy_string(v, "code", err->code, sizeof err->code);
        copy_string(v, "message", err->message, sizeof err->message);
        copy_string(v, "field", err->field, sizeof err->field);
    }
    json_object_put(reply);
    return -1;
}

/* Hand out the next event of the batch being read; 0 when none is left. */
static int next_of_batch(gsc_client *c, json_object **event)
{
    while (c->batch && c->batch_next < json_object_array_length(c->batch)) {
        json_object *ev = json_object_array_get_idx(c->batch, c->batch_next++);
        if (json_object_get_type(ev) == json_type_object) {
            *event = json_object_get(ev);
            return 1;
        }
    }
    json_object_put(c->batch);
    c->batch = NULL;
    return 0;
}

static int recv_event(gsc_client *c, int timeout_ms, json_object **event)
{
    *event = NULL;
    json_object *ev = NULL;
    if (!next_of_batch(c, &ev)) {
        zmq_pollitem_t it = {c->sub, 0, ZMQ_POLLIN, 0};
        if (zmq_poll(&it, 1, timeout_ms) <= 0)
            return 0;
        int nf;
        char topic[64];
        char *text = recv_message(c->sub, &nf, topic, sizeof topic);
        ev = nf == 2 ? parse(text) : NULL;
        free(text);
        if (!ev || json_object_get_type(ev) != json_type_object) {
            json_object_put(ev);
            return 0;
        }
        json_object *evs;
        if (strcmp(topic, "batch") == 0) { /* telemetry events, in order, many per message */
            if (!json_object_object_get_ex(ev, "events", &evs) || json_object_get_type(evs) != json_type_array) {
                json_object_put(ev);
                return 0;
            }
            c->batch = json_object_get(evs);
            c->batch_next = 0;
            json_object_put(ev);
            ev = NULL;
            if (!next_of_batch(c, &ev))
                return 0;
        }
    }
    json_object *seq;
    if (json_object_object_get_ex(ev, "seq", &seq) && json_object_get_type(seq) == json_type_int) {
        long long s = (long long)json_object_get_int64(seq);
        if (c->all_topics && c->last_seq >= 0 && s > c->last_seq + 1)
            c->gaps += (long)(s - c->last_seq - 1);
        c->last_seq = s;
    }
    *event = ev;
    return 1;
}

/* The event types; a daemon that batches telemetry sends it on `batch`. */
static const char *const event_types[] = {"telemetry", "progress", "done", "heartbeat", "warning", "error"};

/* Subscribe to what `topic` asks for: every event type it is a prefix of
 * (telemetry as `batch` from a batching daemon), and heartbeats. */
static int subscribe_topics(gsc_client *c, const char *topic)
{
    if (!c->batched)
        return zmq_setsockopt(c->sub, ZMQ_SUBSCRIBE, topic, strlen(topic)) ||
               (topic[0] && zmq_setsockopt(c->sub, ZMQ_SUBSCRIBE, "heartbeat", 9));
    size_t n = strlen(topic);
    for (size_t i = 0; i < sizeof event_types / sizeof event_types[0]; i++) {
        const char *t = event_types[i];
        if (strncmp(t, topic, n) != 0 && strcmp(t, "heartbeat") != 0)
            continue;
        if (strcmp(t, "telemetry") == 0)
            t = "batch";
        if (zmq_setsockopt(c->sub, ZMQ_SUBSCRIBE, t, strlen(t)))
            return -1;
    }
    return 0;
}

int gsc_subscribe(gsc_client *c, const char *topic, int timeout_ms, gsc_error *err)
{
    if (c->sub)
        return 0;
    c->sub = zmq_socket(c->ctx, ZMQ_SUB);
    int linger = 0, hwm = 100000, v6 = 1;
    if (!c->sub || zmq_setsockopt(c->sub, ZMQ_LINGER, &linger, sizeof linger) ||
        zmq_setsockopt(c->sub, ZMQ_IPV6, &v6, sizeof v6) ||
        zmq_setsockopt(c->sub, ZMQ_RCVHWM, &hwm, sizeof hwm) ||
        subscribe_topics(c, topic) || apply_curve(c, c->sub) ||
        zmq_connect(c->sub, c->telemetry_ep)) {
        set_err(err, "io_error", "", "cannot subscribe to %s: %s", c->telemetry_ep,
                zmq_strerror(zmq_errno()));
        return -1;
    }
    c->all_topics = topic[0] == '\0';
    double deadline = now_ms() + timeout_ms;
    while (now_ms() < deadline) {
        json_object *ev;
        if (recv_event(c, (int)(deadline - now_ms()) + 1, &ev) == 1) {
            json_object *t;
            int hb = json_object_object_get_ex(ev, "type", &t) &&
                     strcmp(json_object_get_string(t), "heartbeat") == 0;
            json_object_put(ev);
            if (hb)
                return 0;
        }
    }
    set_err(err, "timeout", "", "no heartbeat from %s within %d ms", c->telemetry_ep, timeout_ms);
    return -1;
}

int gsc_next_event(gsc_client *c, int timeout_ms, json_object **event)
{
    *event = NULL;
    if (!c->sub)
        return -1;
    double deadline = now_ms() + timeout_ms;
    for (;;) {
        double left = deadline - now_ms();
        if (recv_event(c, left > 0 ? (int)left : 0, event) == 1)
            return 1;
        if (now_ms() >= deadline)
            return 0;
    }
}

/* The done payload of parent_id in a status result's `finished` list
 * (a new reference), or NULL. */
static json_object *finished_entry(json_object *st, const char *parent_id)
{
    json_object *fin;
    if (!json_object_object_get_ex(st, "finished", &fin) || !json_object_is_type(fin, json_type_array))
        return NULL;
    for (size_t i = json_object_array_length(fin); i-- > 0;) {
        json_object *f = json_object_array_get_idx(fin, i), *p;
        if (json_object_object_get_ex(f, "parent_id", &p) && json_object_is_type(p, json_type_string) &&
            strcmp(json_object_get_string(p), parent_id) == 0)
            return json_object_get(f);
    }
    return NULL;
}

int gsc_wait_done(gsc_client *c, const char *parent_id, int timeout_ms,
                  void (*on_event)(json_object *ev, void *user), void *user, json_object **done,
                  gsc_error *err)
{
    *done = NULL;
    double start = now_ms(), last_poll = start;
    for (;;) {
        json_object *ev = NULL;
        if (c->sub) {
            if (gsc_next_event(c, 500, &ev) == 1) {
                json_object *t, *p;
                if (json_object_object_get_ex(ev, "type", &t) && json_object_object_get_ex(ev, "parent_id", &p) &&
                    strcmp(json_object_get_string(t), "done") == 0 &&
                    strcmp(json_object_get_string(p), parent_id) == 0) {
                    *done = ev;
                    return 0;
                }
                /* Events still coming (or queued behind a slow callback):
                 * the done event is behind them; ask status only after a
                 * quiet GSC_DONE_POLL_MS. */
                if (!(json_object_object_get_ex(ev, "type", &t) &&
                      strcmp(json_object_get_string(t), "heartbeat") == 0))
                    last_poll = now_ms();
                if (on_event)
                    on_event(ev, user);
                json_object_put(ev);
            }
        } else {
            struct timespec ts = {0, 200 * 1000000L};
            nanosleep(&ts, NULL);
        }
        double now = now_ms();
        if (daemon_gone(c)) {
            set_err(err, "daemon_stopped", "", "%s", c->stopped);
            return -1;
        }
        if (now - last_poll >= GSC_DONE_POLL_MS) {
            /* The done event may be lost (PUB drops, a subscriber gone):
             * status lists the last finished requests. */
            last_poll = now;
            json_object *st = NULL;
            if (gsc_request(c, "status", NULL, 10000, 2, &st, err) == 0) {
                json_object *f = finished_entry(st, parent_id);
                json_object_put(st);
                if (f) {
                    /* Finished: the events before its done (the last
                     * telemetry) may still be on their way; take them and
                     * the done event if it comes within 1.5 s. */
                    double until = now_ms() + 1500;
                    while (c->sub && now_ms() < until) {
                        json_object *e2 = NULL, *t, *p;
                        if (gsc_next_event(c, (int)(until - now_ms()) + 1, &e2) != 1)
                            continue;
                        if (json_object_object_get_ex(e2, "type", &t) &&
                            json_object_object_get_ex(e2, "parent_id", &p) &&
                            strcmp(json_object_get_string(t), "done") == 0 &&
                            strcmp(json_object_get_string(p), parent_id) == 0) {
                            json_object_put(f);
                            f = e2;
                            break;
                        }
                        if (!(json_object_object_get_ex(e2, "type", &t) &&
                              strcmp(json_object_get_string(t), "heartbeat") == 0))
                            until = now_ms() + 1500; /* still draining */
                        if (on_event)
                            on_event(e2, user);
                        json_object_put(e2);
                    }
                    *done = f;
                    return 0;
                }
            }
        }
        if (timeout_ms >= 0 && now - start > timeout_ms) {
            if (err) {
                snprintf(err->code, sizeof err->code, "timeout");
                snprintf(err->message, sizeof err->message, "'%s' not done after %d ms", parent_id, timeout_ms);
            }
            return -1;
        }
    }
}
