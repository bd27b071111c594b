# SPDX-License-Identifier: MIT
"""Natural frequencies of the lumped train through the gearsim-modal tool,
and the table gearctl prints of them."""
from .stiffness import run_json


def run_modal(tool, scene):
    """gearsim-modal's JSON result for a scene file (ToolError when it fails)."""
    return run_json([tool, scene, "--json"], "gearsim-modal")


def modal_text(res):
    """The group counts, then one line per group of equal frequency."""
    c = res["groups_by_kind"]
    lines = [f"{res['scene']}: {res['dof']} coordinates; groups: {c['rotational']} rotational, "
             f"{c['translational']} translational, {c['planet']} planet, {c['mixed']} mixed",
             f"{'frequency Hz':>14}  {'kind':<13} multiplicity"]
    for g in res["groups"]:
        lines.append(f"{g['frequency_hz']:14.3f}  {g['kind']:<13} {g['multiplicity']}")
    return "\n".join(lines)


def modes_of(modal):
    """The groups above 1 Hz (the rigid-body modes left out) as
    {frequency_hz, kind, multiplicity}."""
    return [{"frequency_hz": g["frequency_hz"], "kind": g["kind"], "multiplicity": g["multiplicity"]}
            for g in (modal or {}).get("groups", []) if g["frequency_hz"] > 1]
