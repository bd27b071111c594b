/* SPDX-License-Identifier: MIT
 * gearsim: the system (bodies, meshes, loads in joint coordinates) and the
 * energy-momentum midpoint step (METHOD.md sections 1, 2 and 7).
 *
 * The step is split so that it can be distributed (src/engine): every rank
 * fills the interface records of the bodies it owns, rank 0 solves the small
 * coupled problem, and every rank applies the increment. gs_step_serial()
 * runs the three parts in one process. Nothing here calls MPI. */
#ifndef GEARSIM_STEP_H
#define GEARSIM_STEP_H

#include "gearsim/models.h"
#include "gearsim/scene.h"
#include "gearsim/types.h"

typedef struct gs_system gs_system;

/* What crosses ranks in one step, identical on every rank (src/step/plan.c).
 * Body i offers n_dof[i] interface unknowns: its coordinate (when it has
 * one) then the x, y displacements of nodes[i][0 .. n_nodes[i]), the nodes
 * the contact search found near the other gear. Its record at rec_off[i]
 * holds the compliance block C (n_dof^2, column-major), the free increment
 * d0 (n_dof) and the current displacements of its nodes (2 n_nodes); the
 * solution gives back its interface forces f (n_dof) at sol_off[i]. */
typedef struct gs_step_plan {
    int *n_nodes;
    gs_index **nodes;
    size_t *cap_nodes;
    int *n_dof;
    size_t *rec_off, *sol_off;
    size_t rec_size, sol_size;
    /* Per body with a mesh: the search pass that last listed each mesh
     * node (duplicates are dropped as the nodes come), and its count. */
    uint32_t **seen;
    uint32_t pass;
} gs_step_plan;

/* Energy bookkeeping (J).
 * balance_residual = total - total0 - work_in + dissipated - contact_work. */
typedef struct gs_energy {
    double kinetic, potential, total, work_in, dissipated, balance_residual;
    double elastic;          /* the part of potential stored in elastic bodies */
    double contact_work;     /* work of the contact reactions (gap closure), booked */
} gs_energy;

struct gs_system {
    gs_scene *scene;         /* owned */
    int rank, nranks;
    int n_bodies, n_meshes, n_coords;
    gs_body_rt *bodies;
    gs_gmesh_rt *meshes;
    int n_eq;                /* equality rows of all meshes */
    bool smooth_contact;     /* lumped meshes close and open flanks with the continuous damper
                              * and the exact Jacobian (bearing joints or pin errors, whose
                              * coupled flanks need them; src/models/meshes.c) */
    int n_joints;            /* compliant supports (bearing joints) */
    gs_joint_rt *joints;
    double *eq_rows;         /* n_eq x n_coords */
    double *q, *w;           /* rigid coordinates and velocities (every rank holds all) */
    double time;
    int64_t step;            /* steps of h taken */
    double h;                /* the scene's time step */
    /* The scene's numerics, copied when the system is built (the step reads
     * these, not the scene): Newton's iteration limit and tolerance,
     * numerics.contact (gs_contact_scheme), numerics.adaptive's halvings and
     * penetration (m). */
    int max_newton;
    double newton_tol;
    int contact_scheme;
    int adapt_levels;
    double adapt_penetration;
    /* Adaptive step (scene numerics.adaptive): a step of h is taken as
     * substeps of h_sub = h / 2^level; sub_ticks counts the part of the
     * current step done, in units of h / 2^adapt_levels. Fixed step: level 0,
     * h_sub = h. */
    double h_sub;
    int level;
    int64_t sub_ticks;
    int64_t substeps;        /* substeps taken since the system was built */
    int64_t refinements;     /* substeps refused by the solve and taken again finer */
    bool refined;            /* a refinement happened in the current step of h */
    double work_in, dissipated, energy0;
    /* Set by the engine on steps whose energies nothing reads (its energy
     * schedule, gs_engine_set_energy_schedule): bodies of their own state
     * then skip them at the end of the step and report NaN; the engine
     * sums them from the state before anyone reads them. False (every
     * step) unless the engine sets it. */
    bool energy_deferred;
    double contact_work;     /* sum of the meshes' contact_work */
    double last_residual;    /* Newton residual of the last step */
    int last_iterations;
    char warning[256];       /* set at build time, e.g. projected initial speeds */
    double *work;            /* scratch owned by the solver */
    int n_contact;           /* contact meshes: the step is then a QP */
    gs_step_plan plan;
    void *solver;            /* rank 0 scratch of the contact solve (src/step/contact_step.c) */
    double *buf;             /* records and solution of gs_step_serial */
    size_t buf_cap;
    int *rec_mask, *rec_sel; /* two-phase record scratch (gs_step_select, gs_step_compliance) */
    double *rec_cbuf;        /* gs_step_serial's packed compliance blocks */
    size_t cap_mask, cap_sel, cap_cbuf;
    gs_diag diag;            /* why the last step was refused (gs_system_check); empty otherwise */
};

/* Build the system from a parsed scene; takes ownership of the scene.
 * rank/nranks decide which bodies this process owns (balanced by work). */
gs_err gs_system_new(gs_scene *scene, int rank, int nranks, gs_system **out, gs_diag *d);
void gs_system_free(gs_system **sys);

/* The view of the system its models see (gearsim/models.h), current: build
 * it again after the state, the time, the plan or the loads change. */
void gs_system_view(const gs_system *sys, gs_model_view *v);

/* Replace or add a load by its name (the system's scene owns it after). */
gs_err gs_system_set_load(gs_system *sys, const gs_scene_load *l);
gs_err gs_system_remove_load(gs_system *sys, const char *name);

/* Sum of the non-brake moments on body b at time t, and the brake coefficient. */
void gs_system_body_load(const gs_system *sys, int b, double t, double *moment, double *brake);

/* A substep is five calls; gs_step_serial() makes them in one process, for
 * as many substeps as a step of h takes (one unless numerics.adaptive).
 *
 *   gs_step_prepare   every rank: the contact search from the rigid state,
 *                     the plan (sizes of the records and the solution)
 *   gs_step_records   every rank: the records of its own bodies (zeros
 *                     elsewhere, so that a sum over ranks assembles them);
 *                     begins the bodies' own steps
 *   gs_step_solve     rank 0: from all records, the solution
 *   gs_step_apply     every rank: update the rigid state, finish the own
 *                     bodies' steps with their interface forces
 *   gs_step_advance   every rank: the time, the next substep; true at the
 *                     end of a step of h (gs_step_refine instead when the
 *                     solve answered GS_EREFINE)
 *
 * Two-phase record (bodies with interface_free and compliance, models.h:
 * the elastic gears): gs_step_records writes their free part only (d0,
 * node displacements); the free parts go to rank 0 (gs_step_free_pack),
 * rank 0 finds the step's rows and names the dofs whose compliance entries
 * the solve reads (gs_step_select, a mask over the plan dofs, bodies in
 * order), every rank takes that mask, the owners write those sub-blocks
 * (gs_step_compliance, packed k x k per two-phase body, zeros for the
 * others' so that a sum over ranks assembles them), and rank 0 places them
 * into its records (gs_step_compliance_unpack) before gs_step_solve. The
 * solution is bit for bit that of the whole blocks (docs/performance/index.md).
 *
 * Solution layout: dq (n_coords), the meshes' dissipation of the step, the
 * meshes' forces (n_meshes), per mesh the contact figures (n_active,
 * n_rows, penetration, friction loss, contact work), then the bodies' interface forces
 * (plan.sol_off). */
gs_err gs_step_prepare(gs_system *sys);
/* After gs_step_apply on every rank: advance the time by the substep just
 * taken and choose the next substep (numerics.adaptive); true when a whole
 * step of h is complete (then sys->step has grown by one). */
bool gs_step_advance(gs_system *sys);
/* When a solve answered GS_EREFINE (adaptive step): take the substep again
 * at half the size (every rank; the bodies' begun steps start again). */
void gs_step_refine(gs_system *sys);
/* One whole step of h: substep(ctx) (prepare to apply, on every rank) until
 * gs_step_advance says the step is complete, taken again finer each time it
 * answers GS_EREFINE; its other errors end the step. */
gs_err gs_step_whole(gs_system *sys, gs_err (*substep)(void *ctx), void *ctx);
void gs_step_records(gs_system *sys, double *rec);
/* True when some body with interface dofs records in two phases. */
bool gs_step_two_phase(const gs_system *sys);
/* Phase one: its size in doubles, and the records' free parts into buf
 * (or, with unpack, from buf into the records). */
size_t gs_step_free_size(const gs_system *sys);
void gs_step_free_pack(const gs_system *sys, double *rec, double *buf, bool unpack);
/* The mask: its size in ints (the plan dofs and one spare slot, free for
 * the caller), the system's scratch for it (NULL when out of memory). */
size_t gs_step_mask_size(const gs_system *sys);
int *gs_step_mask(gs_system *sys);
/* Rank 0, after phase one: the rows of the step and the mask. */
gs_err gs_step_select(gs_system *sys, const double *rec, int *mask);
/* Phase two: its size in doubles for that mask, the own bodies' packed
 * sub-blocks into buf, and (rank 0) from buf into the records. */
size_t gs_step_compliance_size(const gs_system *sys, const int *mask);
gs_err gs_step_compliance(gs_system *sys, const int *mask, double *buf);
gs_err gs_step_compliance_unpack(gs_system *sys, const int *mask, const double *buf, double *rec);
gs_err gs_step_solve(gs_system *sys, const double *rec, double *sol);
gs_err gs_step_apply(gs_system *sys, const double *sol);
gs_err gs_step_serial(gs_system *sys);
/* Offsets in the solution. Per mesh contact figures: constraints with a
 * positive force, constraints imposed, deepest penetration, friction loss of
 * the step, work of the contact reactions in the step, and (closure) the
 * reactions' moments on the coordinates of the mesh's gears 0 and 1, the energy in
 * its near-field springs at the step's end ("nearfield"). */
#define GS_SOL_CONTACT 8
static inline size_t gs_sol_mesh_force(const gs_system *s, int m) { return (size_t)(s->n_coords + 1 + m); }
static inline size_t gs_sol_mesh_contact(const gs_system *s, int m)
{
    return (size_t)(s->n_coords + 1 + s->n_meshes + GS_SOL_CONTACT * m);
}

/* Limits of the scene's numerics against the current state (docs/explanation/stability.md):
 *  - the rigid state and the mesh forces are finite;
 *  - contact meshes: the approach speed along the line of action times h,
 *    and the deepest penetration of the last step, stay within 0.1 module
 *    (the contact search's approach band: a step that carries the teeth
 *    deeper than that no longer resolves the contact);
 *  - lumped meshes with a stiffness wave (rectangular, calibrated): at most
 *    half a tooth-mesh cycle per step (beyond it the wave is aliased).
 * Returns GS_OK (d cleared) or GS_ERANGE with d naming the field to change
 * (numerics.time_step, or meshes[i] for a non-finite force) and by how much.
 * gs_system_new checks the initial state (a priori); every step checks the
 * state it reached, into sys->diag. Not collective: every rank holds the
 * rigid state and the mesh figures, so every rank reaches the same answer. */
gs_err gs_system_check(const gs_system *sys, gs_diag *d);

/* Energies of the current state. Bodies with their own state (elastic)
 * contribute what their owner last reported in b->T, b->V: after a step on
 * several ranks, call gs_system_sync_energy (collective in the engine) first. */
void gs_system_energy(const gs_system *sys, gs_energy *e);
/* Owner side of the energy report: b->T, b->V, b->work_s and b->D_step of
 * this rank's bodies with own state into buf (GS_ENERGY_REPORT per body,
 * zeros elsewhere), for a sum over ranks. */
#define GS_ENERGY_REPORT 5
void gs_system_energy_report(const gs_system *sys, double *buf);
/* Adopt the summed report on every rank. */
void gs_system_energy_adopt(gs_system *sys, const double *buf);
/* Book the bodies' own damping of the last step (b->D_step, in body order,
 * so that every rank sums identically) as dissipated, after the step's
 * energy report has been adopted. */
void gs_system_book_damping(gs_system *sys);
/* numerics.contact "closure_energy" (docs/explanation/contact.md): after the step's
 * energy report has been adopted, give the work of each contact mesh's
 * reactions in the step (sol's contact figures) back as a velocity update
 * of its gears' rotations along the reactions' moments (an impulse pair
 * along the contact normals), exactly, and book the update's energy in
 * contact_work beside that work, carrying what cannot be given back yet
 * to the next steps. Every rank, same result; no-op for the other
 * schemes. Returns the contact work still booked (round-off but when
 * removing energy is asked of a pair that cannot give it yet). */
double gs_step_contact_return(gs_system *sys, const double *sol);
/* The contact rows of the last step's final solve (serial, or rank 0 of a
 * distributed step; for diagnostics such as tests/bench/corner_stats):
 * gs_step_contact_rows gives their number (0 before the first contact
 * step), gs_step_contact_row row i as evaluated at the step's start (gap,
 * gradients, nodes), its contact mesh and its multiplier (the normal force
 * is lambda |dg/dx| of the slave), NULL for i out of range. Valid until the
 * next step. */
struct gs_contact_row;
int gs_step_contact_rows(const gs_system *sys);
const struct gs_contact_row *gs_step_contact_row(const gs_system *sys, int i, int *mesh, double *lambda);
/* The flank friction force on the slave of row i of the last step's final
 * solve, along t = (-n_y, n_x), n the direction of the slave's gap gradient
 * (gap.grad[0..1]); the master carries the reaction. 0 without friction or
 * for i out of range. Serial or rank 0, valid until the next step. */
double gs_step_contact_friction(const gs_system *sys, int i);
/* True when some body keeps state of its own (elastic): then energies and
 * snapshots need the owners. */
bool gs_system_has_body_state(const gs_system *sys);
double gs_system_rpm(const gs_system *sys, int body);
/* Planet load sharing: for each planet meshing a sun (at most max), its
 * body index and its share of the sun's transmitted force, normalised so
 * that equal sharing is 1 for every planet (force of its sun mesh in the
 * last step times the number of planets over their sum). Returns the count. */
int gs_system_planet_shares(const gs_system *sys, int *planet, double *share, int max);
/* Axis position (scene frame, m) and rotation (rad) of a body now. */
void gs_system_body_pose(const gs_system *sys, int body, double c[2], double *theta);
double gs_system_angle(const gs_system *sys, int body);
double gs_system_omega(const gs_system *sys, int body);

#endif
