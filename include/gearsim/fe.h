/* SPDX-License-Identifier: MIT
 * gearsim: linear finite elements of an elastic body in its material frame
 * (METHOD.md sections 1, 2 and 4). Owned by the fe module; the material
 * struct is the contract with the scene module.
 *
 * Two objects:
 *
 *   gs_fe_model  the constant matrices of one body shape: CST stiffness K and
 *                consistent mass M of the elastic part (fixed nodes
 *                eliminated), the angular coupling vector s, the inertias.
 *                Immutable after creation; several bodies (identical
 *                planets) may share one model.
 *   gs_fe_body   the state (q, w) of one body and everything that depends on
 *                the time step h: the Cholesky factor of the step matrix
 *                A = 2/h^2 M + 1/2 K (METHOD.md section 2), the bordered
 *                (Schur) treatment of theta, the per-node cache of compliance
 *                columns used by the condensed contact step (section 4).
 *
 * Body coordinates. q = (u_0 .. u_{ne-1}, theta): the ne elastic unknowns are
 * the x and y displacements of the nodes that are not fixed, in node order
 * (gs_fe_model_dof gives the index), in the body frame; theta is last. w is
 * the matching velocity vector. Interface dofs (condensation) are named in
 * mesh numbering with gs_fe_dof_node(node, comp) or GS_FE_DOF_THETA.
 *
 * Threads and MPI: no function here is collective. A model may be read by
 * several threads at once; a body must be used by one thread at a time.
 */
#ifndef GEARSIM_FE_H
#define GEARSIM_FE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "gearsim/mesh.h"
#include "gearsim/types.h"

typedef enum { GS_PLANE_STRESS = 0, GS_PLANE_STRAIN = 1 } gs_plane;

/* A helical gear whose material does not give the plane state is in plane
 * strain when its face is at least this many normal modules wide, else in
 * plane stress (a spur gear: plane stress). */
#define GS_HELICAL_STRAIN_FACE 5.0

typedef struct gs_material {
    double youngs_pa;   /* E, default 210e9 (steel) */
    double poisson;     /* nu, default 0.3 */
    double density;     /* rho kg/m^3, default 7850 */
    gs_plane plane;     /* default plane stress with the face width as thickness (a wide helical
                         * gear: plane strain, GS_HELICAL_STRAIN_FACE) */
    double damping_s;   /* beta of stiffness-proportional damping D = beta K, s; default 0 */
    double damping_m;   /* alpha of mass-proportional damping D = alpha M of the elastic
                         * unknowns (not the rigid rotation), 1/s; default 0 */
} gs_material;

static inline gs_material gs_material_steel(void)
{
    gs_material m = {210e9, 0.3, 7850.0, GS_PLANE_STRESS, 0.0, 0.0};
    return m;
}

/* ------------------------------------------------------------------------ */
/* Interface dof names (mesh numbering)                                      */
/* ------------------------------------------------------------------------ */

/* The rotation theta of the body. */
#define GS_FE_DOF_THETA ((gs_index)-1)

/* Displacement component comp (0 = x, 1 = y, body frame) of mesh node `node`. */
static inline gs_index gs_fe_dof_node(gs_index node, int comp)
{
    return 2 * node + (gs_index)(comp != 0);
}

/* ------------------------------------------------------------------------ */
/* Model                                                                     */
/* ------------------------------------------------------------------------ */

typedef struct gs_fe_model gs_fe_model;

typedef struct gs_fe_model_info {
    gs_index n_nodes;          /* mesh nodes */
    gs_index n_tris;           /* elements */
    gs_index n_free_nodes;     /* nodes not fixed */
    gs_index n_elastic;        /* ne = 2 * n_free_nodes: elastic unknowns */
    gs_index nnz;              /* entries of the upper triangle of K (and of M, same pattern) */
    double area_m2;            /* area of the elastic part */
    double mass_kg;            /* rho * t * area */
    double centroid[2];        /* centre of mass of the elastic part, body frame */
    double inertia_elastic;    /* integral rho |X|^2 over the elastic part, kg m^2 */
    double inertia_core;       /* as given to gs_fe_model_new */
    double inertia_total;      /* I of METHOD.md section 1: elastic + core */
} gs_fe_model_info;

/* Build the model of the elastic part meshed by `mesh` (linear triangles,
 * constant strain), with material `mat` (plane stress or plane strain), the
 * thickness (face width) thickness_m, and the polar inertia of the rigid core
 * core_inertia (kg m^2, >= 0) that is added to I.
 * The mesh is only read: the model copies what it needs, so the mesh may be
 * freed afterwards. *out receives a new model owned by the caller
 * (gs_fe_model_free).
 * Errors: GS_EINVAL (NULL pointers, non-positive or non-finite E, rho,
 * thickness, nu outside (-1, 0.5), negative core inertia, node index out of
 * range), GS_EGEOMETRY (an element with zero or negative area, i.e. not
 * counter-clockwise, or a node that is neither fixed nor in any element),
 * GS_ESINGULAR (the mass matrix of the body, theta
 * included, is not positive definite: no fixed node and no core inertia),
 * GS_ENOMEM. */
gs_err gs_fe_model_new(const gs_mesh *mesh, const gs_material *mat, double thickness_m,
                       double core_inertia, gs_fe_model **out);

/* Free a model; safe on NULL; sets *m = NULL. Bodies using it must be freed
 * first. */
void gs_fe_model_free(gs_fe_model **m);

/* Sizes and mass properties. */
void gs_fe_model_get_info(const gs_fe_model *m, gs_fe_model_info *info);

/* Index in q of displacement component comp (0 = x, 1 = y) of mesh node
 * `node`, or -1 if the node is fixed or out of range. */
gs_index gs_fe_model_dof(const gs_fe_model *m, gs_index node, int comp);

/* Dense copies of the body matrices in q order, theta last, for checks on
 * small meshes: K and M are (ne+1) x (ne+1), column-major, caller-allocated;
 * K has a zero theta row and column, M is the full mass matrix with the
 * coupling s and the inertia I (METHOD.md section 1). Either may be NULL.
 * Errors: GS_EINVAL, GS_ETOOBIG (ne + 1 > 20000). */
gs_err gs_fe_model_dense(const gs_fe_model *m, double *K, double *M);

/* The coupling vector s (ne values, q order) is copied to s_out. */
void gs_fe_model_coupling(const gs_fe_model *m, double *s_out);

/* Static solution K u = f of the elastic part with the fixed nodes held:
 * f_nodes and u_nodes are 2 * n_nodes arrays (x, y per mesh node, body
 * frame); forces on fixed nodes are ignored and their displacement is set to
 * zero. Factorises K on every call (for verification and for calibrating
 * lumped stiffnesses, not for stepping).
 * Errors: GS_EINVAL, GS_ESINGULAR (K not positive definite: too few fixed
 * nodes), GS_ENOMEM. */
gs_err gs_fe_model_static(const gs_fe_model *m, const double *f_nodes, double *u_nodes);

/* Elastic energy 1/2 u^T K u of a nodal displacement field (2 * n_nodes
 * values; fixed nodes' values are ignored). */
double gs_fe_model_energy(const gs_fe_model *m, const double *u_nodes);

/* Stress recovery from a nodal displacement field u_nodes (2 * n_nodes).
 * Any output may be NULL: stress (3 * n_tris: sigma_xx, sigma_yy, tau_xy per
 * element, body frame, Pa), vm_elem (n_tris: von Mises per element; plane
 * strain includes sigma_zz = nu (sigma_xx + sigma_yy)), vm_node (n_nodes:
 * area-weighted mean of the elements around each node).
 * Errors: GS_EINVAL. */
gs_err gs_fe_model_stress(const gs_fe_model *m, const double *u_nodes, double *stress,
                          double *vm_elem, double *vm_node);

/* ------------------------------------------------------------------------ */
/* Body                                                                      */
/* ------------------------------------------------------------------------ */

typedef struct gs_fe_body gs_fe_body;

typedef struct gs_fe_balance {
    double kinetic;        /* 1/2 w^T M w (theta included), J */
    double elastic;        /* 1/2 u^T K u, J */
    double energy0;        /* kinetic + elastic at the last gs_fe_body_set_state */
    double work_in;        /* sum over steps of F_{n+1/2} . dq (moment on theta, nodal loads) */
    double work_iface;     /* sum over steps of f . dq of the interface forces (gs_fe_body_apply) */
    double dissipated;     /* sum of c dq_theta^2 / h (the brake) and of damped */
    double damped;         /* sum of dq^T D dq / h, D = damping_m M + damping_s K (material damping) */
    double residual;       /* E - energy0 - work_in - work_iface + dissipated */
} gs_fe_balance;

typedef struct gs_fe_stats {
    uint64_t factorizations;   /* numeric Cholesky factorisations (one per new h) */
    uint64_t solves;           /* sparse triangular solve pairs, counted per right-hand side */
    uint64_t steps;            /* completed steps */
    uint64_t cache_hits;       /* node columns found in the compliance cache */
    uint64_t cache_misses;     /* node columns asked for and not cached (two solves each, batched) */
    uint64_t group_solves;     /* multi-column solves of a whole group of nodes (the misses' batches) */
    uint64_t group_kept;       /* columns of group members not asked for, kept for the next requests */
    uint64_t block_reused;     /* compliance entries copied from the previous block */
    gs_index cached_nodes;     /* nodes held now */
    size_t cache_bytes;        /* memory they use */
    double factor_nnz;         /* entries of the Cholesky factor of the elastic block */
} gs_fe_stats;

/* A body at rest (q = w = 0) using model m, which must outlive it. No time
 * step yet: call gs_fe_body_set_step before stepping. *out is owned by the
 * caller (gs_fe_body_free). Errors: GS_EINVAL, GS_ENOMEM. */
gs_err gs_fe_body_new(const gs_fe_model *m, gs_fe_body **out);

/* Free a body; safe on NULL; sets *b = NULL. */
void gs_fe_body_free(gs_fe_body **b);

/* Hold theta (a ring bolted to the housing): theta then stays where it is,
 * its velocity is zero, and moments on it do no work. Takes effect at the
 * next step; nothing is refactorised and the cache stays valid (theta is a
 * border of the factor, not part of it). Errors: GS_EINVAL, GS_ESTATE
 * (inside a step). */
gs_err gs_fe_body_hold_theta(gs_fe_body *b, bool held);

/* Set the state: rotation theta (rad), speed omega (rad/s), nodal elastic
 * displacements u_nodes and velocities v_nodes (2 * n_nodes each, body
 * frame; NULL means zero; fixed nodes' values are ignored). Resets the energy
 * accounts (energy0 = current energy, works and dissipation zero).
 * Errors: GS_EINVAL, GS_ESTATE (inside a step). */
gs_err gs_fe_body_set_state(gs_fe_body *b, double theta, double omega, const double *u_nodes,
                            const double *v_nodes);

/* Set the time step h (s, > 0) and the brake coefficient brake_c (N m s, >= 0;
 * brake moment -c theta', taken implicitly, METHOD.md section 2).
 * Refactorises the elastic block only when h differs from the current one
 * (and then empties the compliance cache); a change of brake_c alone only
 * updates the scalar Schur complement of theta.
 * Errors: GS_EINVAL, GS_ESTATE (inside a step), GS_ESINGULAR, GS_ENOMEM. */
gs_err gs_fe_body_set_step(gs_fe_body *b, double h, double brake_c);

/* One free step: gs_fe_body_begin_step then gs_fe_body_end_step. moment_nm is
 * the moment on theta at the midpoint; f_nodes (2 * n_nodes, body frame,
 * midpoint, may be NULL) nodal forces. Errors: as those two. */
gs_err gs_fe_body_step(gs_fe_body *b, double moment_nm, const double *f_nodes);

/* ---- condensed step, for the global step solver (METHOD.md section 4) ----
 *
 *   gs_fe_body_begin_step(b, M, f)        one solve: dq = A^{-1} b (free motion)
 *   gs_fe_body_increment(b, n, dofs, dq)  dq at the interface dofs
 *   gs_fe_body_compliance(b, n, dofs, C)  C = (A^{-1}) restricted to the dofs
 *   ... global solver finds generalised interface forces f ...
 *   gs_fe_body_apply(b, n, dofs, f)       dq += A^{-1} E f (no solve if cached)
 *   gs_fe_body_end_step(b)                q += dq, w = 2 dq / h - w
 *
 * dofs name body coordinates: GS_FE_DOF_THETA or gs_fe_dof_node(node, comp).
 * Dofs of fixed nodes (and theta of a held body) are allowed and behave as
 * immovable: zero rows in C, zero increment, forces on them ignored.
 * The compliance columns of the elastic block are cached per node for the
 * current h, so a tooth that comes back into mesh costs no solve. */

/* Start a step: solve A dq = 2/h M w - K q + F for the free-motion
 * increment (one sparse solve; formed as dq = h w + delta, see fe_body.c).
 * Errors: GS_EINVAL, GS_ESTATE (no time step set, or a step
 * already begun). */
gs_err gs_fe_body_begin_step(gs_fe_body *b, double moment_nm, const double *f_nodes);

/* The current increment dq (the free motion until gs_fe_body_apply is
 * called) at n dofs, into dq_out (n values). Errors: GS_EINVAL (bad dof),
 * GS_ESTATE (no step begun). */
gs_err gs_fe_body_increment(gs_fe_body *b, int n, const gs_index *dofs, double *dq_out);

/* Compliance block: C (n x n, column-major, caller-allocated, symmetric) =
 * rows and columns `dofs` of A^{-1} (brake included). Needs a time step but
 * not a begun step. Computes and caches the missing node columns (batched
 * solves). Errors: GS_EINVAL, GS_ESTATE (no time step), GS_ENOMEM. */
gs_err gs_fe_body_compliance(gs_fe_body *b, int n, const gs_index *dofs, double *C);

/* The sub-block of that block at the k positions sel[0..k) of the dof list
 * (C: k x k, column-major): the same entries, bit for bit. The columns of
 * all n dofs are cached first, as gs_fe_body_compliance does, so that the
 * cache and its batched solves do not depend on the selection (the
 * two-phase step record: the solver names the rows it reads). Errors: as
 * gs_fe_body_compliance, GS_EINVAL for a position outside 0..n-1. */
gs_err gs_fe_body_compliance_sub(gs_fe_body *b, int n, const gs_index *dofs, int k, const int *sel,
                                 double *C);

/* Add the response to generalised interface forces f (n values, N or N m,
 * body frame, at the midpoint) on `dofs`: dq += A^{-1} E f, from the cached
 * columns (computed if missing). May be called several times in a step; the
 * forces add up. Their work f . dq is booked in work_iface at end_step.
 * Errors: GS_EINVAL, GS_ESTATE (no step begun), GS_ENOMEM. */
gs_err gs_fe_body_apply(gs_fe_body *b, int n, const gs_index *dofs, const double *f);

/* Finish the step: q += dq, w = 2 dq / h - w, energy accounts updated.
 * Errors: GS_ESTATE (no step begun). */
gs_err gs_fe_body_end_step(gs_fe_body *b);

/* Abandon a begun step (the global solve failed): the state stays that of
 * the step's start, interface forces are dropped. Safe when no step is
 * begun. */
void gs_fe_body_cancel_step(gs_fe_body *b);

/* ---- state, energies, diagnostics ---- */

double gs_fe_body_theta(const gs_fe_body *b);
double gs_fe_body_omega(const gs_fe_body *b);
/* 1/2 w^T M w, theta coupling included (J). */
double gs_fe_body_kinetic(const gs_fe_body *b);
/* 1/2 u^T K u (J). */
double gs_fe_body_elastic(const gs_fe_body *b);
/* Both of the above in one pass over the matrices (the same values); after
 * a step, the values its end-of-step pass summed. */
void gs_fe_body_energy(const gs_fe_body *b, double *kinetic, double *elastic);
/* With defer true, the following steps' end skips the energies (its pass
 * over the matrices reads K alone); gs_fe_body_energy then sums them from
 * the state when asked: the same values bit for bit, at the cost of a pass
 * over K and M. Off by default. */
void gs_fe_body_defer_energy(gs_fe_body *b, bool defer);
/* Energy dissipated by material damping since the last set_state, J. */
double gs_fe_body_damped(const gs_fe_body *b);
/* I theta' + s . u' (body frame, about the axis; N m s). */
double gs_fe_body_angular_momentum(const gs_fe_body *b);
/* Add dw to the rotation speed (theta'), keeping the elastic velocities:
 * a rigid spin increment of the whole body. Its kinetic energy changes by
 * dw L + I dw^2 / 2 (L the angular momentum before, I the total inertia). */
void gs_fe_body_spin(gs_fe_body *b, double dw);
/* Nodal displacements and velocities (2 * n_nodes each, zero on fixed nodes;
 * either may be NULL). */
void gs_fe_body_nodal(const gs_fe_body *b, double *u_nodes, double *v_nodes);
/* The raw coordinate vectors (ne + 1 values each, q order); read-only views
 * valid until the next call that changes the state. */
const double *gs_fe_body_q(const gs_fe_body *b);
const double *gs_fe_body_w(const gs_fe_body *b);
void gs_fe_body_get_balance(const gs_fe_body *b, gs_fe_balance *out);
void gs_fe_body_get_stats(const gs_fe_body *b, gs_fe_stats *out);

/* Bound the memory of the compliance cache (default 256 MiB). A request that
 * needs more nodes at once than the bound allows still succeeds: the bound is
 * exceeded for it, and least recently used nodes are dropped later.
 * Errors: GS_EINVAL. */
gs_err gs_fe_body_set_cache_limit(gs_fe_body *b, size_t max_bytes);

/* ------------------------------------------------------------------------ */
/* Reduced body (src/fe/fe_reduced.c, docs/explanation/elastic_body.md "Reduced elastic body")     */
/* ------------------------------------------------------------------------ */

/* The FE body with its modes above f_max taken as massless: the rigid
 * rotation and the elastic modes with f <= f_max are stepped exactly as the
 * full body steps them (the same midpoint scheme, decoupled), the rest is a
 * static residual flexibility with a force-like state on the nodes that
 * carried force. The operations are those of gs_fe_body_* with the same
 * meaning; a step costs O(N |I| + |I| |supp Y|) instead of a sparse solve.
 * Differences: the residual carries no kinetic energy (its velocity in a
 * set_state is dropped: the M_f-orthogonal projection on the kept modes is
 * kept; gs_fe_reduced_nodal's velocities are the modes'), nor
 * mass-proportional damping (material damping_m acts on the kept modes,
 * exactly: diagonal held, with a rank-one coupling through the rotation
 * free), theta is held or free from creation on, and forces may act only
 * on the candidate nodes named at creation (GS_EINVAL otherwise). */
typedef struct gs_fe_reduced gs_fe_reduced;

typedef struct gs_fe_reduced_opts {
    double f_max_hz;        /* keep the elastic modes up to this frequency (> 0; INFINITY: all,
                             * only for small models: dense eigensolver) */
    bool held;              /* theta held (modes of the elastic block alone) */
    gs_index n_nodes;       /* candidate nodes (mesh numbering) that may carry force */
    const gs_index *nodes;  /* NULL: every node (small models) */
    int eigensolver;        /* 0 (default): dense up to 1600 elastic unknowns, else Lanczos;
                             * 1 dense; 2 Lanczos (for the tests) */
    bool residual_static;   /* the residual's rule: false the midpoint rule of the modes (energy
                             * exact; undamped it alternates from step to step), true static
                             * (Y_{n+1} = F_step undamped: z follows the step's force; it loses
                             * 1/2 dY^T G_res dY a step, booked as dissipation) */
} gs_fe_reduced_opts;

typedef struct gs_fe_reduced_info {
    int modes;              /* kept modes, the rigid rotation included for a free body */
    int elastic_modes;      /* of which elastic */
    double f_top_hz;        /* the highest kept */
    gs_index rows;          /* 1 + 2 candidate nodes */
    gs_index cached_nodes;  /* nodes whose residual columns are computed */
    gs_index residual_support; /* rows with a residual force state now */
    uint64_t steps;
    double column_cpu_s;    /* CPU seconds spent computing residual columns (once per node) */
    double residual_loss;   /* J lost by the static residual rule (in the body's dissipation) */
} gs_fe_reduced_info;

/* Factorises K once and computes the modes (Lanczos above ~1600 unknowns).
 * Errors: GS_EINVAL, GS_ERANGE (damping_m < 0), GS_ESINGULAR, GS_ENOCONV,
 * GS_ETOOBIG (more than 4000 modes below f_max), GS_ENOMEM. */
gs_err gs_fe_reduced_new(const gs_fe_model *m, const gs_fe_reduced_opts *o, gs_fe_reduced **out);
void gs_fe_reduced_free(gs_fe_reduced **b);
void gs_fe_reduced_get_info(const gs_fe_reduced *b, gs_fe_reduced_info *info);
/* GS_EINVAL when held differs from the creation's. */
gs_err gs_fe_reduced_hold_theta(gs_fe_reduced *b, bool held);
gs_err gs_fe_reduced_set_state(gs_fe_reduced *b, double theta, double omega, const double *u_nodes,
                               const double *v_nodes);
gs_err gs_fe_reduced_set_step(gs_fe_reduced *b, double h, double brake_c);
gs_err gs_fe_reduced_step(gs_fe_reduced *b, double moment_nm, const double *f_nodes);
gs_err gs_fe_reduced_begin_step(gs_fe_reduced *b, double moment_nm, const double *f_nodes);
gs_err gs_fe_reduced_increment(gs_fe_reduced *b, int n, const gs_index *dofs, double *dq_out);
gs_err gs_fe_reduced_compliance(gs_fe_reduced *b, int n, const gs_index *dofs, double *C);
gs_err gs_fe_reduced_compliance_sub(gs_fe_reduced *b, int n, const gs_index *dofs, int k, const int *sel,
                                    double *C);
gs_err gs_fe_reduced_apply(gs_fe_reduced *b, int n, const gs_index *dofs, const double *f);
gs_err gs_fe_reduced_end_step(gs_fe_reduced *b);
void gs_fe_reduced_cancel_step(gs_fe_reduced *b);
/* Current displacement (x, y, body frame) of a node (zero when fixed);
 * GS_EINVAL for a node that is not a candidate. */
gs_err gs_fe_reduced_node_displacement(const gs_fe_reduced *b, gs_index node, double u[2]);
double gs_fe_reduced_theta(const gs_fe_reduced *b);
/* The modes' share of theta' (the residual is massless). */
double gs_fe_reduced_omega(const gs_fe_reduced *b);
void gs_fe_reduced_energy(const gs_fe_reduced *b, double *kinetic, double *elastic);
double gs_fe_reduced_damped(const gs_fe_reduced *b);
double gs_fe_reduced_angular_momentum(const gs_fe_reduced *b);
void gs_fe_reduced_spin(gs_fe_reduced *b, double dw);
/* Nodal fields (2 * n_nodes each, either may be NULL); the displacement
 * costs one solve with the factor of K when a residual state is present. */
gs_err gs_fe_reduced_nodal(gs_fe_reduced *b, double *u_nodes, double *v_nodes);
void gs_fe_reduced_get_balance(const gs_fe_reduced *b, gs_fe_balance *out);
/* Snapshot: modal q, v, the residual force state on the rows and the order
 * of its support, the amplitude of the residual displacement of the last
 * set_state, the energy books (energy0, work, dissipation, damping, the
 * static rule's loss) and the step count: a body loaded from it steps on
 * bit for bit as the saved one would have (docs/explanation/elastic_body.md "Reduced elastic
 * body"). Its size does not depend on the modes (every rank knows it from
 * the mesh: gs_fe_reduced_state_size_for(ne, candidate nodes); N <= ne + 1).
 * Loading a snapshot of another basis (N differs), a damaged support, or a
 * residual displacement into a body whose set_state left none: GS_EINVAL. */
size_t gs_fe_reduced_state_size_for(gs_index ne, gs_index n_candidates);
size_t gs_fe_reduced_state_size(const gs_fe_reduced *b);
void gs_fe_reduced_save(const gs_fe_reduced *b, double *x);
gs_err gs_fe_reduced_load(gs_fe_reduced *b, const double *x);

#endif
