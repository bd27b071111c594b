#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""`status` is answered while a long advance runs (the service steps in
chunks and polls commands between them): 50 requests during a 1e6-step run of
the planetary scene, at 1 and 2 ranks.

What is checked holds on a loaded machine and involves no clock: every
request gets its reply; the replies say "running"; and the step counter they
report moves on between replies while the advance is still running, which
can only happen when commands are answered between chunks (a service that
answered only after the whole advance would report one step count, the final
one, with the state no longer "running"). The latency itself is a benchmark
figure (tests/bench/bench_service.py, docs/RELIABILITY.md): how long a reply
takes depends on what else the machine runs."""
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_status_latency: status answered during a long advance")
N = 50
STEPS = 1000000   # long enough that the 50 requests fall inside one advance
REPLY_TIMEOUT = 30.0   # a hang guard, not a latency bound


def main(ranks):
    with dmod.Daemon(ranks=ranks) as d:
        with d.client(timeout=REPLY_TIMEOUT, retries=0) as c:
            c.load(builtin="planetary")
            adv = c.advance(steps=STEPS, wait=False)
            R.check("advance accepted", adv.get("accepted") is True, adv)
            replies, lat, restarts = [], [], 0
            while len(replies) < N:
                t0 = time.perf_counter()
                st = c.status()
                lat.append(time.perf_counter() - t0)
                replies.append(st)
                if st.get("state") not in ("running", "paused") and len(replies) < N:
                    # the run ended early (fast machine): start another one
                    restarts += 1
                    if restarts > 20:
                        break
                    c.advance(steps=STEPS, wait=False)
                time.sleep(0.02)
            running = [r for r in replies if r.get("state") == "running"]
            steps = [r.get("step") for r in running]
            moved = sum(1 for a, b in zip(steps, steps[1:]) if isinstance(a, int) and isinstance(b, int) and b > a)
            R.note(f"load average {os.getloadavg()[0]:.2f}; -n {ranks}: {len(replies)} replies, {len(running)} while "
                   f"running, step moved on between {moved} consecutive running replies; {restarts} extra advances; "
                   f"median reply {1e3 * statistics.median(lat):.1f} ms (informative only: latency is benchmarked)")
            R.check(f"-n {ranks}: {N} status replies", len(replies) == N, len(replies))
            R.check(f"-n {ranks}: most replies came while the advance was running", len(running) >= 0.8 * N,
                    [r.get("state") for r in replies])
            R.check(f"-n {ranks}: running replies carry the advance's progress",
                    all(isinstance(r.get("advance"), dict) and 0.0 <= r["advance"].get("fraction", -1) <= 1.0
                        for r in running), running[:2])
            R.check(f"-n {ranks}: the step count moved on between running replies (chunked stepping)",
                    moved >= 0.5 * max(1, len(running) - 1 - restarts), steps)
            st = c.status()
            if st.get("state") == "running":
                c.cancel()
            R.check(f"-n {ranks}: daemon alive and serving", d.alive())


for n in (1, 2):
    R.guard(f"status during an advance against the real daemon at -n {n}", main, n)
R.finish()
