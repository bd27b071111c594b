#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Bad input of every kind gets an error reply with the right code (and the
field at fault), the daemon keeps serving, and nothing changes: a pair run of
fixed steps gives the same state, bit for bit, before and after the bad
requests."""
import copy
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import RawDealer, Results  # noqa: E402
from protoschema import Proto  # noqa: E402

R = Results("test_bad_input: bad requests get error replies and change nothing")
P = Proto()
STEPS = 1000

# Codes where docs/reference/protocol.md leaves a choice (e.g. how a refused path is
# reported) accept a small set; everything else must be the one code.
PATH_CODES = {"invalid_field", "out_of_range", "invalid_argument"}
NOT_JSON = {"bad_json"}
SCHEMA = {"invalid_field"}
RANGE = {"out_of_range"}
NOTFOUND = {"not_found"}
NONFINITE = {"bad_json", "out_of_range", "invalid_field"}


_ids = iter(range(1, 1 << 30))


def uid():
    """A fresh request id: the daemon answers a repeated id from its reply cache."""
    return f"bad{next(_ids)}"


def raw_req(text):
    """Raw request text with @ID@ replaced by a fresh id."""
    return text.replace("@ID@", uid()).encode()


def req(cmd, args=None, rid=None, **extra):
    m = {"v": 1, "id": rid or uid(), "cmd": cmd}
    if args is not None:
        m["args"] = args
    m.update(extra)
    return m


def scene_with(mutate):
    s = copy.deepcopy(dmod.load_scene("pair"))
    mutate(s)
    return s


def planetary_with(mutate):
    s = copy.deepcopy(dmod.load_scene("planetary"))
    mutate(s)
    return s


def set_body(i, **kw):
    return lambda s: s["bodies"][i].update(kw)


def bad_planetary(s):
    # sun 25, planets 24, ring 73: concentric (73 - 25 = 2 x 24) but
    # (25 + 73) / 3 is not an integer: three equally spaced planets cannot be assembled
    for b in s["bodies"]:
        if b["name"] == "sun":
            b["teeth"] = 25
        elif b["name"] == "ring":
            b["teeth"] = 73
    for j in s["joints"]:
        if j["type"] == "on_carrier":
            j["radius_mm"] = (25 + 24) * 2.5 / 2


def two_rings(s):
    s["bodies"] = [{"name": "r1", "kind": "internal", "teeth": 60, "module_mm": 2.5},
                   {"name": "r2", "kind": "internal", "teeth": 40, "module_mm": 2.5}]
    s["joints"] = [{"body": "r1", "type": "fixed_axis"}, {"body": "r2", "type": "fixed_axis", "centre_mm": [25, 0]}]
    s["meshes"] = [{"name": "rr", "gears": ["r1", "r2"], "model": "lumped"}]
    s["loads"] = []
    s.pop("initial", None)


def load_case(name, mutate, codes, field, base=scene_with):
    return (name, req("load", {"scene": base(mutate)}), codes, field)


def cases_empty(limits):
    """Bad requests sent with nothing loaded: (name, payload, codes, field suffix or None).
    payload: dict (sent as JSON), bytes (sent raw), or list of frames."""
    big = limits.get("max_message_bytes", 1 << 20)
    oversized = json.dumps(req("hello", rid="big")).replace('"cmd"', '"pad":"%s","cmd"' % ("x" * (big + 1024)))
    c = [
        ("malformed JSON", b'{"v":1,"id":"m1","cmd":"hello"', NOT_JSON, None),
        ("JSON array instead of an object", b'[1,2,3]', NOT_JSON | SCHEMA, None),
        ("JSON string instead of an object", b'"hello"', NOT_JSON | SCHEMA, None),
        ("JSON number instead of an object", b'42', NOT_JSON | SCHEMA, None),
        ("JSON null", b'null', NOT_JSON | SCHEMA, None),
        ("empty frame", b'', NOT_JSON, None),
        ("binary garbage", bytes(range(256)) * 4, NOT_JSON, None),
        ("invalid UTF-8 in a string", b'{"v":1,"id":"u1","cmd":"hel\xff\xfelo"}', NOT_JSON | {"unknown_command"}, None),
        ("NUL byte inside the JSON", b'{"v":1,"id":"n1",\x00"cmd":"hello"}', NOT_JSON, None),
        ("trailing garbage after the object", b'{"v":1,"id":"t1","cmd":"hello"} xyz', NOT_JSON, None),
        ("deeply nested JSON", b'{"v":1,"id":"d1","cmd":"hello","args":' + b'[' * 100000 + b']' * 100000 + b'}',
         NOT_JSON | {"too_large"} | SCHEMA, None),
        ("oversized message (> limits.max_message_bytes)", oversized.encode(), {"too_large"}, None),
        ("multi-frame message", [b'{"v":1,"id":"mf1","cmd":"hello"}', b'{"v":1,"id":"mf2","cmd":"hello"}'],
         NOT_JSON | SCHEMA | {"invalid_argument", "too_large"}, None),
        ("wrong protocol version v=2", req("hello", v=2), {"unsupported_version"}, "v"),
        ("v missing", {"id": uid(), "cmd": "hello"}, {"unsupported_version"} | SCHEMA, "v"),
        ("v is a string", req("hello", v="1"), {"unsupported_version"} | SCHEMA, "v"),
        ("id missing", {"v": 1, "cmd": "hello"}, SCHEMA, "id"),
        ("id is a number", {"v": 1, "id": next(_ids), "cmd": "hello"}, SCHEMA, "id"),
        ("cmd missing", {"v": 1, "id": uid()}, SCHEMA, "cmd"),
        ("cmd is a number", {"v": 1, "id": uid(), "cmd": 3}, SCHEMA, "cmd"),
        ("unknown command", req("fly"), {"unknown_command"}, "cmd"),
        ("empty command", req(""), {"unknown_command"}, "cmd"),
        ("unknown envelope field", req("hello", extra=1), SCHEMA, "extra"),
        ("args is not an object", req("hello", 5), SCHEMA, "args"),
        ("unknown argument of hello", req("hello", {"verbose": True}), SCHEMA, "verbose"),
        ("advance with nothing loaded", req("advance", {"steps": 10}), {"wrong_state"}, None),
        ("checkpoint with nothing loaded", req("checkpoint", {"path": "c.h5"}), {"wrong_state"}, None),
        ("load: scene is a string", req("load", {"scene": "pair.json"}), SCHEMA, "scene"),
        ("load: no scene and no builtin", req("load", {}), SCHEMA, None),
        ("load: both scene and builtin", req("load", {"scene": dmod.load_scene("pair"), "builtin": "pair"}), SCHEMA, None),
        ("load: unknown builtin", req("load", {"builtin": "octopus"}), NOTFOUND, "builtin"),
        load_case("scene: unknown top-level field", lambda s: s.update(colour="red"), SCHEMA, "colour"),
        load_case("scene: unknown body field", set_body(0, colour="red"), SCHEMA, "bodies[0].colour"),
        load_case("scene: negative teeth", set_body(0, teeth=-20), RANGE, "bodies[0].teeth"),
        load_case("scene: teeth as a string", set_body(0, teeth="20"), SCHEMA, "bodies[0].teeth"),
        load_case("scene: fractional teeth", set_body(0, teeth=20.5), SCHEMA | RANGE, "bodies[0].teeth"),
        load_case("scene: zero module", set_body(1, module_mm=0), RANGE, "bodies[1].module_mm"),
        load_case("scene: negative time step", lambda s: s["numerics"].update(time_step=-1e-5), RANGE, "numerics.time_step"),
        load_case("scene: zero time step", lambda s: s["numerics"].update(time_step=0), RANGE, "numerics.time_step"),
        ("scene: NaN literal time step", json.dumps(req("load", {"scene": dmod.load_scene("pair")}))
         .replace('"time_step": 1e-05', '"time_step": NaN').encode(), NONFINITE, None),
        ("scene: 1e400 module", json.dumps(req("load", {"scene": dmod.load_scene("pair")}))
         .replace('"module_mm": 2.5', '"module_mm": 1e400', 1).encode(), NONFINITE, None),
        load_case("scene: unknown body in a joint", lambda s: s["joints"][1].update(body="wheeel"), NOTFOUND | SCHEMA, "joints[1].body"),
        load_case("scene: unknown body in a mesh", lambda s: s["meshes"][0].update(gears=["pinion", "whee1"]), NOTFOUND | SCHEMA, "meshes[0].gears"),
        load_case("scene: unknown body in a load", lambda s: s["loads"][0].update(body="motor"), NOTFOUND | SCHEMA, "loads[0].body"),
        load_case("scene: unknown body in initial", lambda s: s.update(initial={"motor": {"omega": 1}}), NOTFOUND | SCHEMA, "initial.motor"),
        load_case("scene: duplicate body names", set_body(1, name="pinion"), SCHEMA, "bodies[1].name"),
        load_case("scene: a body without a joint", lambda s: s["joints"].pop(), SCHEMA, "bodies[1]"),
        load_case("scene: no bodies", lambda s: s.update(bodies=[], joints=[], meshes=[], loads=[], initial={}), RANGE | SCHEMA, "bodies"),
        load_case("scene: 65 bodies", lambda s: s.update(
            bodies=[{"name": f"g{i}", "teeth": 20, "module_mm": 1} for i in range(65)],
            joints=[{"body": f"g{i}", "type": "fixed_axis", "centre_mm": [100 * i, 0]} for i in range(65)],
            meshes=[], loads=[], initial={}), RANGE | {"too_large"}, "bodies"),
        load_case("scene: negative mass", set_body(0, mass=-1.0), RANGE, "bodies[0].mass"),
        load_case("scene: unknown mesh model", lambda s: s["meshes"][0].update(model="magic"), RANGE | SCHEMA, "meshes[0].model"),
        load_case("scene: telemetry_every 0", lambda s: s["outputs"].update(telemetry_every=0), RANGE, "outputs.telemetry_every"),
        load_case("scene: table times not increasing", lambda s: s["loads"].__setitem__(0, {
            "body": "pinion", "type": "table", "times": [0, 0.02, 0.01], "moments": [0, 1, 2]}), RANGE, "loads[0].times[2]"),
        load_case("scene: centre distance too small for the pair", lambda s: s["joints"][1].update(centre_mm=[40, 0]),
                  {"impossible_geometry"}, "meshes[0]"),
        load_case("scene: planetary tooth counts that cannot assemble", bad_planetary, {"impossible_geometry"}, None,
                  base=planetary_with),
        load_case("scene: a mesh between two rings", two_rings, {"impossible_geometry"}, "meshes[0]"),
        ("submit: missing duration", req("submit", {"scene": dmod.load_scene("pair")}), SCHEMA, "duration"),
        ("submit: path traversal in record", req("submit", {"scene": dmod.load_scene("pair"), "duration": 0.01,
                                                          "record": "../x.h5"}), PATH_CODES, "record"),
        ("fetch: path traversal", req("fetch", {"path": "../../etc/passwd", "offset": 0, "length": 100}), PATH_CODES, "path"),
        ("fetch: absolute path", req("fetch", {"path": "/etc/passwd", "offset": 0, "length": 100}), PATH_CODES, "path"),
        ("fetch: missing file", req("fetch", {"path": "nothing-here.h5", "offset": 0, "length": 100}), NOTFOUND, "path"),
        ("fetch: length over 1 MiB", req("fetch", {"path": "conn.json", "offset": 0, "length": 2 << 20}), RANGE | {"too_large"}, "length"),
        ("fetch: negative offset", req("fetch", {"path": "conn.json", "offset": -5, "length": 10}), RANGE, "offset"),
    ]
    return c


def cases_loaded(limits):
    maxsteps = limits.get("max_steps_per_advance", 10 ** 9)
    return [
        ("advance: unknown argument", req("advance", {"steps": 10, "speed": 2}), SCHEMA, "speed"),
        ("advance: no arguments", req("advance"), SCHEMA, None),
        ("advance: both time and steps", req("advance", {"steps": 10, "time": 0.1}), SCHEMA, None),
        ("advance: steps as a string", req("advance", {"steps": "10"}), SCHEMA, "steps"),
        ("advance: fractional steps", req("advance", {"steps": 2.5}), SCHEMA | RANGE, "steps"),
        ("advance: negative steps", req("advance", {"steps": -5}), RANGE, "steps"),
        ("advance: zero steps", req("advance", {"steps": 0}), RANGE, "steps"),
        ("advance: negative time", req("advance", {"time": -0.1}), RANGE, "time"),
        ("advance: zero time", req("advance", {"time": 0}), RANGE, "time"),
        ("advance: NaN literal", raw_req('{"v":1,"id":"@ID@","cmd":"advance","args":{"time":NaN}}'), NONFINITE, None),
        ("advance: Infinity literal", raw_req('{"v":1,"id":"@ID@","cmd":"advance","args":{"time":Infinity}}'), NONFINITE, None),
        ("advance: -Infinity literal", raw_req('{"v":1,"id":"@ID@","cmd":"advance","args":{"time":-Infinity}}'), NONFINITE, None),
        ("advance: time 1e400", raw_req('{"v":1,"id":"@ID@","cmd":"advance","args":{"time":1e400}}'), NONFINITE | {"too_large"}, None),
        ("advance: time 1e300 (too many steps)", req("advance", {"time": 1e300}), RANGE | {"too_large"}, "time"),
        ("advance: steps above limits.max_steps_per_advance", req("advance", {"steps": maxsteps + 1}), RANGE | {"too_large"}, "steps"),
        ("advance: steps 1e20", raw_req('{"v":1,"id":"@ID@","cmd":"advance","args":{"steps":100000000000000000000}}'),
         RANGE | {"too_large"} | SCHEMA, "steps"),
        ("set_load: unknown body", req("set_load", {"load": {"body": "motor", "type": "constant", "moment": 1}}),
         NOTFOUND | SCHEMA, "load.body"),
        ("set_load: unknown load type", req("set_load", {"load": {"body": "pinion", "type": "magic", "moment": 1}}),
         RANGE | SCHEMA, "load.type"),
        ("set_load: unknown load field", req("set_load", {"load": {"body": "pinion", "type": "constant", "moment": 1, "x": 2}}),
         SCHEMA, "load.x"),
        ("set_load: NaN moment", raw_req('{"v":1,"id":"@ID@","cmd":"set_load","args":{"load":{"body":"pinion","type":"constant","moment":NaN}}}'),
         NONFINITE, None),
        ("set_load: remove an unknown load", req("set_load", {"remove": "nonexistent"}), NOTFOUND, "remove"),
        ("record: path traversal", req("record", {"path": "../x.h5"}), PATH_CODES, "path"),
        ("record: absolute path", req("record", {"path": "/tmp/x.h5"}), PATH_CODES, "path"),
        ("record: stop false", req("record", {"stop": False}), SCHEMA | RANGE, None),
        ("checkpoint: path traversal", req("checkpoint", {"path": "a/../../x.h5"}), PATH_CODES, "path"),
        ("checkpoint: absolute path", req("checkpoint", {"path": "/tmp/x.h5"}), PATH_CODES, "path"),
        ("checkpoint: path is a number", req("checkpoint", {"path": 5}), SCHEMA, "path"),
        ("restore: missing file", req("restore", {"path": "missing.h5"}), NOTFOUND | {"io_error"}, "path"),
        ("restore: not an HDF5 file", req("restore", {"path": "conn.json"}), {"io_error", "invalid_argument"} | NOT_JSON | SCHEMA, None),
        ("restore: path traversal", req("restore", {"path": "../x.h5"}), PATH_CODES, "path"),
        ("load: while loaded, a bad scene", req("load", {"scene": scene_with(set_body(0, teeth=-3))}),
         RANGE | {"wrong_state"}, None),
    ]


def snapshot(c):
    s = c.state()
    return {"step": s["step"], "time": s["time"], "energy": s["energy"],
            "bodies": [(b["name"], b["angle"], b["omega"]) for b in s["bodies"]],
            "meshes": [(m.get("name"), m.get("force"), m.get("deflection")) for m in s.get("meshes", [])]}


def baseline_run(c):
    c.load(scene=dmod.load_scene("pair"))
    c.advance(steps=STEPS, timeout=300)
    return snapshot(c)


def same(a, b):
    """Bit-for-bit equality of two snapshots (floats compared with ==)."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True) and a == b


def names_field(f, field):
    """The reply's field names the expected path: it ends with it (any prefix such
    as 'args.scene.'), or goes below it ('meshes[0].gears' names 'meshes[0]')."""
    return f.endswith(field) or (field + ".") in f or (field + "[") in f


def send_case(raw, payload):
    if isinstance(payload, dict):
        raw.send_json(payload)
    elif isinstance(payload, list):
        raw.send_multipart(payload)
    else:
        raw.send(payload)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        frames, reply = raw.recv(timeout=deadline - time.monotonic())
        if frames is None:
            return None, "no reply within 30 s"
        if reply is None:
            return None, f"reply is not JSON: {frames[-1][:200]!r}"
        return reply, None
    return None, "no reply"


def run_cases(d, raw, cases, seen):
    for name, payload, codes, field in cases:
        seen.add(name)
        reply, err = send_case(raw, payload)
        if reply is None:
            R.check(f"{name}: error reply", False, err)
            if not d.alive():
                R.check("daemon still running", False, d.log_tail())
                return False
            continue
        detail = json.dumps(reply)[:600]
        env = P.errors("reply.json", reply)
        ok = reply.get("ok") is False and not env
        e = reply.get("error") or {}
        ok = ok and e.get("code") in codes
        if field is not None:
            f = e.get("field") or ""
            ok = ok and names_field(f, field)
        got = f" -> {e.get('code')} {e.get('field') or ''}".rstrip()
        R.check(f"{name}: {'/'.join(sorted(codes))}" + (f" naming {field}" if field else "") + got, ok,
                detail + ("; " + "; ".join(env) if env else ""))
        if isinstance(payload, dict) and isinstance(payload.get("id"), str):
            R.check(f"{name}: reply carries the request id", reply.get("id") == payload["id"], reply.get("id"))
        extra = []
        while True:   # exactly one reply per request
            frames, more = raw.recv(timeout=0.05)
            if frames is None:
                break
            extra.append(more if more is not None else frames)
        R.check(f"{name}: exactly one reply", not extra, str(extra)[:400])
        if reply.get("ok") is True:
            with d.client() as c:
                c.cancel()   # e.g. an advance that should have been refused: stop it
    return d.alive()


def main():
    with dmod.Daemon(ranks=2) as d:
        limits = d.hello.get("limits", {})
        with d.client() as c:
            before = R.guard("baseline run", baseline_run, c)
            c.unload()
        raw = RawDealer(d.conn_file)
        seen = set()
        alive = run_cases(d, raw, cases_empty(limits), seen)
        if alive:
            with d.client() as c:
                c.load(scene=dmod.load_scene("pair"))
            alive = run_cases(d, raw, cases_loaded(limits), seen)
        R.check(f"at least 40 distinct bad requests ({len(seen)})", len(seen) >= 40, len(seen))
        R.check("daemon still running after the bad requests", alive and d.alive(), d.log_tail())
        if not alive:
            return
        with d.client() as c:
            R.check("daemon answers hello", c.hello().get("protocol") == 1)
            st = c.status()
            R.check("scene still loaded at step 0 (nothing was executed)", st.get("state") == "loaded" and st.get("step") == 0, st)
            c.advance(steps=STEPS, timeout=300)
            after_same_load = snapshot(c)
            c.unload()
            after = baseline_run(c)
        if before is not None:
            R.check(f"same pair run ({STEPS} steps) before and after the bad requests, bit for bit",
                    same(before, after), f"before {before}\nafter {after}")
            R.check("and on the scene that received the bad requests", same(before, after_same_load),
                    f"before {before}\nafter {after_same_load}")
        raw.close()


R.guard("bad input against the real daemon", main)
R.finish()
