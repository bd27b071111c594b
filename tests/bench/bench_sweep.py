#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: throughput of the daemon's `sweep` job (docs/explanation/modal.md,
"Sweeps") on the lumped planetary (planetary_sweep), points per second at
mpirun -n 1 with 1 group (the reference, timed in the same run), at -n 2
with 1 group of 2 ranks and at -n 2 with 2 groups of 1 rank; prints the
ratios against the reference and checks that the three tables are
byte-identical. On a machine whose cores are busy with other work the
ratio of 2 groups says little (the second rank has no core of its own);
the ideal on two free cores is 2.

    meson test -C build --benchmark --suite bench sweep
    GEARSIM_BENCH_POINTS=41 GEARSIM_BENCH_SETTLE=0.008 ... for the full sweep
"""
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import daemon as dmod  # noqa: E402

POINTS = int(os.environ.get("GEARSIM_BENCH_POINTS", "16"))
SETTLE = float(os.environ.get("GEARSIM_BENCH_SETTLE", "0.002"))
MEASURE = float(os.environ.get("GEARSIM_BENCH_MEASURE", "0.002"))
H = 2e-6


def sweep(ranks, groups):
    """(points per second, table text) of one sweep on a fresh daemon: from
    the request to the done event, the subscription made before."""
    with dmod.Daemon(ranks=ranks) as d, d.client(timeout=60) as c:
        args = dict(builtin="planetary_sweep", settle=SETTLE, measure=MEASURE, time_step=H, groups=groups,
                    path="bench")
        c.subscribe()
        t0 = time.perf_counter()
        done = c.sweep([{"path": "driver_rpm", "from": 17000, "to": 25000, "points": POINTS}], timeout=3600, **args)
        dt = time.perf_counter() - t0
        with open(d.path("bench.csv")) as f:
            text = f.read()
    if done.get("points_done") != POINTS:
        raise RuntimeError(f"sweep incomplete: {done}")
    return POINTS / dt, text


def loadavg():
    """/proc/loadavg's 1, 5 and 15 minute averages: the ratio of 2 groups
    means something only when they are well below the core count."""
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


steps = POINTS * round((SETTLE + MEASURE) / H)
print(f"# sweep of the lumped planetary: {POINTS} points, {steps} steps in all (h = {H:g} s); "
      f"load average (1, 5, 15 min) {loadavg()} on {os.cpu_count()} cores")
ref, t_ref = sweep(1, 1)
print(f"{'ranks':>5} {'groups':>6} {'points/s':>9} {'steps/s':>9} {'ratio':>6}")
print(f"{1:>5} {1:>6} {ref:9.2f} {ref * steps / POINTS:9.0f} {1.0:6.2f}")
same = True
for ranks, groups in ((2, 1), (2, 2)):
    rate, text = sweep(ranks, groups)
    same = same and text == t_ref
    print(f"{ranks:>5} {groups:>6} {rate:9.2f} {rate * steps / POINTS:9.0f} {rate / ref:6.2f}")
print(f"tables identical: {same}; load average after: {loadavg()}")
sys.exit(0 if same else 1)
