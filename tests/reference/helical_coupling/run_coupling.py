#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""3D check of the slice analysis's coupling along the face
(docs/explanation/helical.md "Loaded tooth contact by slices"): one spur
tooth of the 20-tooth gear (module 2.5 mm, 20 deg, face 30 mm) with its rim
sector, extruded to a 3D body (gmsh, quadratic tetrahedra C3D10), hub arc
and the two radial cuts of the rim held, steel. A force normal to the
loaded flank is spread over a short strip (|z - z0| < 0.5 mm) on the pitch
line; the flank's normal displacement along the pitch line is written
against z. The slice analysis models the spread of a point load along the
face as exp(-|z - z0| / lambda) with lambda the tooth depth (5.625 mm
here); fit_decay() fits lambda to the 3D profile.

Usage: ./run_coupling.py [--h 0.8 0.6] [--z0 15]   (writes runs.csv)
Needs gmsh and ccx (deploy/install-deps.sh --reference). Never run by the
test suite."""
import argparse
import math
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))
import gearref  # noqa: E402

Z, M, B, E, NU = 20, 2.5, 30.0, 210000.0, 0.3
P_TOTAL = 1000.0  # N


def outline(g):
    fil, invl = g.half_tooth()
    ccw = fil + invl[1:]                  # root -> tip, ccw side
    cw = [(x, -y) for (x, y) in ccw]      # mirror
    return ccw, cw


def write_geo(path, g, h):
    ccw, cw = outline(g)
    half = math.pi / Z
    lines = ["SetFactory(\"Built-in\");"]
    pid = [0]

    def pt(p, lc):
        pid[0] += 1
        lines.append("Point(%d) = {%.12g, %.12g, 0, %g};" % (pid[0], p[0], p[1], lc))
        return pid[0]
    lc_t, lc_r = h, 2.5 * h
    o = pt((0, 0), lc_r)
    # cw side from root (fillet start) to tip
    cwi = [pt(p, lc_t) for p in cw]
    ccwi = [pt(p, lc_t) for p in ccw]
    rf, rh = g.rf, g.hub
    r1 = pt((rf * math.cos(-half), rf * math.sin(-half)), lc_r)
    r2 = pt((rf * math.cos(half), rf * math.sin(half)), lc_r)
    h1 = pt((rh * math.cos(-half), rh * math.sin(-half)), lc_r)
    h2 = pt((rh * math.cos(half), rh * math.sin(half)), lc_r)
    c = []
    cid = [0]

    def cur(kind, ids):
        cid[0] += 1
        lines.append("%s(%d) = {%s};" % (kind, cid[0], ", ".join(map(str, ids))))
        c.append(cid[0])
    cur("Circle", [h1, o, h2])            # hub arc (ccw)
    cur("Line", [h2, r2])                 # radial cut, ccw side
    cur("Circle", [r2, o, ccwi[0]])       # root arc to the ccw fillet
    cur("Spline", ccwi)                   # ccw flank root -> tip
    cur("Circle", [ccwi[-1], o, cwi[-1]]) # tip arc
    cur("Spline", list(reversed(cwi)))    # cw flank tip -> root
    cur("Circle", [cwi[0], o, r1])        # root arc
    cur("Line", [r1, h1])                 # radial cut, cw side
    lines.append("Curve Loop(1) = {%s};" % ", ".join(map(str, c)))
    lines.append("Plane Surface(1) = {1};")
    lines.append("out[] = Extrude {0, 0, %g} { Surface{1}; };" % B)
    lines.append("Physical Volume(\"body\") = {out[1]};")
    lines.append("Mesh.ElementOrder = 2;")
    lines.append("Mesh.SecondOrderLinear = 0;")
    lines.append("Mesh.HighOrderOptimize = 1;")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def read_inp_nodes(path):
    nodes, elems, mode = {}, [], None
    for ln in open(path):
        s = ln.strip()
        if s.startswith("*"):
            mode = "n" if s.upper().startswith("*NODE") else ("e" if "C3D10" in s.upper() else None)
            continue
        if mode == "n" and s:
            v = s.split(",")
            nodes[int(v[0])] = (float(v[1]), float(v[2]), float(v[3]))
        elif mode == "e" and s:
            elems.append([int(x) for x in s.split(",") if x.strip()])
    return nodes, elems


def run(h, z0, work):
    g = gearref.Gear(Z, M)
    os.makedirs(work, exist_ok=True)
    geo, inp = os.path.join(work, "tooth.geo"), os.path.join(work, "tooth_mesh.inp")
    write_geo(geo, g, h)
    t0 = time.time()
    subprocess.run(["gmsh", "-3", "-format", "inp", "-o", inp, geo], check=True, capture_output=True)
    nodes, elems = read_inp_nodes(inp)
    half = math.pi / Z
    # pitch point on the ccw flank and its inward normal (the contact force direction)
    ps = g.psi_inv(g.r)
    px, py = g.r * math.cos(ps), g.r * math.sin(ps)
    # involute normal at radius r: along the line of action, at angle (psi - alpha) + ... : numeric
    d = 1e-4
    p2 = (lambda R: (R * math.cos(g.psi_inv(R)), R * math.sin(g.psi_inv(R))))(g.r + d)
    tx, ty = (p2[0] - px) / d, (p2[1] - py) / d
    tn = math.hypot(tx, ty)
    tx, ty = tx / tn, ty / tn
    nx, ny = ty, -tx  # inward (towards the tooth centre, -y side for the ccw flank)
    if nx * (0 - px) + ny * (0 - py) < 0 and ny > 0:
        nx, ny = -nx, -ny
    fixed, load, meas = [], [], []
    tol = 0.6 * h
    for nid, (x, y, z) in nodes.items():
        R = math.hypot(x, y)
        a = math.atan2(y, x)
        if R < g.hub + 1e-6 or abs(abs(a) - half) < 1e-6 and R < g.rf + 1e-6:
            fixed.append(nid)
        on = g.rform < R < g.ra and abs(a - g.psi_inv(R)) * R < 1e-4 * M
        if on and abs(R - g.r) < tol:
            meas.append(nid)
            if abs(z - z0) <= 0.5 + 1e-9:
                load.append(nid)
    if not load:
        raise RuntimeError("no load nodes")
    deck = os.path.join(work, "tooth.inp")
    f = P_TOTAL / len(load)
    with open(deck, "w") as o:
        o.write("*INCLUDE, INPUT=tooth_mesh.inp\n*MATERIAL, NAME=STEEL\n*ELASTIC\n%g, %g\n" % (E, NU))
        o.write("*SOLID SECTION, ELSET=body, MATERIAL=STEEL\n")
        o.write("*NSET, NSET=FIX\n" + "".join("%d,\n" % n for n in fixed))
        o.write("*NSET, NSET=MEAS\n" + "".join("%d,\n" % n for n in meas))
        o.write("*BOUNDARY\nFIX, 1, 3\n*STEP\n*STATIC\n*CLOAD\n")
        for n in load:
            o.write("%d, 1, %.12g\n%d, 2, %.12g\n" % (n, f * nx, n, f * ny))
        o.write("*NODE PRINT, NSET=MEAS\nU\n*END STEP\n")
    c0 = os.times()
    subprocess.run(["ccx", "-i", "tooth"], cwd=work, check=True, capture_output=True,
                   env=dict(os.environ, OMP_NUM_THREADS="1"))
    c1 = os.times()
    cpu = (c1.children_user + c1.children_system) - (c0.children_user + c0.children_system)
    u = {}
    mode = False
    for ln in open(os.path.join(work, "tooth.dat")):
        if "displacements" in ln:
            mode = True
            continue
        v = ln.split()
        if mode and len(v) == 4:
            u[int(v[0])] = (float(v[1]), float(v[2]))
    prof = sorted((nodes[n][2], u[n][0] * nx + u[n][1] * ny) for n in meas if n in u)
    return prof, len(nodes), cpu, time.time() - t0


def fit_decay(prof, z0, lo=3.0, hi=10.0):
    """Least-squares slope of ln w against |z - z0| over lo..hi mm (both sides)."""
    pts = [(abs(z - z0), math.log(w)) for z, w in prof if lo <= abs(z - z0) <= hi and w > 0]
    n = len(pts)
    sx = sum(p[0] for p in pts)
    sy = sum(p[1] for p in pts)
    sxx = sum(p[0] ** 2 for p in pts)
    sxy = sum(p[0] * p[1] for p in pts)
    k = (n * sxy - sx * sy) / (n * sxx - sx * sx)
    return -1.0 / k


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--h", type=float, nargs="+", default=[0.8, 0.6])
    ap.add_argument("--z0", type=float, default=15.0)
    a = ap.parse_args()
    out = os.path.join(HERE, "runs.csv")
    new = not os.path.exists(out)
    with open(out, "a") as f:
        if new:
            f.write("h_mm,z0_mm,nodes,ccx_cpu_s,lambda_fit_mm,w_peak_um,profile_z_mm_w_um\n")
        for h in a.h:
            prof, nn, cpu, wall = run(h, a.z0, os.path.join("/tmp", "gs_coupling_%g" % h))
            lam = fit_decay(prof, a.z0)
            wpk = max(w for z, w in prof) * 1e3
            print("h %.2f mm: %d nodes, ccx CPU %.1f s, decay length %.3f mm, peak %.3f um" % (h, nn, cpu, lam, wpk))
            f.write("%g,%g,%d,%.2f,%.4f,%.5f,%s\n" % (h, a.z0, nn, cpu, lam, wpk,
                                                      ";".join("%.4f:%.6f" % (z, w * 1e3) for z, w in prof)))


if __name__ == "__main__":
    main()
