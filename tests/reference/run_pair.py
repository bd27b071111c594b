#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Run the CalculiX reference of one gear pair at given mesh levels and roll
positions, appending one row per run to DIR/runs.csv (raw results), then
summarise with summarise.py.

    run_pair.py DIR --h 0.2 0.1 0.05 [--positions 12] [--rolls 0 5 7]
                [--penalty 1e8] [--threads 1] [--keep]

DIR/pair.json describes the pair (see stiffness_30_20/pair.json).  A run
already in runs.csv (same h, roll, penalty) is skipped, so an interrupted
sweep resumes.  Work files go to a temporary directory (kept with --keep).
"""
import argparse
import json
import math
import os
import shutil
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gearref  # noqa: E402

FIELDS = ["roll", "h_mm", "penalty", "nodes", "elements", "dofs", "delta_rad", "te_m",
          "te_um", "k_n_per_m", "k_n_per_mm_um", "mesh_s", "ccx_s", "ccx_cpu_s", "driver_teeth",
          "driven_teeth"]


def make_gear(d):
    return gearref.Gear(d["teeth"], d["module_mm"], d.get("pressure_angle_deg", 20.0),
                        d.get("addendum", 1.0), d.get("dedendum", 1.25),
                        d.get("fillet", 0.38), d.get("profile_shift", 0.0),
                        d.get("hub_radius_mm", 0.0), d.get("thinning_mm", 0.0))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--h", type=float, nargs="+", required=True)
    ap.add_argument("--positions", type=int, default=12)
    ap.add_argument("--rolls", type=int, nargs="*")
    ap.add_argument("--penalty", type=float, default=1e8)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--keep", action="store_true")
    a = ap.parse_args()
    cfg = json.load(open(os.path.join(a.dir, "pair.json")))
    g1, g2 = make_gear(cfg["driver"]), make_gear(cfg["driven"])
    centre = cfg["centre_mm"]
    face = cfg["face_width_mm"]
    line_load = cfg.get("line_load_n_per_mm", 200.0)
    torque = line_load * face * g1.rb          # N mm, counter-clockwise on the driver
    force = torque / g1.rb
    th2_0 = cfg.get("driven_angle0_rad", 0.0)
    out = os.path.join(a.dir, "runs.csv")
    done = gearref.done_runs(out)
    rolls = a.rolls if a.rolls else range(a.positions)
    for h in a.h:
        for j in rolls:
            roll = j / a.positions
            if (h, round(roll, 6), a.penalty) in done:     # rolls are stored to 6 digits
                continue
            # kinematic angles as gearsim's stiffness analysis sets them
            th1 = roll * 2.0 * math.pi / g1.z
            th2 = th2_0 - th1 * g1.z / g2.z
            wd = tempfile.mkdtemp(prefix="gearref_")
            info = gearref.build_position(wd, g1, g2, (centre, 0.0), th1, th2, h,
                                          e_mpa=cfg.get("E_mpa", 210000.0),
                                          nu=cfg.get("nu", 0.3), face=face, torque=torque,
                                          penalty=a.penalty,
                                          outline_mm=cfg.get("outline_mm"))
            delta, dt, cpu = gearref.run_ccx(wd, a.threads)
            te_mm = g1.rb * delta
            row = dict(roll="%.6f" % roll, h_mm=h, penalty="%g" % a.penalty,
                       nodes=info["nodes"], elements=info["elements"], dofs=2 * info["nodes"],
                       delta_rad="%.10e" % delta, te_m="%.10e" % (te_mm * 1e-3),
                       te_um="%.6f" % (te_mm * 1e3),
                       k_n_per_m="%.6e" % (force / (te_mm * 1e-3)),
                       k_n_per_mm_um="%.5f" % (force / (te_mm * 1e3) / face),
                       mesh_s="%.2f" % info["mesh_s"], ccx_s="%.2f" % dt, ccx_cpu_s="%.2f" % cpu,
                       driver_teeth=" ".join(map(str, info["teeth1"])),
                       driven_teeth=" ".join(map(str, info["teeth2"])))
            gearref.append_row(out, FIELDS, row)
            print("h %.4g roll %.4f nodes %d TE %.4f um k %.4f N/(mm um) ccx %.1f s (cpu %.1f s)"
                  % (h, roll, info["nodes"], te_mm * 1e3, force / (te_mm * 1e3) / face, dt, cpu),
                  flush=True)
            if a.keep:
                print("  kept", wd)
            else:
                shutil.rmtree(wd, ignore_errors=True)


if __name__ == "__main__":
    main()
