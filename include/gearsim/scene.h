/* SPDX-License-Identifier: MIT
 * gearsim: the scene, parsed and validated (docs/reference/scene.md, proto/v1/scene.json).
 *
 * gs_scene_parse() turns JSON text into a gs_scene with every default filled
 * and every value checked; on error the gs_diag names the offending field by
 * its JSON path. The scene owns its strings and arrays. Not collective. */
#ifndef GEARSIM_SCENE_H
#define GEARSIM_SCENE_H

#include "gearsim/fe.h"
#include "gearsim/geometry.h"
#include "gearsim/modification.h"
#include "gearsim/types.h"

#define GS_NAME_MAX 64

typedef enum { GS_BODY_GEAR = 0, GS_BODY_CARRIER = 1 } gs_body_type;
typedef enum { GS_MODEL_RIGID = 0, GS_MODEL_ELASTIC = 1 } gs_body_model;
typedef enum {
    GS_JOINT_FIXED_AXIS = 0,
    GS_JOINT_ON_CARRIER = 1,
    GS_JOINT_HELD = 2,
    GS_JOINT_BEARING = 3       /* centre moves in the plane on a radial bearing (docs/explanation/modal.md) */
} gs_joint_type;
typedef enum {
    GS_MESH_KINEMATIC = 0,
    GS_MESH_LUMPED = 1,
    GS_MESH_CONTACT = 2,
    GS_MESH_IMPACT = 3,
    GS_MESH_COMPLIANT = 4,
    GS_MESH_LTCA = 5           /* rigid gears, the LTCA tables' mesh potential (gearsim/ltca.h) */
} gs_mesh_model;
typedef enum { GS_STIFF_CONSTANT = 0, GS_STIFF_RECTANGULAR = 1, GS_STIFF_CALIBRATED = 2 } gs_stiffness_type;
typedef enum { GS_LOAD_CONSTANT = 0, GS_LOAD_RAMP, GS_LOAD_BRAKE, GS_LOAD_TABLE } gs_load_type;
/* numerics.contact: how contact rows treat the gap (docs/explanation/contact.md). */
typedef enum { GS_CONTACT_SEED = 0, GS_CONTACT_CLOSURE = 1, GS_CONTACT_CLOSURE_ENERGY = 2 } gs_contact_scheme;

typedef struct gs_mesh_density {
    int flank;   /* elements along a flank */
    int across;  /* elements across a tooth */
    int rim;     /* radial element layers in the rim */
    int refine;  /* uniform refinements: counts times 2^refine */
    double grading; /* largest / smallest element size across a tooth */
    int order;   /* element order: 1 linear, 2 quadratic (curved 6-node triangles) */
    int fine_teeth;  /* local refinement: teeth meshed finer (0: none; quasi-static analysis) */
    int fine_refine; /* levels finer than `refine` on those teeth */
    int fine_centre; /* tooth they are centred on (not a scene field: set by the analysis) */
} gs_mesh_density;

typedef struct gs_scene_body {
    char name[GS_NAME_MAX];
    gs_body_type type;
    gs_body_model model;
    gs_gear_params gear;       /* valid when type == GS_BODY_GEAR */
    gs_lead_mods lead;         /* bodies[i].lead: lead modifications (slice analysis; the
                                * planar rungs refuse them) */
    gs_material material;
    gs_mesh_density mesh;
    double mass;               /* kg (from geometry unless given) */
    double inertia;            /* kg m^2 about the axis (from geometry unless given) */
    bool mass_given, inertia_given;
    /* joint */
    gs_joint_type joint;
    double centre[2];          /* m, fixed_axis */
    int carrier;               /* body index, on_carrier */
    double carrier_radius;     /* m */
    double carrier_angle;      /* rad */
    /* manufacturing errors */
    double pin_error[2];       /* m: radial, tangential error of a planet's pin (on_carrier) */
    /* compliant supports (docs/explanation/modal.md): `bearing` joint, and a planet's
     * bearing on its carrier pin (on_carrier with bearing_stiffness) */
    double bearing_k, bearing_c; /* N/m, N s/m: isotropic radial bearing (0: floating) */
    double torsion_k, torsion_c; /* N m/rad, N m s/rad: torsional support (bearing joint; 0: free) */
    bool pin_bearing;          /* on_carrier: the planet's centre moves on a bearing_k spring */
    int pitch_error_tooth;     /* tooth whose flanks are displaced along the pitch circle, -1 none */
    double pitch_error;        /* m, counter-clockwise */
    gs_gear_mods *mods;        /* profile modifications, pitch errors, run-out (owned; NULL:
                                * a perfect involute gear); the single pitch_error above is
                                * folded into its pitch table */
    /* initial state */
    double angle0, omega0;
    bool angle_given;          /* angle0 from the scene (else contact meshes phase the gear) */
    double tip_load;           /* N: elastic bodies start in the static deflection under a
                                * tangential load on the tip of tooth 0 (0: undeformed) */
    double reduce_f_max_hz;    /* bodies[i].reduction.f_max_hz: an elastic gear as the reduced
                                * body of fe.h (modes up to it; 0: the full FE body) */
    bool reduce_static;        /* bodies[i].reduction.residual "static" (else "midpoint") */
} gs_scene_body;

typedef struct gs_scene_mesh {
    char name[GS_NAME_MAX];
    int gear[2];               /* body indices */
    gs_mesh_model model;
    gs_stiffness_type stiffness_type;
    double k_single, k_double; /* N/m; constant uses k_single */
    double transition;         /* fraction of the mesh cycle over which k changes */
    int calibrate_positions;   /* calibrated: roll positions of the quasi-static FE analysis */
    int calibrate_secant;      /* calibrated: 1 the secant law k = F / TE ("calibration":
                                * "secant"), 0 (default, "tangent") the tangent stiffness
                                * about the static TE at the load */
    int calibrate_modal;       /* calibrated: 1 ("calibration": "modal") the tangent law with
                                * k scaled per position to the FE pair's own first torsional
                                * mesh mode (include/gearsim/fe_modes.h), delta_0 kept at the
                                * static TE */
    double damping;            /* N s/m; < 0 means "from damping_ratio" */
    double damping_ratio;
    double backlash;           /* m along the line of action */
    /* impact: */
    double restitution;        /* coefficient of restitution e, [0, 1] */
    int law;                   /* restitution hypothesis (gs_restitution: newton, poisson, stronge) */
    /* contact: */
    int one_pass;              /* flank slaves on one gear only (default: both gears) */
    int predict;               /* also constrain nodes predicted to touch within the step */
    double friction;           /* Coulomb coefficient on the tooth flanks (contact meshes), 0: none */
    int friction_explicit;     /* friction_scheme: 0 "implicit" (default: Coulomb's law as
                                * complementarity with the normal contact in the step), 1
                                * "explicit" (the force from the frictionless solve's
                                * normal forces and the rigid sliding velocity) */
    int nearfield;             /* 1: the near-field (Hertz) compliance of each loaded tooth pair in
                                * series with its contact rows (from the pair's quasi-static
                                * analysis); 0 (default): the plain FE contact */
    /* compliant (also damping, damping_ratio, backlash, transition): */
    int patches;               /* strips of the patch model across a contact */
    int bending;               /* 0: beam (tooth bending in series), 1: none,
                                  2: beam_foundation (beam + fillet foundation) */
    double max_line_load;      /* N/m: the top of the force-approach table */
    /* meshes[i].misalignment: deviation of the axes over the common face
     * width b (m), in and out of the plane of action (slice analysis; the
     * planar rungs refuse a non-zero value) */
    double misalign_in, misalign_out;
} gs_scene_mesh;

typedef struct gs_scene_load {
    char name[GS_NAME_MAX];
    int body;
    gs_load_type type;
    double moment;             /* N m (constant, ramp) */
    double ramp_time;          /* s */
    double coefficient;        /* N m s/rad (brake) */
    int n_table;
    double *times, *moments;   /* table, owned */
} gs_scene_load;

typedef struct gs_scene {
    char name[GS_NAME_MAX];
    int n_bodies, n_meshes, n_loads;
    gs_scene_body *bodies;
    gs_scene_mesh *meshes;
    gs_scene_load *loads;
    double time_step;
    int adapt_levels;          /* numerics.adaptive: halvings of time_step allowed (0: fixed step) */
    double adapt_penetration;  /* numerics.adaptive.penetration_um, m: finer above it */
    int contact_scheme;        /* numerics.contact: GS_CONTACT_SEED (homogeneous rows) or
                                * GS_CONTACT_CLOSURE (gap kept in the rows, work booked) or
                                * GS_CONTACT_CLOSURE_ENERGY (closure, its work returned; the
                                * default of a scene with contact meshes) */
    double newton_tol;
    int max_newton;
    int telemetry_every;
    int record_every;
    int fields_every;          /* steps between field snapshots of elastic bodies (0: none) */
    int checkpoint_every;      /* steps between automatic checkpoints of an advance (0: none) */
    char *json;                /* the scene as given, canonical JSON text (owned) */
    char *fidelity_choice;     /* "fidelity": {"targets"}: the rung chosen from the trade-off
                                * table and why, JSON text (owned); NULL otherwise */
} gs_scene;

/* A fidelity choice read back (from a checkpoint: input): len bytes of
 * text, at most GS_FIDELITY_CHOICE_MAX, a JSON object holding "choice" (an
 * object with a string "level") and a string "why", as the targets of a
 * scene write it. GS_OK, or GS_EIO with a message naming what is wrong. */
#define GS_FIDELITY_CHOICE_MAX ((size_t)1 << 20)
gs_err gs_scene_check_fidelity_choice(const char *text, size_t len, gs_diag *d);
/* The choice (checked as above) given to sc, a scene parsed from the
 * concrete scene its targets were set on ("fidelity": "as_given"), which
 * has none of its own; GS_EIO otherwise. */
gs_err gs_scene_adopt_fidelity_choice(gs_scene *sc, const char *text, gs_diag *d);

/* Parse and validate. On failure returns the code, fills d, *out = NULL. */
gs_err gs_scene_parse(const char *json_text, size_t len, gs_scene **out, gs_diag *d);
/* Validate an already parsed JSON object (borrowed). */
struct json_object;
gs_err gs_scene_from_json(struct json_object *root, gs_scene **out, gs_diag *d);
/* Embedded example scenes ("pair", "planetary"), else NAME.json of the
 * installed scenes directory (share/gearsim/scenes; $GEARSIM_SCENE_DIR
 * overrides it; names of letters, digits, '_' and '-' only); NULL if
 * unknown. Not thread-safe. */
const char *gs_scene_builtin(const char *name);
/* NULL-terminated list of builtin scene names: the embedded ones, then the
 * other scenes of the installed directory. */
const char *const *gs_scene_builtin_names(void);
/* Read a file and parse it. */
gs_err gs_scene_load_file(const char *path, gs_scene **out, gs_diag *d);
void gs_scene_free(gs_scene **s);
/* Axis position of body i in the scene frame at the scene's initial state
 * (m): its centre (fixed axis), its pin on the carrier at the carrier's
 * initial angle 0 (on carrier), the origin (held). */
void gs_scene_body_centre(const gs_scene *s, int i, double c[2]);
/* Index of a body by name, -1 if none. */
int gs_scene_find_body(const gs_scene *s, const char *name);

/* Size limits, checked before anything is meshed (docs/reference/scene.md, "Size
 * limits"). The estimate of an elastic gear's FE unknowns is
 *   2 * teeth * 1.5 * (flank + rim) * (2 across + 2) * 4^refine
 * (two displacements per node; 1.3-1.6x the unknowns the mesher makes for
 * the example gears, so it errs on the large side); carriers and rigid gears
 * have none. gs_scene_parse refuses a body above GS_SCENE_MAX_BODY_UNKNOWNS
 * (field bodies[i].mesh.refine, or bodies[i].mesh when refine is 0). */
#define GS_SCENE_MAX_BODY_UNKNOWNS 4000000.0
/* Most halvings of the time step numerics.adaptive may make. */
#define GS_SCENE_MAX_ADAPT_LEVELS 6
#define GS_SCENE_BYTES_PER_UNKNOWN 3072.0
#define GS_SCENE_BASE_BYTES (8.0 * 1024 * 1024)
double gs_scene_body_unknowns(const gs_scene_body *b);
/* Estimated memory of a loaded scene on the rank that holds it all (bytes):
 * GS_SCENE_BASE_BYTES + GS_SCENE_BYTES_PER_UNKNOWN per elastic unknown
 * (stiffness, factor, condensation and field buffers; measured, see
 * docs/RELIABILITY.md). *largest (may be NULL) gets the body with the most
 * unknowns, -1 when none is elastic. */
double gs_scene_estimate_bytes(const gs_scene *s, int *largest);

/* Parse one load object (as in scene.loads[] or set_load) against scene s.
 * `path` prefixes field names in diagnostics. Owns nothing of s. */
struct json_object;
gs_err gs_scene_parse_load(const gs_scene *s, struct json_object *o, const char *path,
                           gs_scene_load *out, gs_diag *d);
void gs_scene_load_clear(gs_scene_load *l);

#endif
