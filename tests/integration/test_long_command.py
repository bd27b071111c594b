#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Long commands and completion without PUB.

`stiffness` runs in chunks like `advance`: the reply is an accepted one at
once, `status` is answered while it runs (showing its progress), progress
events come, cancel ends it with a cancelled done event, and a full run's
done event carries the same result as the synchronous form (wait: true).
A client whose subscriber never receives anything (its SUB socket replaced
by one connected nowhere) still learns the completion of an advance and of
a stiffness analysis, from status's `finished` list."""
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import zmq  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_long_command: chunked stiffness, status and cancel meanwhile, completion without PUB")
MESH = "pinion-wheel"


def run():
    with dmod.Daemon() as d, d.client(timeout=60) as c:
        c.load(builtin="elastic_pair")
        c.subscribe()
        # A long analysis: status and cancel while it runs.
        acc = c.stiffness(MESH, positions=720, refine=1, wait=False)
        R.check("stiffness is accepted at once (accepted, positions)",
                acc.get("accepted") is True and acc.get("positions") == 720, acc)
        seen = []
        for _ in range(5):
            st = c.status()
            seen.append(st.get("stiffness"))
            time.sleep(0.2)
        running = [x for x in seen if x and x.get("parent_id") == acc["id"]]
        R.check("status is answered while it runs and shows its progress",
                len(running) >= 3 and all(0 <= x["done"] < x["positions"] for x in running), seen)
        prog = []
        deadline = time.monotonic() + 60
        while not prog and time.monotonic() < deadline:
            ev = c.next_event(1.0)
            if ev and ev.get("type") == "progress" and ev.get("parent_id") == acc["id"]:
                prog.append(ev)
        R.check("progress events of the analysis arrive", prog and 0 < prog[0]["fraction"] < 1, prog[:1])
        try:
            c.load(builtin="pair")
            R.check("load is refused while the analysis runs", False)
        except Exception as e:  # noqa: BLE001
            R.check("load is refused while the analysis runs (wrong_state)",
                    getattr(e, "code", "") == "wrong_state", e)
        can = c.cancel()
        R.check("cancel answers cancelled: true", can.get("cancelled") is True, can)
        done = c.wait_done(acc["id"], timeout=60)
        R.check("done event: cancelled, kind stiffness",
                done.get("cancelled") is True and done.get("kind") == "stiffness", done)
        R.check("status after cancel: no analysis running", c.status().get("stiffness") is None)

        # A complete chunked run equals the synchronous one.
        res = c.stiffness(MESH, positions=6, timeout=300)
        sync = c.request("stiffness", {"mesh": MESH, "positions": 6, "wait": True}, timeout=300)
        R.check("chunked result: 6 points, same k as the synchronous form",
                res and len(res.get("points", [])) == 6 and res.get("k") == sync.get("k"),
                (res and res.get("k"), sync.get("k")))
        # nearfield (default true): false gives the plain FE contact, stiffer
        # (the correction adds the Hertz compliance the FE mesh misses).
        plain = c.stiffness(MESH, positions=6, nearfield=False, timeout=300)
        R.check("nearfield false: mean k above the default's (the correction softens)",
                plain and plain["k"]["mean"] > 1.001 * res["k"]["mean"], (plain and plain.get("k"), res.get("k")))
        try:
            c.request("stiffness", {"mesh": MESH, "positions": 2, "nearfield": 1, "wait": True}, timeout=60)
            R.check("nearfield 1 (not a boolean) is refused", False)
        except Exception as e:  # noqa: BLE001
            R.check("nearfield 1 (not a boolean) is refused naming args.nearfield",
                    getattr(e, "field", "") == "args.nearfield", e)

        # Lost subscriber: the SUB socket never receives anything.
        c._sub.close(linger=0)
        dead = c._ctx.socket(zmq.SUB)
        dead.setsockopt(zmq.SUBSCRIBE, b"")
        dead.connect("tcp://127.0.0.1:9")   # nothing listens there
        c._sub = dead
        c._events.clear()
        t0 = time.monotonic()
        ev = c.advance(steps=300, timeout=120)
        R.check("advance with a deaf subscriber: completion learned from status (from_status, steps 300)",
                ev.get("from_status") is True and ev.get("steps") == 300 and ev.get("kind") == "advance", ev)
        res = c.stiffness(MESH, positions=3, timeout=300)
        R.check("stiffness with a deaf subscriber: result learned from status",
                res is not None and len(res.get("points", [])) == 3, res)
        R.note(f"deaf-subscriber completions took {time.monotonic() - t0:.1f} s (status polled every 2 s)")

        # The C client without a subscriber at all: gsc_wait_done polls status.
        exe = os.path.join(dmod.BUILD_ROOT, "clients", "c", "gearsim-client-c")
        if os.access(exe, os.X_OK):
            c.unload()
            r = subprocess.run([exe, "--connection-file", d.conn_file, "--no-events", "builtin:pair",
                                "--until", "0.01"], capture_output=True, text=True, timeout=300)
            R.check("C client with no subscriber: exit 0, done learned (1000 steps)",
                    r.returncode == 0 and "done: 1000 steps" in r.stderr, (r.returncode, r.stderr[-1000:]))
        else:
            R.check("gearsim-client-c is built", False, exe)


R.guard("long command run", run)
R.finish()
