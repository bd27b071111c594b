/* SPDX-License-Identifier: MIT
 * Internal: the service's state shared by the loop (service.c) and the
 * command handlers (commands.c). */
#ifndef GSI_SERVICE_INTERNAL_H
#define GSI_SERVICE_INTERNAL_H

#include <json-c/json.h>
#include <limits.h>

#include "gearsim/record.h"
#include "gearsim/service.h"

#define GSI_MAX_MESSAGE (4u << 20)
#define GSI_MAX_STEPS_PER_ADVANCE 1000000000LL
/* Jobs: at most GSI_MAX_JOBS queued or running; finished ones stay listed
 * (`jobs`) for GSI_JOBS_KEEP_S seconds, the newest GSI_JOBS_KEEP_FINISHED at
 * most, then are removed, so a daemon takes any number of submits. */
#define GSI_MAX_JOBS 64
#define GSI_JOBS_KEEP_FINISHED 32
#define GSI_JOBS_KEEP_S 3600.0
/* Reply cache (retried ids are answered without running twice): at most
 * GSI_CACHE entries and GSI_CACHE_BYTES in all, GSI_CACHE_CLIENT_ENTRIES and
 * GSI_CACHE_CLIENT_BYTES per client (oldest dropped first), each kept
 * GSI_CACHE_LIFETIME_S seconds; a reply larger than a client's byte budget
 * is not kept. A client's entries are dropped when its routing id is seen
 * again after it expired (GSI_CLIENT_IDLE_S), so a reused id never gets
 * another client's replies. */
#define GSI_CACHE 4096
#define GSI_CACHE_BYTES (32u << 20)
#define GSI_CACHE_CLIENT_ENTRIES 256
#define GSI_CACHE_CLIENT_BYTES (4u << 20)
#define GSI_CACHE_LIFETIME_S 60.0
/* identity (at most 255 bytes, hex) + '/' + id (at most 128) + NUL */
#define GSI_CACHE_KEY (2 * 255 + 1 + 128 + 1)

typedef enum { SVC_EMPTY, SVC_LOADED, SVC_RUNNING, SVC_PAUSED } svc_state;

typedef struct svc_job {
    char id[32];
    char *scene_json;
    json_object *schedule;  /* array of {at, load}, sorted by at */
    double duration;
    char record[PATH_MAX];
    char state[16];         /* queued, running, done, failed, cancelled */
    char error[256];
    double finished;        /* gs_now() when it ended (0 while queued or running) */
} svc_job;

typedef struct svc_advance {
    bool active;
    char parent_id[160];
    int64_t start_step, target_step;
    double wall_start;
    int job;                /* index of the job driving it, -1 for a client */
    int next_schedule;
    int64_t next_autosave;  /* step at or after which the next autosave is due (0: none) */
} svc_advance;

/* A chunked `stiffness` analysis under way (one roll position per poll). */
typedef struct svc_stiffness {
    struct gs_stiffness_run *run; /* NULL when none */
    char parent_id[160];
    char path[PATH_MAX];     /* HDF5 output (absolute) or "" */
    char rel[600];           /* the request's path argument */
    double wall_start, last_progress;
} svc_stiffness;

/* The last finished long requests (advance, job, stiffness), newest last:
 * `status` lists them so that a client that missed the `done` event
 * (lossy PUB) still learns the outcome. */
#define GSI_FINISHED_KEEP 8
typedef struct svc_finished {
    char kind[16];           /* advance, job, stiffness */
    json_object *done;       /* the done event's body */
} svc_finished;

/* A `sweep` job under way (service/sweep_cmd.c). */
typedef struct svc_sweep svc_sweep;

typedef struct svc_cache_entry {
    char key[GSI_CACHE_KEY]; /* identity hex + '/' + id */
    char *reply;
    size_t bytes;            /* strlen(reply) + 1 */
    double t;                /* when stored (gs_now) */
} svc_cache_entry;

/* A client seen on the command socket: its routing id and last request. */
typedef struct svc_client {
    unsigned char id[255];
    uint8_t len;
    double last;
} svc_client;

typedef struct gs_service {
    gs_engine *eng;
    const gs_service_config *cfg;
    char data_dir[PATH_MAX];
    void *zctx, *router, *pub;
    char cmd_endpoint[256], tel_endpoint[256];
    char session[33];
    uint64_t seq;
    svc_state state;
    svc_advance adv;
    svc_stiffness stiff;
    svc_sweep *sweep;        /* NULL when none */
    svc_finished finished[GSI_FINISHED_KEEP];
    int n_finished;
    gs_record *record;
    int64_t chunk_steps;
    double steps_per_second;
    double last_progress, last_heartbeat;
    svc_job jobs[GSI_MAX_JOBS + GSI_JOBS_KEEP_FINISHED];
    int n_jobs, job_counter;
    svc_cache_entry cache[GSI_CACHE];
    size_t cache_bytes;      /* sum of the entries' bytes */
    bool shutdown;
    bool validating;           /* a long validation polls the socket (gsi_poll_during) */
    bool inside;               /* polled from within a request or a chunk (gs_poll): the
                                * requests that would change something wait (deferred) */
    struct svc_deferred *deferred; /* those requests, answered in order after it */
    int n_deferred;
    double last_poll_during;
    char nonfinite[320];       /* the first non-finite value of the running advance, "" none */
    double timing_step, timing_telemetry, timing_record;
    bool keep_autosave;     /* set at shutdown: the cancelled advance stays resumable */
    svc_client *clients;    /* active clients (--max-clients), n_clients of them */
    int n_clients;
    struct svc_telemetry *tel; /* telemetry events queued as text (telemetry.c) */
} gs_service;

/* Events (PUB): adds v, type, seq, session, step, time; takes ownership of o. */
void gsi_publish(gs_service *s, const char *type, json_object *o);
json_object *gsi_state_json(gs_service *s);
/* Queue the telemetry event (gsi_publish of gsi_state_json, parent_id added
 * in an advance) as text, its seq taken; false when out of memory (nothing
 * queued, no seq taken). gsi_telemetry_flush sends the queue; gsi_publish
 * sends it first. src/service/telemetry.c. */
bool gsi_telemetry_queue(gs_service *s);
void gsi_telemetry_flush(gs_service *s);
/* One telemetry event's text, published in the form(s) subscribed to. */
void gsi_telemetry_publish_one(gs_service *s, const char *txt);
void gsi_telemetry_free(gs_service *s);
/* Open the run record at `path` for the loaded system, with the meshes of
 * its elastic bodies when the scene records field snapshots. */
gs_err gsi_record_open(gs_service *s, const char *path, gs_record **out, gs_diag *d);
/* The same, HDF5 creating the file through create_as (/proc/self/fd/N). */
gs_err gsi_record_open_as(gs_service *s, const char *path, const char *create_as, gs_record **out, gs_diag *d);
/* A path under the data directory as the client gave it (relative to it);
 * any other path unchanged. Points into full. */
const char *gsi_data_relative(const gs_service *s, const char *full);
/* Resolve a client path inside the data directory; refuses absolute paths,
 * '..' components and symlinks that lead outside. */
gs_err gsi_resolve_path(gs_service *s, const char *rel, char *out, size_t cap, bool for_write,
                        gs_diag *d);

/* Requests deferred while polled from within work (at most this many;
 * more are told to ask again). */
#define GSI_DEFER_MAX 256

/* Socket-free core of the service (tests/fuzz drive it directly):
 * gsi_service_init fills a zeroed gs_service (data directory, session,
 * step hook) without sockets; gsi_handle_request_text answers one request
 * text from client `who` (any bytes, the reply cache's key) and returns the
 * reply text (malloc'd; NULL only when out of memory); gsi_service_release
 * frees what the requests left (reply cache, jobs). Events are dropped while
 * s->pub is NULL. */
gs_err gsi_service_init(gs_service *s, gs_engine *eng, const gs_service_config *cfg);
char *gsi_handle_request_text(gs_service *s, const unsigned char *who, size_t who_len, const char *data,
                              size_t len, bool too_big);
void gsi_service_release(gs_service *s);

/* Command table (commands.c). */
typedef gs_err (*gsi_handler)(gs_service *s, json_object *args, const char *id,
                              json_object **result, gs_diag *d);
typedef struct gsi_command {
    const char *name;
    gsi_handler handler;
    bool during_advance;     /* may run while an advance is in progress */
    const char *const *args; /* allowed argument names (NULL-terminated) */
} gsi_command;
const gsi_command *gsi_command_find(const char *name);
const gsi_command *gsi_commands(void);
void gsi_start_next_job(gs_service *s);
void gsi_finish_advance(gs_service *s, bool cancelled, gs_err err, const char *msg);
void gsi_job_between_chunks(gs_service *s);
/* Publish the `done` event of a long request of `kind` and keep its body
 * for `status` (takes ownership of o). */
void gsi_publish_done(gs_service *s, const char *kind, json_object *o);
/* The next chunk of a chunked stiffness analysis (service loop), and its
 * end: cancelled (cancel, shutdown) or finished. */
void gsi_stiffness_chunk(gs_service *s);
void gsi_stiffness_stop(gs_service *s, bool cancelled);

/* The `sweep` job (sweep_cmd.c): the command, the next slice (service
 * loop), its end (cancelled: cancel, shutdown), its entry in `status`, and
 * whether a command may run while it holds the other ranks. */
gs_err gsi_cmd_sweep(gs_service *s, json_object *args, const char *id, json_object **result, gs_diag *d);
void gsi_sweep_chunk(gs_service *s);
/* The sweep has nothing for rank 0 to compute now: wait for requests with a timeout. */
bool gsi_sweep_idle(gs_service *s);
void gsi_sweep_stop(gs_service *s, bool cancelled);
json_object *gsi_sweep_status(gs_service *s);
bool gsi_sweep_allows(const char *cmd);

/* Flush the record; on failure (disk full, ...) publish an `error` event and
 * stop recording. The simulation goes on either way. */
void gsi_record_flush_or_stop(gs_service *s, const char *why);
/* Automatic checkpoints (outputs.checkpoint_every) of a client's advance:
 * arm at its start, write between chunks when due, remove at its end. */
void gsi_autosave_arm(gs_service *s);
void gsi_autosave_if_due(gs_service *s);
/* --resume: restore <data dir>/autosave.h5, reopen its record and continue
 * its advance. GS_ENOTFOUND when there is none. */
gs_err gsi_resume(gs_service *s, gs_diag *d);

/* Every non-finite number in o (objects and arrays, recursively) made
 * null: the JSON writer's guard. Returns how many there were. */
int gsi_json_scrub(json_object *o);

/* Answer pending requests (those gsi_validating_allows) from within a long
 * validation; at most every 5 ms. */
void gsi_poll_during(void *user);
bool gsi_validating_allows(const char *cmd);

/* The running sweep's request id ("" none). */
const char *gsi_sweep_parent(gs_service *s);

/* The run's state (coordinates, speeds, time, mesh forces, and with
 * `energies` the energies) all finite? When not, msg says which value,
 * at which step. */
bool gsi_state_finite(gs_service *s, bool energies, char *msg, size_t cap);

#endif
