#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""A tiny stand-in for gearsimd that speaks docs/reference/protocol.md, for testing the
clients and the test helpers themselves (GEARSIM_FAKE_DAEMON=1 makes
daemon.py start this instead of mpirun gearsimd). Its physics is a toy: free
rigid bodies driven by their loads, meshes ignored. Never used to judge the
real daemon."""
import argparse
import base64
import json
import math
import os
import secrets
import sys
import time

import zmq

COMMANDS = ["hello", "load", "set_load", "advance", "pause", "resume", "cancel", "status", "state",
            "record", "checkpoint", "restore", "submit", "jobs", "fetch", "unload", "shutdown"]
NO_ARGS = {"hello", "pause", "resume", "cancel", "status", "state", "jobs", "unload", "shutdown"}
CHUNK = 200


class Fail(Exception):
    def __init__(self, code, message, field=""):
        super().__init__(message)
        self.code, self.message, self.field = code, message, field


def builtin_scene(name):
    root = os.environ.get("GEARSIM_SOURCE_ROOT", os.path.join(os.path.dirname(__file__), "..", ".."))
    path = os.path.join(root, "deploy", "scenes", name + ".json")
    if os.path.exists(path):
        with open(path) as f:
            return json.load(f)
    bodies = [{"name": "pinion", "teeth": 20, "module_mm": 2.5}, {"name": "wheel", "teeth": 30, "module_mm": 2.5}]
    return {"name": name, "bodies": bodies,
            "joints": [{"body": "pinion", "type": "fixed_axis"}, {"body": "wheel", "type": "fixed_axis"}],
            "loads": [{"body": "pinion", "type": "constant", "moment": 1.0}]}


class Fake:
    def __init__(self, args):
        self.data = os.path.abspath(args.data_dir or os.getcwd())
        self.session = secrets.token_hex(8)
        self.ctx = zmq.Context()
        self.router = self.ctx.socket(zmq.ROUTER)
        self.pub = self.ctx.socket(zmq.PUB)
        cport = self.router.bind_to_random_port("tcp://127.0.0.1")
        tport = self.pub.bind_to_random_port("tcp://127.0.0.1")
        self.seq = 0
        self.cache = {}
        self.scene = None
        self.adv = None
        self.paused = False
        self.recording = None
        self.rec_rows = []
        self.jobs = []
        self.running = True
        info = {"v": 1, "protocol": 1, "session": self.session, "command": f"tcp://127.0.0.1:{cport}",
                "telemetry": f"tcp://127.0.0.1:{tport}", "pid": os.getpid(), "ranks": 1, "version": "0.0.0-fake"}
        os.makedirs(os.path.dirname(os.path.abspath(args.connection_file)), exist_ok=True)
        tmp = args.connection_file + ".tmp"
        with open(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600), "w") as f:
            json.dump(info, f)
        os.replace(tmp, args.connection_file)

    # -------------------------------------------------------------- events
    def publish(self, type_, **fields):
        self.seq += 1
        ev = {"v": 1, "type": type_, "seq": self.seq, "session": self.session,
              "step": self.step if self.scene else 0, "time": self.t if self.scene else 0.0}
        ev.update(fields)
        self.pub.send_multipart([type_.encode(), json.dumps(ev).encode()])

    def state_name(self):
        if self.scene is None:
            return "empty"
        if self.adv:
            return "paused" if self.paused else "running"
        return "loaded"

    # -------------------------------------------------------------- model
    def energy(self):
        ke = sum(0.5 * self.inertia * w * w for w in self.omega)
        return {"kinetic": ke, "potential": 0.0, "elastic": 0.0, "total": ke, "work_in": self.work,
                "dissipated": self.diss, "balance_residual": ke - self.work + self.diss}

    def snapshot(self):
        return {"energy": self.energy(),
                "bodies": [{"name": n, "angle": a, "omega": w, "rpm": w * 30 / math.pi}
                           for n, a, w in zip(self.names, self.angle, self.omega)],
                "meshes": [{"name": m, "force": 0.0, "penetration": 0.0, "deflection": 0.0} for m in self.meshes]}

    def moment(self, i):
        m = 0.0
        for ld in self.loads.values():
            if ld["body"] != self.names[i]:
                continue
            if ld["type"] == "constant":
                m += ld["moment"]
            elif ld["type"] == "ramp":
                m += ld["moment"] * min(self.t / ld["ramp_time"], 1.0)
            elif ld["type"] == "brake":
                m -= ld["coefficient"] * self.omega[i]
        return m

    def do_steps(self, n):
        every = self.scene.get("outputs", {}).get("telemetry_every", 10)
        for _ in range(n):
            for i in range(len(self.names)):
                m = self.moment(i)
                w0 = self.omega[i]
                w1 = w0 + self.dt * m / self.inertia
                p = m * 0.5 * (w0 + w1) * self.dt
                if p >= 0:
                    self.work += p
                else:
                    self.diss -= p
                self.omega[i] = w1
                self.angle[i] += 0.5 * (w0 + w1) * self.dt
            self.step += 1
            self.t = self.step * self.dt
            if self.step % every == 0:
                snap = self.snapshot()
                self.publish("telemetry", parent_id=self.adv["id"] if self.adv else None, **snap)
                if self.recording:
                    self.rec_rows.append((self.t, self.step, snap))

    # -------------------------------------------------------------- commands
    def check_path(self, args, key="path"):
        p = args.get(key)
        if not isinstance(p, str) or not p:
            raise Fail("invalid_field", f"{key} must be a non-empty string", f"args.{key}")
        if p.startswith("/") or ".." in p.split("/"):
            raise Fail("invalid_field", f"{key} must be relative without '..'", f"args.{key}")
        return os.path.join(self.data, p)

    def need(self, loaded=True, idle=True):
        if loaded and self.scene is None:
            raise Fail("wrong_state", "no scene is loaded")
        if idle and self.adv:
            raise Fail("wrong_state", "an advance is running")

    def cmd_hello(self, a):
        return {"protocol": 1, "version": "0.0.0-fake", "build": "python fake", "session": self.session,
                "ranks": 1, "capabilities": [], "commands": COMMANDS, "builtin_scenes": ["pair", "planetary"],
                "limits": {"max_message_bytes": 1 << 20, "max_bodies": 64, "max_steps_per_advance": 10**8,
                           "max_queued_jobs": 16}}

    def cmd_load(self, a):
        self.need(loaded=False)
        scene = builtin_scene(a["builtin"]) if "builtin" in a else a.get("scene")
        if not isinstance(scene, dict) or not isinstance(scene.get("bodies"), list):
            raise Fail("invalid_field", "scene.bodies must be an array", "args.scene.bodies")
        self.scene = scene
        self.names = [b["name"] for b in scene["bodies"]]
        self.meshes = [m.get("name", "-".join(m["gears"])) for m in scene.get("meshes", [])]
        self.loads = {}
        for ld in scene.get("loads", []):
            self.loads[ld.get("name", f"{ld['body']}:{ld['type']}")] = ld
        self.dt = scene.get("numerics", {}).get("time_step", 1e-5)
        self.inertia = 1e-4
        self.step, self.t, self.work, self.diss = 0, 0.0, 0.0, 0.0
        self.angle = [0.0] * len(self.names)
        self.omega = [0.0] * len(self.names)
        return {"name": scene.get("name", ""), "bodies": self.names, "meshes": self.meshes,
                "dofs": len(self.names), "time_step": self.dt}

    def cmd_unload(self, a):
        self.need()
        self.scene = None
        return {}

    def loads_list(self):
        return [dict(v, name=k) for k, v in self.loads.items()]

    def cmd_set_load(self, a):
        self.need(idle=False)
        if "remove" in a:
            if a["remove"] not in self.loads:
                raise Fail("not_found", f"no load named {a['remove']}", "args.remove")
            del self.loads[a["remove"]]
        else:
            ld = a.get("load") or {}
            if ld.get("body") not in self.names:
                raise Fail("invalid_field", "unknown body", "args.load.body")
            self.loads[ld.get("name", f"{ld['body']}:{ld['type']}")] = ld
        return {"loads": self.loads_list()}

    def cmd_advance(self, a, rid=None):
        self.need()
        n = a["steps"] if "steps" in a else int(round(a["time"] / self.dt))
        if not isinstance(n, int) or n < 1:
            raise Fail("out_of_range", "steps must be >= 1", "args.steps")
        self.adv = {"id": rid, "target": self.step + n, "n": n, "start": self.step, "wall": time.monotonic(),
                    "last_progress": 0.0}
        self.paused = False
        return {"accepted": True, "steps": n, "until_time": (self.step + n) * self.dt}

    def finish(self, cancelled):
        adv, self.adv = self.adv, None
        self.publish("done", parent_id=adv["id"], cancelled=cancelled, steps=self.step - adv["start"],
                     wall_seconds=time.monotonic() - adv["wall"])

    def cmd_pause(self, a):
        self.need(idle=False)
        if self.adv:
            self.paused = True
        return {"state": self.state_name()}

    def cmd_resume(self, a):
        self.need(idle=False)
        self.paused = False
        return {"state": self.state_name()}

    def cmd_cancel(self, a):
        cancelled = bool(self.adv)
        if self.adv:
            self.finish(True)
        return {"state": self.state_name(), "cancelled": cancelled}

    def cmd_status(self, a):
        adv = None
        if self.adv:
            adv = {"parent_id": self.adv["id"], "target_step": self.adv["target"],
                   "fraction": (self.step - self.adv["start"]) / self.adv["n"]}
        return {"state": self.state_name(), "time": self.t if self.scene else 0.0,
                "step": self.step if self.scene else 0, "scene": self.scene.get("name") if self.scene else None,
                "advance": adv, "recording": self.recording, "jobs_queued": 0, "timing": {}}

    def cmd_state(self, a):
        self.need(idle=False)
        return dict(seq=self.seq, step=self.step, time=self.t, **self.snapshot())

    def write_record(self):
        import h5py
        import numpy as np
        rows = self.rec_rows
        with h5py.File(os.path.join(self.data, self.recording), "w") as f:
            f.attrs["scene"] = json.dumps(self.scene)
            f.attrs["gearsim_version"] = "0.0.0-fake"
            g = f.create_group("telemetry")
            g.create_dataset("time", data=np.array([r[0] for r in rows], dtype=float))
            g.create_dataset("step", data=np.array([r[1] for r in rows], dtype=np.int64))
            cols = ["kinetic", "potential", "total", "work_in", "dissipated", "balance_residual"]
            e = g.create_dataset("energy", data=np.array([[r[2]["energy"][c] for c in cols] for r in rows]).reshape(-1, 6))
            e.attrs["columns"] = json.dumps(cols)
            nb = len(self.names)
            g.create_dataset("angle", data=np.array([[b["angle"] for b in r[2]["bodies"]] for r in rows]).reshape(-1, nb))
            g.create_dataset("omega", data=np.array([[b["omega"] for b in r[2]["bodies"]] for r in rows]).reshape(-1, nb))
            g.attrs["bodies"] = json.dumps(self.names)
            nm = len(self.meshes)
            g.create_dataset("mesh_force", data=np.zeros((len(rows), nm)))
            g.attrs["meshes"] = json.dumps(self.meshes)

    def cmd_record(self, a):
        self.need(idle=False)
        if a.get("stop"):
            if self.recording:
                self.write_record()
            self.recording = None
        else:
            self.check_path(a)
            self.recording, self.rec_rows = a["path"], []
        return {"recording": self.recording}

    def cmd_checkpoint(self, a):
        self.need()
        p = self.check_path(a)
        with open(p, "w") as f:
            json.dump({"step": self.step, "angle": self.angle, "omega": self.omega, "work": self.work,
                       "diss": self.diss, "loads": self.loads}, f)
        return {"path": a["path"], "step": self.step, "time": self.t}

    def cmd_restore(self, a):
        self.need()
        p = self.check_path(a)
        if not os.path.exists(p):
            raise Fail("not_found", f"no file {a['path']}", "args.path")
        with open(p) as f:
            c = json.load(f)
        self.step, self.angle, self.omega = c["step"], c["angle"], c["omega"]
        self.work, self.diss, self.loads = c["work"], c["diss"], c["loads"]
        self.t = self.step * self.dt
        return {"step": self.step, "time": self.t}

    def cmd_submit(self, a):
        job = f"job-{len(self.jobs) + 1}"
        self.jobs.append({"job": job, "state": "queued", "record": a.get("record"), "error": None})
        return {"job": job, "position": len(self.jobs) - 1}

    def cmd_jobs(self, a):
        return {"jobs": self.jobs}

    def cmd_fetch(self, a):
        p = self.check_path(a)
        if not os.path.isfile(p):
            raise Fail("not_found", f"no file {a['path']}", "args.path")
        off, ln = a.get("offset", 0), a.get("length", 1 << 20)
        size = os.path.getsize(p)
        with open(p, "rb") as f:
            f.seek(off)
            data = f.read(ln)
        res = {"path": a["path"], "offset": off, "length": len(data), "size": size,
               "eof": off + len(data) >= size, "data_b64": base64.b64encode(data).decode()}
        if a.get("remove"):
            res["removed"] = res["eof"]
            if res["eof"]:
                os.unlink(p)
        return res

    def cmd_shutdown(self, a):
        self.running = False
        return {}

    # -------------------------------------------------------------- loop
    def handle(self, frames):
        ident, body = frames[0], frames[-1]
        rid = None
        try:
            if len(frames) != 2:
                raise Fail("bad_json", "a request is exactly one frame")
            try:
                req = json.loads(body)
            except (ValueError, RecursionError):
                raise Fail("bad_json", "malformed JSON") from None
            if not isinstance(req, dict):
                raise Fail("bad_json", "a request is a JSON object")
            rid = req.get("id") if isinstance(req.get("id"), str) else None
            if rid is None:
                raise Fail("invalid_field", "id must be a string", "id")
            if (ident, rid) in self.cache:
                self.router.send_multipart([ident, self.cache[(ident, rid)]])
                return
            if req.get("v") != 1:
                raise Fail("unsupported_version", "v must be 1", "v")
            cmd = req.get("cmd")
            if cmd not in COMMANDS:
                raise Fail("unknown_command", f"unknown command {cmd!r}", "cmd")
            args = req.get("args", {})
            if not isinstance(args, dict):
                raise Fail("invalid_field", "args must be an object", "args")
            if cmd in NO_ARGS and args:
                raise Fail("invalid_field", f"unknown field {next(iter(args))}", "args." + next(iter(args)))
            fn = getattr(self, "cmd_" + cmd)
            result = fn(args, rid) if cmd == "advance" else fn(args)
            reply = {"v": 1, "id": rid, "ok": True, "result": result}
        except Fail as e:
            reply = {"v": 1, "id": rid, "ok": False, "error": {"code": e.code, "message": e.message, "field": e.field}}
        except (KeyError, TypeError, ValueError) as e:
            reply = {"v": 1, "id": rid, "ok": False, "error": {"code": "invalid_field", "message": str(e), "field": ""}}
        except OSError as e:
            reply = {"v": 1, "id": rid, "ok": False, "error": {"code": "io_error", "message": str(e), "field": ""}}
        data = json.dumps(reply).encode()
        if rid is not None:
            self.cache[(ident, rid)] = data
        self.router.send_multipart([ident, data])

    def run(self):
        last_hb = 0.0
        while self.running:
            if self.router.poll(0 if (self.adv and not self.paused) else 50):
                self.handle(self.router.recv_multipart())
                continue
            now = time.monotonic()
            if now - last_hb >= 1.0:
                last_hb = now
                self.publish("heartbeat", state=self.state_name())
            if self.adv and not self.paused:
                self.do_steps(min(CHUNK, self.adv["target"] - self.step))
                if now - self.adv["last_progress"] >= 0.1:
                    self.adv["last_progress"] = now
                    wall = max(now - self.adv["wall"], 1e-9)
                    self.publish("progress", parent_id=self.adv["id"],
                                 fraction=(self.step - self.adv["start"]) / self.adv["n"],
                                 steps_per_second=(self.step - self.adv["start"]) / wall)
                if self.step >= self.adv["target"]:
                    self.finish(False)
        time.sleep(0.05)
        self.router.close(0)
        self.pub.close(0)
        self.ctx.term()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--connection-file", required=True)
    ap.add_argument("--data-dir")
    ap.add_argument("--bind")
    ap.add_argument("--command-port")
    ap.add_argument("--telemetry-port")
    Fake(ap.parse_args()).run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
