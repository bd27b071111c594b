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


def during(name, d, cmd, args, before=None):
    """Client A sends cmd (a long request); once it has been sent, client B
    sends status, state, hello and unload. Checks their order. `before`:
    the `state` reply before the request (a `load` being built: `state`
    meanwhile describes that scene, unchanged)."""
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
    if before is not None and not isinstance(box["state"][1], Exception):
        r = box["state"][1]
        R.check(f"{name}: state meanwhile describes the previous scene, unchanged",
                [x.get("name") for x in r.get("bodies", [])] == [x.get("name") for x in before["bodies"]]
                and r.get("step") == before.get("step") and r.get("time") == before.get("time"),
                f"{r.get('bodies')} at step {r.get('step')}")
        st = box["status"][1]
        R.check(f"{name}: status meanwhile names the previous scene",
                not isinstance(st, Exception) and st.get("scene") == before.get("scene_name"), st)
    t_u, r_u = box["unload"]
    # Its order is shown by what it did, not by the stamps (two threads
    # stamp two replies sent back to back: on a busy machine either may
    # stamp first): had it run during the long request, the scene loaded
    # by a `load` would still be there below, and a `stiffness` would have
    # lost its scene midway (an error instead of its result).
    R.check(f"{name}: unload waited for the long request, then ran (not refused)",
            not isinstance(r_u, Exception), f"{r_u}; unload at {t_u:.3f}, long at {t_long:.3f}")
    with d.client(timeout=60.0) as c:
        R.check(f"{name}: the unload came after (nothing loaded now)", c.status().get("state") == "empty")


def stiffness_case():
    with dmod.Daemon(ranks=1) as d:
        with d.client(timeout=120.0) as c:
            c.load(builtin="elastic_pair")
        during("stiffness wait:true, refine 1", d, "stiffness",
               {"mesh": "pinion-wheel", "refine": 1, "positions": 8, "wait": True})


def load_case(ranks):
    """At -n 1 the body is built on a worker thread beside the service (it
    makes no MPI call); at -n 2 on rank 1 while rank 0 waits for it."""
    sc = dmod.load_scene("elastic_spin")
    body = next(b for b in sc["bodies"] if b.get("model") == "elastic")
    body["mesh"] = {"flank": 48, "across": 1}
    with dmod.Daemon(ranks=ranks) as d:
        with d.client(timeout=120.0) as c:
            c.load(builtin="pair")  # `state` has a scene to report meanwhile
            before = c.request("state")
            before["scene_name"] = c.status().get("scene")
        during(f"load of a fine elastic gear at -n {ranks}", d, "load", {"scene": sc}, before)


def main():
    R.guard("stiffness case", stiffness_case)
    R.guard("load case -n 1", load_case, 1)
    R.guard("load case -n 2", load_case, 2)
    R.finish()


if __name__ == "__main__":
    main()
