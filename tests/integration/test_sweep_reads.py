#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Reads during a sweep (docs/RELIABILITY.md, "Longest silence"): while
rank 0 steps a sweep point it answers `status`, `state` and `jobs` between
its steps, and every such reply must describe a consistent sweep: the
counts never go back, points_done never exceeds points, the fraction stays
in [0, 1] and never decreases, and `state` keeps describing the loaded
scene (a sweep point runs on its own engine). The table written by the
polled sweep must be the table of the same sweep run without polling.

At -n 1 rank 0 computes every point; at -n 2 it computes points of its
own group besides dispatching the other's. Checked is an order of replies
and their content, never a duration."""
import os
import sys
import threading

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_sweep_reads: status, state and jobs during sweep points are consistent")
POINTS = 12
# Points of a few thousand steps each: several slices per point, so the
# readers run between a point's steps as well as between points.
SPEC = {"builtin": "pair", "parameters": [{"path": "driver_rpm", "from": 500, "to": 3000, "points": POINTS}],
        "settle": 0.0, "measure": 0.03, "time_step": 1e-5}


def run(c, path, groups):
    rid = c.send("sweep", dict(SPEC, path=path, groups=groups))
    c.wait_reply(rid, timeout=120)
    return c.wait_done(rid, timeout=900)


def reader(d, stop, out):
    """status, state and jobs back to back until stop; every reply kept."""
    with d.client(timeout=300.0) as c:
        while not stop.is_set():
            for cmd in ("status", "state", "jobs"):
                try:
                    out.append((cmd, c.request(cmd, timeout=300.0)))
                except gearsim.GearsimError as e:
                    out.append((cmd, e))


def check_replies(label, replies, scene_bodies):
    sweeps = []
    for cmd, r in replies:
        if isinstance(r, Exception):
            R.check(f"{label}: {cmd} answered", False, r)
            return
        if cmd == "status":
            sweeps.append(r.get("sweep"))
        elif cmd == "state":
            names = [b.get("name") for b in r.get("bodies", [])]
            if names != scene_bodies or r.get("step") != 0:
                R.check(f"{label}: state describes the loaded scene, untouched", False,
                        f"bodies {names}, step {r.get('step')}")
                return
        elif cmd == "jobs" and not isinstance(r.get("jobs"), list):
            R.check(f"{label}: jobs is a list", False, r)
            return
    live = [w for w in sweeps if w]
    R.check(f"{label}: status saw the sweep under way ({len(live)} of {len(sweeps)} replies)", len(live) >= 1,
            f"{len(live)} replies with a sweep")
    bad = []
    prev_done, prev_frac = -1, -1.0
    for w in live:
        k, n, f = w.get("points_done"), w.get("points"), w.get("fraction")
        if n != POINTS or not isinstance(k, int) or not 0 <= k <= n or not isinstance(f, (int, float)) \
                or not 0.0 <= f <= 1.0 or k < prev_done or f < prev_frac or k > round(f * POINTS):
            bad.append(w)
        prev_done, prev_frac = max(prev_done, k if isinstance(k, int) else -1), \
            max(prev_frac, f if isinstance(f, (int, float)) else -1.0)
    R.check(f"{label}: every sweep status consistent (counts monotone, done <= points <= total)", not bad,
            bad[:3])
    R.check(f"{label}: status saw points finish while it polled", prev_done > 0 and
            any(w.get("points_done") < POINTS for w in live), f"last done {prev_done}")


def case(ranks):
    label = f"-n {ranks}"
    with dmod.Daemon(ranks=ranks) as d:
        with d.client(timeout=120.0) as c:
            c.load(builtin="pair")
            bodies = [b.get("name") for b in c.request("state")["bodies"]]
            groups = ranks
            ref = run(c, "quiet", groups)
            R.check(f"{label}: the sweep without readers finished", ref.get("points_done") == POINTS, ref)
            stop, out = threading.Event(), []
            th = threading.Thread(target=reader, args=(d, stop, out))
            th.start()
            try:
                done = run(c, "polled", groups)
            finally:
                stop.set()
                th.join()
            R.check(f"{label}: the polled sweep finished", done.get("points_done") == POINTS, done)
            check_replies(label, out, bodies)
            with open(d.path("quiet.csv")) as f:
                quiet = f.read()
            with open(d.path("polled.csv")) as f:
                polled = f.read()
            R.check(f"{label}: the polled sweep's table is the table without readers", polled == quiet and
                    len(quiet.splitlines()) == POINTS + 1, f"{len(polled)} vs {len(quiet)} bytes")


def main():
    R.guard("-n 1", case, 1)
    R.guard("-n 2", case, 2)
    R.finish()


if __name__ == "__main__":
    main()
