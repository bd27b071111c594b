#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Dynamic convergence study of the contact model in the time step h and
the mesh (issue 15 item 3; docs/validation/data.md).

For one scene with `contact` meshes it runs `dyn_convergence_run` (one
process per run, one at a time) on a grid: every step size at the finest
mesh level and every mesh level at the finest step, with the given
contact treatment and material damping ratios, plus optional comparison
rows (e.g. the seed's scheme). Each run reports over the whole mesh
cycles of a steady window: DTE rms (kinematic TE about its mean), mean TE,
peak and mean mesh force, speed ratio, energy balance residual, deepest
penetration, largest force / mean and largest strain energy (locking
indicators), CPU seconds per simulated second. Then per quantity and
family (h at the finest mesh, mesh at the finest h): the successive
differences, the observed order, the Richardson estimate and whether the
two finest agree within the bar (2 % DTE rms and mean TE, 5 % peak force).

    dyn_convergence.py [--scene contact_drive] [--tool build/tests/bench/dyn_convergence_run]
        [--hs 2e-5 1e-5 5e-6] [--levels o1r0 o1r1 o1r2] [--zeta 0.02 0]
        [--fhz 9200] [--from 0.035] [--to 0.065] [--contact closure_energy]
        [--extra seed:o1r0:1e-5 ...] [--static-mj 1.0] [--fmax F]
        [--reuse CSV] [--out-csv CSV] [--out-md MD] [--quick] [--no-run]

A mesh level is `o<order>r<refine>` (uniform refinements of the order's
default counts: element size / 2^refine) or `o<order>s<scale>` (the
default flank/across/rim counts times the scale: element size / scale).
Runs already in --reuse (CSV written by this tool, or JSON lines of
dyn_convergence_run) with the same scene, h, level, contact, damping and
window are not repeated; new runs are appended to --out-csv as they finish.
--quick: a tiny grid (order 1 refine 0, h 4e-5 and 2e-5, a 14 ms window)
that checks the tool end to end in about a minute.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

FIELDS = ["scene", "contact", "zeta", "fhz", "order", "refine", "scale", "level", "size", "h",
          "from", "to", "unknowns", "cycles", "mesh_hz", "dte_rms_um", "mean_te_um", "te_pp_um",
          "peak_force_n", "mean_force_n", "ratio", "balance_rel", "pen_max_um",
          "force_peak_over_mean", "strain_max_mj", "strain_mean_mj", "contact_work_j", "steps",
          "cpu_s", "cpu_per_sim_s", "fmax_hz", "mesh_dte_rms_um"]

# quantity, label, bar (relative agreement of the two finest), or None
QUANTITIES = [("dte_rms_um", "DTE rms (um)", 0.02), ("mean_te_um", "mean TE (um)", 0.02),
              ("peak_force_n", "peak force (N)", 0.05), ("mean_force_n", "mean force (N)", None),
              ("ratio", "speed ratio", None)]


# ---------------------------------------------------------------- arithmetic

def observed_order(f1, f2, f3, r12, r23):
    """Observed order p of three solutions f1, f2, f3 on sizes s1 > s2 > s3
    (r12 = s1 / s2, r23 = s2 / s3), error model f = f* + C s^p: p solves
    (f2 - f1) / (f3 - f2) = r23^p (r12^p - 1) / (r23^p - 1); for r12 = r23 = r
    that is log_r(|d1| / |d2|). None when the differences change sign,
    vanish or do not shrink (no convergence observed)."""
    d1, d2 = f2 - f1, f3 - f2
    if d1 == 0 or d2 == 0 or d1 * d2 < 0 or abs(d2) >= abs(d1):
        return None
    q = d1 / d2
    if abs(r12 - r23) < 1e-12:
        return math.log(q) / math.log(r23)

    def g(p):
        return r23 ** p * (r12 ** p - 1) / (r23 ** p - 1) - q
    lo, hi = 1e-6, 1.0
    while g(hi) < 0 and hi < 64:
        hi *= 2
    if g(lo) > 0 or g(hi) < 0:
        return None
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if g(mid) < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def richardson(f2, f3, r23, p):
    """Richardson estimate of the limit from the two finest solutions, size
    ratio r23 and order p (None when p is None)."""
    if p is None:
        return None
    return f3 + (f3 - f2) / (r23 ** p - 1)


def within(f2, f3, bar):
    """Do the two finest agree within the relative bar (against the finest)?"""
    return abs(f3 - f2) <= bar * abs(f3)


def family(points):
    """points: [(size, value)] coarse to fine (at least 2). Returns a dict
    with the differences, the observed order of every successive triple
    ("orders"; "p" the finest one's), the Richardson estimate over the
    finest three ("rich"), its uncertainty ("unc": the larger of its
    distance to the finest value and, with four points or more, its change
    from the Richardson estimate of the triple before; None without an
    estimate) and the relative change of the finest step."""
    out = {"values": [v for _, v in points], "diffs": [], "p": None, "rich": None, "rel_last": None,
           "orders": [], "unc": None}
    for (s1, v1), (s2, v2) in zip(points, points[1:]):
        out["diffs"].append(v2 - v1)
    if len(points) >= 2:
        (s2, v2), (s3, v3) = points[-2], points[-1]
        out["rel_last"] = abs(v3 - v2) / abs(v3) if v3 else None
    if len(points) >= 3:
        (s1, v1), (s2, v2), (s3, v3) = points[-3:]
        out["p"] = observed_order(v1, v2, v3, s1 / s2, s2 / s3)
        out["rich"] = richardson(v2, v3, s2 / s3, out["p"])
        for k in range(len(points) - 2):
            (a1, b1), (a2, b2), (a3, b3) = points[k:k + 3]
            out["orders"].append(observed_order(b1, b2, b3, a1 / a2, a2 / a3))
        if out["rich"] is not None:
            out["unc"] = abs(out["rich"] - v3)
            if len(points) >= 4:
                (a1, b1), (a2, b2), (a3, b3) = points[-4:-1]
                prev = richardson(b2, b3, a2 / a3, observed_order(b1, b2, b3, a1 / a2, a2 / a3))
                if prev is not None:
                    out["unc"] = max(out["unc"], abs(out["rich"] - prev))
    return out


# ---------------------------------------------------------------- runs

def parse_level(lv):
    """o<order>r<refine> or o<order>s<scale> -> (order, refine, scale, relative element size)."""
    if not lv.startswith("o") or ("r" not in lv and "s" not in lv):
        raise ValueError(f"mesh level {lv!r}: expected o<order>r<refine> or o<order>s<scale>")
    if "r" in lv:
        o, r = lv[1:].split("r")
        return int(o), int(r), 1.0, 1.0 / 2 ** int(r)
    o, s = lv[1:].split("s")
    return int(o), 0, float(s), 1.0 / float(s)


def level_name(order, refine, scale):
    return f"o{order}r{refine}" if float(scale) == 1.0 else f"o{order}s{float(scale):g}"


def fmax_of(r):
    """reduction.f_max_hz of a run (0: the full FE bodies; older rows have none)."""
    return float(r.get("fmax_hz") or 0)


def key_of(r):
    return (r["scene"], r["contact"], f"{float(r['zeta']):g}", level_name(int(r["order"]), int(r["refine"]),
            float(r["scale"])), f"{float(r['h']):g}", f"{float(r['from']):g}", f"{float(r['to']):g}",
            f"{fmax_of(r):g}")


def normalise(d):
    """A run (JSON line of dyn_convergence_run or CSV row) as a row of FIELDS;
    the per-mesh DTE rms ("meshes") kept as `name=value` pairs joined by ';'."""
    if isinstance(d.get("meshes"), list):
        d["mesh_dte_rms_um"] = ";".join(f"{m['name']}={m['dte_rms_um']:.6f}" for m in d["meshes"])
    order, refine, scale = int(d["order"]), int(d["refine"]), float(d["scale"])
    d["level"] = level_name(order, refine, scale)
    d["size"] = 1.0 / (scale * 2 ** refine)
    return {k: d.get(k, "") for k in FIELDS}


def load_rows(path):
    rows = []
    if not path or not os.path.exists(path):
        return rows
    with open(path) as f:
        text = f.read()
    if text.lstrip().startswith("{"):
        for line in text.splitlines():
            if line.strip():
                rows.append(normalise(json.loads(line)))
    else:
        for r in csv.DictReader(text.splitlines()):
            rows.append(normalise(dict(r)))
    return rows


def run_one(tool, scene, h, level, contact, zeta, fhz, t0, t1, fmax=0.0):
    order, refine, scale, _ = parse_level(level)
    cmd = [tool, scene, "--h", f"{h:g}", "--order", str(order), "--refine", str(refine), "--scale",
           f"{scale:g}", "--contact", contact, "--zeta", f"{zeta:g}", "--fhz", f"{fhz:g}", "--from",
           f"{t0:g}", "--to", f"{t1:g}"]
    if fmax > 0:
        cmd += ["--fmax", f"{fmax:g}"]
    print("# " + " ".join(cmd), file=sys.stderr, flush=True)
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    p = subprocess.run(["nice"] + cmd, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: exit {p.returncode}: {p.stderr.strip()}")
    return normalise(json.loads(p.stdout))


def f(v):
    return float(v)


def fmt(v, nd=4):
    if v is None:
        return "n/a"
    if isinstance(v, str):
        return v
    if v != 0 and (abs(v) >= 1e5 or abs(v) < 1e-3):
        return f"{v:.3e}"
    return f"{v:.{nd}f}" if abs(v) < 100 else f"{v:.1f}"


# ---------------------------------------------------------------- tables

def tables(rows, scene, hs, levels, contact, zetas, t0, t1, static_mj):
    out = []
    sel = [r for r in rows if r["scene"] == scene and f"{f(r['from']):g}" == f"{t0:g}"
           and f"{f(r['to']):g}" == f"{t1:g}"]
    out.append(f"\n#### {scene}: every run (window {t0 * 1e3:g}-{t1 * 1e3:g} ms, whole mesh cycles)\n")
    hdr = ["contact", "damping", "mesh", "unknowns", "h (s)", "cycles", "DTE rms (um)", "mean TE (um)",
           "peak force (N)", "mean force (N)", "speed ratio", "balance / scale", "max penetration (um)",
           "peak / mean force", "max strain (mJ)" + (f" / static {static_mj:g}" if static_mj else ""),
           "CPU s per sim. s"]
    out.append("| " + " | ".join(hdr) + " |")
    out.append("|" + "---|" * len(hdr))
    for r in sorted(sel, key=lambda r: (r["contact"], f(r["zeta"]), -f(r["size"]), -f(r["h"]))):
        sm = f(r["strain_max_mj"])
        out.append("| " + " | ".join([
            r["contact"], f"{f(r['zeta']) * 100:g} %" if f(r["zeta"]) else "none", r["level"],
            str(r["unknowns"]), f"{f(r['h']):g}", str(r["cycles"]), f"{f(r['dte_rms_um']):.4f}",
            f"{f(r['mean_te_um']):.4f}", f"{f(r['peak_force_n']):.1f}", f"{f(r['mean_force_n']):.2f}",
            f"{f(r['ratio']):.6f}", f"{f(r['balance_rel']):.1e}", f"{f(r['pen_max_um']):.4f}",
            f"{f(r['force_peak_over_mean']):.2f}",
            f"{sm:.2f}" + (f" ({sm / static_mj:.1f}x)" if static_mj else ""), f"{f(r['cpu_per_sim_s']):.0f}"]) + " |")
    per = [r for r in sel if r.get("mesh_dte_rms_um")]
    if per:
        names = []
        for r in per:
            for kv in r["mesh_dte_rms_um"].split(";"):
                if kv.split("=")[0] not in names:
                    names.append(kv.split("=")[0])
        out.append(f"\n#### {scene}: DTE rms of every mesh (um; runs that report it)\n")
        hdr = ["contact", "damping", "mesh", "h (s)"] + names
        out.append("| " + " | ".join(hdr) + " |")
        out.append("|" + "---|" * len(hdr))
        for r in sorted(per, key=lambda r: (r["contact"], f(r["zeta"]), -f(r["size"]), -f(r["h"]))):
            v = dict(kv.split("=") for kv in r["mesh_dte_rms_um"].split(";"))
            out.append("| " + " | ".join([r["contact"], f"{f(r['zeta']) * 100:g} %" if f(r["zeta"]) else "none",
                                          r["level"], f"{f(r['h']):g}"] +
                                         [f"{float(v[n]):.4f}" if n in v else "" for n in names]) + " |")
    verdicts = {}
    levels = [level_name(*parse_level(lv)[:3]) for lv in levels]  # o1s1 is o1r0
    finest_lv = levels[-1]
    finest_h = min(hs)
    for zeta in zetas:
        damp = f"{zeta * 100:g} % damping" if zeta else "undamped"
        sub = [r for r in sel if r["contact"] == contact and abs(f(r["zeta"]) - zeta) < 1e-12]

        def get(lv, h):
            m = [r for r in sub if r["level"] == lv and abs(f(r["h"]) - h) < 1e-12 * max(h, 1e-30) + 1e-15]
            return m[0] if m else None
        fams = {"h": [(h, get(finest_lv, h)) for h in sorted(hs, reverse=True)],
                "mesh": [(parse_level(lv)[3], get(lv, finest_h)) for lv in levels]}
        for name, pts in fams.items():
            pts = [(s, r) for s, r in pts if r is not None]
            if len(pts) < 2:
                continue
            if name == "h":
                what = "h = " + ", ".join(format(f(r["h"]), "g") for _, r in pts) + f" s at {finest_lv}"
            else:
                what = "mesh " + ", ".join(r["level"] for _, r in pts) + f" at h = {finest_h:g} s"
            out.append(f"\n#### {scene}, {contact}, {damp}: refinement of {name} ({what})\n")
            cols = ["quantity"] + [f"{'h ' + format(f(r['h']), 'g') if name == 'h' else r['level']}"
                                   for _, r in pts] + ["differences", "observed order",
                                                       "Richardson (finest three)", "two finest", "verdict"]
            out.append("| " + " | ".join(cols) + " |")
            out.append("|" + "---|" * len(cols))
            for q, label, bar in QUANTITIES:
                fam = family([(s, f(r[q])) for s, r in pts])
                ok = None
                if bar is not None and fam["rel_last"] is not None:
                    ok = fam["rel_last"] <= bar
                    verdicts[(zeta, name, q)] = ok
                nd = 6 if q == "ratio" else 4
                shrink = ""
                if len(fam["diffs"]) >= 2:
                    d1, d2 = fam["diffs"][-2:]
                    shrink = ("; differences shrink" if abs(d2) < abs(d1) else "; differences grow") + (
                        "" if fam["p"] is not None else (", change sign" if d1 * d2 < 0 else ""))
                verdict = "" if bar is None else f"{'meets' if ok else 'misses'} {bar * 100:g} %{shrink}"
                out.append("| " + " | ".join(
                    [label] + [fmt(v, nd) for v in fam["values"]] +
                    [", ".join(f"{d:+.{nd}g}" for d in fam["diffs"]),
                     ", ".join(fmt(o, 2) for o in fam["orders"]) if len(fam["orders"]) > 1 else fmt(fam["p"], 2),
                     fmt(fam["rich"], nd) + (f" +- {fam['unc']:.3g}" if fam["unc"] is not None else ""),
                     f"{fam['rel_last'] * 100:.2f} %" if fam["rel_last"] is not None else "n/a", verdict]) + " |")
        # the converged value and the cheapest setting within 2 % of it
        ref = {}
        for q in ("dte_rms_um", "mean_te_um"):
            fin = get(finest_lv, finest_h)
            if fin is None:
                continue
            v = f(fin[q])
            est = v
            for name, pts in fams.items():
                pts = [(s, r) for s, r in pts if r is not None]
                if len(pts) >= 3:
                    fam = family([(s, f(r[q])) for s, r in pts])
                    if fam["rich"] is not None:
                        est += fam["rich"] - v
            ref[q] = est
        if len(ref) == 2:
            ok = [r for r in sub if all(abs(f(r[q]) - ref[q]) <= 0.02 * abs(ref[q]) for q in ref)]
            conv = all(verdicts.get((zeta, n, q)) is True for n in fams for q in ref
                       if (zeta, n, q) in verdicts)
            line = (f"\nReference ({damp}; finest run plus the Richardson corrections of both "
                    f"families where they converge; "
                    f"{'the two finest of every family within 2 %' if conv else 'NOT converged: a family misses 2 %'}"
                    f"): DTE rms {ref['dte_rms_um']:.4f} um, mean TE {ref['mean_te_um']:.4f} um. ")
            if not conv:
                line += "No converged value, so no cheapest setting within 2 % of it."
            elif ok:
                c = min(ok, key=lambda r: f(r["cpu_per_sim_s"]))
                line += (f"Cheapest run within 2 % of both: {c['level']} at h = {f(c['h']):g} s, "
                         f"{f(c['cpu_per_sim_s']):.0f} CPU s per simulated s "
                         f"(DTE rms {f(c['dte_rms_um']):.4f}, mean TE {f(c['mean_te_um']):.4f} um).")
            else:
                line += "No run is within 2 % of both."
            out.append(line)
    return "\n".join(out) + "\n", verdicts


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="contact_drive")
    ap.add_argument("--tool", default="build/tests/bench/dyn_convergence_run")
    ap.add_argument("--hs", type=float, nargs="+", default=[2e-5, 1e-5, 5e-6])
    ap.add_argument("--levels", nargs="+", default=["o1r0", "o1r1", "o1r2"])
    ap.add_argument("--zeta", type=float, nargs="+", default=[0.02, 0.0])
    ap.add_argument("--fhz", type=float, default=9200.0)
    ap.add_argument("--from", dest="t0", type=float, default=0.035)
    ap.add_argument("--to", dest="t1", type=float, default=0.065)
    ap.add_argument("--contact", default="closure_energy")
    ap.add_argument("--extra", nargs="*", default=[],
                    help="comparison runs CONTACT:LEVEL:H (at every damping ratio), e.g. seed:o1r0:1e-5")
    ap.add_argument("--static-mj", type=float, default=None,
                    help="static strain energy of the scene at its load (mJ), for the locking column")
    ap.add_argument("--reuse")
    ap.add_argument("--out-csv")
    ap.add_argument("--out-md")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-run", action="store_true", help="tables from --reuse only; run nothing")
    ap.add_argument("--fmax", type=float, default=0.0,
                    help="reduced elastic bodies with the modes up to FMAX Hz (0: full FE); the tables "
                         "use the runs of this FMAX only")
    a = ap.parse_args()
    if a.quick:
        a.hs, a.levels, a.zeta, a.t0, a.t1, a.extra = [4e-5, 2e-5], ["o1r0"], [0.02], 0.016, 0.03, []
    for lv in a.levels:
        parse_level(lv)
    rows = load_rows(a.reuse)
    others = [r for r in rows if fmax_of(r) != a.fmax]  # kept in --out-csv, not in the tables
    rows = [r for r in rows if fmax_of(r) == a.fmax]
    have = {key_of(r) for r in rows}
    todo = []
    for zeta in a.zeta:
        for h in a.hs:
            todo.append((a.contact, a.levels[-1], h, zeta))
        for lv in a.levels[:-1]:
            todo.append((a.contact, lv, min(a.hs), zeta))
        for e in a.extra:
            c, lv, h = e.split(":")
            todo.append((c, lv, float(h), zeta))
    new = []
    for c, lv, h, zeta in todo:
        o, rf, sc, _ = parse_level(lv)
        k = (a.scene, c, f"{zeta:g}", level_name(o, rf, sc), f"{h:g}", f"{a.t0:g}", f"{a.t1:g}", f"{a.fmax:g}")
        if k in have or a.no_run:
            continue
        r = run_one(a.tool, a.scene, h, lv, c, zeta, a.fhz, a.t0, a.t1, a.fmax)
        rows.append(r)
        new.append(r)
        have.add(k)
        if a.out_csv:
            with open(a.out_csv, "w", newline="") as fo:
                w = csv.DictWriter(fo, fieldnames=FIELDS)
                w.writeheader()
                w.writerows(others + rows)
    if a.out_csv and not new:
        with open(a.out_csv, "w", newline="") as fo:
            w = csv.DictWriter(fo, fieldnames=FIELDS)
            w.writeheader()
            w.writerows(others + rows)
    text, verdicts = tables(rows, a.scene, a.hs, a.levels, a.contact, a.zeta, a.t0, a.t1, a.static_mj)
    if a.out_md:
        with open(a.out_md, "w") as fo:
            fo.write(text)
    print(text)
    if a.quick:
        # the tool works end to end: every run finite, energy at round-off
        bad = [r for r in rows if not all(math.isfinite(f(r[q])) for q, _, _ in QUANTITIES)
               or f(r["balance_rel"]) > 1e-9 or int(r["cycles"]) < 1]
        if bad or len([r for r in rows if r["scene"] == a.scene]) < 2:
            print("quick grid: a run is missing, not finite or off balance", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
