# SPDX-License-Identifier: MIT
"""gearsim.Client: commands over a DEALER socket, events over a SUB socket.

The protocol is docs/reference/protocol.md (schemas in proto/v1). A request is one JSON
frame {v, id, cmd, args}; the reply carries the same id. Retries resend the
very same frame (same id), so the daemon answers them from its reply cache
and never executes a command twice. Events arrive as two frames, topic then
JSON. Unknown fields in replies and events are ignored (kept in the dicts).
"""
import base64
import collections
import itertools
import json
import os
import secrets
import tempfile
import time as _time

import zmq

from .connection import apply_curve, daemon_stopped, default_connection_file, read_connection_file
from .errors import GearsimError, GearsimTimeout

PROTOCOL = 1
EVENT_TYPES = ("telemetry", "progress", "done", "heartbeat", "warning", "error")
FETCH_CHUNK = 1 << 20   # the protocol's maximum fetch length


def _umask():
    """The process's umask (read by setting it and back)."""
    m = os.umask(0)
    os.umask(m)
    return m


class Client:
    """A connection to a running gearsimd.

    connection_file -- path of the daemon's connection file (default: see
                       gearsim.default_connection_file())
    timeout         -- seconds to wait for one reply before resending it
    retries         -- how many times a request is resent (same id) before
                       GearsimTimeout is raised
    curve_key       -- client key for a daemon that requires CURVE (its
                       connection file has `curve_server_key`): a `gearctl
                       keys` .key file or a (public, secret) Z85 pair;
                       default the client pair of a loopback daemon's
                       connection file, else $GEARSIM_CURVE_KEY. An unknown
                       key gets no reply at all (GearsimTimeout).

    Every command method returns the reply's `result` (a dict) or raises
    GearsimError(code, message, field). Not thread-safe: use one Client per
    thread (ZeroMQ sockets must not be shared between threads).
    """

    def __init__(self, connection_file=None, timeout=10.0, retries=2, context=None, curve_key=None):
        self.connection_file = connection_file or default_connection_file()
        self.info = read_connection_file(self.connection_file)
        self.session = self.info.get("session")
        self.timeout = timeout
        self.retries = retries
        self._ctx = context or zmq.Context.instance()
        self._cmd = self._ctx.socket(zmq.DEALER)
        self._cmd.setsockopt(zmq.LINGER, 0)
        self.curve_key = curve_key
        try:
            apply_curve(self._cmd, self.info, curve_key)
        except GearsimError:
            self._cmd.close(linger=0)
            raise
        self._cmd.setsockopt(zmq.IPV6, 1)   # the daemon may listen on ::1 (--bind ::1)
        self._cmd.connect(self.info["command"])
        self._sub = None
        self._topics = None
        self._prefix = secrets.token_hex(4)
        self._counter = itertools.count(1)
        self._sent = {}          # id -> frame, for retries
        self._replies = {}       # id -> reply that arrived while waiting for another
        self._events = collections.deque()
        self._batch = collections.deque()   # the rest of a received batch of telemetry events
        self.last_seq = None     # seq of the last event received
        self.gaps = 0            # events missed (seq gaps), counted when subscribed to all topics
        self.bad_events = 0      # event messages that were not two frames of JSON

    # ------------------------------------------------------------ lifecycle
    def close(self):
        for s in (self._cmd, self._sub):
            if s is not None:
                s.close(linger=0)
        self._cmd = self._sub = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ------------------------------------------------------------ requests
    def new_id(self):
        return f"{self._prefix}-{next(self._counter)}"

    def send(self, cmd, args=None, id=None):
        """Send a request without waiting; returns its id (see wait_reply)."""
        rid = id or self.new_id()
        msg = {"v": PROTOCOL, "id": rid, "cmd": cmd}
        if args is not None:
            msg["args"] = args
        try:
            frame = json.dumps(msg, allow_nan=False, separators=(",", ":")).encode()
        except ValueError as e:
            raise GearsimError("invalid_argument", f"{cmd}: arguments are not valid JSON: {e}") from None
        self._sent[rid] = frame
        self._cmd.send(frame)
        return rid

    def wait_reply(self, rid, timeout=None, retries=None, raw=False):
        """Wait for the reply to request `rid`, resending the same frame on timeout.
        Returns the result (or the whole reply if raw=True); raises GearsimError."""
        timeout = self.timeout if timeout is None else timeout
        retries = self.retries if retries is None else retries
        try:
            for attempt in range(retries + 1):
                if attempt:
                    self._cmd.send(self._sent[rid])
                reply = self._recv_reply(rid, timeout)
                if reply is not None:
                    break
            else:
                raise GearsimTimeout(f"no reply to request {rid} after {retries + 1} attempts of {timeout:g} s")
        finally:
            self._sent.pop(rid, None)
        if raw:
            return reply
        if reply.get("ok") is True:
            result = reply.get("result")
            return result if isinstance(result, dict) else {}
        err = reply.get("error") or {}
        raise GearsimError(err.get("code", "internal"), err.get("message", "error reply without a message"),
                           err.get("field"), reply)

    def check_daemon(self):
        """Raise GearsimError("daemon_stopped") naming the cause when the
        daemon is gone (gearsim.connection.daemon_stopped): its connection
        file removed or marked stopped (a rank died), or its process gone.
        Every wait of this client calls it about once a second."""
        why = daemon_stopped(self.info)
        if why:
            raise GearsimError("daemon_stopped", f"the daemon stopped: {why}")

    def _recv_reply(self, rid, timeout):
        if rid in self._replies:
            return self._replies.pop(rid)
        deadline = _time.monotonic() + timeout
        while True:
            left = deadline - _time.monotonic()
            if left <= 0:
                return None
            if not self._cmd.poll(int(min(left, 1.0) * 1000) + 1):
                self.check_daemon()
                continue
            frames = self._cmd.recv_multipart()
            try:
                reply = json.loads(frames[-1])
            except ValueError:
                continue
            if not isinstance(reply, dict):
                continue
            other = reply.get("id")
            if other == rid:
                return reply
            if isinstance(other, str) and other in self._sent:
                self._replies[other] = reply   # an answer to another request in flight
            # else: a duplicate answer to a retried request already answered: drop it

    def request(self, cmd, args=None, timeout=None, retries=None):
        """Send one command and return its result (GearsimError on an error reply)."""
        return self.wait_reply(self.send(cmd, args), timeout, retries)

    # ------------------------------------------------------------ commands
    def hello(self):
        return self.request("hello")

    def load(self, scene=None, builtin=None, timeout=None):
        """Load a scene: a dict, or the path of a JSON file; or an embedded one by name."""
        if (scene is None) == (builtin is None):
            raise ValueError("load() needs exactly one of scene= and builtin=")
        if builtin is not None:
            args = {"builtin": builtin}
        else:
            if isinstance(scene, (str, os.PathLike)):
                with open(scene) as f:
                    scene = json.load(f)
            args = {"scene": scene}
        return self.request("load", args, timeout=max(timeout or self.timeout, 60.0))

    def unload(self):
        return self.request("unload")

    def modal(self, scene=None, builtin=None, shapes=True):
        """Natural frequencies and mode shapes (docs/explanation/modal.md) of a scene (dict
        or JSON file path), a builtin, or (neither) the loaded scene."""
        args = {"shapes": bool(shapes)}
        if scene is not None:
            if isinstance(scene, (str, os.PathLike)):
                with open(scene) as f:
                    scene = json.load(f)
            args["scene"] = scene
        if builtin is not None:
            args["builtin"] = builtin
        return self.request("modal", args)

    def set_load(self, load=None, remove=None, **fields):
        """set_load(load={...}) or set_load(body="pinion", type="constant", moment=30)
        replaces the load of that name; set_load(remove="name") removes one."""
        if remove is not None:
            return self.request("set_load", {"remove": remove})
        load = dict(load or {}, **fields)
        return self.request("set_load", {"load": load})

    def advance(self, time=None, steps=None, wait=True, on_telemetry=None, on_progress=None,
                on_event=None, timeout=None):
        """Advance by simulated `time` (s) or by `steps`.

        wait=False: returns the reply's result with the request id added as "id"
        (use wait_done(result["id"]) later). wait=True: subscribes to events if
        needed, calls on_telemetry/on_progress/on_event for each event, and
        returns the `done` event; raises GearsimError if the run ended with an
        error, GearsimTimeout after `timeout` seconds (None: no limit)."""
        if (time is None) == (steps is None):
            raise ValueError("advance() needs exactly one of time= and steps=")
        args = {"time": float(time)} if time is not None else {"steps": int(steps)}
        if wait and self._sub is None:
            self.subscribe()
        rid = self.send("advance", args)
        result = self.wait_reply(rid)
        if not wait:
            return dict(result, id=rid)
        return self.wait_done(rid, on_telemetry, on_progress, on_event, timeout)

    def stiffness(self, mesh, positions=None, torque=None, refine=None, path=None, wait=True,
                  on_progress=None, timeout=None, nearfield=None):
        """Quasi-static mesh stiffness of `mesh` of the loaded scene, run by
        the daemon in chunks (status and cancel answered meanwhile).
        wait=True: the `done` event's result (learned from status when the
        event is lost); wait=False: the accepted reply with "id" added.
        nearfield=False: the plain FE contact (default: the daemon's, the
        near-field correction on)."""
        args = {"mesh": mesh}
        for k, v in (("positions", positions), ("torque", torque), ("refine", refine), ("path", path),
                     ("nearfield", nearfield)):
            if v is not None:
                args[k] = str(v) if k == "path" else v
        if wait and self._sub is None:
            self.subscribe()
        rid = self.send("stiffness", args)
        result = self.wait_reply(rid)
        if not wait:
            return dict(result, id=rid)
        return self.wait_done(rid, on_progress=on_progress, timeout=timeout).get("result")

    def sweep(self, parameters, scene=None, builtin=None, settle=None, measure=None, time_step=None, mesh=None,
              driver_rpm=None, groups=None, path=None, resume=None, wait=True, on_progress=None, timeout=None,
              dispatcher=None):
        """A parameter sweep run by the daemon on groups of its ranks (docs/explanation/modal.md,
        "Sweeps"): `parameters` a list of {path, values} or {path, from, to, points}
        (path "driver_rpm" or a JSON path into the scene); the scene a dict or a JSON
        file path, or a builtin name. wait=True: the `done` event (its csv and h5
        name the table in the data directory; fetch() them); wait=False: the
        accepted reply with "id" added. on_progress gets one event per point.
        dispatcher: "shared" (default) or "dedicated" (rank 0 only hands out points)."""
        args = {"parameters": list(parameters)}
        if (scene is None) == (builtin is None):
            raise ValueError("sweep() needs exactly one of scene= and builtin=")
        if scene is not None:
            if isinstance(scene, (str, os.PathLike)):
                with open(scene) as f:
                    scene = json.load(f)
            args["scene"] = scene
        else:
            args["builtin"] = builtin
        for k, v in (("settle", settle), ("measure", measure), ("time_step", time_step), ("mesh", mesh),
                     ("driver_rpm", driver_rpm), ("groups", groups), ("path", path), ("resume", resume),
                     ("dispatcher", dispatcher)):
            if v is not None:
                args[k] = str(v) if k == "path" else v
        if wait and self._sub is None:
            self.subscribe()
        rid = self.send("sweep", args)
        result = self.wait_reply(rid, timeout=max(self.timeout, 60.0))
        if not wait:
            return dict(result, id=rid)
        return self.wait_done(rid, on_progress=on_progress, timeout=timeout)

    def pause(self):
        return self.request("pause")

    def resume(self):
        return self.request("resume")

    def cancel(self):
        return self.request("cancel")

    def status(self):
        return self.request("status")

    def state(self):
        return self.request("state")

    def record(self, path=None, stop=False):
        """record("run.h5") starts recording (path relative to the daemon's data
        directory); record(stop=True) stops."""
        if stop:
            return self.request("record", {"stop": True})
        if path is None:
            raise ValueError("record() needs a path or stop=True")
        return self.request("record", {"path": str(path)})

    def checkpoint(self, path):
        return self.request("checkpoint", {"path": str(path)}, timeout=max(self.timeout, 60.0))

    def restore(self, path):
        return self.request("restore", {"path": str(path)}, timeout=max(self.timeout, 60.0))

    def submit(self, scene, duration, schedule=None, record=None):
        """Queue a whole job; scene is a dict or a JSON file path."""
        if isinstance(scene, (str, os.PathLike)):
            with open(scene) as f:
                scene = json.load(f)
        args = {"scene": scene, "duration": float(duration)}
        if schedule is not None:
            args["schedule"] = schedule
        if record is not None:
            args["record"] = str(record)
        return self.request("submit", args)

    def jobs(self):
        return self.request("jobs")

    def fetch(self, path, out_path=None, chunk=FETCH_CHUNK, remove=False):
        """Download a file of the daemon's data directory in chunks (base64).
        Writes it to out_path and returns its size, or returns the bytes if
        out_path is None. remove=True: once the whole file is here, the
        daemon deletes its copy (a last request at its end with `remove`)."""
        chunks, offset = [], 0
        # Written beside out_path under another name and renamed when whole:
        # an interrupted or failed download leaves no partial file.
        tmp = None
        if out_path is not None:
            fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(out_path) + ".",
                                       dir=os.path.dirname(os.path.abspath(out_path)))
            out = os.fdopen(fd, "wb")
        else:
            out = None
        whole = False
        try:
            while True:
                r = self.request("fetch", {"path": str(path), "offset": offset, "length": int(chunk)})
                data = base64.b64decode(r.get("data_b64", ""), validate=True)
                if len(data) != r.get("length", len(data)):
                    raise GearsimError("io_error", f"fetch {path}: chunk at {offset} has {len(data)} bytes, "
                                                   f"reply says {r.get('length')}")
                if out:
                    out.write(data)
                else:
                    chunks.append(data)
                offset += len(data)
                if r.get("eof") or not data:
                    break
            size = r.get("size", offset)
            if offset != size:
                raise GearsimError("io_error", f"fetch {path}: got {offset} bytes of {size}")
            if out:
                out.close()
                os.chmod(tmp, 0o666 & ~_umask())
                os.replace(tmp, out_path)
            whole = True
        finally:
            if out and not whole:
                out.close()
                os.unlink(tmp)
        if remove:
            r = self.request("fetch", {"path": str(path), "offset": offset, "length": 1, "remove": True})
            if not r.get("removed"):
                raise GearsimError("io_error", f"fetch {path}: the daemon kept its copy (it changed meanwhile)")
        return offset if out_path is not None else b"".join(chunks)

    def shutdown(self):
        return self.request("shutdown")

    # ------------------------------------------------------------ events
    def subscribe(self, topics=None, timeout=None):
        """Connect the SUB socket and wait for the first heartbeat (ZeroMQ's
        slow joiner would otherwise lose the first events). topics=None
        subscribes to every event type (and enables gap detection by seq).
        Telemetry comes as single events either way; from a daemon that
        offers it (`telemetry_batch` in the connection file) it travels in
        batches, many events per message, which this client unpacks in order
        (docs/reference/protocol.md, "Telemetry batches")."""
        if self._sub is not None:
            return
        timeout = max(self.timeout, 5.0) if timeout is None else timeout
        sub = self._ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.RCVHWM, 100000)
        try:
            apply_curve(sub, self.info, self.curve_key)
        except GearsimError:
            sub.close(linger=0)
            raise
        batched = bool(self.info.get("telemetry_batch"))
        if topics is None and not batched:
            sub.setsockopt(zmq.SUBSCRIBE, b"")
            self._topics = None
        else:
            self._topics = None if topics is None else set(topics)
            for t in (set(EVENT_TYPES) if topics is None else self._topics | {"heartbeat"}):
                if batched and t == "telemetry":
                    t = "batch"
                sub.setsockopt(zmq.SUBSCRIBE, t.encode())
        sub.setsockopt(zmq.IPV6, 1)
        sub.connect(self.info["telemetry"])
        self._sub = sub
        deadline = _time.monotonic() + timeout
        while True:
            left = deadline - _time.monotonic()
            if left <= 0:
                raise GearsimTimeout(f"no heartbeat from {self.info['telemetry']} within {timeout:g} s")
            ev = self._recv_event(left)
            if ev is None:
                continue
            if ev.get("type") == "heartbeat":
                if self._topics is None or "heartbeat" in self._topics:
                    self._events.append(ev)
                return
            self._events.append(ev)

    def _recv_event(self, timeout):
        if self._batch:
            return self._seen(self._batch.popleft())
        if not self._sub.poll(int(max(timeout, 0) * 1000)):
            return None
        frames = self._sub.recv_multipart()
        try:
            if len(frames) != 2:
                raise ValueError("not two frames")
            ev = json.loads(frames[1])
            if not isinstance(ev, dict):
                raise ValueError("not an object")
            if frames[0] == b"batch":
                evs = ev.get("events")
                if not isinstance(evs, list) or not evs or not all(isinstance(e, dict) for e in evs):
                    raise ValueError("a batch without events")
                self._batch.extend(evs)
                ev = self._batch.popleft()
        except ValueError:
            self.bad_events += 1
            return None
        return self._seen(ev)

    def _seen(self, ev):
        """Count a gap in seq before ev (subscribed to every topic)."""
        seq = ev.get("seq")
        if isinstance(seq, int):
            if self._topics is None and self.last_seq is not None and seq > self.last_seq + 1:
                self.gaps += seq - self.last_seq - 1
            self.last_seq = seq
        return ev

    def next_event(self, timeout=1.0):
        """The next event (a dict), or None after `timeout` seconds. Subscribes
        to every topic first if subscribe() was not called."""
        if self._sub is None:
            self.subscribe()
        if self._events:
            return self._events.popleft()
        deadline = _time.monotonic() + timeout
        while True:
            ev = self._recv_event(deadline - _time.monotonic())
            if ev is not None:
                if self._topics is not None and ev.get("type") not in self._topics:
                    continue    # a heartbeat we only subscribed to for readiness
                return ev
            if _time.monotonic() >= deadline:
                return None

    def events(self, timeout=1.0):
        """Iterate over events until none arrives for `timeout` seconds."""
        while True:
            ev = self.next_event(timeout)
            if ev is None:
                return
            yield ev

    @staticmethod
    def _dispatch(ev, parent_id, on_telemetry, on_progress, on_event):
        """Hand an event to the callbacks; True when it is the done event of parent_id."""
        if on_event:
            on_event(ev)
        t = ev.get("type")
        if t == "telemetry" and on_telemetry:
            on_telemetry(ev)
        elif t == "progress" and on_progress and ev.get("parent_id") == parent_id:
            on_progress(ev)
        return t == "done" and ev.get("parent_id") == parent_id

    def wait_done(self, parent_id, on_telemetry=None, on_progress=None, on_event=None, timeout=None):
        """Wait for the `done` event of advance request `parent_id`; see advance()."""
        start = _time.monotonic()
        last_check = last_alive = start
        while True:
            ev = self.next_event(0.5)
            now = _time.monotonic()
            if now - last_alive >= 1.0:
                last_alive = now
                self.check_daemon()
            if ev is not None and self._dispatch(ev, parent_id, on_telemetry, on_progress, on_event):
                err = ev.get("error")
                if err:
                    raise GearsimError(err.get("code", "internal"), err.get("message", ""),
                                       err.get("field"), ev)
                return ev
            if timeout is not None and now - start > timeout:
                raise GearsimTimeout(f"advance {parent_id} not done after {timeout:g} s")
            if ev is not None and ev.get("type") != "heartbeat":
                # Events still coming (or queued behind a slow callback): the
                # done event is behind them; ask status only when the stream
                # has been quiet for 2 s.
                last_check = now
            elif now - last_check > 2.0:
                # A done event dropped at a high-water mark (or a subscriber
                # that is gone) must not hang us: status lists the last
                # finished requests with their done payload.
                last_check = now
                st = self.status()
                for f in reversed(st.get("finished") or []):
                    if f.get("parent_id") == parent_id:
                        # Finished: the events before its done (the last
                        # telemetry) may still be on their way; take them
                        # and the done event if it comes.
                        until = _time.monotonic() + 1.5
                        while _time.monotonic() < until:
                            e = self.next_event(max(until - _time.monotonic(), 0.0))
                            if e is None:
                                continue
                            if self._dispatch(e, parent_id, on_telemetry, on_progress, on_event):
                                f = e
                                break
                            if e.get("type") != "heartbeat":
                                until = _time.monotonic() + 1.5   # still draining
                        ev = f if f.get("type") == "done" else dict(f, v=PROTOCOL, type="done", from_status=True)
                        err = ev.get("error")
                        if err and not ev.get("cancelled"):
                            raise GearsimError(err.get("code", "internal"), err.get("message", ""),
                                               err.get("field"), ev)
                        return ev
                adv, stf = st.get("advance"), st.get("stiffness")
                running = any(x and x.get("parent_id") == parent_id for x in (adv, stf, st.get("sweep")))
                if not running:
                    tail, until = [], _time.monotonic() + 1.5
                    while _time.monotonic() < until:
                        e = self.next_event(max(until - _time.monotonic(), 0.0))
                        if e is not None:
                            tail.append(e)
                    self._events.extend(tail)
                    if not any(e.get("type") == "done" and e.get("parent_id") == parent_id for e in tail):
                        self._events.append({"v": PROTOCOL, "type": "done", "parent_id": parent_id,
                                             "lost": True, "step": st.get("step"), "time": st.get("time")})
