# SPDX-License-Identifier: MIT
"""Load the protocol's JSON Schemas (proto/v1) and validate messages against them.

The schemas refer to each other by relative $ref; every file is registered in
one store under its $id so references resolve without network access."""
import glob
import json
import os

import jsonschema
from jsonschema import Draft202012Validator

BASE = "https://gearsim.invalid/proto/v1/"


def proto_dir():
    root = os.environ.get("GEARSIM_SOURCE_ROOT")
    if not root:
        root = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
    return os.path.join(root, "proto", "v1")


class Proto:
    """All schemas of proto/v1, addressed by their path relative to proto/v1."""

    def __init__(self, directory=None):
        self.dir = directory or proto_dir()
        self.schemas = {}
        for path in sorted(glob.glob(os.path.join(self.dir, "**", "*.json"), recursive=True)):
            rel = os.path.relpath(path, self.dir)
            with open(path) as f:
                self.schemas[rel] = json.load(f)
        self.store = {s["$id"]: s for s in self.schemas.values()}
        self._validators = {}

    def validator(self, rel):
        v = self._validators.get(rel)
        if v is None:
            schema = self.schemas[rel]
            resolver = jsonschema.RefResolver(base_uri=schema["$id"], referrer=schema, store=self.store)
            v = Draft202012Validator(schema, resolver=resolver)
            self._validators[rel] = v
        return v

    def errors(self, rel, instance):
        """List of readable validation errors (empty when valid)."""
        out = []
        for e in sorted(self.validator(rel).iter_errors(instance), key=lambda e: list(e.absolute_path)):
            where = "/".join(str(p) for p in e.absolute_path) or "(root)"
            out.append(f"{rel}: at {where}: {e.message[:300]}")
        return out

    def reply_errors(self, cmd, reply):
        """Errors of a reply to `cmd`: the envelope, then the command's result."""
        errs = self.errors("reply.json", reply)
        if not errs and isinstance(reply, dict) and reply.get("ok") is True:
            errs = self.errors(f"results/{cmd}.json", reply["result"])
        return errs

    def event_errors(self, event):
        return self.errors("event.json", event)

    def undocumented(self, rel, instance, prefix=""):
        """Top-level fields of instance that the schema does not name (informative: clients
        ignore unknown fields, but the docs should list what the daemon sends)."""
        props = self.schemas[rel].get("properties", {})
        if not isinstance(instance, dict):
            return []
        return [prefix + k for k in instance if k not in props]


def strict_loads(text):
    """json.loads that refuses NaN/Infinity (not JSON; Python accepts them by default)."""
    def bad(c):
        raise ValueError(f"non-JSON constant {c}")
    if isinstance(text, (bytes, bytearray)):
        text = text.decode("utf-8")
    return json.loads(text, parse_constant=bad)
