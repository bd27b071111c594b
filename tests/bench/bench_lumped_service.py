#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: the rigid lumped 3-planet train (builtin `planetary`) through
the service, telemetry every 10 steps, at mpirun -n 1 and -n 2, against the
step alone (tests/bench/bench_lumped.c) timed in the same run: steps per
second, per rank, and the ratio service / step alone. Sweeps run many such
cheap points, so the service's overhead per step is what bounds them.

    meson test -C build --benchmark --suite bench lumped_service
"""
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import daemon as dmod  # noqa: E402

STEPS = int(os.environ.get("GEARSIM_BENCH_STEPS", "100000"))


def step_alone():
    exe = os.path.join(dmod.BUILD_ROOT, "tests", "bench", "bench_lumped")
    out = subprocess.run([exe, "50000"], stdout=subprocess.PIPE, text=True,
                         env=dict(os.environ, OPENBLAS_NUM_THREADS="1", BENCH_ONLY="0")).stdout
    for line in out.splitlines():
        if line.startswith("planetary "):
            return float(line.split()[2])
    raise RuntimeError(out)


def service(ranks):
    scene = dmod.load_scene("planetary")
    scene["outputs"] = {"telemetry_every": 10}
    with dmod.Daemon(ranks=ranks) as d:
        with d.client() as c:
            c.load(scene=scene)
            c.advance(steps=2000, timeout=600)
            t0 = time.perf_counter()
            n = [0]
            c.advance(steps=STEPS, on_telemetry=lambda ev: n.__setitem__(0, n[0] + 1), timeout=3600)
            dt = time.perf_counter() - t0
    return STEPS / dt, n[0]


ref = step_alone()
print(f"# rigid lumped planetary, {STEPS} steps, telemetry every 10 steps; step alone {ref:.0f} steps/s")
print(f"{'ranks':>5} {'steps/s':>10} {'per rank':>10} {'telemetry':>10} {'service/alone':>14}")
for r in (1, 2):
    sps, nt = service(r)
    print(f"{r:5d} {sps:10.0f} {sps / r:10.0f} {nt:10d} {sps / ref:14.3f}")
