#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The service answers within long requests (docs/RELIABILITY.md, "Longest
silence"): while one client waits on a request that runs for seconds, a
second client's `status`, `state` and `hello` are answered before that
request ends, and a request that would change something (`unload`) waits
for it and is answered after it, in order, not refused.

Cases: `stiffness` with `wait: true` at refine 1 (one rank: meshing,
factorisation and every roll position inside the request), and the `load`
of a fine elastic gear at -n 2 (the body is built on rank 1 while rank 0
waits for it in a collective).

What is checked is an order of events, never a duration: each reply's
arrival is stamped, and the checks compare the stamps (a service silent
for the whole request would answer the second client only after it). The
latency is a benchmark figure (tests/bench/bench_silence.py)."""
import os
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_silence: replies within long requests, changes after them")


def stamped(c, rid, box, key, timeout=900.0):
    """Wait for reply rid on client c; box[key] = (arrival, reply or error)."""
    try:
        r = c.wait_reply(rid, timeout=timeout)
    except gearsim.GearsimError as e:
        r = e
    box[key] = (time.monotonic(), r)


def during(name, d, cmd, args):
    """Client A sends cmd (a long request); once it has been sent, client B
    sends status, state, hello and unload. Checks their order."""
    box = {}
    with d.client(timeout=900.0) as a, d.client(timeout=900.0) as b:
        rid = a.send(cmd, args)
        wa = threading.Thread(target=stamped, args=(a, rid, box, "long"))
        wa.start()
        time.sleep(0.5)  # the long request is under way (it takes seconds)
        ids = {k: b.send(k) for k in ("status", "state", "hello")}
        uid = b.send("unload")
        for k, i in ids.items():
            stamped(b, i, box, k)
        stamped(b, uid, box, "unload")
        wa.join()
    t_long, r_long = box["long"]
    R.check(f"{name}: the long request succeeded", not isinstance(r_long, Exception), r_long)
    for k in ("status", "state", "hello"):
        t, r = box[k]
        R.check(f"{name}: {k} answered", not isinstance(r, Exception), r)
        R.check(f"{name}: {k} answered before the long request ended", t < t_long,
                f"{k} at {t:.3f}, the long request at {t_long:.3f}")
    t_u, r_u = box["unload"]
    R.check(f"{name}: unload waited for the long request, then ran (not refused)",
            not isinstance(r_u, Exception) and t_u >= t_long, f"{r_u}; unload at {t_u:.3f}, long at {t_long:.3f}")
    with d.client(timeout=60.0) as c:
        R.check(f"{name}: the unload came after (nothing loaded now)", c.status().get("state") == "empty")


def stiffness_case():
    with dmod.Daemon(ranks=1) as d:
        with d.client(timeout=120.0) as c:
            c.load(builtin="elastic_pair")
        during("stiffness wait:true, refine 1", d, "stiffness",
               {"mesh": "pinion-wheel", "refine": 1, "positions": 8, "wait": True})


def load_case():
    sc = dmod.load_scene("elastic_spin")
    body = next(b for b in sc["bodies"] if b.get("model") == "elastic")
    body["mesh"] = {"flank": 48, "across": 1}
    with dmod.Daemon(ranks=2) as d:
        with d.client(timeout=120.0) as c:
            c.load(builtin="pair")  # `state` has a scene to report meanwhile
        during("load of a fine elastic gear at -n 2", d, "load", {"scene": sc})


def main():
    R.guard("stiffness case", stiffness_case)
    R.guard("load case", load_case)
    R.finish()


if __name__ == "__main__":
    main()
