#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""When a rank dies, clients are told (docs/RELIABILITY.md, "When a rank
dies").

At -n 2 and -n 3: SIGKILL of one non-zero rank while a Python client
waits on an `advance` (elastic bodies on every rank: rank 0 is in the
step's collectives with the dead rank) and, on another daemon, while a
client waits on a `sweep`. Each waiting client must get a GearsimError
naming the cause ("rank N ... died" or "the daemon stopped") within 10 s
of the kill; `status` asked during the sweep after the kill never reports
the sweep as healthy (it is an error, or no answer because the daemon is
gone); a client connecting afterwards is told the daemon stopped; the C
client and gearctl, each running an elastic scene, exit with the cause
within 10 s."""
import os
import signal
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_rank_death: clients learn when a rank dies")
LIMIT_S = 10.0


def rank_pids(d):
    """The pid of rank 0 and those of the other ranks."""
    pids = d.gearsimd_pids()
    return (pids[0], pids[1:]) if pids else (None, [])


def waiter(c, start, box):
    try:
        box["result"] = start()
    except gearsim.GearsimError as e:
        box["error"] = e
    box["t"] = time.monotonic()


def case(n, kind):
    name = f"-n {n} {kind}"
    with dmod.Daemon(ranks=n) as d:
        c = d.client()
        c.subscribe()
        box = {}
        if kind == "advance":
            c.request("load", {"builtin": "elastic_pair"})
            rid = c.send("advance", {"steps": 10_000_000})
            c.wait_reply(rid)
            start = lambda: c.wait_done(rid, timeout=120)  # noqa: E731
        else:
            scene = dmod.load_scene("pair")
            rid = c.send("sweep", {"scene": scene, "path": "sw", "settle": 50.0, "measure": 50.0,
                                   "parameters": [{"path": "loads[0].moment", "values": [1, 2, 3, 4, 5, 6]}]})
            c.wait_reply(rid)
            start = lambda: c.wait_done(rid, timeout=120)  # noqa: E731
        th = threading.Thread(target=waiter, args=(c, start, box), daemon=True)
        th.start()
        time.sleep(2.0)
        r0, others = rank_pids(d)
        if not R.check(f"{name}: the ranks are found", len(others) == n - 1, others):
            return
        victim = others[-1]
        t_kill = time.monotonic()
        os.kill(victim, signal.SIGKILL)
        healthy = []
        if kind == "sweep":
            # status from another client right after the kill: never a healthy sweep
            with gearsim.Client(d.conn_file, timeout=1.0, retries=0) as c2:
                for _ in range(8):
                    try:
                        st = c2.status()
                        if st.get("sweep") and not st.get("error") and time.monotonic() - t_kill > 0.5:
                            healthy.append(st["sweep"])
                    except gearsim.GearsimError:
                        break
                    time.sleep(0.25)
        th.join(LIMIT_S + 5)
        err = box.get("error")
        dt = (box.get("t") or time.monotonic()) - t_kill
        R.check(f"{name}: the waiting client gets an error within {LIMIT_S:g} s", err is not None and dt <= LIMIT_S,
                f"after {dt:.1f} s: {box}")
        if err is not None:
            R.note(f"{name}: {dt:.2f} s: {err.code}: {err.message[:160]}")
            R.check(f"{name}: the error names the cause", err.code in ("rank_lost", "daemon_stopped")
                    and ("rank" in err.message or "stopped" in err.message), repr(err))
        if kind == "sweep":
            R.check(f"{name}: status never reports the sweep healthy after the rank died", not healthy, healthy)
        t0 = time.monotonic()
        while d.alive() and time.monotonic() - t0 < 15:
            time.sleep(0.2)
        try:
            gearsim.Client(d.conn_file, timeout=2.0, retries=0).status()
            R.check(f"{name}: a new client is told the daemon stopped", False, "answered")
        except gearsim.GearsimError as e:
            R.check(f"{name}: a new client is told the daemon stopped",
                    e.code in ("daemon_stopped", "not_found", "timeout"), repr(e))


def cli_case(n, kind):
    """The C client or gearctl running an elastic scene: it must exit with
    the cause within the limit."""
    name = f"-n {n} {kind}"
    with dmod.Daemon(ranks=n) as d:
        if kind == "c client":
            exe = os.path.join(dmod.BUILD_ROOT, "clients", "c", "gearsim-client-c")
            cmd = [exe, "--connection-file", d.conn_file, "builtin:elastic_pair", "--until", "100"]
        else:
            cmd = [sys.executable, os.path.join(dmod.SOURCE_ROOT, "clients", "python", "gearctl"),
                   "--connection-file", d.conn_file, "run", "builtin:elastic_pair", "--until", "100"]
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60:
            st = d.client().status()
            if st.get("advance"):
                break
            time.sleep(0.3)
        r0, others = rank_pids(d)
        if not R.check(f"{name}: the ranks are found", len(others) == n - 1, others):
            p.kill()
            return
        t_kill = time.monotonic()
        os.kill(others[-1], signal.SIGKILL)
        try:
            out, err = p.communicate(timeout=LIMIT_S + 5)
        except subprocess.TimeoutExpired:
            p.kill()
            out, err = p.communicate()
        dt = time.monotonic() - t_kill
        text = out[-300:] + err[-600:]
        R.note(f"{name}: exit {p.returncode} after {dt:.2f} s: {err.strip().splitlines()[-1:] if err.strip() else ''}")
        R.check(f"{name}: exits with the cause within {LIMIT_S:g} s",
                p.returncode not in (0, None) and dt <= LIMIT_S and ("stopped" in text or "rank" in text), text)


def main():
    for n in (2, 3):
        for kind in ("c client", "gearctl"):
            try:
                cli_case(n, kind)
            except Exception as e:  # noqa: BLE001
                R.check(f"-n {n} {kind}", False, f"{type(e).__name__}: {e}")
        for kind in ("advance", "sweep"):
            try:
                case(n, kind)
            except Exception as e:  # noqa: BLE001
                R.check(f"-n {n} {kind}", False, f"{type(e).__name__}: {e}")
    R.finish()


if __name__ == "__main__":
    main()
