# SPDX-License-Identifier: MIT
"""`gearctl advise`: the cheapest fidelity (level, time step, refine) of the
measured trade-off table that meets relative-error targets on the outputs.

    res = advise(read_scene_spec("pair"), DEFAULT_TABLE, ["speed=1e-2"], "pair")
    print(advice_text(res))
"""
import csv
import json
import math
import os

from .paths import DATA

DEFAULT_TABLE = DATA["table"]
SCENES_DIR = DATA["scenes"]
TABLE_SCENE = {"pair": "contact_drive", "planetary": "planetary_contact"}


class AdviceError(Exception):
    def __init__(self, msg, code=1):
        super().__init__(msg)
        self.code = code


def read_scene_spec(spec, scenes_dir=None):
    """A scene file, builtin:NAME or a bare builtin NAME (deploy/scenes)."""
    name = spec[len("builtin:"):] if spec.startswith("builtin:") else spec
    if not spec.startswith("builtin:") and os.path.isfile(spec):
        path = spec
    else:
        path = os.path.join(scenes_dir or SCENES_DIR, name + ".json")
        if "/" in name or not os.path.isfile(path):
            raise AdviceError(f"scene {spec}: no such file and no builtin scene of that name")
    try:
        with open(path) as f:
            return json.load(f)
    except ValueError as e:
        raise AdviceError(f"scene {spec} is not valid JSON: {e}") from None


def classify_scene(scene):
    """'pair' (one mesh between two gears on fixed axes) or 'planetary'
    (a carrier, a ring or planets on a carrier, or the `train` short form);
    AdviceError for anything the table does not cover."""
    if not isinstance(scene, dict):
        raise AdviceError("the scene is not a JSON object")
    train = scene.get("train")
    if isinstance(train, dict):
        if train.get("type") == "planetary":
            return "planetary", "a planetary train (train short form)"
        raise AdviceError(f"train type {train.get('type')!r}: no table rows for it")
    bodies = scene.get("bodies") or []
    meshes = scene.get("meshes") or []
    joints = scene.get("joints") or []
    if not meshes:
        raise AdviceError("the scene has no gear mesh: the trade-off table measures meshing trains only "
                          "(nothing to choose a mesh fidelity for)")
    carriers = [b.get("name") for b in bodies if isinstance(b, dict) and b.get("type") == "carrier"]
    rings = [b.get("name") for b in bodies if isinstance(b, dict) and b.get("kind") == "internal"]
    on_carrier = [j.get("body") for j in joints if isinstance(j, dict) and j.get("type") == "on_carrier"]
    if carriers or rings or on_carrier:
        return "planetary", (f"a planetary train ({len(meshes)} meshes"
                             + (f", carrier {carriers[0]}" if carriers else "")
                             + (f", ring {rings[0]}" if rings else "") + ")")
    if len(meshes) == 1:
        g = meshes[0].get("gears") if isinstance(meshes[0], dict) else None
        return "pair", f"a gear pair ({' / '.join(map(str, g)) if g else 'one mesh'})"
    raise AdviceError(f"the scene is a chain of {len(meshes)} meshes without a carrier: the table measures "
                      "a single pair (contact_drive) and a planetary train (planetary_contact) only")


def read_table(path):
    """Rows of the trade-off CSV as dicts; columns by header name. Outputs
    are the `err_<name>` columns (relative error against the reference)."""
    try:
        with open(path, newline="") as f:
            rd = csv.DictReader(f)
            rows = list(rd)
            header = rd.fieldnames or []
    except OSError as e:
        raise AdviceError(f"cannot read the table {path}: {e.strerror}") from None
    need = ["scene", "level", "h", "cost"]
    missing = [c for c in need if c not in header]
    if missing:
        raise AdviceError(f"table {path}: no column {', '.join(missing)} (header: {', '.join(header)})")
    outputs = [c[4:] for c in header if c.startswith("err_") and len(c) > 4]
    return rows, outputs


def num(x):
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


# Longer names of the table's outputs, as the docs speak of them.
OUTPUT_ALIASES = {"dte_rms": "dte", "peak_force": "force", "mesh_order": "mesh", "output_speed": "speed"}


def parse_targets(specs, outputs):
    targets = {}
    for t in specs:
        name, eq, val = t.partition("=")
        name = name.strip()
        if name not in outputs and OUTPUT_ALIASES.get(name) in outputs:
            name = OUTPUT_ALIASES[name]
        if not eq or not name:
            raise AdviceError(f"target {t!r}: write OUTPUT=REL_ERR, e.g. speed=1e-3", 2)
        if name not in outputs:
            raise AdviceError(f"unknown output {name!r} in target {t!r}; the table has: {', '.join(outputs)}", 2)
        v = num(val)
        if v is None or v <= 0:
            raise AdviceError(f"target {t!r}: the relative error must be a positive number (e.g. {name}=0.01)", 2)
        if name in targets:
            raise AdviceError(f"output {name!r} is targeted twice", 2)
        targets[name] = v
    if not targets:
        raise AdviceError("give at least one --target OUTPUT=REL_ERR "
                          f"(outputs: {', '.join(outputs)})", 2)
    return targets


def setting(r):
    ref = r.get("refine") or "0"
    s = {"level": r["level"], "h": num(r["h"]), "refine": int(num(ref) or 0), "cost": num(r["cost"])}
    if r.get("scheme"):  # the elastic rows' numerics.contact (tables since issue 15)
        s["scheme"] = r["scheme"]
    if (num(r.get("scale")) or 1.0) != 1.0:  # the order's default mesh counts times this (o2sS)
        s["scale"] = num(r["scale"])
    if num(r.get("zeta")):  # Rayleigh damping of the elastic gears, at 9.2 kHz (tables since issue 15)
        s["zeta"] = num(r["zeta"])
    return s


def label(r):
    return label_s(setting(r))


def advise(scene, table_path, target_specs, scene_label):
    kind, why = classify_scene(scene)
    rows, outputs = read_table(table_path)
    if not outputs:
        raise AdviceError(f"table {table_path}: no err_<output> columns")
    targets = parse_targets(target_specs, outputs)
    tscene = TABLE_SCENE[kind]
    mine = [r for r in rows if r.get("scene") == tscene and num(r.get("cost")) is not None]
    if not mine:
        raise AdviceError(f"{scene_label} is {why}, measured on {tscene}, but table {table_path} has no "
                          f"{tscene} rows")
    # The reference (every error 0 by definition, but the peak force's, which
    # may be against its model converged further in the step) is what the
    # others are measured against: it is no candidate.
    is_ref = [all(num(r.get("err_" + o)) == 0 for o in outputs if o != "force") for r in mine]
    ref = [r for r, f in zip(mine, is_ref) if f]
    cands = sorted((r for r, f in zip(mine, is_ref) if not f), key=lambda r: num(r["cost"]))

    def errors(r):
        return {o: num(r.get("err_" + o)) for o in targets}

    def meets(r):
        return all(e is not None and e <= targets[o] for o, e in errors(r).items())

    if not cands:
        raise AdviceError(f"table {table_path}: no {tscene} row besides the reference (error 0) to propose")
    ok = [r for r in cands if meets(r)]
    result = {"scene": scene_label, "scene_kind": kind, "scene_description": why, "table": table_path,
              "table_scene": tscene, "targets": targets,
              # tables with the damping column time each row in CPU seconds (a shared machine)
              "cost_unit": "CPU" if "zeta" in rows[0] else "wall",
              "reference": ({**setting(ref[0])} if ref else None)}
    if not ok:
        best = {}
        for o in targets:
            vals = [(num(r.get("err_" + o)), r) for r in cands if num(r.get("err_" + o)) is not None]
            if vals:
                e, r = min(vals, key=lambda t: t[0])
                best[o] = {"error": e, **setting(r)}
        closest = min(cands, key=lambda r: max((e if e is not None else math.inf) / targets[o]
                                                   for o, e in errors(r).items()))
        parts = [f"{o} {b['error']:.3g} ({label_s(b)})" for o, b in best.items()]
        ce = ", ".join(f"{o} {e:.3g}" for o, e in errors(closest).items())
        raise AdviceError(
            f"no level meets the target ({', '.join(f'{o} <= {v:g}' for o, v in targets.items())}) on "
            f"{tscene}. Best achievable error: {'; '.join(parts)}. Closest single setting: "
            f"{label(closest)} ({ce}). The reference ({label(ref[0]) if ref else 'none'}) is the "
            "measure of the others and has no measured error of its own.", 1)
    choice = ok[0]
    cost = num(choice["cost"])
    rejected = []
    for r in cands:
        if num(r["cost"]) >= cost or r is choice:
            continue
        failed = {o: e for o, e in errors(r).items() if e is None or e > targets[o]}
        rejected.append({**setting(r), "failed": failed})
    result["choice"] = {**setting(choice), "errors": errors(choice)}
    result["rejected"] = rejected
    return result


def label_s(s):
    return (f"{s['level']} h {s['h']:g}" + (f" refine {s['refine']}" if s.get("refine") else "")
            + (f" counts x {s['scale']:g}" if s.get("scale") else "")
            + (f" ({s['scheme']}" + (f", damping {s['zeta']:g}" if s.get("zeta") else "") + ")"
               if s.get("scheme") else ""))


def advice_text(res):
    c = res["choice"]
    lines = [f"scene {res['scene']}: {res['scene_description']}; measured rows: {res['table_scene']} "
             f"({res['table']})",
             "targets (relative error against the reference"
             + (f", {label_s(res['reference'])}" if res.get("reference") else "") + "): "
             + ", ".join(f"{o} <= {v:g}" for o, v in res["targets"].items()),
             f"advice: {c['level']}, time step {c['h']:g} s"
             + (f", refine {c['refine']}" if c["level"] == "contact" or c["refine"] else "")
             + (f", numerics.contact \"{c['scheme']}\"" if c.get("scheme") else "")
             + (f", elastic gears with \"reduction\": {{\"f_max_hz\": {0.3 / c['h']:g}}}"
                if c["level"] == "reduced" else "")
             + (f", meshes \"model\": \"ltca\" (rigid gears, the pair's loaded tooth contact analysis tables)"
                if c["level"] == "ltca" else "")
             + (f", mesh counts x {c['scale']:g}" if c.get("scale") else "")
             + (f", material \"damping_ratio\": {c['zeta']:g}, \"damping_hz\": 9200" if c.get("zeta") else "")
             + f"; cost {c['cost']:.3g} {res.get('cost_unit', 'wall')} s per simulated s",
             "  measured error: " + ", ".join(f"{o} {e:.3g} (target {res['targets'][o]:g})"
                                              for o, e in c["errors"].items())]
    if res["rejected"]:
        lines.append("cheaper settings rejected:")
        for r in res["rejected"]:
            why = ", ".join(f"{o} {e:.3g} > {res['targets'][o]:g}" if e is not None else f"{o} not measured"
                            for o, e in r["failed"].items())
            lines.append(f"  {label_s(r)} ({r['cost']:.3g} s/s): {why}")
    else:
        lines.append("no cheaper setting in the table")
    lines.append(f"(figures measured on {res['table_scene']}; for another load or geometry they are indicative)")
    return "\n".join(lines)

