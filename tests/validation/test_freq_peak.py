#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Resonance of the dynamic contact model at its FE mesh mode (issue 15,
docs/MODAL.md "FE mesh modes and the frequency response"): a coarse speed
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
rattling in the backlash (DTE rms 11-65 um, docs/MODAL.md).
GEARSIM_FREQ_KEEP=DIR keeps the work directory (points.csv, fe_mode.json)."""
import csv
import json
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
BAR = 0.03

R = Results("test_freq_peak: contact model's DTE peak at its FE mesh mode (linear mesh, 80 N m, 12 %)")
work = os.environ.get("GEARSIM_FREQ_KEEP") or tempfile.mkdtemp(prefix="gearsim_freq_peak_")
os.makedirs(work, exist_ok=True)
peaks_file = os.path.join(work, "peaks.json")
r = subprocess.run([sys.executable, os.path.join(SOURCE, "tests", "bench", "freq_response.py"), "--build", BUILD,
                    "--work", work, "--quick", "--models", "contact", "--grid", "5", "--grid-from", "0.7",
                    "--grid-to", "1.3", "--extra-rel", "0.95,0.975,1.025,1.05", "--peaks-json", peaks_file],
                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
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
    R.check("peak within %.0f %% of the FE mode" % (100 * BAR), abs(fp / f0 - 1) <= BAR, (fp, f0))
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
