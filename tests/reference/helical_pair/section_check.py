#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The transverse section of the helical pair in 2D (gmsh 6-node triangles,
CalculiX CPE6 of thickness b, frictionless contact): the 3D reference's gear
sectors (TEETH teeth, free radial cuts, hub arc held / tied) against whole
gears, at one roll position. Measures how much of the 3D model's compliance
comes from its sector bodies (gearsim's planar analysis, like the spur
references, has whole gears), and, at the 3D model's own element sizes, how
far its mesh is from converged in the section.

--plane strain (default): plane strain. --plane stress: plane stress, solved
as plane strain with E' = E (1 + 2 nu) / (1 + nu)^2, nu' = nu / (1 + nu)
(the same in-plane equations, exact in 2D). --plane cps6: ccx's plane-stress
element CPS6 of thickness b, which ccx expands into 15-node wedges b thick:
with b = 20 mm against a 5 mm tooth that body is not in plane stress (kept
to show the difference; section_check.csv rows `cps6`).

Usage:  ./section_check.py [--roll 0] [--h 0.2] [--teeth 5 9 13 0] [--plane strain]
(teeth 0: whole gears, ../gearref.py's outline). Prints TE and k; appends
to section_check.csv. Never run by the test suite.
"""
import argparse
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, ".."))
import gearref  # noqa: E402
import run_helical as rh  # noqa: E402


def sector_deck(work, pair, g1, g2, roll, h, teeth, e_mpa, nu, grow=0.35):
    """2D sectors of `teeth` teeth (run_helical.sector_geo) meshed with the
    3D model's size function; the deck by gearref.write_inp."""
    os.makedirs(work, exist_ok=True)
    rh.TEETH = teeth
    a = pair["centre_mm"]
    th1, th2, k1, k2 = rh.placing(pair, g1, g2, roll)
    half = teeth // 2
    gw = gearref.GeoWriter()
    L = gw.lines
    L.insert(0, 'SetFactory("Built-in");')
    s1, c1, r1 = rh.sector_geo(gw, g1, (0.0, 0.0), th1, k1 - half, L, set(range(k1 - half, k1 + half + 1)))
    s2, c2, r2 = rh.sector_geo(gw, g2, (a, 0.0), th2, k2 - half, L, set(range(k2 - half, k2 + half + 1)))
    L.append("Physical Surface(1) = {%d};" % s1)
    L.append("Physical Surface(2) = {%d};" % s2)
    for tag, cs, rs, want in ((11, c1, r1, ("flank", "tip")), (12, c2, r2, ("flank", "tip")),
                              (21, c1, r1, ("hub",)), (22, c2, r2, ("hub",))):
        L.append("Physical Curve(%d) = {%s};" % (tag, ", ".join(str(c) for c, r in zip(cs, rs) if r in want)))
    rh.size_field(L, g1, g2, a, h, pair["mn_mm"], grow, None, "Mesh.Algorithm = 6;")
    geo = os.path.join(work, "pair.geo")
    msh = os.path.join(work, "pair.msh")
    with open(geo, "w") as f:
        f.write("\n".join(L) + "\n")
    subprocess.run(["nice", "gmsh", "-2", "-nt", "1", geo, "-o", msh, "-v", "1"], check=True,
                   stdout=subprocess.DEVNULL)
    nodes, elems = gearref.read_msh(msh)
    bad = gearref.jacobian_check(nodes, elems)
    if bad:
        raise RuntimeError("%d folded triangles in %s" % (len(bad), msh))
    gearref.write_inp(os.path.join(work, "pair.inp"), nodes, elems, e_mpa, nu,
                      pair["face_width_mm"], pair["torque_nmm"], pair["penalty"], 2, g1.g.rb)
    return len(nodes)


def whole_deck(work, pair, g1, g2, roll, h, e_mpa, nu):
    th1 = roll * g1.g.pitch
    th2 = pair["driven_angle0_rad"] - th1 * g1.g.z / g2.g.z
    info = gearref.build_position(work, g1.g, g2.g, (pair["centre_mm"], 0.0), th1, th2, h,
                                  e_mpa=e_mpa, nu=nu, face=pair["face_width_mm"],
                                  torque=pair["torque_nmm"], penalty=pair["penalty"], outline_mm=1.25)
    return info["nodes"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--roll", type=float, default=0.0)
    ap.add_argument("--h", type=float, default=0.2)
    ap.add_argument("--teeth", type=int, nargs="+", default=[5, 9, 13, 0])
    ap.add_argument("--plane", choices=("strain", "stress", "cps6"), default="strain")
    ap.add_argument("--work", default=os.path.join("/tmp", "helical_section_%d" % os.getpid()))
    args = ap.parse_args()
    pair, g1, g2 = rh.load_pair(os.path.join(HERE, "pair.json"))
    b = pair["face_width_mm"]
    F = pair["torque_nmm"] / g1.g.rb
    e_mpa, nu = pair["E_mpa"], pair["nu"]
    if args.plane == "stress":
        e_mpa, nu = e_mpa * (1.0 + 2.0 * nu) / (1.0 + nu) ** 2, nu / (1.0 + nu)
    for teeth in args.teeth:
        work = os.path.join(args.work, "t%d" % teeth)
        nn = (sector_deck(work, pair, g1, g2, args.roll, args.h, teeth, e_mpa, nu) if teeth
              else whole_deck(work, pair, g1, g2, args.roll, args.h, e_mpa, nu))
        inp = os.path.join(work, "pair.inp")
        if args.plane == "cps6":
            txt = open(inp).read().replace("TYPE=CPE6", "TYPE=CPS6")
            open(inp, "w").write(txt)
        rot, dt, cpu = gearref.run_ccx(work)
        te = g1.g.rb * rot * 1e3
        row = dict(roll="%.6f" % args.roll, h_mm=args.h, plane=args.plane, teeth=teeth or "whole", nodes=nn,
                   te_um="%.5f" % te, k_n_per_mm_um="%.4f" % (F / te / b), ccx_cpu_s="%.1f" % cpu)
        gearref.append_row(os.path.join(HERE, "section_check.csv"), list(row), row)
        print(row, flush=True)


if __name__ == "__main__":
    main()
