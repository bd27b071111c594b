#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearctl as a package: gearsim.paths finds the data of a checkout, of a
meson install prefix and of neither; builtin:NAME becomes the scene file of
that layout; clients/README.md's gearctl synopsis names every option of the
argument parser; usage errors exit 2 (argparse's and gearctl's own);
`shutdown` prints a sentence, not `{}`; `python3 -m gearsim --help` and the
thin clients/python/gearctl (under 200 lines) run the same parser."""
import argparse
import contextlib
import io
import json
import os
import re
import subprocess
import sys
import tempfile
import unittest

from gearsim import cli, paths

ROOT = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
PY = os.path.join(ROOT, "clients", "python")


def touch(path, text="{}"):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)


class Layout(unittest.TestCase):
    def test_checkout(self):
        with tempfile.TemporaryDirectory() as t:
            pkg = os.path.join(t, "clients", "python", "gearsim")
            touch(os.path.join(pkg, "__init__.py"), "")
            touch(os.path.join(t, "deploy", "scenes", "pair.json"))
            d = paths.layout(pkg)
            self.assertEqual(d["scenes"], os.path.join(t, "deploy", "scenes"))
            self.assertEqual(d["table"], os.path.join(t, "docs", "data", "tradeoff.csv"))
            self.assertEqual(d["tools"], os.path.join(t, "build", "src", "tools"))
            self.assertEqual(paths.scene_file("builtin:pair", d), os.path.join(t, "deploy", "scenes", "pair.json"))
            self.assertEqual(paths.scene_file("x.json", d), "x.json")
            for bad in ("builtin:nope", "builtin:", "builtin:../scenes/pair"):
                with self.assertRaisesRegex(ValueError, "no scene file for"):
                    paths.scene_file(bad, d)

    def test_prefix(self):
        with tempfile.TemporaryDirectory() as P:
            pkg = os.path.join(P, "lib", "python3", "dist-packages", "gearsim")
            touch(os.path.join(pkg, "__init__.py"), "")
            touch(os.path.join(P, "share", "gearsim", "scenes", "lin_parker_3.json"))
            tool = os.path.join(P, "bin", "gearsim-fake-tool")
            touch(tool, "#!/bin/sh\n")
            os.chmod(tool, 0o755)
            d = paths.layout(pkg)
            self.assertEqual(d["scenes"], os.path.join(P, "share", "gearsim", "scenes"))
            self.assertEqual(d["table"], os.path.join(P, "share", "gearsim", "tradeoff.csv"))
            self.assertEqual(d["tools"], os.path.join(P, "bin"))
            self.assertEqual(paths.scene_file("builtin:lin_parker_3", d),
                             os.path.join(P, "share", "gearsim", "scenes", "lin_parker_3.json"))
            self.assertEqual(paths.find_tool("gearsim-fake-tool", d), tool)
            self.assertIsNone(paths.find_tool("gearsim-no-such-tool", d))

    def test_elsewhere(self):
        # a package in some site-packages: the data of another prefix given, else none
        with tempfile.TemporaryDirectory() as t:
            pkg = os.path.join(t, "venv", "lib", "python3.11", "site-packages", "gearsim")
            touch(os.path.join(pkg, "__init__.py"), "")
            other = os.path.join(t, "opt")
            touch(os.path.join(other, "share", "gearsim", "scenes", "pair.json"))
            self.assertEqual(paths.layout(pkg, [other])["scenes"], os.path.join(other, "share", "gearsim", "scenes"))
            # the installation whose gearsimd is on PATH
            pfx = os.path.join(t, "pfx")
            touch(os.path.join(pfx, "share", "gearsim", "scenes", "pair.json"))
            touch(os.path.join(pfx, "bin", "gearsimd"), "#!/bin/sh\n")
            os.chmod(os.path.join(pfx, "bin", "gearsimd"), 0o755)
            old = os.environ["PATH"]
            os.environ["PATH"] = os.path.join(pfx, "bin") + os.pathsep + old
            try:
                d = paths.layout(pkg)
            finally:
                os.environ["PATH"] = old
            self.assertEqual((d["scenes"], d["tools"]), (os.path.join(pfx, "share", "gearsim", "scenes"),
                                                         os.path.join(pfx, "bin")))


def parser_options():
    """{command: [[option strings of one argument], ...]} and the global options."""
    ap = cli.parser()
    glob, cmds = [], {}
    for act in ap._actions:
        if isinstance(act, argparse._SubParsersAction):
            for name, sp in act.choices.items():
                cmds[name] = [a.option_strings for a in sp._actions if a.option_strings and "--help" not in a.option_strings]
        elif act.option_strings and "--help" not in act.option_strings:
            glob.append(act.option_strings)
    return glob, cmds


class Synopsis(unittest.TestCase):
    def test_readme_synopsis(self):
        with open(os.path.join(ROOT, "clients", "README.md")) as f:
            text = f.read()
        sec = text[text.index("## gearctl"):]
        block = re.search(r"```text\n(.*?)```", sec, re.S).group(1)
        entries = {}   # command -> its synopsis text (continuation lines included)
        cur = None
        for line in block.splitlines():
            m = re.match(r"gearctl (\S+)", line)
            if m:
                cur = m.group(1)
                entries[cur] = entries.get(cur, "") + line + "\n"
            elif cur:
                entries[cur] += line + "\n"
        glob, cmds = parser_options()
        top = entries.get("[--connection-file", "")
        missing = [o[-1] for o in glob if not any(re.search(re.escape(s) + r"\b", top) for s in o)]
        self.assertEqual(missing, [], "global options missing from the synopsis")
        listed = set()
        for key, body in entries.items():
            listed.update(key.split("|"))
        self.assertEqual(sorted(set(cmds) - listed), [], "commands without a synopsis line")
        for name, opts in cmds.items():
            body = next((b for k, b in entries.items() if name in k.split("|")), "")
            missing = [o[-1] for o in opts if not any(re.search(re.escape(s) + r"(?![\w-])", body) for s in o)]
            self.assertEqual(missing, [], f"gearctl {name}: options missing from clients/README.md")


def run_main(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = cli.main(argv)
        except SystemExit as e:
            rc = e.code
    return rc, out.getvalue(), err.getvalue()


class ExitStatus(unittest.TestCase):
    def test_usage_errors_exit_2(self):
        for argv in (["nosuchcommand"], ["run", "builtin:pair"], ["sweep", "builtin:pair", "--offline"],
                     ["sweep", "builtin:pair", "--from", "100", "--offline"],
                     ["sweep", "builtin:pair", "--param", "nopath", "--offline"],
                     ["stiffness", "builtin:pair", "--relief", "5"],
                     ["stiffness", "builtin:pair", "--loads", "0,-1"],
                     ["advise", "pair", "--target", "speed"], ["advise", "pair"],
                     ["keys", "../x", "--dir", tempfile.gettempdir()]):
            rc, out, err = run_main(argv)
            self.assertEqual(rc, 2, f"{argv}: {err}")
            self.assertIn("error", err, argv)

    def test_failure_exits_1(self):
        rc, _, err = run_main(["--connection-file", "/nonexistent/gearsimd.json", "status"])
        self.assertEqual(rc, 1, err)
        rc, _, err = run_main(["modal", "builtin:no_such_scene"])
        self.assertEqual((rc, "no scene file for builtin:no_such_scene" in err), (1, True), err)

    def test_shutdown_line(self):
        class Fake:
            def __init__(self, *a, **k):
                pass

            def __enter__(self):
                return self

            def __exit__(self, *a):
                return False

            def shutdown(self):
                return {}

            def status(self):
                return {"state": "idle"}

        real = cli.Client
        cli.Client = Fake
        try:
            rc, out, _ = run_main(["shutdown"])
            self.assertEqual(rc, 0)
            self.assertNotEqual(out.strip(), "{}")
            self.assertIn("shutting down", out)
            rc, out, _ = run_main(["status"])
            self.assertEqual(json.loads(out), {"state": "idle"})
        finally:
            cli.Client = real


class ToolStatus(unittest.TestCase):
    """The C tools gearctl calls keep the same statuses: 2 bad usage, 1 an error."""
    def test_tools(self):
        tools = os.path.join(os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(ROOT, "build")), "src", "tools")
        names = ["gearsim-mesh", "gearsim-impact", "gearsim-stiffness", "gearsim-modal", "gearsim-sweep"]
        missing = [n for n in names if not os.access(os.path.join(tools, n), os.X_OK)]
        if missing:
            self.skipTest(f"not built: {missing}")
        with tempfile.TemporaryDirectory() as t:
            bad = os.path.join(t, "bad.json")
            touch(bad, '{"bodies": 3}')
            usage = {"gearsim-mesh": [bad, "--no-such-option"], "gearsim-impact": [],
                     "gearsim-stiffness": [bad, "--positions", "0"], "gearsim-modal": [bad, "--no-such-option"],
                     "gearsim-sweep": [bad, "--from", "100"]}
            error = {"gearsim-mesh": [bad, "-o", os.path.join(t, "m.h5")], "gearsim-impact": [bad],
                     "gearsim-stiffness": [bad], "gearsim-modal": [bad],
                     "gearsim-sweep": [bad, "--from", "100", "--to", "200", "--points", "2"]}
            for n in names:
                for argv, want in ((usage[n], 2), (error[n], 1)):
                    r = subprocess.run([os.path.join(tools, n)] + argv, capture_output=True, text=True, timeout=120)
                    self.assertEqual(r.returncode, want, f"{n} {argv}: {r.stderr}")
                    self.assertTrue(r.stderr.strip(), f"{n} {argv}: no message")


class EntryPoints(unittest.TestCase):
    def test_thin_gearctl(self):
        with open(os.path.join(PY, "gearctl")) as f:
            n = len(f.read().splitlines())
        self.assertLess(n, 200)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        a = subprocess.run(["/usr/bin/python3", os.path.join(PY, "gearctl"), "--help"], capture_output=True,
                           text=True, env=env, cwd=tempfile.gettempdir())
        b = subprocess.run(["/usr/bin/python3", "-m", "gearsim", "--help"], capture_output=True, text=True,
                           env=dict(env, PYTHONPATH=PY), cwd=tempfile.gettempdir())
        self.assertEqual((a.returncode, b.returncode), (0, 0), a.stderr + b.stderr)
        self.assertEqual(a.stdout, b.stdout)
        self.assertIn("advise", a.stdout)
        r = subprocess.run(["/usr/bin/python3", "-m", "gearsim", "sweep", "x.json"], capture_output=True,
                           text=True, env=dict(env, PYTHONPATH=PY), cwd=tempfile.gettempdir())
        self.assertEqual(r.returncode, 2, r.stderr)

    def test_pyproject_entry_point(self):
        with open(os.path.join(PY, "pyproject.toml")) as f:
            text = f.read()
        self.assertRegex(text, r'(?m)^\[project\.scripts\]\ngearctl = "gearsim\.cli:main"$')


if __name__ == "__main__":
    unittest.main()
