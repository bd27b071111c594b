#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsimd across two hosts: two network namespaces joined by a veth pair
(10.213.37.1 and .2, private addresses that exist only inside them), each
with its own host name (a UTS namespace per launch), stand for two nodes.
mpirun starts on "nodea" and reaches "nodeb" through its ssh launcher
(plm_rsh_agent) pointed at an agent that enters the other namespace with a
clean environment, as ssh would. The MPI settings are the multi-node ones
of deploy/gearsimd.slurm (read from the script): TCP transport and runtime
on the named interface and the documented port ranges, no loopback shim.

Checks: planetary_contact at -n 3 (ranks 0 and 2 on nodea, 1 on nodeb)
gives telemetry bit for bit identical to -n 3 on one host; a 16-point sweep
on 2 groups, one per host, gives the single-host table byte for byte; the
sockets of both namespaces (ss) during the runs show connections between
the hosts only to the documented ports and no listener off loopback on any
other port; SIGTERM to mpirun stops every process on both hosts; a rank
SIGKILLed on nodeb ends the job on both hosts and the client waiting on an
advance is told (an error, not a hang). Exit 77 (skipped) where network
namespaces cannot be made. Every namespace is removed at the end."""
import atexit
import ctypes
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

SKIP = 77
TAG = f"gs{os.getpid() % 100000}{os.urandom(2).hex()}"   # unique per run; stale names never collide
NS = {"nodea": TAG + "a", "nodeb": TAG + "b"}
ADDR = {"nodea": "10.213.37.1", "nodeb": "10.213.37.2"}
IFACE = "gsnet0"
RUNTIME = range(46100, 46164)
TRANSPORT = range(46200, 46264)
STEPS, EVERY = 12, 1
_made = []


def sh(*cmd, check=True):
    return subprocess.run(list(cmd), capture_output=True, text=True, check=check)


def ns_pids(ns):
    """The processes in namespace ns, this test excepted (it lives on nodea)."""
    r = sh("ip", "netns", "pids", ns, check=False)
    return [int(p) for p in r.stdout.split() if int(p) != os.getpid()] if r.returncode == 0 else []


def cleanup():
    """Kill what runs in our namespaces (only ours: their names are this
    run's) and delete them."""
    for ns in list(_made):
        for _ in range(3):
            pids = ns_pids(ns)
            if not pids:
                break
            for p in pids:
                try:
                    os.kill(p, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            time.sleep(0.3)
        sh("ip", "netns", "del", ns, check=False)
        _made.remove(ns)


def make_hosts():
    """The two namespaces and their link; None or the reason it failed."""
    if os.geteuid() != 0:
        return "network namespaces need root (CAP_SYS_ADMIN, CAP_NET_ADMIN)"
    for tool in ("ip", "ss", "unshare", "mpirun"):
        if shutil.which(tool) is None:
            return f"{tool} not found"
    for ns in NS.values():
        r = sh("ip", "netns", "add", ns, check=False)
        if r.returncode:
            return f"ip netns add {ns}: {r.stderr.strip()}"
        _made.append(ns)
    a, b = NS["nodea"], NS["nodeb"]
    r = sh("ip", "link", "add", IFACE, "netns", a, "type", "veth", "peer", "name", IFACE, "netns", b, check=False)
    if r.returncode:
        return f"veth pair: {r.stderr.strip()}"
    for host, ns in NS.items():
        sh("ip", "-n", ns, "addr", "add", ADDR[host] + "/24", "dev", IFACE)
        sh("ip", "-n", ns, "link", "set", "lo", "up")
        sh("ip", "-n", ns, "link", "set", IFACE, "up")
    return None


def enter(ns):
    """Move this process (one thread so far: no ZeroMQ context yet) into ns."""
    libc = ctypes.CDLL(None, use_errno=True)
    fd = os.open(f"/run/netns/{ns}", os.O_RDONLY)
    try:
        if libc.setns(fd, 0x40000000) != 0:   # CLONE_NEWNET
            raise OSError(ctypes.get_errno(), "setns")
    finally:
        os.close(fd)


atexit.register(cleanup)
signal.signal(signal.SIGTERM, lambda *a: sys.exit(1))   # meson's timeout: atexit still runs
why = make_hosts()
if why:
    print(f"skip: two-host test needs network namespaces: {why}", flush=True)
    cleanup()
    sys.exit(SKIP)
# The test itself (its clients and the single-host references) lives on nodea.
enter(NS["nodea"])

import daemon as dmod  # noqa: E402
from harness import Results, json_diff  # noqa: E402

R = Results("test_two_hosts: gearsimd with ranks on two hosts (network namespaces, ssh-style launch)")
SLURM = os.path.join(dmod.SOURCE_ROOT, "deploy", "gearsimd.slurm")
SPEC = {"builtin": "planetary_sweep",
        "parameters": [{"path": "driver_rpm", "from": 17000, "to": 25000, "points": 16}],
        "settle": 0.0006, "measure": 0.0006, "time_step": 2e-6}


def cluster_settings():
    """The `export` lines of deploy/gearsimd.slurm's multi-node branch, with
    the interface substituted: what an operator's job runs with."""
    with open(SLURM) as f:
        text = f.read()
    branch = text.split("\nelse\n", 1)[1].split("\nfi\n", 1)[0]
    out = {}
    for line in branch.splitlines():
        line = line.strip()
        if line.startswith("export "):
            for kv in line[len("export "):].split():
                k, _, v = kv.partition("=")
                out[k] = v.replace("$IFACE", IFACE)
    return out


def mpirun_exports():
    """-x for each variable of the script's FORWARD list that is set: what
    its mpirun passes to ranks on other nodes."""
    with open(SLURM) as f:
        names = re.search(r'^FORWARD="([^"]*)"', f.read(), re.M).group(1).split()
    return " ".join(f"-x {n}" for n in names if os.environ.get(n))


def write_agent(tmp):
    """ssh's stand-in: `agent HOST COMMAND...` runs COMMAND through a shell
    in HOST's namespace with HOST's name and a clean environment."""
    path = os.path.join(tmp, "agent.sh")
    cases = "\n".join(f"  {h}) ns={ns};;" for h, ns in NS.items())
    with open(path, "w") as f:
        f.write(f"""#!/bin/sh
host=$1; shift
case "$host" in
{cases}
  *) echo "agent: unknown host $host" >&2; exit 255;;
esac
exec ip netns exec "$ns" unshare --uts env -i PATH="$PATH" HOME="$HOME" /bin/sh -c "hostname $host && $*"
""")
    os.chmod(path, 0o755)
    hosts = os.path.join(tmp, "hostfile")
    with open(hosts, "w") as f:
        f.write("nodea slots=2\nnodeb slots=2\n")
    return path, hosts


class TwoHostDaemon:
    """gearsimd under mpirun on nodea, ranks mapped round-robin over the hosts."""

    def __init__(self, tmp, ranks, settings):
        self.tmp, self.ranks = tempfile.mkdtemp(dir=tmp), ranks
        self.conn_file = os.path.join(self.tmp, "conn.json")
        agent, hosts = write_agent(tmp)
        env = {k: v for k, v in os.environ.items() if not k.startswith("OMPI_MCA_") and k != "LD_PRELOAD"}
        env.update({k: v for k, v in dmod.MPI_ENV.items() if k not in (
            "OMPI_MCA_btl", "OMPI_MCA_oob_tcp_if_include", "OMPI_MCA_btl_tcp_if_include")})
        env.update(settings)
        env["OMPI_MCA_plm_rsh_agent"] = agent
        self.env = env
        cmd = (f"hostname nodea && exec mpirun {mpirun_exports()} --hostfile {hosts} --map-by node -n {ranks} "
               f"{dmod.gearsimd_path()} --connection-file {self.conn_file} --data-dir {self.tmp}")
        self.err = open(os.path.join(self.tmp, "mpirun.err"), "wb")
        self.proc = subprocess.Popen(["unshare", "--uts", "sh", "-c", cmd], env=env, cwd=self.tmp,
                                     stdin=subprocess.DEVNULL, stdout=self.err, stderr=self.err,
                                     start_new_session=True)
        deadline = time.monotonic() + 120
        while not os.path.exists(self.conn_file):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"two-host daemon did not start:\n{self.log()}")
            time.sleep(0.1)
        while True:
            try:
                with dmod.gearsim.Client(self.conn_file, timeout=2.0, retries=0) as c:
                    self.hello = c.hello()
                break
            except dmod.gearsim.GearsimError:
                if self.proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"two-host daemon does not answer:\n{self.log()}")
                time.sleep(0.2)

    def log(self):
        try:
            with open(os.path.join(self.tmp, "mpirun.err"), "rb") as f:
                return f.read()[-3000:].decode(errors="replace")
        except OSError:
            return ""

    def client(self, **kw):
        return dmod.gearsim.Client(self.conn_file, **kw)

    def procs(self):
        """host -> [(pid, program)] of everything running in its namespace."""
        out = {}
        for host, ns in NS.items():
            lst = []
            for p in ns_pids(ns):
                try:
                    lst.append((p, os.path.basename(os.readlink(f"/proc/{p}/exe"))))
                except OSError:
                    pass
            out[host] = lst
        return out

    def ranks_on(self):
        return {h: sorted(p for p, exe in lst if exe == "gearsimd") for h, lst in self.procs().items()}

    def gone(self, timeout):
        """Seconds until no process is left in either namespace (None: still some)."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            if not any(self.procs().values()):
                return time.monotonic() - t0
            time.sleep(0.2)
        return None

    def stop(self):
        if self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for _, lst in self.procs().items():
            for p, _exe in lst:
                try:
                    os.kill(p, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        self.err.close()


# ------------------------------------------------------------------ sockets
def _split(ep):
    host, _, port = ep.rpartition(":")
    return host.strip("[]"), int(port) if port.isdigit() else -1


def socket_table(host):
    """(listeners, connections, udp) of host's namespace: listeners as
    (addr, port, process), connections as (local, lport, peer, pport, process)."""
    out = sh("ip", "netns", "exec", NS[host], "ss", "-tanpH").stdout
    listen, conns = [], []
    for line in out.splitlines():
        f = line.split()
        if len(f) < 5:
            continue
        proc = re.search(r'"([^"]+)"', line)
        proc = proc.group(1) if proc else ""
        la, lp = _split(f[3])
        pa, pp = _split(f[4])
        if f[0] == "LISTEN":
            listen.append((la, lp, proc))
        else:
            conns.append((la.replace("::ffff:", ""), lp, pa.replace("::ffff:", ""), pp, proc, f[0]))
    udp = [line for line in sh("ip", "netns", "exec", NS[host], "ss", "-uanpH").stdout.splitlines() if line.strip()]
    return listen, conns, udp


def loopback(addr):
    return addr.startswith("127.") or addr == "::1"


def documented(port):
    return port in RUNTIME or port in TRANSPORT


def check_sockets(label, tables):
    """Connections between the hosts go to documented ports; nothing else
    listens off loopback; no UDP off loopback."""
    other = {"nodea": ADDR["nodeb"], "nodeb": ADDR["nodea"]}
    listening = {h: {p for a, p, _ in t[0]} for h, t in tables.items()}
    bad, seen, offlo, udp = [], {"runtime": 0, "transport": 0}, [], []
    for host, (listen, conns, u) in tables.items():
        peer = "nodeb" if host == "nodea" else "nodea"
        for la, lp, pa, pp, proc, state in conns:
            if pa != other[host] or state == "TIME-WAIT":
                continue   # TIME-WAIT: closed, checked while it was live (or a previous job's)
            server_port = lp if lp in listening[host] else pp if pp in listening[peer] else None
            if server_port is None or not documented(server_port):
                bad.append((host, f"{la}:{lp} -> {pa}:{pp}", proc, state))
            elif server_port in RUNTIME:
                seen["runtime"] += 1
            else:
                seen["transport"] += 1
        offlo += [(host, a, p, proc) for a, p, proc in listen if not loopback(a) and not documented(p)]
        udp += [(host, line) for line in u if "127.0.0.1" not in line and "[::1]" not in line]
    R.note(f"{label}: connections between the hosts by server port range: {seen}")
    R.check(f"{label}: every connection between the hosts is to a documented port", not bad, bad)
    R.check(f"{label}: the runtime and the transport both cross between the hosts (the check sees traffic)",
            seen["runtime"] > 0 and seen["transport"] > 0, seen)
    R.check(f"{label}: no listener off loopback on an undocumented port, on either host", not offlo, offlo)
    R.check(f"{label}: no UDP socket off loopback", not udp, udp)


def tables_now():
    return {h: socket_table(h) for h in NS}


# --------------------------------------------------------------------- runs
def planetary_scene():
    scene = dmod.load_scene("planetary_contact")
    scene["outputs"] = dict(scene.get("outputs", {}), telemetry_every=EVERY)
    return scene


def telemetry_run(c, on_first=None):
    c.load(scene=planetary_scene())
    tel = []

    def cb(ev):
        tel.append(ev)
        if on_first and len(tel) == 2:
            on_first()
    done = c.advance(steps=STEPS, on_telemetry=cb, timeout=900)
    series = {ev["step"]: {k: ev.get(k) for k in ("time", "energy", "bodies", "meshes")} for ev in tel}
    return series, done


def sweep_table(c, path):
    rid = c.send("sweep", dict(SPEC, groups=2, path=path))
    c.wait_reply(rid, timeout=120)
    done = c.wait_done(rid, timeout=900)
    return done


def read(path):
    with open(path) as f:
        return f.read()


def main(tmp):
    settings = cluster_settings()
    R.check("deploy/gearsimd.slurm's multi-node settings name the documented ranges",
            settings.get("OMPI_MCA_oob_tcp_dynamic_ipv4_ports") == "46100-46163" and
            settings.get("OMPI_MCA_btl_tcp_port_min_v4") == "46200" and
            settings.get("OMPI_MCA_btl_tcp_port_range_v4") == "64" and
            settings.get("OMPI_MCA_btl_tcp_if_include") == IFACE, settings)
    R.note("settings: " + " ".join(f"{k}={v}" for k, v in sorted(settings.items())))
    # Single-host references (on nodea, shared memory, deploy/env.sh settings).
    with dmod.Daemon(ranks=3) as d, d.client(timeout=60) as c:
        ref_tel, _ = telemetry_run(c)
    with dmod.Daemon(ranks=2) as d, d.client(timeout=60) as c:
        c.subscribe()
        sweep_table(c, "ref")
        ref_table = read(d.path("ref.csv"))
    # -n 3 across the hosts: telemetry, sockets, SIGTERM.
    d = TwoHostDaemon(tmp, 3, settings)
    try:
        on = d.ranks_on()
        R.check("-n 3: ranks 0 and 2 on nodea, rank 1 on nodeb (one gearsimd on nodeb)",
                len(on["nodea"]) == 2 and len(on["nodeb"]) == 1 and d.hello.get("ranks") == 3, on)
        tables = {}
        with d.client(timeout=120) as c:
            tel, done = telemetry_run(c, on_first=lambda: tables.update(tables_now()))
        R.check("-n 3 across hosts: run completed", done.get("steps") == STEPS and not done.get("cancelled"), done)
        diffs = [f"step {s}: {x}" for s in sorted(set(ref_tel) | set(tel))
                 for x in (json_diff(ref_tel.get(s), tel.get(s)) if s in ref_tel and s in tel else ["missing"])]
        R.check(f"planetary_contact -n 3: telemetry across two hosts identical bit for bit to one host "
                f"({len(tel)} messages)", len(tel) >= STEPS // EVERY and not diffs, diffs[:5])
        if tables:
            check_sockets("during planetary_contact", tables)
        else:
            R.check("a socket listing was taken during the run", False)
        os.kill(d.proc.pid, signal.SIGTERM)
        t = d.gone(60)
        R.check("SIGTERM to mpirun stops every process on both hosts", t is not None, d.procs())
        R.note(f"SIGTERM: every process on both hosts gone after {t if t is None else round(t, 1)} s")
        R.check("the connection file is removed", not os.path.exists(d.conn_file))
    finally:
        d.stop()
    # -n 2, one rank (one sweep group) per host: the sweep, then a killed rank.
    d = TwoHostDaemon(tmp, 2, settings)
    try:
        on = d.ranks_on()
        R.check("-n 2: one gearsimd per host", len(on["nodea"]) == 1 and len(on["nodeb"]) == 1, on)
        with d.client(timeout=60) as c:
            c.subscribe()
            done = sweep_table(c, "cl")
            R.check("sweep on 2 groups across hosts completes", done.get("points_done") == 16 and
                    done.get("groups") == 2, done)
            table = read(os.path.join(d.tmp, "cl.csv"))
            R.check("16-point sweep, one group per host: table byte-identical to the single-host one",
                    table == ref_table and len(table.splitlines()) == 17, table[:200] + " | " + ref_table[:200])
            check_sockets("after the sweep", tables_now())
        # A rank killed on nodeb while a client waits on an advance.
        with d.client(timeout=5.0, retries=0) as c:
            c.subscribe()
            c.load(builtin="pair")
            rid = c.send("advance", {"steps": 10 ** 8})
            c.wait_reply(rid, timeout=30)
            victim = d.ranks_on()["nodeb"][0]
            t0 = time.monotonic()
            os.kill(victim, signal.SIGKILL)
            err = None
            try:
                ev = c.wait_done(rid, timeout=60)
            except dmod.gearsim.GearsimError as e:
                err, ev = e, None
            told = time.monotonic() - t0
            R.note(f"rank 1 SIGKILLed on nodeb: the client waiting on advance got "
                   f"{type(err).__name__ if err else 'done'} after {told:.1f} s: {err or ev}")
            R.check("the client waiting on advance is told (an error or a done marked lost), within 60 s",
                    err is not None or (ev or {}).get("lost") or (ev or {}).get("error"), ev)
        t = d.gone(60)
        R.check("a killed rank on nodeb ends the job on both hosts (no process left)", t is not None, d.procs())
    finally:
        d.stop()


with tempfile.TemporaryDirectory(prefix="gearsim-2h-") as tmp:
    os.chmod(tmp, 0o755)
    R.guard("two hosts", main, tmp)
cleanup()
R.finish()
