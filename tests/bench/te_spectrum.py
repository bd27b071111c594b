#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Order spectrum of the dynamic TE with run-out (docs/explanation/geometry.md "Run-out:
the TE spectrum"), from the CSV series that te_errors writes:

    build/tests/bench/te_errors --omega 40 --csv /tmp/te
    tests/bench/te_spectrum.py /tmp/te [--runout-um 20] [--out docs/img/te_runout_spectrum.png]

For each mesh model found (contact, lumped, calibrated) it takes the first
whole pinion revolution of the perfect and the run-out series, computes the
amplitudes of the orders 0..50 of the pinion's rotation (each sample
weighted by the angle its step spans; order z is the mesh frequency, z -+ 1
the sidebands f_mesh -+ f_rot), prints the orders 1, z - 1, z, z + 1 with
the predictions, and plots both spectra per model. Predictions: the
once-per-revolution line e (the centre offset projected on the line of
action); each sideband A_z pi e / p_b (phase modulation of the mesh
harmonic A_z by the contact point's shift along the line of action, index
2 pi e / p_b), A_z the model's own mesh-order amplitude without run-out.
"""
import argparse
import math
import os
import sys

import numpy as np

Z = 20
MODULE_MM = 2.5
ALPHA = math.radians(20.0)


def load(path):
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    return a[:, 1], a[:, 2]


def spectrum(th, te, orders):
    """Amplitudes (um) of the given orders over [th[0], th[0] + 2 pi)."""
    tm = 0.5 * (th[1:] + th[:-1])
    x = 0.5 * (te[1:] + te[:-1])
    d = np.diff(th)
    s = tm < th[0] + 2 * math.pi
    tm, x, d = tm[s], x[s], d[s]
    if d.sum() < 2 * math.pi * 0.999:
        sys.exit("te_spectrum: the series covers less than one pinion revolution")
    out = []
    for k in orders:
        c = (x * np.exp(-1j * k * tm) * d).sum() / math.pi
        out.append(abs(c))
    return np.array(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("prefix")
    ap.add_argument("--runout-um", type=float, default=20.0)
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    pb_um = math.pi * MODULE_MM * math.cos(ALPHA) * 1e3
    e = a.runout_um
    orders = np.arange(1, 51)
    rows = []
    for model in ("contact", "lumped", "calibrated"):
        p, r = f"{a.prefix}_{model}_perfect.csv", f"{a.prefix}_{model}_runout.csv"
        if not (os.path.exists(p) and os.path.exists(r)):
            continue
        sp = spectrum(*load(p), orders)
        sr = spectrum(*load(r), orders)
        side = sp[Z - 1] * math.pi * e / pb_um
        rows.append((model, sp, sr, side))
        print(f"{model:10s} perfect: 1 {sp[0]:.4f} {Z-1} {sp[Z - 2]:.4f} {Z} {sp[Z - 1]:.4f} {Z+1} {sp[Z]:.4f} um; "
              f"run-out: 1 {sr[0]:.4f} (predicted {e:.4f}) {Z-1} {sr[Z - 2]:.4f} {Z} {sr[Z - 1]:.4f} "
              f"{Z+1} {sr[Z]:.4f} um (predicted sidebands {side:.4f} each)")
    if not rows:
        sys.exit("te_spectrum: no CSV pairs found for " + a.prefix)
    if a.out:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(len(rows), 1, figsize=(9, 2.8 * len(rows)), sharex=True, squeeze=False)
        for ax, (model, sp, sr, side) in zip(axes[:, 0], rows):
            w = 0.38
            ax.bar(orders - w / 2, np.maximum(sp, 1e-5), width=w, color="0.6", label="perfect gears")
            ax.bar(orders + w / 2, np.maximum(sr, 1e-5), width=w, color="tab:red", label=f"{e:g} um run-out")
            ax.plot([1], [e], "k_", ms=14, mew=2, label="predicted: 1x line e")
            ax.plot([Z - 1, Z + 1], [side, side], "bx", ms=8, mew=2,
                    label="predicted sidebands A_z pi e / p_b")
            ax.set_yscale("log")
            ax.set_ylim(1e-4, 60)
            ax.set_ylabel("TE amplitude (um)")
            ax.set_title(f"{model} mesh", fontsize=10)
        axes[0, 0].legend(fontsize=7, loc="upper right", ncol=2)
        axes[-1, 0].set_xlabel("order of the pinion rotation (20: mesh frequency; 19, 21: f_mesh -+ f_rot)")
        fig.tight_layout()
        fig.savefig(a.out, dpi=90)
        print("wrote", a.out)


if __name__ == "__main__":
    main()
