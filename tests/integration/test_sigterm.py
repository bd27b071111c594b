#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""SIGTERM to mpirun alone (the systemd stop path: KillMode=mixed signals
the main process first): every rank handles it and the daemon stops
cleanly. Under mpirun -n 2, with an advance running and a record open, the
subscriber gets the advance's `done` with cancelled: true, the connection
file is removed, the record is readable with every flushed row, no rank is
left, and mpirun's exit status is the documented one (0 or 1,
docs/RELIABILITY.md)."""
import os
import signal
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import h5py  # noqa: E402

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_sigterm: SIGTERM to mpirun stops every rank cleanly")


def case():
    d = dmod.Daemon(ranks=2, keep=True).start()
    try:
        ranks = d.gearsimd_pids()
        R.check("two gearsimd ranks run", len(ranks) == 2, ranks)
        with d.client(timeout=10.0) as c:
            c.load(builtin="pair")
            c.record("run.h5")
            c.subscribe()
            rid = c.send("advance", {"steps": 50_000_000})
            R.check("advance accepted", c.wait_reply(rid).get("accepted") is True)
            # let it run and flush some rows
            t_end = time.monotonic() + 2.0
            while time.monotonic() < t_end:
                c.next_event(timeout=0.2)
            mpirun = d.proc.pid
            os.kill(mpirun, signal.SIGTERM)      # mpirun only, not the group
            done = None
            t_end = time.monotonic() + 30
            while time.monotonic() < t_end and done is None:
                ev = c.next_event(timeout=0.5)
                if ev and ev.get("type") == "done" and ev.get("parent_id") == rid:
                    done = ev
        R.check("the running advance gets its done event, cancelled",
                done is not None and done.get("cancelled") is True and done.get("steps", 0) > 0, done)
        try:
            status = d.proc.wait(timeout=30)
        except Exception:   # noqa: BLE001
            status = None
        R.check(f"mpirun exits by itself with the documented status 0 or 1 (got {status})", status in (0, 1),
                d.log_tail())
        t_end = time.monotonic() + 10
        while any(os.path.exists(f"/proc/{p}") for p in ranks) and time.monotonic() < t_end:
            time.sleep(0.1)
        R.check("no rank is left", not any(os.path.exists(f"/proc/{p}") for p in ranks), ranks)
        R.check("the connection file is removed", not os.path.exists(d.conn_file))
        with open(d.path("daemon.err")) as f:
            log = f.read()
        R.note("daemon log after SIGTERM: " + " | ".join(log.strip().splitlines()[-4:]))
        R.check("no rank was killed by the signal (no abort in the log)",
                "signal 15" not in log and "Terminated" not in log and "MPI_ABORT" not in log, log[-1500:])
        with h5py.File(d.path("run.h5"), "r") as f:
            steps = f["telemetry/step"][:]
        R.check(f"the record is readable, its rows up to the last step ({len(steps)} rows, last step "
                f"{int(steps[-1]) if len(steps) else -1})",
                len(steps) > 10 and done is not None and int(steps[-1]) <= done.get("step", 0)
                and list(steps) == sorted(steps), (len(steps), done))
    finally:
        d.stop(graceful=False)
        import shutil
        shutil.rmtree(d.dir, ignore_errors=True)


R.guard("SIGTERM to mpirun", case)
R.finish()
