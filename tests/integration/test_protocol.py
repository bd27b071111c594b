#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The protocol's JSON Schemas (proto/v1) and the real daemon against them.

Offline: every schema is a valid draft 2020-12 schema, every example
validates, a few invalid instances are rejected (the schemas are not
vacuous), and deploy/scenes/*.json validate against scene.json.

Online (mpirun -n 2 gearsimd): a whole session (hello, load, state, status,
set_load, record, advance with progress/telemetry/done, pause/resume/cancel,
checkpoint, restore, submit, jobs, fetch, unload, shutdown) during which every
reply and every event must be strict JSON and validate against its schema,
events must be two frames with topic = type, seq must increase by one, and
the session must match the connection file."""
import copy
import glob
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from jsonschema import Draft202012Validator  # noqa: E402

import daemon as dmod  # noqa: E402
from harness import Probe, Results  # noqa: E402
from protoschema import Proto, strict_loads  # noqa: E402

COMMANDS = ["hello", "load", "set_load", "advance", "pause", "resume", "cancel", "status", "state",
            "record", "checkpoint", "restore", "submit", "jobs", "fetch", "unload", "shutdown"]
EVENTS = ["telemetry", "progress", "done", "heartbeat", "warning", "error"]

R = Results("test_protocol: proto/v1 schemas and the real daemon's messages")
P = Proto()
undocumented = {}


# ---------------------------------------------------------------- offline
def offline():
    names = set(P.schemas)
    for cmd in COMMANDS:
        R.check(f"schemas for {cmd} exist", f"requests/{cmd}.json" in names and f"results/{cmd}.json" in names)
    for ev in EVENTS:
        R.check(f"schema for event {ev} exists", f"events/{ev}.json" in names)
    for rel in ("request.json", "reply.json", "event.json", "connection.json", "scene.json", "common.json"):
        R.check(f"schema {rel} exists", rel in names)
    bad_schemas, n_examples, bad_examples, no_examples = [], 0, [], []
    for rel, schema in sorted(P.schemas.items()):
        try:
            Draft202012Validator.check_schema(schema)
        except Exception as e:  # noqa: BLE001
            bad_schemas.append(f"{rel}: {e}")
        if rel != "common.json" and not schema.get("examples"):
            no_examples.append(rel)
        for ex in schema.get("examples", []):
            n_examples += 1
            bad_examples += P.errors(rel, ex)
        for name, sub in schema.get("$defs", {}).items():
            for ex in sub.get("examples", []):
                n_examples += 1
                v = Draft202012Validator(sub, resolver=P.validator(rel).resolver)
                bad_examples += [f"{rel}#/$defs/{name}: {e.message}" for e in v.iter_errors(ex)]
    R.check(f"all {len(P.schemas)} schemas are valid draft 2020-12", not bad_schemas, bad_schemas)
    R.check("every schema has examples", not no_examples, no_examples)
    R.check(f"all {n_examples} examples validate", not bad_examples, bad_examples)
    # request.json dispatches to the command schemas
    for cmd in COMMANDS:
        for ex in P.schemas[f"requests/{cmd}.json"]["examples"]:
            errs = P.errors("request.json", ex)
            if errs:
                R.check(f"request.json accepts the {cmd} example", False, errs)
    # the schemas are not vacuous
    pair = copy.deepcopy(P.schemas["scene.json"]["examples"][0])
    must_fail = {
        "unknown request field": ("request.json", {"v": 1, "id": "a", "cmd": "hello", "extra": 1}),
        "unknown args field": ("request.json", {"v": 1, "id": "a", "cmd": "advance", "args": {"steps": 5, "x": 1}}),
        "advance with both time and steps": ("request.json", {"v": 1, "id": "a", "cmd": "advance", "args": {"steps": 5, "time": 1.0}}),
        "zero steps": ("request.json", {"v": 1, "id": "a", "cmd": "advance", "args": {"steps": 0}}),
        "wrong version": ("request.json", {"v": 2, "id": "a", "cmd": "hello"}),
        "unknown command": ("request.json", {"v": 1, "id": "a", "cmd": "fly"}),
        "path traversal": ("request.json", {"v": 1, "id": "a", "cmd": "record", "args": {"path": "a/../../x.h5"}}),
        "absolute path": ("request.json", {"v": 1, "id": "a", "cmd": "checkpoint", "args": {"path": "/tmp/x.h5"}}),
        "fetch over 1 MiB": ("request.json", {"v": 1, "id": "a", "cmd": "fetch", "args": {"path": "x", "length": 2 << 20}}),
        "args on hello": ("request.json", {"v": 1, "id": "a", "cmd": "hello", "args": {"x": 1}}),
        "reply ok without result": ("reply.json", {"v": 1, "id": "a", "ok": True}),
        "error with an unknown code": ("reply.json", {"v": 1, "id": "a", "ok": False, "error": {"code": "oops", "message": "", "field": ""}}),
        "telemetry without energy": ("event.json", {"v": 1, "type": "telemetry", "seq": 1, "session": "s", "step": 0, "time": 0, "bodies": [], "meshes": []}),
        "progress fraction above 1": ("event.json", {"v": 1, "type": "progress", "seq": 1, "session": "s", "step": 0, "time": 0, "parent_id": "a", "fraction": 1.5, "steps_per_second": 1}),
        "heartbeat with an unknown state": ("event.json", {"v": 1, "type": "heartbeat", "seq": 1, "session": "s", "step": 0, "time": 0, "state": "dancing"}),
        "scene with an unknown field": ("scene.json", dict(pair, colour="red")),
        "scene body with an unknown field": ("scene.json", dict(pair, bodies=[dict(pair["bodies"][0], colour="red"), pair["bodies"][1]])),
        "scene with negative teeth": ("scene.json", dict(pair, bodies=[dict(pair["bodies"][0], teeth=-20), pair["bodies"][1]])),
        "scene with zero module": ("scene.json", dict(pair, bodies=[dict(pair["bodies"][0], module_mm=0), pair["bodies"][1]])),
        "scene with a negative time step": ("scene.json", dict(pair, numerics={"time_step": -1e-5})),
        "carrier without inertia": ("scene.json", dict(pair, bodies=pair["bodies"] + [{"name": "c", "type": "carrier", "mass": 1}])),
        "carrier with teeth": ("scene.json", dict(pair, bodies=pair["bodies"] + [{"name": "c", "type": "carrier", "mass": 1, "inertia": 1, "teeth": 20}])),
        "ramp load without ramp_time": ("scene.json", dict(pair, loads=[{"body": "pinion", "type": "ramp", "moment": 1}])),
        "brake with a moment": ("scene.json", dict(pair, loads=[{"body": "pinion", "type": "brake", "coefficient": 1, "moment": 2}])),
        "lumped mesh with both damping forms": ("scene.json", dict(pair, meshes=[dict(pair["meshes"][0], damping=1, damping_ratio=0.1)])),
        "kinematic mesh with stiffness": ("scene.json", dict(pair, meshes=[dict(pair["meshes"][0], model="kinematic", stiffness=1e8)])),
        "connection file without endpoints": ("connection.json", {"v": 1, "protocol": 1, "session": "s", "pid": 1, "ranks": 1, "version": "x"}),
    }
    for name, (rel, inst) in must_fail.items():
        R.check(f"schema rejects: {name}", P.errors(rel, inst), f"{rel} accepted it")
    scenes = sorted(glob.glob(os.path.join(dmod.SOURCE_ROOT, "deploy", "scenes", "*.json")))
    R.check("deploy/scenes has example scenes", len(scenes) >= 2, scenes)
    for path in scenes:
        with open(path) as f:
            scene = json.load(f)
        R.check(f"{os.path.relpath(path, dmod.SOURCE_ROOT)} validates against scene.json",
                not P.errors("scene.json", scene), P.errors("scene.json", scene))


# ---------------------------------------------------------------- online
def check_reply(cmd, rec, what=None, expect_ok=True):
    """Validate one reply; returns the parsed reply (or None)."""
    frames, parsed, err = rec
    what = what or cmd
    if not R.check(f"{what}: reply is strict JSON in one frame", err is None and len(frames) == 1,
                   err or f"{len(frames)} frames"):
        return None
    errs = P.reply_errors(cmd, parsed)
    R.check(f"{what}: reply validates", not errs, errs)
    if expect_ok is not None:
        R.check(f"{what}: ok is {expect_ok}", parsed.get("ok") is expect_ok, json.dumps(parsed)[:600])
    if parsed.get("ok") is True:
        extra = P.undocumented(f"results/{cmd}.json", parsed.get("result"), "result.")
        if extra:
            undocumented.setdefault(f"results/{cmd}", set()).update(extra)
    return parsed


def call(probe, cmd, args=None, what=None, expect_ok=True, timeout=60.0):
    rid = probe.send(cmd, args)
    rec = probe.wait(rid, timeout)
    parsed = check_reply(cmd, rec, what, expect_ok)
    R.check(f"{what or cmd}: reply id matches", parsed is not None and parsed.get("id") == rid)
    return parsed, rid


def check_events(probe, session):
    """Every event received so far: frames, strict JSON, schema, topic, seq, session."""
    counts = {}
    problems = []
    last_seq = None
    gaps = 0
    for frames, parsed, err in probe.events:
        if len(frames) != 2:
            problems.append(f"event with {len(frames)} frames")
            continue
        if err:
            problems.append(f"event not strict JSON: {err}: {frames[1][:200]!r}")
            continue
        t = parsed.get("type")
        counts[t] = counts.get(t, 0) + 1
        if frames[0].decode(errors="replace") != t:
            problems.append(f"topic {frames[0]!r} != type {t!r}")
        errs = P.event_errors(parsed)
        if errs:
            problems.append(errs[0])
        if t in EVENTS:
            extra = P.undocumented(f"events/{t}.json", parsed)
            if extra:
                undocumented.setdefault(f"events/{t}", set()).update(extra)
        if parsed.get("session") != session:
            problems.append(f"session {parsed.get('session')!r} != {session!r}")
        seq = parsed.get("seq")
        if isinstance(seq, int):
            if last_seq is not None and seq != last_seq + 1:
                if seq <= last_seq:
                    problems.append(f"seq went from {last_seq} to {seq}")
                else:
                    gaps += seq - last_seq - 1
            last_seq = seq
    uniq = []
    for p in problems:
        if p not in uniq:
            uniq.append(p)
    R.check(f"all {len(probe.events)} events are valid (counts {counts})", not uniq, "\n".join(uniq[:15]))
    bad_batches = []
    for frames, parsed, err in probe.batches:
        errs = [err] if err else P.errors("batch.json", parsed)
        if not errs and frames[0] != b"batch":
            errs = [f"topic {frames[0]!r} of a batch"]
        seqs = [e.get("seq") for e in parsed.get("events", [])] if not errs else []
        if seqs and any(b != a + 1 for a, b in zip(seqs, seqs[1:])):
            errs = [f"seq within a batch not consecutive: {seqs[:8]}"]
        if errs:
            bad_batches.append(errs[0])
    R.check(f"all {len(probe.batches)} telemetry batches validate against batch.json, seq consecutive inside",
            not bad_batches, "\n".join(bad_batches[:5]))
    R.check("event seq increases by one (no gaps for a fast local subscriber)", gaps == 0, f"{gaps} missing")
    return counts


def name_of(item):
    """A list item that is a name or an object with a name."""
    return item.get("name") if isinstance(item, dict) else item


def wait_done(probe, rid, timeout=120.0):
    return probe.wait_event(lambda e: e.get("type") == "done" and e.get("parent_id") == rid, timeout)


def online():
    with dmod.Daemon(ranks=2) as d:
        with open(d.conn_file) as f:
            conn_text = f.read()
        try:
            conn = strict_loads(conn_text)
            R.check("connection file validates", not P.errors("connection.json", conn), P.errors("connection.json", conn))
        except ValueError as e:
            R.check("connection file is strict JSON", False, e)
            conn = {}
        mode = os.stat(d.conn_file).st_mode & 0o777
        R.check("connection file has mode 0600", mode == 0o600, oct(mode))
        R.check("connection file names 2 ranks", conn.get("ranks") == 2, conn.get("ranks"))
        undocumented["connection file"] = set(P.undocumented("connection.json", conn))
        probe = Probe(d.conn_file)
        session = conn.get("session")

        hello, _ = call(probe, "hello")
        res = (hello or {}).get("result", {})
        R.check("hello: session matches the connection file", res.get("session") == session,
                f"{res.get('session')} vs {session}")
        R.check("hello: lists every command", set(COMMANDS) <= set(res.get("commands", [])),
                set(COMMANDS) - set(res.get("commands", [])))
        R.check("hello: builtin_scenes lists pair and planetary",
                {"pair", "planetary"} <= set(res.get("builtin_scenes", [])), res.get("builtin_scenes"))
        R.check("hello: ranks = 2", res.get("ranks") == 2, res.get("ranks"))

        for cmd in ("hello", "status", "jobs"):
            call(probe, cmd, {}, what=f"{cmd} with empty args")
        st, _ = call(probe, "status", what="status (empty)")
        R.check("status (empty): state is empty", (st or {}).get("result", {}).get("state") == "empty", st)
        call(probe, "state", what="state (empty)", expect_ok=None)
        call(probe, "advance", {"steps": 10}, what="advance (empty)", expect_ok=False)

        # every example scene of scene.json loads (schema and parser agree),
        # except those needing a model this build lacks (hello's capabilities)
        caps = set(res.get("capabilities", []))
        for i, scene in enumerate(P.schemas["scene.json"]["examples"]):
            models = {b.get("model", "rigid") for b in scene["bodies"]} | {m.get("model") for m in scene.get("meshes", [])}
            missing = models - caps
            if missing:
                r, _ = call(probe, "load", {"scene": scene}, expect_ok=False,
                            what=f"load scene.json example {i} (needs {sorted(missing)}, not in capabilities)")
                continue
            r, _ = call(probe, "load", {"scene": scene}, what=f"load scene.json example {i}")
            if r and r.get("ok"):
                call(probe, "unload", what=f"unload example {i}")
        # a kinematic mesh with inconsistent initial speeds: a warning event
        kin = json.loads(json.dumps(dmod.load_scene("pair")))
        kin["meshes"] = [{"name": "pw", "gears": ["pinion", "wheel"], "model": "kinematic"}]
        kin["initial"] = {"pinion": {"omega": 10.0}}
        n0 = len(probe.events)
        r, _ = call(probe, "load", {"scene": kin}, what="load kinematic pair with inconsistent speeds")
        try:
            probe.wait_event(lambda e: e.get("type") == "warning", 5.0, start=n0)
            R.check("a warning event follows the projection of initial speeds", True)
        except TimeoutError:
            R.check("a warning event follows the projection of initial speeds (docs/reference/scene.md)", False,
                    "no warning event within 5 s")
        call(probe, "unload", what="unload kinematic pair")

        call(probe, "load", {"builtin": "planetary"}, what="load builtin planetary")
        call(probe, "unload", what="unload planetary")
        r, _ = call(probe, "load", {"scene": dmod.load_scene("pair")}, what="load pair")
        call(probe, "state")
        call(probe, "status")
        r, _ = call(probe, "set_load", {"load": {"name": "extra", "body": "wheel", "type": "brake", "coefficient": 0.01}},
                    what="set_load (add)")
        names = [name_of(ld) for ld in (r or {}).get("result", {}).get("loads", [])]
        R.check("set_load: the new load is listed", "extra" in names, names)
        r, _ = call(probe, "set_load", {"remove": "extra"}, what="set_load (remove)")
        names = [name_of(ld) for ld in (r or {}).get("result", {}).get("loads", [])]
        R.check("set_load: the removed load is gone", "extra" not in names, names)
        call(probe, "record", {"path": "proto.h5"}, what="record (start)")

        r, rid = call(probe, "advance", {"steps": 2000}, what="advance 2000 steps")
        done = wait_done(probe, rid)
        R.check("done: not cancelled, 2000 steps", done.get("cancelled") is False and done.get("steps") == 2000, done)
        R.check("done: step = 2000", done.get("step") == 2000, done)
        tel = [p for _, p, _ in probe.events if p and p.get("type") == "telemetry" and p.get("step", 0) <= 2000]
        R.check("telemetry events arrived during the advance (every 50 steps: 40)", len(tel) >= 40, len(tel))
        R.check("telemetry carries parent_id of the advance", all(t.get("parent_id") == rid for t in tel[-5:]),
                [t.get("parent_id") for t in tel[-5:]])
        every = dmod.load_scene("pair")["outputs"]["telemetry_every"]
        R.check(f"telemetry every {every} steps (outputs.telemetry_every)",
                all(t["step"] % every == 0 for t in tel) and
                all(b["step"] - a["step"] == every for a, b in zip(tel, tel[1:])), [t["step"] for t in tel[:5]])
        call(probe, "state", what="state (after advance)")

        # a long advance: pause, resume, cancel, and set_load/status/state during it
        # 1e9 steps: a rigid train at -n 2 now runs at hundreds of thousands
        # of steps per second (docs/explanation/modal.md), so the advance must not end
        # during these calls.
        t_adv0 = time.monotonic()
        r, rid = call(probe, "advance", {"steps": 1000000000}, what="advance 1e9 steps")
        time.sleep(0.3)
        call(probe, "status", what="status (running)")
        call(probe, "state", what="state (running)")
        call(probe, "hello", what="hello (running)")
        call(probe, "set_load", {"load": {"body": "pinion", "type": "constant", "moment": 15.0}}, what="set_load (running)")
        call(probe, "load", {"builtin": "pair"}, what="load (running)", expect_ok=False)
        call(probe, "checkpoint", {"path": "busy.h5"}, what="checkpoint (running)", expect_ok=False)
        call(probe, "advance", {"steps": 10}, what="second advance (running)", expect_ok=False)
        r, _ = call(probe, "pause")
        R.check("pause: state paused", (r or {}).get("result", {}).get("state") == "paused", r)
        s1, _ = call(probe, "status", what="status (paused)")
        time.sleep(0.3)
        s2, _ = call(probe, "status", what="status (paused, later)")
        step1 = (s1 or {}).get("result", {}).get("step")
        R.check("paused: the step does not move", step1 == (s2 or {}).get("result", {}).get("step"), (s1, s2))
        r, _ = call(probe, "resume")
        R.check("resume: state running", (r or {}).get("result", {}).get("state") == "running", r)
        time.sleep(0.2)
        r, _ = call(probe, "cancel")
        R.check("cancel: cancelled true", (r or {}).get("result", {}).get("cancelled") is True, r)
        done = wait_done(probe, rid)
        t_adv1 = time.monotonic()
        R.check("done after cancel: cancelled true", done.get("cancelled") is True, done)
        # Heartbeats are timed by their arrival here: not while this probe
        # works through the telemetry of the fast advance above.
        calm = time.monotonic()
        idx = [i for i, (_, p, _) in enumerate(probe.events)
               if p and p.get("type") == "progress" and p.get("parent_id") == rid]
        R.check("progress events tagged with the advance id", len(idx) >= 1, len(idx))
        # The daemon spaces progress events by at least 0.1 s, so over the
        # advance's whole life (from before the request to the done event's
        # arrival, an upper bound of the daemon's run) at most 10 per second
        # plus the first. Arrival times of single events are not used: a busy
        # machine delivers queued events in bursts.
        life = t_adv1 - t_adv0
        R.check(f"progress at most 10 per second ({len(idx)} in an advance of {life:.2f} s)",
                len(idx) - 1 <= 10.0 * life + 1.0, (len(idx), life))
        fr = [probe.events[i][1]["fraction"] for i in idx]
        R.check("progress fraction does not decrease", all(b >= a for a, b in zip(fr, fr[1:])), fr)
        r, _ = call(probe, "cancel", what="cancel (nothing running)")
        r, rid = call(probe, "advance", {"time": 0.001}, what="advance by time")
        done = wait_done(probe, rid)
        R.check("advance by 0.001 s: 100 steps", done.get("steps") == 100, done)
        call(probe, "record", {"stop": True}, what="record (stop)")

        r, _ = call(probe, "checkpoint", {"path": "cp.h5"})
        r, _ = call(probe, "restore", {"path": "cp.h5"})
        call(probe, "restore", {"path": "missing.h5"}, what="restore (missing file)", expect_ok=False)
        r, _ = call(probe, "fetch", {"path": "proto.h5", "offset": 0, "length": 65536})
        r, _ = call(probe, "submit", {"scene": dmod.load_scene("pair"), "duration": 0.002, "record": "job1.h5"},
                    what="submit", expect_ok=None)
        r, _ = call(probe, "jobs")
        call(probe, "unload")
        # a queued job may now run: give it a moment, then list the jobs again
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            r, _ = call(probe, "jobs", what="jobs (polling)")
            jobs = (r or {}).get("result", {}).get("jobs", [])
            if jobs and all(j.get("state") not in ("queued", "running") for j in jobs):
                break
            time.sleep(0.5)
        R.check("submitted job finished within 30 s", jobs and all(j.get("state") not in ("queued", "running") for j in jobs), jobs)
        call(probe, "status", what="status (after unload)")
        until = time.monotonic() + 2.5   # at least two more heartbeats
        while time.monotonic() < until:
            probe.pump(until - time.monotonic())
        hb = [probe.event_times[i] for i, (_, p, _) in enumerate(probe.events)
              if p and p.get("type") == "heartbeat" and probe.event_times[i] > calm]
        gaps = [b - a for a, b in zip(hb, hb[1:])]
        R.check(f"heartbeat every second ({len(hb)} heartbeats, intervals {min(gaps, default=0):.2f}"
                f"..{max(gaps, default=0):.2f} s)", gaps and all(0.5 <= g <= 2.5 for g in gaps),
                [round(g, 2) for g in gaps])
        counts = check_events(probe, session)
        for t in ("telemetry", "progress", "done", "heartbeat", "warning"):
            R.check(f"saw {t} events", counts.get(t, 0) > 0, counts)
        if not counts.get("error"):
            R.note("no 'error' event was provoked in this session (its schema is checked by examples only)")
        r, _ = call(probe, "shutdown")
        try:
            d.proc.wait(timeout=30)
            R.check("daemon exits after shutdown", True)
            R.check("exit status 0 after shutdown", d.proc.returncode == 0, d.proc.returncode)
        except Exception:  # noqa: BLE001
            R.check("daemon exits within 30 s of shutdown", False, d.log_tail())
        probe.close()
    if undocumented:
        for k, v in sorted(undocumented.items()):
            if v:
                R.note(f"undocumented fields in {k}: {sorted(v)}")


offline()
R.guard("session against the real daemon", online)
R.finish()
