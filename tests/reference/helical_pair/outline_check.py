#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim's transverse section of the helical pair against the outline the
references mesh (../gearref.py, basic-rack formulas): writes the section as
a spur pair (scene.json with the helix removed and the rack in transverse
values, as docs/tools/helical_sweep.py builds it, in plane strain or with
--plane stress), meshes it with gearsim-mesh and compares the boundary nodes
of both gears with the exact outline after fitting the rotation of the
tooth pattern: the involute nodes by the closed form, the fillet nodes by
the nearest point of a dense sampling of the trochoid; also the tip, root
and hub radii. The same spur scene is what section_check.py's 2D ccx model
is compared against (`gearsim-stiffness SCENE --positions 8 --no-tangent`).

Usage:  ./outline_check.py [--build build] [--scene-out FILE] [--plane strain]
Never run by the test suite.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..", "..")
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, ".."))
import run_helical as rh  # noqa: E402

sys.path.insert(0, os.path.join(ROOT, "docs", "tools"))
import helical_sweep  # noqa: E402


def check(name, h, xy, bnd, fixed):
    g = h.g
    P = xy[bnd] * 1e3
    R = np.hypot(P[:, 0], P[:, 1])
    A = np.arctan2(P[:, 1], P[:, 0])
    fil, invl = g.half_tooth(nfil=4000, ninv=40)
    fil = np.array(fil)
    full = np.vstack([fil, fil * [1, -1]])
    on_inv = (R > g.rform + 1e-3) & (R < g.ra - 1e-6)
    on_fil = (R > g.rf + 1e-6) & (R < g.rform - 1e-3)

    def inv_dev(off):
        a = (A[on_inv] - off + 0.5 * g.pitch) % g.pitch - 0.5 * g.pitch
        return np.array([r * (abs(x) - g.psi_inv(r)) for r, x in zip(R[on_inv], a)])

    # rotation of the tooth pattern: the mean involute deviation is linear in it
    a0 = np.arctan2(P[np.argmax(R), 1], P[np.argmax(R), 0])
    best = min(np.linspace(a0 - 0.5 * g.pitch, a0 + 0.5 * g.pitch, 181), key=lambda o: abs(inv_dev(o)).mean())
    lo, hi = best - g.pitch / 180, best + g.pitch / 180
    for _ in range(60):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        if abs(inv_dev(m1)).mean() < abs(inv_dev(m2)).mean():
            hi = m2
        else:
            lo = m1
    off = 0.5 * (lo + hi)
    dinv = inv_dev(off)
    a = (A[on_fil] - off + 0.5 * g.pitch) % g.pitch - 0.5 * g.pitch
    pts = np.c_[R[on_fil] * np.cos(a), R[on_fil] * np.sin(a)]
    dfil = np.array([np.min(np.hypot(p[0] - full[:, 0], p[1] - full[:, 1])) for p in pts])
    spacing = np.max(np.hypot(*np.diff(fil, axis=0).T))
    rh_ = np.hypot(*(xy[fixed] * 1e3).T)
    print("%s: %d involute nodes, largest deviation from the exact involute %.2e um; "
          "%d fillet nodes, largest distance from the trochoid %.3f um (sampled every %.3f um at most); "
          "tip radius %.6f (exact %.6f), root %.6f (%.6f), hub %.6f (%.6f) mm"
          % (name, on_inv.sum(), abs(dinv).max() * 1e3, on_fil.sum(), dfil.max() * 1e3, spacing * 1e3,
             R.max(), g.ra, R.min(), g.rf, rh_.mean(), g.hub))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--plane", choices=("strain", "stress"), default="strain")
    ap.add_argument("--scene-out", help="also write the spur scene here")
    args = ap.parse_args()
    pair, g1, g2 = rh.load_pair(os.path.join(HERE, "pair.json"))
    with open(os.path.join(HERE, "scene.json")) as f:
        sc = helical_sweep.spur_section(json.load(f), args.plane)
    sc["name"] = "transverse section of the helical reference pair as a spur pair"
    if args.scene_out:
        with open(args.scene_out, "w") as f:
            json.dump(sc, f, indent=1)
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "section.json")
        with open(scene, "w") as f:
            json.dump(sc, f)
        out = os.path.join(tmp, "section.h5")
        subprocess.run([os.path.join(args.build, "src", "tools", "gearsim-mesh"), scene, "-o", out, "--quiet"],
                       check=True)
        with h5py.File(out) as f:
            for name, h in (("pinion", g1), ("wheel", g2)):
                grp = f["gears"][name]
                check(name, h, grp["nodes"][:], grp["boundary"][:], grp["fixed"][:])


if __name__ == "__main__":
    main()
