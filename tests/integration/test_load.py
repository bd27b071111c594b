#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Load: 50 command clients and 10 telemetry subscribers (one stalled: it
connects and never reads) while an advance runs.

* Every command is answered exactly once with its own id: none lost, none
  duplicated, none crossed to another client, each of the right kind.
* `status` replies during the load say "running": commands are answered
  between chunks, not after the advance.
* A stalled subscriber cannot stop the simulation: with it connected (its
  queue full), a fixed advance completes, its `done` arrives, and the
  subscribers that read see the sequence numbers go on.

Nothing here is timed against a bound: on a loaded 2-core machine latencies
and speeds scatter by tens of percent, so the figures (status latency while
stepping, the speed ratio with and without a stalled subscriber) are
measured by tests/bench/bench_service.py and published in
docs/RELIABILITY.md. Timeouts below only guard against hangs.

Readers are separate processes (spawned), so the Python GIL of the test does
not add to the command replies."""
import json
import multiprocessing as mp
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import zmq  # noqa: E402

import daemon as dmod  # noqa: E402
from harness import Results, apply_curve, stalled_sub  # noqa: E402

N_CLIENTS = 50
PER_CLIENT = 20          # requests per client (2 in flight at a time)
N_SUBS = 10              # 9 readers + 1 stalled
TELEMETRY_EVERY = 50
FIXED_STEPS = 20000     # an advance run with the stalled subscriber connected


def reader(info, ready, stop, out):
    """A subscriber that reads everything; reports (events, seq gaps)."""
    ctx = zmq.Context()
    s = ctx.socket(zmq.SUB)
    s.setsockopt(zmq.LINGER, 0)
    s.setsockopt(zmq.RCVHWM, 100000)
    s.setsockopt(zmq.SUBSCRIBE, b"")
    apply_curve(s, info)
    s.connect(info["telemetry"])
    n = gaps = 0
    last = None
    signalled = False
    while not stop.is_set():
        if not s.poll(100):
            continue
        frames = s.recv_multipart()
        try:
            ev = json.loads(frames[-1])
        except ValueError:
            continue
        n += 1
        seq = ev.get("seq")
        if last is not None and isinstance(seq, int) and seq > last + 1:
            gaps += seq - last - 1
        last = seq
        if not signalled and ev.get("type") == "heartbeat":
            ready.release()
            signalled = True
    out.put((n, gaps))
    s.close(0)
    ctx.term()


def pct(xs, p):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p * (len(xs) - 1))))]


def command_load(R, d, ctx, info):
    """50 DEALERs, 20 requests each, while a long advance runs."""
    socks = []
    for _ in range(N_CLIENTS):
        s = ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        apply_curve(s, info)
        s.connect(info["command"])
        socks.append(s)
    kinds = ["status", "status", "state", "hello", "jobs", "nope"]   # "nope": an unknown command
    sent = {}            # id -> (client, cmd, t_send)
    replies = {}         # id -> list of (client, reply, t_recv)
    next_req = [0] * N_CLIENTS
    inflight = [0] * N_CLIENTS
    poller = zmq.Poller()
    for s in socks:
        poller.register(s, zmq.POLLIN)
    index = {s: i for i, s in enumerate(socks)}
    deadline = time.monotonic() + 40
    while time.monotonic() < deadline:
        for i, s in enumerate(socks):
            while inflight[i] < 2 and next_req[i] < PER_CLIENT:
                k = next_req[i]
                cmd = kinds[(i + k) % len(kinds)]
                rid = f"c{i}-{k}"
                sent[rid] = (i, cmd, time.perf_counter())
                s.send(json.dumps({"v": 1, "id": rid, "cmd": cmd}).encode())
                next_req[i] += 1
                inflight[i] += 1
        if all(n == PER_CLIENT for n in next_req) and sum(inflight) == 0:
            break
        for s, _ in poller.poll(100):
            while s.poll(0):
                t = time.perf_counter()
                rep = json.loads(s.recv_multipart()[-1])
                i = index[s]
                replies.setdefault(rep.get("id"), []).append((i, rep, t))
                inflight[i] -= 1
    # anything late or duplicated?
    t_end = time.monotonic() + 1.0
    extra = 0
    while time.monotonic() < t_end:
        for s, _ in poller.poll(100):
            while s.poll(0):
                rep = json.loads(s.recv_multipart()[-1])
                replies.setdefault(rep.get("id"), []).append((index[s], rep, time.perf_counter()))
                extra += 1
    for s in socks:
        s.close(0)
    total = N_CLIENTS * PER_CLIENT
    lost = [r for r in sent if r not in replies]
    dup = [r for r, v in replies.items() if len(v) > 1]
    stray = [r for r in replies if r not in sent]
    crossed = [r for r, v in replies.items() if r in sent and any(c != sent[r][0] for c, _, _ in v)]
    R.check(f"{total} commands sent by {N_CLIENTS} clients", len(sent) == total, len(sent))
    R.check("every command answered (none lost)", not lost, lost[:10])
    R.check("no command answered twice", not dup and extra == 0, (dup[:10], extra))
    R.check("no reply with an unknown id or to the wrong client", not stray and not crossed, (stray[:5], crossed[:5]))
    bad = [r for r, v in replies.items() if r in sent and
           (v[0][1].get("ok") is not (sent[r][1] != "nope") or
            (sent[r][1] == "nope" and (v[0][1].get("error") or {}).get("code") != "unknown_command"))]
    R.check("each reply is the right kind (ok, or unknown_command for 'nope')", not bad, bad[:5])
    lat = [v[0][2] - sent[r][2] for r, v in replies.items()
           if r in sent and sent[r][1] == "status" and v[0][1].get("ok")
           and v[0][1]["result"].get("state") == "running"]
    all_lat = [v[0][2] - sent[r][2] for r, v in replies.items() if r in sent]
    R.check("most status replies came while stepping", len(lat) >= 0.8 * sum(1 for r in sent.values() if r[1] == "status"),
            len(lat))
    if lat:
        p50, p99 = statistics.median(lat), pct(lat, 0.99)
        R.note(f"status latency while stepping, {len(lat)} requests among {total} from {N_CLIENTS} clients "
               f"with {N_SUBS} subscribers (1 stalled): median {1e3 * p50:.2f} ms, p99 {1e3 * p99:.2f} ms, "
               f"max {1e3 * max(lat):.2f} ms; all commands: median {1e3 * statistics.median(all_lat):.2f} ms, "
               f"p99 {1e3 * pct(all_lat, 0.99):.2f} ms (informative only)")


def stalled_run(R, d, ctx, info, c):
    """A fixed advance with a stalled subscriber whose queue is full: it
    must complete, and a reading subscriber sees the events go on."""
    stalled = stalled_sub(ctx, info)
    probe = ctx.socket(zmq.SUB)
    probe.setsockopt(zmq.LINGER, 0)
    probe.setsockopt(zmq.RCVHWM, 100000)
    probe.setsockopt(zmq.SUBSCRIBE, b"")
    apply_curve(probe, info)
    probe.connect(info["telemetry"])
    try:
        c.advance(steps=FIXED_STEPS // 4, timeout=300)   # fills the stalled queue
        seen = []
        while probe.poll(0):
            probe.recv_multipart()
        done = c.advance(steps=FIXED_STEPS, timeout=300)
        t_end = time.monotonic() + 5
        while time.monotonic() < t_end and probe.poll(200):
            ev = json.loads(probe.recv_multipart()[-1])
            if isinstance(ev.get("seq"), int):
                seen.append(ev["seq"])
        R.check(f"a {FIXED_STEPS}-step advance completes with a stalled subscriber connected",
                done.get("steps") == FIXED_STEPS and done.get("cancelled") is not True, done)
        R.check("a reading subscriber saw the sequence go on meanwhile",
                len(seen) > 10 and seen == sorted(seen), seen[:20])
        R.note(f"stalled-subscriber run: {FIXED_STEPS} steps in {done.get('wall_seconds', 0):.2f} s wall "
               f"(informative only: the speed ratio is benchmarked)")
    finally:
        stalled.close(0)
        probe.close(0)


def main(R):
    t_start = time.monotonic()
    scene = dmod.load_scene("pair")
    scene.setdefault("outputs", {})["telemetry_every"] = TELEMETRY_EVERY
    with dmod.Daemon(ranks=1) as d:
        info = d.connection
        ctx = zmq.Context.instance()
        spawn = mp.get_context("spawn")
        stop = spawn.Event()
        ready = spawn.Semaphore(0)
        out = spawn.Queue()
        procs = [spawn.Process(target=reader, args=(info, ready, stop, out), daemon=True)
                 for _ in range(N_SUBS - 1)]
        for p in procs:
            p.start()
        for _ in procs:
            if not ready.acquire(timeout=30):
                raise RuntimeError("a reader saw no heartbeat")
        stalled = stalled_sub(ctx, info)
        with d.client(timeout=30.0, retries=0) as c:
            c.load(scene=scene)
            c.subscribe(topics=["done"])   # this client only waits for done events
            adv = c.advance(steps=10 ** 9, wait=False)
            time.sleep(0.5)   # the stalled subscriber's queue fills
            R.guard("50 clients while stepping", command_load, R, d, ctx, info)
            st = c.status()
            R.check("the advance was still running after the command load", st.get("state") == "running", st)
            c.cancel()
            stalled.close(0)
            done = c.wait_done(adv["id"], timeout=30)
            R.check("the long advance ended cancelled", done.get("cancelled") is True, done)
            stop.set()
            counts = [out.get(timeout=30) for _ in procs]
            for p in procs:
                p.join(timeout=10)
            R.note(f"readers: events received {[n for n, _ in counts]}, seq gaps {[g for _, g in counts]}")
            R.check("every reader got telemetry", all(n > 10 for n, _ in counts), counts)
            R.guard("a fixed advance with a stalled subscriber", stalled_run, R, d, ctx, info, c)
        R.check("daemon alive and serving", d.alive())
    took = time.monotonic() - t_start
    R.note(f"test_load took {took:.1f} s")


if __name__ == "__main__":
    R = Results("test_load: 50 clients and 10 subscribers (1 stalled) during an advance")
    R.guard("load test", main, R)
    R.finish()
