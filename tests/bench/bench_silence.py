#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The longest silence of the service (docs/RELIABILITY.md, "Limits"): a
second client sends `status` back to back (each waits for its reply)
while a heavy but valid request runs; the longest time any `status` waited
is the silence. Cases (each on a fresh daemon):

  sweep4096   -- the request of a sweep of 4096 points (its validation;
                 the sweep is then cancelled)
  stiffness   -- `stiffness` of the elastic pair at the largest refine the
                 daemon's scene limit allows, while it runs (wait: false)
  step        -- an advance of elastic_spin with the finest flank and one
                 element across that `load` accepts, for 5 s of wall time

    tests/bench/bench_silence.py [case ...]      # prints RESULT lines
"""
import os
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402


def probe(d, stop, out):
    with gearsim.Client(d.conn_file, timeout=120.0, retries=0) as c:
        worst = 0.0
        while not stop.is_set():
            t0 = time.monotonic()
            c.status()
            worst = max(worst, time.monotonic() - t0)
            time.sleep(0.005)
        out.append(worst)


def measure(d, work):
    stop, out = threading.Event(), []
    th = threading.Thread(target=probe, args=(d, stop, out))
    th.start()
    time.sleep(0.3)
    try:
        note = work()
    finally:
        stop.set()
        th.join()
    return out[0], note


def sweep4096(d):
    c = d.client(timeout=120.0)
    vals = [1.0 + i * 1e-3 for i in range(4096)]
    t0 = time.monotonic()
    c.request("sweep", {"builtin": "pair", "path": "s4096", "settle": 1e-4, "measure": 1e-4,
                        "parameters": [{"path": "loads[0].moment", "values": vals}]}, timeout=120.0)
    took = time.monotonic() - t0
    c.request("cancel")
    return f"the request took {took:.2f} s"


def stiffness(d):
    c = d.client(timeout=120.0)
    c.request("load", {"builtin": "elastic_pair"})
    best = None
    forced = os.environ.get("GEARSIM_BENCH_REFINE")
    for r in ([int(forced)] if forced else (3, 2, 1, 0)):
        try:
            rid = c.send("stiffness", {"mesh": "pinion-wheel", "refine": r, "positions": 8, "wait": False})
            c.wait_reply(rid, timeout=120.0)
            best = r
            break
        except gearsim.GearsimError:
            continue
    c.subscribe()
    c.wait_done(rid, timeout=600)
    return f"refine {best}"


def step(d):
    c = d.client(timeout=120.0)
    sc = dmod.load_scene("elastic_spin")
    body = next(b for b in sc["bodies"] if b.get("model") == "elastic")
    body["mesh"] = {"flank": 256, "across": 1}
    try:
        c.request("load", {"scene": sc}, timeout=600.0)
    except gearsim.GearsimError as e:
        return f"refused at load: {e.code}: {e.message[:120]}"
    c.request("advance", {"steps": 1000000})
    time.sleep(5.0)
    c.request("cancel", timeout=600.0)
    return "advance of the finest accepted flank"


CASES = {"sweep4096": sweep4096, "stiffness": stiffness, "step": step}


def main():
    for name in sys.argv[1:] or list(CASES):
        with dmod.Daemon(ranks=1) as d:
            worst, note = measure(d, lambda: CASES[name](d))
            print(f"RESULT silence_{name} {worst:.3f} s ({note})", flush=True)


if __name__ == "__main__":
    main()
