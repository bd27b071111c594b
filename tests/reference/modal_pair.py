#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""CalculiX perturbation (modal) reference of a loaded spur pair: a static
contact step under the moment, then a *FREQUENCY perturbation step about
the loaded contact state with both gears free to turn.  The first frequency
above the rigid rolling (0 Hz) is the pair's first mesh mode.

    modal_pair.py DIR --h 0.2 0.1 0.05 [--positions 4] [--rolls 0 2] [--keep]
    modal_pair.py DIR --summarise
    modal_pair.py DIR --record WORKDIR H J [--positions 4]

DIR/pair.json describes the pair (modal_30_20/pair.json).  Rows are
appended to DIR/runs.csv (a run already there is skipped); --summarise
writes DIR/reference.csv (per roll position: every level, the finest, the
change between the two finest).  See tests/reference/README.md "Modal
reference".

The mesh (gmsh) and the static part of the deck (nodes, elements, hub node
sets, contact surfaces) come from gearref.build_position, as for the
stiffness references; this script writes the rest of the deck:

* material with density; plane stress (CPS6) or strain (CPE6), thickness b;
* each gear's hub circle tied to a rigid small rotation about its own axis
  (u_x = -(y - y_c) theta, u_y = (x - x_c) theta; theta = dof 1 of a
  rotation node), the hub centres fixed in translation;
* each rotation node carries a MASS element whose mass, acting on dof 1 =
  theta, is the rotary inertia of the gear's rigid core, the solid hub disc
  0.5 pi rho b r_h^4 (as gearsim's elastic gear: the FE body is the annulus
  from the hub circle out, the core inside it is rigid);
* step 1 (static): the driver turned by a prescribed angle (the loaded
  flank gap plus about half the elastic approach) with the driven gear
  held, so that the contact is established; step 2 (static): the driver
  released and the moment applied, the driven gear's rotation still held
  (what the balancing moment of a free driven gear does: the same stresses
  and contact; a free pair under two balanced moments is singular in the
  rolling); step 3 (*FREQUENCY, perturbation): about the loaded state of
  step 2 (its contact and stiffness), both rotations free.
"""
import argparse
import csv
import json
import math
import os
import re
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gearref  # noqa: E402
from run_pair import make_gear  # noqa: E402

FIELDS = ["roll", "h_mm", "penalty", "nodes", "dofs", "theta_driver_rad", "rolling_hz", "f1_hz", "f2_hz", "f3_hz",
          "theta_ratio_1", "mesh_s", "ccx_s", "ccx_time_s"]
MODES = 4
# the rigid rolling comes out within +-60 Hz of 0 (the penalty contact's
# tangents), the first mesh mode near 8-10 kHz: the modes below this are the rolling
ROLLING_HZ = 1000.0
RMASS = 5.0        # mm: radius of the point masses that carry the cores' inertia


def modal_deck(workdir, cfg, g1, g2, centre2, theta0, penalty):
    """Turn gearref's static deck (pair.inp) into the modal deck."""
    path = os.path.join(workdir, "pair.inp")
    text = open(path).read()
    head = text[:text.index("*MATERIAL")]
    plane = cfg.get("plane", "strain")
    if plane == "stress":
        head = head.replace("TYPE=CPE6", "TYPE=CPS6").replace("TYPE=CPE3", "TYPE=CPS3")
    nodes, sets, cur, maxe = {}, {"HUB0": [], "HUB1": []}, None, 0
    for ln in head.splitlines():
        if ln.startswith("*"):
            m = re.search(r"NSET=(\w+)", ln)
            cur = ("node" if ln.startswith("*NODE") else
                   m.group(1) if ln.startswith("*NSET") and m else
                   "elem" if ln.startswith("*ELEMENT") else None)
            continue
        a = [t for t in ln.replace(",", " ").split()]
        if cur == "node":
            nodes[int(a[0])] = (float(a[1]), float(a[2]))
        elif cur == "elem":
            maxe = max(maxe, int(a[0]))
        elif cur in sets:
            sets[cur] += [int(t) for t in a]
    rot0 = max(nodes)                    # gearref's rotation node (its largest)
    rot1 = rot0 + 1
    rho = cfg.get("density_kg_m3", 7850.0) * 1e-12          # t/mm^3
    b = cfg["face_width_mm"]
    inertia = [0.5 * math.pi * rho * b * g.hub ** 4 for g in (g1, g2)]   # t mm^2
    o = [head.rstrip("\n")]
    o.append("*NODE, NSET=NROT1")
    o.append("%d, %.12f, 0, 0" % (rot1, centre2[0]))
    o.append("*NSET, NSET=NROTS")
    o.append("%d, %d" % (rot0, rot1))
    # the cores' rotary inertia: a point mass I / R^2 on each gear at R =
    # RMASS mm from its axis, carried rigidly by its rotation (ccx 2.20 stops
    # in the frequency step on a MASS element at a node with fixed dofs)
    cen = ((0.0, 0.0), centre2)
    pm = [rot1 + 1, rot1 + 2]
    for k in range(2):
        o.append("*NODE, NSET=PM%d" % k)
        o.append("%d, %.12f, %.12f, 0" % (pm[k], cen[k][0] + RMASS / math.sqrt(2.0),
                                           cen[k][1] + RMASS / math.sqrt(2.0)))
        o.append("*ELEMENT, TYPE=MASS, ELSET=M%d" % k)
        o.append("%d, %d" % (maxe + 1 + k, pm[k]))
        o.append("*MASS, ELSET=M%d" % k)
        o.append("%.12e" % (inertia[k] / RMASS ** 2))
    o.append("*MATERIAL, NAME=STEEL")
    o.append("*ELASTIC")
    o.append("%.10g, %.10g" % (cfg.get("E_mpa", 210000.0), cfg.get("nu", 0.3)))
    o.append("*DENSITY")
    o.append("%.10e" % rho)
    for name in ("E0", "E1"):
        o.append("*SOLID SECTION, ELSET=%s, MATERIAL=STEEL" % name)
        o.append("%.10g" % b)
    o.append("*EQUATION")
    a = RMASS / math.sqrt(2.0)
    for k, rn in enumerate((rot0, rot1)):      # u = theta x (a, a); w tied to the fixed NREF
        o += ["2", "%d, 1, 1., %d, 1, %.12f" % (pm[k], rn, a),
              "2", "%d, 2, 1., %d, 1, %.12f" % (pm[k], rn, -a),
              "2", "%d, 3, 1., %d, 3, -1." % (pm[k], rot0 - 1)]
    for hub, rn, c in (("HUB0", rot0, (0.0, 0.0)), ("HUB1", rot1, centre2)):
        gearref.hub_ties(o, nodes, set(sets[hub]), rn, c)
    gearref.contact_cards(o, penalty)
    fixed = ["NREF, 1, 3, 0", "NROT, 2, 3, 0", "NROT1, 2, 3, 0"]
    o.append("*BOUNDARY")
    o += fixed
    o += ["*STEP, INC=200", "*STATIC", "1., 1.", "*BOUNDARY",
          "NROT, 1, 1, %.10g" % theta0, "NROT1, 1, 1, 0", "*END STEP"]
    o += ["*STEP, INC=200", "*STATIC", "1., 1.", "*BOUNDARY, OP=NEW"] + fixed + ["NROT1, 1, 1, 0"]
    o += ["*CLOAD", "%d, 1, %.12g" % (rot0, cfg["moment_nm"] * 1e3),
          "*NODE PRINT, NSET=NROT", "U", "*END STEP"]
    o += ["*STEP, PERTURBATION", "*FREQUENCY", "%d" % MODES, "*BOUNDARY, OP=NEW"] + fixed
    o += ["*NODE PRINT, NSET=NROTS", "U", "*END STEP"]
    with open(path, "w") as f:
        f.write("\n".join(o) + "\n")
    return rot0, rot1


def parse_dat(workdir, rot0, rot1):
    dat = open(os.path.join(workdir, "pair.dat")).read()
    # static rotation of the driver (step 2's displacement block)
    blocks = re.split(r"\n\s*displacements", dat)
    theta = None
    for ln in blocks[1].strip().splitlines()[1:]:
        a = ln.split()
        if len(a) == 4 and a[0] == str(rot0):
            theta = float(a[1])
    i = dat.index("E I G E N V A L U E   O U T P U T")
    freqs = []
    for ln in dat[i:].splitlines()[1:]:
        a = ln.split()
        if len(a) == 5 and a[0].isdigit():
            freqs.append(float(a[3]))      # cycles/time (Hz: time in s with t, mm, N)
        elif freqs and not a:
            break
    # mode shapes: rotation amplitudes of both rotation nodes per mode
    ratios = []
    for blk in blocks[2:]:
        th = {}
        for ln in blk.strip().splitlines()[1:]:
            a = ln.split()
            if len(a) == 4:
                try:
                    th[int(a[0])] = float(a[1])
                except ValueError:
                    break
        if rot0 in th and rot1 in th and th[rot1] != 0.0:
            ratios.append(th[rot0] / th[rot1])
    return theta, freqs, ratios


def record(a, g1, wd, h, roll, nodes, mesh_s, dt, rot0, rot1):
    """Parse the finished ccx run in wd and append its row to DIR/runs.csv."""
    theta, freqs, ratios = parse_dat(wd, rot0, rot1)
    log = open(os.path.join(wd, "ccx.log")).read()
    m = re.search(r"Total CalculiX Time: *([0-9.eE+-]+)", log)
    nz = [f for f in freqs if f > ROLLING_HZ]  # above the rigid rolling
    row = dict(roll="%.6f" % roll, h_mm=h, penalty="%g" % a.penalty, nodes=nodes,
               dofs=2 * nodes, theta_driver_rad="%.10e" % theta,
               rolling_hz="%.4f" % freqs[0], f1_hz="%.4f" % nz[0], f2_hz="%.4f" % nz[1],
               f3_hz="%.4f" % nz[2],
               theta_ratio_1="%.6f" % ratios[len(freqs) - len(nz)],
               mesh_s="%.2f" % mesh_s, ccx_s="%.2f" % dt, ccx_time_s=m.group(1) if m else "nan")
    gearref.append_row(os.path.join(a.dir, "runs.csv"), FIELDS, row)
    print("h %.4g roll %.4f nodes %d TE %.4f um f1 %.2f Hz (f2 %.1f, f3 %.1f) 0 Hz modes %d "
          "ccx %.1f s" % (h, roll, nodes, theta * g1.rb * 1e3, nz[0], nz[1], nz[2],
                          len(freqs) - len(nz), dt), flush=True)


def recover(a, cfg):
    """--record WORKDIR H J: the row of a run kept in WORKDIR (--keep, or one
    whose parse failed), roll J / positions, level H."""
    wd, h, j = a.record[0], float(a.record[1]), int(a.record[2])
    g1 = make_gear(cfg["driver"])
    nodes, _ = gearref.read_msh(os.path.join(wd, "pair.msh"))
    rot0 = max(nodes) + 2                     # gearref's NREF, NROT follow the mesh nodes
    record(a, g1, wd, h, j / a.positions, len(nodes), float("nan"), float("nan"), rot0, rot0 + 1)


def run(a, cfg):
    g1, g2 = make_gear(cfg["driver"]), make_gear(cfg["driven"])
    centre = (cfg["centre_mm"], 0.0)
    th2_0 = cfg.get("driven_angle0_rad", 0.0)
    out = os.path.join(a.dir, "runs.csv")
    done = gearref.done_runs(out)
    # the loaded flanks' gap at the centred phase: half the normal backlash
    jn = (cfg["driver"].get("thinning_mm", 0.0) + cfg["driven"].get("thinning_mm", 0.0)) \
        * math.cos(g1.alpha)
    force = cfg["moment_nm"] * 1e3 / g1.rb
    theta0 = (0.5 * jn + 0.5 * force / (15.0 * cfg["face_width_mm"]) * 1e-3) / g1.rb
    rolls = a.rolls if a.rolls else range(a.positions)
    for h in a.h:
        for j in rolls:
            roll = j / a.positions
            if (h, round(roll, 6), a.penalty) in done:
                continue
            th1 = roll * 2.0 * math.pi / g1.z
            th2 = th2_0 - th1 * g1.z / g2.z
            wd = tempfile.mkdtemp(prefix="gearmodal_")
            info = gearref.build_position(wd, g1, g2, centre, th1, th2, h,
                                          e_mpa=cfg.get("E_mpa", 210000.0), nu=cfg.get("nu", 0.3),
                                          face=cfg["face_width_mm"], torque=cfg["moment_nm"] * 1e3,
                                          penalty=a.penalty, outline_mm=cfg.get("outline_mm"))
            rot0, rot1 = modal_deck(wd, cfg, g1, g2, centre, theta0, a.penalty)
            t0 = time.time()
            try:
                gearref.run_ccx(wd, a.threads)
            except RuntimeError:
                # run_ccx's own parse of the static rotation looks for gearref's deck
                if not os.path.exists(os.path.join(wd, "pair.dat")):
                    raise
            record(a, g1, wd, h, roll, info["nodes"], info["mesh_s"], time.time() - t0, rot0, rot1)
            if a.keep:
                print("  kept", wd)
            else:
                shutil.rmtree(wd, ignore_errors=True)


def summarise(a):
    rows = list(csv.DictReader(open(os.path.join(a.dir, "runs.csv"))))
    by = {}
    for r in rows:
        by.setdefault(float(r["roll"]), []).append(r)
    out = []
    print("first mesh mode (Hz) per roll position and level; change = finest / next - 1")
    for roll in sorted(by):
        rs = sorted(by[roll], key=lambda r: -float(r["h_mm"]))
        f = [float(r["f1_hz"]) for r in rs]
        ch = f[-1] / f[-2] - 1.0 if len(f) > 1 else float("nan")
        print("  roll %.4f  %s  change %+.3f %%" % (
            roll, "  ".join("h %s: %.2f" % (r["h_mm"], v) for r, v in zip(rs, f)), 100 * ch))
        out.append(dict(roll="%.6f" % roll, h_finest=rs[-1]["h_mm"], f1_hz="%.4f" % f[-1],
                        f1_next_hz="%.4f" % (f[-2] if len(f) > 1 else float("nan")),
                        change_pct="%.4f" % (100 * ch),
                        te_um="%.5f" % (float(rs[-1]["theta_driver_rad"]) * 1e3 *
                                        make_gear(json.load(open(os.path.join(
                                            a.dir, "pair.json")))["driver"]).rb)))
    with open(os.path.join(a.dir, "reference.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(out[0]))
        w.writeheader()
        w.writerows(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--h", type=float, nargs="+")
    ap.add_argument("--positions", type=int, default=4)
    ap.add_argument("--rolls", type=int, nargs="*")
    ap.add_argument("--penalty", type=float, default=1e8)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--keep", action="store_true")
    ap.add_argument("--summarise", action="store_true")
    ap.add_argument("--record", nargs=3, metavar=("WORKDIR", "H", "J"))
    a = ap.parse_args()
    if a.summarise:
        summarise(a)
        return
    if a.record:
        recover(a, json.load(open(os.path.join(a.dir, "pair.json"))))
        return
    run(a, json.load(open(os.path.join(a.dir, "pair.json"))))


if __name__ == "__main__":
    main()
