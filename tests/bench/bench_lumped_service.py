#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: the rigid lumped 3-planet train (builtin `planetary`) through
the service, telemetry every 10 steps, at mpirun -n 1 and -n 2, against the
step alone (tests/bench/bench_lumped.c) timed in the same run. Sweeps run
many such cheap points, so the service's overhead per step is what bounds
them.

Both sides are measured in CPU seconds per step (the machine is shared: wall
time counts other jobs' slices): the step alone as bench_lumped reports it
(best of its batches), the service as the CPU time of the daemon's ranks
(every gearsimd process, from /proc, its ZeroMQ I/O thread included) over a
timed advance, divided by its steps. The ratio service / step alone is the
service's cost per step (scheduling, telemetry, the event loop) as a factor
on the step's. Other jobs slow both sides by varying amounts, so the two are
timed in alternation, ROUNDS times, each ratio against the step alone of its
own round; the median and the ratio of the lowest CPU times (the least
disturbed of each) are printed. The Python client subscribes as it does by
default (telemetry in batches). Steps per second of wall time are printed
as well.

    meson test -C build --benchmark --suite bench lumped_service
    GEARSIM_BENCH_STEPS=200000 GEARSIM_BENCH_ROUNDS=3 /usr/bin/python3 tests/bench/bench_lumped_service.py
"""
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import daemon as dmod  # noqa: E402

STEPS = int(os.environ.get("GEARSIM_BENCH_STEPS", "200000"))
ROUNDS = int(os.environ.get("GEARSIM_BENCH_ROUNDS", "3"))
TICK = os.sysconf("SC_CLK_TCK")


def step_alone():
    """CPU seconds per step of the step alone and bench_lumped's line."""
    exe = os.path.join(dmod.BUILD_ROOT, "tests", "bench", "bench_lumped")
    out = subprocess.run([exe, "20000"], stdout=subprocess.PIPE, text=True, check=True,
                         env=dict(os.environ, OPENBLAS_NUM_THREADS="1", BENCH_ONLY="0", BENCH_NOSOLVE="1")).stdout
    for line in out.splitlines():
        if line.startswith("planetary "):
            return float(line.split()[3]) * 1e-6, line
    raise RuntimeError(out)


def ranks_cpu(d):
    """CPU seconds (user + system) of the daemon's gearsimd processes."""
    total = 0.0
    for p in d.session_pids():
        try:
            with open(f"/proc/{p}/stat") as f:
                st = f.read()
        except OSError:
            continue
        if "(gearsimd)" not in st:
            continue
        fields = st[st.rindex(")") + 2:].split()
        total += (int(fields[11]) + int(fields[12])) / TICK
    return total


def timed_advance(d, c):
    """(steps per wall second, CPU seconds per step, telemetry events) of one advance."""
    n = [0]
    c0, t0 = ranks_cpu(d), time.perf_counter()
    c.advance(steps=STEPS, on_telemetry=lambda ev: n.__setitem__(0, n[0] + 1), timeout=3600)
    dt, cpu = time.perf_counter() - t0, ranks_cpu(d) - c0
    return STEPS / dt, cpu / STEPS, n[0]


def main():
    scene = dmod.load_scene("planetary")
    scene["outputs"] = {"telemetry_every": 10}
    print(f"# rigid lumped planetary, {STEPS} steps per advance, telemetry every 10 steps, {ROUNDS} rounds "
          f"(each: the step alone, then the service; -n 1, then -n 2); load average {os.getloadavg()[0]:.2f}")
    print(f"{'round':>5} {'alone us':>9} {'ranks':>5} {'steps/s':>10} {'telemetry':>10} {'CPU us/step':>12} "
          f"{'service/alone':>14}")
    ratios = {1: [], 2: []}
    best = {1: [], 2: []}
    alone = {1: [], 2: []}
    for r in (1, 2):   # one daemon at a time: an idle one's ranks would disturb the other
        with dmod.Daemon(ranks=r) as d, d.client() as c:
            c.load(scene=scene)
            c.advance(steps=2000, timeout=600)
            for k in range(ROUNDS):
                ref, line = step_alone()
                if k == 0 and r == 1:
                    print(f"# bench_lumped's line: {line.strip()}")
                sps, cpu, nt = timed_advance(d, c)
                ratios[r].append(cpu / ref)
                best[r].append(cpu)
                alone[r].append(ref)
                print(f"{k + 1:5d} {ref * 1e6:9.3f} {r:5d} {sps:10.0f} {nt:10d} {cpu * 1e6:12.3f} {cpu / ref:14.2f}")
    for r in (1, 2):
        v = sorted(ratios[r])
        print(f"# -n {r}: service / step alone median {v[len(v) // 2]:.2f} (range {v[0]:.2f}-{v[-1]:.2f}); "
              f"lowest CPU / lowest step alone {min(best[r]) / min(alone[r]):.2f}")
    print(f"# load average {os.getloadavg()[0]:.2f} at end")


if __name__ == "__main__":
    main()
