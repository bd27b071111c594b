/* SPDX-License-Identifier: MIT
 * gearsim: fidelity levels as implementations of operations tables
 * (METHOD.md section 7, STYLE.md convention 5).
 *
 * A body model (rigid, elastic) presents its rigid coordinate (and, for
 * contact, a few nodal displacements) to the step solver through a condensed
 * interface: per step it returns the compliance C and free increment d0 such
 * that its interface increments obey d = d0 + C f,  f being the generalised
 * forces the meshes, joints and contacts apply. For a rigid body
 * 1/C = 2/h^2 I + c/h and d0 = C (2/h I w + M(t_mid)); an elastic body gives
 * the entries of the inverse of its step matrix (METHOD.md section 4). A mesh model (kinematic, lumped;
 * impact and contact later) contributes equality rows and/or a potential
 * with its discrete gradient (METHOD.md section 2). The step solver knows
 * only these tables, and the models know of the system only the view it
 * gives them (gs_model_view): they include nothing of the step. */
#ifndef GEARSIM_MODELS_H
#define GEARSIM_MODELS_H

#include "gearsim/scene.h"
#include "gearsim/types.h"

typedef struct gs_body_rt gs_body_rt;
typedef struct gs_gmesh_rt gs_gmesh_rt;
typedef struct gs_body_ops gs_body_ops;
typedef struct gs_gmesh_ops gs_gmesh_ops;

/* What a model sees of the system (the system builds it, gs_system_view in
 * gearsim/step.h, and passes it to every operation below). The model ops
 * take this view, never the whole system: the scene only for what a model
 * reads of its own entry at init, the rigid state, the coordinates' layout,
 * the bodies' inverse masses (through bodies[].coord and inertia_eff), the
 * step's plan of interface nodes and the few options models act on. Its
 * fields bear the names of the system's (gs_system, gearsim/step.h): a model
 * written against the whole system adapts by taking a
 * `const gs_model_view *sys` in place of the system, reading the plan's
 * arrays as sys->n_dof, sys->n_nodes and sys->nodes (for sys->plan.*) and a
 * body's loads through gs_model_body_load (for gs_system_body_load); every
 * operation and helper (src/models/mesh_common.h) that took `gs_system *` or
 * `const gs_system *` takes the view (after_step changes the rigid state
 * through sys->q and sys->w). */
typedef struct gs_model_view {
    const gs_scene *scene;   /* the scene the system was built from: init reads the model's
                              * own entry (bodies[b->index], meshes[m->index]) and the gears
                              * it names; the operations of a step read the fields below */
    int rank;                /* this process (a body's owner when b->owner == rank) */
    int n_coords;            /* rigid coordinates: q, w, a mesh's a and c, g and J (n x n) */
    int n_bodies, n_meshes;
    const gs_body_rt *bodies;   /* every body: coord, tcoord, inertia_eff, owner, ops */
    const gs_gmesh_rt *meshes;  /* every mesh (an impact reads the others' potential) */
    int n_eq;                /* kinematic (equality) rows, n_eq x n_coords in eq_rows */
    const double *eq_rows;
    double *q, *w;           /* rigid coordinates and velocities (every rank holds all;
                              * after_step may change them) */
    double time, h_sub;      /* the substep being taken: from time, of length h_sub */
    bool smooth_contact;     /* lumped meshes close and open flanks smoothly (gs_system) */
    bool energy_deferred;    /* the step's energies are not read: skip them (gs_system) */
    bool momentum;           /* bodies of their own state report their angular momentum L
                              * (numerics.contact closure_energy reads it) */
    /* The step's plan (gearsim/step.h, gs_step_plan): body i offers n_dof[i]
     * interface unknowns, its coordinate (when it has one) then x, y of the
     * mesh nodes nodes[i][0 .. n_nodes[i]). */
    const int *n_dof, *n_nodes;
    gs_index *const *nodes;
    /* The loads (the system's current set; gs_model_body_load). */
    const gs_scene_load *loads;
    int n_loads;
    /* The supports of translating centres (bearing joints, pin bearings): an
     * impact's position projection reads their potential. */
    int n_joints;
    const struct gs_joint_rt *joints;
} gs_model_view;

/* Sum of the non-brake moments on body `body` at time t, and the brake
 * coefficient, from the loads[0 .. n) (src/models/loads.c). */
void gs_model_loads(const gs_scene_load *loads, int n, int body, double t, double *moment, double *brake);
static inline void gs_model_body_load(const gs_model_view *sys, int body, double t, double *moment, double *brake)
{
    gs_model_loads(sys->loads, sys->n_loads, body, t, moment, brake);
}

struct gs_body_ops {
    const char *name;
    /* Build model data for body `index` of the system's scene (every rank;
     * heavy per-step data such as a factorisation only on the owner). */
    gs_err (*init)(const gs_model_view *sys, gs_body_rt *b, gs_diag *d);
    void (*destroy)(gs_body_rt *b);
    /* Condensed interface for the step from t to t+h (owner rank only;
     * called for held bodies too). The body's interface unknowns are its
     * coordinate (when it has one) and the x, y displacements of the plan's
     * nodes for it (sys->n_nodes, sys->nodes); their increments obey
     * d = d0 + C f,  f the generalised forces of meshes, joints and contact,
     * d0 the free increment, C the compliance (symmetric positive definite).
     * Writes C (n_dof^2, column-major), d0 (n_dof) and the nodes' current
     * displacements (2 n_nodes, body frame) into rec. A failure is reported
     * as a non-finite C[0]. */
    void (*interface)(const gs_model_view *sys, gs_body_rt *b, double h, double *rec);
    /* The same record in two phases (both NULL: interface() only). The
     * step solver reads only the compliance entries of the unknowns its
     * rows touch, known once the free increments and node positions are
     * (gs_step_select). interface_free: as interface() without C (rec's C
     * block left untouched), a failure reported as a non-finite d0[0].
     * compliance: then the k x k sub-block C[sel, sel] (column-major) of the
     * plan dofs sel[0..k) (ascending), bit for bit the entries interface()
     * writes; a failure as a non-finite Cs[0]. */
    void (*interface_free)(const gs_model_view *sys, gs_body_rt *b, double h, double *rec);
    void (*compliance)(const gs_model_view *sys, gs_body_rt *b, int k, const int *sel, double *Cs);
    /* Owner rank, after the solve: complete the body's own step under the
     * interface forces f (n_dof, same order). NULL: nothing to do (a rigid
     * body's state is the system's q, w). */
    gs_err (*finish)(const gs_model_view *sys, gs_body_rt *b, const double *f);
    /* Kinetic and potential energy of the body's own state (owner rank;
     * rigid bodies use the system's w, which every rank holds). */
    void (*energy)(const gs_model_view *sys, const gs_body_rt *b, double *T, double *V);
    /* Add dw to the rotation speed of the body's own state on its owner
     * (a rigid spin increment: the elastic velocities relative to the
     * body's frame are kept; nothing on other ranks). The caller updates
     * b->T and b->L. NULL: no own state (its speed is the system's w). */
    void (*spin)(gs_body_rt *b, double dw);
    /* Internal state beyond the rigid coordinate, for snapshots: its size in
     * doubles (every rank, same value), save and load (owner rank). NULL
     * when the model has none. */
    size_t (*state_size)(const gs_body_rt *b);
    void (*save)(const gs_body_rt *b, double *x);
    gs_err (*load)(gs_body_rt *b, const double *x);
    /* Field snapshot (owner rank): nodal displacements u (2 n, body frame)
     * and von Mises stress vm (n) on the body's mesh; n = field_nodes().
     * NULL when the model has no fields. */
    gs_index (*field_nodes)(const gs_body_rt *b);
    void (*fields)(const gs_body_rt *b, double *u, double *vm);
    /* The body's mesh (every rank), NULL for models without one. */
    const struct gs_mesh *(*mesh)(const gs_body_rt *b);
};

struct gs_gmesh_ops {
    const char *name;
    gs_err (*init)(const gs_model_view *sys, gs_gmesh_rt *m, gs_diag *d);
    /* Equality rows on dq (kinematic): number of rows. */
    int n_eq;
    /* Add the discrete-gradient force and damping between q0 and q0+dq to
     * g (n_coords) and an approximate Jacobian to J (n x n row-major).
     * Returns the mesh's dissipated energy of the step in *diss and its
     * force along the line of action in *force. */
    void (*force)(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0, const double *dq,
                  double h, double *g, double *J, double *diss, double *force);
    double (*energy)(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q);
    /* Contact meshes: no force or potential; the step adds their
     * linearised non-penetration rows and solves a QP (src/step/contact_step.c).
     * destroy frees m->contact; may be NULL. */
    bool contact;
    void (*destroy)(gs_gmesh_rt *m);
    /* Optional, every rank, after the step updated q and w: velocity jumps
     * (impacts of rigid gears). May change sys->w of rigid coordinates;
     * returns the energy it dissipated in the step (>= 0, J), booked in the
     * balance. Must be deterministic (it runs on every rank alike). */
    double (*after_step)(const gs_model_view *sys, gs_gmesh_rt *m);
};

/* A body and a mesh at run time: what the system builds from the scene
 * (gs_system_new) and their models fill at init. The step reads these, never
 * the scene. */
struct gs_body_rt {
    int index;               /* body index in the scene */
    int coord;               /* rigid coordinate index, -1 when held */
    int tcoord;              /* bearing joint: x coordinate of the centre's displacement
                              * (y at tcoord + 1), m; -1 for a centre that does not move */
    int owner;               /* rank that owns the body */
    double inertia_eff;      /* I + sum m d^2 of planets for a carrier */
    double mass;             /* kg: the body's mass (a translating centre's inertia) */
    double centre[2];        /* m: its axis in the scene frame at the start (a planet:
                              * its pin at carrier angle 0; a carrier: the centre its
                              * planets turn about) */
    int carrier;             /* on a carrier: the carrier's body index; -1 otherwise */
    double carrier_radius, carrier_angle; /* on a carrier: its pin's polar place on the
                              * carrier (m, rad at carrier angle 0) */
    double pin_off[2];       /* on a pin bearing: its pin's offset from the carrier's
                              * centre at the carrier's initial angle (m) */
    const gs_body_ops *ops;
    void *model;             /* model data (elastic: FE body) */
    double T, V;             /* kinetic and potential energy of the body's own state,
                              * as the owner last reported it (the system's energy report) */
    double work_s;           /* seconds its owner spent in its interface and finish, summed */
    double D_step;           /* energy its own damping dissipated in the last step (owner
                              * report, booked by the system) */
    double L;                /* angular momentum of the body's own state about its axis
                              * (owner report, like T; 0 without own state) */
    struct gs_mesh *mesh;    /* an elastic gear's mesh, made once when the system is built
                              * (its weight in the owner map); the model takes it at init */
};

struct gs_gmesh_rt {
    int index;               /* mesh index in the scene */
    const gs_gmesh_ops *ops;
    double *a;               /* n_coords: line-of-action displacement s = a . q (m/rad) */
    double *c;               /* n_coords: mesh phase (cycles) phi = c . q */
    double s_ref;            /* s at zero deflection: the initial state's, less s_pin */
    double s_pin;            /* lumped meshes: deflection the planets' pin errors set at the
                              * initial state, along the line of action (m) */
    /* Translations along the true line of action (bodies on bearing joints,
     * docs/explanation/modal.md): s = a . q + sum_k tr_sign[k] n_k(q) . X_k, X_k the
     * centre displacement of gear k (coordinates tr_coord[k], tr_coord[k]+1),
     * n_k = R(q[tr_carrier]) tr_n0[k] when a gear rides on a carrier (the
     * line turns with it), tr_n0[k] otherwise. abar: scratch, n_coords. */
    int n_tr;
    int tr_coord[2];
    double tr_n0[2][2];
    /* A planet on a pin bearing: its term is n . (X + tr_off) - tr_c, the
     * centre's offset from the point R(theta_C) pin0 that turns with the
     * carrier about its nominal centre (tr_off = R(theta_C0) pin0,
     * tr_c = tr_n0 . pin0; both 0 for a gear on a bearing joint). */
    double tr_off[2][2], tr_c[2];
    int tr_carrier;          /* carrier coordinate, -1 none */
    double *abar;
    /* Tooth errors of lumped meshes (docs/explanation/geometry.md): s gains
     * E(q) = sum_k E_k(v_k), v_k = theta_k - theta_C the angle of gear k in
     * the carrier's frame (housing: theta_C = 0). err[k]: coord / carrier
     * coordinates (-1 none), teeth z, beta the direction to the other gear,
     * kp = sigma r_b / r the pitch-error gain, pitch the tooth table (NULL
     * none), runout (e, phase) and n the signed line-of-action direction. */
    int n_err;
    struct {
        int coord, carrier, z;
        double beta, kp, runout, phase, n[2];
        const double *pitch;
    } err[2];
    /* The pitch errors of an ltca mesh, tooth pair by tooth pair (NULL for
     * the others: err[k].pitch by the teeth's windows). When set, E(q)'s
     * pitch part is E_p(phi), phi = c . q - phase0 the mesh phase (cycles),
     * interpolated linearly between the tables' roll positions like the
     * mesh potential: at position j the load shares of the tooth pairs the
     * analysis found in contact times each pair's error (both teeth's pitch
     * errors times their gains kp), the pairs' teeth moving on by step[k]
     * per mesh cycle (src/models/mesh_common.c). */
    const struct gs_pair_errors {
        int n, np;           /* positions per cycle, pair slots per position */
        const int *tooth;    /* n x np x 2: the teeth of mesh gears 0, 1 (-1: empty slot) */
        const double *share; /* n x np: the pair's share of the mesh force */
        int step[2];         /* tooth index change per cycle of phi, gears 0, 1 */
        int z[2];            /* teeth */
        double kp[2];        /* sigma r_b / r of each gear */
        const double *pitch[2]; /* the gears' pitch errors (m; NULL none) */
        double phase0;
        int n_coords;
    } *pair_err;
    double contact_ratio;
    double overlap_ratio;    /* eps_beta of a helical pair (0: spur) */
    double k_single, k_double, damping, half_backlash;
    double transition;       /* width of the single/double stiffness change, fraction of a cycle */
    double *k_table;         /* calibrated stiffness over one mesh cycle (N/m), n_table values:
                              * the secant F / TE, or the tangent dF/dTE at the load */
    double *d0_table;        /* tangent calibration: the spring's offset delta_0 = TE - F / k
                              * (m), n_table values; NULL otherwise (no offset) */
    int n_table;
    double phase0, phase_dir; /* table entry 0 at phase phase0, advancing with phase_dir (+-1) */
    double force;            /* last step's force along the line of action, N */
    double deflection;       /* s - s_ref at the end of the last step, m */
    /* contact meshes: */
    void *contact;           /* model data (the search, meshes of rigid gears) */
    int n_active;            /* constraints with a positive multiplier in the last step */
    int n_rows;              /* constraints in the last step */
    double penetration;      /* deepest penetration at the last step's start, m (>= 0) */
    double friction_loss;    /* energy dissipated by flank friction since load, J */
    double contact_work;     /* work of the contact reactions since load, J (numerics.contact
                              * "closure": the gap closure's; exactly 0 with "seed") */
    double nf_energy;        /* "nearfield": energy in the pairs' series compliance at the
                              * last step's end, J (part of the potential) */
    /* impact meshes (rattle): */
    int64_t impacts;         /* impacts since the start (sustained-contact impulses not counted) */
    double impact_loss;      /* kinetic energy its impulses dissipated since the start, J */
};


/* A compliant support (joint) with a potential and a damper on rigid
 * coordinates (docs/explanation/modal.md): the `bearing` joint holds a body's centre
 * displacement (x, y) with an isotropic radial spring and damper and its
 * rotation with a torsional one. Its force is the discrete gradient of its
 * potential between q0 and q0 + dq (exact: V(q1) - V(q0) = g . dq) plus the
 * damper's, whose work it returns in *diss. */
typedef struct gs_joint_rt gs_joint_rt;
typedef struct gs_joint_ops {
    const char *name;
    void (*force)(const gs_model_view *sys, const gs_joint_rt *j, const double *q0, const double *dq, double h,
                  double *g, double *J, double *diss);
    double (*energy)(const gs_model_view *sys, const gs_joint_rt *j, const double *q);
} gs_joint_ops;
struct gs_joint_rt {
    int body;
    const gs_joint_ops *ops;
    int coord[3];            /* x, y, rotation coordinates (-1: absent) */
    double k[3], c[3];       /* stiffness and damping on each */
    double q_ref[3];         /* where each spring is relaxed */
    /* `pin_bearing` (a planet on its carrier pin): coord[0..1] the planet's
     * centre displacement X_p (inertial), carrier its rotation coordinate,
     * carrier_t its centre displacement X_C (-1: none), pin0 the pin's offset
     * from the carrier centre at carrier angle 0 and d0 = R(theta_C0) pin0;
     * the spring stretch is e = X_p - X_C + d0 - R(theta_C) pin0. */
    int carrier, carrier_t;
    double pin0[2], d0[2];
};
const gs_joint_ops *gs_joint_ops_find(const char *name);

/* The FE mesh of a scene gear at its scene mesh density (elastic bodies;
 * the outline of a rigid gear in a contact mesh). d->message says why it
 * failed; the caller names the field. */
struct gs_mesh;
gs_err gs_scene_gear_mesh(const gs_scene_body *sb, struct gs_mesh **out, gs_diag *d);
/* The same with `refine` uniform refinements instead of the scene's (< 0:
 * the scene's). Profile modifications, pitch errors and run-out of the body
 * (sb->mods) are applied to the mesh (gs_gear_mods_apply_mesh). */
gs_err gs_scene_gear_mesh_refined(const gs_scene_body *sb, int refine, struct gs_mesh **out,
                                  gs_diag *d);
/* The mesh of the same gear without its modifications and tooth errors (the
 * perfect involute gear; same topology and numbering as the modified one). */
gs_err gs_scene_gear_mesh_perfect(const gs_scene_body *sb, int refine, struct gs_mesh **out,
                                  gs_diag *d);

/* The reduced elastic body's figures (gs_fe_reduced_info: modes, cached
 * residual columns and their CPU seconds, the static rule's loss) of body
 * b: false when b is not a reduced elastic body or lives on another rank. */
struct gs_fe_reduced_info;
bool gs_elastic_reduced_info(const gs_body_rt *b, struct gs_fe_reduced_info *out);

/* The full elastic body's counters (gs_fe_stats: solves, column cache,
 * group solves) of body b: false when b is not a full elastic body or
 * lives on another rank. */
struct gs_fe_stats;
bool gs_elastic_fe_stats(const gs_body_rt *b, struct gs_fe_stats *out);

/* A mesh's line-of-action displacement s(q) (m): a . q, the translations
 * and the tooth errors (gs_gmesh_rt); and the tooth errors' part alone. A
 * mesh's deflection is s(q) - s_ref. */
double gs_gmesh_s(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q);
double gs_gmesh_error(const gs_gmesh_rt *m, const double *q);

/* Registered implementations, by name (the scene's `model`). */
const gs_body_ops *gs_body_ops_find(const char *name);
const gs_gmesh_ops *gs_gmesh_ops_find(const char *name);

#endif
