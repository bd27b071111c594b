#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The `fine` setting of the quasi-static analysis (gearsim-stiffness --fine:
the teeth in contact meshed three levels finer than the rest, docs/explanation/geometry.md
"Local refinement") against the stored CalculiX reference of the steel 20/30
pair (tests/reference/stiffness_30_20; the reference code is never run here),
at all 12 reference positions, transitions included (about 10 s CPU).
GEARSIM_LONG=1 adds the shifted pair (tests/reference/stiffness_20s_30).

Asserted (bars measured when written, in the comments; each can fail):
* k and TE within BAR_FINE of the reference's Richardson limit at every
  position (issue 14's 1 %), the cycle and single-contact means within
  BAR_FINE_MEAN;
* the fine teeth follow the contact: over two mesh cycles (--cycles 2,
  5 fine teeth) k at rolls 0 and 1, and at 0.5 and 1.5 (the same contact,
  one tooth on) agree within BAR_PERIODIC;
* the contact window gives the all-rows solution within BAR_WINDOW, with
  fewer contact dofs;
* the setting is local: fewer than FRACTION_OF_R2 of the unknowns of the
  uniform refine 2 of the default counts (606 304), the cheapest uniform
  level near this accuracy (1.8 % off at the transitions,
  docs/performance/index.md).
"""
import os
import sys

SRC = os.environ.get("GEARSIM_SOURCE_ROOT",
                     os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(SRC, "build"))
sys.path.insert(0, os.path.join(SRC, "tests", "reference"))
import compare  # noqa: E402

PAIRS = ["stiffness_30_20"] + (["stiffness_20s_30"] if os.environ.get("GEARSIM_LONG") == "1" else [])
BAR_FINE = 0.01        # |k error|, |TE error| per position (30/20: 0.90%, 0.89%; 20s/30: 0.52%;
                       # with the near-field default 30/20: 0.93%, 0.94%)
BAR_FINE_MEAN = 0.005  # |cycle mean|, |single-contact mean| k error (+0.24%, +0.12%; +0.20%, +0.08%;
                       # near-field default 30/20: +0.04%, +0.12%)
UNKNOWNS_R2 = 606304   # uniform order 2 refine 2 of the default counts, 20/30 pair
FRACTION_OF_R2 = 0.3   # the fine setting: 144 832 unknowns (0.24)
BAR_WINDOW = 1e-8      # |k windowed / k all rows - 1| (8e-11)
BAR_PERIODIC = 0.001   # |k(roll + 1) / k(roll) - 1| over two cycles (0.001%; 0.64% with 4 teeth)

check, failures = compare.checker()


def main():
    for name in PAIRS:
        pair = os.path.join(SRC, "tests", "reference", name)
        tool, ref = compare.open_checked(pair, BUILD, 10, 0.01, 1.25, check)
        res = compare.compare(pair, tool, extra=["--fine"])   # the near-field default on
        print("%s, gearsim-stiffness --fine:" % name)
        compare.print_result(res)
        s = res["summary"]
        check(s["max_abs_err_k"] < BAR_FINE, "%s fine: max |k error| %.2f%% < %.0f%%"
              % (name, 100 * s["max_abs_err_k"], 100 * BAR_FINE))
        check(s["max_abs_err_te"] < BAR_FINE, "%s fine: max |TE error| %.2f%% < %.0f%%"
              % (name, 100 * s["max_abs_err_te"], 100 * BAR_FINE))
        sm = s["single_mean_err_k"]
        check(abs(s["cycle_mean_err_k"]) < BAR_FINE_MEAN and sm is not None
              and abs(sm) < BAR_FINE_MEAN,
              "%s fine: cycle mean %+.2f%%, single-contact mean %s within %.1f%%"
              % (name, 100 * s["cycle_mean_err_k"], "%+.2f%%" % (100 * sm) if sm is not None
                 else "n/a", 100 * BAR_FINE_MEAN))
        unknowns = 2 * sum(s["nodes"])
        if name == "stiffness_30_20":
            check(unknowns < FRACTION_OF_R2 * UNKNOWNS_R2,
                  "fine setting: %d unknowns < %.1f x %d (uniform refine 2)"
                  % (unknowns, FRACTION_OF_R2, UNKNOWNS_R2))
    # two cycles: the loaded teeth one pitch on are as finely meshed
    import json
    import subprocess
    scene = os.path.join(SRC, "tests", "reference", "stiffness_30_20", "scene.json")
    out = subprocess.run([tool, scene, "--fine", "--cycles", "2", "--positions", "4",
                          "--no-tangent", "--json"], capture_output=True, text=True)
    check(out.returncode == 0, "gearsim-stiffness --fine --cycles 2 runs (%s)" % out.stderr.strip())
    if out.returncode == 0:
        k = [p["k"] for p in json.loads(out.stdout)["points"]]
        for a, b in ((0, 2), (1, 3)):
            check(abs(k[b] / k[a] - 1) < BAR_PERIODIC,
                  "two cycles: k(roll %.1f) %.4f vs k(roll %.1f) %.4f within %.1f%%"
                  % (0.5 * a, k[a], 0.5 * b, k[b], 100 * BAR_PERIODIC))
    # the contact window: the same solution as with every row, fewer contact dofs
    alls = subprocess.run([tool, scene, "--fine", "--cycles", "2", "--positions", "4",
                           "--no-tangent", "--json", "--all-rows"], capture_output=True, text=True)
    check(alls.returncode == 0, "gearsim-stiffness --fine --all-rows runs (%s)" % alls.stderr.strip())
    if out.returncode == 0 and alls.returncode == 0:
        wj, aj = json.loads(out.stdout), json.loads(alls.stdout)
        dk = max(abs(p["k"] / q["k"] - 1) for p, q in zip(wj["points"], aj["points"]))
        check(dk < BAR_WINDOW, "contact window: k within %.0e of all rows (%.1e)" % (BAR_WINDOW, dk))
        check(wj["columns"] < aj["columns"], "contact window: %d contact dofs < %d with all rows"
              % (wj["columns"], aj["columns"]))
    if failures:
        print("%d check(s) failed" % len(failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
