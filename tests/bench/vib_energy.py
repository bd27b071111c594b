#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Vibration energy of a contact_drive run over time (issue 15, "Without
damping, vibration energy no longer grows"; docs/explanation/contact.md "Is the
undamped growth physical?"), from the per-step CSV of tests/bench/corner_stats
(--csv).

Per window: the strain energy (mean / max), the vibration energy

    E_vib = mean(T + V_el) - 1/2 sum_k I_k wbar_k^2 - V_static

(the mechanical energy of both gears less that of their steady rotation at
the window's mean speeds and less the static strain energy at the running
load; it holds the elastic vibration and the torsional oscillation of the
rotations, 1/2 I var(w)), its torsional part 1/2 sum_k I_k var(w_k), the DTE
(kinematic TE, rms about the window's mean), the mean TE and the energy
dissipated in the window other than by the brake on gear 1 of the mesh
(coefficient --brake; the step books c dtheta^2 / h per step: material
damping, and what the contact mesh books). The inertias I_k are fitted (least squares) from
the CSV's rigid kinetic energy 1/2 sum_k I_k w_k^2 and the speeds.

    vib_energy.py RUN.csv [--static-se 1e-3] [--windows 0.02,0.05,0.1,...]
                  [--brake 0.3] [--csv-out OUT]
"""
import argparse
import sys

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("csv")
    ap.add_argument("--static-se", type=float, default=1e-3, help="static strain energy at the load, J")
    ap.add_argument("--brake", type=float, default=0.3, help="brake coefficient on gear 1, N m s")
    ap.add_argument("--windows", default="0.02,0.05,0.1,0.15,0.2,0.25,0.3", help="window edges, s")
    ap.add_argument("--csv-out", dest="out", default=None, help="write the table as CSV")
    a = ap.parse_args()
    d = np.genfromtxt(a.csv, delimiter=",", names=True)
    need = ("t_s", "strain_J", "kinetic_J", "rigid_kinetic_J", "omega0_rad_s", "omega1_rad_s", "te_m",
            "dissipated_J")
    for k in need:
        if k not in d.dtype.names:
            sys.exit(f"{a.csv}: column {k} missing (corner_stats --csv of this version writes it)")
    t = d["t_s"]
    w0, w1 = d["omega0_rad_s"], d["omega1_rad_s"]
    # the brake's share of `dissipated`, step by step: c (h wbar)^2 / h
    hs = np.diff(t, prepend=0.0)
    wb = 0.5 * (w1 + np.concatenate([[0.0], w1[:-1]]))
    other = d["dissipated_J"] - np.cumsum(a.brake * hs * wb ** 2)
    # 2 T_rigid = I0 w0^2 + I1 w1^2, fitted over the steps with motion
    m = (np.abs(w0) + np.abs(w1)) > 1.0
    A = np.column_stack([w0[m] ** 2, w1[m] ** 2])
    I, *_ = np.linalg.lstsq(A, 2 * d["rigid_kinetic_J"][m], rcond=None)
    fit = np.max(np.abs(A @ I - 2 * d["rigid_kinetic_J"][m])) / np.max(2 * d["rigid_kinetic_J"][m])
    print(f"# inertias {I[0]:.6e} {I[1]:.6e} kg m^2 (fit error {fit:.1e}); static strain energy "
          f"{a.static_se * 1e3:.3f} mJ")
    edges = [float(x) for x in a.windows.split(",")]
    rows = []
    hdr = ("from_ms", "to_ms", "strain_mean_mJ", "strain_max_mJ", "vib_mJ", "torsional_mJ", "dte_rms_um",
           "mean_te_um", "dissipated_mJ", "speed0", "speed1")
    print("| window (ms) | strain energy mean / max (mJ) | vibration energy (mJ) | of it torsional (mJ) | "
          "DTE rms (um) | mean TE (um) | dissipated in the window, brake aside (mJ) | mean speeds (rad/s) |")
    print("|---|---|---|---|---|---|---|---|")
    for lo, hi in zip(edges[:-1], edges[1:]):
        s = (t > lo) & (t <= hi + 1e-12)
        if s.sum() < 2:
            continue
        se = d["strain_J"][s]
        tot = d["kinetic_J"][s] + se
        wb0, wb1 = w0[s].mean(), w1[s].mean()
        steady = 0.5 * (I[0] * wb0 ** 2 + I[1] * wb1 ** 2)
        vib = tot.mean() - steady - a.static_se
        tors = 0.5 * (I[0] * w0[s].var() + I[1] * w1[s].var())
        te = d["te_m"][s]
        diss = other[s][-1] - other[s][0]
        r = (lo * 1e3, hi * 1e3, se.mean() * 1e3, se.max() * 1e3, vib * 1e3, tors * 1e3, te.std() * 1e6,
             te.mean() * 1e6, diss * 1e3, wb0, wb1)
        rows.append(r)
        print(f"| {r[0]:.0f}-{r[1]:.0f} | {r[2]:.3f} / {r[3]:.3f} | {r[4]:.3f} | {r[5]:.4f} | {r[6]:.4f} | "
              f"{r[7]:.4f} | {r[8]:.4f} | {r[9]:.4f} / {r[10]:.4f} |")
    if a.out:
        with open(a.out, "w") as f:
            f.write(",".join(hdr) + "\n")
            for r in rows:
                f.write(",".join(f"{x:.6g}" for x in r) + "\n")


if __name__ == "__main__":
    main()
