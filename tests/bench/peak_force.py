#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Where the peak mesh force of contact_drive comes from, at the ltca rung
and at the top rung (docs/explanation/ltca.md "Peak mesh force").

Both runs are bench_tradeoff's rows of contact_drive (the shipped ramp and
brake, the elastic rows' material damping of 2 % at 9.2 kHz): `ltca`
(rigid gears, ltca mesh) and `reduced` (reduced elastic gears, f_max
30 kHz, numerics.contact closure_energy), each stepped by free_response
to 65 ms. Over 35-65 ms (whole mesh cycles of the steady state) the
script prints per run the peak and mean mesh force, the DTE rms, the
amplitude of the force in frequency bands (Hann window, amplitude of a
sine of the same energy) and its strongest lines above 3 kHz.

  peak_force.py --build BUILD --work WORK [--h-reduced 5e-6] [--h-ltca 1e-5]

Not a test: the reduced run is about 5 CPU s at 5 us, 40 at 1.25 us.
"""
import argparse
import copy
import json
import os
import subprocess
import sys

import numpy as np

DROP = ("stiffness", "damping", "damping_ratio", "backlash_mm", "passes", "constrain", "friction", "restitution", "law")
BANDS = ((0, 2000), (2000, 6000), (6000, 12000), (12000, 30000), (30000, 1e9))


def scene(model):
    here = os.path.dirname(os.path.abspath(__file__))
    with open(os.path.join(here, "..", "..", "deploy", "scenes", "contact_drive.json")) as f:
        s = copy.deepcopy(json.load(f))
    for b in s["bodies"]:
        mat = b.setdefault("material", {})
        mat.pop("damping_s", None)
        mat["damping_ratio"] = 0.02
        mat["damping_hz"] = 9200.0
        b["model"] = "elastic" if model == "reduced" else "rigid"
        if model == "reduced":
            b["reduction"] = {"f_max_hz": 30000.0}
    for m in s["meshes"]:
        for k in DROP:
            m.pop(k, None)
        m["model"] = "contact" if model == "reduced" else "ltca"
    if model == "reduced":
        s.setdefault("numerics", {})["contact"] = "closure_energy"
    return s


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default="build")
    ap.add_argument("--work", required=True)
    ap.add_argument("--h-reduced", type=float, default=5e-6)
    ap.add_argument("--h-ltca", type=float, default=1e-5)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    tool = os.path.join(a.build, "tests", "bench", "free_response")
    for model, h in (("ltca", a.h_ltca), ("reduced", a.h_reduced)):
        name = "%s_%g" % (model, h)
        sp, csv = os.path.join(a.work, name + ".json"), os.path.join(a.work, name + ".csv")
        with open(sp, "w") as f:
            json.dump(scene(model), f, indent=1)
        if not os.path.exists(csv):
            r = subprocess.run(["nice", "-n", "10", tool, sp, "--h", repr(h), "--duration", "0.065", "--csv", csv],
                               capture_output=True, text=True)
            if r.returncode:
                sys.exit(r.stderr)
            print("# %s: %s" % (name, r.stdout.strip()))
        d = np.genfromtxt(csv, delimiter=",", names=True)
        w = (d["t_s"] >= 0.035) & (d["t_s"] <= 0.065)
        t, x, f = d["t_s"][w], d["x0_um"][w], d["f0_n"][w]
        n, dt = len(f), t[1] - t[0]
        spec = np.fft.rfft((f - f.mean()) * np.hanning(n))
        fr = np.fft.rfftfreq(n, dt)
        # a sine of amplitude A under the Hann window: |X| = A n / 4
        bands = ", ".join("%g-%g kHz %.1f N" % (lo / 1e3, min(hi, 1e6) / 1e3,
                                               np.sqrt((np.abs(spec[(fr >= lo) & (fr < hi)]) ** 2).sum()) * 4 / n)
                          for lo, hi in BANDS)
        fine = np.abs(np.fft.rfft((f - f.mean()) * np.hanning(n), 8 * n))
        ff = np.fft.rfftfreq(8 * n, dt)
        lines = []
        for i in np.argsort(-fine):
            if ff[i] < 3000:
                continue
            if all(abs(ff[i] - g) > 100 for g, _ in lines):
                lines.append((ff[i], fine[i] * 4 / n))
            if len(lines) == 4:
                break
        print("%s h %g: peak force %.1f N, mean %.1f N (peak/mean %.3f), DTE rms %.4f um, mean TE %.4f um" %
              (model, h, np.abs(f).max(), f.mean(), np.abs(f).max() / f.mean(), x.std(), x.mean()))
        print("  force by band: %s" % bands)
        print("  strongest lines: %s" % ", ".join("%.0f Hz %.1f N" % l for l in lines))


if __name__ == "__main__":
    main()
