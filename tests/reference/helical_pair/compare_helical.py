#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Compare gearsim's slice analysis of the helical pair (scene.json) with the
stored 3D CalculiX reference (reference.csv), aligned and misaligned.

    compare_helical.py [--build DIR] [--tool PATH] [--plane stress|strain] [--json]

Runs `gearsim-stiffness scene.json --json --positions N --no-tangent` (N =
pair.json's positions; rolls j/N, compared where the reference has them), and the same scene with
meshes[0].misalignment.in_plane_um = f for each misalignment f the
reference holds (each gear sector size of the reference, teeth per gear
body, compared on its own). --plane sets both gears' material.plane (without
it: the scene's default, plane strain for this face of 8 normal modules). Per position: the elastic TE (um, from first contact),
the mesh stiffness k = F / (TE b) (N/(mm um)) and the peak of the load per
unit face width along the face, summed over the contact lines, both sides
averaged over the reference's NBIN equal bins of the face, the peak the
largest mean over 4 neighbouring bins (summarise_helical.peak_of). Errors are
gearsim / reference - 1. Nothing is asserted here
(tests/validation/test_helical_reference.py does that).
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

import summarise_helical

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
NBIN = 20


def load_reference():
    ref = {}
    for r in csv.DictReader(open(os.path.join(HERE, "reference.csv"))):
        teeth = int(r.get("sector_teeth") or 5)
        ref.setdefault((float(r["misalign_um"]), teeth), []).append(dict(
            roll=float(r["roll"]), te=float(r["te_um"]), k=float(r["k_n_per_mm_um"]),
            peak=float(r["peak_n_per_mm"]), h=float(r["h_mm"]), levels=int(r["levels"]),
            te_change=float(r["te_change_pct"]), peak_change=float(r["peak_change_pct"]),
            finer=float(r["finer_h_mm"]) if r["finer_h_mm"] else None,
            cpu=float(r["ccx_cpu_s"]), force=float(r["force_n"]), hub_force=float(r["hub_force_n"]),
            contact_force=float(r["contact_force_n"]),
            q=[float(r["q%02d" % i]) for i in range(NBIN)]))
    for f in ref:
        ref[f].sort(key=lambda r: r["roll"])
    return ref


def find_tool(build):
    src = os.path.normpath(os.path.join(HERE, "..", "..", ".."))
    build = build or os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(src, "build"))
    return os.path.join(build, "src", "tools", "gearsim-stiffness")


def binned(z, q, b, nbin=NBIN):
    """Mean of the profile q (at slice centres z from the face centre) over
    nbin equal bins of the face."""
    acc, cnt = [0.0] * nbin, [0] * nbin
    for zi, qi in zip(z, q):
        i = min(max(int((zi + 0.5 * b) / b * nbin), 0), nbin - 1)
        acc[i] += qi
        cnt[i] += 1
    return [a / c if c else 0.0 for a, c in zip(acc, cnt)]


def run_gearsim(tool, scene, n, misalign_um, plane=None):
    sc = json.load(open(scene))
    if plane:
        for b in sc["bodies"]:
            b.setdefault("material", {})["plane"] = plane
    if misalign_um:
        sc["meshes"][0]["misalignment"] = {"in_plane_um": misalign_um, "out_of_plane_um": 0}
    fd, path = tempfile.mkstemp(suffix=".json")
    with os.fdopen(fd, "w") as f:
        json.dump(sc, f)
    try:
        out = subprocess.run([tool, path, "--json", "--positions", str(n), "--no-tangent"],
                             capture_output=True, text=True)
    finally:
        os.remove(path)
    if out.returncode != 0:
        raise RuntimeError("gearsim-stiffness failed: " + out.stderr.strip())
    return json.loads(out.stdout)


def compare(tool, plane=None):
    """{(misalignment, sector teeth): dict(rows=[...], summary)} for every
    misalignment and gear sector size of the reference."""
    ref = load_reference()
    n = json.load(open(os.path.join(HERE, "pair.json")))["positions"]
    res = {}
    runs = {}
    for (f, teeth), rr in sorted(ref.items()):
        if f not in runs:
            runs[f] = run_gearsim(tool, os.path.join(HERE, "scene.json"), n, f, plane)
        g = runs[f]
        b = g["face_width_mm"]
        sl = g["slice_analysis"]
        rows = []
        for r in rr:
            j = int(round(r["roll"] * n))
            p = g["points"][j]
            if abs(p["roll"] - r["roll"]) > 1e-6:
                raise RuntimeError("roll %g against the reference's %g" % (p["roll"], r["roll"]))
            qb = binned(sl["face_z_mm"], sl["face_load_n_per_mm"][j], b)
            pk = summarise_helical.peak_of(qb)
            rows.append(dict(roll=r["roll"], te=p["te_elastic_um"], te_ref=r["te"], k=p["k"], k_ref=r["k"],
                             peak=pk, peak_ref=r["peak"], err_te=p["te_elastic_um"] / r["te"] - 1.0,
                             err_k=p["k"] / r["k"] - 1.0,
                             err_peak=pk / r["peak"] - 1.0 if r["peak"] == r["peak"] else None,
                             h=r["h"], te_change=r["te_change"], peak_change=r["peak_change"], cpu=r["cpu"]))
        kmean = sum(x["k"] for x in rows) / len(rows)
        kmean_ref = sum(x["k_ref"] for x in rows) / len(rows)
        summ = dict(positions=len(rows), cycle_positions=n, max_err_k=max(abs(x["err_k"]) for x in rows), max_err_te=max(abs(x["err_te"]) for x in rows),
                    max_err_peak=max((abs(x["err_peak"]) for x in rows if x["err_peak"] is not None), default=None),
                    k_mean=kmean, k_mean_ref=kmean_ref,
                    err_k_mean=kmean / kmean_ref - 1.0 if len(rows) == n else None, seconds=g.get("seconds"),
                    k_hbeta=sl["k_hbeta"], coupling_mm=sl["coupling_mm"])
        res[(f, teeth)] = dict(rows=rows, summary=summ)
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build")
    ap.add_argument("--tool")
    ap.add_argument("--plane", choices=("stress", "strain"), help="both gears' material.plane")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    res = compare(a.tool or find_tool(a.build), a.plane)
    if a.json:
        print(json.dumps({"%g um, %d teeth" % k: v for k, v in res.items()}, indent=1))
        return
    for (f, teeth), r in res.items():
        print("misalignment %g um (in the plane of action, over the face); reference gear sectors of %d teeth"
              % (f, teeth))
        print("  roll    TE um   ref TE  err TE%       k    ref k  err k%   peak  ref peak err pk%  "
              "ref h  ref dTE%  ref dpk%")
        for x in r["rows"]:
            print("%6.3f %8.4f %8.4f %7.2f %8.3f %8.3f %7.2f %6.1f %8.1f %7.2f %6g %9.3f %9.3f" % (
                x["roll"], x["te"], x["te_ref"], 100 * x["err_te"], x["k"], x["k_ref"], 100 * x["err_k"],
                x["peak"], x["peak_ref"], 100 * x["err_peak"] if x["err_peak"] is not None else float("nan"),
                x["h"], x["te_change"], x["peak_change"]))
        s = r["summary"]
        pct = (lambda v: "%.2f %%" % (100 * v) if v is not None else "n/a")
        print("  max |err|: k %s, TE %s, peak %s; mean k over the positions %.3f against %.3f "
              "(cycle mean: %s)\n" % (pct(s["max_err_k"]), pct(s["max_err_te"]), pct(s["max_err_peak"]),
                                       s["k_mean"], s["k_mean_ref"], pct(s["err_k_mean"])))


if __name__ == "__main__":
    sys.exit(main())
