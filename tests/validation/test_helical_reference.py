#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim's slice analysis of a helical pair against the stored 3D
CalculiX reference of the loaded pair (tests/reference/helical_pair/: gmsh
quadratic tetrahedra, frictionless surface-to-surface contact; never run
here), aligned and with 20 um of misalignment in the plane of action over
the face. Per reference position: the mesh stiffness k, the elastic static
TE and the peak load per unit face width along the face (summed over the
contact lines, the largest mean over 4 mm of face); and the cycle mean of
k. The reference's gear sectors of 5 teeth and of 13 teeth are compared
separately (the 5-tooth sectors' free radial cuts make the 3D pair far
more compliant than gearsim's whole gears: docs/validation/calculix_helical.md).

The bars (BAR_*) are the targets: mesh stiffness within 3 % at every
position and in the cycle mean, static TE within 3 %, peak load within 5 %.
Where a bar is not met, the measured agreement is asserted instead with a
stated margin: a regression bound (REGRESSION, in
docs/validation/calculix_helical.md), which fails if the agreement gets
worse. Each check names which of the two it asserts.
Also asserted: the reference's own state (the positions stored, each
stored run's wheel hub reaction equal to the applied force within 0.1 %,
and where a load profile is stored, its contact forces' transverse load
equal to the applied force within 0.1 %).
"""
import os
import sys

SRC = os.environ.get("GEARSIM_SOURCE_ROOT",
                     os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(SRC, "build"))
sys.path.insert(0, os.path.join(SRC, "tests", "reference", "helical_pair"))
import compare_helical  # noqa: E402

BAR_K, BAR_K_MEAN, BAR_TE, BAR_PEAK = 0.03, 0.03, 0.03, 0.05
# Regression bounds: the measured largest |error| (see the docs page) plus
# a margin; used where the bar above is not met. Keyed by (misalignment um,
# teeth per gear sector of the reference). gearsim's sections of this pair
# (face 8 m_n) are in plane strain (the default for a helical gear whose
# face is at least 5 m_n wide).
# 5-tooth sectors (aligned, h = 1.2 mm, rolls 0 and 0.5): gearsim's k
# 21.41 % above the 3D model's, TE 17.64 % below, peak load 15.76 % below
# (roll 0.5; roll 0 has no load profile stored). Their free radial cuts
# make the sector 27 % more compliant than whole gears (2D check).
# 13-tooth sectors (the reference proper: 1.3 % from whole gears in 2D;
# aligned, h = 1.2 mm, 8 positions over the mesh cycle): largest |k error|
# 5.48 %, |TE error| 5.80 %, |peak load error| 20.89 %; the cycle mean of k
# 2.86 % low, within its bar. Misaligned 20 um (h = 1.2 mm, rolls 0, 0.25,
# 0.5 and 0.75): largest |k error| 21.91 %, |TE error| 28.06 % (both roll
# 0.5), |peak load error| 17.70 % (roll 0.75).
REGRESSION = {
    (0.0, 5): dict(k=0.235, te=0.195, peak=0.175),
    (0.0, 13): dict(k=0.065, te=0.07, peak=0.23),
    (20.0, 13): dict(k=0.24, te=0.30, peak=0.20, k_mean=0.24),
}
MIN_POSITIONS = {(0.0, 5): 2, (0.0, 13): 8, (20.0, 13): 4}
# The reference's own mesh convergence: where a finer level ran at a
# position, its TE and peak load change from the reference level (h = 1.2 mm
# to 0.9 mm at roll 0, aligned: TE +1.65 %, peak -0.76 %) stay within this.
BAR_REF_CHANGE = 0.025
fails = []


def check(ok, what):
    print(("ok     " if ok else "FAILED ") + what)
    if not ok:
        fails.append(what)


def bound(measured, bar, reg, what):
    """Assert measured < bar, or, if a regression bound is stated, measured
    < that bound (the bar then reported as not met). measured None: the
    reference has no such figure (printed, not asserted)."""
    if measured is None:
        print("n/a    %s: not in the stored reference" % what)
    elif measured < bar:
        check(True, "%s %.2f %% within the bar %.0f %%" % (what, 100 * measured, 100 * bar))
    elif reg is not None:
        check(measured < reg, "%s %.2f %%: bar %.0f %% NOT MET; regression bound %.1f %%" %
              (what, 100 * measured, 100 * bar, 100 * reg))
    else:
        check(False, "%s %.2f %% above the bar %.0f %%" % (what, 100 * measured, 100 * bar))


def main():
    tool = os.path.join(BUILD, "src", "tools", "gearsim-stiffness")
    ref = compare_helical.load_reference()
    for (f, teeth), n in MIN_POSITIONS.items():
        rr = ref.get((f, teeth), [])
        check(len(rr) >= n, "reference, misalignment %g um, %d-tooth sectors: %d positions (>= %d)" %
              (f, teeth, len(rr), n))
    for (f, teeth), rr in sorted(ref.items()):
        for r in rr:
            # the stored runs balance: the wheel hub carries the applied force
            if r["peak"] == r["peak"]:
                check(abs(r["contact_force"] / r["force"] - 1.0) < 1e-3,
                      "reference roll %.3f, misalignment %g um, %d-tooth sectors: contact forces carry %.1f N "
                      "of %.1f N" % (r["roll"], f, teeth, r["contact_force"], r["force"]))
            check(abs(r["hub_force"] / r["force"] - 1.0) < 1e-3,
                  "reference roll %.3f, misalignment %g um, %d-tooth sectors: hub reaction %.1f N against %.1f N" %
                  (r["roll"], f, teeth, r["hub_force"], r["force"]))
    for (f, teeth), rr in sorted(ref.items()):
        for r in rr:
            if r["finer"] is None:
                continue
            for what, v in (("TE", r["te_change"]), ("peak load", r["peak_change"])):
                check(abs(v) < 100 * BAR_REF_CHANGE,
                      "reference roll %.3f, misalignment %g um, %d-tooth sectors: %s changes %+.2f %% from h %g to "
                      "%g mm (< %.1f %%)" % (r["roll"], f, teeth, what, v, r["h"], r["finer"], 100 * BAR_REF_CHANGE))
    res = compare_helical.compare(tool)
    for (f, teeth), r in sorted(res.items()):
        s = r["summary"]
        print("misalignment %g um, %d-tooth sectors: %d positions" % (f, teeth, s["positions"]))
        for x in r["rows"]:
            print("  roll %.3f: k %.3f / %.3f (%+.2f %%), TE %.3f / %.3f um (%+.2f %%), peak %.1f / %.1f N/mm"
                  % (x["roll"], x["k"], x["k_ref"], 100 * x["err_k"], x["te"], x["te_ref"], 100 * x["err_te"],
                     x["peak"], x["peak_ref"]))
        reg = REGRESSION.get((f, teeth), {})
        tag = "misalignment %g um, %d-tooth sectors:" % (f, teeth)
        bound(s["max_err_k"], BAR_K, reg.get("k"), tag + " largest |k error|")
        bound(abs(s["err_k_mean"]) if s["err_k_mean"] is not None else None, BAR_K_MEAN, reg.get("k_mean"),
              tag + " cycle mean k error")
        bound(s["max_err_te"], BAR_TE, reg.get("te"), tag + " largest |TE error|")
        bound(s["max_err_peak"], BAR_PEAK, reg.get("peak"), tag + " largest |peak load error|")
    if fails:
        print("%d check(s) failed" % len(fails))
        sys.exit(1)


main()
