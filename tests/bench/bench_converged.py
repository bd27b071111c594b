#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: the cost of a converged answer of the 30/20 pair (contact_drive).

Reduced elastic gears in contact (closure_energy, the study's 2 % material
damping at 9.2 kHz) over a 0.3 s run from rest, at several time steps, one
after the other in one run, each against the converged reference: the
dynamic transmission error (rms of the kinematic TE about its mean) and the
mean TE over the whole mesh cycles of the second half (0.15-0.3 s). Cost is
the CPU seconds (user + system) of the whole process per simulated second,
ALL IN: start-up, scene, meshing, factorisation, modes, the reduced bodies'
residual columns and the steps, one rank. The process's own split (system
construction, residual columns, steps) is printed beside it.

The reference is the converged setting of the dynamic convergence study
(docs/validation/data.md): reduced bodies on the mesh o2s3 at h 1.5e-5 s over
0.035-1 s, the row of docs/data/dyn_convergence_pair_levels.csv (136 mesh
cycles; o2s3 and o2r2 agree to 0.05 % in DTE); --reference run measures it
again over this benchmark's window instead (about ten CPU minutes).

    tests/bench/bench_converged.py [--tool build/tests/bench/dyn_convergence_run]
        [--h 2e-5,4e-5] [--rounds 1] [--reference csv|run]

Bars: DTE rms and mean TE within 2 % of the
reference at <= 5 CPU s per simulated second. Prints a Markdown table; exits
0 whatever the figures (a benchmark, not a test)."""
import argparse
import csv
import json
import os
import resource
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
LEVELS = os.path.join(ROOT, "docs", "data", "dyn_convergence_pair_levels.csv")
COMMON = ["--zeta", "0.02", "--fhz", "9200", "--from", "0.15", "--to", "0.3"]
SIM_S = 0.3


def child_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(tool, args):
    c0 = child_cpu()
    p = subprocess.run([tool, "contact_drive"] + args, capture_output=True, text=True)
    cpu = child_cpu() - c0
    if p.returncode != 0:
        sys.stderr.write(p.stderr)
        return None, cpu
    return json.loads(p.stdout.strip().splitlines()[-1]), cpu


def reference_from_csv():
    with open(LEVELS) as f:
        for r in csv.DictReader(f):
            if float(r["scale"]) == 3 and float(r["h"]) == 1.5e-5 and float(r["to"]) == 1:
                return float(r["dte_rms_um"]), float(r["mean_te_um"]), "o2s3, h 1.5e-5 s, 0.035-1 s (CSV)"
    raise SystemExit("reference row (scale 3, h 1.5e-5, to 1) not in " + LEVELS)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tool", default=os.path.join(ROOT, "build", "tests", "bench", "dyn_convergence_run"))
    ap.add_argument("--h", default="2e-5,4e-5", help="time steps, comma-separated")
    ap.add_argument("--rounds", type=int, default=1, help="the time steps this many times, in turn")
    ap.add_argument("--reference", choices=["csv", "run"], default="csv")
    a = ap.parse_args()
    if a.reference == "run":
        ref, _ = run(a.tool, ["--h", "1e-5", "--scale", "3", "--fmax", "30000"] + COMMON)
        if ref is None:
            raise SystemExit("reference run failed")
        rdte, rmean, rname = ref["dte_rms_um"], ref["mean_te_um"], "o2s3, h 1e-5 s, 0.15-0.3 s (run)"
    else:
        rdte, rmean, rname = reference_from_csv()
    print("# bench_converged: contact_drive, reduced bodies, 0.3 s runs, one rank, all in")
    print(f"reference: {rname}: DTE rms {rdte:.6f} um, mean TE {rmean:.6f} um\n")
    print("| h (s) | f_max (Hz) | CPU s per sim. s (all in) | construction (s) | residual columns (s) | "
          "steps (s) | DTE rms (um) | DTE err | mean TE (um) | mean TE err | met |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    hs = [float(x) for x in a.h.split(",") if x]
    for _ in range(a.rounds):
        for h in hs:
            fmax = 0.3 / h  # the fidelity ladder's rule (15 kHz at 2e-5 s)
            r, cpu = run(a.tool, ["--h", repr(h), "--fmax", "%.6g" % fmax] + COMMON)
            if r is None:
                print(f"| {h:g} | {fmax:.6g} | failed | | | | | | | | |")
                continue
            ed = r["dte_rms_um"] / rdte - 1
            em = r["mean_te_um"] / rmean - 1
            cost = cpu / SIM_S
            met = abs(ed) <= 0.02 and abs(em) <= 0.02 and cost <= 5.0
            steps = r["cpu_s"] - r["setup_cpu_s"] - r["column_cpu_s"]
            print(f"| {h:g} | {fmax:.6g} | {cost:.2f} | {r['setup_cpu_s']:.2f} | {r['column_cpu_s']:.2f} | "
                  f"{steps:.2f} | {r['dte_rms_um']:.6f} | {100 * ed:+.2f} % | {r['mean_te_um']:.6f} | "
                  f"{100 * em:+.3f} % | {'yes' if met else 'no'} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
