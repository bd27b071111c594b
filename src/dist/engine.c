/* SPDX-License-Identifier: MIT
 * The replicated engine (see include/gearsim/engine.h). */
#include <json-c/json.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gearsim/engine.h"
#include "gearsim/util.h"

struct gs_engine {
    MPI_Comm comm;
    int rank, size;
    gs_system *sys;
    gs_engine_step_hook hook;
    void *hook_user;
    double *rec, *sol;
    int rec_n, sol_n;
};

gs_err gs_engine_new(MPI_Comm comm, gs_engine **out)
{
    gs_engine *e = gs_calloc(1, sizeof *e);
    if (!e)
        return GS_ENOMEM;
    e->comm = comm;
    MPI_Comm_rank(comm, &e->rank);
    MPI_Comm_size(comm, &e->size);
    *out = e;
    return GS_OK;
}

static void unload(gs_engine *e)
{
    gs_system_free(&e->sys);
    free(e->rec);
    free(e->sol);
    e->rec = e->sol = NULL;
}

void gs_engine_free(gs_engine **pe)
{
    if (!pe || !*pe)
        return;
    unload(*pe);
    free(*pe);
    *pe = NULL;
}

int gs_engine_rank(const gs_engine *e) { return e->rank; }
int gs_engine_size(const gs_engine *e) { return e->size; }
gs_system *gs_engine_system(gs_engine *e) { return e->sys; }

void gs_engine_set_hook(gs_engine *e, gs_engine_step_hook hook, void *user)
{
    e->hook = hook;
    e->hook_user = user;
}

static gs_err adopt(gs_engine *e, gs_scene *sc, gs_diag *d)
{
    gs_system *sys;
    GS_TRY(gs_system_new(sc, e->rank, e->size, &sys, d));
    unload(e);
    e->sys = sys;
    e->rec_n = 2 * sys->n_bodies;
    e->sol_n = gs_step_solution_size(sys) + 1;
    e->rec = gs_calloc((size_t)e->rec_n, sizeof(double));
    e->sol = gs_calloc((size_t)e->sol_n, sizeof(double));
    if (!e->rec || !e->sol) {
        unload(e);
        return GS_ENOMEM;
    }
    return GS_OK;
}

/* One distributed step: records reduced to rank 0 (each rank fills only its
 * own bodies, the others are exact zeros, so the sum is exact and the result
 * independent of the rank count), solve there, broadcast, apply. */
static gs_err dist_step(gs_engine *e)
{
    gs_system *s = e->sys;
    gs_step_records(s, e->rec);
    if (e->size > 1) {
        if (e->rank == 0)
            MPI_Reduce(MPI_IN_PLACE, e->rec, e->rec_n, MPI_DOUBLE, MPI_SUM, 0, e->comm);
        else
            MPI_Reduce(e->rec, NULL, e->rec_n, MPI_DOUBLE, MPI_SUM, 0, e->comm);
    }
    int n = e->sol_n - 1;
    if (e->rank == 0) {
        gs_err err = gs_step_solve(s, e->rec, e->sol);
        e->sol[n] = (double)err;
    }
    if (e->size > 1)
        MPI_Bcast(e->sol, e->sol_n, MPI_DOUBLE, 0, e->comm);
    gs_err err = (gs_err)(int)e->sol[n];
    if (err != GS_OK)
        return err;
    gs_step_apply(s, e->sol);
    return GS_OK;
}

static gs_err run_steps(gs_engine *e, int64_t n, int64_t *done)
{
    int64_t i = 0;
    gs_err err = GS_OK;
    for (; i < n; i++) {
        err = dist_step(e);
        if (err != GS_OK)
            break;
        /* The hook (telemetry, recording) runs on rank 0 only and does not
         * stop a step half-way: chunks end at the step count rank 0 chose. */
        if (e->rank == 0 && e->hook)
            e->hook(e, e->hook_user);
    }
    if (done)
        *done = i;
    return err;
}

/* Snapshot format: magic, n_coords, n_meshes, step, time, work_in,
 * dissipated, energy0, q[n], w[n], mesh force[n_meshes] (the last step's,
 * reported by telemetry), then scene JSON and loads JSON, NUL-terminated. */
#define SNAP_MAGIC 0x32534753u /* "GSS2" */

static char *loads_json(const gs_scene *sc)
{
    json_object *arr = json_object_new_array();
    static const char *types[] = {"constant", "ramp", "brake", "table"};
    for (int i = 0; i < sc->n_loads; i++) {
        const gs_scene_load *l = &sc->loads[i];
        json_object *o = json_object_new_object();
        json_object_object_add(o, "name", json_object_new_string(l->name));
        json_object_object_add(o, "body", json_object_new_string(sc->bodies[l->body].name));
        json_object_object_add(o, "type", json_object_new_string(types[l->type]));
        switch (l->type) {
        case GS_LOAD_CONSTANT:
            json_object_object_add(o, "moment", json_object_new_double(l->moment));
            break;
        case GS_LOAD_RAMP:
            json_object_object_add(o, "moment", json_object_new_double(l->moment));
            json_object_object_add(o, "ramp_time", json_object_new_double(l->ramp_time));
            break;
        case GS_LOAD_BRAKE:
            json_object_object_add(o, "coefficient", json_object_new_double(l->coefficient));
            break;
        case GS_LOAD_TABLE: {
            json_object *t = json_object_new_array(), *m = json_object_new_array();
            for (int k = 0; k < l->n_table; k++) {
                json_object_array_add(t, json_object_new_double(l->times[k]));
                json_object_array_add(m, json_object_new_double(l->moments[k]));
            }
            json_object_object_add(o, "times", t);
            json_object_object_add(o, "moments", m);
            break;
        }
        }
        json_object_array_add(arr, o);
    }
    char *s = gs_strdup(json_object_to_json_string_ext(arr, JSON_C_TO_STRING_PLAIN));
    json_object_put(arr);
    return s;
}

gs_err gs_engine_snapshot(gs_engine *e, char **bytes, size_t *len)
{
    *bytes = NULL;
    *len = 0;
    gs_system *s = e->sys;
    if (!s)
        return GS_ESTATE;
    char *lj = loads_json(s->scene);
    if (!lj)
        return GS_ENOMEM;
    size_t n = (size_t)s->n_coords, nm = (size_t)s->n_meshes;
    size_t sl = strlen(s->scene->json) + 1, ll = strlen(lj) + 1;
    size_t total = 3 * sizeof(uint32_t) + sizeof(int64_t) + 4 * sizeof(double) +
                   (2 * n + nm) * sizeof(double) + sl + ll;
    char *b = malloc(total), *p = b;
    if (!b) {
        free(lj);
        return GS_ENOMEM;
    }
    uint32_t magic = SNAP_MAGIC, nc = (uint32_t)n, nmesh = (uint32_t)nm;
#define PUT(x, sz) (memcpy(p, (x), (sz)), p += (sz))
    PUT(&magic, sizeof magic);
    PUT(&nc, sizeof nc);
    PUT(&nmesh, sizeof nmesh);
    PUT(&s->step, sizeof s->step);
    PUT(&s->time, sizeof(double));
    PUT(&s->work_in, sizeof(double));
    PUT(&s->dissipated, sizeof(double));
    PUT(&s->energy0, sizeof(double));
    PUT(s->q, n * sizeof(double));
    PUT(s->w, n * sizeof(double));
    for (size_t i = 0; i < nm; i++)
        PUT(&s->meshes[i].force, sizeof(double));
    PUT(s->scene->json, sl);
    PUT(lj, ll);
#undef PUT
    free(lj);
    *bytes = b;
    *len = total;
    return GS_OK;
}

static gs_err restore(gs_engine *e, const char *b, size_t len, gs_diag *d)
{
    size_t head = 3 * sizeof(uint32_t) + sizeof(int64_t) + 4 * sizeof(double);
    if (len < head)
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint is truncated");
    uint32_t magic, nc, nm;
    const char *p = b;
    memcpy(&magic, p, sizeof magic);
    memcpy(&nc, p + 4, sizeof nc);
    memcpy(&nm, p + 8, sizeof nm);
    p += 12;
    if (magic != SNAP_MAGIC || nc > (1u << 20) || nm > (1u << 20) ||
        len < head + (2 * (size_t)nc + nm) * sizeof(double) + 2)
        return gs_diag_set(d, GS_EIO, "path", "not a gearsim checkpoint");
    int64_t step;
    double t, wi, di, e0;
    memcpy(&step, p, 8), p += 8;
    memcpy(&t, p, 8), p += 8;
    memcpy(&wi, p, 8), p += 8;
    memcpy(&di, p, 8), p += 8;
    memcpy(&e0, p, 8), p += 8;
    const double *q = (const double *)(const void *)p;
    const double *forces = q + 2 * (size_t)nc;
    const char *scene = p + (2 * (size_t)nc + nm) * sizeof(double);
    const char *end = b + len;
    const char *lj = memchr(scene, '\0', (size_t)(end - scene));
    if (!lj || lj + 1 >= end || !memchr(lj + 1, '\0', (size_t)(end - lj - 1)))
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint is truncated");
    lj++;
    gs_scene *sc;
    GS_TRY(gs_scene_parse(scene, strlen(scene), &sc, d));
    json_object *loads = json_tokener_parse(lj);
    if (!loads || json_object_get_type(loads) != json_type_array) {
        json_object_put(loads);
        gs_scene_free(&sc);
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint's loads are damaged");
    }
    for (int i = 0; i < sc->n_loads; i++)
        gs_scene_load_clear(&sc->loads[i]);
    sc->n_loads = 0;
    size_t nl = json_object_array_length(loads);
    gs_scene_load *nls = gs_calloc(nl ? nl : 1, sizeof *nls);
    if (!nls) {
        json_object_put(loads);
        gs_scene_free(&sc);
        return GS_ENOMEM;
    }
    free(sc->loads);
    sc->loads = nls;
    for (size_t i = 0; i < nl; i++) {
        gs_err err = gs_scene_parse_load(sc, json_object_array_get_idx(loads, i), "loads", &nls[i], d);
        if (err != GS_OK) {
            json_object_put(loads);
            gs_scene_free(&sc);
            return err;
        }
        sc->n_loads++;
    }
    json_object_put(loads);
    GS_TRY(adopt(e, sc, d));
    gs_system *s = e->sys;
    if ((uint32_t)s->n_coords != nc || (uint32_t)s->n_meshes != nm) {
        unload(e);
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint does not match its scene");
    }
    memcpy(s->q, q, nc * sizeof(double));
    memcpy(s->w, q + nc, nc * sizeof(double));
    s->step = step;
    s->time = t;
    s->work_in = wi;
    s->dissipated = di;
    s->energy0 = e0;
    for (int i = 0; i < s->n_meshes; i++) {
        gs_gmesh_rt *m = &s->meshes[i];
        double v = 0;
        for (int j = 0; j < s->n_coords; j++)
            v += m->a[j] * s->q[j];
        m->deflection = v - m->s_ref;
        memcpy(&m->force, forces + i, sizeof(double));
    }
    return GS_OK;
}

static gs_err exec(gs_engine *e, gs_op op, const char *payload, size_t len, gs_diag *d,
                   int64_t *done)
{
    switch (op) {
    case GS_OP_NONE:
    case GS_OP_SHUTDOWN:
        return GS_OK;
    case GS_OP_LOAD: {
        gs_scene *sc;
        GS_TRY(gs_scene_parse(payload, len, &sc, d));
        return adopt(e, sc, d);
    }
    case GS_OP_UNLOAD:
        unload(e);
        return GS_OK;
    case GS_OP_STEP: {
        int64_t n;
        if (!e->sys || len != sizeof n)
            return GS_ESTATE;
        memcpy(&n, payload, sizeof n);
        return run_steps(e, n, done);
    }
    case GS_OP_SET_LOAD: {
        if (!e->sys)
            return GS_ESTATE;
        json_object *o = json_tokener_parse(payload);
        gs_scene_load l;
        gs_err err = gs_scene_parse_load(e->sys->scene, o, "load", &l, d);
        json_object_put(o);
        if (err != GS_OK)
            return err;
        err = gs_system_set_load(e->sys, &l);
        if (err != GS_OK)
            gs_scene_load_clear(&l);
        return err;
    }
    case GS_OP_REMOVE_LOAD:
        if (!e->sys)
            return GS_ESTATE;
        return gs_system_remove_load(e->sys, payload);
    case GS_OP_RESTORE:
        return restore(e, payload, len, d);
    }
    return GS_EINVAL;
}

gs_err gs_engine_run(gs_engine *e, gs_op op, const void *payload, size_t len, gs_diag *d,
                     int64_t *done)
{
    if (e->size > 1) {
        int64_t hdr[2] = {op, (int64_t)len};
        MPI_Request rq;
        MPI_Ibcast(hdr, 2, MPI_INT64_T, 0, e->comm, &rq);
        MPI_Wait(&rq, MPI_STATUS_IGNORE);
        if (len > 0)
            MPI_Bcast((void *)payload, (int)len, MPI_BYTE, 0, e->comm);
    }
    return exec(e, op, payload, len, d, done);
}

gs_err gs_engine_serve(gs_engine *e)
{
    for (;;) {
        int64_t hdr[2];
        MPI_Request rq;
        MPI_Ibcast(hdr, 2, MPI_INT64_T, 0, e->comm, &rq);
        /* Spin briefly (a chunk of an advance follows quickly), then sleep. */
        int flag = 0;
        double t0 = gs_now();
        while (!flag) {
            MPI_Test(&rq, &flag, MPI_STATUS_IGNORE);
            if (!flag && gs_now() - t0 > 0.005) {
                struct timespec ts = {0, 500000};
                nanosleep(&ts, NULL);
            }
        }
        size_t len = (size_t)hdr[1];
        char *payload = malloc(len + 1);
        if (!payload)
            MPI_Abort(e->comm, 3);
        if (len > 0)
            MPI_Bcast(payload, (int)len, MPI_BYTE, 0, e->comm);
        payload[len] = '\0';
        gs_diag d;
        gs_op op = (gs_op)hdr[0];
        exec(e, op, payload, len, &d, NULL);
        free(payload);
        if (op == GS_OP_SHUTDOWN)
            return GS_OK;
    }
}
