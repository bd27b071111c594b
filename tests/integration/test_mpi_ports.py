#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Open MPI listens on loopback only: under mpirun -n 2 with the deployment
settings (deploy/env.sh MCA parameters: shared-memory transport, runtime on
lo; mpirun preloaded with gearsim-loopback.so), every listening TCP socket
of the daemon's process tree (mpirun and both ranks; from /proc/<pid>/fd
and /proc/net/tcp, tcp6) is bound to a loopback address, and a run across
both ranks works. The same tree started without those settings shows the
detector at work (Open MPI's wildcard listeners are reported)."""
import ipaddress
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results, listening_sockets  # noqa: E402

R = Results("test_mpi_ports: every listener of the daemon's tree is on loopback")


def tree(d):
    out = {}
    for p in d.session_pids():
        try:
            with open(f"/proc/{p}/comm") as f:
                out[p] = f.read().strip()
        except OSError:
            pass
    return out


def loopback(addr):
    return ipaddress.ip_address(addr).is_loopback


def deployed():
    with dmod.Daemon(ranks=2) as d:
        procs = tree(d)
        R.check("mpirun and two gearsimd ranks in the tree",
                sorted(procs.values()).count("gearsimd") == 2 and "mpirun" in procs.values(), procs)
        per = {f"{procs[p]}[{p}]": listening_sockets([p]) for p in procs}
        allsocks = [s for v in per.values() for s in v]
        R.note(f"listening sockets: {per}")
        R.check("the tree listens somewhere (the detector sees the command and telemetry ports)",
                len(allsocks) >= 2, per)
        bad = [(k, s) for k, v in per.items() for s in v if not loopback(s[0])]
        R.check("every listening socket is bound to a loopback address", not bad, bad)
        with d.client() as c:
            c.load(builtin="elastic_pair")
            done = c.advance(steps=20, timeout=300)
            R.check("a run across both ranks works with these settings", done.get("steps") == 20, done)


def control():
    """The same binary with Open MPI's defaults: no shim, no MCA limits."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("OMPI_MCA_btl") and
           not k.startswith("OMPI_MCA_oob") and k != "LD_PRELOAD"}
    for k in ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "OMPI_MCA_rmaps_base_oversubscribe",
              "OMPI_MCA_btl_vader_single_copy_mechanism"):
        env[k] = dmod.MPI_ENV[k]
    import tempfile
    with tempfile.TemporaryDirectory(prefix="gearsim-ports-") as tmp:
        conn = os.path.join(tmp, "c.json")
        p = subprocess.Popen(["mpirun", "-n", "2", dmod.gearsimd_path(), "--connection-file", conn,
                              "--data-dir", tmp], env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, start_new_session=True)
        try:
            t_end = time.monotonic() + 60
            while not os.path.exists(conn) and time.monotonic() < t_end and p.poll() is None:
                time.sleep(0.1)
            time.sleep(0.5)
            pids = [int(n) for n in os.listdir("/proc") if n.isdigit() and os.getsid(int(n)) == p.pid] \
                if os.path.exists(conn) else []
            socks = listening_sockets(pids)
            wild = [s for s in socks if not loopback(s[0])]
            R.note(f"without the settings: {len(wild)} of {len(socks)} listeners not on loopback: {wild}")
            R.check("without the settings the detector reports the tree's listeners", len(socks) >= 2, socks)
        finally:
            import signal
            try:
                os.killpg(p.pid, signal.SIGTERM)
                p.wait(timeout=30)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                os.killpg(p.pid, signal.SIGKILL)


R.guard("deployment settings", deployed)
R.guard("Open MPI defaults (control)", control)
R.finish()
