#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Frequency response of the contact_drive pair (docs/explanation/modal.md "Frequency
response of the elastic pair"): DTE rms and dynamic factor against the mesh
frequency for the contact model and the lumped, calibrated and compliant
meshes of the same pair, with the first torsional mesh mode of the FE model
(gearsim-modal --fe) marked.

    tests/bench/freq_response.py [--build build] [--work DIR] [--models contact,lumped,...]
                                 [--scene SCENE.json] [--thinning MM] [--h-max H]
                                 [--torque T] [--damping Z] [--order 1|2] [--grid N]
                                 [--grid-from A] [--grid-to B] [--dense N] [--extra F1,F2,..]
                                 [--contact closure_energy|closure|seed] [--coarse] [--nearfield] [--scale S] [--fmax F]
                                 [--settle S] [--min-measure S] [--min-cycles N]
                                 [--quick] [--no-run] [--plot docs/img/freq_response.png]
                                 [--csv docs/data/freq_response.csv]

The order-2 figures of docs/explanation/modal.md (default mesh): --order 2 --torque 80
--damping 0.12 --settle 0.002 --min-measure 0.0012 for the lumped models
(grid 10 and dense 7, the defaults), then with --models contact --contact
closure --grid 1 --grid-from 1.0 --dense 0
--extra-rel 0.35,0.6,0.85,0.92,1.08,1.15,1.3,1.6,2.0 (with the default
"closure_energy" the pair keeps rattling: docs/explanation/modal.md). --quick (the meson benchmark): order 1 (the linear
mesh), numerics.contact "closure", 80 N m, 12 %, 7 points from 0.7 to 1.3
times the mode, FE mode from 4 positions, settle 2 ms (minutes of CPU).

The order-1 figures of docs/explanation/modal.md (contact "closure"): the defaults (20 N m, 5 %) plus
--extra 6000,6500,6800,7000,7150,7450,7600,7800,8250,8400,8550,9400,9700;
--damping 0.12 --models calibrated,contact --grid 13 --grid-from 0.7
--grid-to 1.3 --dense 0; and --torque 80 --damping 0.12 with that grid and
then --grid 10 (0.2 to 2), each in its own --work directory.

The pair (--scene, default deploy/scenes/contact_drive.json) is one mesh
of two gears; a scene without loads (deploy/scenes/pair_relief.json) gets
contact_drive's: the moment (ramp to 20 N m, --torque sets it) on the gear
with more teeth, the brake on the other; the mesh's gears are put driver
first (gearsim-modal --fe --torque loads the mesh's first gear). The relief
pair at its design load (docs/explanation/modal.md "The relief pair at its design
load"): --scene deploy/scenes/pair_relief.json --thinning 0.05 --order 2
--torque 70.5 --damping 0.05 --settle 0.002 --min-measure 0.0012 --contact
closure --models contact --grid 1 --grid-from 1.0 --dense 0 --extra-rel ...
(--thinning 0.05: contact_drive's backlash; pair_relief has none).

Every point is one run of gearsim-sweep (its own settle and a whole number
of mesh cycles measured), cached in WORK/points.csv: a rerun computes only
the missing points, so the contact points can be run in the background
(`nice`) and the plot redone afterwards; remove the cache after changing
the default mesh or the contact step. Points: mesh frequencies 0.2 .. 2
times the FE mode (--grid points, evenly spaced) plus a dense set within
+-12 % of it, plus --extra frequencies (Hz), e.g. to refine a peak.
Settings: numerics.contact (--contact, default "closure_energy"), material damping (--damping, 5 %)
at the FE mode frequency on both elastic gears (stiffness proportional),
lumped / calibrated / compliant meshes with the same ratio of their mesh
mode; each --work directory holds one damping's points;
time step h = min(2.5 us, mesh period / 24); settle 5 ms; measure the
whole mesh cycles in at least 2.5 ms (and at least 12 cycles).
Peaks: every local maximum of the DTE rms above 1.5 times the median of
its curve, refined by a parabola through it and its neighbours.

Models: contact, lumped, calibrated (tangent), compliant and modal (the
calibrated lumped mesh with "calibration": "modal", its k_t scaled per
position to the FE eigenproblem's mode). With the eigenproblem's positions
in fe_mode.json the report adds linear_parametric: the DTE rms of the
single-degree-of-freedom mesh with those modes as a stiffness over the
cycle and the same damping, a spring that also pulls (its peak is where
the damped time-varying mesh resonates; the plot draws its curve).
The order-2 figures with the tip-corner rule (docs/explanation/modal.md, work directory
of their own): --order 2 --torque 80 --damping 0.12 --settle 0.002
--min-measure 0.0012 --contact closure --models contact --grid 1 --grid-from
1.0 --dense 0 --extra-rel 0.8,0.86,0.9,0.94,0.955,0.97,0.985,1.03,1.06,1.1,1.14,1.2;
the same with --models modal on 0.86-1.06; the lumped models with the
default grid and those points.

The damping study (docs/explanation/modal.md "Damping and contact loss"): the same
with --damping 0.08 / 0.05 (and --torque 200), --grid 1 --grid-from 0.97
--extra-rel 0.86,...,1.06, one --work directory each; then
--compare "DIR:DAMPING:TORQUE:LABEL;..." --compare-plot
docs/img/freq_response_damping.png draws their contact curves and steps
without contact against the mesh frequency over each run's FE mode. When
tests/bench/freq_point is built the contact points run through it (the
sweep's point and meter, the same row) and points.csv also gets
separated_fraction (steps without an active contact row),
low_force_fraction and contact_work_rel (the closure's losses over the
driver's work).
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
from gearsim.sweep import parabola_vertex  # noqa: E402  (the client's peak fit)
sys.path.insert(0, HERE)
from dyn_convergence import level_name  # noqa: E402  (the study's mesh levels)
from static_te_levels import level_mesh  # noqa: E402
MODELS = ["contact", "lumped", "calibrated", "compliant", "modal", "ltca"]
FIELDS = ["model", "mesh_hz_target", "driver_rpm", "time_step", "settle", "measure", "mesh_hz", "dte_rms_um",
          "dynamic_factor", "balance_rel", "seconds", "cpu_seconds", "separated_fraction", "low_force_fraction",
          "contact_work_rel", "dte_h1_um"]
COARSE = {"flank": 2, "across": 1, "rim": 1, "grading": 1}


DEFAULT_SCENE = os.path.join(ROOT, "deploy", "scenes", "contact_drive.json")


def base_scene(path=None, thinning=None):
    """The pair the points run: contact_drive (default) or the scene at path.
    A scene without loads (e.g. pair_relief.json) gets contact_drive's: the
    moment ramping to 20 N m on the gear with more teeth (the driver), the
    brake of 0.3 N m s on the other. The mesh's gears are put driver first,
    so that gearsim-modal --fe --torque T loads the driver as the sweep does
    and linear_parametric's force is T / rb of the first. thinning (mm):
    every gear's thinning_mm (the backlash; contact_drive has 0.05)."""
    s = json.load(open(path or DEFAULT_SCENE))
    gears = [b for b in s["bodies"] if b.get("type") == "gear"]
    if len(gears) != 2 or len(s.get("meshes", [])) != 1:
        sys.exit("freq_response: the scene must be one pair (two gears, one mesh)")
    if not s.get("loads"):
        drv, out = sorted(gears, key=lambda b: -b["teeth"])
        s["loads"] = [{"body": drv["name"], "type": "ramp", "moment": 20.0, "ramp_time": 0.02},
                      {"body": out["name"], "type": "brake", "coefficient": 0.3}]
    drv = s["loads"][0]["body"]
    m = s["meshes"][0]
    if m["gears"][0] != drv:
        m["gears"] = list(reversed(m["gears"]))
    if thinning is not None:
        for b in gears:
            b["thinning_mm"] = thinning
    return s


def driver_teeth(s):
    """Teeth of the driver (the body of the first moment load): the mesh
    frequency is driver rpm / 60 * teeth."""
    drv = s["loads"][0]["body"]
    return next(b["teeth"] for b in s["bodies"] if b["name"] == drv)


def scene_for(model, mode_hz, zeta, order=1, torque=0.0, contact="closure_energy", coarse=False, scene=None,
              thinning=None, scale=1.0, fmax=0.0, nearfield=False):
    s = base_scene(scene, thinning)
    if torque:
        s["loads"][0]["moment"] = torque
    s["outputs"] = {"telemetry_every": 100000}
    s.setdefault("numerics", {})
    s["numerics"]["contact"] = contact
    if model == "contact":
        for b in s["bodies"]:
            b["material"] = {"damping_ratio": zeta, "damping_hz": round(mode_hz, 1)}
            # --scale: the default counts times S, the study's o<order>s<S> meshes
            b["mesh"] = (dict(COARSE, order=order) if coarse else {"order": order} if scale == 1
                         else level_mesh(level_name(order, 0, scale)))
            if fmax > 0:  # the reduced elastic body (docs/explanation/elastic_body.md)
                b["reduction"] = {"f_max_hz": fmax}
        if nearfield:  # the near-field compliance in the contact step (docs/explanation/contact.md)
            s["meshes"][0]["nearfield"] = True
    else:
        for b in s["bodies"]:
            b["model"] = "rigid"
        m = s["meshes"][0]
        if model == "lumped":
            m["model"] = "lumped"
        elif model == "calibrated":
            m["model"] = "lumped"
            m["stiffness"] = {"type": "calibrated"}
        elif model == "ltca":  # the loaded tooth contact analysis' tables (docs/explanation/ltca.md)
            m["model"] = "ltca"
        elif model == "modal":  # k_t scaled per position to the FE eigenproblem's mode (docs/explanation/stiffness.md)
            m["model"] = "lumped"
            m["stiffness"] = {"type": "calibrated", "calibration": "modal"}
        else:
            m["model"] = "compliant"
        m["damping_ratio"] = zeta
    return s


def fe_mode(build, work, positions, order=1, torque=0.0, coarse=False, scene=None, thinning=None, scale=1.0):
    """The FE mode of the contact model's own gears (its mesh as scene_for
    writes it; the damping does not enter)."""
    path = os.path.join(work, "scene_fe.json")
    json.dump(scene_for("contact", 1.0, 0.0, order, torque, coarse=coarse, scene=scene, thinning=thinning,
                        scale=scale), open(path, "w"))
    exe = os.path.join(build, "src", "tools", "gearsim-modal")
    out = subprocess.run([exe, "--fe", "--positions", str(positions), "--torque", repr(torque), "--json", path],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def run_point(build, work, model, mode_hz, f, zeta, order=1, torque=0.0, contact="closure_energy", coarse=False,
              settle=5e-3, min_measure=2.5e-3, min_cycles=12, scene=None, thinning=None, h_max=2.5e-6, scale=1.0,
              fmax=0.0, nearfield=False):
    path = os.path.join(work, "scene_%s.json" % model)
    if not os.path.exists(path):
        json.dump(scene_for(model, mode_hz, zeta, order, torque, contact, coarse, scene, thinning, scale, fmax,
                            nearfield), open(path, "w"))
    h = min(h_max, 1.0 / f / 24)
    cycles = max(min_cycles, math.ceil(min_measure * f))
    measure = cycles / f
    rpm = f * 60.0 / driver_teeth(json.load(open(path)))
    import resource
    import time
    t0 = time.time()
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    # The contact model's points go through tests/bench/freq_point (the
    # sweep's point and meter, so the same row) when it is built: it also
    # counts the steps without contact and the closure's losses.
    point = os.path.join(build, "tests", "bench", "freq_point")
    if model == "contact" and os.path.exists(point):
        r = subprocess.run(["nice", point, path, "--rpm", repr(rpm), "--settle", repr(settle), "--measure",
                            repr(measure), "--h", repr(h)], capture_output=True, text=True)
        row = json.loads(r.stdout) if r.returncode == 0 else {}
    else:
        exe = os.path.join(build, "src", "tools", "gearsim-sweep")
        r = subprocess.run(["nice", exe, path, "--from", repr(rpm), "--to", repr(rpm), "--points", "1",
                            "--settle", repr(settle), "--measure", repr(measure), "--time-step", repr(h)],
                           capture_output=True, text=True)
        row = list(csv.DictReader(r.stdout.splitlines()))[0] if r.returncode == 0 else {}
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        sys.exit("freq_response: %s at %.1f Hz failed: %s" % (model, f, r.stderr.strip()))
    out = {"model": model, "mesh_hz_target": f, "driver_rpm": rpm, "time_step": h, "settle": settle,
           "measure": measure, "mesh_hz": float(row["mesh_hz"]), "dte_rms_um": float(row["dte_rms_um"]),
           "dynamic_factor": float(row["dynamic_factor"]), "balance_rel": float(row["balance_rel"]),
           "seconds": time.time() - t0,
           "cpu_seconds": (c1.ru_utime + c1.ru_stime) - (c0.ru_utime + c0.ru_stime)}
    if "separated_fraction" in row:
        out["separated_fraction"] = row["separated_fraction"]
        out["low_force_fraction"] = row["low_force_fraction"]
        out["contact_work_rel"] = row["contact_work_j"] / row["work_in_j"] if row["work_in_j"] else float("nan")
    if "dte_h1_um" in row:
        out["dte_h1_um"] = row["dte_h1_um"]
    return out


def linear_parametric(mode, zeta, torque, rel, steps=240, cycles=60, measure=20, push_only=False):
    """DTE rms of the linear single-degree-of-freedom mesh the FE eigenproblem
    describes, at mesh frequencies rel * mean mode: the equivalent mass
    m = 1 / (rb1^2 / I1 + rb2^2 / I2) of the two gears' inertias, the
    stiffness k(phase) = m (2 pi f_j)^2 through the modes f_j of the
    eigenproblem's roll positions (periodic, piecewise linear), the
    constant damper c = 2 zeta m (2 pi f_mean) (what the stiffness-
    proportional material damping gives the mesh mode) and the mean force
    torque / rb1:  m x'' + c x' + k(f t) x = F. The spring also pulls (no
    separation): the linear parametric resonance (push_only: a spring that
    only pushes, the flanks free to part). Classical RK4, `steps` per
    mesh cycle, rms over the last `measure` of `cycles` cycles, all the
    frequencies at once. Returns the rms (m), one per rel."""
    import numpy as np
    I1, I2 = mode["inertia"]
    rb1, rb2 = (r * 1e-3 for r in mode["base_radius_mm"])
    m = 1.0 / (rb1 * rb1 / I1 + rb2 * rb2 / I2)
    roll = [p["roll"] for p in mode["points"]] + [1.0]
    kj = [m * (2 * math.pi * p["hz"][0]) ** 2 for p in mode["points"]]
    kj.append(kj[0])
    c = 2 * zeta * m * 2 * math.pi * mode["mean_hz"]
    force = torque / rb1
    fm = np.asarray(rel, dtype=float) * mode["mean_hz"]
    h = 1.0 / fm / steps

    def acc(k, x, v, ph):
        fs = np.interp(ph % 1.0, roll, kj) * x
        if push_only:
            fs = np.maximum(fs, 0.0)
        return (force - fs - c * v) / m

    x = force / np.mean(kj[:-1]) * np.ones_like(fm)
    v = np.zeros_like(fm)
    sx = np.zeros_like(fm)
    sxx = np.zeros_like(fm)
    n = steps * cycles
    for k in range(n):
        ph = k / steps
        a1 = acc(k, x, v, ph)
        x2, v2 = x + 0.5 * h * v, v + 0.5 * h * a1
        a2 = acc(k, x2, v2, ph + 0.5 / steps)
        x3, v3 = x + 0.5 * h * v2, v + 0.5 * h * a2
        a3 = acc(k, x3, v3, ph + 0.5 / steps)
        x4, v4 = x + h * v3, v + h * a3
        a4 = acc(k, x4, v4, ph + 1.0 / steps)
        x, v = x + h / 6 * (v + 2 * v2 + 2 * v3 + v4), v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        if k >= n - steps * measure:
            sx += x
            sxx += x * x
    cnt = steps * measure
    return np.sqrt(np.maximum(sxx / cnt - (sx / cnt) ** 2, 0.0))


def linear_peak(mode, zeta, torque, lo=0.8, hi=1.1, step=0.005, push_only=False):
    """Mesh frequency (Hz) of the largest DTE rms of linear_parametric,
    refined by a parabola, and that rms (um)."""
    n = int(round((hi - lo) / step)) + 1
    rel = [lo + step * i for i in range(n)]
    y = list(linear_parametric(mode, zeta, torque, rel, push_only=push_only) * 1e6)
    x = [r * mode["mean_hz"] for r in rel]
    i = max(range(n), key=lambda i: y[i])
    return parabola(x, y, i), y[i]


def load_cache(path):
    if not os.path.exists(path):
        return []
    with open(path) as fh:
        out = []
        for r in csv.DictReader(fh):
            for k in FIELDS[1:]:
                r[k] = float(r[k]) if r.get(k) not in (None, "") else float("nan")
            out.append(r)
        return out


def parabola(x, y, i):
    """Vertex of the parabola through points i-1, i, i+1 (gearsim.sweep's),
    kept only within half an interval of x[i]; x[i] at the ends."""
    if 0 < i < len(y) - 1:
        v = parabola_vertex(x, y, i)
        if 0.5 * (x[i - 1] + x[i]) < v < 0.5 * (x[i] + x[i + 1]):
            return v
    return x[i]


def peaks(pts):
    """Local maxima of the DTE rms standing at least 25 % of their height
    above the lower of the two valleys that separate them from higher
    points (prominence), each (mesh frequency refined by a parabola, DTE
    rms), largest first."""
    pts = sorted(pts, key=lambda r: r["mesh_hz"])
    x = [r["mesh_hz"] for r in pts]
    y = [r["dte_rms_um"] for r in pts]
    out = []
    for i in range(len(y)):
        if not ((i == 0 or y[i] > y[i - 1]) and (i == len(y) - 1 or y[i] >= y[i + 1])):
            continue
        lo = []
        for rng in (range(i - 1, -1, -1), range(i + 1, len(y))):
            m = y[i]
            for j in rng:
                if y[j] > y[i]:
                    break
                m = min(m, y[j])
            lo.append(m)
        if y[i] - max(lo) >= 0.25 * y[i]:
            out.append((parabola(x, y, i), y[i]))
    return sorted(out, key=lambda p: -p[1])


def lsq_peak(x, y, centre, half):
    """Vertex of the least-squares parabola through the points within
    centre +- half (at least 4 of them; None otherwise or if it opens up)."""
    import numpy as np
    sel = [(a, b) for a, b in zip(x, y) if abs(a - centre) <= half]
    if len(sel) < 4:
        return None
    c = np.polyfit([a - centre for a, _ in sel], [b for _, b in sel], 2)
    if c[0] >= 0:
        return None
    v = centre - c[1] / (2 * c[0])
    return v if min(a for a, _ in sel) <= v <= max(a for a, _ in sel) else None


def fit_report(cache, f0):
    """Peak estimates of every model's largest point: the three-point parabola
    and least-squares parabolas through the points within +-3, 4 and 6 % of
    the mode around it; for the contact model also of the DTE's first mesh
    harmonic (dte_h1_um, when freq_point measured it)."""
    for m in MODELS:
        for col in ("dte_rms_um", "dte_h1_um"):
            pts = sorted((r for r in cache if r["model"] == m and r.get(col) is not None and r[col] == r[col]),
                         key=lambda r: r["mesh_hz"])
            if len(pts) < 4:
                continue
            x = [r["mesh_hz"] for r in pts]
            y = [r[col] for r in pts]
            i = max(range(len(y)), key=lambda i: y[i])
            est = [("parabola", parabola(x, y, i))]
            for hw in (0.03, 0.04, 0.06):
                est.append(("lsq +-%g %%" % (100 * hw), lsq_peak(x, y, x[i], hw * f0)))
            print("%s %s: %s" % (m, col, ", ".join("%s %s" % (k, "%.1f Hz (%+.2f %%)" % (v, 100 * (v / f0 - 1))
                                                                  if v else "-") for k, v in est)))


def overlay_points(spec):
    """(label, contact points sorted by mesh frequency) of an --overlay
    entry PATH:LABEL, PATH a work directory (its points.csv) or a CSV of
    points (--csv's)."""
    d, label = spec.split(":", 1)
    path = d if d.endswith(".csv") else os.path.join(d, "points.csv")
    return label, sorted((r for r in load_cache(path) if r["model"] == "contact"), key=lambda r: r["mesh_hz"])


def compare_plot(specs, out):
    """The contact model's DTE rms and steps without contact against the
    mesh frequency relative to each run's FE mode, one curve per work
    directory (spec DIR:DAMPING:TORQUE:LABEL), with the FE eigenproblem's
    time-varying mesh with a spring that only pushes (dotted) for each."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for k, spec in enumerate(specs):
        d, zeta, torque, label = spec.split(":", 3)
        mode = json.load(open(os.path.join(d, "fe_mode.json")))
        f0 = mode["mean_hz"]
        pts = sorted((r for r in load_cache(os.path.join(d, "points.csv")) if r["model"] == "contact"),
                     key=lambda r: r["mesh_hz"])
        col = "C%d" % k
        x = [r["mesh_hz"] / f0 for r in pts]
        ax[0].plot(x, [r["dte_rms_um"] for r in pts], "-o", color=col, ms=4, label="contact, " + label)
        sep = [(r["mesh_hz"] / f0, 100 * r["separated_fraction"]) for r in pts
               if r["separated_fraction"] == r["separated_fraction"]]
        if sep:
            ax[1].plot([p[0] for p in sep], [p[1] for p in sep], "-o", color=col, ms=4, label=label)
        rel = [0.75 + 0.35 * i / 140 for i in range(141)]
        ax[0].plot(rel, linear_parametric(mode, float(zeta), float(torque), rel, push_only=True) * 1e6, ":",
                   color=col, lw=1)
    for k in range(2):
        ax[k].axvline(1.0, color="m", ls="--", lw=1)
        ax[k].axvspan(0.97, 1.03, color="m", alpha=0.08)
        ax[k].set_xlim(0.75, 1.2)
        ax[k].grid(alpha=0.3)
    ax[0].set_ylabel("DTE rms (um)")
    ax[1].set_ylabel("steps without contact (%)")
    ax[1].set_xlabel("mesh frequency / FE mesh mode (the band: +-3 %)")
    ax[0].legend(fontsize=8)
    ax[0].set_title("contact_drive, order 2, closure: damping and contact loss\n"
                    "(dotted: the FE modes' time-varying mesh, flanks free to part)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print("plot:", out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--work", default="/tmp/gearsim_freq_response")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--grid", type=int, default=10)
    ap.add_argument("--dense", type=int, default=7)
    ap.add_argument("--extra", default="")
    ap.add_argument("--extra-rel", default="", help="more points, as fractions of the FE mode")
    ap.add_argument("--positions", type=int, default=12)
    ap.add_argument("--mode-hz", type=float, default=0.0, help="skip the FE eigenproblem, use this mode")
    ap.add_argument("--damping", type=float, default=0.05,
                    help="damping ratio (material at the FE mode; lumped meshes of their mesh mode)")
    ap.add_argument("--grid-from", type=float, default=0.2, help="grid from this fraction of the mode")
    ap.add_argument("--grid-to", type=float, default=2.0, help="grid to this fraction of the mode")
    ap.add_argument("--order", type=int, default=1,
                    help="element order of the contact model's gears (and of the FE mode)")
    ap.add_argument("--torque", type=float, default=0.0, help="moment on the wheel, N m (0: the scene's 20)")
    ap.add_argument("--contact", default="closure_energy", help="numerics.contact of the scenes")
    ap.add_argument("--scene", default=None,
                    help="the pair (default deploy/scenes/contact_drive.json); without loads it gets contact_drive's")
    ap.add_argument("--thinning", type=float, default=None,
                    help="thinning_mm of both gears (the backlash; default the scene's)")
    ap.add_argument("--h-max", type=float, default=2.5e-6, help="largest time step, s (h = min(this, period / 24))")
    ap.add_argument("--nearfield", action="store_true",
                    help="the contact model with the near-field compliance (\"nearfield\": true on the mesh)")
    ap.add_argument("--coarse", action="store_true", help="the contact model on the coarse mesh (flank 2, across 1, rim 1)")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="the contact model's mesh: the order's default counts times this (grading kept)")
    ap.add_argument("--fmax", type=float, default=0.0,
                    help="the contact model's gears the reduced elastic body with the modes up to this (Hz)")
    ap.add_argument("--settle", type=float, default=5e-3, help="settling time per point, s")
    ap.add_argument("--min-measure", type=float, default=2.5e-3, help="measured at least this long, s")
    ap.add_argument("--min-cycles", type=int, default=12, help="measured at least this many mesh cycles")
    ap.add_argument("--quick", action="store_true",
                    help="order 1, closure, 80 N m, 12 %%, 7 points 0.7-1.3, 4 positions, settle 2 ms")
    ap.add_argument("--peaks-json", default=None, help="write the peaks and the FE mode to this file")
    ap.add_argument("--plot", default=None)
    ap.add_argument("--no-sdof", action="store_true",
                    help="plot without linear_parametric's curves (it has no profile modification's excitation)")
    ap.add_argument("--overlay", default=None,
                    help="the contact curves of more work directories or CSVs, PATH:LABEL;... (their peaks "
                         "reported; with --plot drawn)")
    ap.add_argument("--title", default=None, help="with --plot: the title")
    ap.add_argument("--csv", default=None)
    ap.add_argument("--no-run", action="store_true", help="only report and plot the cached points")
    ap.add_argument("--compare", default=None,
                    help="only plot the contact curves of several work directories, DIR:DAMPING:TORQUE:LABEL;...")
    ap.add_argument("--compare-plot", default="freq_response_damping.png")
    a = ap.parse_args()
    if a.compare:
        compare_plot(a.compare.split(";"), a.compare_plot)
        return
    if a.quick:
        quick = {"order": 1, "torque": 80.0, "damping": 0.12, "contact": "closure", "grid": 7, "grid_from": 0.7,
                 "grid_to": 1.3, "dense": 0, "positions": 4, "settle": 2e-3, "min_measure": 1.2e-3,
                 "work": "/tmp/gearsim_freq_response_quick"}
        for k, v in quick.items():  # options given on the command line win
            if getattr(a, k) == ap.get_default(k):
                setattr(a, k, v)
    os.makedirs(a.work, exist_ok=True)
    modefile = os.path.join(a.work, "fe_mode.json")
    if a.mode_hz > 0:
        mode = {"mean_hz": a.mode_hz}
    elif os.path.exists(modefile):
        mode = json.load(open(modefile))
    else:
        mode = fe_mode(a.build, a.work, a.positions, a.order, a.torque, a.coarse, a.scene, a.thinning, a.scale)
        json.dump(mode, open(modefile, "w"), indent=1)
    f0 = mode["mean_hz"]
    print("FE first torsional mesh mode: %.1f Hz (mean over the mesh cycle)" % f0)
    freqs = [f0 * (a.grid_from + (a.grid_to - a.grid_from) * k / max(a.grid - 1, 1)) for k in range(a.grid)]
    freqs += [f0 * (0.88 + 0.24 * k / (a.dense - 1)) for k in range(a.dense) if a.dense > 1]
    freqs += [float(v) for v in a.extra.split(",") if v]
    freqs += [f0 * float(v) for v in a.extra_rel.split(",") if v]
    freqs = sorted(set(round(f, 1) for f in freqs))
    cachefile = os.path.join(a.work, "points.csv")
    cache = load_cache(cachefile)
    have = {(r["model"], round(r["mesh_hz_target"], 1)) for r in cache}
    models = [m for m in a.models.split(",") if m]
    for m in models:
        if m not in MODELS:
            sys.exit("freq_response: unknown model '%s'" % m)
    if not a.no_run:
        # Cheap models first, the contact model last.
        for m in sorted(models, key=lambda m: m == "contact"):
            for f in freqs:
                if (m, f) in have:
                    continue
                r = run_point(a.build, a.work, m, f0, f, a.damping, a.order, a.torque, a.contact, a.coarse, a.settle,
                              a.min_measure, a.min_cycles, a.scene, a.thinning, a.h_max, a.scale, a.fmax, a.nearfield)
                r["mesh_hz_target"] = f
                cache.append(r)
                have.add((m, f))
                with open(cachefile + ".new", "w", newline="") as fh:  # whole file: older caches lack columns
                    w = csv.DictWriter(fh, fieldnames=FIELDS)
                    w.writeheader()
                    w.writerows(cache)
                os.replace(cachefile + ".new", cachefile)
                print("%-10s %8.1f Hz  DTE rms %7.3f um  DF %6.3f  balance %.1e  %.0f s (%.1f s CPU)%s" %
                      (m, r["mesh_hz"], r["dte_rms_um"], r["dynamic_factor"], r["balance_rel"], r["seconds"],
                       r["cpu_seconds"], "  no contact %.1f %% of steps" % (100 * r["separated_fraction"])
                       if "separated_fraction" in r else ""),
                      flush=True)
    found = {}
    for m in MODELS:
        pts = [r for r in cache if r["model"] == m]
        if len(pts) >= 3:
            found[m] = peaks(pts)
    fc = found["calibrated"][0][0] if found.get("calibrated") else float("nan")
    fm = found["modal"][0][0] if found.get("modal") else float("nan")
    print("\nDTE rms peaks (local maxima, prominence >= 25 %; largest first)")
    print("| model | peak (Hz) | DTE rms (um) | vs FE mode %.1f Hz | vs calibrated (tangent) peak | "
          "vs calibrated (modal) peak |" % f0)
    print("|---|---|---|---|---|---|")
    for m, lst in found.items():
        for fp, yp in lst:
            print("| %s | %.1f | %.3f | %+.2f %% | %+.2f %% | %+.2f %% |" %
                  (m, fp, yp, 100 * (fp / f0 - 1), 100 * (fp / fc - 1), 100 * (fp / fm - 1)))
    fl = float("nan")
    if mode.get("points") and mode.get("inertia"):
        fl, yl = linear_peak(mode, a.damping, a.torque or 20.0)
        print("| FE eigenproblem's damped time-varying mesh (linear_parametric) | %.1f | %.3f | %+.2f %% | %+.2f %% | "
              "%+.2f %% |" % (fl, yl, 100 * (fl / f0 - 1), 100 * (fl / fc - 1), 100 * (fl / fm - 1)))
        fpo, ypo = linear_peak(mode, a.damping, a.torque or 20.0, lo=0.75, push_only=True)
        print("| the same with a spring that only pushes (push_only: the flanks part) | %.1f | %.3f | %+.2f %% | "
              "%+.2f %% | %+.2f %% |" % (fpo, ypo, 100 * (fpo / f0 - 1), 100 * (fpo / fc - 1), 100 * (fpo / fm - 1)))
        for m, lst in found.items():
            if lst:
                print("%s peak against it: %+.2f %%" % (m, 100 * (lst[0][0] / fl - 1)))
    for m in MODELS:  # with contact loss the curve jumps: the largest point and its lower neighbour bracket it
        pts = sorted((r for r in cache if r["model"] == m), key=lambda r: r["mesh_hz"])
        if pts:
            i = max(range(len(pts)), key=lambda i: pts[i]["dte_rms_um"])
            print("%s: largest DTE rms measured %.3f um at %.1f Hz (%+.2f %%), the point below at %s Hz" %
                  (m, pts[i]["dte_rms_um"], pts[i]["mesh_hz"], 100 * (pts[i]["mesh_hz"] / f0 - 1),
                   "%.1f" % pts[i - 1]["mesh_hz"] if i > 0 else "-"))
    fit_report(cache, f0)
    overlays = [overlay_points(o) for o in (a.overlay or "").split(";") if o]
    for label, pts in overlays:  # often points near the peak only: the parabola through the largest and its neighbours
        x = [r["mesh_hz"] for r in pts]
        y = [r["dte_rms_um"] for r in pts]
        i = max(range(len(y)), key=lambda i: y[i]) if y else -1
        if 0 < i < len(y) - 1:
            fp = parabola(x, y, i)
            print("contact, %s: peak (parabola) %.1f Hz (%+.2f %% vs the FE mode), largest DTE rms %.3f um at %.1f Hz" %
                  (label, fp, 100 * (fp / f0 - 1), y[i], x[i]))
        else:
            print("contact, %s: the largest DTE rms is not bracketed by two points" % label)
    con = [r for r in cache if r["model"] == "contact"]
    sep = [r for r in con if r.get("separated_fraction") == r.get("separated_fraction")]
    near = min(con, key=lambda r: abs(r["mesh_hz"] - found["contact"][0][0])) if found.get("contact") else None
    if near and near in sep:
        print("contact: steps without contact %.1f %% at the point nearest its peak (%.1f Hz), %.1f - %.1f %% over "
              "the points" % (100 * near["separated_fraction"], near["mesh_hz"],
                              100 * min(r["separated_fraction"] for r in sep),
                              100 * max(r["separated_fraction"] for r in sep)))
    if a.peaks_json:
        json.dump({"fe_mode_hz": f0, "lumped_mean_hz": mode.get("lumped_mean_hz"), "linear_parametric_hz": fl,
                   "peaks": {m: [{"hz": fp, "dte_rms_um": yp} for fp, yp in lst] for m, lst in found.items()}},
                  open(a.peaks_json, "w"), indent=1)
    if a.csv:
        with open(a.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=FIELDS)
            w.writeheader()
            for r in sorted(cache, key=lambda r: (MODELS.index(r["model"]), r["mesh_hz"])):
                w.writerow(r)
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
        style = {"contact": "k-o", "lumped": "b-s", "calibrated": "g-^", "compliant": "r-d", "modal": "c-v",
                 "ltca": "m-P"}
        for m in MODELS:
            pts = sorted((r for r in cache if r["model"] == m), key=lambda r: r["mesh_hz"])
            if not pts:
                continue
            x = [r["mesh_hz"] for r in pts]
            ax[0].plot(x, [r["dte_rms_um"] for r in pts], style[m], ms=4, label=m)
            ax[1].plot(x, [r["dynamic_factor"] for r in pts], style[m], ms=4, label=m)
        for k, (label, pts) in enumerate(overlays):
            x = [r["mesh_hz"] for r in pts]
            ax[0].plot(x, [r["dte_rms_um"] for r in pts], "-o", color="C%d" % (k + 5), ms=3, lw=1,
                       label="contact, " + label)
            ax[1].plot(x, [r["dynamic_factor"] for r in pts], "-o", color="C%d" % (k + 5), ms=3, lw=1,
                       label="contact, " + label)
        h1 = sorted((r for r in cache if r["model"] == "contact" and r.get("dte_h1_um") == r.get("dte_h1_um")),
                    key=lambda r: r["mesh_hz"])
        if h1:
            ax[0].plot([r["mesh_hz"] for r in h1], [r["dte_h1_um"] / math.sqrt(2) for r in h1], "k--x", ms=4, lw=1,
                       label="contact, first mesh harmonic / sqrt 2")
        if fl == fl and not a.no_sdof:
            lo = min(r["mesh_hz"] for r in cache) / f0
            hi = max(r["mesh_hz"] for r in cache) / f0
            rel = [lo + (hi - lo) * k / 119 for k in range(120)]
            ax[0].plot([r * f0 for r in rel], linear_parametric(mode, a.damping, a.torque or 20.0, rel) * 1e6, "m--",
                       lw=1, label="FE modes, linear time-varying")
            ax[0].plot([r * f0 for r in rel], linear_parametric(mode, a.damping, a.torque or 20.0, rel,
                                                                push_only=True) * 1e6, "m:",
                       lw=1, label="the same, flanks free to part")
        ax[0].set_yscale("log")
        ax[1].set_yscale("log")
        fl = mode.get("lumped_mean_hz")
        for k in range(2):
            ax[k].axvline(f0, color="m", ls="--", lw=1)
            if fc == fc:
                ax[k].axvline(fc, color="c", ls="-.", lw=1)
            if fl:
                ax[k].axvline(fl, color="g", ls=":", lw=1)
            ax[k].grid(alpha=0.3)
        if fl:
            ax[0].text(fl, ax[0].get_ylim()[1] * 0.4, "closed form with k_t %.0f Hz " % fl, color="g", va="top",
                       ha="right")
        ax[0].text(f0, ax[0].get_ylim()[1] * 0.8, " FE mesh mode %.0f Hz" % f0, color="m", va="top")
        if fc == fc:
            ax[0].text(fc, ax[0].get_ylim()[1] * 0.15, "calibrated peak %.0f Hz " % fc, color="c", va="top", ha="right")
        if fm == fm:
            for k in range(2):
                ax[k].axvline(fm, color="c", ls=":", lw=1)
            ax[0].text(fm, ax[0].get_ylim()[1] * 0.05, " modal-calibrated peak %.0f Hz" % fm, color="c", va="top")
        ax[0].set_ylabel("DTE rms (um)")
        ax[1].set_ylabel("dynamic factor (peak / mean force)")
        ax[1].set_xlabel("mesh frequency (Hz)")
        ax[0].legend(loc="lower left", fontsize=8)
        title = "%s: frequency response (%g N m, %g %% damping, order %d%s, %s)" % (
            os.path.splitext(os.path.basename(a.scene or DEFAULT_SCENE))[0], a.torque or 20, 100 * a.damping, a.order,
            ", coarse" if a.coarse else "", a.contact)
        ax[0].set_title(a.title.replace("\\n", "\n") if a.title else title, fontsize=10)
        fig.tight_layout()
        fig.savefig(a.plot, dpi=110)
        print("plot:", a.plot)


if __name__ == "__main__":
    main()
