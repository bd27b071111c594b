#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The floors of the library run one way (scene -> geometry -> mesh -> bodies
-> step): a check of the includes and identifiers of src/.

 - a model (src/models) includes nothing of the step (src/step, gearsim/step.h)
   and names none of its types or functions (gs_system, gs_step_*, gsi_plan_*,
   gsi_contact_solve...): it sees the system through gs_model_view (models.h);
 - the stepping code (every file of src/step but system.c, where the system is
   built from the scene) names no scene type (gs_scene*) and reads no
   system's scene (->scene): it reads the bodies' and meshes' runtime data;
 - the geometry (src/geometry, gearsim/geometry.h, gearsim/modification.h)
   includes no mesh header.

Comments are left out of the identifier checks. Each rule first runs on a
sample that breaks it and must flag it, so a rule that no longer matches
anything fails here too.

    test_layers.py [source root]      (default: this checkout)
"""
import os
import re
import sys

STEP_SEAM = "system.c"  # src/step: builds the system from the scene

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^">]+)[">]', re.M)


def strip_comments(text):
    """C source without its comments and string literals' contents."""
    out = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    out = re.sub(r"//[^\n]*", "", out)
    return re.sub(r'"(\\.|[^"\\\n])*"', '""', out)


def model_problems(name, text):
    """What a file of src/models must not do."""
    bad = []
    for inc in INCLUDE.findall(text):
        base = os.path.basename(inc)
        if inc.startswith("step/") or base in ("step.h", "step_internal.h") or "/step/" in inc:
            bad.append(f"{name}: includes the step's header {inc}")
    code = strip_comments(text)
    for ident in sorted(set(re.findall(r"\b(gs_system\w*|gs_step_\w+|gsi_plan_\w+|gsi_contact_(?:solve|select|free)"
                                       r"|gsi_mesh_forces|gs_sol_\w+)\b", code))):
        bad.append(f"{name}: names the step's {ident}")
    return bad


def step_problems(name, text):
    """What a stepping file of src/step (not the seam) must not do."""
    code = strip_comments(text)
    bad = [f"{name}: names the scene type {i}" for i in sorted(set(re.findall(r"\b(gs_scene\w*)\b", code)))]
    if re.search(r"->\s*scene\b|\.\s*scene\b", code):
        bad.append(f"{name}: reads a system's scene (->scene)")
    for inc in INCLUDE.findall(text):
        if os.path.basename(inc) == "scene.h":
            bad.append(f"{name}: includes {inc}")
    return bad


def geometry_problems(name, text):
    """What the geometry floor must not include."""
    bad = []
    for inc in INCLUDE.findall(text):
        base = os.path.basename(inc)
        if inc.startswith("mesh/") or base.startswith("mesh") or base.endswith("_mesh.h"):
            bad.append(f"{name}: includes the mesh header {inc}")
    return bad


def self_check():
    """Every rule flags a sample that breaks it and passes one that keeps it."""
    samples = [
        (model_problems, '#include "gearsim/step.h"\n', True),
        (model_problems, '#include "../step/step_internal.h"\n', True),
        (model_problems, "static void f(const gs_system *sys) {}\n", True),
        (model_problems, "x = gs_step_prepare(s);\n", True),
        (model_problems, "/* gs_system: the whole */ static int f(const gs_model_view *sys) { return 0; }\n", False),
        (step_problems, "const gs_scene_body *sb = 0;\n", True),
        (step_problems, "int n = sys->scene->max_newton;\n", True),
        (step_problems, '#include "gearsim/scene.h"\n', True),
        (step_problems, "/* the scene's gs_scene */ int n = sys->max_newton;\n", False),
        (geometry_problems, '#include "gearsim/mesh.h"\n', True),
        (geometry_problems, '#include "mesh/mesh_internal.h"\n', True),
        (geometry_problems, '#include "gearsim/geometry.h"\n', False),
    ]
    failures = []
    for rule, text, broken in samples:
        if bool(rule("sample", text)) != broken:
            failures.append(f"rule {rule.__name__} {'missed' if broken else 'flagged'}: {text.strip()}")
    return failures


def sources(root, sub, exts=(".c", ".h")):
    d = os.path.join(root, sub)
    if not os.path.isdir(d):
        return []
    return sorted(os.path.join(d, f) for f in os.listdir(d) if f.endswith(exts))


def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    failures = self_check()
    checked = 0
    for path in sources(root, "src/models"):
        failures += model_problems(os.path.relpath(path, root), read(path))
        checked += 1
    for path in sources(root, "src/step"):
        if os.path.basename(path) != STEP_SEAM:
            failures += step_problems(os.path.relpath(path, root), read(path))
            checked += 1
    geometry = sources(root, "src/geometry") + [
        p for p in (os.path.join(root, "include/gearsim", h) for h in ("geometry.h", "modification.h"))
        if os.path.isfile(p)]
    for path in geometry:
        failures += geometry_problems(os.path.relpath(path, root), read(path))
        checked += 1
    if checked < 10:
        failures.append(f"only {checked} files found under {root}/src: wrong root?")
    for f in failures:
        print("not ok:", f)
    print(f"{checked} files checked, {len(failures)} problems")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
