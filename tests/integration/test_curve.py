#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""CURVE authentication and path confinement against the real daemon.

Keys come from `gearctl keys`. With --curve-server-key/--curve-allow: the
allowed client key gets replies and events; a key not on the allow-list, a
client without a key, and a client with the wrong server key get nothing (no
reply, no event: a timeout). A non-loopback --bind without CURVE is refused
at start. Paths: '..', absolute paths and symlinks leading out of the data
directory (a linked directory for writes, a linked file for reads, a link as
the file written) are refused, and nothing is written outside."""
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import zmq  # noqa: E402

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from gearsim.connection import read_key_file  # noqa: E402
from harness import Results, apply_curve  # noqa: E402
from protoschema import Proto  # noqa: E402

R = Results("test_curve: CURVE allow-list, no key / wrong key get nothing, paths stay inside")
GEARCTL = os.path.join(dmod.SOURCE_ROOT, "clients", "python", "gearctl")
SILENCE = 3.0   # seconds a refused client waits for a reply that must not come


def make_keys(d, *names):
    r = subprocess.run(["/usr/bin/python3", GEARCTL, "keys", *names, "--dir", d],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=60)
    R.check("gearctl keys exits 0", r.returncode == 0, r.stdout)
    for n in names:
        st = os.stat(os.path.join(d, n + ".key"))
        R.check(f"{n}.key is mode 0600", (st.st_mode & 0o777) == 0o600, oct(st.st_mode))
    return {n: os.path.join(d, n + ".key") for n in names}


def raw_sockets(info, key=None, server_key=None):
    """A DEALER and a SUB on the daemon, CURVE client with `key` (a .key file) or none."""
    ctx = zmq.Context.instance()
    socks = []
    for kind, ep in ((zmq.DEALER, info["command"]), (zmq.SUB, info["telemetry"])):
        s = ctx.socket(kind)
        s.setsockopt(zmq.LINGER, 0)
        if key:
            pub, sec = read_key_file(key)
            s.setsockopt(zmq.CURVE_SERVERKEY, (server_key or info["curve_server_key"]).encode())
            s.setsockopt(zmq.CURVE_PUBLICKEY, pub)
            s.setsockopt(zmq.CURVE_SECRETKEY, sec)
        if kind == zmq.SUB:
            s.setsockopt(zmq.SUBSCRIBE, b"")
        s.connect(ep)
        socks.append(s)
    return socks


def silent(name, info, key=None, server_key=None):
    """The client sends hello and listens for events: nothing must arrive."""
    dealer, sub = raw_sockets(info, key, server_key)
    try:
        dealer.send(json.dumps({"v": 1, "id": "h1", "cmd": "hello"}).encode())
        t0 = time.monotonic()
        got = []
        poller = zmq.Poller()
        poller.register(dealer, zmq.POLLIN)
        poller.register(sub, zmq.POLLIN)
        while time.monotonic() - t0 < SILENCE:   # heartbeats come every second
            for s, _ in poller.poll(200):
                got.append(s.recv_multipart())
        R.check(f"{name}: no reply and no event within {SILENCE:g} s", not got, got[:3])
    finally:
        dealer.close(0)
        sub.close(0)


def config_case(tmp):
    """The documented deploy/gearsimd.conf, with CURVE keys, read by --config."""
    keys = make_keys(tmp, "cserver", "cclient")
    conf = os.path.join(tmp, "curve.conf")
    with open(os.path.join(dmod.SOURCE_ROOT, "deploy", "gearsimd.conf")) as f:
        text = f.read()
    text = text.replace("connection-file = /run/gearsim/gearsimd.json", "").replace("data-dir = /var/lib/gearsim", "")
    text += f"curve-server-key = {keys['cserver']}\ncurve-allow = {os.path.join(tmp, 'cclient.pub')}\n"
    with open(conf, "w") as f:
        f.write(text)
    with dmod.Daemon(ranks=1, extra_args=["--config", conf], curve_key=keys["cclient"]) as d:
        R.check("deploy/gearsimd.conf + CURVE keys via --config: served with the key",
                d.hello.get("protocol") == 1 and bool(d.connection.get("curve_server_key")), d.connection)
        silent("--config daemon, no key", d.connection)


def curve_case(tmp):
    keys = make_keys(tmp, "server", "alice", "mallory")
    allow = os.path.join(tmp, "allowed")
    os.makedirs(allow)
    os.rename(os.path.join(tmp, "alice.pub"), os.path.join(allow, "alice.pub"))
    args = ["--curve-server-key", keys["server"], "--curve-allow", allow]
    with dmod.Daemon(ranks=1, extra_args=args, curve_key=keys["alice"]) as d:
        info = d.connection
        srv_pub = read_key_file(keys["server"])[0].decode()
        R.check("connection file carries the server public key", info.get("curve_server_key") == srv_pub, info)
        R.check("connection file has no secret", "secret" not in json.dumps(info).lower(), info)
        errs = Proto().errors("connection.json", info)
        und = Proto().undocumented("connection.json", info)
        R.check("connection file with CURVE validates against proto/v1/connection.json (no undocumented field)",
                not errs and not und, (errs, und))
        with d.client(timeout=5.0, retries=0) as c:
            h = c.hello()
            R.check("allowed key: hello answered", h.get("protocol") == 1, h)
            c.subscribe(timeout=5.0)
            c.load(builtin="pair")
            done = c.advance(steps=200)
            R.check("allowed key: advance runs and its done event arrives", done.get("steps") == 200, done)
        silent("no key", info)
        silent("key not on the allow-list", info, key=keys["mallory"])
        silent("the server's own key pair as a client", info, key=keys["server"])
        wrong_server = read_key_file(keys["mallory"])[0].decode()
        silent("allowed key but the wrong server key", info, key=keys["alice"], server_key=wrong_server)
        try:
            with gearsim.Client(d.conn_file, timeout=2.0, retries=0) as c:
                c.hello()
            R.check("client without a key: refused", False, "got a reply")
        except gearsim.GearsimError as e:
            R.check("client without a key: clear error before sending", e.code == "invalid_argument", e)
        with d.client(timeout=5.0, retries=0) as c:
            R.check("allowed client still served after the refused ones", c.status().get("state") == "loaded")
        log = d.log_tail()
        R.check("refusals are logged", "refused a client" in log, log)


def bind_refused(tmp):
    conn = os.path.join(tmp, "remote.json")
    env = dict(os.environ, **dmod.MPI_ENV)

    def daemon(*args):
        """gearsimd on one rank with these arguments, run to its exit (output in .stdout)."""
        return subprocess.run(["mpirun", "-n", "1", dmod.gearsimd_path(), *args], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=60, env=env)

    r = daemon("--connection-file", conn, "--data-dir", tmp, "--bind", "0.0.0.0")
    R.check("--bind 0.0.0.0 without CURVE: exits non-zero", r.returncode != 0, r.returncode)
    R.check("--bind 0.0.0.0 without CURVE: says why", "without CURVE" in r.stdout, r.stdout[-2000:])
    R.check("--bind 0.0.0.0 without CURVE: no connection file", not os.path.exists(conn))
    r = daemon("--connection-file", conn, "--data-dir", tmp, "--curve-server-key",
               os.path.join(tmp, "nonexistent.key"), "--curve-allow", tmp)
    R.check("missing server key file: exits non-zero with a message",
            r.returncode != 0 and "nonexistent.key" in r.stdout, r.stdout[-2000:])
    conf = os.path.join(tmp, "gearsimd.conf")
    with open(conf, "w") as f:
        f.write("# test\nbind = \"0.0.0.0\"\n")
    r = daemon("--config", conf, "--connection-file", conn, "--data-dir", tmp)
    R.check("--config with bind = 0.0.0.0 and no CURVE: refused", r.returncode != 0 and "without CURVE" in r.stdout,
            r.stdout[-2000:])
    with open(conf, "w") as f:
        f.write("bind = 127.0.0.1\ncolour = blue\n")
    r = daemon("--config", conf, "--connection-file", conn, "--data-dir", tmp)
    R.check("--config with an unknown key: refused naming the line", r.returncode != 0 and ":2:" in r.stdout,
            r.stdout[-2000:])


def paths_case(tmp):
    outside = os.path.join(tmp, "outside")
    os.makedirs(outside)
    secret = os.path.join(outside, "secret.txt")
    with open(secret, "w") as f:
        f.write("not for clients\n")
    with dmod.Daemon(ranks=1) as d:
        os.symlink(outside, d.path("escape"))                      # a directory link leading out
        os.symlink(secret, d.path("link.txt"))                     # a file link leading out
        os.symlink(os.path.join(outside, "new.h5"), d.path("dangling.h5"))   # a link as the written file
        os.makedirs(d.path("inside"))
        os.symlink(d.path("inside"), d.path("ok-link"))            # a link that stays inside
        with d.client(timeout=10.0, retries=0) as c:
            c.load(builtin="pair")
            c.advance(steps=10)

            def refused(name, fn, *a, **kw):
                try:
                    fn(*a, **kw)
                    R.check(f"{name}: refused", False, "accepted")
                except gearsim.GearsimError as e:
                    R.check(f"{name}: refused ({e.code}, field {e.field})",
                            e.code in ("out_of_range", "not_found", "invalid_field", "invalid_argument")
                            and (e.field or "").startswith("args."), e)

            refused("fetch ../outside/secret.txt", c.fetch, "../outside/secret.txt")
            refused("fetch absolute path", c.fetch, secret)
            refused("fetch a/../../outside/secret.txt", c.fetch, "inside/../../outside/secret.txt")
            refused("fetch through a directory symlink", c.fetch, "escape/secret.txt")
            refused("fetch a file symlink leading out", c.fetch, "link.txt")
            refused("checkpoint into a directory symlink leading out", c.checkpoint, "escape/c.h5")
            refused("checkpoint onto a dangling symlink", c.checkpoint, "dangling.h5")
            refused("record into a directory symlink leading out", c.record, "escape/r.h5")
            refused("record ../r.h5", c.record, "../r.h5")
            refused("restore through a directory symlink", c.restore, "escape/secret.txt")
            R.check("nothing was written outside the data directory",
                    sorted(os.listdir(outside)) == ["secret.txt"], os.listdir(outside))
            # Every component is opened with O_NOFOLLOW (docs/RELIABILITY.md,
            # "File rules"): a symlink is refused even when it stays inside.
            refused("checkpoint through a directory symlink that stays inside", c.checkpoint, "ok-link/c.h5")
            R.check("... and nothing was written through it", not os.path.exists(d.path("inside/c.h5")))
            R.check("daemon alive after the refused paths", c.status().get("state") == "loaded")
        # The reply cache is keyed by (client identity, id): a client with a
        # long routing id (up to 255 bytes) must still get its own replies.
        ctx = zmq.Context.instance()
        s = ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.ROUTING_ID, b"L" * 255)
        apply_curve(s, d.connection)
        s.connect(d.connection["command"])
        got = []
        for rid, cmd in (("a1", "hello"), ("a2", "status"), ("a3", "nope")):
            s.send(json.dumps({"v": 1, "id": rid, "cmd": cmd}).encode())
            got.append(json.loads(s.recv()) if s.poll(5000) else None)
        s.close(0)
        R.check("255-byte client identity: each request gets its own reply",
                [g and g.get("id") for g in got] == ["a1", "a2", "a3"] and got[2].get("ok") is False, got)


with tempfile.TemporaryDirectory(prefix="gearsim-curve-") as tmp:
    R.guard("CURVE allow-list", curve_case, tmp)
    R.guard("remote bind without CURVE is refused", bind_refused, tmp)
    R.guard("path confinement", paths_case, tmp)
    R.guard("configuration file", config_case, tmp)
R.finish()
