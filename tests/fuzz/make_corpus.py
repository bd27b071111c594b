#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Write the seed corpus of the fuzz targets from the protocol's own examples:
corpus/request/ gets every `examples` entry of proto/v1/requests/*.json (one
request per file, one line) plus a few multi-request sequences (one request
per line: load, then commands that need a loaded scene); corpus/scene/ gets
the examples of proto/v1/scene.json and deploy/scenes/*.json.

    tests/fuzz/make_corpus.py            # rewrite tests/fuzz/corpus/
"""
import glob
import hashlib
import json
import os
import shutil

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))


def compact(o):
    return json.dumps(o, separators=(",", ":"))


def write(d, data):
    name = hashlib.sha1(data.encode()).hexdigest()[:16]
    with open(os.path.join(d, name), "w") as f:
        f.write(data)


def main():
    out = os.path.join(HERE, "corpus")
    shutil.rmtree(out, ignore_errors=True)
    req_dir, scene_dir = os.path.join(out, "request"), os.path.join(out, "scene")
    os.makedirs(req_dir)
    os.makedirs(scene_dir)
    requests = {}
    for p in sorted(glob.glob(os.path.join(ROOT, "proto", "v1", "requests", "*.json"))):
        with open(p) as f:
            schema = json.load(f)
        for ex in schema.get("examples", []):
            if ex.get("cmd") == "stiffness":   # skipped by the target (seconds per run)
                continue
            requests.setdefault(ex.get("cmd"), []).append(ex)
            write(req_dir, compact(ex))
            if ex.get("cmd") not in ("hello", "load", "submit", "jobs", "shutdown", "restore"):
                # the same request with a scene loaded first
                write(req_dir, compact({"v": 1, "id": "L", "cmd": "load", "args": {"builtin": "pair"}})
                      + "\n" + compact(ex))
    pair = json.load(open(os.path.join(ROOT, "deploy", "scenes", "pair.json")))
    load = {"v": 1, "id": "s1", "cmd": "load", "args": {"scene": pair}}
    seqs = [
        [load, {"v": 1, "id": "s2", "cmd": "set_load", "args": {"load": {"body": "pinion", "type": "constant", "moment": 5}}},
         {"v": 1, "id": "s3", "cmd": "advance", "args": {"steps": 10}},
         {"v": 1, "id": "s4", "cmd": "status"}, {"v": 1, "id": "s5", "cmd": "cancel"},
         {"v": 1, "id": "s6", "cmd": "state"}],
        [{"v": 1, "id": "b1", "cmd": "load", "args": {"builtin": "planetary"}},
         {"v": 1, "id": "b2", "cmd": "checkpoint", "args": {"path": "c.h5"}},
         {"v": 1, "id": "b3", "cmd": "restore", "args": {"path": "c.h5"}},
         {"v": 1, "id": "b4", "cmd": "fetch", "args": {"path": "c.h5", "offset": 0, "length": 64}},
         {"v": 1, "id": "b5", "cmd": "record", "args": {"path": "r.h5"}},
         {"v": 1, "id": "b6", "cmd": "record", "args": {"stop": True}}],
        [{"v": 1, "id": "j1", "cmd": "submit", "args": {"scene": pair, "duration": 0.001, "record": "j.h5",
                                                        "schedule": [{"at": 0.0005, "load": {"body": "pinion", "type": "constant", "moment": 1}}]}},
         {"v": 1, "id": "j2", "cmd": "jobs"}, {"v": 1, "id": "j1", "cmd": "hello"}],
        # a job waiting for a client's scene, then unload; status with its finished list
        [{"v": 1, "id": "w1", "cmd": "load", "args": {"builtin": "pair"}},
         {"v": 1, "id": "w2", "cmd": "submit", "args": {"scene": pair, "duration": 0.0002}},
         {"v": 1, "id": "w3", "cmd": "jobs"}, {"v": 1, "id": "w4", "cmd": "unload"},
         {"v": 1, "id": "w5", "cmd": "advance", "args": {"steps": 3}}, {"v": 1, "id": "w6", "cmd": "status"}],
        # the same id again (reply cache), v as 1.0
        [{"v": 1, "id": "r1", "cmd": "status"}, {"v": 1, "id": "r1", "cmd": "status"},
         {"v": 1.0, "id": "r2", "cmd": "hello"}],
    ]
    for seq in seqs:
        write(req_dir, "\n".join(compact(r) for r in seq))
    for raw in ['{"v":1,"id":"x","cmd":"nope"}', '{"v":2,"id":"x","cmd":"hello"}', "[]", "{",
                '{"v":1,"id":"x","cmd":"advance","args":{"time":1e308}}',
                '{"v":1,"id":"x","cmd":"fetch","args":{"path":"../etc/passwd"}}',
                # strict JSON (RFC 8259): each of these is refused with bad_json
                '{"v":1,"id":"x","cmd":"status","cmd":"shutdown"}',
                '{"v":1,"id":"x","cmd":"status","c\\u006dd":"shutdown"}',
                '{"v":1,"id":"x\\u0000y","cmd":"status"}',
                '{"v":1,"id":"\\ud800","cmd":"status"}', '{"v":1,"id":"\\udc00\\ud800","cmd":"status"}',
                '{"v":1,"id":"\\ud83d\\ude00","cmd":"status"}',
                '{"v":1,/*c*/"id":"x","cmd":"status"}', "{'v':1,'id':'x','cmd':'status'}",
                '{"v":1,"id":"x","cmd":"status",}', '{"v":01,"id":"x","cmd":"status"}',
                '{"v":1,"id":"x","cmd":"advance","args":{"time":NaN}}',
                '{"v":1,"id":"x","cmd":"advance","args":{"time":-Infinity}}',
                '{"v":1,"id":"x","cmd":"status"}garbage', '{"v":1.0,"id":"x","cmd":"status"}',
                '{"v":1,"id":"x","cmd":"advance","args":{"steps":1e999}}',
                '{"v":1,"id":"x","cmd":"stiffness","args":{"mesh":"m","wait":true}}']:
        write(req_dir, raw)
    with open(os.path.join(ROOT, "proto", "v1", "scene.json")) as f:
        for ex in json.load(f).get("examples", []):
            write(scene_dir, json.dumps(ex, indent=1))
    for p in sorted(glob.glob(os.path.join(ROOT, "deploy", "scenes", "*.json"))):
        with open(p) as f:
            write(scene_dir, f.read())
    # variants that reach the options no builtin scene uses
    def scene(name):
        with open(os.path.join(ROOT, "deploy", "scenes", name + ".json")) as f:
            return json.load(f)
    s = scene("contact_impact")
    s["numerics"] = {"time_step": 1e-5, "adaptive": {"penetration_um": 1.0, "levels": 3}}
    write(scene_dir, json.dumps(s, indent=1))
    s = scene("contact_drive")
    s["meshes"][0]["friction"] = 0.05
    for b in s["bodies"]:
        b["material"] = {"E": 210e9, "nu": 0.3, "density": 7850, "plane": "stress", "damping_s": 1.7e-6}
    write(scene_dir, json.dumps(s, indent=1))
    s = scene("pair")
    s["meshes"][0] = {"name": s["meshes"][0]["name"], "gears": s["meshes"][0]["gears"], "model": "compliant",
                      "patches": 20, "bending": "beam", "damping_ratio": 0.05}
    write(scene_dir, json.dumps(s, indent=1))
    s = scene("planetary_contact")
    for b in s["bodies"]:
        if b["name"] not in ("ring", "carrier"):
            b["model"] = "rigid"
    for m in s["meshes"]:
        if m["name"].startswith("sun-"):
            m["model"] = "lumped"
    write(scene_dir, json.dumps(s, indent=1))
    print(f"{len(os.listdir(req_dir))} request seeds, {len(os.listdir(scene_dir))} scene seeds in {out}")


if __name__ == "__main__":
    main()
