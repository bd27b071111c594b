#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""A scene's `"fidelity": {"targets": {...}}`: the daemon picks the cheapest
rung of the measured trade-off table that meets the targets, the choice
gearctl advise makes.

1. The same choice as advise.py (clients/python/gearsim/advise.py) on the
   shipped table and on the frozen fixture, over a grid of single and
   paired targets on both measured scenes: the same row (level, h, refine,
   cost) and the same cheaper rows rejected, or both refusing.
2. Through the daemon (-n 2): contact_drive at dte 5 % loads with ltca
   meshes and rigid gears; the load reply, `status`, `state` and the HDF5
   record's attributes carry the choice and why, and so does the run
   restored from its checkpoint; a planetary train written
   with the `train` short form is classified as a planetary train; bad
   targets are refused naming the field (unknown output, a target nothing
   meets, a scene the table does not measure) and the daemon stays up.
"""
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import h5py  # noqa: E402

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

sys.path.insert(0, os.path.join(dmod.SOURCE_ROOT, "clients", "python"))
from gearsim import advise as adv  # noqa: E402
from gearsim.errors import GearsimError  # noqa: E402

R = Results("test_fidelity_targets: the scene's accuracy targets pick the rung")
TOOL = os.path.join(dmod.BUILD_ROOT, "tests", "integration", "tradeoff_choose")
TABLES = [os.path.join(dmod.SOURCE_ROOT, "docs", "data", "tradeoff.csv"),
          os.path.join(dmod.SOURCE_ROOT, "tests", "integration", "tradeoff_fixture.csv")]
SCENES = {"contact_drive": {"meshes": [{"gears": ["a", "b"]}]},
          "planetary_contact": {"bodies": [{"name": "c", "type": "carrier"}], "meshes": [{}]}}


def c_choice(table, scene, targets):
    spec = ",".join(f"{k}={v!r}" for k, v in targets.items())
    out = subprocess.run([TOOL, table, scene, spec], capture_output=True, text=True, timeout=60, check=True)
    return json.loads(out.stdout)


def py_choice(table, scene, targets):
    try:
        res = adv.advise(SCENES[scene], table, [f"{k}={v!r}" for k, v in targets.items()], scene)
    except adv.AdviceError as e:
        return {"error": str(e)}
    ch = res["choice"]
    return {"level": ch["level"], "h": ch["h"], "refine": ch["refine"], "cost": ch["cost"],
            "rejected": [adv.label_s(r) for r in res["rejected"]]}


def same_as_advise():
    grid = []
    for v in (1.0, 0.5, 0.35, 0.1, 0.05, 0.04, 0.03, 0.02, 0.012, 0.005, 1e-4):
        for o in ("dte", "force", "mesh", "speed"):
            grid.append({o: v})
    for a, b in ((0.05, 0.1), (0.05, 0.02), (0.2, 0.05), (0.04, 0.012), (0.5, 0.5)):
        grid.append({"dte": a, "force": b})
        grid.append({"dte": a, "mesh": b})
    for table in TABLES:
        with open(table) as f:
            scenes = {line.split(",")[0] for line in f.readlines()[1:] if line.strip()}
        for scene in SCENES:
            if scene not in scenes:
                continue
            bad, chosen = [], set()
            for t in grid:
                c, p = c_choice(table, scene, t), py_choice(table, scene, t)
                if "error" in c or "error" in p:
                    if not ("error" in c and "error" in p):
                        bad.append((t, c, p))
                    continue
                chosen.add(c["level"])
                if (c["level"], c["h"], c["refine"], c["cost"], c["rejected"]) != \
                        (p["level"], p["h"], p["refine"], p["cost"], p["rejected"]):
                    bad.append((t, c, p))
            R.check(f"{os.path.basename(table)} {scene}: the daemon's choice is advise's on {len(grid)} targets "
                    f"({len(chosen)} different rungs chosen)", not bad and len(chosen) >= 3, bad[:3])


def scene_with(name, fid):
    s = dmod.load_scene(name)
    s["fidelity"] = fid
    return s


def expect_error(c, scene, field, says, name):
    try:
        c.load(scene=scene)
    except GearsimError as e:
        R.check(name, e.field == field and says in e.message, (e.code, e.field, e.message))
        return
    R.check(name, False, "loaded")


def through_daemon():
    with dmod.Daemon(ranks=2) as d:
        with d.client() as c:
            r = c.load(scene=scene_with("contact_drive", {"targets": {"dte": 0.05}}))
            fc = r.get("fidelity_choice") or {}
            ch = fc.get("choice", {})
            R.check("load: ltca chosen for dte 5 % on the pair, measured on contact_drive",
                    ch.get("level") == "ltca" and fc.get("table_scene") == "contact_drive"
                    and fc.get("scene_kind") == "pair" and ch.get("errors", {}).get("dte", 1) <= 0.05, fc)
            R.check("load: the meshes are ltca and the gears rigid",
                    all(m.get("model") == "ltca" for m in r["meshes"])
                    and all(b.get("model") == "rigid" for b in r["bodies"]), r["meshes"])
            R.check("load: why names the cheaper rungs that miss",
                    "cheapest" in fc.get("why", "") and len(fc.get("rejected", [])) >= 5
                    and all(x["failed"]["dte"] > 0.05 for x in fc["rejected"]), fc.get("why"))
            R.check("load: the scene's finer time step kept", r.get("time_step") == 1e-5
                    and fc.get("time_step") == 1e-5, (r.get("time_step"), fc.get("time_step")))
            st = c.status()
            R.check("status carries the choice", st.get("fidelity_choice") == fc, st.get("fidelity_choice"))
            R.check("state carries the choice", c.state().get("fidelity_choice") == fc)
            c.record("targets.h5")
            c.advance(steps=200, timeout=300)
            c.record(stop=True)
            with h5py.File(d.path("targets.h5"), "r") as f:
                a = f.attrs.get("fidelity_choice")
                a = a.decode() if isinstance(a, bytes) else a
            R.check("the record's attributes carry the choice", a is not None and json.loads(a) == fc, a)
            step = c.status().get("step")
            c.checkpoint("targets.ckpt")
            c.unload()
            rr = c.restore("targets.ckpt")
            R.check("a checkpoint keeps the choice: restored, status carries it",
                    rr.get("step") == step and c.status().get("fidelity_choice") == fc,
                    (rr, c.status().get("fidelity_choice")))

            tr = {"name": "short train", "train": {
                "type": "planetary", "module_mm": 2.5, "face_width_mm": 10, "sun": {"teeth": 24},
                "planet": {"teeth": 24}, "ring": {"teeth": 72, "addendum": 0.8}, "planets": 3,
                "carrier": {"mass": 1.5, "inertia": 0.002}},
                "loads": [{"body": "sun", "type": "ramp", "moment": 20.0, "ramp_time": 0.02},
                          {"body": "carrier", "type": "brake", "coefficient": 0.8}],
                "fidelity": {"targets": {"force": 0.05}}}
            r = c.load(scene=tr)
            fc = r.get("fidelity_choice") or {}
            R.check("train short form: a planetary train, measured on planetary_contact",
                    fc.get("scene_kind") == "planetary" and fc.get("table_scene") == "planetary_contact"
                    and fc.get("choice", {}).get("errors", {}).get("force", 1) <= 0.05, fc)
            c.unload()
            r = c.load(builtin="pair")
            R.check("a scene without targets has no choice", "fidelity_choice" not in r
                    and c.status().get("fidelity_choice") is None, r.get("fidelity_choice"))

            expect_error(c, scene_with("pair", {"targets": {"noise": 0.1}}), "args.scene.fidelity.targets.noise",
                         "dte", "unknown output refused naming it")
            expect_error(c, scene_with("pair", {"targets": {"dte": 1e-6}}), "args.scene.fidelity.targets",
                         "no measured setting", "a target nothing meets refused with the best reached")
            chain = dmod.load_scene("pair")
            chain["bodies"].append({**chain["bodies"][1], "name": "third"})
            chain.setdefault("joints", []).append({"body": "third", "type": "fixed_axis", "centre_mm": [0, 200]})
            chain["meshes"].append({**chain["meshes"][0], "name": "second", "gears": [chain["bodies"][1]["name"],
                                                                                         "third"]})
            chain["fidelity"] = {"targets": {"dte": 0.05}}
            expect_error(c, chain, "args.scene.fidelity.targets", "chain of 2 meshes",
                         "a chain of meshes (not measured) refused")
            R.check("the daemon answers after the refusals", c.status().get("state") in ("empty", "loaded"))


def main():
    R.guard("same choice as gearctl advise", same_as_advise)
    R.guard("through the daemon", through_daemon)
    R.finish()


if __name__ == "__main__":
    main()
