#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearctl and the Python client, without a daemon: `--wait` also waits for
the daemon before `sweep` (not with --offline); a download interrupted part
way (Ctrl-C, a failed chunk) leaves no partial file at the destination and
no temporary file beside it, while a whole one arrives with the usual mode;
`gearctl run --record` interrupted during the run removes the daemon's copy
and writes no local file. The elastic part of the static TE is named
te_elastic_um in the C API (gs_stiffness_point) and read under that name by
the bench scripts and the client; te_um, its former output name, is read
only as a fallback (older daemons)."""
import base64
import glob
import os
import re
import stat
import tempfile
import types
import unittest
from unittest import mock

from gearsim import cli
from gearsim.client import Client
from gearsim.errors import GearsimError


class FakeFetch:
    """Client.request for `fetch` over an in-memory file; raises `fail` at
    chunk number `fail_at` (0-based)."""

    def __init__(self, data, chunk, fail_at=None, fail=KeyboardInterrupt):
        self.data, self.chunk, self.fail_at, self.fail, self.calls = data, chunk, fail_at, fail, []

    def __call__(self, cmd, args=None, timeout=None):
        self.calls.append((cmd, dict(args or {})))
        if self.fail_at is not None and len(self.calls) - 1 == self.fail_at:
            raise self.fail()
        if args.get("remove"):
            return {"removed": True}
        off = args["offset"]
        part = self.data[off:off + self.chunk]
        return {"data_b64": base64.b64encode(part).decode(), "length": len(part), "size": len(self.data),
                "eof": off + len(part) >= len(self.data)}


def client_with(fake):
    c = Client.__new__(Client)   # no sockets: only fetch() is exercised
    c.request = fake
    return c


class Fetch(unittest.TestCase):
    def test_interrupted_leaves_nothing(self):
        for fail in (KeyboardInterrupt, lambda: GearsimError("io_error", "chunk lost")):
            with tempfile.TemporaryDirectory() as t:
                out = os.path.join(t, "run.h5")
                c = client_with(FakeFetch(b"x" * 1000, 100, fail_at=3, fail=fail))
                with self.assertRaises((KeyboardInterrupt, GearsimError)):
                    c.fetch("remote.h5", out, chunk=100)
                self.assertEqual(os.listdir(t), [], "a partial download was left")

    def test_whole_file_renamed_in_place(self):
        with tempfile.TemporaryDirectory() as t:
            out = os.path.join(t, "run.h5")
            with open(out, "wb") as f:
                f.write(b"old")
            c = client_with(FakeFetch(bytes(range(256)) * 5, 100))
            self.assertEqual(c.fetch("remote.h5", out, chunk=100), 1280)
            with open(out, "rb") as f:
                self.assertEqual(f.read(), bytes(range(256)) * 5)
            self.assertEqual(os.listdir(t), ["run.h5"])
            mask = os.umask(0)
            os.umask(mask)
            self.assertEqual(stat.S_IMODE(os.stat(out).st_mode), 0o666 & ~mask)


class WaitSweep(unittest.TestCase):
    def run_main(self, argv):
        calls = []
        with mock.patch.object(cli, "wait_for_daemon", lambda a: calls.append("wait")), \
                mock.patch.object(cli, "cmd_sweep", lambda a: calls.append("sweep") or 0):
            self.assertEqual(cli.main(argv), 0)
        return calls

    def test_wait_applies_to_sweep(self):
        argv = ["--wait", "5", "sweep", "builtin:pair", "--from", "500", "--to", "900", "--points", "3"]
        self.assertEqual(self.run_main(argv), ["wait", "sweep"])

    def test_not_offline(self):
        argv = ["--wait", "5", "sweep", "builtin:pair", "--from", "500", "--to", "900", "--offline"]
        self.assertEqual(self.run_main(argv), ["sweep"])


class RunRecordInterrupted(unittest.TestCase):
    def test_remote_copy_removed_no_local_file(self):
        log = []

        class FakeClient:
            gaps = 0

            def __enter__(self):
                return self

            def __exit__(self, *a):
                return False

            def status(self):
                return {"time": 0.0}

            def subscribe(self):
                pass

            def record(self, path=None, stop=False):
                log.append(("record", "stop" if stop else path))

            def advance(self, **kw):
                raise KeyboardInterrupt

            def cancel(self):
                log.append(("cancel",))

            def fetch(self, path, out_path=None, remove=False):
                log.append(("fetch", path, out_path, remove))
                if path.endswith(".xmf"):
                    raise GearsimError("not_found", "no such file")
                return b""

        with tempfile.TemporaryDirectory() as t:
            out = os.path.join(t, "run.h5")
            args = types.SimpleNamespace(telemetry=None, record=out, live=False, until=1.0, scene="builtin:pair")
            with mock.patch.object(cli, "client", lambda a: FakeClient()), \
                    mock.patch.object(cli, "load_scene", lambda c, s: {"name": "pair"}):
                self.assertEqual(cli.cmd_run(args), 130)
            self.assertEqual(os.listdir(t), [])
        remote = [e[1] for e in log if e[0] == "record" and e[1] != "stop"][0]
        self.assertIn(("record", "stop"), log)
        self.assertIn(("fetch", remote, None, True), log, log)


ROOT = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")


class TeElasticName(unittest.TestCase):
    def test_c_struct_field(self):
        with open(os.path.join(ROOT, "include", "gearsim", "stiffness.h")) as f:
            h = f.read()
        self.assertRegex(h, r"double\s+te_elastic_um\s*;")
        self.assertNotRegex(h, r"double\s+te_um\s*;")

    def test_readers_use_the_new_names(self):
        files = glob.glob(os.path.join(ROOT, "tests", "bench", "*.py")) + \
            glob.glob(os.path.join(ROOT, "clients", "python", "gearsim", "*.py"))
        alias = re.compile(r"""\[\s*['"]te_um['"]\s*\]""")
        readers, bad = [], []
        for f in files:
            with open(f) as fh:
                text = fh.read()
            # the scripts that read the stiffness analysis' output (other
            # te_um, e.g. a reference table's column, are not the alias)
            if re.search(r"te_raw_um|te0_um|te_loaded_um|te_elastic_um", text):
                readers.append(f)
                if alias.search(text):
                    bad.append(os.path.relpath(f, ROOT))
        self.assertTrue(len(readers) >= 4, readers)
        self.assertEqual(bad, [], "scripts index the deprecated alias te_um")


if __name__ == "__main__":
    unittest.main()
