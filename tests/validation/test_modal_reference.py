#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim's first mesh mode of the loaded elastic pair against the stored,
independent CalculiX perturbation reference (tests/reference/modal_30_20,
tests/reference/README.md "Modal reference"): contact_drive's 30/20 steel
pair at 20 N m, both gears free to turn, each with its rigid hub core's
rotary inertia; CalculiX: static contact step, then a *FREQUENCY
perturbation step about the loaded contact.

The reference code is never run here: the test reads reference.csv (per roll
position the finest level's first frequency above the rolling, and its change
from the next coarser level) and runs `gearsim-modal --fe` on
tests/reference/modal_30_20/scene.json at the same positions on the default
mesh, with the near-field correction (the default) and without it
(--no-nearfield).

Asserted (bars are named constants; each can fail):
* the stored reference: at least MIN_POSITIONS positions, the two finest
  levels within REF_CONV_BAR of each other at every position;
* default (near-field correction): |f / f_ref - 1| within BAR_NF at every
  position (what holds: 2 %; the target of 1 % is not met);
* plain FE: too high at every position (stiff), within BAR_PLAIN, and
  further from the reference than with the correction in the mean.
"""
import csv
import json
import os
import subprocess
import sys

SRC = os.environ.get("GEARSIM_SOURCE_ROOT",
                     os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(SRC, "build"))
PAIR = os.path.join(SRC, "tests", "reference", "modal_30_20")

MIN_POSITIONS = 4
REF_CONV_BAR = 0.01    # two finest CalculiX levels, h 0.1 / 0.05 mm (measured 0.13-0.81 %)
BAR_NF = 0.02          # near-field modes per position (measured -1.61 .. +1.43 %; the 1 % target is not met)
BAR_PLAIN = 0.06       # plain FE on the default mesh: too stiff, by less than this (measured +1.48 .. +3.88 %)


def gearsim(positions, plain):
    args = [os.path.join(BUILD, "src", "tools", "gearsim-modal"), os.path.join(PAIR, "scene.json"),
            "--fe", "--positions", str(positions), "--modes", "1", "--torque", "20", "--json"]
    if plain:
        args.append("--no-nearfield")
    r = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, check=True)
    return json.loads(r.stdout)


def main():
    ref = list(csv.DictReader(open(os.path.join(PAIR, "reference.csv"))))
    fail = []
    if len(ref) < MIN_POSITIONS:
        fail.append("reference has %d positions (< %d)" % (len(ref), MIN_POSITIONS))
    for r in ref:
        if not abs(float(r["change_pct"])) <= 100 * REF_CONV_BAR:
            fail.append("reference roll %s: two finest levels %s %% apart" % (r["roll"], r["change_pct"]))
    n = int(round(1.0 / (float(ref[1]["roll"]) - float(ref[0]["roll"]))))
    res = {}
    for plain in (False, True):
        out = gearsim(n, plain)
        errs = []
        for r in ref:
            j = int(round(float(r["roll"]) * n))
            f = out["points"][j]["hz"][0]
            errs.append(f / float(r["f1_hz"]) - 1.0)
        res[plain] = errs
    print("   roll    ref Hz   near-field err %   plain err %")
    for r, e0, e1 in zip(ref, res[False], res[True]):
        print("%7.4f %9.2f %12.3f %14.3f" % (float(r["roll"]), float(r["f1_hz"]), 100 * e0, 100 * e1))
    m0 = sum(abs(e) for e in res[False]) / len(ref)
    m1 = sum(abs(e) for e in res[True]) / len(ref)
    print("mean |err|: near-field %.3f %%, plain %.3f %%" % (100 * m0, 100 * m1))
    for r, e in zip(ref, res[False]):
        if not abs(e) <= BAR_NF:
            fail.append("near-field roll %s: %+.3f %% (bar %.1f %%)" % (r["roll"], 100 * e, 100 * BAR_NF))
    for r, e in zip(ref, res[True]):
        if not 0.0 < e <= BAR_PLAIN:
            fail.append("plain roll %s: %+.3f %% (expected in (0, %.0f %%])" % (r["roll"], 100 * e,
                                                                                100 * BAR_PLAIN))
    if not m0 < m1:
        fail.append("the correction does not bring the modes closer (%.3f vs %.3f %%)" % (100 * m0, 100 * m1))
    for f in fail:
        print("FAIL:", f)
    return 1 if fail else 0


if __name__ == "__main__":
    sys.exit(main())
