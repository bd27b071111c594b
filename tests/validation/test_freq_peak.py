#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Resonance of the dynamic contact model at its FE mesh mode (issue 15,
docs/explanation/modal.md "FE mesh modes and the frequency response"): a coarse speed
sweep of contact_drive (tests/bench/freq_response.py --quick: 9 points
from 0.7 to 1.3 times the mode, 80 N m, 12 % material damping at the mode)
around the first torsional mesh mode of the same FE model's generalised
eigenproblem (gearsim-modal --fe, 4 roll positions). Checks (each can fail):
  - the DTE rms has a peak (prominence >= 25 %) and the largest lies within
    BAR = 3 % of the FE mode (the issue's bar);
  - the DTE rms at the peak point is at least 1.5 times that at the sweep's
    ends (0.7 and 1.3 times the mode): a resonance, not a flat curve;
  - every point keeps the energy balance (residual below 1e-9 of the scale),
    and the measured mesh frequencies (the abscissa) keep the order of the
    points' starts (the closure's impact losses slow the pair by up to 8 %).
On the linear mesh with numerics.contact "closure" (--quick): with
"closure_energy" the impacts' energy is returned and the pair keeps
rattling in the backlash (DTE rms 11-65 um, docs/explanation/modal.md).
GEARSIM_LONG=1 runs the default order-2 mesh instead (about 16 CPU minutes;
docs/explanation/modal.md "The frequency response on the default order-2 mesh"): the
contact model at 11 points from 0.8 to 1.2 times the FE mode (12 roll
positions) and the modal-calibrated lumped mesh (the same eigenproblem's
modes per position) at 8, 80 N m, 12 % (the condition of docs/explanation/modal.md
"Damping and contact loss": at 8 % and 5 % the flanks part near resonance
and the peak falls 5-12 % below the mode). Checks there:
  - the contact peak within 3 % of the FE mode (the issue's bar, as above);
  - the contact peak within 3 % of the resonance the FE eigenproblem gives
    the damped, time-varying mesh (linear_parametric in freq_response.py:
    the eigenproblem's per-position modes as a stiffness over the mesh
    cycle, 12 % damping; its DTE rms peaks 3.3 % below the mean mode, of
    which sqrt(1 - 2 zeta^2) is 1.45 %), the gap to the mean mode printed;
  - the solver of that prediction against the closed form sqrt(1 - 2 zeta^2)
    f of a weakly varying stiffness (1e-3);
  - the contact peak within 5 % of the modal-calibrated lumped mesh's peak;
  - resonance, balance and order as above.
GEARSIM_FREQ_KEEP=DIR keeps the work directory (points.csv, fe_mode.json)."""
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))
from harness import Results  # noqa: E402

SOURCE = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.abspath(os.path.join(HERE, "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT") or os.path.join(SOURCE, "build")
sys.path.insert(0, os.path.join(SOURCE, "tests", "bench"))
import freq_response  # noqa: E402

BAR = 0.03
BAR_CAL = 0.05
LONG = os.environ.get("GEARSIM_LONG") == "1"
ZETA = 0.12
TORQUE = 80.0

R = Results("test_freq_peak: contact model's DTE peak at its FE mesh mode (%s, 80 N m, 12 %%)" %
            ("default order-2 mesh" if LONG else "linear mesh"))
work = os.environ.get("GEARSIM_FREQ_KEEP") or tempfile.mkdtemp(prefix="gearsim_freq_peak_")
os.makedirs(work, exist_ok=True)
peaks_file = os.path.join(work, "peaks.json")
tool = [sys.executable, os.path.join(SOURCE, "tests", "bench", "freq_response.py"), "--build", BUILD, "--work", work,
        "--peaks-json", peaks_file]
if LONG:
    common = ["--order", "2", "--torque", repr(TORQUE), "--damping", repr(ZETA), "--contact", "closure",
              "--settle", "0.002", "--min-measure", "0.0012", "--positions", "12", "--grid", "1", "--grid-from", "1.0",
              "--dense", "0"]
    runs = [common + ["--models", "contact", "--extra-rel", "0.8,0.9,0.94,0.955,0.97,0.985,1.03,1.06,1.1,1.2"],
            common + ["--models", "modal", "--extra-rel", "0.8,0.9,0.94,0.97,1.03,1.06,1.2"]]
else:
    runs = [["--quick", "--models", "contact", "--grid", "5", "--grid-from", "0.7", "--grid-to", "1.3",
             "--extra-rel", "0.95,0.975,1.025,1.05"]]
for args in runs:
    r = subprocess.run(tool + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    print("\n".join("# " + line for line in r.stdout.splitlines()))
    if not R.check("freq_response.py runs", r.returncode == 0, r.stderr[-2000:]):
        R.finish()
res = json.load(open(peaks_file))
f0 = res["fe_mode_hz"]
R.check("FE mode found (%.1f Hz)" % f0, 5000.0 < f0 < 15000.0, f0)
pk = res["peaks"].get("contact", [])
if R.check("the contact model's DTE rms has a peak", len(pk) >= 1, pk):
    fp = pk[0]["hz"]
    R.note("contact peak %.1f Hz, FE mode %.1f Hz: %+.2f %% (bar %.0f %%)" % (fp, f0, 100 * (fp / f0 - 1), 100 * BAR))
    # The bar, against the mean undamped mode itself (in the long
    # mode, 80 N m and 12 %, it holds with 0.07 % to spare: docs/explanation/modal.md
    # "Damping and contact loss"; at 8 % and 5 % the flanks part and it fails).
    R.check("peak within %.0f %% of the FE mode (%+.2f %%)" % (100 * BAR, 100 * (fp / f0 - 1)),
            abs(fp / f0 - 1) <= BAR, (fp, f0))
    if LONG:
        mode = json.load(open(os.path.join(work, "fe_mode.json")))
        # The prediction's solver against the closed form of a weakly varying
        # stiffness (the excitation then a force at the mesh frequency).
        weak = dict(mode, points=[dict(p, hz=[f0 * (1 + 1e-2 * math.cos(2 * math.pi * p["roll"])) ** 0.5])
                                  for p in mode["points"]])
        fw, _ = freq_response.linear_peak(weak, ZETA, TORQUE, lo=0.95, hi=1.02, step=0.0025)
        fcf = f0 * math.sqrt(1 - 2 * ZETA * ZETA)
        R.check("linear_parametric: weakly varying stiffness peaks at sqrt(1 - 2 zeta^2) f (%.1f / %.1f Hz)" %
                (fw, fcf), abs(fw / fcf - 1) < 1e-3, (fw, fcf))
        fl, yl = freq_response.linear_peak(mode, ZETA, TORQUE)
        R.note("the FE eigenproblem's damped time-varying mesh (12 positions, %.0f %%) peaks at %.1f Hz (%+.2f %% of "
               "the mean mode; %.2f um)" % (100 * ZETA, fl, 100 * (fl / f0 - 1), yl))
        R.check("contact peak within %.0f %% of the eigenproblem's damped time-varying resonance (%+.2f %%)" %
                (100 * BAR, 100 * (fp / fl - 1)), abs(fp / fl - 1) <= BAR, (fp, fl))
        pm = res["peaks"].get("modal", [])
        if R.check("the modal-calibrated lumped mesh's DTE rms has a peak", len(pm) >= 1, pm):
            R.check("contact peak within %.0f %% of the modal-calibrated peak %.1f Hz (%+.2f %%)" %
                    (100 * BAR_CAL, pm[0]["hz"], 100 * (fp / pm[0]["hz"] - 1)),
                    abs(fp / pm[0]["hz"] - 1) <= BAR_CAL, (fp, pm[0]["hz"]))
with open(os.path.join(work, "points.csv")) as fh:
    pts = sorted((p for p in csv.DictReader(fh) if p["model"] == "contact"), key=lambda p: float(p["mesh_hz"]))
y = [float(p["dte_rms_um"]) for p in pts]
R.check("at least 7 points", len(pts) >= 7, len(pts))
if pts:
    R.check("resonance: DTE rms at the peak >= 1.5 x at both ends (%.3f / %.3f, %.3f um)" % (max(y), y[0], y[-1]),
            max(y) >= 1.5 * max(y[0], y[-1]), y)
    worst = max(float(p["balance_rel"]) for p in pts)
    R.check("energy balance below 1e-9 of the scale at every point (%.1e)" % worst, worst < 1e-9, worst)
    slip = [float(p["mesh_hz"]) / float(p["mesh_hz_target"]) - 1 for p in pts]
    R.note("measured mesh frequency against the start: %+.2f .. %+.2f %% (the closure's impact losses slow the "
           "pair)" % (100 * min(slip), 100 * max(slip)))
    tgt = [float(p["mesh_hz_target"]) for p in pts]
    R.check("the measured mesh frequencies keep the order of the starts (the sweep crosses the mode in order)",
            tgt == sorted(tgt), tgt)
    R.note("dynamic factor %.2f - %.2f" % (min(float(p["dynamic_factor"]) for p in pts),
                                          max(float(p["dynamic_factor"]) for p in pts)))
if not os.environ.get("GEARSIM_FREQ_KEEP"):
    shutil.rmtree(work, ignore_errors=True)
R.finish()
