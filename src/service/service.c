/* SPDX-License-Identifier: MIT
 * The service loop on rank 0: one poll loop over the ROUTER socket, advance
 * in chunks of about 20 ms so that commands are answered promptly while a
 * long run goes on, periodic work (heartbeat, progress, jobs) in one place,
 * every request answered — bad input included — and retried ids answered
 * from a cache without running twice. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <zmq.h>

#include "gearsim/stiffness.h"
#include "gearsim/util.h"
#include "scene/jsonstrict.h"
#include "scene/jsonv.h"
#include "service/auth.h"
#include "service/files.h"
#include "service/options.h"
#include "service/service_internal.h"

static volatile sig_atomic_t stop_signal = 0;
static bool opt_resume = false;
static int64_t opt_max_scene_mb = GSI_DEFAULT_MAX_SCENE_MB;
static int64_t opt_max_record_mb = GSI_DEFAULT_MAX_RECORD_MB;
static int64_t opt_max_clients = GSI_DEFAULT_MAX_CLIENTS;

void gs_service_set_resume(bool on) { opt_resume = on; }
void gs_service_set_max_scene_mb(int64_t mb) { opt_max_scene_mb = mb < 1 ? 1 : mb; }
int64_t gsi_opt_max_scene_mb(void) { return opt_max_scene_mb; }
void gs_service_set_max_record_mb(int64_t mb) { opt_max_record_mb = mb < 1 ? 1 : mb; }
int64_t gsi_opt_max_record_mb(void) { return opt_max_record_mb; }
void gs_service_set_max_clients(int64_t n)
{
    opt_max_clients = n < 1 ? 1 : n > GSI_MAX_CLIENTS_CAP ? GSI_MAX_CLIENTS_CAP : n;
}
int64_t gsi_opt_max_clients(void) { return opt_max_clients; }

static void on_signal(int sig)
{
    (void)sig;
    stop_signal = 1;
}

void gs_service_catch_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
}

/* The last guard of the JSON writer: a non-finite number is not JSON
 * (json-c would write NaN or Infinity), so every one left in a reply or an
 * event becomes null; returns how many were. The run itself stops at the
 * first non-finite value (gsi_check_finite); this is for anything else. */
int gsi_json_scrub(json_object *o)
{
    int n = 0;
    if (json_object_get_type(o) == json_type_object) {
        json_object_object_foreach(o, k, v) {
            if (json_object_get_type(v) == json_type_double && !isfinite(json_object_get_double(v))) {
                json_object_object_add(o, k, NULL);
                n++;
            } else {
                n += gsi_json_scrub(v);
            }
        }
    } else if (json_object_get_type(o) == json_type_array) {
        size_t len = json_object_array_length(o);
        for (size_t i = 0; i < len; i++) {
            json_object *v = json_object_array_get_idx(o, i);
            if (json_object_get_type(v) == json_type_double && !isfinite(json_object_get_double(v))) {
                json_object_array_put_idx(o, i, NULL);
                n++;
            } else {
                n += gsi_json_scrub(v);
            }
        }
    }
    return n;
}

void gsi_publish(gs_service *s, const char *type, json_object *o)
{
    gsi_telemetry_flush(s); /* the queued telemetry goes first: seq in order */
    gs_system *sys = gs_engine_system(s->eng);
    json_object *ev = json_object_new_object();
    json_object_object_add(ev, "v", json_object_new_int(1));
    json_object_object_add(ev, "type", json_object_new_string(type));
    json_object_object_add(ev, "seq", json_object_new_int64((int64_t)++s->seq));
    json_object_object_add(ev, "session", json_object_new_string(s->session));
    json_object_object_add(ev, "step", json_object_new_int64(sys ? sys->step : 0));
    json_object_object_add(ev, "time", json_object_new_double(sys ? sys->time : 0.0));
    json_object_object_foreach(o, k, v) json_object_object_add(ev, k, json_object_get(v));
    json_object_put(o);
    gsi_json_scrub(ev);
    const char *txt = json_object_to_json_string_ext(ev, JSON_C_TO_STRING_PLAIN);
    if (!s->pub) { /* socket-free use (tests/fuzz) */
        json_object_put(ev);
        return;
    }
    /* A slow subscriber never slows the simulation: drop on a full queue. */
    if (strcmp(type, "telemetry") == 0) {
        gsi_telemetry_publish_one(s, txt); /* in the form(s) subscribed to */
    } else {
        zmq_send(s->pub, type, strlen(type), ZMQ_SNDMORE | ZMQ_DONTWAIT);
        zmq_send(s->pub, txt, strlen(txt), ZMQ_DONTWAIT);
    }
    json_object_put(ev);
}

void gsi_publish_done(gs_service *s, const char *kind, json_object *o)
{
    gs_system *sys = gs_engine_system(s->eng);
    json_object_object_add(o, "kind", json_object_new_string(kind));
    json_object_object_add(o, "step", json_object_new_int64(sys ? sys->step : 0));
    json_object_object_add(o, "time", json_object_new_double(sys ? sys->time : 0.0));
    if (s->n_finished == GSI_FINISHED_KEEP) {
        json_object_put(s->finished[0].done);
        memmove(&s->finished[0], &s->finished[1], (GSI_FINISHED_KEEP - 1) * sizeof s->finished[0]);
        s->n_finished--;
    }
    svc_finished *f = &s->finished[s->n_finished++];
    snprintf(f->kind, sizeof f->kind, "%s", kind);
    f->done = json_object_get(o);
    gsi_publish(s, "done", o);
    /* gsi_publish copied o's members into the event and dropped our
     * reference; the kept reference holds the body. */
}

void gsi_record_flush_or_stop(gs_service *s, const char *why)
{
    if (!s->record)
        return;
    char msg[1400];
    if (gs_record_flush(s->record) == GS_OK) {
        /* The record size limit (--max-record-mb): checked after each flush. */
        struct stat st;
        if (stat(gs_record_path(s->record), &st) != 0 ||
            (double)st.st_size <= (double)opt_max_record_mb * 1048576.0)
            return;
        snprintf(msg, sizeof msg, "recording stopped: '%.1100s' reached the record size limit of %lld MiB "
                 "(--max-record-mb); the simulation goes on", gs_record_path(s->record),
                 (long long)opt_max_record_mb);
    } else {
        snprintf(msg, sizeof msg, "recording stopped: %s ('%.1100s'; disk full?); the simulation goes on",
                 why, gs_record_path(s->record));
    }
    json_object *w = json_object_new_object();
    json_object_object_add(w, "code", json_object_new_string("io_error"));
    json_object_object_add(w, "message", json_object_new_string(msg));
    if (s->adv.active)
        json_object_object_add(w, "parent_id", json_object_new_string(s->adv.parent_id));
    gsi_publish(s, "error", w);
    fprintf(stderr, "gearsimd: %s\n", msg);
    gs_record_close(&s->record);
}

static json_object *energy_json(const gs_energy *e)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "kinetic", json_object_new_double(e->kinetic));
    json_object_object_add(o, "potential", json_object_new_double(e->potential));
    json_object_object_add(o, "elastic", json_object_new_double(e->elastic));
    json_object_object_add(o, "total", json_object_new_double(e->total));
    json_object_object_add(o, "work_in", json_object_new_double(e->work_in));
    json_object_object_add(o, "dissipated", json_object_new_double(e->dissipated));
    json_object_object_add(o, "balance_residual", json_object_new_double(e->balance_residual));
    json_object_object_add(o, "contact_work", json_object_new_double(e->contact_work));
    return o;
}

/* Telemetry body shared by the telemetry event and the `state` reply. */
json_object *gsi_state_json(gs_service *s)
{
    gs_system *sys = gs_engine_system(s->eng);
    json_object *o = json_object_new_object();
    gs_energy e;
    gs_system_energy(sys, &e);
    json_object_object_add(o, "energy", energy_json(&e));
    json_object *bodies = json_object_new_array();
    for (int i = 0; i < sys->n_bodies; i++) {
        json_object *b = json_object_new_object();
        json_object_object_add(b, "name", json_object_new_string(sys->scene->bodies[i].name));
        json_object_object_add(b, "angle", json_object_new_double(gs_system_angle(sys, i)));
        json_object_object_add(b, "omega", json_object_new_double(gs_system_omega(sys, i)));
        json_object_object_add(b, "rpm", json_object_new_double(gs_system_rpm(sys, i)));
        int tc = sys->bodies[i].tcoord;
        if (tc >= 0) { /* on a bearing or a pin bearing: the centre's displacement (m) */
            json_object *x = json_object_new_array();
            json_object_array_add(x, json_object_new_double(sys->q[tc]));
            json_object_array_add(x, json_object_new_double(sys->q[tc + 1]));
            json_object_object_add(b, "offset", x);
        }
        json_object_array_add(bodies, b);
    }
    json_object_object_add(o, "bodies", bodies);
    json_object *meshes = json_object_new_array();
    for (int i = 0; i < sys->n_meshes; i++) {
        const gs_gmesh_rt *m = &sys->meshes[i];
        json_object *j = json_object_new_object();
        json_object_object_add(j, "name", json_object_new_string(sys->scene->meshes[i].name));
        json_object_object_add(j, "force", json_object_new_double(isfinite(m->force) ? m->force : 0.0));
        json_object_object_add(j, "deflection", json_object_new_double(m->deflection));
        json_object_object_add(j, "penetration", json_object_new_double(m->penetration));
        if (m->ops->contact) {
            json_object_object_add(j, "contacts", json_object_new_int(m->n_active));
            json_object_object_add(j, "rows", json_object_new_int(m->n_rows));
            json_object_object_add(j, "friction_loss", json_object_new_double(m->friction_loss));
            json_object_object_add(j, "contact_work", json_object_new_double(m->contact_work));
        }
        if (m->ops->after_step) {
            json_object_object_add(j, "impacts", json_object_new_int64(m->impacts));
            json_object_object_add(j, "impact_loss", json_object_new_double(m->impact_loss));
        }
        json_object_array_add(meshes, j);
    }
    json_object_object_add(o, "meshes", meshes);
    int planet[64];
    double share[64];
    int np = gs_system_planet_shares(sys, planet, share, 64);
    if (np > 0) {
        json_object *ps = json_object_new_array();
        for (int i = 0; i < np; i++) {
            json_object *j = json_object_new_object();
            json_object_object_add(j, "name", json_object_new_string(sys->scene->bodies[planet[i]].name));
            json_object_object_add(j, "share", json_object_new_double(share[i]));
            json_object_array_add(ps, j);
        }
        json_object_object_add(o, "planets", ps);
    }
    return o;
}

gs_err gsi_record_open(gs_service *s, const char *path, gs_record **out, gs_diag *d)
{
    return gsi_record_open_as(s, path, path, out, d);
}

gs_err gsi_record_open_as(gs_service *s, const char *path, const char *create_as, gs_record **out, gs_diag *d)
{
    gs_system *sys = gs_engine_system(s->eng);
    GS_TRY(gs_record_open_as(path, create_as, sys, out, d));
    if (sys->scene->fields_every <= 0)
        return GS_OK;
    gs_record_mesh bm[64];
    int n = 0;
    for (int i = 0; i < sys->n_bodies && n < 64; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (!b->ops->fields)
            continue;
        double th;
        bm[n].name = sys->scene->bodies[i].name;
        bm[n].mesh = b->ops->mesh(b);
        gs_system_body_pose(sys, i, bm[n].centre, &th);
        n++;
    }
    gs_err e = n ? gs_record_add_meshes(*out, bm, n, d) : GS_OK;
    if (e != GS_OK)
        gs_record_close(out);
    return e;
}

/* Field snapshots of the elastic bodies, gathered by the engine this step. */
static gs_err record_fields(gs_service *s, gs_system *sys)
{
    for (int i = 0, k = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (!b->ops->fields)
            continue;
        const double *f = gs_engine_fields(s->eng, i);
        if (f) {
            gs_index nn = b->ops->field_nodes(b);
            GS_TRY(gs_record_field_frame(s->record, k, sys->step, sys->time, gs_system_angle(sys, i),
                                         f, f + 2 * nn));
        }
        k++;
    }
    return GS_OK;
}

bool gsi_state_finite(gs_service *s, bool energies, char *msg, size_t cap)
{
    gs_system *sys = gs_engine_system(s->eng);
    if (!sys)
        return true;
    gs_energy e = {0};
    if (energies)
        gs_system_energy(sys, &e);
    const char *what = NULL;
    int idx = -1;
    for (int i = 0; i < sys->n_coords && !what; i++)
        if (!isfinite(sys->q[i]) || !isfinite(sys->w[i]))
            what = isfinite(sys->q[i]) ? "a speed" : "a coordinate", idx = i;
    if (!what) {
        const double v[] = {sys->time, e.kinetic, e.potential, e.elastic, e.total, e.work_in, e.dissipated};
        static const char *const nv[] = {"the time", "the kinetic energy", "the potential energy",
                                         "the elastic energy", "the total energy", "the work in",
                                         "the dissipated energy"};
        for (int i = 0; i < 7 && !what; i++)
            if (!isfinite(v[i]))
                what = nv[i];
    }
    for (int i = 0; i < sys->n_meshes && !what; i++)
        if (!isfinite(sys->meshes[i].force))
            what = "a mesh force", idx = i;
    if (!what)
        return true;
    char at[40] = "";
    if (idx >= 0)
        snprintf(at, sizeof at, " (#%d)", idx);
    snprintf(msg, cap, "the run stopped: %s%s is not a finite number at step %lld; the scene's physical "
             "parameters are out of what the model can integrate (for example a material's E, a mass or "
             "a stiffness many orders from real ones)", what, at, (long long)sys->step);
    return false;
}

/* Runs on rank 0 after every step of a chunk. */
static bool step_hook(gs_engine *eng, void *user)
{
    gs_service *s = user;
    gs_system *sys = gs_engine_system(eng);
    int64_t st = sys->step;
    /* The first non-finite value stops the advance at the end of this
     * chunk (every rank stops there); nothing after it is published. */
    if (s->nonfinite[0])
        return true;
    if (!gsi_state_finite(s, false, s->nonfinite, sizeof s->nonfinite))
        return true;
    if (st % sys->scene->telemetry_every == 0) {
        double t0 = gs_now();
        if (!gsi_telemetry_queue(s)) {
            json_object *o = gsi_state_json(s);
            if (s->adv.active)
                json_object_object_add(o, "parent_id", json_object_new_string(s->adv.parent_id));
            gsi_publish(s, "telemetry", o);
        }
        s->timing_telemetry += gs_now() - t0;
    }
    int fe = sys->scene->fields_every;
    if (s->record && fe > 0 && st % fe == 0 && gs_record_n_meshes(s->record) > 0) {
        double t0 = gs_now();
        if (record_fields(s, sys) != GS_OK) {
            json_object *w = json_object_new_object();
            json_object_object_add(w, "code", json_object_new_string("io_error"));
            json_object_object_add(w, "message", json_object_new_string("recording stopped: field snapshot failed"));
            gsi_publish(s, "error", w);
            gs_record_close(&s->record);
        }
        s->timing_record += gs_now() - t0;
    }
    if (s->record && st % sys->scene->record_every == 0) {
        double t0 = gs_now();
        if (gs_record_sample(s->record, sys) != GS_OK) {
            json_object *w = json_object_new_object();
            json_object_object_add(w, "code", json_object_new_string("io_error"));
            json_object_object_add(w, "message", json_object_new_string("recording stopped: out of memory"));
            gsi_publish(s, "error", w);
            gs_record_close(&s->record);
        }
        s->timing_record += gs_now() - t0;
    }
    return true;
}

gs_err gsi_resolve_path(gs_service *s, const char *rel, char *out, size_t cap, bool for_write,
                        gs_diag *d)
{
    if (!rel || !rel[0])
        return gs_diag_set(d, GS_ERANGE, "path", "the path is empty");
    if (rel[0] == '/')
        return gs_diag_set(d, GS_ERANGE, "path", "absolute paths are refused; paths are relative to the data directory");
    if (strlen(rel) > 512)
        return gs_diag_set(d, GS_ERANGE, "path", "the path is too long");
    /* No '..' component anywhere, no control characters. */
    const char *p = rel;
    while (*p) {
        const char *q = strchr(p, '/');
        size_t n = q ? (size_t)(q - p) : strlen(p);
        if (n == 2 && p[0] == '.' && p[1] == '.')
            return gs_diag_set(d, GS_ERANGE, "path", "'..' is refused in paths");
        p += n;
        if (*p == '/')
            p++;
    }
    for (p = rel; *p; p++)
        if ((unsigned char)*p < 0x20)
            return gs_diag_set(d, GS_ERANGE, "path", "control characters are refused in paths");
    int n = snprintf(out, cap, "%s/%s", s->data_dir, rel);
    if (n < 0 || (size_t)n >= cap)
        return gs_diag_set(d, GS_ERANGE, "path", "the path is too long");
    /* Symlinks must not lead outside: check the real path of the existing
     * file (reads) or of its directory (writes). */
    char probe[PATH_MAX], real[PATH_MAX];
    snprintf(probe, sizeof probe, "%s", out);
    if (for_write) {
        char *slash = strrchr(probe, '/');
        if (slash)
            *slash = '\0';
    }
    if (!realpath(probe, real)) {
        if (for_write)
            return gs_diag_set(d, GS_ENOTFOUND, "path", "the directory of '%s' does not exist", rel);
        return gs_diag_set(d, GS_ENOTFOUND, "path", "no file '%s' in the data directory", rel);
    }
    size_t dl = strlen(s->data_dir);
    if (strncmp(real, s->data_dir, dl) != 0 || (real[dl] != '\0' && real[dl] != '/'))
        return gs_diag_set(d, GS_ERANGE, "path", "'%s' leads outside the data directory", rel);
    if (for_write) {
        struct stat st;
        if (lstat(out, &st) == 0 && S_ISLNK(st.st_mode))
            return gs_diag_set(d, GS_ERANGE, "path", "'%s' is a symbolic link; refused", rel);
    }
    return GS_OK;
}

const char *gsi_data_relative(const gs_service *s, const char *full)
{
    size_t dl = strlen(s->data_dir);
    if (strncmp(full, s->data_dir, dl) == 0 && full[dl] == '/')
        return full + dl + 1;
    return full;
}

/* Strict UTF-8 (no overlongs, surrogates or code points above U+10FFFF):
 * a request that is not text is refused before anything echoes it. */
static bool valid_utf8(const unsigned char *p, size_t n)
{
    size_t i = 0;
    while (i < n) {
        unsigned c = p[i];
        size_t k;
        unsigned min, cp;
        if (c < 0x80) {
            i++;
            continue;
        } else if ((c & 0xE0) == 0xC0) {
            k = 1, min = 0x80, cp = c & 0x1F;
        } else if ((c & 0xF0) == 0xE0) {
            k = 2, min = 0x800, cp = c & 0x0F;
        } else if ((c & 0xF8) == 0xF0) {
            k = 3, min = 0x10000, cp = c & 0x07;
        } else {
            return false;
        }
        if (i + k >= n)
            return false;
        for (size_t j = 1; j <= k; j++) {
            if (i + j >= n || (p[i + j] & 0xC0) != 0x80)
                return false;
            cp = cp << 6 | (p[i + j] & 0x3F);
        }
        if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
            return false;
        i += k + 1;
    }
    return true;
}

static void send_reply(gs_service *s, zmq_msg_t *ident, bool delim, const char *txt)
{
    gsi_telemetry_flush(s); /* a reply never overtakes the telemetry of earlier steps */
    zmq_msg_t copy;
    zmq_msg_init(&copy);
    zmq_msg_copy(&copy, ident);
    zmq_msg_send(&copy, s->router, ZMQ_SNDMORE | ZMQ_DONTWAIT);
    if (delim)
        zmq_send(s->router, "", 0, ZMQ_SNDMORE | ZMQ_DONTWAIT);
    zmq_send(s->router, txt, strlen(txt), ZMQ_DONTWAIT);
}

static json_object *error_reply(json_object *id, gs_err e, const gs_diag *d)
{
    json_object *r = json_object_new_object();
    json_object_object_add(r, "v", json_object_new_int(1));
    json_object_object_add(r, "id", id ? json_object_get(id) : NULL);
    json_object_object_add(r, "ok", json_object_new_boolean(0));
    json_object *err = json_object_new_object();
    json_object_object_add(err, "code", json_object_new_string(gs_errcode(e)));
    json_object_object_add(err, "message",
                           json_object_new_string(d && d->message[0] ? d->message : gs_strerror(e)));
    json_object_object_add(err, "field", json_object_new_string(d ? d->field : ""));
    json_object_object_add(r, "error", err);
    return r;
}

static void cache_key(char *out, size_t cap, const unsigned char *b, size_t n, const char *id)
{
    size_t k = 0;
    for (size_t i = 0; i < n && k + 3 < cap; i++)
        k += (size_t)snprintf(out + k, cap - k, "%02x", b[i]);
    snprintf(out + k, cap - k, "/%s", id);
}

static void cache_drop(gs_service *s, svc_cache_entry *c)
{
    s->cache_bytes -= c->bytes;
    free(c->reply);
    c->reply = NULL;
    c->bytes = 0;
}

/* Length of the client part of a key ("<hex>/"), the id after it. */
static size_t cache_client_len(const char *key)
{
    const char *slash = strchr(key, '/');
    return slash ? (size_t)(slash - key) + 1 : strlen(key);
}

static const char *cache_get(gs_service *s, const char *key)
{
    double now = gs_now();
    for (int i = 0; i < GSI_CACHE; i++) {
        svc_cache_entry *c = &s->cache[i];
        if (!c->reply)
            continue;
        if (now - c->t > GSI_CACHE_LIFETIME_S)
            cache_drop(s, c);
        else if (strcmp(c->key, key) == 0)
            return c->reply;
    }
    return NULL;
}

/* The oldest entry (of the client whose key part is key[0..plen) when
 * plen > 0); NULL when there is none. */
static svc_cache_entry *cache_oldest(gs_service *s, const char *key, size_t plen)
{
    svc_cache_entry *o = NULL;
    for (int i = 0; i < GSI_CACHE; i++) {
        svc_cache_entry *c = &s->cache[i];
        if (c->reply && (!plen || strncmp(c->key, key, plen) == 0) && (!o || c->t < o->t))
            o = c;
    }
    return o;
}

static void cache_put(gs_service *s, const char *key, const char *reply)
{
    size_t n = strlen(reply) + 1, plen = cache_client_len(key);
    if (n > GSI_CACHE_CLIENT_BYTES)
        return; /* beyond a client's budget: a retry runs again */
    double now = gs_now();
    int total = 0, mine = 0;
    size_t my_bytes = 0;
    svc_cache_entry *free_slot = NULL;
    for (int i = 0; i < GSI_CACHE; i++) {
        svc_cache_entry *c = &s->cache[i];
        if (c->reply && (now - c->t > GSI_CACHE_LIFETIME_S || strcmp(c->key, key) == 0))
            cache_drop(s, c);
        if (!c->reply) {
            free_slot = free_slot ? free_slot : c;
            continue;
        }
        total++;
        if (strncmp(c->key, key, plen) == 0)
            mine++, my_bytes += c->bytes;
    }
    while (mine >= GSI_CACHE_CLIENT_ENTRIES || my_bytes + n > GSI_CACHE_CLIENT_BYTES) {
        svc_cache_entry *o = cache_oldest(s, key, plen);
        mine--, total--, my_bytes -= o->bytes;
        cache_drop(s, o);
        free_slot = o;
    }
    while (total >= GSI_CACHE || s->cache_bytes + n > GSI_CACHE_BYTES) {
        svc_cache_entry *o = cache_oldest(s, key, 0);
        total--;
        cache_drop(s, o);
        free_slot = o;
    }
    char *copy = gs_strdup(reply);
    if (!free_slot || !copy) {
        free(copy);
        return;
    }
    snprintf(free_slot->key, sizeof free_slot->key, "%s", key);
    free_slot->reply = copy;
    free_slot->bytes = n;
    free_slot->t = now;
    s->cache_bytes += n;
}

/* A routing id seen anew (first time, or after its client expired): what
 * the cache holds under it belongs to an earlier client. */
static void cache_forget_client(gs_service *s, const unsigned char *who, size_t who_len)
{
    char key[GSI_CACHE_KEY];
    cache_key(key, sizeof key, who, who_len, "");
    size_t plen = strlen(key);
    for (int i = 0; i < GSI_CACHE; i++)
        if (s->cache[i].reply && strncmp(s->cache[i].key, key, plen) == 0)
            cache_drop(s, &s->cache[i]);
}

/* Count the client `who` as active now. False when it is new and
 * --max-clients others are active (a request within GSI_CLIENT_IDLE_S);
 * silent ones make room. Without an identity (in-process callers) true. */
static bool client_admit(gs_service *s, const unsigned char *who, size_t who_len)
{
    if (!who || who_len == 0 || who_len > sizeof s->clients[0].id)
        return true;
    double now = gs_now();
    int keep = 0, found = -1;
    for (int i = 0; i < s->n_clients; i++) {
        svc_client *c = &s->clients[i];
        bool me = c->len == who_len && memcmp(c->id, who, who_len) == 0;
        if (now - c->last > GSI_CLIENT_IDLE_S)
            continue; /* expired: dropped (`who` itself too: back after that, it is a new client) */
        if (me)
            found = keep;
        s->clients[keep++] = *c;
    }
    s->n_clients = keep;
    if (found < 0) {
        if (s->n_clients >= gsi_opt_max_clients())
            return false;
        if (!s->clients) {
            s->clients = gs_calloc((size_t)gsi_opt_max_clients(), sizeof *s->clients);
            if (!s->clients)
                return false;
        }
        found = s->n_clients++;
        cache_forget_client(s, who, who_len);
        memcpy(s->clients[found].id, who, who_len);
        s->clients[found].len = (uint8_t)who_len;
    }
    s->clients[found].last = now;
    return true;
}

/* Validate the envelope, dispatch, reply. Never fails: bad input is answered. */
char *gsi_handle_request_text(gs_service *s, const unsigned char *who, size_t who_len, const char *data,
                              size_t len, bool too_big)
{
    gs_diag d;
    gs_diag_clear(&d);
    json_object *req = NULL, *reply = NULL, *idv = NULL;
    gs_err e = GS_OK;
    if (too_big) {
        e = gs_diag_set(&d, GS_ETOOBIG, "", "the message has %zu bytes; the limit is %u bytes "
                        "(hello: limits.max_message_bytes)", len, GSI_MAX_MESSAGE);
        goto answer;
    }
    /* RFC 8259 strictly (duplicate keys, NUL, lone surrogates, ... refused)
     * before json-c's lenient tokener sees the text. */
    if (valid_utf8((const unsigned char *)data, len) && (e = gsi_json_strict(data, len, "", &d)) != GS_OK)
        goto answer;
    json_tokener *tok = json_tokener_new_ex(GSI_JSON_MAX_DEPTH);
    req = json_tokener_parse_ex(tok, data, (int)len);
    enum json_tokener_error je = json_tokener_get_error(tok);
    size_t end = req ? (size_t)json_tokener_get_parse_end(tok) : 0;
    json_tokener_free(tok);
    if (req)
        for (size_t i = end; i < len; i++)
            if (!strchr(" \t\r\n", data[i])) {
                je = json_tokener_error_parse_unexpected;
                break;
            }
    if (!valid_utf8((const unsigned char *)data, len)) {
        json_object_put(req);
        req = NULL;
        e = gs_diag_set(&d, GS_EPARSE, "", "the request is not valid UTF-8 text");
        goto answer;
    }
    if (!req || je != json_tokener_success || memchr(data, '\0', len)) {
        json_object_put(req);
        req = NULL;
        e = gs_diag_set(&d, GS_EPARSE, "", "the request is not valid JSON%s%s",
                        je != json_tokener_success ? ": " : "",
                        je != json_tokener_success ? json_tokener_error_desc(je) : "");
        goto answer;
    }
    if (json_object_get_type(req) != json_type_object) {
        e = gs_diag_set(&d, GS_ESCHEMA, "", "the request must be a JSON object");
        goto answer;
    }
    if (json_object_object_get_ex(req, "id", &idv) && json_object_get_type(idv) != json_type_string) {
        idv = NULL;
        e = gs_diag_set(&d, GS_ESCHEMA, "id", "'id' must be a string");
        goto answer;
    }
    static const char *const env_keys[] = {"v", "id", "cmd", "args", NULL};
    if ((e = gsi_json_only(req, "", env_keys, &d)) != GS_OK)
        goto answer;
    json_object *v;
    if (!json_object_object_get_ex(req, "v", &v)) {
        e = gs_diag_set(&d, GS_ESCHEMA, "v", "missing required field 'v' (protocol version)");
        goto answer;
    }
    /* A number equal to 1 (the schema's const: 1 and 1.0 alike). */
    double vnum;
    if (!gsi_json_as_double(v, &vnum) || vnum != 1.0) {
        e = gs_diag_set(&d, GS_EVERSION, "v", "protocol version %s is not supported (this daemon speaks 1)",
                        json_object_to_json_string(v));
        goto answer;
    }
    if (!idv) {
        e = gs_diag_set(&d, GS_ESCHEMA, "id", "missing required field 'id'");
        goto answer;
    }
    const char *id = json_object_get_string(idv);
    if (strlen(id) == 0 || strlen(id) > 128) {
        e = gs_diag_set(&d, GS_ERANGE, "id", "'id' must have 1 to 128 characters");
        goto answer;
    }
    if (!client_admit(s, who, who_len)) {
        e = gs_diag_set(&d, GS_ETOOBIG, "", "too many clients: %lld are active (a client counts until it has "
                        "been silent for %.0f s); retry later, or start gearsimd with a larger --max-clients",
                        (long long)gsi_opt_max_clients(), GSI_CLIENT_IDLE_S);
        goto answer;
    }
    char key[GSI_CACHE_KEY];
    cache_key(key, sizeof key, who, who_len, id);
    const char *cached = cache_get(s, key);
    if (cached) {
        json_object_put(req);
        return gs_strdup(cached);
    }
    json_object *cmdv, *args = NULL;
    if (!json_object_object_get_ex(req, "cmd", &cmdv) || json_object_get_type(cmdv) != json_type_string) {
        e = gs_diag_set(&d, GS_ESCHEMA, "cmd", "'cmd' must be a string naming a command");
        goto answer;
    }
    const gsi_command *c = gsi_command_find(json_object_get_string(cmdv));
    if (!c) {
        e = gs_diag_set(&d, GS_EUNKNOWN, "cmd", "unknown command '%.64s'", json_object_get_string(cmdv));
        goto answer;
    }
    if (json_object_object_get_ex(req, "args", &args)) {
        if (json_object_get_type(args) != json_type_object) {
            e = gs_diag_set(&d, GS_ESCHEMA, "args", "'args' must be an object");
            goto answer;
        }
    }
    json_object *empty = NULL;
    if (!args)
        args = empty = json_object_new_object();
    if ((e = gsi_json_only(args, "args", c->args, &d)) == GS_OK) {
        const char *lost = gsi_watchdog_check();
        if (lost)
            e = gs_diag_set(&d, GS_ERANKLOST, "", "%s", lost);
        else if (s->adv.active && !c->during_advance)
            e = gs_diag_set(&d, GS_ESTATE, "cmd", "'%s' is not allowed while an advance runs (pause does not end it; cancel does)", c->name);
        else if (s->stiff.run && !c->during_advance)
            e = gs_diag_set(&d, GS_ESTATE, "cmd", "'%s' is not allowed while a stiffness analysis runs (cancel ends it)", c->name);
        else if (s->validating && !gsi_validating_allows(c->name))
            e = gs_diag_set(&d, GS_EBUSY, "cmd", "'%s' waits: a sweep request is being validated (a second or "
                            "so; ask again)", c->name);
        else if (s->sweep && !gsi_sweep_allows(c->name))
            e = gs_diag_set(&d, GS_ESTATE, "cmd", "'%s' is not allowed while a sweep runs (cancel ends it)", c->name);
        else {
            json_object *result = NULL;
            e = c->handler(s, args, id, &result, &d);
            if (e == GS_OK) {
                reply = json_object_new_object();
                json_object_object_add(reply, "v", json_object_new_int(1));
                json_object_object_add(reply, "id", json_object_get(idv));
                json_object_object_add(reply, "ok", json_object_new_boolean(1));
                json_object_object_add(reply, "result", result ? result : json_object_new_object());
            } else {
                json_object_put(result);
            }
        }
    }
    json_object_put(empty);
answer:
    if (!reply)
        reply = error_reply(idv, e, &d);
    gsi_json_scrub(reply);
    const char *txt = json_object_to_json_string_ext(reply, JSON_C_TO_STRING_PLAIN);
    if (idv && json_object_get_type(idv) == json_type_string && e != GS_ETOOBIG) {
        char k2[GSI_CACHE_KEY];
        cache_key(k2, sizeof k2, who, who_len, json_object_get_string(idv));
        cache_put(s, k2, txt);
    }
    char *out = gs_strdup(txt);
    json_object_put(reply);
    json_object_put(req);
    return out;
}

static void handle_request(gs_service *s, zmq_msg_t *ident, bool delim, const char *data, size_t len,
                           bool too_big)
{
    char *txt = gsi_handle_request_text(s, zmq_msg_data(ident), zmq_msg_size(ident), data, len, too_big);
    if (txt)
        send_reply(s, ident, delim, txt);
    free(txt);
}

/* Receive one whole multipart message from the ROUTER and answer it. */
/* A request received while polled from within work (s->inside): one that
 * would change something (load, advance, cancel, ...) cannot run in the
 * middle of it, so it waits in order and is answered as soon as the work
 * has returned to the service loop (answer_deferred). Takes the identity
 * and the text (*data set to NULL) when it defers. */
typedef struct svc_deferred {
    zmq_msg_t ident;
    bool delim;
    char *data;
    size_t len;
} svc_deferred;

static bool defer_request(gs_service *s, zmq_msg_t *ident, bool delim, char **data, size_t len)
{
    if (!s->inside || s->validating)
        return false;
    json_object *req = json_tokener_parse(*data), *cmd;
    bool later = false;
    if (req && json_object_object_get_ex(req, "cmd", &cmd) && json_object_get_type(cmd) == json_type_string) {
        const char *c = json_object_get_string(cmd);
        /* `state` reads the running system: within a chunk of steps it waits
         * for the chunk's end, where every body and energy is of one step. */
        later = !gsi_validating_allows(c) || (!strcmp(c, "state") && gs_engine_stepping(s->eng));
    }
    json_object_put(req);
    if (!later)
        return false;
    if (!s->deferred)
        s->deferred = calloc(GSI_DEFER_MAX, sizeof *s->deferred);
    if (!s->deferred || s->n_deferred >= GSI_DEFER_MAX) {
        gs_diag d;
        gs_diag_set(&d, GS_EBUSY, "cmd", "%d requests already wait for the work under way; ask again",
                    GSI_DEFER_MAX);
        json_object *r = error_reply(NULL, GS_EBUSY, &d);
        send_reply(s, ident, delim, json_object_to_json_string_ext(r, JSON_C_TO_STRING_PLAIN));
        json_object_put(r);
        return true;
    }
    svc_deferred *q = &s->deferred[s->n_deferred++];
    zmq_msg_init(&q->ident);
    zmq_msg_move(&q->ident, ident);
    q->delim = delim;
    q->data = *data;
    q->len = len;
    *data = NULL;
    return true;
}

/* The deferred requests, oldest first (from the service loop). */
static void answer_deferred(gs_service *s)
{
    while (s->n_deferred > 0 && !s->shutdown) {
        svc_deferred q = s->deferred[0];
        s->n_deferred--;
        memmove(s->deferred, s->deferred + 1, (size_t)s->n_deferred * sizeof *s->deferred);
        handle_request(s, &q.ident, q.delim, q.data, q.len, false);
        free(q.data);
        zmq_msg_close(&q.ident);
    }
}

static void free_deferred(gs_service *s)
{
    for (int i = 0; i < s->n_deferred; i++) {
        free(s->deferred[i].data);
        zmq_msg_close(&s->deferred[i].ident);
    }
    free(s->deferred);
    s->deferred = NULL;
    s->n_deferred = 0;
}

static void receive_one(gs_service *s)
{
    zmq_msg_t ident, part;
    zmq_msg_init(&ident);
    if (zmq_msg_recv(&ident, s->router, ZMQ_DONTWAIT) < 0) {
        zmq_msg_close(&ident);
        return;
    }
    int nparts = 0;
    bool delim = false, too_big = false;
    char *data = NULL;
    size_t len = 0;
    while (zmq_msg_more(&ident) || nparts > 0) {
        zmq_msg_init(&part);
        if (zmq_msg_recv(&part, s->router, 0) < 0) {
            zmq_msg_close(&part);
            break;
        }
        size_t n = zmq_msg_size(&part);
        bool more = zmq_msg_more(&part);
        if (nparts == 0 && n == 0 && more) {
            delim = true; /* REQ-style envelope */
        } else {
            nparts++;
            if (nparts == 1) {
                if (n > GSI_MAX_MESSAGE) {
                    too_big = true;
                    len = n; /* named in the reply */
                } else {
                    data = malloc(n + 1);
                    if (data) {
                        memcpy(data, zmq_msg_data(&part), n);
                        data[n] = '\0';
                        len = n;
                    }
                }
            }
        }
        zmq_msg_close(&part);
        if (!more)
            break;
    }
    if (nparts > 1) {
        gs_diag d;
        gs_diag_set(&d, GS_ESCHEMA, "", "a request is one frame; got %d", nparts);
        json_object *r = error_reply(NULL, GS_ESCHEMA, &d);
        send_reply(s, &ident, delim, json_object_to_json_string_ext(r, JSON_C_TO_STRING_PLAIN));
        json_object_put(r);
    } else if (nparts == 1 && data && !too_big && defer_request(s, &ident, delim, &data, len)) {
        /* answered after the work under way */
    } else if (nparts == 1) {
        handle_request(s, &ident, delim, data ? data : "", len, too_big || !data);
    } else {
        gs_diag d;
        gs_diag_set(&d, GS_EPARSE, "", "empty message");
        json_object *r = error_reply(NULL, GS_EPARSE, &d);
        send_reply(s, &ident, delim, json_object_to_json_string_ext(r, JSON_C_TO_STRING_PLAIN));
        json_object_put(r);
    }
    free(data);
    zmq_msg_close(&ident);
}

/* A rank died (watchdog.c): the error event, the done events of the work
 * in progress (its error names the cause), the record flushed, then the
 * job aborted: nothing more can be computed, and a broadcast to the dead
 * rank would block. The autosave of an unfinished advance is kept. */
static void rank_lost(gs_service *s)
{
    const char *msg = gsi_watchdog_lost();
    json_object *w = json_object_new_object();
    json_object_object_add(w, "code", json_object_new_string(gs_errcode(GS_ERANKLOST)));
    json_object_object_add(w, "message", json_object_new_string(msg));
    gsi_publish(s, "error", w);
    const char *pid[3] = {s->adv.active ? s->adv.parent_id : NULL, s->sweep ? gsi_sweep_parent(s) : NULL,
                          s->stiff.run ? s->stiff.parent_id : NULL};
    static const char *const kind[3] = {"advance", "sweep", "stiffness"};
    for (int k = 0; k < 3; k++) {
        if (!pid[k])
            continue;
        json_object *o = json_object_new_object();
        json_object_object_add(o, "parent_id", json_object_new_string(pid[k]));
        json_object_object_add(o, "cancelled", json_object_new_boolean(0));
        json_object *e = json_object_new_object();
        json_object_object_add(e, "code", json_object_new_string(gs_errcode(GS_ERANKLOST)));
        json_object_object_add(e, "message", json_object_new_string(msg));
        json_object_object_add(o, "error", e);
        gsi_publish_done(s, k == 0 && s->adv.job >= 0 ? "job" : kind[k], o);
    }
    gsi_record_flush_or_stop(s, "the record could not be written");
    gs_record_close(&s->record);
    /* The events leave before the abort. */
    struct timespec ts = {0, 300000000};
    nanosleep(&ts, NULL);
    MPI_Abort(MPI_COMM_WORLD, 3);
}

static void heartbeat(gs_service *s);

bool gsi_validating_allows(const char *cmd)
{
    static const char *const ok[] = {"hello", "status", "state", "jobs", "fetch", "modal", NULL};
    for (int i = 0; ok[i]; i++)
        if (!strcmp(cmd, ok[i]))
            return true;
    return false;
}

/* Answer up to max queued requests, stopping early when none is left or
 * a shutdown was asked for. */
static void drain_router(gs_service *s, int max)
{
    for (int i = 0; i < max && !s->shutdown; i++) {
        int ev = 0;
        size_t n = sizeof ev;
        zmq_getsockopt(s->router, ZMQ_EVENTS, &ev, &n);
        if (!(ev & ZMQ_POLLIN))
            break;
        receive_one(s);
    }
}

/* Long validation on rank 0 (a sweep's every point) calls this every few
 * milliseconds: requests are answered meanwhile (those that change nothing;
 * the others are told to wait), and heartbeats go on, so the service is
 * never silent for longer than a slice (docs/RELIABILITY.md, "Limits"). */
void gsi_poll_during(void *user)
{
    gs_service *s = user;
    double now = gs_now();
    if (now - s->last_poll_during < 0.005)
        return;
    s->last_poll_during = now;
    if (!s->router)
        return;
    drain_router(s, 64);
    if (now - s->last_heartbeat >= 1.0) {
        s->last_heartbeat = now;
        heartbeat(s);
    }
}

/* The gs_poll hook (include/gearsim/util.h) while the service runs: called
 * from within a request's or a chunk's computation (meshing, assembly,
 * stiffness columns, rank 0's waits on the other ranks), it answers the
 * requests that read (the others wait: defer_request) and keeps the
 * heartbeat, so a long piece of work leaves no silence longer than the
 * pieces it is divided into (docs/RELIABILITY.md, "Limits"). */
static void poll_within(void *user)
{
    gs_service *s = user;
    if (s->inside || s->shutdown)
        return;
    s->inside = true;
    gsi_poll_during(s);
    s->inside = false;
    if (gsi_watchdog_lost())
        rank_lost(s);
}

static void heartbeat(gs_service *s)
{
    static const char *const names[] = {"empty", "loaded", "running", "paused"};
    json_object *o = json_object_new_object();
    json_object_object_add(o, "state", json_object_new_string(names[s->state]));
    gsi_publish(s, "heartbeat", o);
}

/* One chunk of the running advance, sized to about 20 ms of work. */
static void run_chunk(gs_service *s)
{
    gs_system *sys = gs_engine_system(s->eng);
    int64_t left = s->adv.target_step - sys->step;
    if (left <= 0) {
        gsi_finish_advance(s, false, GS_OK, NULL);
        return;
    }
    if (s->adv.job >= 0)
        gsi_job_between_chunks(s);
    int64_t n = s->chunk_steps < left ? s->chunk_steps : left;
    /* Stop a job's chunk at its next scheduled load change. */
    if (s->adv.job >= 0) {
        json_object *sch = s->jobs[s->adv.job].schedule;
        if (sch && s->adv.next_schedule < (int)json_object_array_length(sch)) {
            double at = json_object_get_double(json_object_object_get(
                json_object_array_get_idx(sch, (size_t)s->adv.next_schedule), "at"));
            int64_t k = (int64_t)ceil((at - sys->time) / sys->h - 1e-9);
            if (k >= 1 && k < n)
                n = k;
        }
    }
    double t0 = gs_now();
    int64_t done = 0;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = gs_engine_run(s->eng, GS_OP_STEP, &n, sizeof n, &d, &done);
    gsi_telemetry_flush(s);
    double dt = gs_now() - t0;
    s->timing_step += dt;
    if (done > 0 && dt > 0) {
        double rate = (double)done / dt;
        s->steps_per_second = rate;
        /* About 10 ms of work per chunk, growing at most twofold per chunk
         * so a misjudged rate never makes `status` wait long. */
        int64_t want = (int64_t)(0.01 * rate);
        if (want > 2 * s->chunk_steps)
            want = 2 * s->chunk_steps;
        s->chunk_steps = want < 1 ? 1 : (want > 1000000 ? 1000000 : want);
    }
    gsi_record_flush_or_stop(s, "the record could not be written");
    if (e == GS_OK && !s->nonfinite[0])
        gsi_state_finite(s, true, s->nonfinite, sizeof s->nonfinite);
    if (s->nonfinite[0]) {
        fprintf(stderr, "gearsimd: %s\n", s->nonfinite);
        gsi_finish_advance(s, false, GS_ERANGE, s->nonfinite);
        s->nonfinite[0] = '\0';
        return;
    }
    if (e != GS_OK) {
        /* A limit of the scene's numerics (gs_system_check) says which field to change. */
        char why[sizeof sys->diag.field + sizeof sys->diag.message + 4];
        if (sys->diag.message[0])
            snprintf(why, sizeof why, "%s: %s", sys->diag.field, sys->diag.message);
        gsi_finish_advance(s, false, e, sys->diag.message[0] ? why
                                        : e == GS_ENOCONV ? "the step's Newton iteration did not converge" : gs_strerror(e));
        return;
    }
    double now = gs_now();
    if (now - s->last_progress > 0.1 || sys->step >= s->adv.target_step) {
        s->last_progress = now;
        json_object *o = json_object_new_object();
        double total = (double)(s->adv.target_step - s->adv.start_step);
        json_object_object_add(o, "parent_id", json_object_new_string(s->adv.parent_id));
        json_object_object_add(o, "fraction", json_object_new_double(total > 0 ? (double)(sys->step - s->adv.start_step) / total : 1.0));
        json_object_object_add(o, "steps_per_second", json_object_new_double(s->steps_per_second));
        gsi_publish(s, "progress", o);
    }
    if (sys->step >= s->adv.target_step)
        gsi_finish_advance(s, false, GS_OK, NULL);
    else
        gsi_autosave_if_due(s);
}

static gs_err write_connection_file(gs_service *s)
{
    const char *path = s->cfg->connection_file;
    char dir[PATH_MAX];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash && slash != dir) {
        *slash = '\0';
        mkdir(dir, 0700);
    }
    json_object *o = json_object_new_object();
    int size = gs_engine_size(s->eng);
    json_object_object_add(o, "v", json_object_new_int(1));
    json_object_object_add(o, "protocol", json_object_new_int(1));
    json_object_object_add(o, "session", json_object_new_string(s->session));
    json_object_object_add(o, "command", json_object_new_string(s->cmd_endpoint));
    json_object_object_add(o, "telemetry", json_object_new_string(s->tel_endpoint));
    /* Telemetry also comes in batches on the topic `batch` (telemetry.c). */
    json_object_object_add(o, "telemetry_batch", json_object_new_boolean(1));
    json_object_object_add(o, "pid", json_object_new_int((int)getpid()));
    json_object_object_add(o, "ranks", json_object_new_int(size));
    json_object_object_add(o, "version", json_object_new_string("0.1.0"));
    json_object_object_add(o, "data_dir", json_object_new_string(s->data_dir));
    if (gsi_curve_enabled())
        json_object_object_add(o, "curve_server_key", json_object_new_string(gsi_curve_server_public()));
    const char *cpub, *csec;
    if (gsi_curve_local_client(&cpub, &csec)) {
        /* The loopback client key pair: who can read this 0600 file can
         * talk to the daemon, nobody else (docs/reference/protocol.md). */
        json_object_object_add(o, "curve_client_public_key", json_object_new_string(cpub));
        json_object_object_add(o, "curve_client_secret_key", json_object_new_string(csec));
    }
    char err[PATH_MAX + 200];
    gs_err e = GS_OK;
    const char *txt = json_object_to_json_string_ext(o, JSON_C_TO_STRING_PRETTY);
    if (gsi_write_connection_text(path, txt, err, sizeof err) != 0) {
        fprintf(stderr, "gearsimd: %s\n", err);
        e = GS_EIO;
    } else {
        gsi_watchdog_start(path, txt);
    }
    json_object_put(o);
    return e;
}

static gs_err bind_socket(void *sock, const char *bind, int port, char *out, size_t cap)
{
    /* ZeroMQ binds addresses and interface names, not host names: localhost
     * is 127.0.0.1; an IPv6 address ("::1", "[::1]") needs ZMQ_IPV6 and
     * brackets. */
    char host[256];
    if (!strcmp(bind, "localhost"))
        snprintf(host, sizeof host, "127.0.0.1");
    else if (strchr(bind, ':') && bind[0] != '[')
        snprintf(host, sizeof host, "[%s]", bind);
    else
        snprintf(host, sizeof host, "%s", bind);
    if (strchr(host, ':')) {
        int v6 = 1;
        zmq_setsockopt(sock, ZMQ_IPV6, &v6, sizeof v6);
    }
    char ep[300];
    if (port > 0)
        snprintf(ep, sizeof ep, "tcp://%s:%d", host, port);
    else
        snprintf(ep, sizeof ep, "tcp://%s:*", host);
    if (zmq_bind(sock, ep) != 0) {
        fprintf(stderr, "gearsimd: cannot bind %s: %s\n", ep, zmq_strerror(errno));
        return GS_EIO;
    }
    size_t n = cap;
    zmq_getsockopt(sock, ZMQ_LAST_ENDPOINT, out, &n);
    return GS_OK;
}

gs_err gsi_service_init(gs_service *s, gs_engine *eng, const gs_service_config *cfg)
{
    s->eng = eng;
    s->cfg = cfg;
    s->adv.job = -1;
    s->chunk_steps = 20;
    if (!realpath(cfg->data_dir ? cfg->data_dir : ".", s->data_dir)) {
        fprintf(stderr, "gearsimd: data directory '%s' does not exist\n", cfg->data_dir);
        return GS_EIO;
    }
    FILE *ur = fopen("/dev/urandom", "rb");
    unsigned char rnd[16] = {0};
    if (!ur || fread(rnd, 1, sizeof rnd, ur) != sizeof rnd) {
        double t = gs_now();
        memcpy(rnd, &t, sizeof t);
    }
    if (ur)
        fclose(ur);
    for (int i = 0; i < 16; i++)
        snprintf(s->session + 2 * i, 3, "%02x", rnd[i]);
    gs_engine_set_hook(eng, step_hook, s);
    gs_engine_set_energy_schedule(eng, true); /* step_hook reads them on its steps only */
    return GS_OK;
}

void gsi_service_release(gs_service *s)
{
    for (int i = 0; i < GSI_CACHE; i++) {
        free(s->cache[i].reply);
        s->cache[i].reply = NULL;
    }
    for (int i = 0; i < s->n_jobs; i++) {
        free(s->jobs[i].scene_json);
        json_object_put(s->jobs[i].schedule);
    }
    s->n_jobs = 0;
    for (int i = 0; i < s->n_finished; i++)
        json_object_put(s->finished[i].done);
    s->n_finished = 0;
    gs_stiffness_run_free(&s->stiff.run);
    free(s->clients);
    s->clients = NULL;
    s->n_clients = 0;
    gsi_telemetry_free(s);
}

gs_err gs_service_run(gs_engine *eng, const gs_service_config *cfg)
{
    const char *bind = cfg->bind ? cfg->bind : "127.0.0.1";
    gs_service *s = gs_calloc(1, sizeof *s);
    if (!s)
        return GS_ENOMEM;
    if (gsi_service_init(s, eng, cfg) != GS_OK) {
        gs_diag d;
        gs_engine_run(eng, GS_OP_SHUTDOWN, NULL, 0, &d, NULL); /* release the other ranks */
        free(s);
        return GS_EIO;
    }

    s->zctx = zmq_ctx_new();
    s->router = zmq_socket(s->zctx, ZMQ_ROUTER);
    s->pub = zmq_socket(s->zctx, ZMQ_XPUB); /* XPUB: telemetry.c reads the subscriptions */
    int linger = 0, hwm = 10000, mandatory = 0;
    /* No transport cap: ZMQ_MAXMSGSIZE would drop the connection with no
     * reply. Every frame is received; above GSI_MAX_MESSAGE it is discarded
     * at once and answered with too_large naming the limit. */
    int64_t maxmsg = -1;
    zmq_setsockopt(s->router, ZMQ_LINGER, &linger, sizeof linger);
    zmq_setsockopt(s->pub, ZMQ_LINGER, &linger, sizeof linger);
    zmq_setsockopt(s->pub, ZMQ_SNDHWM, &hwm, sizeof hwm);
    zmq_setsockopt(s->router, ZMQ_ROUTER_MANDATORY, &mandatory, sizeof mandatory);
    zmq_setsockopt(s->router, ZMQ_MAXMSGSIZE, &maxmsg, sizeof maxmsg);
    gs_err e = GS_OK;
    if (!gs_bind_is_loopback(bind) && !gsi_curve_enabled()) {
        /* Nothing is bound; the other ranks still get GS_OP_SHUTDOWN below. */
        fprintf(stderr, "gearsimd: refusing to bind '%s' without CURVE: remote use needs "
                        "--curve-server-key FILE and --curve-allow DIR_OR_FILE (gearctl keys)\n", bind);
        e = GS_EINVAL;
    } else if (gsi_curve_enabled()) {
        /* The ZAP handler is bound before the sockets so that no client is
         * ever let in unchecked. */
        if (gsi_curve_start(s->zctx) != 0 || gsi_curve_apply(s->router) != 0 || gsi_curve_apply(s->pub) != 0) {
            fprintf(stderr, "gearsimd: cannot set up CURVE: %s\n", zmq_strerror(errno));
            e = GS_EIO;
        } else {
            fprintf(stderr, "gearsimd: CURVE on, server key %s, %d client key(s) allowed\n",
                    gsi_curve_server_public(), gsi_curve_allowed_count());
        }
    }
    if (e == GS_OK)
        e = bind_socket(s->router, bind, cfg->command_port, s->cmd_endpoint, sizeof s->cmd_endpoint);
    if (e == GS_OK)
        e = bind_socket(s->pub, bind, cfg->telemetry_port, s->tel_endpoint, sizeof s->tel_endpoint);
    if (e == GS_OK && opt_resume) {
        /* Before the connection file: clients find the advance running. */
        gs_diag d;
        gs_diag_clear(&d);
        gs_err re = gsi_resume(s, &d);
        if (re == GS_ENOTFOUND && !gs_engine_system(eng))
            fprintf(stderr, "gearsimd: --resume: nothing to resume (%s)\n", d.message);
        else if (re != GS_OK)
            fprintf(stderr, "gearsimd: --resume failed: %s\n", d.message[0] ? d.message : gs_strerror(re));
    }
    if (e == GS_OK && write_connection_file(s) != GS_OK) {
        fprintf(stderr, "gearsimd: cannot write the connection file '%s'\n", cfg->connection_file);
        e = GS_EIO;
    }
    if (e == GS_OK) {
        struct sigaction sa;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = on_signal;
        sigaction(SIGTERM, &sa, NULL);
        sigaction(SIGINT, &sa, NULL);
        signal(SIGPIPE, SIG_IGN);
        fprintf(stderr, "gearsimd: %d rank(s), commands on %s, telemetry on %s\n",
                gs_engine_size(eng), s->cmd_endpoint, s->tel_endpoint);
    }
    if (e == GS_OK)
        gs_poll_set(poll_within, s);
    while (e == GS_OK && !s->shutdown && !stop_signal) {
        if (s->n_deferred)
            answer_deferred(s);
        bool running = (s->adv.active && s->state == SVC_RUNNING) || s->stiff.run || s->sweep;
        zmq_pollitem_t items[1] = {{s->router, 0, ZMQ_POLLIN, 0}};
        /* A sweep whose points all run on other ranks waits up to 5 ms at a
         * time (their rows wait in MPI; every group has more than that
         * queued): rank 0 leaves the core to the groups. */
        int rc = zmq_poll(items, 1, !running ? 100 : s->sweep && gsi_sweep_idle(s) ? 5 : 0);
        if (rc > 0 && (items[0].revents & ZMQ_POLLIN))
            drain_router(s, 256);
        if (s->shutdown)
            break;
        if (s->sweep)
            gsi_sweep_chunk(s);
        else if (s->stiff.run)
            gsi_stiffness_chunk(s);
        else if (s->adv.active && s->state == SVC_RUNNING)
            run_chunk(s);
        else if (!s->adv.active)
            gsi_start_next_job(s);
        double now = gs_now();
        if (now - s->last_heartbeat >= 1.0) {
            s->last_heartbeat = now;
            heartbeat(s);
        }
        if (gsi_watchdog_lost())
            rank_lost(s);
    }
    gs_poll_set(NULL, NULL);
    free_deferred(s);
    gsi_watchdog_stop();
    if (s->adv.active) {
        s->keep_autosave = true; /* still resumable with --resume */
        gsi_finish_advance(s, true, GS_OK, "the daemon is shutting down");
    }
    if (s->stiff.run)
        gsi_stiffness_stop(s, true);
    if (s->sweep)
        gsi_sweep_stop(s, true); /* finished points stay in its table: resumable */
    gs_record_close(&s->record);
    gs_diag d;
    gs_engine_run(eng, GS_OP_SHUTDOWN, NULL, 0, &d, NULL);
    if (cfg->connection_file)
        unlink(cfg->connection_file);
    /* The last events (the cancelled `done`) leave before the socket goes:
     * behind a backlog of telemetry to a slow subscriber on a loaded
     * machine that can take seconds. */
    int flush_ms = 5000;
    zmq_setsockopt(s->pub, ZMQ_LINGER, &flush_ms, sizeof flush_ms);
    zmq_close(s->router);
    zmq_close(s->pub);
    gsi_curve_stop(s->zctx);
    zmq_ctx_term(s->zctx);
    gsi_service_release(s);
    free(s);
    return e;
}
