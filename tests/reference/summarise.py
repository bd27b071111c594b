#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Summarise DIR/runs.csv (raw CalculiX runs of run_pair.py) into
DIR/results.csv (every mesh level plus the Richardson-extrapolated value per
roll position) and DIR/reference.csv (the extrapolated values the test suite
compares against), and print the convergence table.

    summarise.py DIR [--h H1 H2 H3] [--penalty P]

Richardson extrapolation on the TE at three mesh levels h, h/2, h/4 (the
three finest run at every position unless --h names them): observed order
p = log2((T1 - T2) / (T2 - T3)); the limit T = T3 + (T3 - T2) / (2^p - 1).
Where the three are not monotone or p falls outside [0.5, 4] the order is
taken as 2 (quadratic elements) and flagged.  The error estimate of the
finest level is |T3 - T|.  Stiffness k = F / TE (N/m), per mm face width
k / b / 1e6 (N/(mm um)).
"""
import argparse
import csv
import json
import math
import os
from collections import defaultdict


def richardson(v):
    t1, t2, t3 = v
    d1, d2 = t1 - t2, t2 - t3
    flag = ""
    if d1 != 0 and d2 != 0 and d1 * d2 > 0:
        p = math.log2(d1 / d2)
    else:
        p = float("nan")
    if not (0.5 <= p <= 4.0):
        flag = "p=2 assumed"
        p = 2.0
    lim = t3 + (t3 - t2) / (2.0 ** p - 1.0)
    return lim, p, flag


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--h", type=float, nargs=3)
    ap.add_argument("--penalty", type=float, default=1e8)
    a = ap.parse_args()
    cfg = json.load(open(os.path.join(a.dir, "pair.json")))
    face = cfg["face_width_mm"]
    force = cfg.get("line_load_n_per_mm", 200.0) * face
    runs = defaultdict(dict)     # roll -> h -> row
    for r in csv.DictReader(open(os.path.join(a.dir, "runs.csv"))):
        if abs(float(r["penalty"]) - a.penalty) > 1e-6 * a.penalty:
            continue
        runs[float(r["roll"])][float(r["h_mm"])] = r
    hs_all = sorted({h for v in runs.values() for h in v}, reverse=True)
    if a.h:
        hs_all = sorted(a.h, reverse=True)
    # per position: its three finest levels (h, h/2, h/4); where only two
    # exist, the order observed at the other positions (median) is used
    orders = []
    for v in runs.values():
        have = [h for h in hs_all if h in v]
        if len(have) >= 3:
            te = [float(v[h]["te_m"]) for h in have[-3:]]
            lim, p, flag = richardson(te)
            if not flag:
                orders.append(p)
    orders.sort()
    p_two = orders[len(orders) // 2] if orders else 2.0
    hs = hs_all
    res, ref = [], []
    print("TE (um) and k (N/(mm um)) per roll position; the three finest levels of h = %s mm" % hs)
    print("%6s " % "roll" + " ".join("%10s" % ("TE %d" % i) for i in range(3))
          + " %10s %6s %9s %9s %9s %s" % ("TE lim", "p", "err fin%", "k lim", "k fine", ""))
    for roll in sorted(runs):
        v = runs[roll]
        for h in hs_all:
            if h in v:
                r = v[h]
                res.append(dict(roll="%.6f" % roll, level="h=%g" % h, h_mm=h,
                                nodes=r["nodes"], dofs=r["dofs"], te_m=r["te_m"],
                                te_um=r["te_um"], k_n_per_m=r["k_n_per_m"],
                                k_n_per_mm_um=r["k_n_per_mm_um"], ccx_s=r["ccx_s"],
                                order="", note=""))
        have = [h for h in hs_all if h in v]
        if len(have) < 2:
            continue
        if len(have) >= 3:
            te = [float(v[h]["te_m"]) for h in have[-3:]]
            lim, p, flag = richardson(te)
        else:
            te = [float("nan")] + [float(v[h]["te_m"]) for h in have]
            p = p_two
            lim = te[2] + (te[2] - te[1]) / (2.0 ** p - 1.0)
            flag = "two levels, median order of the other positions"
        err = abs(te[2] - lim) / lim
        k = force / lim
        res.append(dict(roll="%.6f" % roll, level="richardson", h_mm=0, nodes="", dofs="",
                        te_m="%.10e" % lim, te_um="%.6f" % (lim * 1e6),
                        k_n_per_m="%.6e" % k, k_n_per_mm_um="%.5f" % (k / face / 1e6),
                        ccx_s="", order="%.3f" % p, note=flag))
        ref.append(dict(roll="%.6f" % roll, te_m="%.10e" % lim, te_um="%.6f" % (lim * 1e6),
                        k_n_per_m="%.6e" % k, k_n_per_mm_um="%.5f" % (k / face / 1e6),
                        finest_h_mm=have[-1], finest_rel_err="%.5f" % err, order="%.3f" % p))
        print("%6.3f " % roll + " ".join("%10.5f" % (t * 1e6) for t in te)
              + " %10.5f %6.2f %9.4f %9.4f %9.4f %s" % (lim * 1e6, p, 100 * err,
                                                         k / face / 1e6,
                                                         force / te[2] / face / 1e6, flag))
    with open(os.path.join(a.dir, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(res[0].keys()))
        w.writeheader()
        w.writerows(res)
    with open(os.path.join(a.dir, "reference.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(ref[0].keys()))
        w.writeheader()
        w.writerows(ref)
    # per level: error against the limit, time
    lims = {float(r["roll"]): float(r["te_m"]) for r in ref}
    print("\nlevel     nodes(mean)  max|k err|%  mean k err%  wall s/position  cpu s/position (mean)")
    for h in hs_all:
        errs, nodes, secs, cpus = [], [], [], []
        for roll, lim in lims.items():
            if h in runs[roll]:
                r = runs[roll][h]
                errs.append(lim / float(r["te_m"]) - 1.0)
                nodes.append(int(r["nodes"]))
                secs.append(float(r["ccx_s"]) + float(r["mesh_s"]))
                cpus.append(float(r["ccx_cpu_s"]))
        if errs:
            print("h=%-6g %10.0f %12.3f %12.3f %16.1f %16.1f" % (
                h, sum(nodes) / len(nodes), 100 * max(abs(e) for e in errs),
                100 * sum(errs) / len(errs), sum(secs) / len(secs), sum(cpus) / len(cpus)))


if __name__ == "__main__":
    main()
