#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Argument hygiene (docs/RELIABILITY.md):

* sweep parameter paths with an empty segment ('loads[0]..moment',
  '.loads[0].moment', 'loads[0].moment.') are refused, not normalised
  (the column would keep the literal name);
* a sweep `path` whose last component is not a name ('.', '..', 'dir/')
  is refused (it would write files named '..csv');
* `modal` with `builtin` names the field with its 'args.builtin.' prefix;
* a checkpoint whose declared body state is missing is an io_error, never
  bad_json (the request was valid JSON);
* a sweep whose every point failed ends finished: the next sweep at that
  path runs without resume."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_hygiene: argument hygiene")


def refused(name, fn, field, code=None):
    try:
        fn()
        R.check(name, False, "accepted")
        return False
    except gearsim.GearsimError as e:
        return R.check(name, e.field == field and (code is None or e.code == code), f"{e.code} {e.field} {e.message}")


def main():
    pair = dmod.load_scene("pair")
    with dmod.Daemon(ranks=1) as d:
        c = d.client()

        def sweep(path="hy", param="loads[0].moment", **kw):
            a = {"scene": pair, "path": path, "parameters": [{"path": param, "values": [1.0, 2.0]}],
                 "settle": 1e-4, "measure": 1e-4}
            a.update(kw)
            return c.request("sweep", a)

        for p in ("loads[0]..moment", ".loads[0].moment", "loads[0].moment.", "loads.[0].moment", "[0].moment",
                  "loads[]"):
            if not refused(f"sweep parameter path '{p}' refused", lambda: sweep(param=p),
                           "args.parameters[0].path"):
                c.request("cancel")
        for p in (".", "..", "sub/", "a/.", "a/.."):
            os.makedirs(d.path("sub"), exist_ok=True)
            os.makedirs(d.path("a"), exist_ok=True)
            if not refused(f"sweep path '{p}' refused", lambda: sweep(path=p), "args.path"):
                c.request("cancel")
        R.check("no file named '..csv' or '.csv'", not any(n in os.listdir(d.dir) for n in ("..csv", ".csv", "...csv")),
                os.listdir(d.dir))
        refused("modal of builtin contact_drive names args.builtin.*",
                lambda: c.request("modal", {"builtin": "contact_drive"}), "args.builtin.meshes[0].model")
        # every point fails at run time (a time step that skips the tooth stiffness wave)
        c.subscribe()
        for k in range(2):
            try:
                rid = c.send("sweep", {"scene": pair, "path": "allfail",
                                       "parameters": [{"path": "loads[0].moment", "values": [1e6, 2e6]}],
                                       "settle": 1, "measure": 1, "time_step": 1.0})
                c.wait_reply(rid)
                done = c.wait_done(rid, timeout=120)
                R.check(f"all-failed sweep #{k + 1} runs and lists its failures",
                        done.get("points_done") == 0 and len(done.get("failed", [])) == 2, str(done)[:300])
            except gearsim.GearsimError as e:
                R.check(f"all-failed sweep #{k + 1} runs and lists its failures", False, repr(e))
        # a checkpoint with its body state missing
        c.request("load", {"builtin": "elastic_spin"})
        c.request("checkpoint", {"path": "es.h5"})
        import h5py
        import numpy as np
        import struct
        with h5py.File(d.path("es.h5"), "r") as f:
            b = f["snapshot"][()].tobytes()
        nc, nm = struct.unpack_from("<II", b, 4)
        o = 60 + 16 * nc + 64 * nm
        ns, = struct.unpack_from("<d", b, o)
        R.check("elastic_spin's snapshot holds a body state", ns > 0, ns)
        cut = b[:o + 8] + b[o + 8 + 8 * int(ns):]
        with h5py.File(d.path("nostate.h5"), "w") as f:
            f.create_dataset("snapshot", data=np.frombuffer(cut, dtype=np.uint8))
        refused("restore of a checkpoint without its body state: io_error",
                lambda: c.request("restore", {"path": "nostate.h5"}), "args.path", "io_error")
        R.check("the daemon answers", c.hello()["protocol"] == 1)
    R.finish()


if __name__ == "__main__":
    main()
