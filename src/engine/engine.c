/* SPDX-License-Identifier: MIT
 * The replicated engine (see include/gearsim/engine.h). */
#include <json-c/json.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gearsim/engine.h"
#include "gearsim/record.h"
#include "gearsim/sweep.h"
#include "gearsim/util.h"

struct gs_engine {
    MPI_Comm comm;
    int rank, size;
    gs_system *sys;
    gs_engine_step_hook hook;
    void *hook_user;
    double *rec, *sol;
    size_t rec_n, sol_n;    /* capacities */
    double *pk;             /* two-phase record: free parts, then compliance sub-blocks, packed */
    size_t pk_n;
    int *mask;              /* the plan dofs whose compliance the solve reads, then the status */
    size_t mask_n;
    double *ebuf;           /* 2 per body: energy reports */
    double **field;         /* per body with fields (rank 0): u (2n) then vm (n) */
    int64_t field_step;     /* step of the fields held, -1 none */
    double *states;         /* rank 0: gathered body states for a snapshot */
    size_t n_states;
    gs_step_timing timing;  /* this rank's, since load */
    double cpu_mark;        /* thread CPU time at the start of the current phase */
    double cpu_ph[3];       /* this substep's parallel phases (CPU s): records, compliance, apply */
    double cpu_own;         /* this substep's CPU s outside the collectives */
    bool cpu_on;            /* time the phases (bodies with their own state only) */
    bool cpu_timing;        /* gs_engine_set_cpu_timing: cpu_on allowed */
    bool energy_sched;      /* gs_engine_set_energy_schedule (rank 0's travels with GS_OP_STEP) */
    bool solo;              /* steps on rank 0 alone (no body state elsewhere) */
    bool stepping;          /* within a GS_OP_STEP chunk (gs_engine_stepping) */
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
    if (e->field && e->sys)
        for (int i = 0; i < e->sys->n_bodies; i++)
            free(e->field[i]);
    free(e->field);
    e->field = NULL;
    free(e->states);
    e->states = NULL;
    e->n_states = 0;
    gs_system_free(&e->sys);
    free(e->rec);
    free(e->sol);
    free(e->ebuf);
    free(e->pk);
    free(e->mask);
    e->rec = e->sol = e->ebuf = e->pk = NULL;
    e->mask = NULL;
    e->pk_n = e->mask_n = 0;
}

/* CPU seconds of the calling thread: the step's critical path is summed
 * from these (struct gs_step_timing), so that a rank descheduled by other
 * jobs, or spinning in a collective, does not count. */
static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* CPU seconds since the last mark (and a new mark), counted as this rank's
 * own work; skip_lap restarts after a collective (its wait is not work). */
static double cpu_lap(gs_engine *e)
{
    if (!e->cpu_on) /* a thread CPU clock is a system call: not on steps of microseconds */
        return 0.0;
    double c = cpu_now(), d = c - e->cpu_mark;
    e->cpu_mark = c;
    e->cpu_own += d;
    return d;
}

static void skip_lap(gs_engine *e)
{
    if (e->cpu_on)
        e->cpu_mark = cpu_now();
}

/* Slots for each rank's CPU time of a parallel phase behind a reduced
 * buffer: own slot set, the others zero; after the sum rank 0 reads the
 * slowest (max_slot). */
static void put_slot(const gs_engine *e, double *slots, double v)
{
    for (int r = 0; r < e->size; r++)
        slots[r] = r == e->rank ? v : 0.0;
}

static double max_slot(const gs_engine *e, const double *slots)
{
    double m = 0;
    for (int r = 0; r < e->size; r++)
        m = slots[r] > m ? slots[r] : m;
    return m;
}

/* Owners report the energies of bodies with their own state; every rank
 * adopts the sum (one value is non-zero per body: the sum is exact). */
static void wait_collective(gs_engine *e, MPI_Request *rq);

static gs_err sync_energy(gs_engine *e, gs_err err, double cpu_apply)
{
    gs_system *s = e->sys;
    if (e->size == 1 || !gs_system_has_body_state(s))
        return err;
    /* The slot after the reports carries a failure of any owner, so that
     * every rank stops at the same step; then each rank's CPU time of its
     * apply phase (the critical path, gs_step_timing). */
    int n = GS_ENERGY_REPORT * s->n_bodies;
    gs_system_energy_report(s, e->ebuf);
    e->ebuf[n] = err != GS_OK ? 1.0 : 0.0;
    put_slot(e, e->ebuf + n + 1, cpu_apply);
    MPI_Request rq;
    MPI_Iallreduce(MPI_IN_PLACE, e->ebuf, n + 1 + e->size, MPI_DOUBLE, MPI_SUM, e->comm, &rq);
    wait_collective(e, &rq); /* the owners' apply phases run meanwhile */
    e->cpu_ph[2] = max_slot(e, e->ebuf + n + 1);
    gs_system_energy_adopt(s, e->ebuf);
    if (err == GS_OK && e->ebuf[n] != 0.0)
        err = GS_EINTERNAL;
    return err;
}

/* Move n doubles of body b's data from its owner to rank 0: `fill` runs on
 * the owner into buf (rank 0's buf receives). Collective over the engine. */
static void to_root(gs_engine *e, const gs_body_rt *b, double *buf, size_t n,
                    void (*fill)(const gs_body_rt *, double *, size_t))
{
    if (b->owner == e->rank)
        fill(b, buf, n);
    if (e->size == 1 || b->owner == 0)
        return;
    if (e->rank == b->owner)
        MPI_Send(buf, (int)n, MPI_DOUBLE, 0, 7, e->comm);
    else if (e->rank == 0)
        MPI_Recv(buf, (int)n, MPI_DOUBLE, b->owner, 7, e->comm, MPI_STATUS_IGNORE);
}

static void fill_fields(const gs_body_rt *b, double *buf, size_t n)
{
    gs_index nn = b->ops->field_nodes(b);
    (void)n;
    b->ops->fields(b, buf, buf + 2 * nn);
}

static void fill_state(const gs_body_rt *b, double *buf, size_t n)
{
    (void)n;
    b->ops->save(b, buf);
}

/* Field snapshots of every body with fields, to rank 0 (collective). */
static gs_err gather_fields(gs_engine *e)
{
    gs_system *s = e->sys;
    double *tmp = NULL;
    for (int i = 0; i < s->n_bodies; i++) {
        gs_body_rt *b = &s->bodies[i];
        if (!b->ops->fields)
            continue;
        size_t n = 3 * (size_t)b->ops->field_nodes(b);
        double *buf = e->rank == 0 ? e->field[i] : NULL;
        if (!buf) {
            free(tmp);
            tmp = malloc(n * sizeof(double));
            if (!tmp)
                MPI_Abort(e->comm, 3); /* a collective cannot be left half-way */
            buf = tmp;
        }
        to_root(e, b, buf, n, fill_fields);
    }
    free(tmp);
    e->field_step = s->step;
    return GS_OK;
}

static size_t states_size(const gs_system *s)
{
    size_t n = 0;
    for (int i = 0; i < s->n_bodies; i++)
        if (s->bodies[i].ops->state_size)
            n += s->bodies[i].ops->state_size(&s->bodies[i]);
    return n;
}

/* Body states from their owners into e->states on rank 0 (collective). */
static gs_err gather_states(gs_engine *e)
{
    gs_system *s = e->sys;
    if (!s)
        return GS_ESTATE;
    size_t total = states_size(s), off = 0;
    free(e->states);
    e->states = gs_calloc(total ? total : 1, sizeof(double));
    if (!e->states)
        MPI_Abort(e->comm, 3); /* a collective cannot be left half-way */
    e->n_states = total;
    for (int i = 0; i < s->n_bodies; i++) {
        gs_body_rt *b = &s->bodies[i];
        if (!b->ops->state_size)
            continue;
        size_t n = b->ops->state_size(b);
        to_root(e, b, e->states + off, n, fill_state);
        off += n;
    }
    return GS_OK;
}

const double *gs_engine_fields(const gs_engine *e, int body)
{
    if (!e->sys || !e->field || body < 0 || body >= e->sys->n_bodies || e->field_step != e->sys->step)
        return NULL;
    return e->field[body];
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
bool gs_engine_stepping(const gs_engine *e) { return e && e->stepping; }
gs_system *gs_engine_system(gs_engine *e) { return e->sys; }
MPI_Comm gs_engine_comm(const gs_engine *e) { return e->comm; }

void gs_engine_set_hook(gs_engine *e, gs_engine_step_hook hook, void *user)
{
    e->hook = hook;
    e->hook_user = user;
}

void gs_engine_set_energy_schedule(gs_engine *e, bool on)
{
    e->energy_sched = on;
}

void gs_engine_set_cpu_timing(gs_engine *e, bool on)
{
    e->cpu_timing = on;
}

/* On the energy schedule: are the energies read after the next step? */
static bool energy_due(const gs_system *s, bool last)
{
    int64_t k = s->step + 1;
    const gs_scene *sc = s->scene;
    return last || sc->contact_scheme == GS_CONTACT_CLOSURE_ENERGY || k % sc->telemetry_every == 0 ||
           k % sc->record_every == 0;
}

/* The energies of the bodies with their own state, summed by their owners
 * from the state and reported to every rank (collective). */
static gs_err refresh_energy(gs_engine *e, gs_err err)
{
    gs_system *s = e->sys;
    gs_model_view v;
    gs_system_view(s, &v);
    for (int i = 0; i < s->n_bodies; i++) {
        gs_body_rt *b = &s->bodies[i];
        if (b->ops->state_size && b->owner == e->rank)
            b->ops->energy(&v, b, &b->T, &b->V);
    }
    return sync_energy(e, err, 0.0);
}

/* A system built for gs_run_polled. */
typedef struct build_job {
    gs_scene *sc;
    int rank, size;
    gs_system **sys;
    gs_diag *d;
} build_job;

static int build_system(void *arg)
{
    build_job *j = arg;
    return gs_system_new(j->sc, j->rank, j->size, j->sys, j->d);
}

/* Wait for a collective: rank 0 calls the poll hook meanwhile (its service
 * answers while the other ranks work), the others block. */
static void wait_collective(gs_engine *e, MPI_Request *rq)
{
    if (e->rank != 0) {
        MPI_Wait(rq, MPI_STATUS_IGNORE);
        return;
    }
    int flag = 0;
    for (;;) {
        MPI_Test(rq, &flag, MPI_STATUS_IGNORE);
        if (flag)
            return;
        gs_poll();
    }
}

static gs_err adopt(gs_engine *e, gs_scene *sc, gs_diag *d)
{
    gs_system *sys = NULL;
    /* Meshing, models and factorisations: seconds for fine meshes. */
    build_job bj = {sc, e->rank, e->size, &sys, d};
    gs_err err0 = (gs_err)gs_run_polled(build_system, &bj);
    if (e->size > 1) {
        /* Owners build more than the others (factorisations): all ranks
         * agree on success, or none adopts the scene. */
        int bad = err0 != GS_OK;
        MPI_Request rq;
        MPI_Iallreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, e->comm, &rq);
        wait_collective(e, &rq);
        if (bad && err0 == GS_OK) {
            gs_system_free(&sys);
            return gs_diag_set(d, GS_EINTERNAL, "scene", "another rank could not build the scene");
        }
    }
    if (err0 != GS_OK)
        return err0;
    unload(e);
    e->sys = sys;
    e->rec_n = sys->plan.rec_size;
    e->sol_n = sys->plan.sol_size + 1;
    e->rec = gs_calloc(e->rec_n, sizeof(double));
    e->sol = gs_calloc(e->sol_n, sizeof(double));
    e->ebuf = gs_calloc((size_t)(GS_ENERGY_REPORT * sys->n_bodies + 1 + e->size), sizeof(double));
    e->field = gs_calloc((size_t)sys->n_bodies, sizeof(double *));
    e->field_step = -1;
    memset(&e->timing, 0, sizeof e->timing);
    if (!e->rec || !e->sol || !e->ebuf || !e->field) {
        unload(e);
        return GS_ENOMEM;
    }
    for (int i = 0; e->rank == 0 && sys->scene->fields_every > 0 && i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (!b->ops->fields)
            continue;
        e->field[i] = gs_calloc(3 * (size_t)b->ops->field_nodes(b), sizeof(double));
        if (!e->field[i]) {
            unload(e);
            return GS_ENOMEM;
        }
    }
    /* The initial energy of bodies with their own state is known to their
     * owners only. */
    gs_err err = sync_energy(e, GS_OK, 0.0);
    if (err != GS_OK) {
        unload(e);
        return err;
    }
    gs_energy en;
    gs_system_energy(sys, &en);
    sys->energy0 = en.total;
    return GS_OK;
}

/* One distributed step: records reduced to rank 0 (each rank fills only its
 * own bodies, the others are exact zeros, so the sum is exact and the result
 * independent of the rank count), solve there, broadcast, apply. */
static bool grow_pk(gs_engine *e, size_t n)
{
    double *r = gs_grow(e->pk, &e->pk_n, n, sizeof(double));
    if (r)
        e->pk = r;
    return r != NULL;
}

static gs_err reserve(gs_engine *e)
{
    const gs_step_plan *p = &e->sys->plan;
    double *r = gs_grow(e->rec, &e->rec_n, p->rec_size, sizeof(double));
    if (!r)
        return GS_ENOMEM;
    e->rec = r;
    r = gs_grow(e->sol, &e->sol_n, p->sol_size + 1, sizeof(double));
    if (!r)
        return GS_ENOMEM;
    e->sol = r;
    if (gs_step_two_phase(e->sys)) {
        int *m = gs_grow(e->mask, &e->mask_n, gs_step_mask_size(e->sys), sizeof(int));
        if (!m)
            return GS_ENOMEM;
        e->mask = m;
        if (e->size > 1 && !grow_pk(e, gs_step_free_size(e->sys) + (size_t)e->size))
            return GS_ENOMEM;
    }
    return GS_OK;
}

/* Sum the packed buffer (n doubles) over the ranks into rank 0's. */
static void reduce_pk(gs_engine *e, size_t n)
{
    MPI_Request rq;
    if (e->rank == 0)
        MPI_Ireduce(MPI_IN_PLACE, e->pk, (int)n, MPI_DOUBLE, MPI_SUM, 0, e->comm, &rq);
    else
        MPI_Ireduce(e->pk, NULL, (int)n, MPI_DOUBLE, MPI_SUM, 0, e->comm, &rq);
    wait_collective(e, &rq);
}

/* The two-phase record (step.h) after phase one's records: their free
 * parts to rank 0, the rows and the mask there, the mask to every rank,
 * the selected compliance sub-blocks from their owners to rank 0's
 * records. Collective; returns the selection's verdict on every rank, and
 * in *root a failure of rank 0 alone (it goes out with the solution). */
static gs_err two_phase(gs_engine *e, gs_err *root)
{
    *root = GS_OK;
    gs_system *s = e->sys;
    gs_step_timing *tm = &e->timing;
    double t0 = gs_now(), t1;
    if (e->size > 1) {
        size_t n = gs_step_free_size(s);
        gs_step_free_pack(s, e->rec, e->pk, false);
        e->cpu_ph[0] += cpu_lap(e); /* this rank's records, with the free parts packed */
        put_slot(e, e->pk + n, e->cpu_ph[0]);
        reduce_pk(e, n + (size_t)e->size);
        if (e->rank == 0) {
            gs_step_free_pack(s, e->rec, e->pk, true);
            e->cpu_ph[0] = max_slot(e, e->pk + n);
        }
    }
    t1 = gs_now();
    tm->reduce += t1 - t0;
    skip_lap(e);
    size_t nm = gs_step_mask_size(s);
    if (e->rank == 0)
        e->mask[nm - 1] = (int)gs_step_select(s, e->rec, e->mask);
    double cpu_select = cpu_lap(e);
    t0 = gs_now();
    tm->solve += t0 - t1;
    if (e->size > 1)
        MPI_Bcast(e->mask, (int)nm, MPI_INT, 0, e->comm);
    t1 = gs_now();
    tm->bcast += t1 - t0;
    gs_err err = (gs_err)e->mask[nm - 1];
    if (err != GS_OK)
        return err;
    skip_lap(e);
    size_t nc = gs_step_compliance_size(s, e->mask);
    if (!grow_pk(e, nc + (size_t)e->size))
        MPI_Abort(e->comm, 3); /* a collective cannot be left half-way */
    if (gs_step_compliance(s, e->mask, e->pk) != GS_OK)
        for (size_t k = 0; k < nc; k++) /* out of memory: the solve refuses NaN */
            e->pk[k] = NAN;
    e->cpu_ph[1] = cpu_lap(e);
    t0 = gs_now();
    tm->records += t0 - t1;
    if (e->size > 1) {
        put_slot(e, e->pk + nc, e->cpu_ph[1]);
        reduce_pk(e, nc + (size_t)e->size);
        e->cpu_ph[1] = e->rank == 0 ? max_slot(e, e->pk + nc) : e->cpu_ph[1];
    }
    skip_lap(e);
    if (e->rank == 0)
        *root = gs_step_compliance_unpack(s, e->mask, e->pk, e->rec);
    e->cpu_ph[1] += cpu_select + cpu_lap(e); /* rank 0's serial parts */
    tm->reduce += gs_now() - t0;
    return GS_OK;
}

static gs_err two_phase(gs_engine *e, gs_err *root);

/* The critical path of a substep (gs_step_timing cpu_path) is summed as
 * cpu_ph[0] (the slowest rank's prepare and records) + cpu_ph[1] (rank 0's
 * selection, the slowest rank's compliance sub-blocks, rank 0's unpacking)
 * + rank 0's solve + cpu_ph[2] (the slowest rank's apply) + the replicated
 * end (energy adoption, damping, closure's velocity update). */
static gs_err dist_substep(gs_engine *e)
{
    gs_system *s = e->sys;
    gs_step_timing *tm = &e->timing;
    double t0 = gs_now(), t1;
    skip_lap(e);
    e->cpu_own = e->cpu_ph[0] = e->cpu_ph[1] = e->cpu_ph[2] = 0;
    /* The plan is the same on every rank (contact search from the rigid
     * state); a failure there is too, so ranks stay in step. */
    gs_err err = gs_step_prepare(s);
    if (err == GS_OK)
        err = reserve(e);
    e->cpu_ph[0] = cpu_lap(e);
    if (e->size > 1) {
        int bad = err != GS_OK;
        MPI_Request rq;
        MPI_Iallreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, e->comm, &rq);
        wait_collective(e, &rq);
        if (bad)
            return err != GS_OK ? err : GS_ENOMEM;
    } else if (err != GS_OK) {
        return err;
    }
    skip_lap(e);
    int rn = (int)s->plan.rec_size, n = (int)s->plan.sol_size;
    t1 = gs_now();
    tm->prepare += t1 - t0;
    gs_step_records(s, e->rec);
    e->cpu_ph[0] += cpu_lap(e);
    t0 = gs_now();
    tm->records += t0 - t1;
    /* Elastic gears record in two phases (step.h); the others' records go
     * to rank 0 whole. */
    bool two = gs_step_two_phase(s);
    if (e->size > 1 && !two) {
        MPI_Request rq;
        if (e->rank == 0)
            MPI_Ireduce(MPI_IN_PLACE, e->rec, rn, MPI_DOUBLE, MPI_SUM, 0, e->comm, &rq);
        else
            MPI_Ireduce(e->rec, NULL, rn, MPI_DOUBLE, MPI_SUM, 0, e->comm, &rq);
        wait_collective(e, &rq);
    }
    t1 = gs_now();
    tm->reduce += t1 - t0;
    gs_err perr = GS_OK;
    if (two) {
        GS_TRY(two_phase(e, &perr));
        t1 = gs_now();
    }
    skip_lap(e);
    if (e->rank == 0) {
        err = perr != GS_OK ? perr : gs_step_solve(s, e->rec, e->sol);
        e->sol[n] = (double)err;
    }
    double cpu_solve = cpu_lap(e);
    t0 = gs_now();
    tm->solve += t0 - t1;
    if (e->size > 1)
        MPI_Bcast(e->sol, n + 1, MPI_DOUBLE, 0, e->comm);
    t1 = gs_now();
    tm->bcast += t1 - t0;
    err = (gs_err)(int)e->sol[n];
    if (err != GS_OK)
        return err;
    skip_lap(e);
    err = gs_step_apply(s, e->sol);
    double cpu_apply = cpu_lap(e);
    t0 = gs_now();
    tm->apply += t0 - t1;
    e->cpu_ph[2] = cpu_apply; /* sync_energy takes the slowest rank's */
    err = sync_energy(e, err, cpu_apply);
    skip_lap(e);
    gs_system_book_damping(s);
    if (err == GS_OK) /* numerics.contact closure_energy: every rank alike */
        gs_step_contact_return(s, e->sol);
    double cpu_end = cpu_lap(e);
    tm->sync += gs_now() - t0;
    tm->cpu_work += e->cpu_own;
    tm->cpu_path += e->cpu_ph[0] + e->cpu_ph[1] + cpu_solve + e->cpu_ph[2] + cpu_end;
    return err;
}

static gs_err dist_substep_cb(void *e)
{
    return dist_substep(e);
}

/* One step of h: one substep, or several with numerics.adaptive. */
static gs_err dist_step(gs_engine *e)
{
    gs_system *s = e->sys;
    GS_TRY(gs_step_whole(s, dist_substep_cb, e));
    int fe = s->scene->fields_every;
    if (fe > 0 && s->step % fe == 0) {
        double t0 = gs_now();
        gather_fields(e);
        e->timing.sync += gs_now() - t0;
    }
    e->timing.steps++;
    return GS_OK;
}

void gs_engine_timing(const gs_engine *e, gs_step_timing *out)
{
    *out = e->timing;
}

/* The replicated rigid state from rank 0 to the others after a chunk
 * stepped on rank 0 alone (collective). */
static void sync_solo(gs_engine *e)
{
    gs_system *s = e->sys;
    size_t n = (size_t)s->n_coords, k = 2 * n;
    double *b = malloc((k + 6) * sizeof(double));
    if (!b)
        MPI_Abort(e->comm, 3); /* a collective cannot be left half-way */
    if (e->rank == 0) {
        memcpy(b, s->q, n * sizeof(double));
        memcpy(b + n, s->w, n * sizeof(double));
        b[k] = s->time, b[k + 1] = (double)s->step, b[k + 2] = s->work_in;
        b[k + 3] = s->dissipated, b[k + 4] = (double)s->level, b[k + 5] = s->h_sub;
    }
    /* The others wait the whole chunk here: poll with short sleeps rather
     * than spin in a blocking broadcast (TOOLCHAIN.md gotcha 3). */
    MPI_Request rq;
    MPI_Ibcast(b, (int)(k + 6), MPI_DOUBLE, 0, e->comm, &rq);
    if (e->rank == 0)
        MPI_Wait(&rq, MPI_STATUS_IGNORE);
    else
        gs_mpi_wait_idle(&rq, 0.0);
    if (e->rank != 0) {
        memcpy(s->q, b, n * sizeof(double));
        memcpy(s->w, b + n, n * sizeof(double));
        s->time = b[k], s->step = (int64_t)b[k + 1], s->work_in = b[k + 2];
        s->dissipated = b[k + 3], s->level = (int)b[k + 4], s->h_sub = b[k + 5];
        gs_model_view v;
        gs_system_view(s, &v);
        for (int i = 0; i < s->n_meshes; i++)
            s->meshes[i].deflection = gs_gmesh_s(&v, &s->meshes[i], s->q) - s->meshes[i].s_ref;
    }
    free(b);
}

static gs_err run_steps(gs_engine *e, int64_t n, int64_t *done, bool sched)
{
    int64_t i = 0;
    gs_err err = GS_OK;
    /* A train without bodies of their own state (rigid and lumped) has
     * nothing worth distributing: its records are a few flops per body, far
     * less than the two collectives per step that would gather them. Rank 0
     * steps alone (assembling every body's records, as one process does)
     * and the others take its state once per chunk. */
    e->solo = e->size > 1 && !gs_system_has_body_state(e->sys);
    e->cpu_on = e->cpu_timing && gs_system_has_body_state(e->sys);
    /* The energy schedule decides the same on every rank (rank 0's flag,
     * the scene, the step count). */
    sched = sched && !e->solo && gs_system_has_body_state(e->sys);
    bool stale = false;
    if (e->solo && e->rank != 0) {
        sync_solo(e);
        if (done)
            *done = n;
        return GS_OK;
    }
    int64_t poll_stride = n / 64 > 1 ? n / 64 : 1;
    for (; i < n; i++) {
        if (e->solo) {
            err = gs_step_serial(e->sys);
            e->timing.steps++;
        } else {
            e->sys->energy_deferred = sched && !energy_due(e->sys, i + 1 == n);
            stale = stale || e->sys->energy_deferred;
            err = dist_step(e);
            if (err == GS_OK && !e->sys->energy_deferred)
                stale = false;
        }
        if (err != GS_OK)
            break;
        /* The hook (telemetry, recording) runs on rank 0 only and does not
         * stop a step half-way: chunks end at the step count rank 0 chose. */
        if (e->rank == 0 && e->hook)
            e->hook(e, e->hook_user);
        /* Between steps a service answers within a chunk. A chunk is sized
         * to about 10 ms of work: 64 polls in it are plenty (the service
         * reads its socket every 5 ms at most) and spare cheap steps a clock
         * read each. */
        if (e->rank == 0 && (i + 1) % poll_stride == 0)
            gs_poll();
    }
    if (e->solo)
        sync_solo(e);
    e->sys->energy_deferred = false;
    if (stale) /* a step failed after deferred ones: every rank alike */
        err = refresh_energy(e, err);
    if (done)
        *done = i;
    return err;
}

/* Snapshot format: magic, n_coords, n_meshes, step, time, work_in,
 * dissipated, energy0, q[n], w[n], per mesh force, contacts, rows,
 * penetration (the last step's, reported by telemetry), impacts and their
 * energy loss, friction loss, contact work (since load), n_states (as a double), the body states (elastic:
 * q then w of each FE body, in body order), then scene JSON and loads JSON,
 * NUL-terminated, then (only for a scene that gave accuracy targets) the
 * fidelity choice JSON, NUL-terminated. */
#define SNAP_MAGIC 0x39534753u /* "GSS9" */
#define SNAP_HEAD_DOUBLES 5 /* time, work_in, dissipated, energy0, adaptive level */
#define MESH_SNAP 9 /* doubles per mesh */

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
    if (gs_system_has_body_state(s)) {
        gs_diag d;
        GS_TRY(gs_engine_run(e, GS_OP_SNAPSHOT, NULL, 0, &d, NULL));
    }
    size_t ns = gs_system_has_body_state(s) ? e->n_states : 0;
    char *lj = loads_json(s->scene);
    if (!lj)
        return GS_ENOMEM;
    size_t n = (size_t)s->n_coords, nm = (size_t)s->n_meshes;
    size_t sl = strlen(s->scene->json) + 1, ll = strlen(lj) + 1;
    size_t cl = s->scene->fidelity_choice ? strlen(s->scene->fidelity_choice) + 1 : 0;
    size_t total = 3 * sizeof(uint32_t) + sizeof(int64_t) + SNAP_HEAD_DOUBLES * sizeof(double) +
                   (2 * n + MESH_SNAP * nm + 1 + ns) * sizeof(double) + sl + ll + cl;
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
    double level = (double)s->level;
    PUT(&level, sizeof(double));
    PUT(s->q, n * sizeof(double));
    PUT(s->w, n * sizeof(double));
    for (size_t i = 0; i < nm; i++) {
        const gs_gmesh_rt *m = &s->meshes[i];
        double ct[MESH_SNAP] = {m->force, (double)m->n_active, (double)m->n_rows, m->penetration,
                                (double)m->impacts, m->impact_loss, m->friction_loss,
                                m->contact_work, m->nf_energy};
        PUT(ct, sizeof ct);
    }
    double nsd = (double)ns;
    PUT(&nsd, sizeof nsd);
    if (ns)
        PUT(e->states, ns * sizeof(double));
    PUT(s->scene->json, sl);
    PUT(lj, ll);
    if (cl)
        PUT(s->scene->fidelity_choice, cl);
#undef PUT
    free(lj);
    *bytes = b;
    *len = total;
    return GS_OK;
}

static double get_double(const char *p, size_t i)
{
    double v;
    memcpy(&v, p + i * sizeof v, sizeof v);
    return v;
}

/* A whole number in [0, max] held in a double. */
static bool is_count(double v, double max) { return v >= 0 && v <= max && v == floor(v); }

static gs_err finite_run(const char *p, size_t n, const char *what, gs_diag *d)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(get_double(p, i)))
            return gs_diag_set(d, GS_ERANGE, "path", "the checkpoint's %s[%zu] is not a finite number", what, i);
    return GS_OK;
}

gs_err gs_engine_snapshot_check(const char *b, size_t len, gs_snapshot_view *v, gs_diag *d)
{
    memset(v, 0, sizeof *v);
    size_t head = 3 * sizeof(uint32_t) + sizeof(int64_t) + SNAP_HEAD_DOUBLES * sizeof(double);
    if (len < head)
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint is truncated");
    uint32_t magic, nc, nm;
    const char *p = b;
    memcpy(&magic, p, sizeof magic);
    memcpy(&nc, p + 4, sizeof nc);
    memcpy(&nm, p + 8, sizeof nm);
    p += 12;
    if (magic != SNAP_MAGIC)
        return gs_diag_set(d, GS_EIO, "path", "not a gearsim checkpoint");
    if (nc > (1u << 20) || nm > (1u << 20) ||
        len < head + (2 * (size_t)nc + MESH_SNAP * (size_t)nm + 1) * sizeof(double) + 2)
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint is truncated or declares %u coordinates and %u "
                           "meshes", nc, nm);
    memcpy(&v->step, p, 8), p += 8;
    double head_d[SNAP_HEAD_DOUBLES];
    memcpy(head_d, p, sizeof head_d), p += sizeof head_d;
    v->time = head_d[0], v->work_in = head_d[1], v->dissipated = head_d[2], v->energy0 = head_d[3];
    static const char *const head_names[] = {"time", "work_in", "dissipated", "energy0", "adaptive level"};
    for (int i = 0; i < SNAP_HEAD_DOUBLES; i++)
        if (!isfinite(head_d[i]))
            return gs_diag_set(d, GS_ERANGE, "path", "the checkpoint's %s is not a finite number", head_names[i]);
    if (v->step < 0 || v->step > GS_CHECKPOINT_MAX_STEP)
        return gs_diag_set(d, GS_ERANGE, "path", "the checkpoint's step count %lld is out of range [0, 2^53]",
                           (long long)v->step);
    if (v->time < 0)
        return gs_diag_set(d, GS_ERANGE, "path", "the checkpoint's time %g is negative", v->time);
    if (!is_count(head_d[4], 30))
        return gs_diag_set(d, GS_ERANGE, "path", "the checkpoint's adaptive level %g is not a level", head_d[4]);
    v->level = (int)head_d[4];
    v->n_coords = nc;
    v->n_meshes = nm;
    v->q = p;
    v->meshes = p + 2 * (size_t)nc * sizeof(double);
    GS_TRY(finite_run(v->q, 2 * (size_t)nc, "coordinates and speeds", d));
    for (size_t i = 0; i < nm; i++) {
        const char *m = v->meshes + MESH_SNAP * i * sizeof(double);
        GS_TRY(finite_run(m, MESH_SNAP, "mesh counters", d));
        if (!is_count(get_double(m, 1), 1 << 30) || !is_count(get_double(m, 2), 1 << 30) ||
            !is_count(get_double(m, 4), (double)GS_CHECKPOINT_MAX_STEP))
            return gs_diag_set(d, GS_ERANGE, "path", "the checkpoint's counters of mesh %zu are out of range", i);
        if (get_double(m, 8) < 0.0)
            return gs_diag_set(d, GS_ERANGE, "path", "the checkpoint's near-field spring energy of mesh %zu is "
                               "negative (%g J)", i, get_double(m, 8));
    }
    double nsd = get_double(v->meshes, MESH_SNAP * (size_t)nm);
    size_t avail = (len - head) / sizeof(double) - (2 * (size_t)nc + MESH_SNAP * (size_t)nm + 1);
    if (!is_count(nsd, (double)avail))
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint is truncated (%g body state values declared)", nsd);
    v->n_states = (size_t)nsd;
    v->states = v->meshes + (MESH_SNAP * (size_t)nm + 1) * sizeof(double);
    GS_TRY(finite_run(v->states, v->n_states, "body states", d));
    const char *scene = v->states + v->n_states * sizeof(double);
    const char *end = b + len;
    const char *lj = memchr(scene, '\0', (size_t)(end - scene));
    if (!lj || lj + 1 >= end || !memchr(lj + 1, '\0', (size_t)(end - lj - 1)))
        return gs_diag_set(d, GS_EIO, "path", "the checkpoint is truncated");
    lj++;
    const char *ch = lj + strlen(lj) + 1; /* the fidelity choice, when the scene gave targets */
    if (ch != end) {
        const char *z = memchr(ch, '\0', (size_t)(end - ch));
        if (!z || z + 1 != end)
            return gs_diag_set(d, GS_EIO, "path", "the checkpoint has %zu bytes after its end", (size_t)(end - ch));
        GS_TRY(gs_scene_check_fidelity_choice(ch, (size_t)(z - ch), d));
        v->choice = ch;
    }
    v->scene = scene;
    v->loads = lj;
    return GS_OK;
}

static gs_err restore(gs_engine *e, const char *b, size_t len, gs_diag *d)
{
    gs_snapshot_view sv;
    GS_TRY(gs_engine_snapshot_check(b, len, &sv, d));
    uint32_t nc = sv.n_coords, nm = sv.n_meshes;
    size_t ns = sv.n_states;
    const char *scene = sv.scene, *lj = sv.loads;
    gs_scene *sc;
    GS_TRY(gs_scene_parse(scene, strlen(scene), &sc, d));
    gs_err ce = sv.choice ? gs_scene_adopt_fidelity_choice(sc, sv.choice, d) : GS_OK;
    if (ce != GS_OK) {
        gs_scene_free(&sc);
        return ce;
    }
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
    if ((uint32_t)s->n_coords != nc || (uint32_t)s->n_meshes != nm ||
        (gs_system_has_body_state(s) ? states_size(s) : 0) != ns) {
        /* The message reads the system: write it before unloading. */
        gs_diag_set(d, GS_EIO, "path", "the checkpoint does not match its scene (%u coordinates, %u "
                    "meshes, %zu state values for a scene of %d, %d, %zu)", nc, nm, ns, s->n_coords,
                    s->n_meshes, gs_system_has_body_state(s) ? states_size(s) : 0);
        unload(e);
        return GS_EIO;
    }
    /* The clock follows the step count (time = step h, or within the step
     * when it was taken between substeps), the level the scene's range. */
    double t_lo = (double)sv.step * s->h, tol = 1e-9 * (t_lo + s->h);
    if (!(sv.time >= t_lo - tol && sv.time <= t_lo + s->h + tol) || sv.level > s->adapt_levels) {
        gs_diag_set(d, GS_ERANGE, "path", "the checkpoint's time %.17g s or adaptive level %d does not "
                    "match step %lld of its scene (time step %g s, %d levels)", sv.time, sv.level,
                    (long long)sv.step, s->h, s->adapt_levels);
        unload(e);
        return GS_ERANGE;
    }
    /* The near-field springs' energy: only on the meshes that have them. */
    for (uint32_t i = 0; i < nm; i++) {
        double enf = get_double(sv.meshes, MESH_SNAP * (size_t)i + 8);
        if (enf != 0.0 && !s->scene->meshes[s->meshes[i].index].nearfield) {
            gs_diag_set(d, GS_EIO, "path", "the checkpoint does not match its scene (near-field spring energy "
                        "%g J on mesh %u, which has no \"nearfield\")", enf, i);
            unload(e);
            return GS_EIO;
        }
    }
    gs_err lerr = GS_OK;
    for (int i = 0, off = 0; i < s->n_bodies; i++) {
        gs_body_rt *b = &s->bodies[i];
        if (!b->ops->state_size)
            continue;
        double *x = malloc(b->ops->state_size(b) * sizeof(double));
        if (!x) {
            lerr = GS_ENOMEM;
        } else {
            /* The payload is not aligned for doubles: copy out. */
            memcpy(x, sv.states + (size_t)off * sizeof(double),
                   b->ops->state_size(b) * sizeof(double));
            if (b->owner == e->rank) {
                gs_err le = b->ops->load(b, x);
                gs_model_view v;
                gs_system_view(s, &v);
                if (le == GS_OK)
                    b->ops->energy(&v, b, &b->T, &b->V);
                else if (lerr == GS_OK)
                    lerr = le;
            }
            free(x);
        }
        off += (int)b->ops->state_size(b);
    }
    lerr = sync_energy(e, lerr, 0.0);
    if (lerr != GS_OK) {
        unload(e);
        return gs_diag_set(d, lerr, "path", "the checkpoint's body states could not be restored");
    }
    memcpy(s->q, sv.q, nc * sizeof(double));
    memcpy(s->w, sv.q + nc * sizeof(double), nc * sizeof(double));
    s->step = sv.step;
    s->time = sv.time;
    s->work_in = sv.work_in;
    s->dissipated = sv.dissipated;
    s->energy0 = sv.energy0;
    s->level = sv.level;
    s->sub_ticks = 0;
    s->refined = false;
    s->h_sub = s->h / (double)((int64_t)1 << s->level);
    gs_model_view v;
    gs_system_view(s, &v);
    for (int i = 0; i < s->n_meshes; i++) {
        gs_gmesh_rt *m = &s->meshes[i];
        m->deflection = gs_gmesh_s(&v, m, s->q) - m->s_ref;
        double ct[MESH_SNAP];
        memcpy(ct, sv.meshes + MESH_SNAP * (size_t)i * sizeof(double), sizeof ct);
        m->force = ct[0];
        m->n_active = (int)ct[1];
        m->n_rows = (int)ct[2];
        m->penetration = ct[3];
        m->impacts = (int64_t)ct[4];
        m->impact_loss = ct[5];
        m->friction_loss = ct[6];
        m->contact_work = ct[7];
        m->nf_energy = ct[8];
    }
    s->contact_work = 0.0;
    for (int i = 0; i < s->n_meshes; i++)
        s->contact_work += s->meshes[i].contact_work;
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
        int64_t n[2]; /* count, rank 0's energy schedule (gs_engine_run adds it) */
        if (!e->sys || len != sizeof n)
            return GS_ESTATE;
        memcpy(n, payload, len);
        e->stepping = true;
        gs_err err = run_steps(e, n[0], done, n[1] != 0);
        e->stepping = false;
        return err;
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
    case GS_OP_SNAPSHOT:
        return gather_states(e);
    case GS_OP_SWEEP:
        /* Rank 0 coordinates the sweep from the service (gs_sweep_run_*). */
        return e->rank == 0 ? GS_OK : gs_sweep_serve(e->comm, payload, len);
    }
    return GS_EINVAL;
}

gs_err gs_engine_run(gs_engine *e, gs_op op, const void *payload, size_t len, gs_diag *d,
                     int64_t *done)
{
    int64_t st[2];
    if (op == GS_OP_STEP && len == sizeof st[0]) { /* the energy schedule travels with it */
        memcpy(st, payload, sizeof st[0]);
        st[1] = e->energy_sched;
        payload = st;
        len = sizeof st;
    }
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

void gs_mpi_wait_idle(MPI_Request *rq, double spin_s)
{
    int flag = 0;
    double t0 = gs_now();
    for (;;) {
        MPI_Test(rq, &flag, MPI_STATUS_IGNORE);
        if (flag)
            return;
        if (gs_now() - t0 >= spin_s) {
            struct timespec ts = {0, 500000};
            nanosleep(&ts, NULL);
        }
    }
}

gs_err gs_engine_serve(gs_engine *e)
{
    for (;;) {
        int64_t hdr[2];
        MPI_Request rq;
        MPI_Ibcast(hdr, 2, MPI_INT64_T, 0, e->comm, &rq);
        /* Spin briefly (a chunk of an advance follows quickly), then sleep. */
        gs_mpi_wait_idle(&rq, 0.005);
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
