#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim's quasi-static mesh stiffness and static TE against the second
stored CalculiX reference (tests/reference/, README.md there, "Second
pair"): the steel 20/30 pair with the pinion profile-shifted by x1 = +0.3 at
the tight-mesh centre distance (working pressure angle 21.72 deg), module
2.5 mm, face 10 mm, plane strain, 200 N/mm.

The reference code is never run here: the test reads
tests/reference/stiffness_20s_30/reference.csv (Richardson limit per roll
position) and runs gearsim-stiffness on the pair's scene.json at the same
positions through tests/reference/compare.py, with linear and with
quadratic elements on the scene's mesh density (refine 0), and prints the
per-position errors.

Asserted (bars are named constants, measured values in the comments; each
can fail):
* the stored reference is sane: at least 10 positions j/N over one mesh
  cycle, its finest level within REF_EST_BAR of its limit everywhere, the
  spur-mesh shape (stiffest position at least REF_SHAPE_RATIO times the
  softest), and the shift visible: the largest TE over the cycle (single
  contact, the thicker shifted pinion tooth) below the unshifted pair's
  (stiffness_30_20) by more than REF_SHIFT_MIN;
* order 1, refine 0 (the linear default counts, mesh {"order": 1}): |k
  error| and |TE error| below BAR_K_O1 / BAR_TE_O1 at every position;
* order 2, refine 0 (the default mesh): |k error| below BAR_K_O2 at every position, the cycle
  mean within BAR_CYCLE_O2, and closer to the reference than order 1 in
  the largest error and in the mean |error| (the quadratic element is the
  better one on this pair too);
* the default mesh with the near-field correction (the default): k and TE
  within BAR_K_NF / BAR_TE_NF per position, the cycle mean within
  BAR_CYCLE_NF (issue 14's 1 %), the single-contact mean within
  BAR_SINGLE_NF.
  BAR_K_NF / BAR_TE_NF are issue 14's 2 % per position (TARGET_POS), met
  since the fourth revision of the correction (docs/validation/calculix.md).
"""
import os
import sys

SRC = os.environ.get("GEARSIM_SOURCE_ROOT",
                     os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(SRC, "build"))
sys.path.insert(0, os.path.join(SRC, "tests", "reference"))
import compare  # noqa: E402

PAIR = os.path.join(SRC, "tests", "reference", "stiffness_20s_30")
UNSHIFTED = os.path.join(SRC, "tests", "reference", "stiffness_30_20")

# Bars: what holds today; measured when written in the comments.
REF_MIN_POSITIONS = 10
REF_EST_BAR = 0.002       # finest level within 0.2% of its limit (max 0.044%)
REF_SHAPE_RATIO = 1.25    # k max / k min of the reference (1.529)
REF_SHIFT_MIN = 0.02      # 1 - max TE / unshifted max TE (3.44%)
BAR_K_O1 = 0.30           # |k / k_ref - 1| per position, order 1 refine 0 (25.0%)
BAR_TE_O1 = 0.27          # |TE / TE_ref - 1| per position, order 1 refine 0 (22.5%)
BAR_K_O2 = 0.13           # |k error| per position, order 2 refine 0 (default mesh, parabolic-edge gap 11.45%; chord gap 13.2%)
BAR_CYCLE_O2 = 0.085      # |cycle-mean k error|, order 2 refine 0 (+6.9%; chord gap +7.9%)
# The default mesh with the near-field correction as revised in issue 14,
# fourth revision (docs/validation/calculix.md; in brackets the third revision's figure and the previous ones'):
TARGET_POS = 0.02         # issue 14: k and TE within 2 % per position
BAR_K_NF = TARGET_POS     # |k error| per position (1.04%; 4.45%, at the corner 0.083; 3.74%; 7.1%)
BAR_TE_NF = TARGET_POS    # |TE error| per position (1.03%; 4.65%; 3.89%; 7.6%)
BAR_CYCLE_NF = 0.01       # |cycle-mean k error|: issue 14's 1 % (+0.71%; +0.39%; +0.60%; +0.7%)
BAR_SINGLE_NF = 0.01      # |single-contact-mean k error|: issue 14's 1 % (+0.64%; +0.64%; +1.32%; +2.3%)

failures = []


def check(cond, what):
    print("%s: %s" % ("ok" if cond else "FAIL", what))
    if not cond:
        failures.append(what)


def mean_abs(res):
    return sum(abs(x["err_k"]) for x in res["rows"]) / len(res["rows"])


def run(tool, order):
    """gearsim at the given element order and its default counts, refine 0,
    against the reference."""
    res = compare.compare(PAIR, tool, refine=0, mesh={"order": order}, extra=["--no-nearfield"])
    print("order %d:" % order)
    compare.print_result(res)
    return res


def main():
    tool, ref = compare.open_checked(PAIR, BUILD, REF_MIN_POSITIONS, REF_EST_BAR,
                                     REF_SHAPE_RATIO, check)
    base = compare.load_reference(UNSHIFTED)
    te_s = max(r["te_um"] for r in ref)
    te_u = max(r["te_um"] for r in base)
    check(1 - te_s / te_u > REF_SHIFT_MIN,
          "shifted pair's largest TE %.4f um below the unshifted pair's %.4f um by more "
          "than %.0f%% (%+.2f%%)" % (te_s, te_u, 100 * REF_SHIFT_MIN, 100 * (te_s / te_u - 1)))

    res1 = run(tool, 1)
    s1 = res1["summary"]
    check(s1["max_abs_err_k"] < BAR_K_O1, "order 1 refine 0: max |k error| %.2f%% < %.0f%%"
          % (100 * s1["max_abs_err_k"], 100 * BAR_K_O1))
    check(s1["max_abs_err_te"] < BAR_TE_O1, "order 1 refine 0: max |TE error| %.2f%% < %.0f%%"
          % (100 * s1["max_abs_err_te"], 100 * BAR_TE_O1))

    res2 = run(tool, 2)
    s2 = res2["summary"]
    check(s2["max_abs_err_k"] < BAR_K_O2, "order 2 refine 0: max |k error| %.2f%% < %.0f%%"
          % (100 * s2["max_abs_err_k"], 100 * BAR_K_O2))
    check(abs(s2["cycle_mean_err_k"]) < BAR_CYCLE_O2,
          "order 2 refine 0: |cycle-mean k error| %.2f%% < %.1f%%"
          % (100 * abs(s2["cycle_mean_err_k"]), 100 * BAR_CYCLE_O2))
    check(s2["max_abs_err_k"] < s1["max_abs_err_k"] and mean_abs(res2) < mean_abs(res1),
          "order 2 closer than order 1: max |k error| %.2f%% vs %.2f%%, mean |k error| "
          "%.2f%% vs %.2f%%" % (100 * s2["max_abs_err_k"], 100 * s1["max_abs_err_k"],
                                100 * mean_abs(res2), 100 * mean_abs(res1)))

    nf = compare.compare(PAIR, tool, refine=0)   # the correction: the default
    print("order 2 refine 0, near-field correction:")
    compare.print_result(nf)
    sn = nf["summary"]
    compare.check_max_errors(sn, BAR_K_NF, BAR_TE_NF, "near-field", check)
    check(abs(sn["cycle_mean_err_k"]) < BAR_CYCLE_NF,
          "near-field: |cycle-mean k error| %.2f%% < %.0f%%"
          % (100 * abs(sn["cycle_mean_err_k"]), 100 * BAR_CYCLE_NF))
    sm = sn["single_mean_err_k"]
    check(sm is not None and abs(sm) < BAR_SINGLE_NF,
          "near-field: |single-contact-mean k error| %s < %.1f%%"
          % ("n/a" if sm is None else "%.2f%%" % (100 * abs(sm)), 100 * BAR_SINGLE_NF))
    print("issue-14 target (k, TE within %.0f%% per position): %s"
          % (100 * TARGET_POS, "met" if max(sn["max_abs_err_k"], sn["max_abs_err_te"])
             < TARGET_POS else "NOT met"))  # asserted by check_max_errors above

    print("%d failed" % len(failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
