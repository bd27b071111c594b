#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Contact meshes on moving members through the daemon
(docs/explanation/planetary.md, "Contact meshes on moving members"):
the elastic planetary train (planetary_contact, linear triangles) with its
sun floating (a bearing joint of zero stiffness) and a 10 um tangential pin
error on planet1 runs with its balance at round-off, the sun's centre moves,
and the telemetry and final state are identical bit for bit at 1, 2 and 3
ranks (the translations are unknowns of rank 0's contact step, broadcast
with the rest of its solution)."""
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results, check_same_at_ranks, ranks_run  # noqa: E402

R = Results("test_floating_contact: floating sun with contact meshes at 1, 2 and 3 ranks")


def scene():
    sc = dmod.load_scene("planetary_contact")
    for b in sc["bodies"]:
        if b.get("type") == "gear":
            b["mesh"] = {"order": 1}
    for j in sc["joints"]:
        if j["body"] == "sun":
            j.clear()
            j.update({"body": "sun", "type": "bearing", "stiffness": 0.0, "damping": 50.0})
        if j["body"] == "planet1":
            j["pin_error_um"] = [0.0, 10.0]
    sc["outputs"] = {"telemetry_every": 50}
    return sc


def run(ranks, steps=600):
    return ranks_run(R, dmod, "floating sun, contact meshes", ranks, scene(), steps, timeout=900)


runs = {n: R.guard(f"floating sun with contact meshes at -n {n}", run, n) for n in (1, 2, 3)}
if runs.get(1):
    t1 = runs[1][0]
    R.check("telemetry arrived", len(t1) > 5, len(t1))
    last = json.loads(t1[max(t1)])
    bal = last["energy"]["balance_residual"]
    R.note(f"-n 1 at step {max(t1)}: balance residual {bal!r} J of {last['energy']['total']!r} J; "
           f"planets {last.get('planets')}")
    R.check("balance at round-off (1e-9 of the input work)",
            abs(bal) < 1e-9 * max(last["energy"]["work_in"], 1e-30), last["energy"])
    moved = [b["name"] for b in last["bodies"] if "offset" in b and math.hypot(*b["offset"]) > 1e-8]
    R.check("the sun's centre moves (telemetry offsets)", "sun" in moved, last["bodies"])
    check_same_at_ranks(R, "floating sun, contact meshes", runs)

sys.exit(R.finish() if hasattr(R, "finish") else (1 if R.failed else 0))
