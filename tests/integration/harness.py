# SPDX-License-Identifier: MIT
"""Tiny test harness shared by the integration tests: named checks, a final
`N passed, N failed` line, and a non-zero exit status on failure."""
import contextlib
import hashlib
import json
import os
import shutil
import stat
import sys
import tempfile
import time
import traceback

import zmq


def apply_curve(sock, info):
    """The client keys of the connection file `info` (a loopback daemon's
    own pair, or none): what every legitimate client does."""
    import os
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.abspath(os.path.join(here, "..", ".."))
    path = os.path.join(root, "clients", "python")
    if path not in sys.path:
        sys.path.insert(0, path)
    from gearsim.connection import apply_curve as apply
    if info.get("curve_client_secret_key"):
        apply(sock, info)


class Results:
    def __init__(self, title):
        self.title = title
        self.passed = 0
        self.failed = 0
        self.failures = []
        print(f"# {title}", flush=True)

    def check(self, name, cond, detail=""):
        if cond:
            self.passed += 1
            print(f"ok - {name}", flush=True)
        else:
            self.failed += 1
            self.failures.append(name)
            msg = f"FAIL - {name}"
            if detail:
                msg += ": " + str(detail)[:2000]
            print(msg, flush=True)
        return bool(cond)

    def note(self, text):
        print(f"# {text}", flush=True)

    def skip(self, name, reason):
        print(f"skip - {name}: {reason}", flush=True)

    def guard(self, name, fn, *args, **kw):
        """Run fn; an exception counts as a failure of `name`. Returns fn's value or None."""
        try:
            return fn(*args, **kw)
        except Exception as e:  # noqa: BLE001 - report and continue with the next case
            self.check(name, False, f"{type(e).__name__}: {e}\n{traceback.format_exc(limit=4)}")
            return None

    def seeded_rng(self, env):
        """A random.Random from $env, else from a fresh seed, which is
        printed so that setting $env replays the run."""
        import random
        seed = int(os.environ.get(env) or random.SystemRandom().randrange(1 << 30))
        self.note(f"seed {seed} ({env}={seed} replays it)")
        return random.Random(seed)

    def finish(self):
        if self.failures:
            print("# failed: " + ", ".join(self.failures))
        print(f"{self.passed} passed, {self.failed} failed", flush=True)
        sys.exit(1 if self.failed else 0)


def strict_json(obj):
    """True when obj serialises as JSON without NaN or Infinity."""
    try:
        json.dumps(obj, allow_nan=False)
        return True
    except ValueError:
        return False


def stalled_sub(ctx, info):
    """A telemetry subscriber that connects, subscribes to everything and
    never reads, with tiny buffers (RCVHWM 1, 4 KiB)."""
    s = ctx.socket(zmq.SUB)
    s.setsockopt(zmq.LINGER, 0)
    s.setsockopt(zmq.RCVHWM, 1)
    s.setsockopt(zmq.RCVBUF, 4096)
    s.setsockopt(zmq.SUBSCRIBE, b"")
    apply_curve(s, info)
    s.connect(info["telemetry"])
    return s


def tree_digest(root):
    """Names, types and contents of everything under root (to show that a
    test changed nothing there)."""
    out = {}
    for dirpath, dirs, files in os.walk(root):
        for n in dirs + files:
            p = os.path.join(dirpath, n)
            st = os.lstat(p)
            if stat.S_ISREG(st.st_mode):
                with open(p, "rb") as f:
                    out[p] = ("file", hashlib.sha256(f.read()).hexdigest())
            elif stat.S_ISLNK(st.st_mode):
                out[p] = ("link", os.readlink(p))
            else:
                out[p] = ("other", stat.S_IFMT(st.st_mode))
    return out


def victim_and_data(tmp, content):
    """tmp/outside/victim.txt holding content (what a test must never
    change) and a new 0700 data directory tmp/data: (victim, data)."""
    outside = os.path.join(tmp, "outside")
    os.makedirs(outside)
    victim = os.path.join(outside, "victim.txt")
    with open(victim, "wb") as f:
        f.write(content)
    data = os.path.join(tmp, "data")
    os.makedirs(data, mode=0o700)
    return victim, data


@contextlib.contextmanager
def scratch_dir(prefix):
    """A temporary directory for one test, removed at the end unless
    GEARSIM_KEEP_TMP=1 (then its path is printed)."""
    tmp = tempfile.mkdtemp(prefix=prefix)
    try:
        yield tmp
    finally:
        if os.environ.get("GEARSIM_KEEP_TMP") == "1":
            print(f"# kept {tmp}", flush=True)
        else:
            shutil.rmtree(tmp, ignore_errors=True)


class RawDealer:
    """A bare DEALER socket for sending arbitrary bytes and frames to the daemon."""

    def __init__(self, conn_file, ctx=None):
        with open(conn_file) as f:
            self.info = json.load(f)
        self.ctx = ctx or zmq.Context.instance()
        self.sock = self.ctx.socket(zmq.DEALER)
        self.sock.setsockopt(zmq.LINGER, 0)
        apply_curve(self.sock, self.info)
        self.sock.connect(self.info["command"])

    def send(self, data):
        if isinstance(data, str):
            data = data.encode()
        self.sock.send(data)

    def send_json(self, obj):
        self.send(json.dumps(obj, separators=(",", ":")))

    def send_multipart(self, frames):
        self.sock.send_multipart([f.encode() if isinstance(f, str) else f for f in frames])

    def recv(self, timeout=10.0):
        """The next reply as (frames, parsed last frame or None); (None, None) on timeout."""
        if not self.sock.poll(int(timeout * 1000)):
            return None, None
        frames = self.sock.recv_multipart()
        try:
            return frames, json.loads(frames[-1])
        except ValueError:
            return frames, None

    def request(self, obj, timeout=10.0):
        t0 = time.monotonic()
        self.send_json(obj)
        frames, reply = self.recv(timeout)
        return reply, time.monotonic() - t0

    def close(self):
        self.sock.close(0)


class Probe:
    """Raw DEALER + SUB sockets that keep every message as received, for
    checking the daemon's bytes against the schemas. Events are collected
    whenever the probe waits for something."""

    def __init__(self, conn_file, ctx=None, subscribe=True, prefix="p"):
        from protoschema import strict_loads
        self._loads = strict_loads
        with open(conn_file) as f:
            self.info = json.load(f)
        self.ctx = ctx or zmq.Context.instance()
        self.dealer = self.ctx.socket(zmq.DEALER)
        self.dealer.setsockopt(zmq.LINGER, 0)
        apply_curve(self.dealer, self.info)
        self.dealer.connect(self.info["command"])
        self.sub = None
        self.events = []        # (frames, parsed or None, error text or None)
        self.batches = []       # (frames, parsed or None, error text or None) of each batch message
        self.event_times = []   # arrival time (time.monotonic()) of each event
        self.replies = {}       # id -> (frames, parsed, error)
        self.stray = []         # replies whose id we did not expect
        self.n = 0
        self.prefix = prefix
        if subscribe:
            self.subscribe()

    def subscribe(self, timeout=10.0, single=False):
        """Subscribe to every event; telemetry in batches (the topic `batch`,
        unpacked into self.events one event each, the batch itself kept in
        self.batches) from a daemon that offers them, unless single=True
        (everything, telemetry one event per message)."""
        self.sub = self.ctx.socket(zmq.SUB)
        self.sub.setsockopt(zmq.LINGER, 0)
        self.sub.setsockopt(zmq.RCVHWM, 1000000)
        if self.info.get("telemetry_batch") and not single:
            for t in ("batch", "progress", "done", "heartbeat", "warning", "error"):
                self.sub.setsockopt(zmq.SUBSCRIBE, t.encode())
        else:
            self.sub.setsockopt(zmq.SUBSCRIBE, b"")
        apply_curve(self.sub, self.info)
        self.sub.connect(self.info["telemetry"])
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.pump(0.2)
            if any(p and p.get("type") == "heartbeat" for _, p, _ in self.events):
                return True
        raise TimeoutError("no heartbeat within %g s" % timeout)

    def _parse(self, frames):
        try:
            return self._loads(frames[-1]), None
        except (ValueError, UnicodeDecodeError) as e:
            return None, f"{type(e).__name__}: {e}"

    def pump(self, timeout=0.0):
        """Receive whatever is waiting (up to timeout s for the first message)."""
        poller = zmq.Poller()
        poller.register(self.dealer, zmq.POLLIN)
        if self.sub is not None:
            poller.register(self.sub, zmq.POLLIN)
        got = 0
        wait = int(timeout * 1000)
        while True:
            ready = dict(poller.poll(wait))
            if not ready:
                return got
            wait = 0
            if self.sub in ready:
                frames = self.sub.recv_multipart()
                parsed, err = self._parse(frames)
                evs = parsed.get("events") if frames[0] == b"batch" and isinstance(parsed, dict) else None
                if isinstance(evs, list):
                    self.batches.append((frames, parsed, err))
                    for ev in evs:   # as a single telemetry message would carry it
                        text = json.dumps(ev, allow_nan=False, separators=(",", ":")).encode()
                        self.events.append(([b"telemetry", text], ev, None))
                        self.event_times.append(time.monotonic())
                else:
                    self.events.append((frames, parsed, err))
                    self.event_times.append(time.monotonic())
                got += 1
            if self.dealer in ready:
                frames = self.dealer.recv_multipart()
                parsed, err = self._parse(frames)
                rid = parsed.get("id") if isinstance(parsed, dict) else None
                if rid in self.replies and self.replies[rid] is None:
                    self.replies[rid] = (frames, parsed, err)
                else:
                    self.stray.append((frames, parsed, err))
                got += 1
                return got   # a reply: let the caller look at it, even under a stream of events
            if got >= 5000:
                return got   # a fast run's telemetry never pauses: return now and then

    def send(self, cmd, args=None, rid=None, raw=None):
        """Send a request (or raw bytes/frames); returns the id expected in the reply."""
        if rid is None:
            self.n += 1
            rid = f"{self.prefix}{self.n}"
        self.replies[rid] = None
        if raw is not None:
            if isinstance(raw, list):
                self.dealer.send_multipart(raw)
            else:
                self.dealer.send(raw)
        else:
            msg = {"v": 1, "id": rid, "cmd": cmd}
            if args is not None:
                msg["args"] = args
            self.dealer.send(json.dumps(msg, separators=(",", ":")).encode())
        return rid

    def wait(self, rid, timeout=30.0):
        """(frames, parsed, parse error) of the reply to rid; raises TimeoutError."""
        deadline = time.monotonic() + timeout
        while self.replies.get(rid) is None:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no reply to {rid} within {timeout:g} s")
            self.pump(min(left, 0.5))
        return self.replies[rid]

    def wait_stray(self, timeout=10.0):
        """The next reply with an unexpected id (e.g. null after bad JSON)."""
        deadline = time.monotonic() + timeout
        while not self.stray:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no reply within {timeout:g} s")
            self.pump(min(left, 0.5))
        return self.stray.pop(0)

    def call(self, cmd, args=None, timeout=30.0):
        """Send and wait; returns the parsed reply."""
        return self.wait(self.send(cmd, args), timeout)[1]

    def wait_event(self, pred, timeout=60.0, start=0):
        """First parsed event at index >= start satisfying pred; raises TimeoutError."""
        deadline = time.monotonic() + timeout
        i = start
        while True:
            while i < len(self.events):
                p = self.events[i][1]
                if p is not None and pred(p):
                    return p
                i += 1
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("event not seen within %g s" % timeout)
            self.pump(min(left, 0.5))

    def close(self):
        self.dealer.close(0)
        if self.sub is not None:
            self.sub.close(0)


def json_diff(a, b, path=""):
    """Paths where two parsed JSON values differ (floats compared with ==); empty when equal."""
    out = []
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in one")
            else:
                out += json_diff(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{path}: lengths {len(a)} vs {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            out += json_diff(x, y, f"{path}[{i}]")
    elif a != b:
        rel = ""
        if isinstance(a, float) and isinstance(b, float) and max(abs(a), abs(b)) > 0:
            rel = f" (rel {abs(a - b) / max(abs(a), abs(b)):.2e})"
        out.append(f"{path}: {a!r} vs {b!r}{rel}")
    return out


def snap(client):
    """The client's simulation state, without its bookkeeping: what must agree bit for bit
    between runs that should be the same."""
    s = client.state()
    return {k: s[k] for k in ("step", "time", "energy", "bodies", "meshes") if k in s}


def ranks_run(R, dmod, label, ranks, scene, steps, timeout=600):
    """Run `scene` `steps` steps on a daemon of `ranks` ranks: the telemetry
    by step (time, energy, bodies, meshes, planets) and the final state, as
    JSON strings, for check_same_at_ranks."""
    with dmod.Daemon(ranks=ranks) as d:
        with d.client() as c:
            c.load(scene=scene)
            tel = []
            done = c.advance(steps=steps, on_telemetry=tel.append, timeout=timeout)
            R.check(f"{label} -n {ranks}: run completed", not done.get("cancelled") and not done.get("lost"), done)
            st = snap(c)
    return {ev["step"]: json.dumps({k: ev.get(k) for k in ("time", "energy", "bodies", "meshes", "planets")},
                                   sort_keys=True) for ev in tel}, json.dumps(st, sort_keys=True)


def check_same_at_ranks(R, label, runs, ranks=(2, 3)):
    """runs: {ranks: (telemetry by step, final state)}, as JSON strings; check
    that each of `ranks` gives the -n 1 run's telemetry and final state bit
    for bit."""
    t1, f1 = runs[1]
    for n in ranks:
        if runs.get(n):
            tn, fn = runs[n]
            same = sorted(t1) == sorted(tn) and all(t1[k] == tn[k] for k in t1)
            R.check(f"{label}: telemetry identical bit for bit at -n 1 and -n {n}", same,
                    [k for k in sorted(t1) if t1.get(k) != tn.get(k)][:5])
            R.check(f"{label}: final state identical at -n 1 and -n {n}", f1 == fn)


def replay_after_restore(client, path, before, after, timeout=600):
    """Advance `before` steps, checkpoint to `path`, advance `after` steps and
    take snap(); restore `path`, advance the same `after` steps and take
    snap() again. Returns both snapshots: equal when checkpoint and restore
    carry the whole state."""
    client.advance(steps=before, timeout=timeout)
    client.checkpoint(path)
    client.advance(steps=after, timeout=timeout)
    a = snap(client)
    client.restore(path)
    client.advance(steps=after, timeout=timeout)
    return a, snap(client)


def _proc_net_listen():
    """inode -> (address, port) of every listening TCP socket of the machine
    (/proc/net/tcp and tcp6, state 0A)."""
    import socket
    import struct
    out = {}
    for name, fam in (("tcp", socket.AF_INET), ("tcp6", socket.AF_INET6)):
        try:
            with open(f"/proc/net/{name}") as f:
                lines = f.read().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            parts = line.split()
            if len(parts) < 10 or parts[3] != "0A":
                continue
            hexaddr, hexport = parts[1].split(":")
            raw = bytes.fromhex(hexaddr)
            # the kernel prints each 32-bit word in host (little-endian) order
            raw = b"".join(struct.pack("<I", struct.unpack(">I", raw[i:i + 4])[0]) for i in range(0, len(raw), 4))
            out[int(parts[9])] = (socket.inet_ntop(fam, raw), int(hexport, 16))
    return out


def listening_sockets(pids=None):
    """(address, port) of the listening TCP sockets owned by `pids` (every
    process when None), from /proc/<pid>/fd and /proc/net/tcp{,6}: what a
    local user can see without any file of the daemon."""
    import os
    listen = _proc_net_listen()
    if pids is None:
        return sorted(set(listen.values()))
    found = set()
    for p in pids:
        try:
            fds = os.listdir(f"/proc/{p}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                target = os.readlink(f"/proc/{p}/fd/{fd}")
            except OSError:
                continue
            if target.startswith("socket:["):
                ino = int(target[8:-1])
                if ino in listen:
                    found.add(listen[ino])
    return sorted(found)
