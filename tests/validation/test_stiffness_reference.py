#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim's quasi-static mesh stiffness and static TE against the stored,
independent CalculiX reference (tests/reference/, README.md there): the steel
20/30 pair, module 2.5 mm, 20 deg, face 10 mm, plane strain, 200 N/mm.

The reference code is never run here: the test reads
tests/reference/stiffness_30_20/reference.csv (Richardson limit per roll
position) and runs gearsim-stiffness on tests/reference/stiffness_30_20/
scene.json at the same positions, on gearsim's default mesh (the scene's mesh
density: curved quadratic elements) and at refine 1, and on the linear
default mesh (mesh {"order": 1}), through tests/reference/compare.py, and
prints the per-position errors.

Asserted (bars are named constants; each can fail):
* the stored reference is sane: at least 10 positions j/N over one mesh
  cycle, its finest level within REF_EST_BAR of its limit at every position
  (0.01-0.04 % away from the transitions, ~0.5 % at the two transitions),
  and the shape of a spur mesh: the stiffest position at least
  REF_SHAPE_RATIO times the softest (double vs single contact);
* linear default mesh (order 1): |k error| and |TE error| below
  BAR_K_O1 / BAR_TE_O1 at every position, and the single-contact mean k
  too stiff (error > 0: the linear triangles are stiff) and within
  BAR_SINGLE_O1;
* default mesh (order 2, refine 0): per position |k error| within BAR_K_O2
  and |TE error| within BAR_TE_O2, the cycle mean too stiff by less than
  BAR_CYCLE_O2, the single-contact mean too stiff and closer than the
  linear mesh's (plain FE: --no-nearfield); with the near-field correction
  (the tool's default) k within
  BAR_K_O2_NF and TE within BAR_TE_O2_NF per position, the cycle mean
  within BAR_CYCLE_O2_NF (1 %) and closer than without it, the
  single-contact mean within BAR_SINGLE_O2_NF;
* refine 1: the single-contact mean error smaller than on the default mesh
  (gearsim converges towards the reference), |k error| below
  BAR_K_REFINE1; with the correction: k and TE within BAR_K_O2R1_NF per
  position, the cycle mean within BAR_MEAN_O2R1_NF and the single-contact
  mean within BAR_SINGLE_O2R1_NF.
With the correction, issue 14's targets on the default mesh (k and TE within
TARGET_POS = 2 % at every position, cycle and single-contact means within
TARGET_MEAN = 1 %) are met and asserted (BAR_K_O2_NF, BAR_TE_O2_NF are
TARGET_POS): docs/validation/calculix.md.
"""
import os
import sys

SRC = os.environ.get("GEARSIM_SOURCE_ROOT",
                     os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(SRC, "build"))
sys.path.insert(0, os.path.join(SRC, "tests", "reference"))
import compare  # noqa: E402

PAIR = os.path.join(SRC, "tests", "reference", "stiffness_30_20")

# Bars: what holds today; measured when written in the comments.
REF_MIN_POSITIONS = 10
REF_EST_BAR = 0.01         # finest level within 1% of its limit (max 0.53%, the transitions)
REF_SHAPE_RATIO = 1.25     # k max / k min of the reference over the cycle (1.52)
# Linear triangles at their default counts (mesh {"order": 1}, 11 224 unknowns):
BAR_K_O1 = 0.25            # |k / k_ref - 1| per position (20.7%)
BAR_TE_O1 = 0.25           # |TE / TE_ref - 1| per position (17.2%)
BAR_SINGLE_O1 = 0.25       # single-contact mean k error (> 0 asserted; +16.4%)
# The default mesh (order 2 {8, 4, 2, 3}, 38 060 unknowns), gaps to the
# parabolic edges (docs/explanation/contact.md "Quadratic edges"), and the near-field
# correction (--nearfield, docs/explanation/stiffness.md "Near-field correction");
# measured on the merged main, in brackets with the chord gap:
BAR_K_O2 = 0.115           # |k error| per position, plain FE (10.3%; 11.6%)
BAR_TE_O2 = 0.105          # |TE error| per position, plain FE (9.4%; 10.4%)
BAR_CYCLE_O2 = 0.08        # cycle-mean k error in (0, bar): too stiff (+6.8%; +5.9%)
# Issue 14's targets for the default mesh: k and TE within 2 % at every
# position, the cycle and single-contact means within 1 %.
# The correction is gearsim-stiffness's default: the plain FE runs pass this.
PLAIN = ["--no-nearfield"]
TARGET_POS = 0.02
TARGET_MEAN = 0.01
# The near-field correction as revised in issue 14, fourth revision (tip
# corners located on the line of action, the truncated-contact law there;
# docs/validation/calculix.md), in brackets
# the third revision's figure and the previous ones':
BAR_K_O2_NF = TARGET_POS   # |k error| per position, near-field (1.56%; 3.01%; 3.29%; 4.7%)
BAR_TE_O2_NF = TARGET_POS  # |TE error| per position, near-field (1.54%; 2.92%; 3.18%; 4.5%)
BAR_CYCLE_O2_NF = TARGET_MEAN   # |cycle-mean k error|, near-field (+0.56%; +0.77%; +0.36%; +0.78%)
BAR_SINGLE_O2_NF = TARGET_MEAN  # |single-contact-mean k error|, near-field (+0.91%; +0.91%; +1.14%; +2.28%)
BAR_K_REFINE1 = 0.05       # |k error| per position at refine 1, plain (4.0%; 4.5%; linear refine 1 was 10.7%)
BAR_K_O2R1_NF = 0.01       # |k error| and |TE error| per position, refine 1, near-field (0.75%, 0.75%; 1.99%, 1.95%; 2.11%, 2.07%; 3.3%, 3.2%)
BAR_MEAN_O2R1_NF = 0.01    # |cycle-mean| k error, same: issue 14's 1 % (+0.33%; +0.68%; +0.77%; +1.19%)
BAR_SINGLE_O2R1_NF = 0.01  # |single-contact-mean| k error, same: 1 % (+0.57%; +0.57%; +1.20%; +2.31%)

failures = []


def check(cond, what):
    print("%s: %s" % ("ok" if cond else "FAIL", what))
    if not cond:
        failures.append(what)


def main():
    tool, ref = compare.open_checked(PAIR, BUILD, REF_MIN_POSITIONS, REF_EST_BAR,
                                     REF_SHAPE_RATIO, check)

    lin = compare.compare(PAIR, tool, mesh={"order": 1}, extra=PLAIN)   # the linear default mesh
    print("linear default mesh (order 1):")
    compare.print_result(lin)
    sl = lin["summary"]
    check(sl["max_abs_err_k"] < BAR_K_O1, "order 1: max |k error| %.2f%% < %.0f%%"
          % (100 * sl["max_abs_err_k"], 100 * BAR_K_O1))
    check(sl["max_abs_err_te"] < BAR_TE_O1, "order 1: max |TE error| %.2f%% < %.0f%%"
          % (100 * sl["max_abs_err_te"], 100 * BAR_TE_O1))
    sml = sl["single_mean_err_k"]
    check(sml is not None and 0 < sml < BAR_SINGLE_O1,
          "order 1: single-contact mean k too stiff, by less than %.0f%% (%s)"
          % (100 * BAR_SINGLE_O1, "n/a" if sml is None else "%+.2f%%" % (100 * sml)))

    res0 = compare.compare(PAIR, tool, extra=PLAIN)   # the scene's (default) mesh density
    print("default mesh (order 2):")
    compare.print_result(res0)
    s0 = res0["summary"]
    check(s0["max_abs_err_k"] < BAR_K_O2, "default mesh: max |k error| %.2f%% < %.0f%%"
          % (100 * s0["max_abs_err_k"], 100 * BAR_K_O2))
    check(s0["max_abs_err_te"] < BAR_TE_O2, "default mesh: max |TE error| %.2f%% < %.0f%%"
          % (100 * s0["max_abs_err_te"], 100 * BAR_TE_O2))
    check(0 < s0["cycle_mean_err_k"] < BAR_CYCLE_O2,
          "default mesh: cycle-mean k too stiff, by less than %.0f%% (%+.2f%%)"
          % (100 * BAR_CYCLE_O2, 100 * s0["cycle_mean_err_k"]))
    sm0 = s0["single_mean_err_k"]
    check(sm0 is not None and sml is not None and 0 < sm0 < sml,
          "default mesh: single-contact mean k too stiff, and closer than the linear mesh's (%s vs %s)"
          % ("n/a" if sm0 is None else "%+.2f%%" % (100 * sm0),
             "n/a" if sml is None else "%+.2f%%" % (100 * sml)))

    res1 = compare.compare(PAIR, tool, refine=1, extra=PLAIN)
    compare.print_result(res1)
    s1 = res1["summary"]
    check(s1["max_abs_err_k"] < BAR_K_REFINE1, "refine 1: max |k error| %.2f%% < %.0f%%"
          % (100 * s1["max_abs_err_k"], 100 * BAR_K_REFINE1))
    sm1 = s1["single_mean_err_k"]
    check(sm0 is not None and sm1 is not None and abs(sm1) < abs(sm0),
          "refine 1: single-contact mean error smaller than on the default mesh (%s vs %s)"
          % ("n/a" if sm1 is None else "%+.2f%%" % (100 * sm1),
             "n/a" if sm0 is None else "%+.2f%%" % (100 * sm0)))

    # The near-field (Hertz) correction on the default mesh and at refine 1:
    # the tool's default (no option).
    n0 = compare.compare(PAIR, tool, refine=0)
    compare.print_result(n0)
    sn0 = n0["summary"]
    compare.check_max_errors(sn0, BAR_K_O2_NF, BAR_TE_O2_NF, "near-field", check)
    check(abs(sn0["cycle_mean_err_k"]) < min(BAR_CYCLE_O2_NF, abs(s0["cycle_mean_err_k"])),
          "near-field: |cycle-mean k error| %.2f%% < %.0f%% and below the plain FE's %.2f%%"
          % (100 * abs(sn0["cycle_mean_err_k"]), 100 * BAR_CYCLE_O2_NF,
             100 * abs(s0["cycle_mean_err_k"])))
    smn = sn0["single_mean_err_k"]
    check(smn is not None and abs(smn) < BAR_SINGLE_O2_NF,
          "near-field: |single-contact-mean k error| %s < %.1f%%"
          % ("n/a" if smn is None else "%.2f%%" % (100 * abs(smn)), 100 * BAR_SINGLE_O2_NF))
    met = (sn0["max_abs_err_k"] < TARGET_POS and sn0["max_abs_err_te"] < TARGET_POS
           and abs(sn0["cycle_mean_err_k"]) < TARGET_MEAN and smn is not None
           and abs(smn) < TARGET_MEAN)
    check(met, "issue-14 target on the default mesh (k, TE within %.0f%% per position, means "
          "within %.0f%%): %s" % (100 * TARGET_POS, 100 * TARGET_MEAN, "met" if met else "NOT met"))
    n1 = compare.compare(PAIR, tool, refine=1)
    compare.print_result(n1)
    sn1 = n1["summary"]
    check(sn1["max_abs_err_k"] < BAR_K_O2R1_NF and sn1["max_abs_err_te"] < BAR_K_O2R1_NF,
          "refine 1 near-field: max |k error| %.2f%%, max |TE error| %.2f%% < %.1f%%"
          % (100 * sn1["max_abs_err_k"], 100 * sn1["max_abs_err_te"], 100 * BAR_K_O2R1_NF))
    sm = sn1["single_mean_err_k"]
    check(abs(sn1["cycle_mean_err_k"]) < BAR_MEAN_O2R1_NF and sm is not None
          and abs(sm) < BAR_SINGLE_O2R1_NF,
          "refine 1 near-field: cycle-mean %+.2f%% within %.0f%% and single-contact-mean "
          "%s k error within %.1f%%" % (100 * sn1["cycle_mean_err_k"], 100 * BAR_MEAN_O2R1_NF,
                                        "n/a" if sm is None else "%+.2f%%" % (100 * sm),
                                        100 * BAR_SINGLE_O2R1_NF))

    print("%d failed" % len(failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
