#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The slice analysis of a helical pair (gearsim-stiffness on helical scenes,
docs/explanation/helical.md "Loaded tooth contact by slices").

Asserted (each can fail):
* convergence in the number of slices: on the crowned, misaligned pair and
  on the misaligned pair without crowning, the two finest of 160, 320 and
  640 slices agree within SLICE_BAR (0.5 %) in the mean mesh stiffness, the
  mean loaded static TE and K_Hbeta;
* overlap: the aligned pair (eps_beta = 0.989) has a peak-to-peak loaded
  static TE and a stiffness variation (max - min) at least OVERLAP_FACTOR (3)
  times smaller than the spur pair of the same transverse geometry (the
  planar analysis of its transverse section, in the same run), and its
  K_Hbeta is 1 within 2 %;
* a uniform face load on the aligned pair: K_Hbeta < 1.02;
* crowning sized for the misalignment (C = 0.5 f_ma, ISO 6336-1) lowers
  K_Hbeta against the uncrowned misaligned pair; both are printed beside
  ISO 6336-1 method C (computed here, see iso_method_c);
* the coupling length: the stored 3D CalculiX runs of one tooth under a
  strip load (tests/reference/helical_coupling/runs.csv, never run here)
  have a decay length converged in the mesh (two finest within 2 %), and the
  analysis's default coupling length (JSON coupling_mm) is within 3 % of the
  finest run's, scaled by the normal module (the runs: m 2.5 mm);
* bad input named: fewer than 8 positions, slices out of range.
"""
import json
import os
import subprocess
import sys
import tempfile

SRC = os.environ.get("GEARSIM_SOURCE_ROOT", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(SRC, "build"))
TOOL = os.path.join(BUILD, "src", "tools", "gearsim-stiffness")
SCENE = os.path.join(SRC, "tests", "validation", "helical_crowned.json")
SLICE_BAR = 0.005
OVERLAP_FACTOR = 3.0
POS = 12
fails = 0


def check(ok, what):
    global fails
    print(("ok     " if ok else "FAILED ") + what)
    if not ok:
        fails += 1


def run(scene, *args):
    out = subprocess.run([TOOL, scene, "--json", "--positions", str(POS), "--no-tangent"] + list(args),
                         capture_output=True, text=True)
    if out.returncode != 0:
        print(out.stderr)
        return None
    return json.loads(out.stdout)


def iso_method_c(f_ma_um, b2, c_gamma, w_m):
    """ISO 6336-1 method C face load factor without running-in and shaft
    deflection (f_sh = 0, y_beta = 0): F_beta_y = F_beta_x = B2 f_ma (B2 = 1
    unmodified, 0.5 crowned); K_Hbeta = 1 + F_beta_y c_gamma / (2 w_m) while
    that is <= 2, else sqrt(2 F_beta_y c_gamma / w_m). c_gamma in N/(mm um),
    w_m = F_t / b in N/mm."""
    fy = b2 * f_ma_um
    k = 1.0 + fy * c_gamma / (2.0 * w_m)
    return k if k <= 2.0 else (2.0 * fy * c_gamma / w_m) ** 0.5


def main():
    base = json.load(open(SCENE))
    tmp = tempfile.mkdtemp()
    uncrowned = json.loads(json.dumps(base))
    del uncrowned["bodies"][0]["lead"]
    aligned = json.loads(json.dumps(uncrowned))
    del aligned["meshes"][0]["misalignment"]
    paths = {}
    for name, sc in (("uncrowned", uncrowned), ("aligned", aligned)):
        paths[name] = os.path.join(tmp, name + ".json")
        json.dump(sc, open(paths[name], "w"))
    paths["crowned"] = SCENE

    for name in ("crowned", "uncrowned"):
        rows = []
        for n in (160, 320, 640):
            r = run(paths[name], "--slices", str(n))
            check(r is not None, "%s, %d slices runs" % (name, n))
            if r is None:
                return
            s = r["slice_analysis"]
            rows.append((n, r["k"]["mean"], r["te_loaded_um"]["mean"], s["k_hbeta"]))
            print("  %s %4d slices: k mean %.4f N/(mm um), TE mean %.4f um, K_Hbeta %.4f" % ((name,) + rows[-1]))
        for c, what in ((1, "k mean"), (2, "TE mean"), (3, "K_Hbeta")):
            rel = abs(rows[-1][c] - rows[-2][c]) / abs(rows[-1][c])
            check(rel < SLICE_BAR, "%s: %s, 320 and 640 slices within %.2g %% (%.3g %%)" %
                  (name, what, 100 * SLICE_BAR, 100 * rel))

    a = run(paths["aligned"])
    s = a["slice_analysis"]
    sec = s["transverse_section"]
    te_h = a["te_loaded_um"]["peak_to_peak"]
    te_s = sec["te_loaded_peak_to_peak_um"]
    dk_h = a["k"]["max"] - a["k"]["min"]
    dk_s = sec["k_max"] - sec["k_min"]
    print("  aligned, eps_beta %.4f: TE p-p %.4f um (spur section %.4f), k variation %.4f (spur %.4f) N/(mm um)"
          % (s["overlap_ratio"], te_h, te_s, dk_h, dk_s))
    check(abs(s["overlap_ratio"] - 0.988616) < 1e-5, "overlap ratio 0.988616")
    check(te_s / te_h >= OVERLAP_FACTOR, "static TE p-p reduced %.1fx >= %g" % (te_s / te_h, OVERLAP_FACTOR))
    check(dk_s / dk_h >= OVERLAP_FACTOR, "stiffness variation reduced %.1fx >= %g" % (dk_s / dk_h, OVERLAP_FACTOR))
    check(abs(s["k_hbeta"] - 1.0) < 0.02, "aligned K_Hbeta %.4f is 1 within 2 %%" % s["k_hbeta"])

    w_m = a["force_n"] / a["face_width_mm"]
    c_g = a["k"]["mean"]
    f_ma = base["meshes"][0]["misalignment"]["in_plane_um"]
    u = run(paths["uncrowned"])
    c = run(paths["crowned"])
    ku, kc = u["slice_analysis"]["k_hbeta"], c["slice_analysis"]["k_hbeta"]
    iu, ic = iso_method_c(f_ma, 1.0, c_g, w_m), iso_method_c(f_ma, 0.5, c_g, w_m)
    print("  f_ma %g um, w_m %.1f N/mm, c_gamma %.3f N/(mm um) (aligned slice analysis)" % (f_ma, w_m, c_g))
    print("  K_Hbeta uncrowned: slices %.4f, ISO 6336-1 method C %.4f" % (ku, iu))
    print("  K_Hbeta crowned 0.5 f_ma: slices %.4f, ISO 6336-1 method C %.4f" % (kc, ic))
    check(kc < ku, "crowning lowers K_Hbeta (%.3f < %.3f)" % (kc, ku))
    check(ku > 1.2 and iu > 1.2, "misalignment raises K_Hbeta in both")

    runs = [ln.strip().split(",") for ln in open(os.path.join(SRC, "tests", "reference", "helical_coupling",
                                                               "runs.csv")).readlines()[1:]]
    runs.sort(key=lambda v: -float(v[0]))
    lam3d = [float(v[4]) for v in runs]
    print("  3D decay length by mesh size: " + ", ".join("h %s mm: %.3f mm" % (v[0], float(v[4])) for v in runs))
    check(len(runs) >= 2 and abs(lam3d[-1] - lam3d[-2]) / lam3d[-1] < 0.02,
          "3D decay length converged in the mesh (two finest within 2 %)")
    m_n = base["bodies"][0]["module_mm"]
    lam = c["slice_analysis"]["coupling_mm"]
    check(abs(lam / m_n - lam3d[-1] / 2.5) / (lam3d[-1] / 2.5) < 0.03,
          "default coupling length %.3f mm = %.3f m_n, 3D %.3f m_n (within 3 %%)" % (lam, lam / m_n, lam3d[-1] / 2.5))

    for args, field in ((["--positions", "4"], "positions"),):
        out = subprocess.run([TOOL, SCENE] + args, capture_output=True, text=True)
        check(out.returncode != 0 and field in out.stderr, "refused, naming '%s': %s" % (field, out.stderr.strip()))
    out = subprocess.run([TOOL, SCENE, "--slices", "1"], capture_output=True, text=True)
    check(out.returncode != 0 and "slices" in out.stderr, "--slices 1 refused: %s" % out.stderr.strip())
    if fails:
        print("%d check(s) failed" % fails)
        sys.exit(1)


main()
