#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Mesh convergence study of the quasi-static mesh stiffness and static TE
(docs/validation/data.md): runs gearsim-stiffness on a scene for element orders
1 and 2 at several uniform refinements, extrapolates each roll position to
the Richardson limit from the two finest levels of each order, and writes a
CSV of every run and the markdown tables of docs/validation/data.md.

    convergence.py SCENE.json --tool build/src/tools/gearsim-stiffness
                   [--positions 12] [--order1 0 1 2] [--order2 0 1]
                   [--out-csv docs/data/convergence.csv] [--out-md FILE]
                   [--reuse CSV] [--extra NAME=ARGS ...]

Runs already in --reuse (same order, refine, positions, label) are not
repeated. The Richardson limit at each position uses the observed order of
the finest three levels of an order when they converge monotonically,
else the nominal order (2 for linear, 4 for quadratic elements in
energy-like quantities is not assumed: 2 is used for both, the
conservative choice) from the two finest levels.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time

FIELDS = ["label", "order", "refine", "unknowns", "positions", "roll", "k", "te_elastic_um", "te0_um",
          "pairs", "seconds"]


def run(tool, scene, order, refine, positions, extra):
    cmd = [tool, scene, "--positions", str(positions), "--no-tangent", "--json", "--order",
           str(order), "--refine", str(refine)] + extra
    t0 = time.time()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    d = json.loads(out)
    d["wall_s"] = time.time() - t0
    return d


def richardson(levels):
    """levels: list of (unknowns, value) coarse to fine. Returns (limit,
    observed order or None)."""
    if len(levels) < 2:
        return float("nan"), None
    (n1, v1), (n2, v2) = levels[-2], levels[-1]
    p = None
    if len(levels) >= 3:
        v0 = levels[-3][1]
        d1, d2 = v1 - v0, v2 - v1
        if d1 != 0 and d2 != 0 and d1 * d2 > 0 and abs(d2) < abs(d1):
            p = math.log(abs(d1 / d2)) / math.log(2.0)
    q = p if p is not None else 2.0
    r = 2.0 ** q
    return v2 + (v2 - v1) / (r - 1.0), p


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--tool", default="build/src/tools/gearsim-stiffness")
    ap.add_argument("--positions", type=int, default=12)
    ap.add_argument("--order1", type=int, nargs="*", default=[0, 1, 2])
    ap.add_argument("--order2", type=int, nargs="*", default=[0, 1])
    ap.add_argument("--out-csv", default="docs/data/convergence.csv")
    ap.add_argument("--out-md")
    ap.add_argument("--reuse")
    a = ap.parse_args()

    rows = []
    if a.reuse and os.path.exists(a.reuse):
        with open(a.reuse) as f:
            rows = [r for r in csv.DictReader(f)]
    have = {(r["label"], int(r["order"]), int(r["refine"]), int(r["positions"])) for r in rows}
    for order, refines in ((1, a.order1), (2, a.order2)):
        for rf in refines:
            key = ("uniform", order, rf, a.positions)
            if key in have:
                continue
            d = run(a.tool, a.scene, order, rf, a.positions, [])
            unknowns = 2 * sum(d["nodes"])
            for p in d["points"]:
                rows.append({"label": "uniform", "order": order, "refine": rf,
                             "unknowns": unknowns, "positions": a.positions,
                             "roll": p["roll"], "k": p["k"], "te_elastic_um": p["te_elastic_um"],
                             "te0_um": p["te0_um"], "pairs": p["pairs"],
                             "seconds": d["seconds"] / a.positions})
            print(f"order {order} refine {rf}: {unknowns} unknowns, "
                  f"{d['seconds'] / a.positions:.2f} s per position", file=sys.stderr)
    with open(a.out_csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in FIELDS})

    # tables
    def series(order):
        lv = sorted({int(r["refine"]) for r in rows if int(r["order"]) == order
                     and r["label"] == "uniform"})
        return lv

    out = []
    lims = {}
    for qty in ("k", "te_elastic_um"):
        for order in (1, 2):
            lv = series(order)
            if not lv:
                continue
            rolls = sorted({float(r["roll"]) for r in rows if int(r["order"]) == order})
            per = {}
            for rl in rolls:
                levels = []
                for rf in lv:
                    m = [r for r in rows if int(r["order"]) == order and int(r["refine"]) == rf
                         and abs(float(r["roll"]) - rl) < 1e-9]
                    if m:
                        levels.append((int(m[0]["unknowns"]), float(m[0][qty])))
                per[rl] = levels
            lims[(qty, order)] = {rl: richardson(v) for rl, v in per.items()}
    # reference limit: the quadratic extrapolation when present
    ref_order = 2 if any(k[1] == 2 for k in lims) else 1
    for qty, unit in (("k", "N/(mm um)"), ("te_elastic_um", "um")):
        lim = lims.get((qty, ref_order), {})
        out.append(f"\n### {'mesh stiffness k' if qty == 'k' else 'static TE'} ({unit}), "
                   f"per roll position\n")
        hdr = ["roll", "limit"]
        cols = []
        for order in (1, 2):
            for rf in series(order):
                n = [int(r["unknowns"]) for r in rows if int(r["order"]) == order
                     and int(r["refine"]) == rf][0]
                cols.append((order, rf))
                hdr.append(f"o{order} r{rf} ({n})")
        out.append("| " + " | ".join(hdr) + " |")
        out.append("|" + "---|" * len(hdr))
        worst = {c: 0.0 for c in cols}
        means = {c: [] for c in cols}
        lmeans = []
        for rl in sorted(lim):
            L = lim[rl][0]
            lmeans.append(L)
            cells = [f"{rl:.3f}", f"{L:.4f}"]
            for c in cols:
                m = [r for r in rows if int(r["order"]) == c[0] and int(r["refine"]) == c[1]
                     and abs(float(r["roll"]) - rl) < 1e-9]
                v = float(m[0][qty])
                e = (v - L) / L * 100
                worst[c] = max(worst[c], abs(e))
                means[c].append(v)
                cells.append(f"{v:.4f} ({e:+.2f}%)")
            out.append("| " + " | ".join(cells) + " |")
        lm = sum(lmeans) / len(lmeans)
        out.append("| max abs err | | " + " | ".join(f"{worst[c]:.2f}%" for c in cols) + " |")
        out.append(f"| mean | {lm:.4f} | " + " | ".join(
            f"{sum(means[c]) / len(means[c]):.4f} ({(sum(means[c]) / len(means[c]) - lm) / lm * 100:+.2f}%)"
            for c in cols) + " |")
        out.append("| s/position | | " + " | ".join(
            f"{float([r for r in rows if int(r['order']) == c[0] and int(r['refine']) == c[1]][0]['seconds']):.2f}"
            for c in cols) + " |")
        orders = [p for (_, p) in lim.values() if p is not None]
        if orders:
            out.append(f"\nObserved order (finest three levels, order {ref_order}): "
                       f"median {sorted(orders)[len(orders) // 2]:.2f} over {len(orders)} "
                       f"of {len(lim)} positions (others: nominal 2).")
    text = "\n".join(out) + "\n"
    if a.out_md:
        with open(a.out_md, "w") as f:
            f.write(text)
    print(text)


if __name__ == "__main__":
    main()
