/* SPDX-License-Identifier: MIT
 * gearsim: the engine, replicated over MPI ranks (src/engine).
 *
 * Every state change is an operation that rank 0 broadcasts and every rank
 * executes in the same order: load, unload, step, set/remove load, restore,
 * shutdown. Bodies are spread over ranks (gs_system ownership); per step each
 * rank contributes the interface records of its bodies, rank 0 solves the
 * coupled problem, and the increment is broadcast back. Idle workers wait
 * for the next operation with a non-blocking broadcast and short sleeps, so
 * they do not burn a core (TOOLCHAIN.md gotcha 3).
 *
 * Collective: gs_engine_new/free, gs_engine_run (rank 0) paired with
 * gs_engine_serve (other ranks). */
#ifndef GEARSIM_ENGINE_H
#define GEARSIM_ENGINE_H

#include <mpi.h>

#include "gearsim/step.h"

typedef enum {
    GS_OP_NONE = 0,
    GS_OP_LOAD,        /* payload: scene JSON */
    GS_OP_UNLOAD,
    GS_OP_STEP,        /* payload: int64 number of steps */
    GS_OP_SET_LOAD,    /* payload: load JSON object */
    GS_OP_REMOVE_LOAD, /* payload: load name */
    GS_OP_RESTORE,     /* payload: gs_engine_snapshot serialisation */
    GS_OP_SHUTDOWN,
    GS_OP_SNAPSHOT,    /* internal: owners send body states to rank 0 */
    GS_OP_SWEEP,       /* payload: a sweep (gearsim/sweep.h); other ranks run gs_sweep_serve */
} gs_op;

typedef struct gs_engine gs_engine;

/* Where a rank's time goes, summed over the steps since load (s). On rank 0:
 * prepare = contact search and plan; records = its bodies' condensation
 * (free-motion solves, compliance blocks); reduce and bcast = the two
 * collectives of a step (waiting for the slowest owner included); solve =
 * the coupled problem (Newton or QP); apply = back-substitution and the end
 * of its bodies' steps; sync = energy reports and field gathering.
 * CPU time of the thread, summed over the substeps: cpu_work = this rank's
 * outside the step's collectives; cpu_path (rank 0) = the step's critical
 * path, the sum over its phases of the slowest rank's CPU time in the
 * parallel ones (search and records, compliance sub-blocks, apply) and
 * rank 0's in the serial ones (selection, solve): the time a step would
 * take with a core per rank and instant collectives, which neither
 * descheduling by other jobs nor spinning in a collective inflates (timed
 * for trains with bodies of their own state only, and only with
 * gs_engine_set_cpu_timing on; zero otherwise). */
typedef struct gs_step_timing {
    double prepare, records, reduce, solve, bcast, apply, sync;
    int64_t steps;
    double cpu_work, cpu_path;
} gs_step_timing;

/* Called on rank 0 after every step of a GS_OP_STEP; return false to stop
 * the chunk early (cancel). */
typedef bool (*gs_engine_step_hook)(gs_engine *e, void *user);

gs_err gs_engine_new(MPI_Comm comm, gs_engine **out);
void gs_engine_free(gs_engine **e);
int gs_engine_rank(const gs_engine *e);
int gs_engine_size(const gs_engine *e);
/* True while a chunk of steps runs (a poll from within it sees bodies
 * part-way through a step, or energies not yet summed). */
bool gs_engine_stepping(const gs_engine *e);
gs_system *gs_engine_system(gs_engine *e);   /* NULL when nothing is loaded */
MPI_Comm gs_engine_comm(const gs_engine *e);
void gs_engine_set_hook(gs_engine *e, gs_engine_step_hook hook, void *user);
/* Energy schedule (set on rank 0, the driver; it travels with each
 * GS_OP_STEP to the other ranks). Off (default): the bodies of their own
 * state (elastic gears) sum their kinetic and strain energies at the end of
 * every step. On: only at the end of steps whose number is a multiple of
 * the scene's outputs.telemetry_every or record_every (the steps the
 * daemon's hook publishes or records) and of the last step of each
 * GS_OP_STEP, so that whatever reads gs_system_energy between operations
 * sees the current values; numerics.contact "closure_energy" books against
 * them and keeps them every step. The values are those of every step bit
 * for bit (they are functions of the state); the steps in between skip a
 * third of the end-of-step pass's memory traffic (the mass matrix). A hook
 * that reads the energies on other steps must leave it off. */
void gs_engine_set_energy_schedule(gs_engine *e, bool on);
/* Time the step's phases in thread CPU (gs_step_timing cpu_work and
 * cpu_path: a clock read, a system call, per phase and substep). Off by
 * default; set on every rank that should time (the benchmarks do). */
void gs_engine_set_cpu_timing(gs_engine *e, bool on);

/* Rank 0: broadcast an operation and execute it here too. Errors name the
 * field in d. For GS_OP_STEP, *steps_done (may be NULL) receives the number
 * of steps taken. */
gs_err gs_engine_run(gs_engine *e, gs_op op, const void *payload, size_t len, gs_diag *d,
                     int64_t *steps_done);
/* Wait for a non-blocking MPI request without burning a core: test it,
 * spinning for spin_s seconds, then with sleeps of 0.5 ms (TOOLCHAIN.md
 * gotcha 3). */
void gs_mpi_wait_idle(MPI_Request *rq, double spin_s);
/* Other ranks: execute operations until GS_OP_SHUTDOWN. */
gs_err gs_engine_serve(gs_engine *e);

/* Full state as bytes (rank 0, owned by the caller), restorable with
 * GS_OP_RESTORE so that the run continues bit for bit. With bodies that keep
 * state of their own (elastic) on other ranks this broadcasts an operation:
 * call it only where gs_engine_run may be called. */
gs_err gs_engine_snapshot(gs_engine *e, char **bytes, size_t *len);

/* A snapshot's bytes read back (from a checkpoint file: input like a
 * request): the layout, every count within the bytes, every value finite,
 * the step count in [0, GS_CHECKPOINT_MAX_STEP], the level a level, the
 * scene and loads texts NUL-terminated, then either nothing or the scene's
 * fidelity choice (gs_scene_check_fidelity_choice) and nothing after it. Pointers in
 * the view are into b (not aligned for doubles). GS_OK, or an error with a
 * message naming what is wrong. GS_OP_RESTORE checks the rest against the
 * scene (sizes, time against the step count, the level's range). */
typedef struct gs_snapshot_view {
    int64_t step;
    double time, work_in, dissipated, energy0;
    int level;
    uint32_t n_coords, n_meshes;
    size_t n_states;
    const char *q;      /* 2 n_coords doubles: coordinates then speeds */
    const char *meshes; /* 9 doubles per mesh */
    const char *states; /* n_states doubles */
    const char *scene;  /* the scene's JSON */
    const char *loads;  /* the loads in force, a JSON array */
    const char *choice; /* gs_scene.fidelity_choice, or NULL (a scene without targets) */
} gs_snapshot_view;
gs_err gs_engine_snapshot_check(const char *b, size_t len, gs_snapshot_view *v, gs_diag *d);

/* This rank's timing breakdown since load. */
void gs_engine_timing(const gs_engine *e, gs_step_timing *out);

/* Rank 0: the field snapshot of body `body` gathered after the current step
 * (u: 2 n nodal displacements, body frame, then vm: n nodal von Mises
 * stresses), or NULL when the scene records no fields or this step has none. */
const double *gs_engine_fields(const gs_engine *e, int body);

#endif
