/* SPDX-License-Identifier: MIT
 * Commands as data: one table of name, handler, whether it may run during an
 * advance, and its allowed arguments (schemas in proto/v1/). The loop in
 * service.c validates the envelope and the argument names and calls the
 * handler; handlers validate values and answer with errors naming the field. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <fcntl.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gearsim/modal.h"
#include "gearsim/stiffness.h"
#include "gearsim/util.h"
#include "scene/jsonv.h"
#include "service/files.h"
#include "service/options.h"
#include "service/service_internal.h"

static const char *const state_names[] = {"empty", "loaded", "running", "paused"};

static gs_err need_loaded(gs_service *s, gs_diag *d)
{
    if (!gs_engine_system(s->eng))
        return gs_diag_set(d, GS_ESTATE, "cmd", "nothing is loaded (use 'load' first)");
    return GS_OK;
}

static gs_err cmd_hello(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id, (void)d;
    json_object *o = json_object_new_object();
    json_object_object_add(o, "protocol", json_object_new_int(1));
    json_object_object_add(o, "version", json_object_new_string("0.1.0"));
    json_object_object_add(o, "build", json_object_new_string(__DATE__ " " __TIME__));
    json_object_object_add(o, "session", json_object_new_string(s->session));
    json_object_object_add(o, "ranks", json_object_new_int(gs_engine_size(s->eng)));
    json_object *caps = json_object_new_array();
    static const char *const cap[] = {"rigid", "elastic", "kinematic", "lumped", "contact", "fields", "record",
                                      "checkpoint", "jobs", "fetch", "modal", "sweep", "telemetry_batch", NULL};
    for (int i = 0; cap[i]; i++)
        json_object_array_add(caps, json_object_new_string(cap[i]));
    json_object_object_add(o, "capabilities", caps);
    json_object *lim = json_object_new_object();
    json_object_object_add(lim, "max_message_bytes", json_object_new_int64(GSI_MAX_MESSAGE));
    json_object_object_add(lim, "max_bodies", json_object_new_int(64));
    json_object_object_add(lim, "max_steps_per_advance", json_object_new_int64(GSI_MAX_STEPS_PER_ADVANCE));
    json_object_object_add(lim, "max_queued_jobs", json_object_new_int(GSI_MAX_JOBS));
    json_object_object_add(lim, "max_fetch_bytes", json_object_new_int(1 << 20));
    json_object_object_add(lim, "max_scene_mb", json_object_new_int64(gsi_opt_max_scene_mb()));
    json_object_object_add(lim, "max_record_mb", json_object_new_int64(gsi_opt_max_record_mb()));
    json_object_object_add(lim, "max_clients", json_object_new_int64(gsi_opt_max_clients()));
    json_object_object_add(lim, "reply_cache_bytes", json_object_new_int64(GSI_CACHE_BYTES));
    json_object_object_add(lim, "reply_cache_entries", json_object_new_int(GSI_CACHE));
    json_object_object_add(lim, "reply_cache_client_bytes", json_object_new_int64(GSI_CACHE_CLIENT_BYTES));
    json_object_object_add(lim, "reply_cache_client_entries", json_object_new_int(GSI_CACHE_CLIENT_ENTRIES));
    json_object_object_add(lim, "reply_cache_lifetime_s", json_object_new_double(GSI_CACHE_LIFETIME_S));
    json_object_object_add(lim, "client_idle_s", json_object_new_double(GSI_CLIENT_IDLE_S));
    json_object_object_add(lim, "max_body_unknowns", json_object_new_int64((int64_t)GS_SCENE_MAX_BODY_UNKNOWNS));
    json_object_object_add(o, "limits", lim);
    json_object *cmds = json_object_new_array();
    for (const gsi_command *c = gsi_commands(); c->name; c++)
        json_object_array_add(cmds, json_object_new_string(c->name));
    json_object_object_add(o, "commands", cmds);
    json_object *b = json_object_new_array();
    for (const char *const *n = gs_scene_builtin_names(); *n; n++)
        json_object_array_add(b, json_object_new_string(*n));
    json_object_object_add(o, "builtin_scenes", b);
    *res = o;
    return GS_OK;
}

/* The rung chosen for `fidelity: {targets}` and why (the scene's
 * fidelity_choice), or JSON null. */
static json_object *fidelity_choice(const gs_system *sys)
{
    return sys && sys->scene->fidelity_choice ? json_tokener_parse(sys->scene->fidelity_choice) : NULL;
}

static json_object *scene_summary(gs_system *sys)
{
    static const char *const jt[] = {"fixed_axis", "on_carrier", "held", "bearing"};
    json_object *o = json_object_new_object();
    json_object_object_add(o, "name", json_object_new_string(sys->scene->name));
    json_object *bs = json_object_new_array();
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_scene_body *b = &sys->scene->bodies[i];
        json_object *j = json_object_new_object();
        json_object_object_add(j, "name", json_object_new_string(b->name));
        json_object_object_add(j, "type", json_object_new_string(b->type == GS_BODY_GEAR ? "gear" : "carrier"));
        json_object_object_add(j, "model", json_object_new_string(sys->bodies[i].ops->name));
        json_object_object_add(j, "joint", json_object_new_string(jt[b->joint]));
        json_object_object_add(j, "mass", json_object_new_double(b->mass));
        json_object_object_add(j, "inertia", json_object_new_double(b->inertia));
        json_object_object_add(j, "rank", json_object_new_int(sys->bodies[i].owner));
        json_object_array_add(bs, j);
    }
    json_object_object_add(o, "bodies", bs);
    json_object *ms = json_object_new_array();
    for (int i = 0; i < sys->n_meshes; i++) {
        const gs_gmesh_rt *m = &sys->meshes[i];
        json_object *j = json_object_new_object();
        json_object_object_add(j, "name", json_object_new_string(sys->scene->meshes[i].name));
        json_object_object_add(j, "model", json_object_new_string(m->ops->name));
        json_object_object_add(j, "contact_ratio", json_object_new_double(m->contact_ratio));
        if (m->ops->n_eq == 0) {
            json_object_object_add(j, "k_single", json_object_new_double(m->k_single));
            json_object_object_add(j, "k_double", json_object_new_double(m->k_double));
            json_object_object_add(j, "damping", json_object_new_double(m->damping));
        }
        json_object_array_add(ms, j);
    }
    json_object_object_add(o, "meshes", ms);
    json_object_object_add(o, "dofs", json_object_new_int(sys->n_coords));
    json_object_object_add(o, "time_step", json_object_new_double(sys->h));
    if (sys->warning[0])
        json_object_object_add(o, "warning", json_object_new_string(sys->warning));
    if (sys->scene->fidelity_choice)
        json_object_object_add(o, "fidelity_choice", fidelity_choice(sys));
    return o;
}

/* The daemon's memory limit (--max-scene-mb), before anything is meshed;
 * the field names the mesh of the largest elastic body. */
static gs_err check_scene_size(const gs_scene *sc, gs_diag *d)
{
    int big;
    double bytes = gs_scene_estimate_bytes(sc, &big);
    double limit = (double)gsi_opt_max_scene_mb() * 1048576.0;
    if (bytes <= limit)
        return GS_OK;
    char f[128] = "bodies";
    if (big >= 0)
        snprintf(f, sizeof f, "bodies[%d].mesh", big);
    return gs_diag_set(d, GS_ETOOBIG, f,
                       "the scene would need about %.0f MiB (estimate; '%s' alone has about %.3g FE "
                       "unknowns); this daemon's limit is %lld MiB (--max-scene-mb)",
                       bytes / 1048576.0, big >= 0 ? sc->bodies[big].name : "?",
                       big >= 0 ? gs_scene_body_unknowns(&sc->bodies[big]) : 0.0,
                       (long long)gsi_opt_max_scene_mb());
}

/* The stiffness analysis meshes both gears of mesh mi at `refine` (-1: the
 * scene's density): the same memory limit as `load`, with the same
 * estimate, before anything is meshed. */
static gs_err check_stiffness_size(const gs_scene *sc, int mi, int refine, gs_diag *d)
{
    double bytes = GS_SCENE_BASE_BYTES, unknowns = 0;
    for (int k = 0; k < 2; k++) {
        gs_scene_body b = sc->bodies[sc->meshes[mi].gear[k]];
        if (refine >= 0)
            b.mesh.refine = refine;
        if (b.type == GS_BODY_GEAR)
            b.model = GS_MODEL_ELASTIC;
        unknowns += gs_scene_body_unknowns(&b);
    }
    bytes += GS_SCENE_BYTES_PER_UNKNOWN * unknowns;
    double limit = (double)gsi_opt_max_scene_mb() * 1048576.0;
    if (bytes <= limit)
        return GS_OK;
    return gs_diag_set(d, GS_ETOOBIG, refine >= 0 ? "args.refine" : "args.mesh",
                       "the stiffness analysis would need about %.0f MiB (estimate: %.3g FE unknowns in both "
                       "gears%s); this daemon's limit is %lld MiB (--max-scene-mb)", bytes / 1048576.0, unknowns,
                       refine >= 0 ? " at this refine" : "", (long long)gsi_opt_max_scene_mb());
}

/* Validate on rank 0 (with a diagnostic naming the field), then broadcast. */
static gs_err load_scene_text(gs_service *s, const char *text, gs_diag *d)
{
    gs_scene *sc;
    GS_TRY(gs_scene_parse(text, strlen(text), &sc, d));
    gs_err se = check_scene_size(sc, d);
    gs_scene_free(&sc);
    if (se != GS_OK)
        return se;
    gs_record_close(&s->record);
    gs_err e = gs_engine_run(s->eng, GS_OP_LOAD, text, strlen(text), d, NULL);
    s->state = gs_engine_system(s->eng) ? SVC_LOADED : SVC_EMPTY;
    return e;
}

/* The scene text of args.scene (an object) or args.builtin (a name): the
 * one given (*has_s tells which), or NULL in *text when neither is (an
 * error when `required`, or when both are). */
static gs_err scene_text_arg(json_object *args, bool required, const char **text, bool *has_s, gs_diag *d)
{
    json_object *scene = NULL, *builtin = NULL;
    *has_s = json_object_object_get_ex(args, "scene", &scene);
    bool has_b = json_object_object_get_ex(args, "builtin", &builtin);
    *text = NULL;
    if ((*has_s && has_b) || (required && !*has_s && !has_b))
        return gs_diag_set(d, GS_ESCHEMA, "args", "give exactly one of 'scene' (an object) or 'builtin' (a name)");
    if (has_b) {
        if (json_object_get_type(builtin) != json_type_string)
            return gs_diag_set(d, GS_ESCHEMA, "args.builtin", "'builtin' must be a string");
        *text = gs_scene_builtin(json_object_get_string(builtin));
        if (!*text)
            return gs_diag_set(d, GS_ENOTFOUND, "args.builtin", "no builtin scene '%.64s'", json_object_get_string(builtin));
    } else if (*has_s) {
        if (json_object_get_type(scene) != json_type_object)
            return gs_diag_set(d, GS_ESCHEMA, "args.scene", "'scene' must be an object");
        *text = json_object_to_json_string_ext(scene, JSON_C_TO_STRING_PLAIN);
    }
    return GS_OK;
}

static gs_err cmd_load(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)id;
    const char *text;
    bool has_s;
    GS_TRY(scene_text_arg(args, true, &text, &has_s, d));
    gs_err e = load_scene_text(s, text, d);
    if (e != GS_OK) {
        if (has_s && d->field[0]) {
            char f[sizeof d->field];
            snprintf(f, sizeof f, "args.scene.%.140s", d->field);
            memcpy(d->field, f, sizeof f);
        }
        return e;
    }
    gs_system *sys = gs_engine_system(s->eng);
    *res = scene_summary(sys);
    if (sys->warning[0]) {
        json_object *w = json_object_new_object();
        json_object_object_add(w, "code", json_object_new_string("projected_initial_speeds"));
        json_object_object_add(w, "message", json_object_new_string(sys->warning));
        json_object_object_add(w, "parent_id", json_object_new_string(id));
        gsi_publish(s, "warning", w);
    }
    return GS_OK;
}

static gs_err cmd_unload(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id, (void)res;
    GS_TRY(need_loaded(s, d));
    gs_record_close(&s->record);
    gs_engine_run(s->eng, GS_OP_UNLOAD, NULL, 0, d, NULL);
    s->state = SVC_EMPTY;
    return GS_OK;
}

static json_object *load_names(gs_system *sys)
{
    json_object *a = json_object_new_array();
    for (int i = 0; i < sys->scene->n_loads; i++)
        json_object_array_add(a, json_object_new_string(sys->scene->loads[i].name));
    return a;
}

static gs_err cmd_set_load(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)id;
    GS_TRY(need_loaded(s, d));
    gs_system *sys = gs_engine_system(s->eng);
    json_object *load = NULL, *rm = NULL;
    bool has_l = json_object_object_get_ex(args, "load", &load);
    bool has_r = json_object_object_get_ex(args, "remove", &rm);
    if (has_l == has_r)
        return gs_diag_set(d, GS_ESCHEMA, "args", "give exactly one of 'load' (an object) or 'remove' (a load name)");
    if (has_r) {
        if (json_object_get_type(rm) != json_type_string)
            return gs_diag_set(d, GS_ESCHEMA, "args.remove", "'remove' must be a load name");
        const char *name = json_object_get_string(rm);
        bool found = false;
        for (int i = 0; i < sys->scene->n_loads; i++)
            found |= strcmp(sys->scene->loads[i].name, name) == 0;
        if (!found)
            return gs_diag_set(d, GS_ENOTFOUND, "args.remove", "no load named '%.64s'", name);
        GS_TRY(gs_engine_run(s->eng, GS_OP_REMOVE_LOAD, name, strlen(name) + 1, d, NULL));
    } else {
        gs_scene_load l;
        GS_TRY(gs_scene_parse_load(sys->scene, load, "args.load", &l, d));
        gs_scene_load_clear(&l);
        const char *txt = json_object_to_json_string_ext(load, JSON_C_TO_STRING_PLAIN);
        GS_TRY(gs_engine_run(s->eng, GS_OP_SET_LOAD, txt, strlen(txt) + 1, d, NULL));
    }
    *res = json_object_new_object();
    json_object_object_add(*res, "loads", load_names(sys));
    return GS_OK;
}

static gs_err cmd_advance(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    GS_TRY(need_loaded(s, d));
    gs_system *sys = gs_engine_system(s->eng);
    bool has_t = json_object_object_get_ex(args, "time", NULL);
    bool has_n = json_object_object_get_ex(args, "steps", NULL);
    if (has_t == has_n)
        return gs_diag_set(d, GS_ESCHEMA, "args", "give exactly one of 'time' (s) or 'steps'");
    int64_t n;
    if (has_t) {
        double t;
        GS_TRY(gsi_json_positive(args, "time", "args", 1e9, true, 0, &t, d));
        double k = ceil(t / sys->h - 1e-9);
        if (k > (double)GSI_MAX_STEPS_PER_ADVANCE)
            return gs_diag_set(d, GS_ETOOBIG, "args.time", "%g s is %.3g steps; at most %lld steps per advance",
                               t, k, (long long)GSI_MAX_STEPS_PER_ADVANCE);
        n = (int64_t)(k < 1 ? 1 : k);
    } else {
        GS_TRY(gsi_json_int(args, "steps", "args", 1, GSI_MAX_STEPS_PER_ADVANCE, true, 0, &n, d));
    }
    s->adv = (svc_advance){.active = true, .start_step = sys->step, .target_step = sys->step + n,
                           .wall_start = gs_now(), .job = -1};
    snprintf(s->adv.parent_id, sizeof s->adv.parent_id, "%s", id);
    gsi_autosave_arm(s);
    s->state = SVC_RUNNING;
    s->timing_step = s->timing_telemetry = s->timing_record = 0;
    *res = json_object_new_object();
    json_object_object_add(*res, "accepted", json_object_new_boolean(1));
    json_object_object_add(*res, "steps", json_object_new_int64(n));
    json_object_object_add(*res, "until_time", json_object_new_double(sys->time + (double)n * sys->h));
    return GS_OK;
}

void gsi_finish_advance(gs_service *s, bool cancelled, gs_err err, const char *msg)
{
    gs_system *sys = gs_engine_system(s->eng);
    json_object *o = json_object_new_object();
    json_object_object_add(o, "parent_id", json_object_new_string(s->adv.parent_id));
    json_object_object_add(o, "cancelled", json_object_new_boolean(cancelled));
    json_object_object_add(o, "steps", json_object_new_int64(sys ? sys->step - s->adv.start_step : 0));
    json_object_object_add(o, "wall_seconds", json_object_new_double(gs_now() - s->adv.wall_start));
    if (err != GS_OK) {
        json_object *e = json_object_new_object();
        json_object_object_add(e, "code", json_object_new_string(gs_errcode(err)));
        json_object_object_add(e, "message", json_object_new_string(msg ? msg : gs_strerror(err)));
        json_object_object_add(o, "error", e);
    }
    gsi_record_flush_or_stop(s, "the record could not be written");
    int job = s->adv.job;
    if (job < 0 && s->adv.next_autosave > 0 && !s->keep_autosave) {
        char p[PATH_MAX + 16];
        snprintf(p, sizeof p, "%s/%s", s->data_dir, GSI_AUTOSAVE_NAME);
        unlink(p);
    }
    s->adv.active = false;
    s->state = sys ? SVC_LOADED : SVC_EMPTY;
    gsi_publish_done(s, job >= 0 ? "job" : "advance", o);
    if (job >= 0) {
        svc_job *j = &s->jobs[job];
        snprintf(j->state, sizeof j->state, "%s", err != GS_OK ? "failed" : cancelled ? "cancelled" : "done");
        j->finished = gs_now();
        if (err != GS_OK)
            snprintf(j->error, sizeof j->error, "%.250s", msg ? msg : gs_strerror(err));
        gs_record_close(&s->record);
        gs_diag d;
        gs_engine_run(s->eng, GS_OP_UNLOAD, NULL, 0, &d, NULL);
        s->state = SVC_EMPTY;
    }
}

static gs_err cmd_pause(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id;
    if (!s->adv.active)
        return gs_diag_set(d, GS_ESTATE, "cmd", "no advance is running");
    s->state = SVC_PAUSED;
    *res = json_object_new_object();
    json_object_object_add(*res, "state", json_object_new_string(state_names[s->state]));
    return GS_OK;
}

static gs_err cmd_resume(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id;
    if (!s->adv.active)
        return gs_diag_set(d, GS_ESTATE, "cmd", "no advance is paused");
    s->state = SVC_RUNNING;
    *res = json_object_new_object();
    json_object_object_add(*res, "state", json_object_new_string(state_names[s->state]));
    return GS_OK;
}

static gs_err cmd_cancel(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id, (void)d;
    bool was = s->adv.active || s->stiff.run || s->sweep;
    if (s->adv.active)
        gsi_finish_advance(s, true, GS_OK, NULL);
    if (s->stiff.run)
        gsi_stiffness_stop(s, true);
    if (s->sweep)
        gsi_sweep_stop(s, true);
    *res = json_object_new_object();
    json_object_object_add(*res, "state", json_object_new_string(state_names[s->state]));
    json_object_object_add(*res, "cancelled", json_object_new_boolean(was));
    return GS_OK;
}

static gs_err cmd_status(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id, (void)d;
    gs_system *sys = gs_engine_system(s->eng);
    json_object *o = json_object_new_object();
    json_object_object_add(o, "state", json_object_new_string(state_names[s->state]));
    json_object_object_add(o, "time", json_object_new_double(sys ? sys->time : 0.0));
    json_object_object_add(o, "step", json_object_new_int64(sys ? sys->step : 0));
    json_object_object_add(o, "scene", sys ? json_object_new_string(sys->scene->name) : NULL);
    json_object_object_add(o, "ranks", json_object_new_int(gs_engine_size(s->eng)));
    if (sys && sys->scene->fidelity_choice)
        json_object_object_add(o, "fidelity_choice", fidelity_choice(sys));
    if (s->adv.active && sys) {
        json_object *a = json_object_new_object();
        double total = (double)(s->adv.target_step - s->adv.start_step);
        json_object_object_add(a, "parent_id", json_object_new_string(s->adv.parent_id));
        json_object_object_add(a, "target_step", json_object_new_int64(s->adv.target_step));
        json_object_object_add(a, "fraction", json_object_new_double(total > 0 ? (double)(sys->step - s->adv.start_step) / total : 1.0));
        json_object_object_add(o, "advance", a);
    } else {
        json_object_object_add(o, "advance", NULL);
    }
    if (s->stiff.run) {
        json_object *a = json_object_new_object();
        int n = gs_stiffness_run_positions(s->stiff.run), k = gs_stiffness_run_done(s->stiff.run);
        json_object_object_add(a, "parent_id", json_object_new_string(s->stiff.parent_id));
        json_object_object_add(a, "positions", json_object_new_int(n));
        json_object_object_add(a, "done", json_object_new_int(k));
        json_object_object_add(a, "fraction", json_object_new_double(n > 0 ? (double)k / n : 1.0));
        json_object_object_add(o, "stiffness", a);
    } else {
        json_object_object_add(o, "stiffness", NULL);
    }
    json_object_object_add(o, "sweep", gsi_sweep_status(s));
    /* The last finished long requests, oldest first: completion without PUB. */
    json_object *fin = json_object_new_array();
    for (int i = 0; i < s->n_finished; i++)
        json_object_array_add(fin, json_object_get(s->finished[i].done));
    json_object_object_add(o, "finished", fin);
    json_object_object_add(o, "recording", s->record ? json_object_new_string(gsi_data_relative(s, gs_record_path(s->record))) : NULL);
    int queued = 0;
    for (int i = 0; i < s->n_jobs; i++)
        queued += strcmp(s->jobs[i].state, "queued") == 0;
    json_object_object_add(o, "jobs_queued", json_object_new_int(queued));
    json_object *t = json_object_new_object();
    json_object_object_add(t, "steps_per_second", json_object_new_double(s->steps_per_second));
    json_object_object_add(t, "chunk_steps", json_object_new_int64(s->chunk_steps));
    json_object_object_add(t, "step_seconds", json_object_new_double(s->timing_step));
    json_object_object_add(t, "telemetry_seconds", json_object_new_double(s->timing_telemetry));
    json_object_object_add(t, "record_seconds", json_object_new_double(s->timing_record));
    gs_system *tsys = gs_engine_system(s->eng);
    if (tsys) {
        json_object *ad = json_object_new_object();
        json_object_object_add(ad, "substeps", json_object_new_int64(tsys->substeps));
        json_object_object_add(ad, "refinements", json_object_new_int64(tsys->refinements));
        json_object_object_add(ad, "level", json_object_new_int(tsys->level));
        json_object_object_add(t, "adaptive", ad);
        /* The step's breakdown on rank 0, and each body's work on its owner. */
        gs_step_timing st;
        gs_engine_timing(s->eng, &st);
        json_object *b = json_object_new_object();
        json_object_object_add(b, "steps", json_object_new_int64(st.steps));
        const char *names[] = {"prepare", "records", "reduce", "solve", "bcast", "apply", "sync"};
        double v[] = {st.prepare, st.records, st.reduce, st.solve, st.bcast, st.apply, st.sync};
        for (int i = 0; i < 7; i++)
            json_object_object_add(b, names[i], json_object_new_double(v[i]));
        json_object_object_add(t, "breakdown", b);
        json_object *bw = json_object_new_array();
        for (int i = 0; i < tsys->n_bodies; i++) {
            json_object *w = json_object_new_object();
            json_object_object_add(w, "name", json_object_new_string(tsys->scene->bodies[i].name));
            json_object_object_add(w, "rank", json_object_new_int(tsys->bodies[i].owner));
            json_object_object_add(w, "work_seconds", json_object_new_double(tsys->bodies[i].work_s));
            json_object_array_add(bw, w);
        }
        json_object_object_add(t, "bodies", bw);
    }
    json_object_object_add(o, "timing", t);
    *res = o;
    return GS_OK;
}

static gs_err cmd_state(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id;
    GS_TRY(need_loaded(s, d));
    gs_system *sys = gs_engine_system(s->eng);
    json_object *o = gsi_state_json(s);
    json_object_object_add(o, "seq", json_object_new_int64((int64_t)s->seq));
    json_object_object_add(o, "step", json_object_new_int64(sys->step));
    json_object_object_add(o, "time", json_object_new_double(sys->time));
    if (sys->scene->fidelity_choice)
        json_object_object_add(o, "fidelity_choice", fidelity_choice(sys));
    *res = o;
    return GS_OK;
}

/* The path relative to the data directory of a resolved path. */
static const char *rel_of(gs_service *s, const char *full)
{
    size_t dl = strlen(s->data_dir);
    return strncmp(full, s->data_dir, dl) == 0 && full[dl] == '/' ? full + dl + 1 : full;
}

/* Every output is written by rename (as checkpoints and sweeps are): the
 * target's name checked (no symlink, none of the daemon's own files), a new
 * file created beside it under an unguessable name through the checked
 * directory's descriptor, written, then renamed over the name. A file
 * someone else made at that name is replaced, never written into (its
 * owner, mode and other names keep the old content). */
typedef struct out_file {
    gsi_beneath b;
    char tmp[PATH_MAX], target[PATH_MAX], via_fd[64];
    int fd;
} out_file;

static gs_err out_begin(gs_service *s, const char *rel, const char *field, out_file *o, gs_diag *d)
{
    o->fd = -1;
    GS_TRY(gsi_check_write(s, rel, field, false, &o->b, d));
    /* A name with other names stays refused: the client meant one file. */
    struct stat st;
    if (fstatat(o->b.dirfd, o->b.leaf, &st, AT_SYMLINK_NOFOLLOW) == 0 && st.st_nlink > 1) {
        gsi_beneath_close(&o->b);
        return gs_diag_set(d, GS_ERANGE, field, "'%s' has %lu hard links; writing it is refused", rel,
                           (unsigned long)st.st_nlink);
    }
    snprintf(o->target, sizeof o->target, "/proc/self/fd/%d/%s", o->b.dirfd, o->b.leaf);
    o->fd = gs_tmp_create_beside(o->target, o->tmp, sizeof o->tmp);
    if (o->fd < 0 || fchmod(o->fd, 0644) != 0) {
        if (o->fd >= 0) {
            close(o->fd);
            unlink(o->tmp);
        }
        gsi_beneath_close(&o->b);
        return gs_diag_set(d, GS_EIO, field, "cannot create a file beside '%s'", rel);
    }
    gsi_fd_path(o->fd, o->via_fd, sizeof o->via_fd);
    return GS_OK;
}

/* ok: rename the new file over the target; else remove it. */
static gs_err out_end(out_file *o, bool ok, const char *rel, const char *field, gs_diag *d)
{
    gs_err e = GS_OK;
    close(o->fd);
    if (ok && rename(o->tmp, o->target) != 0)
        e = gs_diag_set(d, GS_EIO, field, "cannot rename the new file onto '%s'", rel);
    if (!ok || e != GS_OK)
        unlink(o->tmp);
    gsi_beneath_close(&o->b);
    return e;
}

/* Open a record for writing at `full` (gsi_resolve_path'd), by rename: HDF5
 * creates the new file through its descriptor and keeps it open; the name
 * is renamed onto it at once (the open file follows). */
static gs_err open_record_safely(gs_service *s, const char *full, gs_record **r, const char *field, gs_diag *d)
{
    const char *rel = rel_of(s, full);
    out_file o;
    GS_TRY(out_begin(s, rel, field, &o, d));
    gs_err e = gsi_record_open_as(s, full, o.via_fd, r, d);
    gs_err re = out_end(&o, e == GS_OK, rel, field, d);
    if (e == GS_OK && re != GS_OK) {
        gs_record_close(r);
        e = re;
    }
    if (e != GS_OK)
        snprintf(d->field, sizeof d->field, "%s", field);
    return e;
}

static gs_err cmd_record(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)id;
    bool stop = false;
    GS_TRY(gsi_json_bool(args, "stop", "args", false, &stop, d));
    bool has_p = json_object_object_get_ex(args, "path", NULL);
    if (stop == has_p)
        return gs_diag_set(d, GS_ESCHEMA, "args", "give 'path' to start recording or 'stop': true to stop");
    if (stop) {
        gs_err e = gs_record_close(&s->record);
        if (e != GS_OK)
            return gs_diag_set(d, e, "path", "the record could not be completed");
    } else {
        GS_TRY(need_loaded(s, d));
        char rel[600], full[PATH_MAX];
        GS_TRY(gsi_json_string(args, "path", "args", true, NULL, rel, sizeof rel, d));
        gs_err e = gsi_resolve_path(s, rel, full, sizeof full, true, d);
        if (e != GS_OK) {
            snprintf(d->field, sizeof d->field, "args.path");
            return e;
        }
        gs_record *r;
        e = open_record_safely(s, full, &r, "args.path", d);
        if (e != GS_OK)
            return e;
        gs_record_close(&s->record);
        s->record = r;
        gs_record_sample(r, gs_engine_system(s->eng));
        gsi_record_flush_or_stop(s, "the record could not be written");
    }
    *res = json_object_new_object();
    json_object_object_add(*res, "recording", s->record ? json_object_new_string(gsi_data_relative(s, gs_record_path(s->record))) : NULL);
    return GS_OK;
}

/* The stiffness table file: the same checks as a record, by rename. */
static gs_err write_stiffness_safely(gs_service *s, const char *full, const gs_scene *sc,
                                     const gs_stiffness_result *r, gs_diag *d)
{
    const char *rel = rel_of(s, full);
    out_file o;
    GS_TRY(out_begin(s, rel, "args.path", &o, d));
    gs_err e = gs_stiffness_write_h5(o.via_fd, sc, r, d);
    if (e != GS_OK)
        gs_diag_set(d, e, "args.path", "cannot write the stiffness table '%s'", rel);
    gs_err re = out_end(&o, e == GS_OK, rel, "args.path", d);
    return e != GS_OK ? e : re;
}

static gs_err path_arg(gs_service *s, json_object *args, bool for_write, char *full, size_t cap, gs_diag *d)
{
    char rel[600];
    GS_TRY(gsi_json_string(args, "path", "args", true, NULL, rel, sizeof rel, d));
    gs_err e = gsi_resolve_path(s, rel, full, cap, for_write, d);
    if (e != GS_OK)
        snprintf(d->field, sizeof d->field, "args.path");
    return e;
}

static gs_err cmd_checkpoint(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)id;
    GS_TRY(need_loaded(s, d));
    char full[PATH_MAX];
    GS_TRY(path_arg(s, args, true, full, sizeof full, d));
    if (s->adv.active && s->state != SVC_PAUSED)
        return gs_diag_set(d, GS_ESTATE, "cmd", "pause the advance before a checkpoint");
    /* Written beside the target through the directory's descriptor, then
     * renamed over it: never through a symlink, never onto the daemon's
     * own files. */
    gsi_beneath b;
    const char *rel = rel_of(s, full);
    GS_TRY(gsi_check_write(s, rel, "args.path", false, &b, d));
    char target[PATH_MAX];
    snprintf(target, sizeof target, "/proc/self/fd/%d/%s", b.dirfd, b.leaf);
    char *bytes;
    size_t len;
    gs_err e = gs_engine_snapshot(s->eng, &bytes, &len);
    gs_system *sys = gs_engine_system(s->eng);
    if (e == GS_OK) {
        e = gs_checkpoint_write(target, bytes, len, sys->scene->json, sys->step, sys->time, d);
        free(bytes);
        if (e != GS_OK)
            gs_diag_set(d, e, "args.path", "cannot write the checkpoint '%s'", rel);
    }
    gsi_beneath_close(&b);
    if (e != GS_OK)
        return e;
    *res = json_object_new_object();
    json_object_object_add(*res, "path", json_object_object_get(args, "path") ? json_object_get(json_object_object_get(args, "path")) : NULL);
    json_object_object_add(*res, "step", json_object_new_int64(sys->step));
    json_object_object_add(*res, "time", json_object_new_double(sys->time));
    return GS_OK;
}

/* A checkpoint file is input like a request: the snapshot at most the
 * daemon's scene limit in bytes (checked before it is allocated), its
 * content checked (gs_engine_snapshot_check) and its scene through the same
 * size limit as `load`, all on rank 0 before anything is broadcast. */
static gs_err read_checkpoint(const char *via_fd, char **bytes, size_t *len, gs_diag *d)
{
    size_t max = (size_t)gsi_opt_max_scene_mb() * 1048576u;
    GS_TRY(gs_checkpoint_read(via_fd, max, bytes, len, d));
    gs_snapshot_view v;
    gs_scene *sc = NULL;
    gs_err e = gs_engine_snapshot_check(*bytes, *len, &v, d);
    if (e == GS_OK && (e = gs_scene_parse(v.scene, strlen(v.scene), &sc, d)) != GS_OK) {
        char m[sizeof d->message], f[sizeof d->field];
        snprintf(m, sizeof m, "%s", d->message);
        snprintf(f, sizeof f, "%s", d->field);
        /* The file is damaged (not the request): never bad_json. */
        e = gs_diag_set(d, e == GS_EPARSE ? GS_EIO : e, "path", "the checkpoint's scene is refused (%.60s): %.240s",
                        f, m);
    }
    if (e == GS_OK)
        e = check_scene_size(sc, d);
    gs_scene_free(&sc);
    if (e != GS_OK) {
        free(*bytes);
        *bytes = NULL;
        *len = 0;
    }
    return e;
}

static gs_err cmd_restore(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)id;
    char full[PATH_MAX];
    GS_TRY(path_arg(s, args, false, full, sizeof full, d));
    gsi_beneath b;
    struct stat st;
    GS_TRY(gsi_open_read(s, rel_of(s, full), "args.path", &b, &st, d));
    char via_fd[64];
    gsi_fd_path(b.fd, via_fd, sizeof via_fd);
    char *bytes;
    size_t len;
    gs_err e = read_checkpoint(via_fd, &bytes, &len, d);
    gsi_beneath_close(&b);
    if (e != GS_OK) {
        char m[sizeof d->message];
        snprintf(m, sizeof m, "%s", d->message);
        gs_diag_set(d, e, "args.path", "'%s' is not a readable gearsim checkpoint: %.300s", rel_of(s, full), m);
        return e;
    }
    gs_record_close(&s->record);
    e = gs_engine_run(s->eng, GS_OP_RESTORE, bytes, len, d, NULL);
    free(bytes);
    s->state = gs_engine_system(s->eng) ? SVC_LOADED : SVC_EMPTY;
    if (e != GS_OK) {
        snprintf(d->field, sizeof d->field, "args.path");
        return e;
    }
    gs_system *sys = gs_engine_system(s->eng);
    *res = json_object_new_object();
    json_object_object_add(*res, "step", json_object_new_int64(sys->step));
    json_object_object_add(*res, "time", json_object_new_double(sys->time));
    return GS_OK;
}

/* ---- automatic checkpoints and --resume ---------------------------------- */

void gsi_autosave_arm(gs_service *s)
{
    gs_system *sys = gs_engine_system(s->eng);
    int every = sys ? sys->scene->checkpoint_every : 0;
    s->adv.next_autosave = every > 0 && s->adv.job < 0 ? (sys->step / every + 1) * every : 0;
}

static void publish_error(gs_service *s, const char *code, const char *msg)
{
    json_object *w = json_object_new_object();
    json_object_object_add(w, "code", json_object_new_string(code));
    json_object_object_add(w, "message", json_object_new_string(msg));
    if (s->adv.active)
        json_object_object_add(w, "parent_id", json_object_new_string(s->adv.parent_id));
    gsi_publish(s, "error", w);
}

/* Between chunks only: gs_engine_snapshot broadcasts an operation when
 * elastic bodies live on other ranks. */
void gsi_autosave_if_due(gs_service *s)
{
    gs_system *sys = gs_engine_system(s->eng);
    if (!sys || !s->adv.active || s->adv.next_autosave <= 0 || sys->step < s->adv.next_autosave)
        return;
    int every = sys->scene->checkpoint_every;
    s->adv.next_autosave = (sys->step / every + 1) * every;
    double t0 = gs_now();
    gs_autosave_info a;
    memset(&a, 0, sizeof a);
    snprintf(a.parent_id, sizeof a.parent_id, "%s", s->adv.parent_id);
    a.start_step = s->adv.start_step;
    a.target_step = s->adv.target_step;
    /* Everything recorded before the checkpoint goes to disk first. */
    gsi_record_flush_or_stop(s, "the record could not be written");
    if (s->record) {
        snprintf(a.record, sizeof a.record, "%s", gsi_data_relative(s, gs_record_path(s->record)));
        a.record_rows = gs_record_rows(s->record);
        a.n_field_bodies = gs_record_n_meshes(s->record);
        if (a.n_field_bodies > GS_AUTOSAVE_MAX_BODIES)
            a.n_field_bodies = GS_AUTOSAVE_MAX_BODIES;
        for (int b = 0; b < a.n_field_bodies; b++)
            a.field_frames[b] = gs_record_field_frames(s->record, b);
    }
    char *bytes = NULL;
    size_t len = 0;
    gs_diag d;
    gs_diag_clear(&d);
    char path[PATH_MAX + 16];
    snprintf(path, sizeof path, "%s/%s", s->data_dir, GSI_AUTOSAVE_NAME);
    gs_err e = gs_engine_snapshot(s->eng, &bytes, &len);
    if (e == GS_OK)
        e = gs_autosave_write(path, bytes, len, sys->scene->json, sys->step, sys->time, &a, &d);
    free(bytes);
    if (e != GS_OK) {
        char msg[400];
        snprintf(msg, sizeof msg, "automatic checkpoint at step %lld failed: %.300s", (long long)sys->step,
                 d.message[0] ? d.message : gs_strerror(e));
        publish_error(s, gs_errcode(e), msg);
    }
    s->timing_record += gs_now() - t0;
}

gs_err gsi_resume(gs_service *s, gs_diag *d)
{
    char path[PATH_MAX + 16];
    snprintf(path, sizeof path, "%s/%s", s->data_dir, GSI_AUTOSAVE_NAME);
    if (access(path, F_OK) != 0)
        return gs_diag_set(d, GS_ENOTFOUND, "path", "no %s in the data directory", GSI_AUTOSAVE_NAME);
    gs_autosave_info a;
    gsi_beneath b;
    struct stat st;
    GS_TRY(gsi_open_read(s, GSI_AUTOSAVE_NAME, "path", &b, &st, d));
    char via_fd[64];
    gsi_fd_path(b.fd, via_fd, sizeof via_fd);
    char *bytes = NULL;
    size_t len;
    gs_err ie = gs_autosave_read_info(via_fd, &a, d);
    if (ie == GS_OK && a.target_step - a.start_step > GSI_MAX_STEPS_PER_ADVANCE)
        ie = gs_diag_set(d, GS_ERANGE, "path", "%s holds an advance of %lld steps; at most %lld steps per advance",
                         GSI_AUTOSAVE_NAME, (long long)(a.target_step - a.start_step),
                         (long long)GSI_MAX_STEPS_PER_ADVANCE);
    if (ie == GS_OK)
        ie = read_checkpoint(via_fd, &bytes, &len, d);
    gsi_beneath_close(&b);
    if (ie == GS_ENOTFOUND) /* the file is there: "not found" would read as nothing to resume */
        ie = GS_EIO;
    if (ie != GS_OK)
        return ie;
    gs_record_close(&s->record);
    gs_err e = gs_engine_run(s->eng, GS_OP_RESTORE, bytes, len, d, NULL);
    free(bytes);
    gs_system *sys = gs_engine_system(s->eng);
    s->state = sys ? SVC_LOADED : SVC_EMPTY;
    if (e != GS_OK)
        return e == GS_ENOTFOUND ? GS_EIO : e;
    if (a.target_step <= sys->step || a.start_step > sys->step)
        return gs_diag_set(d, GS_EIO, "path", "%s holds no unfinished advance (step %lld, target %lld)",
                           GSI_AUTOSAVE_NAME, (long long)sys->step, (long long)a.target_step);
    if (a.record[0]) {
        char rec[PATH_MAX];
        gs_diag rd;
        gs_diag_clear(&rd);
        gs_err re = gsi_resolve_path(s, a.record, rec, sizeof rec, false, &rd);
        gsi_beneath rb = {.dirfd = -1, .fd = -1};
        char via_fd[64];
        if (re == GS_OK && (re = gsi_check_write(s, a.record, "path", true, &rb, &rd)) == GS_OK) {
            gsi_fd_path(rb.fd, via_fd, sizeof via_fd);
            re = gs_record_reopen_as(rec, via_fd, sys, a.record_rows, a.field_frames, a.n_field_bodies,
                                     &s->record, &rd);
        }
        gsi_beneath_close(&rb);
        if (re != GS_OK)
            fprintf(stderr, "gearsimd: --resume: the advance goes on without its record: %s\n",
                    rd.message[0] ? rd.message : gs_strerror(re));
    }
    s->adv = (svc_advance){.active = true, .start_step = a.start_step, .target_step = a.target_step,
                           .wall_start = gs_now(), .job = -1};
    snprintf(s->adv.parent_id, sizeof s->adv.parent_id, "%s", a.parent_id);
    gsi_autosave_arm(s);
    s->state = SVC_RUNNING;
    fprintf(stderr, "gearsimd: --resume: continuing advance '%s' from step %lld to %lld%s%s\n", a.parent_id,
            (long long)sys->step, (long long)a.target_step, s->record ? ", recording to " : "",
            s->record ? a.record : "");
    return GS_OK;
}

static int cmp_at(const void *a, const void *b)
{
    json_object *x = *(json_object *const *)a, *y = *(json_object *const *)b;
    double u = json_object_get_double(json_object_object_get(x, "at"));
    double v = json_object_get_double(json_object_object_get(y, "at"));
    return u < v ? -1 : u > v;
}

static bool job_finished(const svc_job *j) { return j->finished > 0; }

static void job_remove(gs_service *s, int i)
{
    free(s->jobs[i].scene_json);
    json_object_put(s->jobs[i].schedule);
    memmove(&s->jobs[i], &s->jobs[i + 1], (size_t)(s->n_jobs - i - 1) * sizeof s->jobs[0]);
    s->n_jobs--;
    if (s->adv.job > i)
        s->adv.job--;
}

/* Drop finished jobs older than GSI_JOBS_KEEP_S and all but the newest
 * GSI_JOBS_KEEP_FINISHED (the list is in submit order). */
static void jobs_prune(gs_service *s)
{
    double now = gs_now();
    int finished = 0;
    for (int i = s->n_jobs - 1; i >= 0; i--) {
        if (!job_finished(&s->jobs[i]))
            continue;
        if (now - s->jobs[i].finished > GSI_JOBS_KEEP_S || finished >= GSI_JOBS_KEEP_FINISHED)
            job_remove(s, i);
        else
            finished++;
    }
}

/* Why the queued job i has not started (NULL when it is next and nothing
 * holds it back). The rule: queued jobs start one at a time, in submit
 * order, when no scene is loaded. */
static const char *job_waiting(gs_service *s, int i, char *buf, size_t cap)
{
    int ahead = 0;
    for (int k = 0; k < i; k++)
        ahead += strcmp(s->jobs[k].state, "queued") == 0;
    if (s->adv.active && s->adv.job >= 0)
        snprintf(buf, cap, "behind the running job %s%s", s->jobs[s->adv.job].id,
                 ahead ? " and earlier queued jobs" : "");
    else if (gs_engine_system(s->eng))
        snprintf(buf, cap, "a client's scene is loaded: queued jobs start when it is unloaded ('unload')");
    else if (ahead)
        snprintf(buf, cap, "behind %d earlier queued job(s)", ahead);
    else
        return NULL;
    return buf;
}

static gs_err cmd_submit(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)id;
    jobs_prune(s);
    int queued = 0, unfinished = 0;
    for (int i = 0; i < s->n_jobs; i++) {
        queued += strcmp(s->jobs[i].state, "queued") == 0;
        unfinished += !job_finished(&s->jobs[i]);
    }
    if (unfinished >= GSI_MAX_JOBS)
        return gs_diag_set(d, GS_ETOOBIG, "cmd", "the job queue is full (%d jobs queued or running)", GSI_MAX_JOBS);
    if (s->n_jobs >= GSI_MAX_JOBS + GSI_JOBS_KEEP_FINISHED) /* only finished ones beyond: drop the oldest */
        for (int i = 0; i < s->n_jobs; i++)
            if (job_finished(&s->jobs[i])) {
                job_remove(s, i);
                break;
            }
    json_object *scene, *sched;
    GS_TRY(gsi_json_object(args, "scene", "args", true, &scene, d));
    gs_scene *sc;
    const char *text = json_object_to_json_string_ext(scene, JSON_C_TO_STRING_PLAIN);
    gs_err e = gs_scene_parse(text, strlen(text), &sc, d);
    if (e == GS_OK && (e = check_scene_size(sc, d)) != GS_OK)
        gs_scene_free(&sc);
    if (e != GS_OK) {
        char f[sizeof d->field];
        snprintf(f, sizeof f, "args.scene%s%.140s", d->field[0] ? "." : "", d->field);
        memcpy(d->field, f, sizeof f);
        return e;
    }
    double duration;
    e = gsi_json_positive(args, "duration", "args", 1e6, true, 0, &duration, d);
    if (e == GS_OK && ceil(duration / sc->time_step) > (double)GSI_MAX_STEPS_PER_ADVANCE)
        e = gs_diag_set(d, GS_ETOOBIG, "args.duration", "the job would exceed %lld steps", (long long)GSI_MAX_STEPS_PER_ADVANCE);
    char full[PATH_MAX] = "";
    if (e == GS_OK && json_object_object_get_ex(args, "record", NULL)) {
        char rel[600];
        e = gsi_json_string(args, "record", "args", true, NULL, rel, sizeof rel, d);
        if (e == GS_OK && (e = gsi_resolve_path(s, rel, full, sizeof full, true, d)) != GS_OK)
            snprintf(d->field, sizeof d->field, "args.record");
        gsi_beneath b;
        if (e == GS_OK && (e = gsi_check_write(s, rel, "args.record", false, &b, d)) == GS_OK)
            gsi_beneath_close(&b);
    }
    json_object *copy = NULL;
    if (e == GS_OK)
        e = gsi_json_array(args, "schedule", "args", false, &sched, d);
    if (e == GS_OK && sched) {
        size_t n = json_object_array_length(sched);
        copy = json_object_new_array();
        for (size_t i = 0; i < n && e == GS_OK; i++) {
            json_object *it = json_object_array_get_idx(sched, i), *ld;
            char p[64];
            snprintf(p, sizeof p, "args.schedule[%zu]", i);
            static const char *const keys[] = {"at", "load", NULL};
            double at;
            if (json_object_get_type(it) != json_type_object) {
                e = gs_diag_set(d, GS_ESCHEMA, p, "a schedule entry is {at, load}");
                break;
            }
            if ((e = gsi_json_only(it, p, keys, d)) != GS_OK ||
                (e = gsi_json_number(it, "at", p, 0, duration, true, 0, &at, d)) != GS_OK ||
                (e = gsi_json_object(it, "load", p, true, &ld, d)) != GS_OK)
                break;
            char lp[80];
            snprintf(lp, sizeof lp, "%s.load", p);
            gs_scene_load l;
            if ((e = gs_scene_parse_load(sc, ld, lp, &l, d)) != GS_OK)
                break;
            gs_scene_load_clear(&l);
            json_object *c = json_object_new_object();
            json_object_object_add(c, "at", json_object_new_double(at));
            json_object_object_add(c, "load", json_object_get(ld));
            json_object_array_add(copy, c);
        }
        if (e == GS_OK)
            json_object_array_sort(copy, cmp_at);
    }
    gs_scene_free(&sc);
    if (e != GS_OK) {
        json_object_put(copy);
        return e;
    }
    svc_job *j = &s->jobs[s->n_jobs++];
    memset(j, 0, sizeof *j);
    snprintf(j->id, sizeof j->id, "job-%d", ++s->job_counter);
    j->scene_json = gs_strdup(text);
    j->schedule = copy;
    j->duration = duration;
    snprintf(j->record, sizeof j->record, "%s", full);
    snprintf(j->state, sizeof j->state, "queued");
    *res = json_object_new_object();
    json_object_object_add(*res, "job", json_object_new_string(j->id));
    json_object_object_add(*res, "position", json_object_new_int(queued));
    char why[200];
    const char *w = job_waiting(s, s->n_jobs - 1, why, sizeof why);
    json_object_object_add(*res, "waiting", w ? json_object_new_string(w) : NULL);
    return GS_OK;
}

void gsi_start_next_job(gs_service *s)
{
    if (s->state != SVC_EMPTY)
        return;
    for (int i = 0; i < s->n_jobs; i++) {
        svc_job *j = &s->jobs[i];
        if (strcmp(j->state, "queued") != 0)
            continue;
        gs_diag d;
        gs_diag_clear(&d);
        snprintf(j->state, sizeof j->state, "running");
        gs_err e = load_scene_text(s, j->scene_json, &d);
        if (e == GS_OK && j->record[0])
            e = open_record_safely(s, j->record, &s->record, "args.record", &d);
        if (e != GS_OK) {
            snprintf(j->state, sizeof j->state, "failed");
            j->finished = gs_now();
            snprintf(j->error, sizeof j->error, "%.250s", d.message[0] ? d.message : gs_strerror(e));
            gs_engine_run(s->eng, GS_OP_UNLOAD, NULL, 0, &d, NULL);
            s->state = SVC_EMPTY;
            continue;
        }
        gs_system *sys = gs_engine_system(s->eng);
        if (s->record)
            gs_record_sample(s->record, sys);
        int64_t n = (int64_t)ceil(j->duration / sys->h - 1e-9);
        s->adv = (svc_advance){.active = true, .start_step = sys->step, .target_step = sys->step + (n < 1 ? 1 : n),
                               .wall_start = gs_now(), .job = i, .next_schedule = 0};
        snprintf(s->adv.parent_id, sizeof s->adv.parent_id, "%s", j->id);
        s->state = SVC_RUNNING;
        return;
    }
}

/* Apply the job's load changes whose time has come. */
void gsi_job_between_chunks(gs_service *s)
{
    svc_job *j = &s->jobs[s->adv.job];
    gs_system *sys = gs_engine_system(s->eng);
    if (!j->schedule)
        return;
    int n = (int)json_object_array_length(j->schedule);
    while (s->adv.next_schedule < n) {
        json_object *it = json_object_array_get_idx(j->schedule, (size_t)s->adv.next_schedule);
        double at = json_object_get_double(json_object_object_get(it, "at"));
        if (at > sys->time + 0.5 * sys->h)
            break;
        const char *txt = json_object_to_json_string_ext(json_object_object_get(it, "load"), JSON_C_TO_STRING_PLAIN);
        gs_diag d;
        gs_engine_run(s->eng, GS_OP_SET_LOAD, txt, strlen(txt) + 1, &d, NULL);
        s->adv.next_schedule++;
    }
}

static gs_err cmd_jobs(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id, (void)d;
    jobs_prune(s);
    json_object *a = json_object_new_array();
    for (int i = 0; i < s->n_jobs; i++) {
        svc_job *j = &s->jobs[i];
        json_object *o = json_object_new_object();
        json_object_object_add(o, "job", json_object_new_string(j->id));
        json_object_object_add(o, "state", json_object_new_string(j->state));
        char why[200];
        const char *w = strcmp(j->state, "queued") == 0 ? job_waiting(s, i, why, sizeof why) : NULL;
        json_object_object_add(o, "waiting", w ? json_object_new_string(w) : NULL);
        const char *rel = j->record[0] ? j->record + strlen(s->data_dir) + 1 : NULL;
        json_object_object_add(o, "record", rel ? json_object_new_string(rel) : NULL);
        json_object_object_add(o, "error", j->error[0] ? json_object_new_string(j->error) : NULL);
        json_object_array_add(a, o);
    }
    *res = json_object_new_object();
    json_object_object_add(*res, "jobs", a);
    return GS_OK;
}

static char *base64(const unsigned char *in, size_t n)
{
    static const char tbl[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    char *out = malloc(4 * ((n + 2) / 3) + 1), *p = out;
    if (!out)
        return NULL;
    for (size_t i = 0; i < n; i += 3) {
        unsigned v = (unsigned)in[i] << 16 | (i + 1 < n ? (unsigned)in[i + 1] << 8 : 0) | (i + 2 < n ? in[i + 2] : 0);
        *p++ = tbl[v >> 18 & 63];
        *p++ = tbl[v >> 12 & 63];
        *p++ = i + 1 < n ? tbl[v >> 6 & 63] : '=';
        *p++ = i + 2 < n ? tbl[v & 63] : '=';
    }
    *p = '\0';
    return out;
}

static gs_err cmd_fetch(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)id;
    char full[PATH_MAX];
    GS_TRY(path_arg(s, args, false, full, sizeof full, d));
    int64_t off, len;
    GS_TRY(gsi_json_int(args, "offset", "args", 0, INT64_MAX / 2, false, 0, &off, d));
    GS_TRY(gsi_json_int(args, "length", "args", 1, 1 << 20, false, 1 << 20, &len, d));
    bool remove = false;
    GS_TRY(gsi_json_bool(args, "remove", "args", false, &remove, d));
    bool recording = s->record && strcmp(full, gs_record_path(s->record)) == 0;
    if (recording && remove)
        return gs_diag_set(d, GS_ERANGE, "args.remove", "'%s' is being recorded; stop the record first",
                           rel_of(s, full));
    if (recording)
        gsi_record_flush_or_stop(s, "the record could not be written");
    /* Never through a symlink, never a FIFO or device (which could block
     * the daemon), never a file with a second name (a hard link). */
    gsi_beneath b;
    struct stat st;
    GS_TRY(gsi_open_read(s, rel_of(s, full), "args.path", &b, &st, d));
    FILE *f = fdopen(b.fd, "rb");
    if (!f) {
        gsi_beneath_close(&b);
        return gs_diag_set(d, GS_EIO, "args.path", "cannot read that file");
    }
    b.fd = -1; /* owned by f now */
    unsigned char *buf = malloc((size_t)len);
    size_t got = 0;
    if (buf && fseeko(f, (off_t)off, SEEK_SET) == 0)
        got = fread(buf, 1, (size_t)len, f);
    fclose(f);
    bool eof = off + (int64_t)got >= (int64_t)st.st_size;
    /* remove: the file goes once a chunk reaches its end, if the name still
     * holds the file just read (a retried request is answered from the
     * reply cache, so the deletion happens once). */
    bool removed = false;
    if (remove && eof && buf) {
        struct stat now;
        if (fstatat(b.dirfd, b.leaf, &now, AT_SYMLINK_NOFOLLOW) == 0 && now.st_ino == st.st_ino &&
            now.st_dev == st.st_dev)
            removed = unlinkat(b.dirfd, b.leaf, 0) == 0;
    }
    gsi_beneath_close(&b);
    char *b64 = buf ? base64(buf, got) : NULL;
    free(buf);
    if (!b64)
        return GS_ENOMEM;
    json_object *o = json_object_new_object();
    json_object_object_add(o, "path", json_object_get(json_object_object_get(args, "path")));
    json_object_object_add(o, "offset", json_object_new_int64(off));
    json_object_object_add(o, "length", json_object_new_int64((int64_t)got));
    json_object_object_add(o, "size", json_object_new_int64((int64_t)st.st_size));
    json_object_object_add(o, "eof", json_object_new_boolean(eof));
    if (remove)
        json_object_object_add(o, "removed", json_object_new_boolean(removed));
    json_object_object_add(o, "data_b64", json_object_new_string(b64));
    free(b64);
    *res = o;
    return GS_OK;
}

static gs_err cmd_shutdown(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)args, (void)id, (void)res, (void)d;
    s->shutdown = true;
    return GS_OK;
}

static const char *const no_args[] = {NULL};
static const char *const load_args[] = {"scene", "builtin", NULL};
static const char *const set_load_args[] = {"load", "remove", NULL};
static const char *const advance_args[] = {"time", "steps", NULL};
static const char *const record_args[] = {"path", "stop", NULL};
static const char *const path_args[] = {"path", NULL};
static const char *const submit_args[] = {"scene", "schedule", "duration", "record", NULL};
static const char *const fetch_args[] = {"path", "offset", "length", "remove", NULL};
static const char *const stiffness_args[] = {"mesh", "positions", "torque", "refine", "nearfield", "path", "wait", NULL};

/* The result of a finished analysis: written to its HDF5 file when asked,
 * as JSON (the reply of the synchronous form, the done event's `result`). */
static gs_err stiffness_result(gs_service *s, gs_stiffness_result *r, const char *full, const char *rel,
                               json_object **res, gs_diag *d)
{
    gs_system *sys = gs_engine_system(s->eng);
    if (full[0]) {
        gs_err e = write_stiffness_safely(s, full, sys->scene, r, d);
        if (e != GS_OK) {
            gs_stiffness_result_clear(r);
            snprintf(d->field, sizeof d->field, "args.path");
            return e;
        }
    }
    *res = gs_stiffness_json(r, sys->scene);
    if (full[0])
        json_object_object_add(*res, "path", json_object_new_string(rel));
    gs_stiffness_result_clear(r);
    return GS_OK;
}

/* The analysis' set-up and its roll positions as single pieces of work
 * for gs_run_polled: the service answers while they run (they read the
 * scene and write their own run only). */
typedef struct stiff_job {
    const gs_scene *sc;
    int mesh;
    const gs_stiffness_opts *o;
    gs_stiffness_run **run;
    gs_diag *d;
} stiff_job;

static int stiff_begin(void *arg)
{
    stiff_job *j = arg;
    return gs_stiffness_begin(j->sc, j->mesh, j->o, j->run, j->d);
}

static int stiff_next(void *arg)
{
    stiff_job *j = arg;
    return gs_stiffness_next(*j->run, j->d);
}

static gs_err stiff_next_polled(gs_stiffness_run *run, gs_diag *d)
{
    stiff_job j = {.run = &run, .d = d};
    return (gs_err)gs_run_polled(stiff_next, &j);
}

/* Quasi-static mesh stiffness and transmission error of one mesh of the
 * loaded scene (docs/explanation/stiffness.md): rank 0 alone, no inertia, the run's
 * state untouched. Runs in chunks like `advance` (one roll position per
 * poll of the command socket): accepted at once, progress events, a done
 * event carrying the result, cancel ends it. With wait: true the reply
 * carries the result; meanwhile requests that read are answered and the
 * others wait (gs_run_polled).
 * Refused while an advance runs. */
static gs_err cmd_stiffness(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    GS_TRY(need_loaded(s, d));
    if (s->adv.active)
        return gs_diag_set(d, GS_EBUSY, "cmd", "the stiffness analysis is refused while an advance runs");
    if (s->stiff.run)
        return gs_diag_set(d, GS_EBUSY, "cmd", "a stiffness analysis ('%.128s') is running; cancel ends it",
                           s->stiff.parent_id);
    gs_system *sys = gs_engine_system(s->eng);
    char name[GS_NAME_MAX];
    GS_TRY(gsi_json_string(args, "mesh", "args", true, NULL, name, sizeof name, d));
    int mi = -1;
    for (int i = 0; i < sys->scene->n_meshes; i++)
        if (!strcmp(sys->scene->meshes[i].name, name))
            mi = i;
    if (mi < 0)
        return gs_diag_set(d, GS_ENOTFOUND, "args.mesh", "no mesh named '%s'", name);
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    int64_t v;
    GS_TRY(gsi_json_int(args, "positions", "args", 1, 720, false, o.positions, &v, d));
    o.positions = (int)v;
    GS_TRY(gsi_json_int(args, "refine", "args", -1, 3, false, -1, &v, d));
    o.refine = (int)v;
    GS_TRY(check_stiffness_size(sys->scene, mi, o.refine, d));
    GS_TRY(gsi_json_number(args, "torque", "args", -1e7, 1e7, false, 0, &o.torque_nm, d));
    bool nearfield = true;
    GS_TRY(gsi_json_bool(args, "nearfield", "args", true, &nearfield, d));
    o.nearfield = nearfield ? 2 : 0; /* true: the library's auto (quadratic meshes) */
    bool wait = false;
    GS_TRY(gsi_json_bool(args, "wait", "args", false, &wait, d));
    char full[PATH_MAX] = "", rel[600] = "";
    if (json_object_object_get_ex(args, "path", NULL)) {
        GS_TRY(path_arg(s, args, true, full, sizeof full, d));
        snprintf(rel, sizeof rel, "%s", json_object_get_string(json_object_object_get(args, "path")));
        /* The target's checks now, so a bad path is refused in the reply
         * rather than in the done event; the file is written (and checked
         * again) when the analysis ends. */
        gsi_beneath b;
        GS_TRY(gsi_check_write(s, rel_of(s, full), "args.path", false, &b, d));
        struct stat st;
        bool linked = fstatat(b.dirfd, b.leaf, &st, AT_SYMLINK_NOFOLLOW) == 0 && st.st_nlink > 1;
        gsi_beneath_close(&b);
        if (linked)
            return gs_diag_set(d, GS_ERANGE, "args.path", "'%s' has %lu hard links; refused as for every output "
                               "(docs/RELIABILITY.md)", rel, (unsigned long)st.st_nlink);
    }
    gs_stiffness_run *run = NULL;
    stiff_job sj = {.sc = sys->scene, .mesh = mi, .o = &o, .run = &run, .d = d};
    gs_err e = (gs_err)gs_run_polled(stiff_begin, &sj); /* meshing and factorisations */
    if (e != GS_OK) {
        if (!strchr(d->field, '.'))
            snprintf(d->field, sizeof d->field, "args.mesh");
        return e;
    }
    if (wait) {
        while (e == GS_OK && gs_stiffness_run_done(run) < gs_stiffness_run_positions(run))
            e = stiff_next_polled(run, d);
        gs_stiffness_result r;
        if (e == GS_OK)
            e = gs_stiffness_end(&run, &r, d);
        gs_stiffness_run_free(&run);
        if (e != GS_OK) {
            if (!strchr(d->field, '.'))
                snprintf(d->field, sizeof d->field, "args.mesh");
            return e;
        }
        return stiffness_result(s, &r, full, rel, res, d);
    }
    svc_stiffness *st = &s->stiff;
    memset(st, 0, sizeof *st);
    st->run = run;
    snprintf(st->parent_id, sizeof st->parent_id, "%s", id);
    snprintf(st->path, sizeof st->path, "%s", full);
    snprintf(st->rel, sizeof st->rel, "%s", rel);
    st->wall_start = st->last_progress = gs_now();
    *res = json_object_new_object();
    json_object_object_add(*res, "accepted", json_object_new_boolean(1));
    json_object_object_add(*res, "mesh", json_object_new_string(name));
    json_object_object_add(*res, "positions", json_object_new_int(o.positions));
    return GS_OK;
}

static const char *const modal_args[] = {"scene", "builtin", "shapes", NULL};
static const char *const sweep_args[] = {"scene", "builtin", "parameters", "settle", "measure", "time_step", "mesh",
                                         "driver_rpm", "groups", "path", "resume", "dispatcher", NULL};

/* Natural frequencies and mode shapes of the linearised rigid/lumped train
 * (docs/explanation/modal.md): of the scene in args.scene or the builtin args.builtin,
 * else of the loaded scene. Rank 0 alone, milliseconds; the run's state is
 * untouched. */
static gs_err cmd_modal(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    (void)id;
    const char *text;
    bool has_s;
    GS_TRY(scene_text_arg(args, false, &text, &has_s, d));
    bool shapes = true;
    json_object *sh;
    if (json_object_object_get_ex(args, "shapes", &sh)) {
        if (json_object_get_type(sh) != json_type_boolean)
            return gs_diag_set(d, GS_ESCHEMA, "args.shapes", "'shapes' must be true or false");
        shapes = json_object_get_boolean(sh);
    }
    gs_scene *own = NULL;
    const gs_scene *sc;
    if (text) {
        gs_err e = gs_scene_parse(text, strlen(text), &own, d);
        if (e != GS_OK) {
            char f[sizeof d->field];
            snprintf(f, sizeof f, "args.%s.%.140s", has_s ? "scene" : "builtin", d->field);
            memcpy(d->field, f, sizeof f);
            return e;
        }
        sc = own;
    } else {
        GS_TRY(need_loaded(s, d));
        sc = gs_engine_system(s->eng)->scene;
    }
    gs_modal *m = NULL;
    gs_err e = gs_modal_analyse(sc, &m, d);
    if (e == GS_OK) {
        *res = gs_modal_json(m, sc);
        if (!shapes)
            json_object_object_del(*res, "modes");
    } else if (text) {
        char f[sizeof d->field];
        snprintf(f, sizeof f, "args.%s%s%.140s", has_s ? "scene" : "builtin", d->field[0] ? "." : "", d->field);
        memcpy(d->field, f, sizeof f);
    }
    gs_modal_free(&m);
    gs_scene_free(&own);
    return e;
}

/* The done event of the analysis (cancelled, failed with e naming a field
 * of d, or with its result) and the end of the run. */
static void stiffness_done(gs_service *s, bool cancelled, int positions_done, gs_err e, const gs_diag *d,
                           json_object *result)
{
    svc_stiffness *st = &s->stiff;
    json_object *o = json_object_new_object();
    json_object_object_add(o, "parent_id", json_object_new_string(st->parent_id));
    json_object_object_add(o, "cancelled", json_object_new_boolean(cancelled));
    json_object_object_add(o, "positions_done", json_object_new_int(positions_done));
    json_object_object_add(o, "wall_seconds", json_object_new_double(gs_now() - st->wall_start));
    if (e != GS_OK) {
        json_object *err = json_object_new_object();
        json_object_object_add(err, "code", json_object_new_string(gs_errcode(e)));
        json_object_object_add(err, "message", json_object_new_string(d->message[0] ? d->message : gs_strerror(e)));
        json_object_object_add(err, "field", json_object_new_string(strchr(d->field, '.') ? d->field : "args.mesh"));
        json_object_object_add(o, "error", err);
    }
    if (result)
        json_object_object_add(o, "result", result);
    gs_stiffness_run_free(&st->run);
    gsi_publish_done(s, "stiffness", o);
}

void gsi_stiffness_stop(gs_service *s, bool cancelled)
{
    svc_stiffness *st = &s->stiff;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = GS_OK;
    json_object *result = NULL;
    int done = gs_stiffness_run_done(st->run);
    if (!cancelled) {
        gs_stiffness_result r;
        e = gs_stiffness_end(&st->run, &r, &d); /* frees the run */
        if (e == GS_OK)
            e = stiffness_result(s, &r, st->path, st->rel, &result, &d);
    }
    stiffness_done(s, cancelled, done, e, &d, result);
}

void gsi_stiffness_chunk(gs_service *s)
{
    svc_stiffness *st = &s->stiff;
    double t0 = gs_now();
    gs_err e = GS_OK;
    gs_diag d;
    gs_diag_clear(&d);
    int n = gs_stiffness_run_positions(st->run);
    /* At least one roll position, more while under about 20 ms. */
    do
        e = stiff_next_polled(st->run, &d);
    while (e == GS_OK && gs_stiffness_run_done(st->run) < n && gs_now() - t0 < 0.02);
    int k = gs_stiffness_run_done(st->run);
    double now = gs_now();
    if (e == GS_OK && (now - st->last_progress > 0.1 || k == n)) {
        st->last_progress = now;
        json_object *o = json_object_new_object();
        json_object_object_add(o, "parent_id", json_object_new_string(st->parent_id));
        json_object_object_add(o, "kind", json_object_new_string("stiffness"));
        json_object_object_add(o, "fraction", json_object_new_double(n > 0 ? (double)k / n : 1.0));
        double el = now - st->wall_start;
        json_object_object_add(o, "steps_per_second", json_object_new_double(el > 0 ? k / el : 0.0));
        gsi_publish(s, "progress", o);
    }
    if (e != GS_OK)
        stiffness_done(s, false, k, e, &d, NULL);
    else if (k >= n)
        gsi_stiffness_stop(s, false);
}

static const gsi_command commands[] = {
    {"hello", cmd_hello, true, no_args},
    {"load", cmd_load, false, load_args},
    {"unload", cmd_unload, false, no_args},
    {"set_load", cmd_set_load, true, set_load_args},
    {"advance", cmd_advance, false, advance_args},
    {"pause", cmd_pause, true, no_args},
    {"resume", cmd_resume, true, no_args},
    {"cancel", cmd_cancel, true, no_args},
    {"status", cmd_status, true, no_args},
    {"state", cmd_state, true, no_args},
    {"record", cmd_record, true, record_args},
    {"checkpoint", cmd_checkpoint, true, path_args},
    {"restore", cmd_restore, false, path_args},
    {"submit", cmd_submit, true, submit_args},
    {"jobs", cmd_jobs, true, no_args},
    {"fetch", cmd_fetch, true, fetch_args},
    {"stiffness", cmd_stiffness, true, stiffness_args},
    {"modal", cmd_modal, true, modal_args},
    {"sweep", gsi_cmd_sweep, false, sweep_args},
    {"shutdown", cmd_shutdown, true, no_args},
    {NULL, NULL, false, NULL},
};

const gsi_command *gsi_commands(void) { return commands; }

const gsi_command *gsi_command_find(const char *name)
{
    for (const gsi_command *c = commands; c->name; c++)
        if (strcmp(c->name, name) == 0)
            return c;
    return NULL;
}
