#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The mesh modes of planetary_contact's train at the ltca rung against the
elastic gears' (docs/explanation/ltca.md "Planetary trains"), from free
responses.

The train is planetary_contact with its carrier held (the ring is held
already): sun and planets turn only as far as the meshes deflect. The sun's
moment ramps to the scene's 20 N m over RAMP (the backlash closes gently),
holds until STEP (the closing's ringing dies away in the material
damping), then a step of STEP_NM more (a separate table load, so the
tables' key, which reads the ramp's moment, stays the shipped one) rings
the mesh modes the sun excites. Every mesh's deflection after the step is
fitted with damped exponentials (a matrix pencil); the script prints the
modes that carry the response of sun-planet1 and planet1-ring and their
frequencies corrected for the step (the midpoint rule's
omega_num h = 2 atan(omega h / 2) of a linear oscillator).

  train_modes.py --build BUILD --work WORK [--models ltca,reduced] [--h H]

Models: ltca (rigid gears, every mesh `ltca`, the gears' material damping
as bench_tradeoff's rows), reduced (the top rung: reduced elastic gears,
numerics.contact closure_energy, f_max 30 kHz, the same damping), lumped
(`ltca` meshes read with GEARSIM_LTCA_NEARFIELD as the environment has
it). Not a test: the reduced run is 20-60 CPU s.
"""
import argparse
import copy
import json
import math
import os
import subprocess
import sys

import numpy as np

RAMP, STEP, END = 0.004, 0.008, 0.0125
STEP_NM = 4.0
ZETA, FHZ = 0.02, 9200.0


def scene(model):
    here = os.path.dirname(os.path.abspath(__file__))
    with open(os.path.join(here, "..", "..", "deploy", "scenes", "planetary_contact.json")) as f:
        sc = json.load(f)
    sc = copy.deepcopy(sc)
    for j in sc["joints"]:
        if j["body"] == "carrier":
            j.clear()
            j.update({"body": "carrier", "type": "held"})
    sc["loads"] = [
        {"body": "sun", "type": "ramp", "moment": 20.0, "ramp_time": RAMP},
        {"body": "sun", "type": "table", "times": [0.0, STEP, STEP + 1e-7, 1.0],
         "moments": [0.0, 0.0, STEP_NM, STEP_NM]},
    ]
    for b in sc["bodies"]:
        if b.get("type") == "carrier":
            continue
        mat = b.setdefault("material", {})
        mat["damping_ratio"] = ZETA
        mat["damping_hz"] = FHZ
        if model == "reduced":
            b["model"] = "elastic"
            b["reduction"] = {"f_max_hz": 30000.0}
        else:
            b["model"] = "rigid"
    for m in sc["meshes"]:
        m["model"] = "contact" if model == "reduced" else "ltca"
    if model == "reduced":
        sc.setdefault("numerics", {})["contact"] = "closure_energy"
    return sc


def pencil(t, x, order):
    """Damped exponentials of x (uniform t): frequencies (Hz), damping
    ratios and amplitudes, by the matrix pencil with `order` poles."""
    n = len(x)
    L = n // 3
    Y = np.array([x[i:i + L + 1] for i in range(n - L)])
    U, s, Vt = np.linalg.svd(Y, full_matrices=False)
    V = Vt[:order].T
    V1, V2 = V[:-1], V[1:]
    z = np.linalg.eigvals(np.linalg.pinv(V1) @ V2)
    dt = t[1] - t[0]
    lam = np.log(z.astype(complex)) / dt
    Z = np.exp(np.outer(t - t[0], lam))
    amp = np.linalg.lstsq(Z, x.astype(complex), rcond=None)[0]
    out = []
    for l, a in zip(lam, amp):
        w = abs(l.imag)
        if w <= 0:
            continue
        out.append((w / (2 * math.pi), -l.real / abs(l), 2 * abs(a)))
    out.sort(key=lambda r: -r[2])
    seen = []
    for f, zt, a in out:  # conjugate pairs: keep one
        if not any(abs(f - g) < 1e-6 * f for g, _, _ in seen):
            seen.append((f, zt, a))
    return seen


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default="build")
    ap.add_argument("--work", required=True)
    ap.add_argument("--models", default="ltca,reduced")
    ap.add_argument("--h", type=float, default=5e-6)
    ap.add_argument("--order", type=int, default=12)
    ap.add_argument("--tag", default="")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    tool = os.path.join(a.build, "tests", "bench", "free_response")
    for model in a.models.split(","):
        name = model + a.tag
        sp = os.path.join(a.work, name + ".json")
        csv = os.path.join(a.work, name + ".csv")
        with open(sp, "w") as f:
            json.dump(scene(model), f, indent=1)
        if not os.path.exists(csv):
            r = subprocess.run(["nice", "-n", "10", tool, sp, "--h", repr(a.h), "--duration", repr(END),
                                "--csv", csv], capture_output=True, text=True)
            if r.returncode:
                sys.exit(r.stderr)
            print("# %s: %s" % (name, r.stdout.strip()))
        d = np.genfromtxt(csv, delimiter=",", names=True)
        t = d["t_s"]
        sel = t > STEP + 2 * a.h
        for col, label in (("x0_um", "sun-planet1"), ("x3_um", "planet1-ring")):
            x = d[col][sel]
            x = x - x.mean()
            modes = pencil(t[sel], x, a.order)
            top = [m for m in modes if m[2] > 0.05 * modes[0][2] and 2000 < m[0] < 30000][:4]
            desc = ", ".join("%.0f Hz (corrected %.0f, zeta %.3f, amp %.3f um)"
                             % (f, 2 / a.h * math.tan(math.pi * f * a.h) / (2 * math.pi), z, am)
                             for f, z, am in top)
            print("%s h %g %s: %s" % (name, a.h, label, desc))


if __name__ == "__main__":
    main()
