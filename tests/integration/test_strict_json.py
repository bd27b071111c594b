#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Strict JSON (RFC 8259) against the real daemon: every lenient form that
json-c would accept is refused with bad_json (duplicate keys, `cmd` included,
NUL and raw control characters, lone surrogates, comments, single quotes,
trailing commas, leading zeros, NaN/Infinity, trailing garbage), nothing of
a refused request runs, "v": 1.0 is accepted, frames over the message limit
and over 64 MiB are answered with too_large naming the limit, and default
load names of bodies with long common prefixes stay distinct."""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import RawDealer, Results  # noqa: E402

R = Results("test_strict_json: strict RFC 8259 requests, every request answered")

BAD = [
    ("duplicate cmd (shutdown after status)", '{"v":1,"id":"@","cmd":"status","cmd":"shutdown"}', "cmd"),
    ("duplicate id", '{"v":1,"id":"@","id":"@x","cmd":"status"}', "id"),
    ("duplicate key after unescaping", '{"v":1,"id":"@","cmd":"status","c\\u006dd":"shutdown"}', "cmd"),
    ("duplicate key inside args.scene",
     '{"v":1,"id":"@","cmd":"load","args":{"scene":{"name":"a","name":"b"}}}', "args.scene.name"),
    ("NUL byte inside a string", '{"v":1,"id":"@\x00tail","cmd":"status"}', "id"),
    ("escaped NUL inside a string", '{"v":1,"id":"@\\u0000tail","cmd":"status"}', "id"),
    ("raw control character", '{"v":1,"id":"@\x01","cmd":"status"}', "id"),
    ("lone high surrogate", '{"v":1,"id":"@\\ud800","cmd":"status"}', "id"),
    ("lone low surrogate", '{"v":1,"id":"@\\udc00","cmd":"status"}', "id"),
    ("misordered surrogates", '{"v":1,"id":"@\\udc00\\ud800","cmd":"status"}', "id"),
    ("block comment", '{"v":1,/* c */"id":"@","cmd":"status"}', None),
    ("line comment", '{"v":1,"id":"@","cmd":"status"} // c', None),
    ("single quotes", "{'v':1,'id':'@','cmd':'status'}", None),
    ("trailing comma in object", '{"v":1,"id":"@","cmd":"status",}', None),
    ("trailing comma in array",
     '{"v":1,"id":"@","cmd":"advance","args":{"steps":[1,]}}', None),
    ("leading zero", '{"v":01,"id":"@","cmd":"status"}', "v"),
    ("NaN literal", '{"v":1,"id":"@","cmd":"advance","args":{"time":NaN}}', "args.time"),
    ("Infinity literal", '{"v":1,"id":"@","cmd":"advance","args":{"time":Infinity}}', "args.time"),
    ("-Infinity literal", '{"v":1,"id":"@","cmd":"advance","args":{"time":-Infinity}}', "args.time"),
    ("trailing garbage", '{"v":1,"id":"@","cmd":"status"}x', None),
    ("two objects", '{"v":1,"id":"@","cmd":"status"}{"v":1,"id":"@2","cmd":"shutdown"}', None),
    ("unquoted key", '{v:1,"id":"@","cmd":"status"}', None),
    ("byte order mark", '\ufeff{"v":1,"id":"@","cmd":"status"}', None),
]


def alive(d, dealer, n):
    rep, _ = dealer.request({"v": 1, "id": f"alive{n}", "cmd": "status"}, timeout=20)
    return rep is not None and rep.get("ok") is True and d.alive()


def run():
    with dmod.Daemon() as d:
        dealer = RawDealer(d.conn_file)
        hello, _ = dealer.request({"v": 1, "id": "h", "cmd": "hello"})
        limit = hello["result"]["limits"]["max_message_bytes"]
        for i, (name, text, field) in enumerate(BAD):
            dealer.send(text.replace("@", f"s{i}").encode("utf-8", "surrogatepass"))
            _, rep = dealer.recv(20)
            err = (rep or {}).get("error") or {}
            ok = rep is not None and rep.get("ok") is False and err.get("code") == "bad_json"
            if field is not None:
                ok = ok and err.get("field") == field
            R.check(f"{name}: bad_json" + (f" naming '{field}'" if field else ""), ok, rep)
        R.check("after the refused requests the daemon still answers (no shutdown ran)", alive(d, dealer, 0))

        # Numbers equal to 1 are version 1 (the schema's const), 2.0 is not.
        dealer.send(b'{"v":1.0,"id":"v10b","cmd":"status"}')
        _, rep = dealer.recv(20)
        R.check('"v": 1.0 is accepted', rep and rep.get("ok") is True, rep)
        dealer.send(b'{"v":2.0,"id":"v20","cmd":"status"}')
        _, rep = dealer.recv(20)
        R.check('"v": 2.0 is refused: unsupported_version',
                rep and rep.get("error", {}).get("code") == "unsupported_version", rep)

        # Every frame is answered, also far above the limit.
        for size, label in ((limit + 1, "just over the message limit"), ((64 << 20) + 4096, "over 64 MiB")):
            dealer.send(b" " * size)
            _, rep = dealer.recv(60)
            err = (rep or {}).get("error") or {}
            R.check(f"frame {label} ({size} bytes): too_large naming the limit {limit}",
                    rep is not None and err.get("code") == "too_large" and str(limit) in err.get("message", ""),
                    rep)
        R.check("after the oversized frames the daemon still answers", alive(d, dealer, 1))

        # Default load names: bodies sharing their first 40+ characters.
        scene = json.loads(open(dmod.scene_path("pair")).read())
        txt = json.dumps(scene)
        long_p, long_w = "g" * 45 + "-pinion", "g" * 45 + "-wheel"
        txt = txt.replace('"pinion"', json.dumps(long_p)).replace('"wheel"', json.dumps(long_w))
        scene = json.loads(txt)
        scene["loads"] = [{"body": long_p, "type": "constant", "moment": 1.0},
                          {"body": long_w, "type": "constant", "moment": -1.0}]
        rep, _ = dealer.request({"v": 1, "id": "load-long", "cmd": "load", "args": {"scene": scene}}, timeout=60)
        R.check("two constant loads on long-named bodies load (no duplicate default name)",
                rep and rep.get("ok") is True, rep)
        rep, _ = dealer.request({"v": 1, "id": "setl", "cmd": "set_load",
                                 "args": {"load": {"body": long_p, "type": "constant", "moment": 2.0}}})
        loads = (rep or {}).get("result", {}).get("loads", [])
        R.check("set_load on the long-named body replaces its own default-named load",
                rep and rep.get("ok") is True and len(loads) == 2 and len(set(loads)) == 2, rep)
        dealer.close()


R.guard("strict JSON run", run)
R.finish()
