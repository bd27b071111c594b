#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""A second gearsimd on the same data directory, or on the same connection
file, refuses to start: a clear message naming the lock, a non-zero exit of
every rank (mpirun reports it), and the first daemon's connection file and
service untouched. Once the first has stopped, a new daemon starts there."""
import os
import signal
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_lock: one daemon per data directory and connection file")


def second(conn, data, ranks=2):
    """Run a second daemon to its end (it must refuse at once); one that
    starts anyway (no lock) is stopped with SIGTERM after 60 s."""
    env = dict(os.environ, **dmod.MPI_ENV)
    p = subprocess.Popen(["mpirun", "-n", str(ranks), dmod.gearsimd_path(), "--connection-file", conn,
                          "--data-dir", data], env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    try:
        out, err = p.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        p.send_signal(signal.SIGTERM)     # mpirun forwards it to its ranks
        try:
            out, err = p.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            out, err = p.communicate()
        err = "still running after 60 s (no lock?)\n" + err
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def case(tmp):
    other_data = os.path.join(tmp, "other-data")
    other_conn_dir = os.path.join(tmp, "other-conn")
    os.makedirs(other_data)
    os.makedirs(other_conn_dir, mode=0o700)
    with dmod.Daemon(ranks=1) as d:
        with open(d.conn_file, "rb") as f:
            conn_before = f.read()
        with d.client() as c:
            c.load(builtin="pair")
        for what, conn, data in (("the same data directory", os.path.join(other_conn_dir, "c.json"), d.dir),
                                 ("the same connection file", d.conn_file, other_data)):
            r = second(conn, data)
            err = r.stderr + r.stdout
            R.check(f"a second daemon on {what}: non-zero exit ({r.returncode})", r.returncode != 0, err[-1500:])
            R.check(f"... a clear message naming the lock and the first daemon's pid",
                    "refusing to start" in err and ".lock" in err and str(d.connection["pid"]) in err, err[-1500:])
            R.check("... every rank exited with status 3 (no rank killed)",
                    "Exit code:    3" in err and "signal" not in err, err[-1500:])
            with open(d.conn_file, "rb") as f:
                R.check("... the first daemon's connection file is unchanged", f.read() == conn_before)
            with d.client() as c:
                R.check("... the first daemon still serves its loaded scene", c.status().get("state") == "loaded")
        R.check("no connection file was written for the refused daemons",
                not os.path.exists(os.path.join(other_conn_dir, "c.json")))
    with dmod.Daemon(ranks=1, data_dir=os.path.join(tmp, "other-data")) as d2:
        R.check("after the first one stopped, a new daemon starts on a used data directory",
                d2.hello.get("ranks") == 1)


with tempfile.TemporaryDirectory(prefix="gearsim-lock-") as tmp:
    R.guard("lock", case, tmp)
R.finish()
