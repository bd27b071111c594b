#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The telemetry event, written straight to text (src/service/telemetry.c),
against the `state` reply, built as a JSON tree (gsi_state_json), at the same
step: the same members in the same order, every number the identical double
and every integer equal. Scenes: the rigid planetary train (planet shares),
the floating one (bearing offsets), a rattling pair (impacts) and the
elastic contact pair (contacts, rows, friction and contact work). Events
arrive in order, nothing lost (seq of all events one apart, telemetry steps
one period apart)."""
import json
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_telemetry_text: the telemetry event's text against the state reply")
ENVELOPE = {"v", "type", "seq", "session", "step", "time", "parent_id"}


def same(a, b, path, bad):
    """Structure, order and bit-identical numbers; first differences in bad."""
    if isinstance(a, dict) and isinstance(b, dict):
        if list(a) != list(b):
            bad.append(f"{path}: keys {list(a)} vs {list(b)}")
            return
        for k in a:
            same(a[k], b[k], f"{path}.{k}", bad)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            bad.append(f"{path}: {len(a)} vs {len(b)} items")
            return
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{path}[{i}]", bad)
    elif isinstance(a, float) and isinstance(b, float):
        if struct.pack("<d", a) != struct.pack("<d", b):
            bad.append(f"{path}: {a!r} vs {b!r}")
    elif type(a) is not type(b) or a != b:
        bad.append(f"{path}: {a!r} ({type(a).__name__}) vs {b!r} ({type(b).__name__})")


def run(name, steps, every):
    scene = dmod.load_scene(name)
    scene.setdefault("outputs", {})["telemetry_every"] = every
    with dmod.Daemon(ranks=1) as d:
        with d.client() as c:
            c.load(scene=scene)
            evs, alls = [], []
            c.advance(steps=steps, on_telemetry=evs.append, on_event=alls.append, timeout=600)
            st = c.state()
    R.check(f"{name}: {steps // every} telemetry events", len(evs) == steps // every, f"{len(evs)}")
    if not evs:
        return
    seqs = [e["seq"] for e in alls]
    stepn = [e["step"] for e in evs]
    R.check(f"{name}: events' seq one apart, telemetry steps one period apart, in order",
            all(b - a == 1 for a, b in zip(seqs, seqs[1:])) and
            all(b - a == every for a, b in zip(stepn, stepn[1:])), f"{seqs[:5]} {stepn[:5]}")
    last = evs[-1]
    body = {k: v for k, v in last.items() if k not in ENVELOPE}
    ref = {k: v for k, v in st.items() if k in body or k in ("energy", "bodies", "meshes", "planets")}
    bad = []
    same(body, ref, name, bad)
    R.check(f"{name}: last event (step {last['step']}) equals the state reply bit for bit", not bad,
            "; ".join(bad[:4]))
    R.check(f"{name}: the event's keys in the tree's order", list(last)[:6] ==
            ["v", "type", "seq", "session", "step", "time"] and last.get("parent_id"), f"{list(last)}")


def main():
    run("planetary", 400, 10)
    run("planetary_floating", 200, 10)
    run("rattle", 200, 10)
    run("contact_drive", 20, 5)
    R.finish()


if __name__ == "__main__":
    main()
