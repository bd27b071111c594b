#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Where a dynamic TE differs from the quasi-static TE, by harmonic of the mesh.

    te_harmonics.py DYN.csv STATIC.txt [--from 0.05] [--to 0.09]

DYN.csv: `lowspeed_te SCENE.json --csv DYN.csv` (per step the mesh phase in
cycles and the kinematic TE). STATIC.txt: the table `gearsim-stiffness SCENE.json
--positions N` prints (per roll position the elastic TE and the no-load closing
te0, whose sum is the raw TE the dynamic run sees).

The dynamic TE over the whole mesh cycles in the window is averaged in N bins of
mesh phase (its phase-locked part: the response to the mesh's periodic
excitation) and the rest is the part not locked to the mesh (free vibration).
The static TE is turned to the phase of best fit (the static table's roll 0 is
not the dynamic run's phase 0). Printed: both rms values, the rms difference of
the locked part and the static TE, and the rms of each band of mesh harmonics
in both (one-sided amplitudes, rms = sqrt(sum |A_k|^2 / 2)). Not a test.
"""
import argparse
import sys

import numpy as np

BANDS = [(1, 4), (4, 10), (10, 20), (20, 40), (40, None)]


def static_table(path):
    roll, raw = [], []
    for line in open(path):
        f = line.split()
        if len(f) >= 4 and f[0].replace('.', '', 1).isdigit():
            roll.append(float(f[0]))
            raw.append(float(f[2]) + float(f[3]))
    return np.array(roll), np.array(raw)


def band_rms(a, lo, hi):
    return float(np.sqrt(np.sum(np.abs(a[lo:hi]) ** 2) / 2))


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('dyn')
    ap.add_argument('static')
    ap.add_argument('--from', dest='t0', type=float, default=0.05)
    ap.add_argument('--to', dest='t1', type=float, default=0.09)
    a = ap.parse_args(argv)
    d = np.genfromtxt(a.dyn, delimiter=',', names=True)
    t, ph, te = d['t_s'], d['phase_cycles'], d['te_um']
    w = (t >= a.t0) & (t <= a.t1)
    c0, c1 = np.ceil(ph[w][0]), np.floor(ph[w][-1])
    w &= (ph >= c0) & (ph < c1)
    ph, te = ph[w], te[w]
    _, raw = static_table(a.static)
    nb = len(raw)
    if nb < 8 or c1 - c0 < 1:
        sys.exit('te_harmonics: too few static positions or no whole mesh cycle in the window')
    b = np.minimum((np.mod(ph, 1.0) * nb).astype(int), nb - 1)
    locked = np.array([te[b == k].mean() if np.any(b == k) else np.nan for k in range(nb)])
    if np.any(np.isnan(locked)):
        sys.exit('te_harmonics: a phase bin holds no step (fewer static positions, or a longer window)')
    lz, rz = locked - locked.mean(), raw - raw.mean()
    diffs = [np.sqrt(np.mean((np.roll(rz, s) - lz) ** 2)) for s in range(nb)]
    shift = int(np.argmin(diffs))
    A, B = np.fft.rfft(lz) / nb * 2, np.fft.rfft(np.roll(rz, shift)) / nb * 2
    print('dynamic: %d cycles, mean %.4f um, rms %.4f um; locked rms %.4f um, not locked %.4f um'
          % (c1 - c0, te.mean(), te.std(), lz.std(), (te - locked[b]).std()))
    print('static:  %d positions, mean %.4f um, rms %.4f um; locked - static rms %.4f um'
          % (nb, raw.mean(), raw.std(), diffs[shift]))
    for lo, hi in BANDS:
        hi = hi or nb // 2 + 1
        print('harmonics %2d-%2d: dynamic %.4f um, static %.4f um' % (lo, hi - 1, band_rms(A, lo, hi),
                                                                   band_rms(B, lo, hi)))


if __name__ == '__main__':
    main(sys.argv[1:])
