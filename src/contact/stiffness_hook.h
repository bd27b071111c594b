/* SPDX-License-Identifier: MIT
 * Test hook of the quasi-static stiffness analysis (src/contact/stiffness.c),
 * not part of the API: tests/validation/test_stiffness.c forces the
 * displacement zone's re-solve path with it. */
#ifndef GEARSIM_CONTACT_STIFFNESS_HOOK_H
#define GEARSIM_CONTACT_STIFFNESS_HOOK_H

/* 0 (default). 1: in each roll position the displacement zone grows only
 * from a search after displacements were computed and the last
 * linearisation changed delta by little (not from the first, unloaded
 * search that covers everything on the involute pairs), so every tooth it
 * needs is added once the solution has nearly settled on stale zero
 * displacements there, and the position is solved again
 * (gs_stiffness_result.zone_restarts; docs/explanation/stiffness.md "Displacement
 * zone"). The results must not change. */
extern int gsi_stiffness_zone_late;

/* 0 (default). 1: the near-field correction keeps its compliance but takes
 * no gap offsets off the rows (the rows keep the node-sampled gaps of the
 * FE flanks), in the quasi-static analysis and in the tables of the dynamic
 * contact step built while it is set (src/contact/nearfield_dyn.c):
 * tests/validation/test_nearfield_dyn.c measures what the offsets account
 * for. */
extern int gsi_stiffness_nf_no_offsets;

#endif
