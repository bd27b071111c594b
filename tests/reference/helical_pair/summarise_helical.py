#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Summarise the 3D helical pair runs (runs.csv, profiles.csv) into
reference.csv: per roll position, misalignment and gear sector size (teeth
per gear body), at the reference level (the finest mesh size run at every
position of that misalignment and sector size), the TE,
k, peak load per unit face width (the largest mean over 4 mm of face) and
the load profile along the face
(summed over the driven teeth, NBIN bins; the peak is "nan" where the
contact forces' transverse load misses the applied force by more than 5 %:
the profile is then not valid); the change to a finer level
where one ran at that position (the convergence figure); where three
levels up to the reference level ran, the Richardson limit of TE (what the
reference holds then).

Usage: ./summarise_helical.py      (reads and writes beside this file)
"""
import csv
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
NBIN = 20
PEAK_BINS = 4


def richardson(h, v):
    """Limit and order from the three finest (h, v), coarse to fine; None
    where the changes do not shrink (no asymptotic range)."""
    (h0, v0), (h1, v1), (h2, v2) = list(zip(h, v))[-3:]
    d1, d2 = v1 - v0, v2 - v1
    if d1 == 0 or d2 / d1 <= 0 or abs(d2) >= abs(d1):
        return None
    r = h1 / h2
    p = math.log(abs(d1 / d2)) / math.log(r)
    return v2 + d2 / (r ** p - 1.0), p


def peak_of(q, width=None):
    """The peak load per unit face width: the largest mean of `width`
    neighbouring bins (PEAK_BINS: 4 mm, about three elements of the 3D
    mesh, whose contact forces scatter from one element to the next)."""
    w = width or PEAK_BINS
    return max(sum(q[i:i + w]) / w for i in range(len(q) - w + 1))


def teeth_of(r):
    """The gear sector size of a stored row (rows before that column: 5)."""
    return int(r.get("sector_teeth") or 5)


def main():
    runs = list(csv.DictReader(open(os.path.join(HERE, "runs.csv"))))
    profs = list(csv.DictReader(open(os.path.join(HERE, "profiles.csv"))))
    prof = {}
    for r in profs:
        key = (round(float(r["roll"]), 6), float(r["misalign_um"]), teeth_of(r), float(r["h_mm"]))
        acc = prof.setdefault(key, [0.0] * NBIN)
        for i in range(NBIN):
            acc[i] += float(r["q%02d" % i])
    by = {}
    for r in runs:
        key = (round(float(r["roll"]), 6), float(r["misalign_um"]), teeth_of(r))
        by.setdefault(key, []).append(r)
    # the reference level of a misalignment: the finest h run at all its
    # positions (one level for the whole cycle); a finer level run at some
    # positions gives the change (finer / reference - 1) there
    hs_all = {}
    for (roll, f, t), rows in by.items():
        hs_all.setdefault((f, t), []).append(set(float(r["h_mm"]) for r in rows))
    href = {f: min(set.intersection(*v)) for f, v in hs_all.items()}
    out = []
    print("%6s %5s %5s %6s %9s %9s %8s %6s %9s %9s %8s %8s" % ("roll", "f um", "teeth", "h mm", "TE um", "k", "peak",
                                                              "finer", "dTE %", "dpeak %", "TE lim", "cpu s"))
    for key in sorted(by):
        rows = sorted(by[key], key=lambda r: -float(r["h_mm"]))
        hr = href[key[1:]]
        rows = [r for r in rows if float(r["h_mm"]) >= hr] + [r for r in rows if float(r["h_mm"]) < hr]
        hs = [float(r["h_mm"]) for r in rows]
        te = [float(r["te_um"]) for r in rows]
        iref = hs.index(hr)
        fin = rows[iref]
        q = prof.get(key + (hs[iref],), [0.0] * NBIN)
        # the profile counts only where the contact forces carry the
        # applied force (within 5 %)
        valid = abs(float(fin["contact_force_n"]) / float(fin["force_n"]) - 1.0) < 0.05
        peak = peak_of(q) if valid else float("nan")
        dte = dpk = float("nan")
        hfiner = ""
        if iref + 1 < len(rows):
            hfiner = hs[iref + 1]
            dte = 100.0 * (te[iref + 1] / te[iref] - 1.0)
            q1 = prof.get(key + (hfiner,), [0.0] * NBIN)
            dpk = 100.0 * (peak_of(q1) / peak - 1.0) if valid and peak > 0 else float("nan")
        lim = richardson(hs[:iref + 1], te[:iref + 1]) if iref >= 2 else None
        te_ref = lim[0] if lim else te[iref]
        F = float(fin["force_n"])
        b = F / float(fin["k_n_per_mm_um"]) / te[iref]
        out.append(dict(roll="%.6f" % key[0], misalign_um=key[1], sector_teeth=key[2], h_mm=hs[iref],
                        levels=iref + 1,
                        te_um="%.6f" % te_ref, te_level_um="%.6f" % te[iref],
                        k_n_per_mm_um="%.5f" % (F / te_ref / b), peak_n_per_mm="%.3f" % peak,
                        finer_h_mm=hfiner, te_change_pct="%.4f" % dte, peak_change_pct="%.4f" % dpk,
                        order="%.3f" % lim[1] if lim else "",
                        ccx_cpu_s=fin["ccx_cpu_s"], nodes=fin["nodes"],
                        contact_force_n=fin["contact_force_n"], force_n=fin["force_n"],
                        hub_force_n=fin["hub_force_n"],
                        **{"q%02d" % i: "%.4f" % q[i] for i in range(NBIN)}))
        print("%6.3f %5g %5d %6g %9.4f %9.4f %8.2f %6s %9.3f %9.3f %9s %8s" % (
            key[0], key[1], key[2], hs[iref], te[iref], F / te[iref] / b, peak, hfiner, dte, dpk,
            "%.4f" % lim[0] if lim else "-", fin["ccx_cpu_s"]))
    if not out:
        sys.exit("no runs")
    with open(os.path.join(HERE, "reference.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(out[0].keys()))
        w.writeheader()
        w.writerows(out)
    levels = {}
    for r in runs:
        levels.setdefault(float(r["h_mm"]), []).append(r)
    print("\nlevel    runs  nodes(mean)  ccx cpu s/position (mean)  ccx wall s (mean)")
    for h in sorted(levels, reverse=True):
        rs = levels[h]
        print("h=%-5g %5d %12.0f %26.1f %18.1f" % (h, len(rs), sum(float(r["nodes"]) for r in rs) / len(rs),
                                                   sum(float(r["ccx_cpu_s"]) for r in rs) / len(rs),
                                                   sum(float(r["ccx_s"]) for r in rs) / len(rs)))


if __name__ == "__main__":
    main()
