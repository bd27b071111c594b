#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The frequency response's --scene option (tests/bench/freq_response.py,
docs/explanation/modal.md "The relief pair at its design load"): a pair without loads
(deploy/scenes/pair_relief.json) gets contact_drive's driver and brake and
keeps its tooth modification in every point's scene. Checks (each can fail):
  - the default (no --scene) is contact_drive unchanged (its loads, its mesh
    order), so the old commands run the old points;
  - pair_relief gets the moment on its 30-tooth gear and the brake on the
    20-tooth one, the mesh's gears driver first (gearsim-modal --torque loads
    its first gear), --thinning on both gears, and the tip relief of the
    scene on both gears of every model's point scene;
  - the modification reaches the analysis the points and the FE mode run
    on: the quasi-static loaded TE of the contact point's scene, as written
    (gearsim-stiffness, default order-2 mesh, 12 positions, 70.5 N m on the
    wheel = 200 N/mm, the load the relief is sized for), has a peak-to-peak
    below 0.4 of the same scene with the modification taken out (measured
    1.21 against 4.91 um, plain FE for the unrelieved pair), and the
    relieved pair has fewer positions with two loaded pairs;
  - one dynamic point on the linear mesh (order 1, refine 0) at half the
    mesh mode runs through run_point for both scenes, in contact (no step
    without a contact row), and the relief changes its DTE rms by more than
    5 % (the points are deterministic: without the modification reaching
    the point the two rows are equal; measured 4.09 against 3.23 um: on the
    linear mesh the chords' excitation dominates, so the relief does not
    lower it there; on the coarse mesh both rattle).
About 10 s of CPU."""
import json
import os
import subprocess
import sys
import tempfile
import shutil

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))
from harness import Results  # noqa: E402

SOURCE = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.abspath(os.path.join(HERE, "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT") or os.path.join(SOURCE, "build")
sys.path.insert(0, os.path.join(SOURCE, "tests", "bench"))
import freq_response as fr  # noqa: E402

RELIEF = os.path.join(SOURCE, "deploy", "scenes", "pair_relief.json")
TORQUE = 70.5  # N m on the wheel: 2000 N along the line of action, 200 N/mm, the relief's design load

R = Results("test_freq_scene: freq_response.py --scene (pair_relief at its design load)")
work = tempfile.mkdtemp(prefix="gearsim_freq_scene_")

# The default is contact_drive as before.
cd = json.load(open(os.path.join(SOURCE, "deploy", "scenes", "contact_drive.json")))
d = fr.scene_for("contact", 9243.9, 0.12, 2, 80.0, "closure")
R.check("default scene: contact_drive's loads (moment set to 80 N m on its wheel, brake on its pinion)",
        [(ld["body"], ld["type"]) for ld in d["loads"]] == [(ld["body"], ld["type"]) for ld in cd["loads"]] and
        d["loads"][0]["moment"] == 80.0 and d["meshes"] == cd["meshes"], d["loads"])
R.check("default scene: bodies as contact_drive's plus material and mesh order",
        all({k: v for k, v in b.items() if k not in ("material", "mesh")} == c for b, c in zip(d["bodies"], cd["bodies"])),
        d["bodies"])

src = json.load(open(RELIEF))
mods = {b["name"]: b["modification"] for b in src["bodies"]}
R.check("pair_relief.json carries a tip relief on both gears and no loads", len(mods) == 2 and not src.get("loads"),
        mods)
scenes = {m: fr.scene_for(m, 9440.1, 0.05, 2, TORQUE, "closure", scene=RELIEF, thinning=0.05) for m in fr.MODELS}
s = scenes["contact"]
teeth = {b["name"]: b["teeth"] for b in s["bodies"]}
R.check("driver: the moment on the 30-tooth gear, the brake on the 20-tooth gear",
        s["loads"][0]["type"] == "ramp" and teeth[s["loads"][0]["body"]] == 30 and s["loads"][0]["moment"] == TORQUE
        and s["loads"][1]["type"] == "brake" and teeth[s["loads"][1]["body"]] == 20, s["loads"])
R.check("the mesh's gears driver first", s["meshes"][0]["gears"][0] == s["loads"][0]["body"], s["meshes"])
R.check("driver_teeth 30", fr.driver_teeth(s) == 30, fr.driver_teeth(s))
for m, sc in scenes.items():
    R.check("%s point scene: both gears keep the scene's modification, thinning 0.05 mm" % m,
            all(b.get("modification") == mods[b["name"]] and b.get("thinning_mm") == 0.05 for b in sc["bodies"]),
            sc["bodies"])


def static(scene, name, plain):
    path = os.path.join(work, name + ".json")
    json.dump(scene, open(path, "w"))
    args = [os.path.join(BUILD, "src", "tools", "gearsim-stiffness"), path, "--torque", repr(TORQUE),
            "--positions", "12", "--json"] + (["--plain"] if plain else [])
    r = subprocess.run(args, capture_output=True, text=True)
    if not R.check("gearsim-stiffness on the %s scene runs" % name, r.returncode == 0, r.stderr[-1500:]):
        R.finish()
    return json.loads(r.stdout)


bare = json.loads(json.dumps(s))
for b in bare["bodies"]:
    del b["modification"]
st_rel = static(s, "relief", False)
st_bare = static(bare, "bare", True)
pp_rel, pp_bare = st_rel["te_loaded_um"]["peak_to_peak"], st_bare["te_loaded_um"]["peak_to_peak"]
R.check("the contact point's scene is modified (the analysis says so)", st_rel["modified"] and not st_bare["modified"],
        (st_rel["modified"], st_bare["modified"]))
R.check("loaded TE p-p with the relief %.3f um < 0.4 x without %.3f um (%.2f)" % (pp_rel, pp_bare, pp_rel / pp_bare),
        pp_rel < 0.4 * pp_bare, (pp_rel, pp_bare))
R.check("the relief shortens the two-pair zone (%.3f < %.3f of the positions)" %
        (st_rel["fraction_multi_pair"], st_bare["fraction_multi_pair"]),
        st_rel["fraction_multi_pair"] < st_bare["fraction_multi_pair"],
        (st_rel["fraction_multi_pair"], st_bare["fraction_multi_pair"]))

# One dynamic point per scene, linear mesh, half the mode.
rows = {}
bare_path = os.path.join(work, "bare_src.json")
src_bare = json.loads(json.dumps(src))
for b in src_bare["bodies"]:
    del b["modification"]
json.dump(src_bare, open(bare_path, "w"))
for name, path in (("relief", RELIEF), ("bare", bare_path)):
    wd = os.path.join(work, "dyn_" + name)
    os.makedirs(wd)
    try:
        rows[name] = fr.run_point(BUILD, wd, "contact", 9440.1, 4720.0, 0.05, order=1, torque=TORQUE,
                                  contact="closure", settle=2e-3, min_measure=1.2e-3, min_cycles=5,
                                  scene=path, thinning=0.05)
    except SystemExit as e:
        R.check("run_point on the %s scene runs" % name, False, str(e))
        R.finish()
    pt = json.load(open(os.path.join(wd, "scene_contact.json")))
    R.check("%s: the point's scene as written %s the modification" % (name, "carries" if name == "relief" else "lacks"),
            all(("modification" in b) == (name == "relief") for b in pt["bodies"]), pt["bodies"])
    R.check("%s: balance below 1e-9 (%.1e)" % (name, rows[name]["balance_rel"]), rows[name]["balance_rel"] < 1e-9,
            rows[name])
    if "separated_fraction" in rows[name]:
        R.check("%s: the flanks stay in contact (%.3f of the steps without a row)" %
                (name, rows[name]["separated_fraction"]), rows[name]["separated_fraction"] == 0.0, rows[name])
yr, yb = rows["relief"]["dte_rms_um"], rows["bare"]["dte_rms_um"]
R.check("dynamic point at half the mode: the relief changes the DTE rms (%.3f against %.3f um, %+.1f %%)" %
        (yr, yb, 100 * (yr / yb - 1)), abs(yr / yb - 1) > 0.05, (yr, yb))
shutil.rmtree(work, ignore_errors=True)
R.finish()
