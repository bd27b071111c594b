#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: the service's responsiveness, as ratios measured in one run.

1. `status` latency while a long advance runs, against the latency of the
   same request on the same daemon when idle (scene loaded, nothing
   stepping), at mpirun -n 1 and -n 2: median, p90, p99 and the ratios.
2. Simulation speed with a stalled telemetry subscriber (RCVHWM 1, 4 KiB
   receive buffer, never reads) against without one: fixed advances of the
   pair scene interleaved A B B A over several blocks, the ratio of the
   medians and its spread over blocks.

Both figures depend on what else the machine runs (measured speeds scatter
by +-30% between runs of one condition on a shared 2-core machine), so they
are benchmarks, not tests; the test suite checks only what holds under
load (tests/integration/test_status_latency.py, test_load.py).

    meson test -C build --benchmark --suite bench service
    GEARSIM_BENCH_BLOCKS=8 /usr/bin/python3 tests/bench/bench_service.py
"""
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import zmq  # noqa: E402

import daemon as dmod  # noqa: E402
from harness import stalled_sub  # noqa: E402

N_STATUS = int(os.environ.get("GEARSIM_BENCH_STATUS", "200"))
BLOCKS = int(os.environ.get("GEARSIM_BENCH_BLOCKS", "4"))
RUN_SECONDS = float(os.environ.get("GEARSIM_BENCH_RUN_SECONDS", "0.5"))


def pct(xs, p):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p * (len(xs) - 1))))]


def latencies(c, n):
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        c.status()
        out.append(time.perf_counter() - t0)
        time.sleep(0.01)
    return out


def status_latency(ranks):
    with dmod.Daemon(ranks=ranks) as d:
        with d.client(timeout=30.0, retries=0) as c:
            c.load(builtin="planetary")
            idle = latencies(c, N_STATUS)
            c.advance(steps=10 ** 9, wait=False)
            time.sleep(0.2)
            busy = latencies(c, N_STATUS)
            running = c.status().get("state") == "running"
            c.cancel()
    return idle, busy, running


def timed_run(c, steps):
    done = c.advance(steps=steps, timeout=600)
    return steps / done["wall_seconds"]


def stalled_speed():
    scene = dmod.load_scene("pair")
    scene.setdefault("outputs", {})["telemetry_every"] = 50
    ratios, rates = [], {"without": [], "stalled": []}
    with dmod.Daemon(ranks=1) as d:
        ctx = zmq.Context.instance()
        with d.client(timeout=60.0, retries=0) as c:
            c.load(scene=scene)
            steps = max(20000, int(timed_run(c, 20000) * RUN_SECONDS))
            stalled = None
            for _ in range(BLOCKS):
                block = {"without": [], "stalled": []}
                for cond in ("without", "stalled", "stalled", "without"):
                    if (cond == "stalled") != (stalled is not None):
                        if stalled is None:
                            stalled = stalled_sub(ctx, d.connection)
                        else:
                            stalled.close(0)
                            stalled = None
                        time.sleep(0.2)
                        timed_run(c, steps // 4)   # unmeasured: the new queue fills (or the old drains)
                    r = timed_run(c, steps)
                    block[cond].append(r)
                    rates[cond].append(r)
                ratios.append(statistics.median(block["stalled"]) / statistics.median(block["without"]))
            if stalled is not None:
                stalled.close(0)
    return steps, rates, ratios


def main():
    print(f"# bench_service: load average {os.getloadavg()[0]:.2f} at start")
    print(f"{'ranks':>5} {'idle p50':>9} {'idle p90':>9} {'run p50':>9} {'run p90':>9} {'run p99':>9} "
          f"{'p50 ratio':>9} {'p90 ratio':>9}   (ms; status while a long advance runs vs idle)")
    for n in (1, 2):
        idle, busy, running = status_latency(n)
        i50, i90 = statistics.median(idle), pct(idle, 0.9)
        b50, b90, b99 = statistics.median(busy), pct(busy, 0.9), pct(busy, 0.99)
        print(f"{n:>5} {1e3 * i50:9.2f} {1e3 * i90:9.2f} {1e3 * b50:9.2f} {1e3 * b90:9.2f} {1e3 * b99:9.2f} "
              f"{b50 / i50:9.1f} {b90 / i90:9.1f}" + ("" if running else "   (advance ended early)"))
    steps, rates, ratios = stalled_speed()
    a, b = statistics.median(rates["without"]), statistics.median(rates["stalled"])
    print(f"\nstalled subscriber, pair scene, {BLOCKS} blocks of A B B A runs of {steps} steps:")
    print(f"  steps/s without {a:.0f} (range {min(rates['without']):.0f}..{max(rates['without']):.0f}), "
          f"with {b:.0f} (range {min(rates['stalled']):.0f}..{max(rates['stalled']):.0f})")
    print(f"  speed ratio stalled/without: {b / a:.3f} (medians of all runs); per block "
          + ", ".join(f"{r:.3f}" for r in ratios))
    print(f"# load average {os.getloadavg()[0]:.2f} at end")


if __name__ == "__main__":
    main()
