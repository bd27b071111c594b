#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Non-finite physics is refused, never reported (docs/RELIABILITY.md).

* A scene whose elastic gear has material.E = 1e-300 (or 1e5, below any
  real solid, or a density of 1e-300) is refused by `load`, `modal` and
  `submit` with the field named (args.scene.bodies[i].material.E), so no
  run ever reports "total": NaN.
* The same scene inside a sweep's points is refused at the request.
* Replies and events of a run are strict JSON: every `state`, `status` and
  event of a short elastic run parses without NaN or Infinity.
(The run-time stop at the first non-finite value and the JSON writer's
guard are checked in tests/unit/test_service.c.)"""
import copy
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results, strict_json  # noqa: E402

R = Results("test_nonfinite: non-finite physics refused with the field named")



def refused(name, fn, field, code="out_of_range"):
    try:
        r = fn()
        R.check(name, False, f"accepted: {str(r)[:300]}")
    except gearsim.GearsimError as e:
        R.check(name, e.code == code and e.field == field, f"{e.code} {e.field} {e.message}")


def main():
    ep = dmod.load_scene("elastic_pair")
    k = next(i for i, b in enumerate(ep["bodies"]) if b.get("model") == "elastic")
    with dmod.Daemon(ranks=1) as d:
        c = d.client()
        for key, v in (("E", 1e-300), ("E", 1e5), ("density", 1e-300), ("density", 0.5)):
            s = copy.deepcopy(ep)
            s["bodies"][k].setdefault("material", {})[key] = v
            f = f"args.scene.bodies[{k}].material.{key}"
            refused(f"load refuses material.{key} = {v:g}", lambda: c.request("load", {"scene": s}), f)
            refused(f"modal refuses material.{key} = {v:g}", lambda: c.request("modal", {"scene": s}), f)
            refused(f"submit refuses material.{key} = {v:g}",
                    lambda: c.request("submit", {"scene": s, "duration": 1e-3}), f)
        s = copy.deepcopy(ep)
        s["bodies"][k].setdefault("material", {})["E"] = 1e-300
        try:
            c.request("sweep", {"scene": s, "parameters": [{"path": "loads[0].moment", "values": [1.0, 2.0]}],
                                "settle": 1e-4, "measure": 1e-4, "path": "nf"})
            R.check("sweep refuses material.E = 1e-300", False, "accepted")
        except gearsim.GearsimError as e:
            R.check("sweep refuses material.E = 1e-300", e.code == "out_of_range" and "material.E" in (e.field or ""),
                    f"{e.code} {e.field} {e.message}")
        # A real elastic run: every reply and event strict JSON.
        c.request("load", {"scene": ep})
        events = []
        c.advance(steps=40, wait=True, timeout=300, on_telemetry=events.append, on_event=events.append)
        st, stat = c.request("state"), c.request("status")
        R.check("state, status and events of an elastic run are strict JSON",
                strict_json(st) and strict_json(stat) and all(strict_json(e) for e in events) and len(events) > 0,
                f"{len(events)} events")
    R.finish()


if __name__ == "__main__":
    main()
