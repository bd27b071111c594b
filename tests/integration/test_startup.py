#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Start-up of gearsimd as the README runs it: where the daemon and the
clients look for each other, the data directory, and start-up errors.

* A data directory that cannot be used (a regular file, a path under a
  file) stops every rank with a non-zero status, for 2 and 3 ranks, within a
  generous timeout (a rank left waiting in a collective would hang until it).
  Each rank's own status is seen through a shell wrapper that prints it.
* A missing data directory (several levels) is created and used.
* A refused --bind (non-loopback without CURVE) also ends every rank non-zero.
* --bind localhost and --bind ::1 are accepted and clients connect.
* Without --connection-file the daemon writes the file where gearsim.Client(),
  gearctl and the C client look by default ($XDG_RUNTIME_DIR/gearsim/)."""
import json
import os
import re
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from daemon import BUILD_ROOT, MPI_ENV, SOURCE_ROOT, gearsimd_path  # noqa: E402
from harness import Results, scratch_dir  # noqa: E402

import gearsim  # noqa: E402

TIMEOUT = 60.0   # generous: a hang is what is detected, not speed
WRAP = '"$@"; s=$?; echo "rank-exit rank=$OMPI_COMM_WORLD_RANK status=$s"; exit 0'


def env(**extra):
    e = dict(os.environ, **MPI_ENV)
    e.update(extra)
    return e


def run_to_end(ranks, args, wrap=False, cwd=None, extra_env=None):
    """mpirun -n ranks gearsimd args; (mpirun status or None on timeout,
    output, [status of each rank] when wrap)."""
    cmd = ["mpirun", "-n", str(ranks)]
    if wrap:
        cmd += ["sh", "-c", WRAP, "sh"]
    cmd += [gearsimd_path()] + list(args)
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                         env=env(**(extra_env or {})), cwd=cwd, start_new_session=True)
    try:
        out, _ = p.communicate(timeout=TIMEOUT)
        rc = p.returncode
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, _ = p.communicate()
        rc = None
    text = out.decode(errors="replace")
    statuses = [int(s) for s in re.findall(r"rank-exit rank=\d+ status=(\d+)", text)]
    return rc, text, statuses


class Running:
    """A daemon left running: start, wait for its connection file, stop."""

    def __init__(self, ranks, args, conn, extra_env=None):
        self.conn = conn
        self.p = subprocess.Popen(["mpirun", "-n", str(ranks), gearsimd_path()] + list(args),
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                  env=env(**(extra_env or {})), start_new_session=True)
        deadline = time.monotonic() + TIMEOUT
        while not os.path.exists(conn):
            if self.p.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError("gearsimd did not start: " + self.output)
            time.sleep(0.05)

    def stop(self):
        if self.p.poll() is None:
            try:
                with gearsim.Client(self.conn, timeout=5.0, retries=0) as c:
                    c.shutdown()
            except (gearsim.GearsimError, OSError):
                os.killpg(self.p.pid, signal.SIGTERM)
        try:
            out, _ = self.p.communicate(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            os.killpg(self.p.pid, signal.SIGKILL)
            out, _ = self.p.communicate()
        self.output = out.decode(errors="replace")
        return self.p.returncode


def bad_data_dir(R, tmp):
    afile = os.path.join(tmp, "a-file")
    with open(afile, "w") as f:
        f.write("not a directory\n")
    for ranks in (2, 3):
        for dd in (afile, os.path.join(afile, "sub")):
            rc, out, st = run_to_end(ranks, ["--connection-file", os.path.join(tmp, "c.json"),
                                              "--data-dir", dd], wrap=True)
            tag = f"-n {ranks} --data-dir {os.path.relpath(dd, tmp)}"
            R.check(f"{tag}: ends (no rank left waiting)", rc is not None, out[-1500:])
            R.check(f"{tag}: every rank exits non-zero", len(st) == ranks and all(s != 0 for s in st),
                    f"statuses {st}\n{out[-1500:]}")
            R.check(f"{tag}: the error names --data-dir", "--data-dir" in out and "not a directory" in out.lower(),
                    out[-1500:])
    # and mpirun itself, unwrapped, reports the failure
    rc, out, _ = run_to_end(2, ["--connection-file", os.path.join(tmp, "c.json"), "--data-dir", afile])
    R.check("-n 2 bad data dir: mpirun exits non-zero", rc not in (None, 0), f"rc={rc}\n{out[-1500:]}")
    R.check("no connection file left behind", not os.path.exists(os.path.join(tmp, "c.json")))


def refused_bind(R, tmp):
    rc, out, st = run_to_end(2, ["--connection-file", os.path.join(tmp, "c.json"), "--data-dir", tmp,
                                 "--bind", "192.0.2.1"], wrap=True)
    R.check("--bind 192.0.2.1 without CURVE: every rank exits non-zero",
            rc is not None and len(st) == 2 and all(s != 0 for s in st), f"rc={rc} statuses {st}\n{out[-1500:]}")
    R.check("--bind refused: the message says why", "CURVE" in out, out[-1500:])


def created_data_dir(R, tmp):
    dd = os.path.join(tmp, "new", "deeper", "data")
    conn = os.path.join(tmp, "created.json")
    d = Running(2, ["--connection-file", conn, "--data-dir", dd], conn)
    try:
        R.check("missing --data-dir is created", os.path.isdir(dd))
        with gearsim.Client(conn) as c:
            c.load(builtin="pair")
            r = c.record("rec.h5")
            R.check("record path comes back relative to the data dir", r.get("recording") == "rec.h5", r)
            R.check("status.recording relative too", c.status().get("recording") == "rec.h5")
            c.record(stop=True)
        R.check("the record lands in the created data dir", os.path.isfile(os.path.join(dd, "rec.h5")))
    finally:
        rc = d.stop()
    R.check("created data dir: clean shutdown, status 0", rc == 0, d.output[-1500:])


def binds(R, tmp):
    for b in ("localhost", "::1"):
        conn = os.path.join(tmp, "bind.json")
        try:
            d = Running(1, ["--connection-file", conn, "--data-dir", tmp, "--bind", b], conn)
        except RuntimeError as e:
            R.check(f"--bind {b} accepted", False, e)
            continue
        try:
            with open(conn) as f:
                ep = json.load(f)["command"]
            with gearsim.Client(conn, timeout=5.0) as c:
                h = c.hello()
                R.check(f"--bind {b}: a client gets hello", h.get("protocol") == 1 or "commands" in h, h)
                want = "[::1]" if b == "::1" else "127.0.0.1"
                R.check(f"--bind {b}: endpoint on {want}", want in ep, ep)
                c.subscribe(["heartbeat"])   # raises GearsimTimeout without a heartbeat
                R.check(f"--bind {b}: a heartbeat arrives on the telemetry socket", True)
        finally:
            d.stop()


def default_connection_file(R, tmp):
    """No --connection-file anywhere: daemon, gearsim.Client(), gearctl and
    the C client meet at $XDG_RUNTIME_DIR/gearsim/gearsimd.json."""
    xdg = os.path.join(tmp, "xdg")
    os.makedirs(xdg, mode=0o700)
    want = os.path.join(xdg, "gearsim", "gearsimd.json")
    old = os.environ.get("XDG_RUNTIME_DIR")
    os.environ["XDG_RUNTIME_DIR"] = xdg
    try:
        R.check("gearsim.default_connection_file() is under XDG_RUNTIME_DIR",
                gearsim.default_connection_file() == want, gearsim.default_connection_file())
        d = Running(2, ["--data-dir", os.path.join(tmp, "dd")], want)
        try:
            with gearsim.Client() as c:
                R.check("default: Client() reaches the daemon", c.status().get("ranks") == 2)
            g = subprocess.run(["/usr/bin/python3", os.path.join(SOURCE_ROOT, "clients", "python", "gearctl"),
                                "status"], capture_output=True, text=True, timeout=TIMEOUT, env=env())
            R.check("default: gearctl status reaches the daemon", g.returncode == 0 and '"ranks": 2' in g.stdout,
                    g.stdout + g.stderr)
            cli = os.path.join(BUILD_ROOT, "clients", "c", "gearsim-client-c")
            if os.access(cli, os.X_OK):
                r = subprocess.run([cli, "builtin:pair", "--until", "0.002"], capture_output=True, text=True,
                                   timeout=TIMEOUT, env=env())
                R.check("default: the C client reaches the daemon", r.returncode == 0 and "t=" in r.stdout,
                        r.stdout + r.stderr)
            else:
                R.skip("default: the C client", "gearsim-client-c is not built")
        finally:
            rc = d.stop()
        R.check("default connection file removed at shutdown", not os.path.exists(want))
        R.check("default: clean shutdown", rc == 0, d.output[-1500:])
    finally:
        if old is None:
            del os.environ["XDG_RUNTIME_DIR"]
        else:
            os.environ["XDG_RUNTIME_DIR"] = old


def main():
    R = Results("gearsimd start-up: data directory, errors on every rank, binds, default connection file")
    with scratch_dir("gearsim-startup-") as tmp:
        for name, fn in (("bad data dir", bad_data_dir), ("refused bind", refused_bind),
                         ("created data dir", created_data_dir), ("binds", binds),
                         ("default connection file", default_connection_file)):
            R.guard(name, fn, R, tmp)
    R.finish()


if __name__ == "__main__":
    main()
