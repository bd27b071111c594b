# SPDX-License-Identifier: MIT
"""The Harris map: peak-to-peak loaded static transmission error against
line load, one series per tip relief amount (gearctl stiffness --loads).

Each relief amount C (um, on both gears of the mesh, linear or parabolic,
over `relief_length` mm of roll from the tip; default the long relief
(eps - 1) p_b, from the highest point of single-tooth contact) is written
into a copy of the scene; without reliefs the scene's own modifications make
the one series. Loads are line loads w (N/mm): T = w b r_b1 on the driver."""
import copy
import json
import math
import os
import tempfile

from .stiffness import run_json, stiffness_command

# te_pp_um .. te_max_um: the former names of the te_loaded_* columns, repeated
# at the end for one release (docs/reference/outputs.md)
CSV_HEADER = ("relief_um,line_load_n_per_mm,torque_nm,te_loaded_pp_um,te_loaded_mean_um,te_loaded_min_um,"
              "te_loaded_max_um,k_mean,fraction_multi_pair,te_pp_um,te_mean_um,te_min_um,te_max_um")


def parse_list(text, what):
    """Comma-separated numbers: ValueError naming `what` when one is not."""
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ValueError(f"{what}: comma-separated numbers, not {text!r}") from None


def parse_loads(text):
    loads = parse_list(text, "--loads")
    if not loads or any(not (w > 0) for w in loads):
        raise ValueError("--loads: positive line loads in N/mm, comma-separated")
    return loads


def long_relief_length(probe):
    """(eps - 1) p_b in mm: the roll from the tip down to the highest point
    of single-tooth contact, from a gearsim-stiffness result."""
    pb_mm = math.pi * 2e3 * probe["base_radius_mm"] * 1e-3 / probe["teeth"][0]
    return (probe["contact_ratio"] - 1.0) * pb_mm


def relief_scene(base, gears, amount_um, length_mm, shape):
    """A copy of the scene with tip relief `amount_um` on the bodies named in
    `gears` (none when the amount is 0: their modifications removed)."""
    sc = copy.deepcopy(base)
    for body in sc.get("bodies", []):
        if body.get("name") in gears:
            if amount_um > 0:
                body["modification"] = {"tip_relief": {"amount_um": amount_um, "length_mm": length_mm,
                                                       "shape": shape}}
            else:
                body.pop("modification", None)
    return sc


def harris_map(tool, scene, loads, reliefs=None, relief_length=None, relief_shape="linear", positions=24,
               mesh=None, refine=None, driver=None, nearfield=True, run=run_json):
    """The map as a dict (mesh, driver, driven, teeth, relief_length_mm,
    relief_shape, positions, refine, rows); one gearsim-stiffness analysis
    per load and relief. ToolError when the tool fails."""
    with open(scene) as f:
        base = json.load(f)

    def analyse(path, torque):
        cmd = stiffness_command(tool, path, positions=positions, mesh=mesh, torque=torque, refine=refine,
                                driver=driver, nearfield=nearfield, tangent=False)
        return run(cmd, "gearsim-stiffness")

    rows = []
    with tempfile.TemporaryDirectory(prefix="gearctl-harris-") as tmp:
        probe = analyse(scene, None)
        rb_m = probe["base_radius_mm"] * 1e-3
        b_mm = probe["face_width_mm"]
        sgn = 1.0 if probe["torque_nm"] >= 0 else -1.0
        length = relief_length if relief_length else long_relief_length(probe)
        series = []
        if reliefs:
            gears = {probe["driver"], probe["driven"]}
            for c in reliefs:
                path = os.path.join(tmp, f"relief_{c:g}.json")
                with open(path, "w") as f:
                    json.dump(relief_scene(base, gears, c, length, relief_shape), f)
                series.append((f"{c:g} um", c, path))
        else:
            series.append(("as given", float("nan"), scene))
        for label, c, path in series:
            for w in loads:
                res = analyse(path, sgn * w * b_mm * rb_m)
                tl = res.get("te_loaded_um", res.get("te_um"))
                rows.append({"relief_um": c, "label": label, "line_load_n_per_mm": w,
                             "torque_nm": res["torque_nm"], "te_loaded_pp_um": tl["peak_to_peak"],
                             "te_loaded_mean_um": tl["mean"], "te_loaded_min_um": tl["min"],
                             "te_loaded_max_um": tl["max"],
                             "k_mean": res["k"]["mean"], "fraction_multi_pair": res["fraction_multi_pair"]})
    return {"mesh": probe["mesh"], "driver": probe["driver"], "driven": probe["driven"],
            "teeth": probe["teeth"], "relief_length_mm": length, "relief_shape": relief_shape,
            "positions": positions, "refine": probe["refine"], "rows": rows}


def harris_csv(rows):
    """The map as CSV text (header line, one row per analysis)."""
    out = [CSV_HEADER]
    for r in rows:
        tl = (f"{r['te_loaded_pp_um']:.6g},{r['te_loaded_mean_um']:.6g},{r['te_loaded_min_um']:.6g},"
              f"{r['te_loaded_max_um']:.6g}")
        out.append(f"{r['relief_um']:g},{r['line_load_n_per_mm']:g},{r['torque_nm']:.6g},{tl},"
                   f"{r['k_mean']:.6g},{r['fraction_multi_pair']:.4g},{tl}")
    return "\n".join(out) + "\n"


def series_labels(rows):
    """The series of a map in their order."""
    labels = []
    for r in rows:
        if r["label"] not in labels:
            labels.append(r["label"])
    return labels


def harris_text(out, loads):
    """The table gearctl prints: one line per load, one column per series."""
    labels = series_labels(out["rows"])
    lines = [f"Harris map of {out['mesh']}: {out['driver']} (z={out['teeth'][0]}) drives {out['driven']} "
             f"(z={out['teeth'][1]}); tip relief on both gears over {out['relief_length_mm']:.4g} mm of roll, "
             f"{out['relief_shape']}",
             f"{'line load N/mm':>15} " + " ".join(f"{'p-p TE ' + lab:>16}" for lab in labels) + "   (um)"]
    for w in loads:
        vals = [next(r["te_loaded_pp_um"] for r in out["rows"] if r["label"] == lab and r["line_load_n_per_mm"] == w)
                for lab in labels]
        lines.append(f"{w:15g} " + " ".join(f"{v:16.4f}" for v in vals))
    return "\n".join(lines)
