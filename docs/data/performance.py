#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The fidelity-ladder table of the performance report (docs/performance/).

    docs/data/performance.py [--table docs/data/tradeoff.csv] [--out docs/data/performance_tradeoff.csv]

Reads the measured trade-off table (written by tests/bench/bench_tradeoff,
`gearctl bench tradeoff --csv docs/data/tradeoff.csv`) and writes the short
table the report includes: per scene and rung at the time step 1e-5 s (the
rungs measured only at other steps: their finest), the cost in CPU seconds
per simulated second, the cost as a ratio to the scene's kinematic rung at
the same step, and the relative errors of the dynamic transmission error,
the peak mesh force, the mesh-order amplitude and the output speed against
the scene's reference row (the table's last row per scene). Runs nothing.
"""
import argparse
import csv
import os

HERE = os.path.dirname(os.path.abspath(__file__))
LABEL = {"kinematic": "kinematic (rigid ratio)", "impact": "impact (rigid teeth, backlash)",
         "lumped": "lumped (rectangular stiffness)", "calibrated": "lumped, calibrated from the FE analysis",
         "compliant": "compliant (patch, tooth bending)", "contact_seed": "elastic gears, seed contact rows",
         "contact": "elastic gears (full FE bodies)", "reduced": "elastic gears (reduced bodies)"}


def short(rows):
    """Rows of one scene: one per rung (h 1e-5 s where measured), the reference last."""
    ref = rows[-1]
    kin = {r["h"]: float(r["cost"]) for r in rows if r["level"] == "kinematic"}
    out = []
    for level in [lv for i, lv in enumerate(r["level"] for r in rows[:-1]) if lv not in
                  [r["level"] for r in rows[:i]]]:
        cand = [r for r in rows[:-1] if r["level"] == level and r["refine"] == "0" and r["scale"] in ("1", "")]
        if not cand:
            continue
        pick = [r for r in cand if float(r["h"]) == 1e-5] or sorted(cand, key=lambda r: float(r["h"]))[:1]
        out.append((pick[0], False))
    out.append((ref, True))
    table = []
    for r, is_ref in out:
        k = kin.get(r["h"])
        mesh = "o2, refine %s" % r["refine"] if r["refine"] != "0" else (
            "o2, counts x %s" % r["scale"] if r["scale"] not in ("1", "") else "default")
        errs = ["reference"] * 4 if is_ref else ["%.*f %%" % (2 if c == "err_speed" else 1, 100 * float(r[c]))
                                                  for c in ("err_dte", "err_force", "err_mesh", "err_speed")]
        table.append([r["scene"], ("reference: " if is_ref else "") + LABEL.get(r["level"], r["level"]),
                      "%g" % float(r["h"]), mesh, "%.3g" % float(r["cost"]),
                      "%.3g" % (float(r["cost"]) / k) if k else "", *errs])
    return table


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--table", default=os.path.join(HERE, "tradeoff.csv"))
    ap.add_argument("--out", default=os.path.join(HERE, "performance_tradeoff.csv"))
    a = ap.parse_args()
    rows = list(csv.DictReader(open(a.table, newline="")))
    head = ["scene", "rung", "h (s)", "mesh", "CPU s per simulated s", "cost / kinematic",
            "DTE rms error", "peak force error", "mesh-order error", "speed error"]
    with open(a.out, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(head)
        for scene in dict.fromkeys(r["scene"] for r in rows):
            w.writerows(short([r for r in rows if r["scene"] == scene]))
    print("wrote", a.out)


if __name__ == "__main__":
    main()
