#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: gearsim's quasi-static stiffness analysis against the general
FE reference code (gmsh + CalculiX ccx, tests/reference/), side by side in
one run, on the same machine and load.

* CalculiX: one roll position of the pair at its 1%-accurate mesh
  (h = 0.05 mm, tests/reference/README.md), meshed and solved here exactly
  as run_pair.py does (gearref.build_position + run_ccx, one thread);
* gearsim: `gearsim-stiffness PAIR/scene.json` over the reference's 12 roll
  positions at the given setting (--order, --refine, any further
  gearsim-stiffness options after `--`), through tests/reference/compare.py.

Printed: each code's error against the stored Richardson limit
(PAIR/reference.csv; CalculiX at its position, gearsim at every position),
each code's CPU and wall time per roll position, and the ratios
(reference / gearsim) per position; "equal accuracy" says whether both are
within 1% of the limit. CPU time is the comparable figure on a shared
machine (wall time is shown too). Nothing is asserted: a benchmark reports.
Exits 77 (skipped) if gmsh or ccx is missing.

    meson test -C build --benchmark --suite bench reference
    tests/bench/bench_reference.py [--pair stiffness_30_20] [--roll 1] [--h 0.05]
        [--order 2] [--refine 1] [--tool PATH] [-- extra gearsim-stiffness options]

The environment variable GEARSIM_BENCH_REFERENCE_ARGS (split on blanks) is
prepended to the command line, so a setting can be chosen under meson test.
"""
import argparse
import json
import math
import os
import resource
import shlex
import shutil
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.environ.get("GEARSIM_SOURCE_ROOT", os.path.join(HERE, "..", ".."))
REFDIR = os.path.join(SRC, "tests", "reference")
sys.path.insert(0, REFDIR)

import compare  # noqa: E402
import gearref  # noqa: E402
import run_pair  # noqa: E402

EQUAL_ACCURACY = 0.01


def child_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_reference(pair_dir, j, positions, h, threads, keep):
    """Mesh and solve roll j/positions at h with gmsh + ccx, as run_pair.py
    does. Returns TE (um), k (N/(mm um)), nodes, CPU and wall seconds."""
    cfg = json.load(open(os.path.join(pair_dir, "pair.json")))
    g1, g2 = run_pair.make_gear(cfg["driver"]), run_pair.make_gear(cfg["driven"])
    face = cfg["face_width_mm"]
    torque = cfg.get("line_load_n_per_mm", 200.0) * face * g1.rb
    force = torque / g1.rb
    roll = j / positions
    th1 = roll * 2.0 * math.pi / g1.z
    th2 = cfg.get("driven_angle0_rad", 0.0) - th1 * g1.z / g2.z
    wd = tempfile.mkdtemp(prefix="bench_ref_")
    try:
        w0, c0 = time.monotonic(), child_cpu()
        info = gearref.build_position(wd, g1, g2, (cfg["centre_mm"], 0.0), th1, th2, h,
                                      e_mpa=cfg.get("E_mpa", 210000.0), nu=cfg.get("nu", 0.3),
                                      face=face, torque=torque, outline_mm=cfg.get("outline_mm"))
        w1, c1 = time.monotonic(), child_cpu()
        delta, _, _ = gearref.run_ccx(wd, threads)
        w2, c2 = time.monotonic(), child_cpu()
    finally:
        if keep:
            print("kept", wd)
        else:
            shutil.rmtree(wd, ignore_errors=True)
    te_um = g1.rb * delta * 1e3
    return dict(roll=roll, te_um=te_um, k=force / te_um / face, nodes=info["nodes"],
                mesh_cpu=c1 - c0, mesh_wall=w1 - w0, ccx_cpu=c2 - c1, ccx_wall=w2 - w1,
                cpu=c2 - c0, wall=w2 - w0)


def main():
    argv = shlex.split(os.environ.get("GEARSIM_BENCH_REFERENCE_ARGS", "")) + sys.argv[1:]
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pair", default="stiffness_30_20")
    ap.add_argument("--roll", type=int, default=1,
                    help="reference position index j (roll j/N) for CalculiX (default 1)")
    ap.add_argument("--h", type=float, default=0.05, help="CalculiX mesh level, mm")
    ap.add_argument("--order", type=int, help="gearsim element order (default: the scene's)")
    ap.add_argument("--refine", type=int, help="gearsim refine level (default: the scene's mesh)")
    ap.add_argument("--threads", type=int, default=1, help="ccx threads (1: CPU = one core)")
    ap.add_argument("--build", default=os.environ.get("GEARSIM_BUILD_ROOT",
                                                      os.path.join(SRC, "build")))
    ap.add_argument("--tool")
    ap.add_argument("--keep", action="store_true", help="keep the CalculiX work directory")
    ap.add_argument("extra", nargs="*", help="further gearsim-stiffness options (after --)")
    a = ap.parse_args(argv)

    missing = [p for p in ("gmsh", "ccx") if shutil.which(p) is None]
    if missing:
        print("SKIP: %s not installed (apt-get install gmsh calculix-ccx)" % " and ".join(missing))
        return 77
    pair_dir = a.pair if os.path.isdir(a.pair) else os.path.join(REFDIR, a.pair)
    if not os.path.exists(os.path.join(pair_dir, "reference.csv")):
        print("SKIP: no stored reference %s/reference.csv" % pair_dir)
        return 77
    tool = a.tool or compare.find_tool(a.build)
    ref = compare.load_reference(pair_dir)
    n = len(ref)
    if not 0 <= a.roll < n:
        raise SystemExit("--roll must be in 0..%d" % (n - 1))
    extra = list(a.extra)
    if a.order is not None:
        extra = ["--order", str(a.order)] + extra
    setting = " ".join((["--refine %d" % a.refine] if a.refine is not None else []) + extra) \
        or "the scene's default mesh"

    # gearsim first (short), then the reference position
    w0, c0 = time.monotonic(), child_cpu()
    res = compare.compare(pair_dir, tool, a.refine, extra)
    g_wall, g_cpu = time.monotonic() - w0, child_cpu() - c0
    s = res["summary"]
    print("pair %s, %d roll positions; gearsim setting: %s" % (os.path.basename(pair_dir), n,
                                                              setting))
    compare.print_result(res)
    print()

    r = run_reference(pair_dir, a.roll, n, a.h, a.threads, a.keep)
    rr = ref[a.roll]
    err_k = r["k"] / rr["k"] - 1.0
    err_te = r["te_um"] / rr["te_um"] - 1.0
    print("CalculiX roll %.4f at h = %g mm: %d nodes (%d unknowns), TE %.4f um (limit %.4f, "
          "%+.3f%%), k %.4f N/(mm um) (limit %.4f, %+.3f%%)"
          % (r["roll"], a.h, r["nodes"], 2 * r["nodes"], r["te_um"], rr["te_um"], 100 * err_te,
             r["k"], rr["k"], 100 * err_k))
    print("CalculiX per position: CPU %.2f s (gmsh %.2f, ccx %.2f), wall %.2f s"
          % (r["cpu"], r["mesh_cpu"], r["ccx_cpu"], r["wall"]))
    g_cpu_pos, g_wall_pos = g_cpu / n, g_wall / n
    print("gearsim per position:  CPU %.4f s, wall %.4f s (%d positions; the tool's own "
          "figure %.4f s; unknowns %s)"
          % (g_cpu_pos, g_wall_pos, n, s["seconds"] / n,
             2 * sum(s["nodes"]) if isinstance(s["nodes"], list) else s["nodes"]))
    g_err = max(s["max_abs_err_k"], s["max_abs_err_te"])
    c_err = max(abs(err_k), abs(err_te))
    equal = g_err < EQUAL_ACCURACY and c_err < EQUAL_ACCURACY
    print("errors against the limit: gearsim max |k|,|TE| %.3f%% over %d positions; "
          "CalculiX %.3f%% at its position" % (100 * g_err, n, 100 * c_err))
    print("time per position, reference / gearsim: CPU ratio %.1f, wall ratio %.1f"
          % (r["cpu"] / g_cpu_pos if g_cpu_pos > 0 else float("inf"),
             r["wall"] / g_wall_pos if g_wall_pos > 0 else float("inf")))
    print("equal accuracy (both within %.0f%% of the limit): %s"
          % (100 * EQUAL_ACCURACY, "yes" if equal else "no"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
