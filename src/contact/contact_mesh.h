/* SPDX-License-Identifier: MIT
 * gearsim internal: the data of a `contact` gear mesh, shared by its model
 * (src/models/contact.c: built at load), the step plan (src/step/plan.c:
 * the search, every rank) and the contact solve (src/step/contact_step.c: the
 * rows and the QP, rank 0). Not part of the public API. */
#ifndef GEARSIM_CONTACT_MESH_H
#define GEARSIM_CONTACT_MESH_H

#include "gearsim/contact.h"
#include "gearsim/models.h"

typedef struct gsi_contact_mesh {
    int body[2];                       /* the two gears (body indices) */
    const gs_mesh *mesh[2];            /* their meshes (elastic: the body's own) */
    gs_mesh *own[2];                   /* meshes made here for rigid gears */
    bool elastic[2];                   /* nodes of this gear are unknowns */
    bool predict;                      /* constrain nodes predicted to touch too */
    double friction;                   /* Coulomb coefficient on the flanks */
    bool friction_explicit;            /* friction_scheme "explicit" (src/step/contact_step.c),
                                        * else implicit (src/step/contact_friction.c) */
    struct gsi_nf_table *nf;           /* "nearfield": the pairs' series compliance
                                        * (src/contact/nearfield_dyn.c), NULL: none */
    gs_contact_search *search;
    const gs_contact_candidate *cand;  /* the last search (owned by `search`) */
    gs_index n_cand;
} gsi_contact_mesh;

#endif
