#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The Slurm scripts under a real Slurm: munged, slurmctld and slurmd
(Debian's slurm-wlm and munge) started as a one-node cluster on this
machine from tests/integration/slurm/slurm.conf.in, every file (key,
state, spool, logs, sockets) in a temporary directory, on ports picked free
for this run; nothing system-wide is touched and every daemon is stopped at
the end.

Checks: `sbatch deploy/gearsimd.slurm` brings the daemon up and publishes
its connection file; a client with its own CURVE key connects through it,
runs a scene and shuts the daemon down, and the job ends; a second job is
stopped by `scancel` while an advance records: the client gets its `done`
marked cancelled, the record is readable up to that step, no rank is left,
the connection file is gone; `deploy/sweep_slurm.sh` runs a sweep as a job
array of 4 tasks and its collect step, and the merged table equals the
daemon's `sweep` table on the same arguments. Exit 77 (skipped) where the
packages are missing or the daemons cannot run."""
import atexit
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

SKIP = 77
HERE = os.path.dirname(os.path.abspath(__file__))
_procs = []


def need():
    for tool in ("munged", "slurmctld", "slurmd", "sbatch", "scancel", "squeue", "scontrol"):
        if shutil.which(tool) is None:
            return f"{tool} not found (Debian packages slurmctld, slurmd, slurm-client, munge)"
    if os.geteuid() != 0:
        return "slurmd must run as root"
    return None


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stop_all():
    for p in reversed(_procs):
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    _procs.clear()


atexit.register(stop_all)
signal.signal(signal.SIGTERM, lambda *a: sys.exit(1))
why = need()
if why:
    print(f"skip: Slurm test: {why}", flush=True)
    sys.exit(SKIP)

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_slurm: the daemon and sweep scripts under a one-node Slurm cluster")
GEARCTL = os.path.join(dmod.SOURCE_ROOT, "clients", "python", "gearctl")
SPEC = {"builtin": "planetary_sweep",
        "parameters": [{"path": "driver_rpm", "from": 17000, "to": 25000, "points": 8}],
        "settle": 0.0006, "measure": 0.0006, "time_step": 2e-6}


class Cluster:
    def __init__(self, tmp):
        self.dir = tmp
        host = socket.gethostname()
        for d in ("munge", "state", "spool"):
            os.makedirs(os.path.join(tmp, d), mode=0o700)
        key = os.path.join(tmp, "munge", "munge.key")
        with open(key, "wb") as f:
            f.write(os.urandom(128))
        os.chmod(key, 0o400)
        with open(os.path.join(HERE, "slurm", "slurm.conf.in")) as f:
            conf = f.read()
        for k, v in (("DIR", tmp), ("HOST", host), ("NODE", host), ("USER", "root"),
                     ("CTLD_PORT", str(free_port())), ("SLURMD_PORT", str(free_port()))):
            conf = conf.replace(f"@{k}@", v)
        self.conf = os.path.join(tmp, "slurm.conf")
        with open(self.conf, "w") as f:
            f.write(conf)
        open(os.path.join(tmp, "plugstack.conf"), "w").close()
        self.env = dict(os.environ, SLURM_CONF=self.conf)
        log = open(os.path.join(tmp, "daemons.out"), "wb")
        m = os.path.join(tmp, "munge")
        self.start(["munged", "-F", "--force", f"--socket={m}/munge.socket", f"--key-file={key}",
                    f"--pid-file={m}/munged.pid", f"--log-file={m}/munged.log", f"--seed-file={m}/seed"], log)
        self.wait_for(lambda: os.path.exists(f"{m}/munge.socket"), 20, "munged socket")
        self.start(["slurmctld", "-D", "-i", "-f", self.conf], log)
        self.start(["slurmd", "-D", "-f", self.conf, "-N", host], log)
        self.wait_for(self.node_idle, 60, "the node idle in sinfo")

    def start(self, cmd, log):
        p = subprocess.Popen(cmd, env=self.env, stdout=log, stderr=log, stdin=subprocess.DEVNULL,
                             start_new_session=True)
        _procs.append(p)

    def wait_for(self, pred, timeout, what):
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            if pred():
                return
            if any(p.poll() is not None for p in _procs):
                break
            time.sleep(0.3)
        raise RuntimeError(f"no {what} after {timeout} s:\n{self.logs()}")

    def logs(self):
        out = []
        for n in ("daemons.out", "slurmctld.log", "slurmd.log", "munge/munged.log"):
            try:
                with open(os.path.join(self.dir, n), "rb") as f:
                    out.append(f"--- {n}\n" + f.read()[-1500:].decode(errors="replace"))
            except OSError:
                pass
        return "\n".join(out)

    def run(self, *cmd, env=None, cwd=None):
        return subprocess.run(list(cmd), env=dict(self.env, **(env or {})), cwd=cwd or self.dir,
                              capture_output=True, text=True, timeout=60)

    def node_idle(self):
        r = self.run("sinfo", "-h", "-o", "%T")
        return r.returncode == 0 and r.stdout.strip() in ("idle", "mixed")

    def jobs(self):
        r = self.run("squeue", "-h", "-o", "%i %T")
        return r.stdout.split("\n") if r.stdout.strip() else []

    def wait_jobs_gone(self, timeout):
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            if not self.jobs():
                return time.monotonic() - t0
            time.sleep(0.5)
        return None


def gearsimd_pids(job, conn):
    """The gearsimd processes of Slurm job `job` whose connection file is
    `conn` (other suites on the same machine run Slurm jobs of their own,
    numbered by their own controller)."""
    out = []
    for n in os.listdir("/proc"):
        if n.isdigit():
            try:
                env = open(f"/proc/{n}/environ", "rb").read().split(b"\0")
                if os.path.basename(os.readlink(f"/proc/{n}/exe")) == "gearsimd" and \
                        f"SLURM_JOB_ID={job}".encode() in env and f"GEARSIM_CONNECTION={conn}".encode() in env:
                    out.append(int(n))
            except OSError:
                pass
    return out


def alive(pids, timeout):
    """pids still running (state not zombie) after up to timeout s, with their state."""
    t_end = time.monotonic() + timeout
    while True:
        left = []
        for p in pids:
            try:
                with open(f"/proc/{p}/stat") as f:
                    st = f.read().rsplit(")", 1)[1].split()[0]
                if st != "Z":
                    left.append((p, st))
            except OSError:
                pass
        if not left or time.monotonic() > t_end:
            return left
        time.sleep(0.2)


def submit_daemon(cl, tmp, name, ports=None):
    """sbatch gearsimd.slurm (ports: (command, telemetry) to fix); returns
    (job id, connection file, data dir)."""
    conn = os.path.join(tmp, "conn", f"{name}.json")
    data = os.path.join(tmp, f"data-{name}")
    env = {"GEARSIMD": dmod.gearsimd_path(), "GEARSIM_KEYS": os.path.join(tmp, "keys"), "GEARSIM_DATA": data,
           "GEARSIM_CONNECTION": conn, "GEARSIM_BIND": "127.0.0.1",
           "GEARSIM_LOOPBACK_PRELOAD": dmod.loopback_preload()}
    if ports:
        env.update(GEARSIM_COMMAND_PORT=str(ports[0]), GEARSIM_TELEMETRY_PORT=str(ports[1]))
    r = cl.run("sbatch", "--parsable", os.path.join(dmod.SOURCE_ROOT, "deploy", "gearsimd.slurm"), env=env)
    if r.returncode:
        raise RuntimeError(f"sbatch: {r.stderr}")
    jid = r.stdout.strip().split(";")[0]
    t_end = time.monotonic() + 90
    while not os.path.exists(conn):
        if time.monotonic() > t_end or not any(jid in j for j in cl.jobs()):
            log = os.path.join(tmp, f"gearsimd-{jid}.log")
            text = open(log).read()[-2000:] if os.path.exists(log) else "(no job log)"
            raise RuntimeError(f"job {jid}: no connection file {conn}; jobs {cl.jobs()}\n{text}\n{cl.logs()}")
        time.sleep(0.3)
    return jid, conn, data


def client(conn, tmp):
    t_end = time.monotonic() + 30
    while True:
        try:
            c = dmod.gearsim.Client(conn, timeout=10.0, retries=0, curve_key=os.path.join(tmp, "me.key"))
            c.hello()
            return c
        except dmod.gearsim.GearsimError:
            if time.monotonic() > t_end:
                raise
            time.sleep(0.3)


def main(tmp):
    try:
        cl = Cluster(tmp)
    except (RuntimeError, OSError) as e:
        print(f"skip: Slurm test: the one-node cluster does not come up here: {e}", flush=True)
        stop_all()
        sys.exit(SKIP)
    R.check("one-node cluster up: munged, slurmctld, slurmd; the node idle", cl.node_idle())
    # Keys as the script's header says: a server pair, one client allowed.
    keys = os.path.join(tmp, "keys")
    for args in (["keys", "server", "--dir", keys], ["keys", "me", "--dir", tmp]):
        r = subprocess.run([sys.executable, GEARCTL] + args, capture_output=True, text=True)
        R.check(f"gearctl {' '.join(args[:2])}", r.returncode == 0, r.stderr[-300:])
    os.makedirs(os.path.join(keys, "allowed"), exist_ok=True)
    shutil.copy(os.path.join(tmp, "me.pub"), os.path.join(keys, "allowed", "me.pub"))

    # 1. Daemon job, client run, shutdown.
    ports = (free_port(), free_port())
    jid, conn, data = submit_daemon(cl, tmp, "one", ports)
    R.check(f"sbatch gearsimd.slurm: job {jid} publishes its connection file", os.path.exists(conn))
    with open(conn) as f:
        info = json.load(f)
    R.check("GEARSIM_COMMAND_PORT and GEARSIM_TELEMETRY_PORT fix the daemon's ports",
            info.get("command") == f"tcp://127.0.0.1:{ports[0]}" and
            info.get("telemetry") == f"tcp://127.0.0.1:{ports[1]}", info.get("command"))
    with client(conn, tmp) as c:
        hello = c.hello()
        R.check("the client connects through the published file (CURVE with its own key)",
                hello.get("ranks") == 4, hello)
        c.load(builtin="pair")
        done = c.advance(steps=200, timeout=300)
        R.check("a scene runs in the job", done.get("steps") == 200, done)
        c.shutdown()
    t = cl.wait_jobs_gone(60)
    R.check("shutdown ends the job", t is not None, cl.jobs())

    # 2. scancel while an advance records.
    jid, conn, data = submit_daemon(cl, tmp, "two")
    with client(conn, tmp) as c:
        c.load(builtin="pair")
        c.record("run.h5")
        c.subscribe()
        rid = c.send("advance", {"steps": 50_000_000})
        c.wait_reply(rid)
        t_end = time.monotonic() + 2.0
        while time.monotonic() < t_end:
            c.next_event(timeout=0.2)
        ranks = gearsimd_pids(jid, conn)
        r = cl.run("scancel", jid)
        R.check("scancel accepted", r.returncode == 0, r.stderr)
        done, t_end = None, time.monotonic() + 60
        while done is None and time.monotonic() < t_end:
            ev = c.next_event(timeout=0.5)
            if ev and ev.get("type") == "done" and ev.get("parent_id") == rid:
                done = ev
    R.check("scancel: the running advance's done arrives, cancelled",
            done is not None and done.get("cancelled") is True, done)
    t = cl.wait_jobs_gone(90)
    R.check("scancel: the job ends", t is not None, cl.jobs())
    left = alive(ranks, 15)
    R.check(f"scancel: no rank left ({len(ranks)} ranks ran)", len(ranks) == 4 and not left, left)
    R.check("scancel: the connection file is removed", not os.path.exists(conn))
    import h5py
    with h5py.File(os.path.join(data, "run.h5"), "r") as f:
        steps = f["telemetry/step"][:]
    R.check(f"scancel: the record is readable up to the cancelled step ({len(steps)} rows)",
            len(steps) > 10 and done is not None and int(steps[-1]) <= done.get("step", 0), (len(steps), done))
    log = open(os.path.join(tmp, f"gearsimd-{jid}.log")).read()
    R.note("job log tail: " + " | ".join(log.strip().splitlines()[-3:]))

    # 3. The sweep as a job array, against the daemon's table.
    spec = os.path.join(tmp, "sweep.json")
    with open(spec, "w") as f:
        json.dump(SPEC, f)
    out = os.path.join(tmp, "sweep-out")
    r = cl.run(os.path.join(dmod.SOURCE_ROOT, "deploy", "sweep_slurm.sh"), spec, out, "4",
               env={"GEARSIM_SWEEP": os.path.join(dmod.BUILD_ROOT, "src", "tools", "gearsim-sweep")})
    R.check("sweep_slurm.sh submits the array and its collect step", r.returncode == 0, r.stderr)
    R.note(r.stdout.strip())
    t = cl.wait_jobs_gone(300)
    R.check("the array and the collect step finish", t is not None, cl.jobs())
    parts = sorted(n for n in os.listdir(out) if n.startswith("part-")) if os.path.isdir(out) else []
    R.check("4 array tasks wrote their parts", len(parts) == 4, parts)
    with dmod.Daemon(ranks=1) as d, d.client(timeout=60) as c:
        c.subscribe()
        rid = c.send("sweep", dict(SPEC, path="ref"))
        c.wait_reply(rid)
        c.wait_done(rid, timeout=600)
        ref = open(d.path("ref.csv")).read()
    merged = open(os.path.join(out, "sweep.csv")).read() if os.path.exists(os.path.join(out, "sweep.csv")) else ""
    R.check("the merged table is byte-identical to the daemon's sweep table",
            merged == ref and len(ref.splitlines()) == 9, merged[:300] + " | " + ref[:300])


with tempfile.TemporaryDirectory(prefix="gearsim-slurm-") as tmp:
    os.chmod(tmp, 0o755)
    R.guard("Slurm", main, tmp)
    stop_all()
R.finish()
