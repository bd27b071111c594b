/* SPDX-License-Identifier: MIT
 * gearsim: the system (bodies, meshes, loads in joint coordinates) and the
 * energy-momentum midpoint step (METHOD.md sections 1, 2 and 7).
 *
 * The step is split so that it can be distributed (src/dist): every rank
 * fills the interface records of the bodies it owns, rank 0 solves the small
 * coupled problem, and every rank applies the increment. gs_step_serial()
 * runs the three parts in one process. Nothing here calls MPI. */
#ifndef GEARSIM_STEP_H
#define GEARSIM_STEP_H

#include "gearsim/models.h"
#include "gearsim/scene.h"
#include "gearsim/types.h"

struct gs_body_rt {
    int index;               /* body index in the scene */
    int coord;               /* rigid coordinate index, -1 when held */
    int owner;               /* rank that owns the body */
    double inertia_eff;      /* I + sum m d^2 of planets for a carrier */
    const gs_body_ops *ops;
    void *model;             /* model data (elastic: FE body) */
};

struct gs_gmesh_rt {
    int index;               /* mesh index in the scene */
    const gs_gmesh_ops *ops;
    double *a;               /* n_coords: line-of-action displacement s = a . q (m/rad) */
    double *c;               /* n_coords: mesh phase (cycles) phi = c . q */
    double s_ref;            /* s at the initial state: zero deflection */
    double contact_ratio;
    double k_single, k_double, damping, half_backlash;
    double transition;       /* width of the single/double stiffness change, fraction of a cycle */
    double force;            /* last step's force along the line of action, N */
    double deflection;       /* s - s_ref at the end of the last step, m */
};

/* Energy bookkeeping (J). balance_residual = total - total0 - work_in + dissipated. */
typedef struct gs_energy {
    double kinetic, potential, total, work_in, dissipated, balance_residual;
} gs_energy;

struct gs_system {
    gs_scene *scene;         /* owned */
    int rank, nranks;
    int n_bodies, n_meshes, n_coords;
    gs_body_rt *bodies;
    gs_gmesh_rt *meshes;
    int n_eq;                /* equality rows of all meshes */
    double *eq_rows;         /* n_eq x n_coords */
    double *q, *w;           /* rigid coordinates and velocities (every rank holds all) */
    double time;
    int64_t step;
    double h;
    double work_in, dissipated, energy0;
    double last_residual;    /* Newton residual of the last step */
    int last_iterations;
    char warning[256];       /* set at build time, e.g. projected initial speeds */
    double *work;            /* scratch owned by the solver */
};

/* Build the system from a parsed scene; takes ownership of the scene.
 * rank/nranks decide which bodies this process owns (balanced by work). */
gs_err gs_system_new(gs_scene *scene, int rank, int nranks, gs_system **out, gs_diag *d);
void gs_system_free(gs_system **sys);

/* Replace or add a load by its name (the system's scene owns it after). */
gs_err gs_system_set_load(gs_system *sys, const gs_scene_load *l);
gs_err gs_system_remove_load(gs_system *sys, const char *name);

/* Sum of the non-brake moments on body b at time t, and the brake coefficient. */
void gs_system_body_load(const gs_system *sys, int b, double t, double *moment, double *brake);

/* Records: 2 doubles (H, rhs) per body, zero for bodies not owned by this rank. */
void gs_step_records(const gs_system *sys, double *rec);
/* Solve on rank 0: from all records, the increment dq (n_coords) plus, at
 * dq[n_coords], the mesh dissipation of the step and at dq[n_coords+1+m] the
 * force of mesh m. Size of dq: gs_step_solution_size(). */
gs_err gs_step_solve(gs_system *sys, const double *rec, double *dq);
int gs_step_solution_size(const gs_system *sys);
/* Apply on every rank: update q, w, time, step, work and dissipation. */
void gs_step_apply(gs_system *sys, const double *dq);
/* One step in one process. */
gs_err gs_step_serial(gs_system *sys);

/* Energies of the current state; body energies from this rank's bodies only
 * when `own_only` (for a reduction), else from all. */
void gs_system_energy(const gs_system *sys, gs_energy *e);
double gs_system_rpm(const gs_system *sys, int body);
double gs_system_angle(const gs_system *sys, int body);
double gs_system_omega(const gs_system *sys, int body);

#endif
