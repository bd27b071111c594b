#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Quasi-static TE of meshes of a scene at the mesh levels of the dynamic
convergence study (docs/validation/data.md): for every level (o<order>r<refine> or o<order>s<scale>, as
tests/bench/dyn_convergence_run names them) and mesh it writes a scene with
that mesh density on every elastic gear (o<order>f<n>: the order's default
mesh with the three teeth in contact refined n times, mesh.fine_teeth 3 and
mesh.fine_refine n, placed by the tool at the mesh's contact), runs gearsim-stiffness (plain FE
contact, --no-nearfield: what the dynamic model has) over one mesh cycle and
reduces the loaded TE (te_raw = te0 + te: the rigid closing of the
discretised flanks plus the elastic deflection, the static counterpart of
the kinematic TE the dynamic run measures) and its two parts to mean, rms
about the mean and peak-to-peak. One CSV row per (level, mesh).

Columns te_el_1pair_um / te_el_2pair_um: mean elastic TE over the positions
with one tooth pair in contact and with two or more.

  static_te_levels.py --scene deploy/scenes/planetary_contact.json \
      --mesh sun-planet1:6.6667 --mesh planet1-ring:-6.6667 \
      --levels o2r0 o2s1.5 o2r1 --positions 192 --out docs/data/x.csv

--mesh NAME:TORQUE (N m on the mesh's driver, signed). Runs one analysis
at a time (nice); the tool is taken from --tool (default build's)."""
import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from dyn_convergence import parse_level  # noqa: E402  (the study's level names)

DEFAULTS = {1: (8, 4, 3), 2: (8, 4, 2)}  # flank, across, rim of each order's default mesh


def level_mesh(level):
    m = re.fullmatch(r"o([12])f(\d)", level)
    if m:  # the default counts, the 3 teeth in contact refined fine_refine times
        return {"order": int(m.group(1)), "fine_teeth": 3, "fine_refine": int(m.group(2))}
    try:
        order, refine, scale, _ = parse_level(level)
    except ValueError:
        order = None
    if order not in DEFAULTS:
        sys.exit(f"level {level}: expected o<order>r<refine>, o<order>s<scale> or o<order>f<fine_refine>")
    if scale == 1.0:
        return {"order": order, "refine": refine}
    f, a, r = DEFAULTS[order]
    # dyn_convergence_run rounds with lround (half away from zero)
    return {"order": order, "flank": int(math.floor(f * scale + 0.5)), "across": int(math.floor(a * scale + 0.5)),
            "rim": int(math.floor(r * scale + 0.5))}


def stats(v):
    n = len(v)
    mean = sum(v) / n
    rms = math.sqrt(sum((x - mean) ** 2 for x in v) / n)
    return mean, rms, max(v) - min(v)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", required=True)
    ap.add_argument("--mesh", action="append", required=True, help="NAME:TORQUE")
    ap.add_argument("--levels", nargs="+", required=True)
    ap.add_argument("--positions", type=int, default=192)
    ap.add_argument("--tool", default=os.path.join(os.path.dirname(__file__), "..", "..", "build", "src",
                                                   "tools", "gearsim-stiffness"))
    ap.add_argument("--out", help="CSV to append rows to (header written when new)")
    a = ap.parse_args()
    with open(a.scene) as f:
        base = json.load(f)
    cols = ["scene", "level", "mesh", "torque_nm", "positions", "nodes", "te_raw_mean_um", "te_raw_rms_um", "te_raw_pp_um",
            "te_el_mean_um", "te_el_rms_um", "te_el_pp_um", "te0_mean_um", "te0_rms_um", "te0_pp_um",
            "te_el_1pair_um", "te_el_2pair_um", "unconverged", "cpu_s"]
    out = None
    if a.out:
        new = not os.path.exists(a.out)
        out = csv.writer(open(a.out, "a", newline=""))
        if new:
            out.writerow(cols)
    print(" | ".join(cols))
    for level in a.levels:
        sc = json.loads(json.dumps(base))
        for b in sc["bodies"]:
            if b.get("model") == "elastic":
                b.setdefault("mesh", {}).update(level_mesh(level))
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as t:
            json.dump(sc, t)
            path = t.name
        try:
            for spec in a.mesh:
                name, torque = spec.rsplit(":", 1)
                c0 = time.process_time()
                r = subprocess.run(["nice", a.tool, path, "--mesh", name, "--positions", str(a.positions),
                                    "--torque", torque, "--no-nearfield", "--json"],
                                   capture_output=True, text=True)
                if r.returncode != 0:
                    sys.exit(f"{level} {name}: {r.stderr.strip()}")
                d = json.loads(r.stdout)
                pts = d["points"]
                raw = stats([p["te_raw_um"] for p in pts])
                el = stats([p["te_elastic_um"] for p in pts])
                t0 = stats([p["te0_um"] for p in pts])
                one = [p["te_elastic_um"] for p in pts if p["pairs"] == 1]
                two = [p["te_elastic_um"] for p in pts if p["pairs"] >= 2]
                bad = sum(1 for p in pts if not p.get("converged", True))
                cpu = d.get("cpu", {}).get("cpu_s") if isinstance(d.get("cpu"), dict) else None
                row = [os.path.splitext(os.path.basename(a.scene))[0], level, name, torque, len(pts), "+".join(str(x) for x in d["nodes"]),
                       *(f"{x:.5f}" for x in raw), *(f"{x:.5f}" for x in el), *(f"{x:.5f}" for x in t0),
                       f"{sum(one) / len(one):.5f}" if one else "", f"{sum(two) / len(two):.5f}" if two else "", bad,
                       f"{cpu:.2f}" if cpu is not None else ""]
                print(" | ".join(str(x) for x in row), flush=True)
                if out:
                    out.writerow(row)
        finally:
            os.unlink(path)


if __name__ == "__main__":
    main()
