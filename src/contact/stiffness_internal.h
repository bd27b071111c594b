/* SPDX-License-Identifier: MIT
 * gearsim contact module, library-internal: the quasi-static stiffness
 * analysis's working state (include/gearsim/stiffness.h, docs/explanation/stiffness.md),
 * shared by its files: the run and its roll positions (stiffness.c), the
 * elastic bodies' compliance cache (stiffness_body.c), one load case's
 * contact rows, near-field correction and solve (stiffness_load.c), and the
 * output (stiffness_output.c). */
#ifndef GEARSIM_CONTACT_STIFFNESS_INTERNAL_H
#define GEARSIM_CONTACT_STIFFNESS_INTERNAL_H

#include <stdbool.h>

#include "gearsim/contact.h"
#include "gearsim/fe.h"
#include "gearsim/fe_static.h"
#include "gearsim/mesh.h"
#include "gearsim/qp.h"
#include "gearsim/stiffness.h"

/* Compliance columns per back substitution (bounds the dense work to
 * STIFF_BATCH free-dof vectors). */
#define STIFF_BATCH 32

/* Automatic near-field depth, in modules. */
#define GS_NF_DEPTH 0.2

/* A contact point within this many modules of a tip circle is a corner contact. */
#define GS_NF_CORNER 0.02

/* Near-field correction: half-width of the gap fit along the flank, module. */
#define GS_NF_FIT 0.25

/* ... and whose parabola is no more curved than this many times the
 * flanks' own relative curvature (a neighbour whose foot lies beyond the
 * master's tip or form point is far off the flanks' gap: no vertex). */
#define GS_NF_FIT_CURV 2.0

/* One elastic body: mesh, model, factor, and the compliance among the
 * boundary dofs that contact rows have needed so far (a cache across
 * linearisations and roll positions): their half columns y_d
 * (gs_fe_static_half_column) and the Gram matrix G_de = y_d . y_e =
 * (K^{-1})_de. */
typedef struct sbody {
    const gs_scene_body *sb;
    gs_mesh *mesh;
    gs_fe_model *model;
    gs_fe_static *fs;
    gs_index nb;          /* boundary nodes */
    gs_index *bpos;       /* n_nodes: position on the boundary loop, or -1 */
    gs_index *bdof;       /* 2 nb: boundary dofs (gs_fe_dof_node) */
    int *slot;            /* 2 nb: cache slot of boundary dof j, or -1 */
    int nd, capd;         /* cached dofs, capacity */
    gs_index *ynz;        /* capd: nonzeros of each half column */
    gs_index **yi;        /* capd: its pattern (factor positions, ascending) */
    double **yv;          /* capd: its values */
    double *G;            /* capd x capd: Gram matrix of the cached dofs (the entries
                           * flagged in gk: computed when two dofs first meet in the rows
                           * of one linearisation) */
    unsigned char *gk;    /* capd x capd: G entry known */
    double **col;         /* capd: compliance column of each cached dof at the boundary dofs
                           * (the first ncol; ncol = 0 while the displacements come from
                           * one back substitution per linearisation) */
    int ncol;
    long nback;           /* back substitutions for displacements so far */
    double backw;         /* their cost in full back substitutions (partial ones: the
                           * fraction of L visited) */
    /* Displacement zone (docs/explanation/stiffness.md "Displacement zone"): the
     * displacements are computed only at the boundary nodes of the teeth the
     * contact search reads (gs_fe_static_back_rows), the others stay 0. */
    int zone_on;          /* 0: every boundary dof (gs_stiffness_opts.all_dofs) */
    int *btooth;          /* nb: tooth of each boundary node */
    unsigned char *zt;    /* teeth: in the zone */
    gs_index nzn;         /* boundary nodes in the zone */
    gs_index *zk;         /* nb: their boundary positions */
    gs_index *zdof;       /* 2 nb: their dofs */
    int zall;             /* the zone holds every tooth: full back substitutions */
    int dirty;            /* displacements computed since the last reset of u */
    double zfrac;         /* fraction of L the last partial back substitution visited */
    double *fd;           /* capd: scratch, the force on each cached dof */
    double *z;            /* max(ne, 2 nb): dense work (zero between uses) */
    double *u;            /* 2 n_nodes: current displacement */
    double c[2];          /* axis */
    double *xy_ref;       /* 2 n_nodes: the perfect gear's nodes (NULL: not modified) */
    double t_mesh;        /* CPU s: meshing and the FE model */
    double t_factor;      /* CPU s: factorisation of K */
    double t_columns;     /* CPU s: compliance columns (half columns and Gram entries) */
    double t_solves;      /* CPU s: the displacements (back substitutions or column sums) */
    long columns;         /* compliance columns cached (dofs) */
} sbody;

/* Reallocate array p to count elements; return GS_ENOMEM from the calling
 * function on failure (p is then unchanged). */
#define GROW(p, count)                                         \
    do {                                                       \
        void *q_ = realloc((p), (count) * sizeof *(p));        \
        if (!q_)                                               \
            return GS_ENOMEM;                                  \
        (p) = q_;                                              \
    } while (0)
/* The dofs of one contact row in one body: cache slots and dg/du. */
typedef struct rowdofs {
    int m;                /* nodes (the dofs are 2 m) */
    int slot[8];
    double g[8];
} rowdofs;

/* Working state of one analysis. */
typedef struct work {
    sbody b[2];            /* 0 driver, 1 driven */
    int si[2];             /* search gear index of driver, driven */
    gs_contact_search *search;
    double theta0[2];      /* kinematic angles of the current position */
    double rb, sgn;
    /* rows */
    int cap;
    gs_contact_row *row;
    const gs_contact_candidate **cand;
    double *H, *cvec, *x, *lam_in, *Gm, *gz, *gbar, *a;
    rowdofs *rd[2];        /* per row and body: its dofs' cache slots and dg/du */
    int (*teeth)[2];       /* per row: tooth pair of its candidate (cand_teeth) */
    int *gsl;              /* 8 cap: the rows' cache slots of one body (gsi_stiff_sbody_gram) */
    int n_prev;            /* 1 when the last linearisation changed delta by little */
    /* Contact window: the QP takes the rows whose gap is below win (m); the
     * others are checked at the solution (window_missed). */
    double win;
    const gs_contact_candidate *call; /* every candidate of the last search */
    gs_index ncall;
    unsigned char *kept;   /* per candidate of call: in the rows */
    gs_index capk;
    int win_on;            /* the window is used (not gs_stiffness_opts.all_rows) */
    long win_dropped, win_widened;
    long zone_restarts;    /* positions solved again for it */
    int restart;           /* the displacement zone grew after displacements were computed:
                            * the roll position is solved again (gs_stiffness_next) */
    gs_qp *qp;
    int qp_n;
    /* Near-field correction: the extra compliance c (m/N) of each loaded tooth
     * pair from the previous linearisation, added to its rows' block of W. */
    int nf;                /* on */
    double nf_depth;       /* depth d, m */
    double nf_estar;       /* contact modulus E* of the pair, Pa */
    double nf_bw;          /* face width in contact, m */
    int nf_conj;           /* conjugate involute flanks (gsi_stiff_nf_offsets) */
    int nf_refconj;        /* modified flanks of gears whose perfect flanks are conjugate
                            * involutes: their offsets from the perfect meshes */
    double nf_dc;          /* the driver's turn from the kinematic angle that closes
                            * their backlash (0 at the tight mesh), rad: gsi_stiff_nf_offsets
                            * evaluates the rows there */
    double nf_rform[2];    /* form radius of each body (involute above it), m */
    double ftot;           /* the load case's force T / r_b1, N (pairs below 1e-6 of it: none) */
    int n_pc;
    struct {
        int tooth[2];
        double c;          /* m/N */
        double L;          /* FE near-field compliance (surface to Q, both bodies), m/N */
        double depth[2];   /* depth of Q in each body, m */
        double reff;       /* effective radius of curvature, m */
        int kc;            /* contact next to a tip corner: the corner body (-1: none) */
        double xv;         /* the flanks' touching point from the corner, m (corner_loa) */
        double kw;         /* the corner's wedge apex factor (gs_wedge_apex_factor) */
        int skip;          /* Q not found, or a corner on a concave flank: no correction */
    } pc[GS_STIFF_MAX_PAIRS];
    double *fq, *uq;       /* scratch 2 n_nodes of the larger body */
    /* Near-field correction: per tooth pair the node-sampling part of its
     * rows' rigid gap (gsi_stiff_nf_offsets), taken off their gaps in gsi_stiff_collect. */
    int n_go;
    struct gap_off {
        int tooth[2];
        double off;        /* m */
        int slave;         /* search gear of the rows it applies to (-1: all) */
        int flank;         /* a conjugate contact inside both flanks next to a tip
                            * corner (corner_loa): a flank contact at xb */
        int kc;            /* next to a tip corner of this body (-1: no) */
        double xv;         /* the touching point from the corner (corner_loa), m */
        int has_x;         /* the flanks' contact point found: */
        double xb[2];      /* it, in the driver's body frame, m */
        double ref;        /* the flanks' gap where gsi_stiff_nf_offsets evaluates the rows
                            * (offset taken off; 0 for conjugate flanks), m: the
                            * reference of the rows' rigid gaps */
    } go[2 * GS_STIFF_MAX_PAIRS];
} work;

double gsi_stiff_default_torque(const gs_scene *sc, int body, double rb, double b_m);
gs_err gsi_stiff_collect(work *w, double delta, double win, int *nr, double *gmin);
gs_err gsi_stiff_nf_offsets(work *w);
double gsi_stiff_nf_tangent(const work *w, int nr, int p);
/* The near-field gap offsets (gsi_stiff_nf_offsets, into the run's work:
 * w->go, w->n_go) at roll position roll (mesh cycles, as the positions of
 * gs_stiffness_next), rigid bodies; after the first position, near field on.
 * The displacements are left at zero. */
gs_err gsi_stiffness_run_offsets(gs_stiffness_run *r, double roll);
/* The working state of a run after gs_stiffness_next (NULL before the first). */
const work *gsi_stiffness_run_work(const gs_stiffness_run *run);
gs_err gsi_stiff_sbody_displace(sbody *b);
gs_err gsi_stiff_sbody_init(const gs_scene *sc, int bi, int refine, int order, int fine,
                            int fine_centre, sbody *b, gs_diag *d);
gs_err gsi_stiff_sbody_need(sbody *b, int n, const gs_index *nodes);
gs_err gsi_stiff_solve_load(work *w, double T, int max_iter, double delta0, double *delta, int *nr_out,
                            int *iters, int *converged, double *pen, gs_diag *d);
gs_err gsi_stiff_zone_cover(work *w, const gs_contact_stats *st, const gs_contact_candidate *cand,
                            gs_index nc);
int gsi_stiff_node_tooth(const gs_mesh *m, int z, gs_index node);
int gsi_stiff_zone_add(sbody *b, int t);
void gsi_stiff_fine_centres(const gs_scene *sc, const int bidx[2], const gs_stiffness_opts *o,
                            int centre[2]);
gs_err gsi_stiff_slices(const gs_scene *sc, const gs_scene_mesh *sm, const gs_stiffness_opts *o,
                        gs_stiffness_result *out, gs_diag *d);
void gsi_stiff_pairs_of(const work *w, int nr, double F, gs_stiffness_point *pt);
void gsi_stiff_sbody_free(sbody *b);
void gsi_stiff_sbody_gram(sbody *b, int n, const int *sl);
void gsi_stiff_work_free(work *w);
void gsi_stiff_zone_rebuild(sbody *b);

#endif
