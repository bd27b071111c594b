#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""A hostile local user who knows only the daemon's ports (read from
/proc/net/tcp, as any user can; not from the 0600 connection file) gets no
reply to hello, fetch or shutdown and no event, while the legitimate client
(keys from the connection file) goes on being served. The connection file is
0600 in a 0700 directory. --insecure-loopback, the documented opt-out,
answers the same hostile user: the check above is able to fail."""
import os
import stat
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import zmq  # noqa: E402

import daemon as dmod  # noqa: E402
from harness import Results, listening_sockets  # noqa: E402

R = Results("test_local_trust: loopback authentication on by default")


def daemon_ports(d):
    pids = [p for p in d.session_pids() if open(f"/proc/{p}/comm").read().strip() == "gearsimd"]
    return [port for addr, port in listening_sockets(pids) if addr.startswith("127.")]


def hostile(ports, wait=3.0, curve=False):
    """Try every port as a command socket (hello, fetch, shutdown) and as a
    telemetry socket; returns (replies, events) received."""
    ctx = zmq.Context()
    socks, subs = [], []
    for port in ports:
        ep = f"tcp://127.0.0.1:{port}"
        s = ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        if curve:   # a CURVE client with keys of its own, guessing at the server key
            pub, sec = zmq.curve_keypair()
            s.setsockopt(zmq.CURVE_SERVERKEY, zmq.curve_keypair()[0])
            s.setsockopt(zmq.CURVE_PUBLICKEY, pub)
            s.setsockopt(zmq.CURVE_SECRETKEY, sec)
        s.connect(ep)
        for cmd, args in (("hello", {}), ("fetch", {"path": "conn.json"}), ("shutdown", {})):
            s.send_json({"v": 1, "id": f"h-{cmd}", "cmd": cmd, "args": args})
        socks.append(s)
        sub = ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.connect(ep)
        subs.append(sub)
    replies, events = [], []
    deadline = time.monotonic() + wait
    while time.monotonic() < deadline:
        for s in socks:
            while s.poll(0):
                replies.append(s.recv_multipart())
        for s in subs:
            while s.poll(0):
                events.append(s.recv_multipart())
        time.sleep(0.05)
    for s in socks + subs:
        s.close(0)
    ctx.term()
    return replies, events


def secure():
    with dmod.Daemon(ranks=1) as d:
        ports = daemon_ports(d)
        R.check("the daemon's two ports are visible in /proc/net/tcp", len(ports) == 2, ports)
        conn_mode = stat.S_IMODE(os.stat(d.conn_file).st_mode)
        dir_mode = stat.S_IMODE(os.stat(os.path.dirname(d.conn_file)).st_mode)
        R.check("the connection file is 0600", conn_mode == 0o600, oct(conn_mode))
        R.check("its directory is 0700", dir_mode == 0o700, oct(dir_mode))
        keys = {k: v for k, v in d.connection.items() if k.startswith("curve_")}
        R.check("the connection file holds the server key and a client key pair",
                all(len(keys.get(k, "")) == 40 for k in
                    ("curve_server_key", "curve_client_public_key", "curve_client_secret_key")), sorted(keys))
        with d.client() as c:
            c.load(builtin="pair")
            c.advance(steps=10)
        for curve in (False, True):
            kind = "with keys of its own" if curve else "without keys"
            replies, events = hostile(ports, curve=curve)
            R.check(f"hostile user {kind}: no reply to hello/fetch/shutdown", not replies, replies[:3])
            R.check(f"hostile user {kind}: no event", not events, events[:3])
            R.check(f"hostile user {kind}: the daemon is still running", d.alive())
        with d.client() as c:
            st = c.status()
            R.check("the legitimate client is still served (state and step kept)",
                    st.get("state") == "loaded" and st.get("step") == 10, st)
            c.subscribe()
            ev = c.next_event(timeout=5.0)
            R.check("the legitimate client receives events (a heartbeat)",
                    ev is not None and ev.get("type") == "heartbeat", ev)


def insecure():
    with dmod.Daemon(ranks=1, extra_args=["--insecure-loopback"]) as d:
        R.check("--insecure-loopback: no keys in the connection file",
                not any(k.startswith("curve_") for k in d.connection), sorted(d.connection))
        replies, _ = hostile(daemon_ports(d), wait=3.0)
        R.check("--insecure-loopback: the same hostile user is answered (the opt-out is real)",
                len(replies) >= 2, replies[:3])


R.guard("authenticated loopback daemon", secure)
R.guard("--insecure-loopback daemon", insecure)
R.finish()
