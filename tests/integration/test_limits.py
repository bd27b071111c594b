#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Every documented limit on every path that the quantity it limits can
enter (docs/RELIABILITY.md, "Limits").

* --max-scene-mb holds for every point of a sweep, not only the first: a
  sweep whose first point fits and whose second is far over is refused at
  the request (field args.parameters, the point named), and so is one
  whose first point is over.
* --max-scene-mb holds for the `refine` argument of `stiffness`: refine 2
  on the elastic pair (an estimate of GiB) is refused (field args.refine)
  on a daemon whose limit the scene itself fits, while refine 0 runs.
* The step cap of `advance` holds for each sweep point: settle + measure
  over the time step above it is refused (field args.measure).
* (The scene stored in a checkpoint is checked against the same limit:
  tests/integration/test_checkpoint_input.py.)"""
import copy
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_limits: every limit on every path")
LIMIT_MB = 400


def refused(name, fn, field, code="too_large"):
    try:
        fn()
        R.check(name, False, "accepted")
        return False
    except gearsim.GearsimError as e:
        return R.check(name, e.code == code and e.field == field and ("MiB" in e.message or "steps" in e.message),
                       f"{e.code} {e.field} {e.message}")


def main():
    ep = dmod.load_scene("elastic_pair")
    ep["bodies"][1]["mesh"] = {"refine": 0}
    mesh = ep["meshes"][0]["name"]
    with dmod.Daemon(ranks=2, extra_args=["--max-scene-mb", str(LIMIT_MB)]) as d:
        c = d.client()
        R.check("hello reports the limit", c.hello()["limits"]["max_scene_mb"] == LIMIT_MB)
        c.request("load", {"scene": ep})
        for vals in ([0, 2], [2, 0], [0, 0, 0, 2]):
            ok = refused(f"sweep over the limit at a point: refine {vals}",
                         lambda: c.request("sweep", {"scene": ep, "path": "s",
                                                     "parameters": [{"path": "bodies[1].mesh.refine",
                                                                     "values": vals}],
                                                     "settle": 1e-4, "measure": 1e-4}),
                         "args.parameters")
            if not ok:
                try:
                    c.request("cancel")
                except gearsim.GearsimError:
                    pass
        refused("stiffness refine 2 over the limit",
                lambda: c.request("stiffness", {"mesh": mesh, "refine": 2, "positions": 1, "wait": False}),
                "args.refine")
        try:
            c.request("stiffness", {"mesh": mesh, "refine": 0, "positions": 1, "wait": False})
            R.check("stiffness refine 0 within the limit is accepted", True)
            c.request("cancel")
        except gearsim.GearsimError as e:
            R.check("stiffness refine 0 within the limit is accepted", False, repr(e))
        pair = dmod.load_scene("pair")
        ok = refused("sweep point over the step cap",
                     lambda: c.request("sweep", {"scene": pair, "path": "long",
                                                 "parameters": [{"path": "loads[0].moment", "values": [1, 2]}],
                                                 "settle": 1000, "measure": 1000, "time_step": 1e-7}),
                     "args.measure")
        if not ok:
            try:
                c.request("cancel")
            except gearsim.GearsimError:
                pass
        R.check("the daemon answers", c.hello()["protocol"] == 1)
    R.finish()


if __name__ == "__main__":
    main()
