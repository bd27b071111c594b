#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Telemetry batches (docs/reference/protocol.md, "Telemetry batches"): the
daemon sends the telemetry events of consecutive steps in one message on
the topic `batch`, and still one event per message on `telemetry` while
someone subscribes to that.

Three subscribers read the same run of the rigid planetary train, telemetry
every step: a raw subscriber to `telemetry` (the single-event form), a raw
subscriber to `batch`, and the Python client (which unpacks batches). The
checks would fail if batching lost, reordered, duplicated or altered an
event:

* the batches' events, written out, are the single events' texts byte for
  byte, in the same order: the inside of every batch is a run of consecutive
  single-event texts joined by commas, and the runs cover them all once;
* every event arrives: seq one apart, steps one apart, as many as steps;
* events travel many per message (fewer batch messages than half the
  events) and no batch holds more than 64;
* the Python client yields the same events, one at a time, in order;
* the C client (gsc_next_event) prints one line per telemetry event;
* the connection file and `hello` announce the batches."""
import json
import os
import re
import subprocess
import sys
import threading
import time

import zmq

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results, apply_curve  # noqa: E402

R = Results("test_telemetry_batch: telemetry in batches and one event per message")
STEPS = 3000


class Reader(threading.Thread):
    """A raw subscriber to `topic` that keeps every message's frames."""

    def __init__(self, ctx, info, topic):
        super().__init__(daemon=True)
        self.sock = ctx.socket(zmq.SUB)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.setsockopt(zmq.RCVHWM, 1000000)
        self.sock.setsockopt(zmq.SUBSCRIBE, topic.encode())
        self.sock.setsockopt(zmq.SUBSCRIBE, b"heartbeat")
        apply_curve(self.sock, info)
        self.sock.connect(info["telemetry"])
        self.msgs = []
        self.stop = False
        self.ready = threading.Event()

    def run(self):
        while not self.stop:
            if self.sock.poll(100):
                f = self.sock.recv_multipart()
                if f[0] == b"heartbeat":
                    self.ready.set()
                else:
                    self.msgs.append(f)
        self.sock.close(linger=0)


def inner(body):
    """The events' text inside a batch message: between `"events":[` and `]}`."""
    head = body.index(b'"events":[') + len(b'"events":[')
    return body[head:-2] if body.endswith(b"]}") else None


def same_texts(singles, batches):
    """(ok, detail): the batches' insides are consecutive runs of the single
    texts joined by ',', covering each once and in order."""
    i = 0
    for k, body in enumerate(batches):
        part = inner(body)
        if part is None:
            return False, f"batch {k} does not end with ]}}"
        n = part.count(b'{"v":1,"type":"telemetry",')
        if part != b",".join(singles[i:i + n]):
            return False, f"batch {k} (events {i}..{i + n}) differs from the single messages"
        i += n
    return i == len(singles), f"{i} events in batches, {len(singles)} single"


def run():
    scene = dmod.load_scene("planetary")
    scene["outputs"] = {"telemetry_every": 1}
    ctx = zmq.Context.instance()
    with dmod.Daemon(ranks=1) as d:
        info = d.connection
        R.check("connection file announces telemetry_batch", info.get("telemetry_batch") is True, info)
        with d.client() as c:
            R.check("hello lists the capability telemetry_batch",
                    "telemetry_batch" in c.request("hello").get("capabilities", []))
            c.load(scene=scene)

            c.advance(steps=10, timeout=300)
            single = Reader(ctx, info, "telemetry")
            batch = Reader(ctx, info, "batch")
            single.start(), batch.start()
            R.check("raw subscribers see a heartbeat", single.ready.wait(20) and batch.ready.wait(20))
            got, alls = [], []
            t0 = time.monotonic()
            c.advance(steps=STEPS, on_telemetry=got.append, on_event=alls.append, timeout=900)
            time.sleep(1.0)
            single.stop = batch.stop = True
            single.join(), batch.join()
            R.note(f"{STEPS} steps with three subscribers in {time.monotonic() - t0:.1f} s")

            texts = [f[1] for f in single.msgs if f[0] == b"telemetry"]
            bodies = [f[1] for f in batch.msgs if f[0] == b"batch"]
            R.check(f"single-event subscriber: {STEPS} telemetry messages", len(texts) == STEPS, len(texts))
            evs = [json.loads(t) for t in texts]
            R.check("single events: seq increasing, step one apart",
                    all(b["seq"] > a["seq"] and b["step"] == a["step"] + 1 for a, b in zip(evs, evs[1:])),
                    [(e["seq"], e["step"]) for e in evs[:4]])
            ok, detail = same_texts(texts, bodies)
            R.check("batches carry the single events' texts byte for byte, in order, each once", ok, detail)
            sizes = [len(json.loads(b)["events"]) for b in bodies]
            R.check(f"batched: {len(bodies)} messages for {sum(sizes)} events (fewer than half), at most 64 each",
                    0 < len(bodies) < STEPS / 2 and max(sizes) <= 64, sizes[:20])
            R.check(f"Python client: {STEPS} telemetry events, the same as the single messages, in order",
                    got == evs, f"{len(got)} events; first {[e.get('seq') for e in got[:3]]}")
            seqs = [e["seq"] for e in alls]
            R.check("Python client: every event's seq one apart (telemetry, progress, done)",
                    all(b == a + 1 for a, b in zip(seqs, seqs[1:])) and c.gaps == 0, (seqs[:5], c.gaps))


            # The C client: one printed line per telemetry event.
            exe = os.path.join(dmod.BUILD_ROOT, "clients", "c", "gearsim-client-c")
            if os.access(exe, os.X_OK):
                c.unload()
                pair = dmod.load_scene("pair")
                pair["outputs"] = {"telemetry_every": 2}
                path = d.path("pair_every2.json")
                with open(path, "w") as f:
                    json.dump(pair, f)
                r = subprocess.run([exe, "--connection-file", d.conn_file, path, "--until", "0.01"],
                                   capture_output=True, text=True, timeout=300)
                lines = [ln for ln in r.stdout.splitlines() if ln.startswith("t=")]
                m = re.search(r"done: (\d+) steps", r.stderr)
                n = int(m.group(1)) // 2 if m else -1
                R.check(f"C client: exit 0 and one line per telemetry event ({n})",
                        r.returncode == 0 and n > 100 and len(lines) == n and "dropped" not in r.stderr,
                        (r.returncode, len(lines), r.stderr[-600:]))
            else:
                R.check("gearsim-client-c is built", False, exe)


R.guard("telemetry batches", run)
R.finish()
