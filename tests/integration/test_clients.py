#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Clients against the real daemon.

* the C client (gearsim-client-c) runs a scene and prints one line per
  telemetry event, matching what the Python client receives for the same run;
* idempotent retry: the same request id sent twice gets the identical reply
  and the command runs once (an advance's steps are counted once); the same
  id from another client is a different request;
* several DEALER clients, and pipelined requests on one DEALER, in flight at once;
  Python clients in threads during an advance."""
import json
import os
import re
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import zmq  # noqa: E402

import daemon as dmod  # noqa: E402
from harness import Probe, RawDealer, Results, apply_curve  # noqa: E402

R = Results("test_clients: C client, idempotent retries, concurrent clients")
UNTIL = 0.01


def c_client_path():
    return os.path.join(dmod.BUILD_ROOT, "clients", "c", "gearsim-client-c")


LINE = re.compile(r"^t=(\S+) E=(\S+)((?: \S+=\S+)*)$")


def parse_lines(text):
    out = []
    for line in text.splitlines():
        m = LINE.match(line)
        if not m:
            continue
        rpm = dict(kv.split("=", 1) for kv in m.group(3).split())
        out.append((float(m.group(1)), float(m.group(2)), {k: float(v) for k, v in rpm.items()}))
    return out


def close(a, b, rel=1e-9):
    return abs(a - b) <= rel * max(abs(a), abs(b), 1e-300)


def reset(c):
    """Unload whatever is loaded (cancelling a run first)."""
    st = c.status().get("state")
    if st in ("running", "paused"):
        c.cancel()
        while c.status().get("state") in ("running", "paused"):
            time.sleep(0.05)
    if c.status().get("state") != "empty":
        c.unload()


def c_client(d):
    exe = c_client_path()
    if not os.access(exe, os.X_OK):
        R.check("gearsim-client-c is built", False, exe)
        return
    r = subprocess.run([exe, "--connection-file", d.conn_file, "builtin:pair", "--until", str(UNTIL)],
                       capture_output=True, text=True, timeout=300)
    R.check("C client: exit status 0", r.returncode == 0, r.stderr[-2000:])
    lines = parse_lines(r.stdout)
    every = dmod.load_scene("pair")["outputs"]["telemetry_every"]
    dt = dmod.load_scene("pair")["numerics"]["time_step"]
    expect = int(round(UNTIL / dt)) // every
    R.check(f"C client: one line per telemetry event ({len(lines)}, expected {expect})", len(lines) == expect,
            r.stdout[:500])
    R.note("C client output: " + (r.stdout.splitlines()[-1] if r.stdout else "(none)"))
    # the same run through the Python client
    with d.client() as c:
        reset(c)
        c.load(builtin="pair")
        tel = []
        c.advance(time=UNTIL, on_telemetry=tel.append)
    ref = [(ev["time"], ev["energy"]["total"], {b["name"]: b["rpm"] for b in ev["bodies"]}) for ev in tel]
    same = len(ref) == len(lines) and all(
        close(a[0], b[0]) and close(a[1], b[1]) and a[2].keys() == b[2].keys() and
        all(close(a[2][k], b[2][k]) for k in a[2]) for a, b in zip(lines, ref))
    R.check("C client: time, total energy and rpm agree with the Python client's telemetry (10 digits)", same,
            f"{lines[:2]} vs {ref[:2]}")
    bad = os.path.join(d.dir, "bad_scene.json")
    s = dmod.load_scene("pair")
    s["bodies"][0]["teeth"] = -4
    with open(bad, "w") as f:
        json.dump(s, f)
    r = subprocess.run([exe, "--connection-file", d.conn_file, bad, "--until", "0.001"],
                       capture_output=True, text=True, timeout=60)
    R.check("C client: a bad scene exits non-zero with the error", r.returncode != 0 and "error" in r.stderr
            and "teeth" in r.stderr, (r.returncode, r.stderr))
    r = subprocess.run([exe, "--connection-file", os.path.join(d.dir, "nope.json"), "builtin:pair", "--until", "1"],
                       capture_output=True, text=True, timeout=60)
    R.check("C client: a missing connection file exits non-zero", r.returncode != 0 and r.stderr, r.stderr)


def idempotent(d):
    with d.client() as c:
        reset(c)
        c.load(builtin="pair")
    probe = Probe(d.conn_file, prefix="idem")
    frame = json.dumps({"v": 1, "id": "retry-1", "cmd": "advance", "args": {"steps": 500}}).encode()
    probe.send(None, rid="retry-1", raw=frame)
    first = probe.wait("retry-1")
    probe.replies["retry-1"] = None
    probe.send(None, rid="retry-1", raw=frame)          # the retry: same identity, same id
    second = probe.wait("retry-1")
    R.check("retry: first reply ok", first[1] and first[1].get("ok") is True, first[1])
    R.check("retry: identical reply bytes", first[0] == second[0], (first[0], second[0]))
    probe.wait_event(lambda e: e.get("type") == "done" and e.get("parent_id") == "retry-1", 120)
    # a retry after the run finished is still answered from the cache
    probe.replies["retry-1"] = None
    probe.send(None, rid="retry-1", raw=frame)
    third = probe.wait("retry-1")
    R.check("retry after done: identical reply", third[0] == first[0], third[0])
    probe.pump(1.2)
    st = probe.call("status")
    R.check("retry: the advance ran once (step 500)", st["result"]["step"] == 500, st["result"])
    dones = [p for _, p, _ in probe.events if p and p.get("type") == "done" and p.get("parent_id") == "retry-1"]
    R.check("retry: one done event", len(dones) == 1, len(dones))
    # the same id from another client identity is another request
    other = RawDealer(d.conn_file)
    other.send_json({"v": 1, "id": "retry-1", "cmd": "status"})
    frames, rep = other.recv(10)
    R.check("same id from another client: its own reply", rep and rep.get("ok") and "state" in rep.get("result", {}),
            rep)
    other.close()
    # set_load retried: applied once, the same reply
    frame = json.dumps({"v": 1, "id": "retry-2", "cmd": "set_load",
                        "args": {"load": {"name": "x", "body": "wheel", "type": "brake", "coefficient": 0.01}}}).encode()
    probe.send(None, rid="retry-2", raw=frame)
    a = probe.wait("retry-2")
    probe.replies["retry-2"] = None
    probe.send(None, rid="retry-2", raw=frame)
    b = probe.wait("retry-2")
    R.check("retried set_load: identical reply", a[0] == b[0], (a[0], b[0]))
    probe.close()
    # the Python client's own retry path: a tiny timeout forces resends of the same id
    with d.client(timeout=0.002, retries=200) as c:
        before = c.status()["step"]
        res = c.request("advance", {"steps": 100})
        R.check("Client retries with the same id: advance accepted", res.get("accepted") is True, res)
    with d.client() as c:
        deadline = time.monotonic() + 60
        while c.status().get("state") == "running" and time.monotonic() < deadline:
            time.sleep(0.05)
        after = c.status()["step"]
    R.check(f"Client retries: 100 steps counted once ({before} -> {after})", after - before == 100, (before, after))


def concurrent(d):
    with d.client() as c:
        reset(c)
        c.load(builtin="planetary")
    ctx = zmq.Context.instance()
    socks = []
    for i in range(6):
        s = ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        apply_curve(s, d.connection)
        s.connect(d.connection["command"])
        socks.append(s)
    sent = {}
    cmds = ["status", "hello", "state", "jobs"]
    for k in range(10):
        for i, s in enumerate(socks):
            rid = f"s{i}-{k}"
            cmd = cmds[(i + k) % len(cmds)]
            s.send(json.dumps({"v": 1, "id": rid, "cmd": cmd}).encode())
            sent[rid] = (i, cmd)
    got, wrong = {}, []
    poller = zmq.Poller()
    for s in socks:
        poller.register(s, zmq.POLLIN)
    deadline = time.monotonic() + 30
    while len(got) < len(sent) and time.monotonic() < deadline:
        for s, _ in poller.poll(500):
            rep = json.loads(s.recv())
            i = socks.index(s)
            rid = rep.get("id")
            if rid not in sent or sent[rid][0] != i:
                wrong.append((i, rid))
            got[rid] = rep
    R.check(f"{len(socks)} DEALER clients x 10 pipelined requests: all {len(sent)} answered",
            len(got) == len(sent), len(got))
    R.check("each reply went to the client that asked, with its id", not wrong, wrong[:5])
    R.check("all replies ok", all(r.get("ok") for r in got.values()),
            [r for r in got.values() if not r.get("ok")][:3])
    for s in socks:
        s.close(0)

    # Python clients in threads while an advance runs
    with d.client() as c:
        c.advance(steps=100000, wait=False)
    errors, counts = [], []

    def worker(n):
        try:
            with d.client(timeout=10) as c:
                k = 0
                for _ in range(n):
                    c.status()
                    c.state()
                    k += 2
                counts.append(k)
        except Exception as e:  # noqa: BLE001
            errors.append(repr(e))
    threads = [threading.Thread(target=worker, args=(20,)) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    R.check("4 threads x 40 requests during an advance: all answered", sum(counts) == 160 and not errors,
            (counts, errors))
    with d.client() as c:
        if c.status().get("state") in ("running", "paused"):
            c.cancel()


def main():
    with dmod.Daemon(ranks=2) as d:
        R.guard("C client", c_client, d)
        R.guard("idempotent retries", idempotent, d)
        R.guard("concurrent clients", concurrent, d)


R.guard("clients against the real daemon", main)
R.finish()
