#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The arithmetic of tests/bench/dyn_convergence.py on synthetic data:
observed orders (equal and unequal size ratios), Richardson estimates,
the 2 % / 5 % bars and the per-family verdicts of its tables. Each check
compares against a value set by construction, so a wrong formula fails."""
import math
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "bench"))
import dyn_convergence as dc  # noqa: E402

failures = []


def check(name, cond, detail=""):
    print(("ok" if cond else "not ok") + f" - {name} {detail}")
    if not cond:
        failures.append(name)


def close(a, b, tol):
    return a is not None and b is not None and abs(a - b) <= tol * max(1.0, abs(b))


# f = f* + C s^p on ratio-2 sizes: p = log2(|d1| / |d2|), Richardson exact
for p_true, fstar, C in ((1.0, 3.0, 2.0), (1.5, 54.1, -0.7), (2.0, 1.4, 0.3), (0.5, 10.0, 5.0)):
    s = [1.0, 0.5, 0.25]
    v = [fstar + C * x ** p_true for x in s]
    p = dc.observed_order(v[0], v[1], v[2], 2.0, 2.0)
    check(f"order p={p_true} ratio 2", close(p, p_true, 1e-12), f"got {p}")
    check(f"log2 form p={p_true}", close(p, math.log2(abs(v[1] - v[0]) / abs(v[2] - v[1])), 1e-12))
    r = dc.richardson(v[1], v[2], 2.0, p)
    check(f"Richardson p={p_true}", close(r, fstar, 1e-12), f"got {r} want {fstar}")

# unequal ratios (mesh counts x1, x1.5, x2): sizes 1, 2/3, 1/2
for p_true in (0.8, 1.0, 2.0, 3.0):
    s = [1.0, 2.0 / 3.0, 0.5]
    v = [7.0 + 4.0 * x ** p_true for x in s]
    p = dc.observed_order(v[0], v[1], v[2], s[0] / s[1], s[1] / s[2])
    check(f"order p={p_true} unequal ratios", close(p, p_true, 1e-9), f"got {p}")
    r = dc.richardson(v[1], v[2], s[1] / s[2], p)
    check(f"Richardson unequal p={p_true}", close(r, 7.0, 1e-9), f"got {r}")

# no convergence observed: sign change, growth, a zero difference
check("oscillating -> None", dc.observed_order(1.0, 2.0, 1.5, 2, 2) is None)
check("growing differences -> None", dc.observed_order(1.0, 1.1, 1.4, 2, 2) is None)
check("zero difference -> None", dc.observed_order(1.0, 1.0, 1.0, 2, 2) is None)
check("Richardson without order -> None", dc.richardson(1.0, 2.0, 2.0, None) is None)

# the bars
check("within 2 %", dc.within(100.0, 101.9, 0.02))
check("outside 2 %", not dc.within(100.0, 103.0, 0.02))
check("within 5 %", dc.within(1000.0, 1040.0, 0.05))
check("outside 5 %", not dc.within(1000.0, 1100.0, 0.05))

# family(): differences and relative change of the finest step
fam = dc.family([(1.0, 2.0), (0.5, 1.5), (0.25, 1.25)])
check("family diffs", fam["diffs"] == [-0.5, -0.25])
check("family order 1", close(fam["p"], 1.0, 1e-12))
check("family Richardson 1.0", close(fam["rich"], 1.0, 1e-12))
check("family rel_last", close(fam["rel_last"], 0.25 / 1.25, 1e-12))
check("family uncertainty, three points: distance to the finest", close(fam["unc"], 0.25, 1e-12))
# four points, f = 1 + s + s^2: the last triple's order and Richardson are
# closer to the limit than the first's; the uncertainty is the larger of the
# estimate's distance to the finest value and its change from the triple before
pts4 = [(s_, 1 + s_ + s_ * s_) for s_ in (1.0, 0.5, 0.25, 0.125)]
fam4 = dc.family(pts4)
check("family orders per triple", len(fam4["orders"]) == 2 and all(o is not None for o in fam4["orders"]))
check("family orders approach 1", abs(fam4["orders"][1] - 1) < abs(fam4["orders"][0] - 1))
r_prev = dc.family(pts4[:3])["rich"]
check("family uncertainty, four points",
      close(fam4["unc"], max(abs(fam4["rich"] - pts4[3][1]), abs(fam4["rich"] - r_prev)), 1e-12))
check("family Richardson nearer the limit than the finest", abs(fam4["rich"] - 1) < abs(pts4[3][1] - 1))

# levels
check("level o2r1", dc.parse_level("o2r1") == (2, 1, 1.0, 0.5))
check("level o2s1.5", dc.parse_level("o2s1.5")[3] == 1.0 / 1.5)
try:
    dc.parse_level("fine")
    check("bad level refused", False)
except ValueError:
    check("bad level refused", True)


# the tables' verdicts on a synthetic grid: DTE rms and mean TE converge at
# order 1 in h and 2 in the mesh with the two finest within 2 %; the peak
# force keeps growing (misses 5 %)
def row(level, h, dte, te, peak):
    o, rf, sc, size = dc.parse_level(level)
    return {"scene": "syn", "contact": "closure_energy", "zeta": 0.02, "fhz": 9200, "order": o, "refine": rf,
            "scale": sc, "level": level, "size": size, "h": h, "from": 0.035, "to": 0.065, "unknowns": 1,
            "cycles": 4, "mesh_hz": 141, "dte_rms_um": dte, "mean_te_um": te, "te_pp_um": 1,
            "peak_force_n": peak, "mean_force_n": 568, "ratio": 2 / 3, "balance_rel": 1e-15,
            "pen_max_um": 0, "force_peak_over_mean": 1, "strain_max_mj": 1, "strain_mean_mj": 1,
            "contact_work_j": 0, "steps": 1, "cpu_s": 1, "cpu_per_sim_s": 1e3 * (1 / h) * 1e-5 / size}


def dte(s, h):
    return 1.4 + 0.1 * s ** 2 + 2e3 * h


def te(s, h):
    return 54.0 - 0.5 * s ** 2 + 1e4 * h


hs = [2e-5, 1e-5, 5e-6]
levels = ["o1r0", "o1r1", "o1r2"]
rows = []
for h in hs:
    rows.append(row("o1r2", h, dte(0.25, h), te(0.25, h), 700 + 1e8 * (2e-5 - h)))
for lv, s in (("o1r0", 1.0), ("o1r1", 0.5)):
    rows.append(row(lv, 5e-6, dte(s, 5e-6), te(s, 5e-6), 700 + 1e8 * 1.5e-5 * (1 + s)))
text, verdicts = dc.tables(rows, "syn", hs, levels, "closure_energy", [0.02], 0.035, 0.065, 1.0)
check("h family: DTE meets 2 %", verdicts.get((0.02, "h", "dte_rms_um")) is True, str(verdicts))
check("mesh family: mean TE meets 2 %", verdicts.get((0.02, "mesh", "mean_te_um")) is True)
check("h family: peak force misses 5 %", verdicts.get((0.02, "h", "peak_force_n")) is False)
check("table reports order 1.00 in h", "| 1.00 |" in text)
check("table reports order 2.00 in the mesh", "| 2.00 |" in text)
limit_dte = 1.4
check("converged estimate printed", f"DTE rms {limit_dte:.4f} um" in text, text[-400:])
check("reference marked converged", "the two finest of every family within 2 %" in text)
# the same grid with the DTE still moving by 10 % between the two finest steps
rows2 = [dict(r) for r in rows]
for r in rows2:
    if r["level"] == "o1r2" and r["h"] == 5e-6:
        r["dte_rms_um"] *= 0.9
text2, verdicts2 = dc.tables(rows2, "syn", hs, levels, "closure_energy", [0.02], 0.035, 0.065, 1.0)
check("moving DTE misses 2 %", verdicts2.get((0.02, "h", "dte_rms_um")) is False)
check("reference marked not converged", "NOT converged" in text2)
check("no cheapest setting when not converged", "No converged value" in text2 and "Cheapest" not in text2)
check("cheapest setting when converged", "Cheapest run within 2 % of both: o1r2 at h = 1e-05 s" in text)

# every mesh's DTE rms (dyn_convergence_run's "meshes") kept through normalise
# and listed in its own table
j = dict(rows[0], meshes=[{"name": "sun-planet1", "dte_rms_um": 0.30924}, {"name": "planet1-ring",
                                                                          "dte_rms_um": 0.2268}])
n = dc.normalise(j)
check("per-mesh DTE kept", n["mesh_dte_rms_um"] == "sun-planet1=0.309240;planet1-ring=0.226800",
      n["mesh_dte_rms_um"])
text3, _ = dc.tables([n] + rows[1:], "syn", hs, levels, "closure_energy", [0.02], 0.035, 0.065, 1.0)
check("per-mesh table", "| sun-planet1 | planet1-ring |" in text3 and "| 0.3092 | 0.2268 |" in text3,
      text3[:600])
check("no per-mesh table without it", "DTE rms of every mesh" not in text)

if failures:
    print(f"FAILED: {len(failures)}: {', '.join(failures)}")
    sys.exit(1)
print("all checks passed")
