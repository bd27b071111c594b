#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The job queue over a daemon's life: 100 submits of short jobs (more than
the 64 queue slots) all run to done, finished jobs leave the list (bounded
count), and a job submitted while a client's scene is loaded says why it
waits, in the submit reply and in `jobs`, and starts once the scene is
unloaded."""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_job_queue: unlimited submits, waiting jobs say why")
TOTAL, BATCH = 100, 20


def wait_jobs(c, ids, timeout=120):
    """States of the jobs `ids` once none is queued or running."""
    deadline = time.monotonic() + timeout
    while True:
        listed = {j["job"]: j for j in c.jobs()["jobs"]}
        states = {i: listed[i]["state"] if i in listed else "gone" for i in ids}
        if all(s not in ("queued", "running") for s in states.values()) or time.monotonic() > deadline:
            return states, listed
        time.sleep(0.05)


def run():
    scene = dmod.load_scene("pair")
    with dmod.Daemon() as d, d.client(timeout=30) as c:
        done = 0
        max_listed = 0
        for b in range(TOTAL // BATCH):
            ids = [c.submit(scene, 0.002)["job"] for _ in range(BATCH)]
            states, listed = wait_jobs(c, ids)
            done += sum(s == "done" for s in states.values())
            max_listed = max(max_listed, len(listed))
            if any(s != "done" for s in states.values()):
                R.note(f"batch {b}: {states}")
        R.check(f"all {TOTAL} submitted jobs ran to done", done == TOTAL, done)
        keep = 32
        R.check(f"finished jobs are dropped from the list (at most {keep} listed, saw {max_listed})",
                max_listed <= keep, max_listed)

        # A client's scene blocks the queue; the job says so, then runs after unload.
        c.load(builtin="pair")
        sub = c.submit(scene, 0.002)
        w = sub.get("waiting") or ""
        R.check("submit while a scene is loaded: 'waiting' says a scene is loaded",
                "scene is loaded" in w, sub)
        time.sleep(0.5)
        j = {x["job"]: x for x in c.jobs()["jobs"]}[sub["job"]]
        R.check("jobs lists it queued, waiting for the unload",
                j["state"] == "queued" and "unload" in (j.get("waiting") or ""), j)
        c.unload()
        states, _ = wait_jobs(c, [sub["job"]], timeout=60)
        R.check("after unload the waiting job runs to done", states[sub["job"]] == "done", states)
        sub = c.submit(scene, 0.002)
        R.check("a submit with nothing ahead has waiting null", sub.get("waiting") is None, sub)


R.guard("job queue run", run)
R.finish()
