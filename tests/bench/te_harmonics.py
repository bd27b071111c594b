#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Where a dynamic TE differs from the quasi-static TE, by harmonic of the mesh.

    te_harmonics.py DYN.csv STATIC.txt [--from 0.05] [--to 0.09] [--windows K] [--profile M]

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
in both (one-sided amplitudes, rms = sqrt(sum |A_k|^2 / 2)). With --windows K:
per run of K whole mesh cycles in the window, the rms of the part not locked to
the mesh (against the locked part of the whole window) and the frequency of the
largest peak of its spectrum (is the free vibration decaying, constant or fed?).
With --profile M: in M runs of phase bins over the mesh cycle, the static TE, the
locked part and the rms of the part not locked (where in the cycle it is fed).
Not a test.
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
    ap.add_argument('--windows', type=int, default=0, help='cycles per window of the unlocked part')
    ap.add_argument('--profile', type=int, default=0, help='phase intervals of the unlocked part\'s profile')
    a = ap.parse_args(argv)
    d = np.genfromtxt(a.dyn, delimiter=',', names=True)
    t, ph, te = d['t_s'], d['phase_cycles'], d['te_um']
    w = (t >= a.t0) & (t <= a.t1)
    c0, c1 = np.ceil(ph[w][0]), np.floor(ph[w][-1])
    w &= (ph >= c0) & (ph < c1)
    ph, te, t = ph[w], te[w], t[w]
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
    free = te - locked[b]
    if a.profile > 0:
        st = np.roll(rz, shift)
        for k in range(a.profile):
            lo, hi = k * nb // a.profile, (k + 1) * nb // a.profile
            s = (b >= lo) & (b < hi)
            print('phase %.3f-%.3f: static %+.3f um, locked %+.3f um, not locked %.3f um rms'
                  % (lo / nb, hi / nb, st[lo:hi].mean(), lz[lo:hi].mean(), free[s].std()))
    if a.windows > 0:
        for k in np.arange(c0, c1 - a.windows + 0.5, a.windows):
            s = (ph >= k) & (ph < k + a.windows)
            u, ts = free[s] - free[s].mean(), t[s]
            f = np.fft.rfftfreq(len(u), (ts[-1] - ts[0]) / (len(u) - 1))
            peak = f[1 + np.argmax(np.abs(np.fft.rfft(u))[1:])]
            print('cycles %3d-%3d, %.4f-%.4f s: not locked %.4f um rms, largest peak %.0f Hz'
                  % (k - c0, k - c0 + a.windows, ts[0], ts[-1], u.std(), peak))


if __name__ == '__main__':
    main(sys.argv[1:])
