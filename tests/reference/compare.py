#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Compare gearsim's quasi-static mesh stiffness and static TE with the stored
CalculiX reference (tests/reference/README.md).

    compare.py [--pair stiffness_30_20] [--refine R ...] [--build DIR]
               [--tool PATH] [--json] [--mesh JSON] [-- extra gearsim-stiffness options]

Runs `gearsim-stiffness PAIR/scene.json --json --positions N --no-tangent`
(N = the reference's number of positions; without --refine the scene's own
mesh density, i.e. gearsim's default mesh, else each --refine level; the
tool's default contact, the near-field correction on: `-- --no-nearfield`
for the plain FE) and
prints per roll position gearsim's TE and k, the reference's, and the
relative errors (gearsim / reference - 1), then the summary: largest |error|,
mean error, the cycle-mean and single-contact-mean stiffness errors (single
contact: positions where gearsim reports one loaded tooth pair).  --json
prints the same as one JSON document.  Nothing is asserted here; the
validation test tests/validation/test_stiffness_reference.py does that.
"""
import argparse
import csv
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def load_reference(pair_dir):
    rows = list(csv.DictReader(open(os.path.join(pair_dir, "reference.csv"))))
    return [dict(roll=float(r["roll"]), te_um=float(r["te_um"]),
                 k=float(r["k_n_per_mm_um"]), est=float(r["finest_rel_err"])) for r in rows]


def reference_checks(ref, min_positions, est_bar, shape_ratio):
    """The sanity conditions of a stored reference, as (holds, description)
    pairs for a test to assert: at least min_positions rolls j/N, the finest
    level within est_bar of its limit everywhere, k max/min above
    shape_ratio (double against single contact)."""
    n = len(ref)
    est = max(r["est"] for r in ref)
    ratio = max(r["k"] for r in ref) / min(r["k"] for r in ref)
    return [(n >= min_positions, "reference has >= %d positions (%d)" % (min_positions, n)),
            (all(abs(r["roll"] - j / n) < 1e-6 for j, r in enumerate(ref)),
             "reference rolls are j/%d" % n),
            (est < est_bar, "reference finest level within %.2f%% of its limit (%.3f%%)"
             % (100 * est_bar, 100 * est)),
            (ratio > shape_ratio, "reference k max/min > %.2f (%.3f)" % (shape_ratio, ratio))]


def checker():
    """(check, failures) for a validation test: check(cond, what) prints
    ok/FAIL and what, and collects the failed ones in the list failures."""
    failures = []

    def check(cond, what):
        print("%s: %s" % ("ok" if cond else "FAIL", what))
        if not cond:
            failures.append(what)
    return check, failures


def open_checked(pair_dir, build, min_positions, est_bar, shape_ratio, check):
    """The tool and the reference of a pair, the reference's own checks passed
    to check(cond, what) (the validation tests' common start)."""
    tool = find_tool(build)
    ref = load_reference(pair_dir)
    print("reference: %d positions, k %.3f .. %.3f N/(mm um)" % (
        len(ref), min(r["k"] for r in ref), max(r["k"] for r in ref)))
    for cond, what in reference_checks(ref, min_positions, est_bar, shape_ratio):
        check(cond, what)
    return tool, ref


def check_max_errors(summ, bar_k, bar_te, label, check):
    """check(cond, what) that the largest |k error| and |TE error| of a
    compare() summary are below bar_k and bar_te (the validation tests'
    per-position bars)."""
    check(summ["max_abs_err_k"] < bar_k and summ["max_abs_err_te"] < bar_te,
          "%s: max |k error| %.2f%% < %.1f%%, max |TE error| %.2f%% < %.1f%%"
          % (label, 100 * summ["max_abs_err_k"], 100 * bar_k, 100 * summ["max_abs_err_te"],
             100 * bar_te))


def find_tool(build):
    for p in (os.path.join(build, "src", "tools", "gearsim-stiffness"),):
        if os.access(p, os.X_OK):
            return p
    raise SystemExit("gearsim-stiffness not found under %s (build first, or --tool)" % build)


def run_gearsim(tool, scene, positions, refine=None, extra=()):
    cmd = [tool, scene, "--json", "--positions", str(positions), "--no-tangent"]
    if refine is not None:
        cmd += ["--refine", str(refine)]
    cmd += list(extra)
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        raise RuntimeError("%s failed: %s" % (" ".join(cmd), r.stderr.strip()))
    return json.loads(r.stdout)


def compare(pair_dir, tool, refine=None, extra=(), mesh=None):
    """gearsim against the reference of pair_dir: dict with per-position rows
    and the summary figures (errors as fractions). mesh: a scene mesh object
    (e.g. {"order": 1}: the linear default) given to every gear of a copy of
    the scene."""
    ref = load_reference(pair_dir)
    n = len(ref)
    for j, r in enumerate(ref):
        if abs(r["roll"] - j / n) > 1e-6:
            raise RuntimeError("reference rolls are not j/%d (row %d: %g)" % (n, j, r["roll"]))
    scene = os.path.join(pair_dir, "scene.json")
    if mesh is not None:
        import tempfile
        sc = json.load(open(scene))
        for b in sc["bodies"]:
            b["mesh"] = dict(mesh)
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump(sc, f)
        try:
            g = run_gearsim(tool, f.name, n, refine, extra)
        finally:
            os.unlink(f.name)
    else:
        g = run_gearsim(tool, scene, n, refine, extra)
    rows = []
    for r, p in zip(ref, g["points"]):
        if abs(p["roll"] - r["roll"]) > 1e-5:
            raise RuntimeError("roll mismatch %g vs %g" % (p["roll"], r["roll"]))
        rows.append(dict(roll=r["roll"], pairs=p["pairs"], te_um=p["te_um"], ref_te_um=r["te_um"],
                         k=p["k"], ref_k=r["k"], err_k=p["k"] / r["k"] - 1.0,
                         err_te=p["te_um"] / r["te_um"] - 1.0, ref_est=r["est"]))
    single = [x for x in rows if x["pairs"] == 1]

    def mean(v):
        return sum(v) / len(v) if v else float("nan")

    summ = dict(refine=g["refine"], nodes=g["nodes"], seconds=g["seconds"], positions=n,
                cpu=g.get("cpu"),
                max_abs_err_k=max(abs(x["err_k"]) for x in rows),
                min_err_k=min(x["err_k"] for x in rows),
                max_err_k=max(x["err_k"] for x in rows),
                max_abs_err_te=max(abs(x["err_te"]) for x in rows),
                mean_err_k=mean([x["err_k"] for x in rows]),
                cycle_mean_err_k=mean([x["k"] for x in rows]) / mean([x["ref_k"] for x in rows]) - 1,
                single_mean_err_k=(mean([x["k"] for x in single]) /
                                   mean([x["ref_k"] for x in single]) - 1) if single else None,
                single_positions=len(single))
    return dict(rows=rows, summary=summ)


def print_result(res, out=sys.stdout):
    s = res["summary"]
    print("gearsim refine %s, nodes %s, %.2f s for %d positions" % (
        s["refine"], s["nodes"], s["seconds"], s["positions"]), file=out)
    print("%7s %5s %9s %9s %8s %9s %9s %8s %8s" % ("roll", "pairs", "TE um", "ref TE", "err TE%",
                                                 "k", "ref k", "err k%", "ref err%"), file=out)
    for x in res["rows"]:
        print("%7.4f %5d %9.4f %9.4f %8.2f %9.4f %9.4f %8.2f %8.3f" % (
            x["roll"], x["pairs"], x["te_um"], x["ref_te_um"], 100 * x["err_te"], x["k"],
            x["ref_k"], 100 * x["err_k"], 100 * x["ref_est"]), file=out)
    sm = s["single_mean_err_k"]
    print("k error: max |.| %.2f%% (min %+.2f%%, max %+.2f%%), mean %+.2f%%, cycle mean %+.2f%%, "
          "single-contact mean %s (%d positions); TE error max |.| %.2f%%" % (
              100 * s["max_abs_err_k"], 100 * s["min_err_k"], 100 * s["max_err_k"],
              100 * s["mean_err_k"], 100 * s["cycle_mean_err_k"],
              "%+.2f%%" % (100 * sm) if sm is not None else "n/a", s["single_positions"],
              100 * s["max_abs_err_te"]), file=out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pair", default="stiffness_30_20")
    ap.add_argument("--refine", type=int, nargs="*")
    ap.add_argument("--build", default=os.environ.get(
        "GEARSIM_BUILD_ROOT", os.path.join(HERE, "..", "..", "build")))
    ap.add_argument("--tool")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--mesh", help="a scene mesh object for every gear, as JSON "
                    "(e.g. '{\"fine_teeth\": 3, \"fine_refine\": 2}')")
    ap.add_argument("extra", nargs="*")
    a = ap.parse_args()
    tool = a.tool or find_tool(a.build)
    pair_dir = a.pair if os.path.isdir(a.pair) else os.path.join(HERE, a.pair)
    levels = a.refine if a.refine else [None]
    out = []
    for r in levels:
        res = compare(pair_dir, tool, r, a.extra, json.loads(a.mesh) if a.mesh else None)
        out.append(res)
        if not a.json:
            print_result(res)
            print()
    if a.json:
        print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
