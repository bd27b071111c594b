#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Speed sweep of the lumped planetary (deploy/scenes/planetary_sweep.json)
against its modal analysis: `gearctl sweep`, the daemon's `sweep` job at
mpirun -n 2 on 2 groups of ranks, over 41 driver speeds (mesh
frequency 5100-7500 Hz, h = 2e-6 s so that the midpoint rule's frequency
error, (w h)^2 / 12, stays below 0.1%) finds resonance peaks of the sun mesh's
dynamic transmission error; each peak lies within 2% of a natural frequency
of `gearctl modal` or of half of one (the second harmonic of the mesh
frequency), and the first rotational mode has its peak."""
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_sweep: speed sweep resonances at the modal frequencies")
GEARCTL = os.path.join(dmod.SOURCE_ROOT, "clients", "python", "gearctl")
env = dict(os.environ, GEARSIM_BUILD_ROOT=dmod.BUILD_ROOT)
# GEARSIM_SWEEP_CSV / GEARSIM_SWEEP_PLOT: also write the table and the plot (docs/explanation/modal.md's figures).
extra = []
if os.environ.get("GEARSIM_SWEEP_CSV"):
    extra += ["--csv", os.environ["GEARSIM_SWEEP_CSV"]]
if os.environ.get("GEARSIM_SWEEP_PLOT"):
    extra += ["--plot", os.environ["GEARSIM_SWEEP_PLOT"]]
with dmod.Daemon(ranks=2) as d:
    r = subprocess.run([sys.executable, GEARCTL, "--connection-file", d.conn_file, "sweep", "builtin:planetary_sweep",
                        "--from", "17000", "--to", "25000", "--points", "41", "--time-step", "2e-6", "--settle",
                        "0.008", "--measure", "0.006", "--groups", "2", "--json"] + extra,
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
R.check("gearctl sweep runs (daemon at -n 2, 2 groups)", r.returncode == 0, r.stderr[-2000:])
if r.returncode == 0:
    res = json.loads(r.stdout)
    pts, peaks, modes = res["points"], res["peaks"], res["modes"]
    R.check("41 points", len(pts) == 41, len(pts))
    R.check("balance at round-off at every point", all(p["balance_rel"] < 1e-9 for p in pts),
            max(p["balance_rel"] for p in pts))
    R.note("peaks: " + ", ".join(f"{p['mesh_hz']:.1f} Hz" for p in peaks) + "; modes: " +
           ", ".join(f"{m['frequency_hz']:.1f} {m['kind']}" for m in modes))
    R.check("at least two resonance peaks", len(peaks) >= 2, peaks)
    for p in peaks:
        best = min(((abs(p["mesh_hz"] * k / m["frequency_hz"] - 1), k, m) for m in modes for k in (1, 2)),
                   key=lambda t: t[0])
        R.check(f"peak at {p['mesh_hz']:.1f} Hz: {'mesh frequency' if best[1] == 1 else 'its 2nd harmonic'} at "
                f"the {best[2]['kind']} mode {best[2]['frequency_hz']:.1f} Hz ({best[0] * 100:.2f}%, within 2%)",
                best[0] < 0.02)
    first = min((m for m in modes if m["kind"] == "rotational"), key=lambda m: m["frequency_hz"])
    R.check(f"the first rotational mode ({first['frequency_hz']:.1f} Hz) has its peak within 2%",
            any(abs(p["mesh_hz"] / first["frequency_hz"] - 1) < 0.02 for p in peaks), peaks)
R.finish()
