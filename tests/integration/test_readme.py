#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The README is executable: every ```sh and ```python snippet of README.md
and then clients/README.md (the "Quick start" section aside, and blocks
followed by a `<!-- readme-test: skip (reason) -->` comment) runs in order,
as a user would type them, in one bash session in a fresh copy of the tree
(its build/ a link to the build under test), with a fresh XDG_RUNTIME_DIR
and HOME and without the MPI/HDF5/Python variables of the test environment:
the docs must say what to set. A snippet fails when any command in it fails
(ERR trap, pipefail). A ```output block after a snippet is its sample
output, checked against what the snippet printed (stdout and stderr):
  * expected lines must match, in order, lines of the output; `...` alone
    on a line stands for any lines, `...` inside a line for any text; without
    a `...` line the output has exactly those lines;
  * numbers match to a relative 1e-6 (the runs are deterministic).
Other fences (```text, ```json ...) are not run.

Modes: no argument -- the engine's self-check on a small document with
known good and bad snippets, then the real documents (this must pass);
`--docs A.md B.md ...` -- those documents instead (the manual's tutorials,
one shell session for all, in order); with GEARSIM_DOC_PLOTS=DIR the PNG
files they leave in tutorial/ are copied to DIR;
`--broken` -- the real documents in a copy with one command and one sample
output deliberately broken: the test passes only if exactly those two
snippets are reported failing (the test can fail)."""
import math
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from daemon import BUILD_ROOT, SOURCE_ROOT  # noqa: E402
from harness import Results, scratch_dir  # noqa: E402

DOCS = ["README.md", os.path.join("clients", "README.md")]
SKIP_SECTIONS = {"Quick start"}
BLOCK_TIMEOUT = 300.0
# What the test environment sets and a user's shell does not have.
SCRUB = ("GEARSIM_", "OMPI_", "HDF5_", "PYTHONPATH", "OPENBLAS_", "OMP_", "CMOCKA_", "MESON_", "PKG_CONFIG_PATH")
NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


# ---------------------------------------------------------------- parsing
class Block:
    def __init__(self, doc, line, lang, text, section):
        self.doc, self.line, self.lang, self.text, self.section = doc, line, lang, text, section
        self.expected = None     # text of the ```output block after it
        self.skip = None         # reason

    @property
    def name(self):
        return f"{self.doc}:{self.line} ({self.lang}, {self.section})"


def parse(doc, text):
    """Runnable blocks of a Markdown text, with their sample outputs and skips."""
    blocks, section, last = [], "", None
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        ln = lines[i]
        if ln.startswith("## "):
            section = ln[3:].strip()
        m = re.match(r"^```\s*([A-Za-z0-9_-]*)\s*$", ln)
        if m:
            lang, start, body = m.group(1), i + 1, []
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                body.append(lines[i])
                i += 1
            content = "\n".join(body) + "\n"
            if lang in ("sh", "bash", "python"):
                last = Block(doc, start, "python" if lang == "python" else "sh", content, section)
                if section in SKIP_SECTIONS:
                    last.skip = f"section {section}"
                blocks.append(last)
            elif lang == "output":
                if last is None or last.expected is not None:
                    raise ValueError(f"{doc}:{start}: ```output without a snippet before it")
                last.expected = content
            else:
                last = None
        else:
            m = re.match(r"^<!--\s*readme-test:\s*skip\s*(.*?)\s*-->\s*$", ln)
            if m and blocks:
                blocks[-1].skip = m.group(1) or "skipped"
        i += 1
    return blocks


# ---------------------------------------------------------------- checking
def line_regex(expected):
    parts, nums = [], 0
    for tok in re.split(r"(\.\.\.|" + NUM + ")", expected.strip()):
        if tok == "...":
            parts.append(".*?")
        elif tok and re.fullmatch(NUM, tok):
            parts.append("(" + NUM + ")")
            nums += 1
        else:
            parts.append(re.escape(tok))
    return re.compile("".join(parts) + r"\Z"), [float(t) for t in re.findall(NUM, expected.replace("...", " "))]


def line_matches(expected, actual):
    rx, want = line_regex(expected)
    m = rx.match(actual.strip())
    if not m:
        return False
    for w, g in zip(want, m.groups()):
        if not math.isclose(float(g), w, rel_tol=1e-6, abs_tol=1e-12):
            return False
    return True


def compare_output(expected, actual):
    """None if actual matches the sample output, else the reason."""
    exp = [e for e in expected.splitlines() if e.strip()]
    act = [a for a in actual.splitlines() if a.strip()]
    gap = any(e.strip() == "..." for e in exp)
    if not gap and len(exp) != len(act):
        return f"{len(act)} lines printed, the sample shows {len(exp)}"
    j = 0
    free = False
    for e in exp:
        if e.strip() == "...":
            free = True
            continue
        while j < len(act) and not line_matches(e, act[j]):
            if not free:
                return f"line {act[j]!r} does not match the sample {e!r}"
            j += 1
        if j == len(act):
            return f"no printed line matches the sample {e!r}"
        j += 1
        free = False
    if j < len(act) and not free:
        return f"printed more than the sample: {act[j]!r}"
    return None


# ---------------------------------------------------------------- running
class Shell:
    """One bash session: each snippet is sourced into it (so `.`, export,
    cd and background jobs carry over, as for a user typing them)."""

    def __init__(self, cwd, env, work):
        self.work = work
        self.p = subprocess.Popen(["bash", "--norc", "--noprofile"], cwd=cwd, env=env, stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True,
                                  text=True, bufsize=1)
        self.n = 0
        self.send("set -o pipefail\n")

    def send(self, text):
        self.p.stdin.write(text)
        self.p.stdin.flush()

    def run(self, block):
        """(ok, output, why)."""
        self.n += 1
        base = os.path.join(self.work, f"snippet{self.n:02d}")
        out, errf = base + ".out", base + ".err"
        if block.lang == "python":
            with open(base + ".py", "w") as f:
                f.write(block.text)
            script = base + ".sh"
            with open(script, "w") as f:
                f.write(f"/usr/bin/python3 {base}.py\n")
        else:
            script = base + ".sh"
            with open(script, "w") as f:
                f.write(block.text)
        marker = f"@@done-{self.n}@@"
        self.send(f"trap 'echo \"failed ($?): $BASH_COMMAND\" >> {errf}' ERR\n"
                  f"source {script} > {out} 2>&1 < /dev/null\n"
                  f"trap - ERR\necho {marker}\n")
        deadline = time.monotonic() + BLOCK_TIMEOUT
        buf = ""
        while marker not in buf:
            left = deadline - time.monotonic()
            if left <= 0 or self.p.poll() is not None:
                return False, self._read(out), "timed out" if left <= 0 else "the shell exited"
            r, _, _ = select.select([self.p.stdout], [], [], min(left, 1.0))
            if r:
                line = self.p.stdout.readline()
                if not line:
                    continue
                buf += line
        output = self._read(out)
        errors = self._read(errf)
        if errors:
            return False, output, errors.strip()
        if block.expected is not None:
            why = compare_output(block.expected, output)
            if why:
                return False, output, "sample output: " + why
        return True, output, ""

    @staticmethod
    def _read(path):
        try:
            with open(path, errors="replace") as f:
                return f.read()
        except OSError:
            return ""

    def close(self, cleanup=""):
        if self.p.poll() is None:
            try:
                self.send(cleanup + "\nexit 0\n")
                self.p.wait(timeout=60)
            except (subprocess.TimeoutExpired, BrokenPipeError, OSError):
                pass
        try:
            os.killpg(self.p.pid, signal.SIGKILL)   # anything the snippets left behind
        except ProcessLookupError:
            pass
        self.p.wait()


def user_env(tmp):
    env = {k: v for k, v in os.environ.items() if not k.startswith(SCRUB)}
    env["HOME"] = os.path.join(tmp, "home")
    env["XDG_RUNTIME_DIR"] = os.path.join(tmp, "xdg")
    os.makedirs(env["HOME"], exist_ok=True)
    os.makedirs(env["XDG_RUNTIME_DIR"], mode=0o700, exist_ok=True)
    return env


def copy_tree(tmp):
    """The files of the checkout (tracked, and new ones not ignored) into
    tmp/tree, with build/ a link to the build under test."""
    tree = os.path.join(tmp, "tree")
    r = subprocess.run(["git", "-C", SOURCE_ROOT, "ls-files", "-co", "--exclude-standard", "-z"],
                       capture_output=True)
    if r.returncode == 0:
        files = r.stdout.decode().split("\0")
    else:   # not a git checkout (an unpacked tarball): every file but build trees and caches
        files = []
        for d, dirs, names in os.walk(SOURCE_ROOT):
            dirs[:] = [x for x in dirs if not x.startswith(("build", ".git", "__pycache__"))]
            files += [os.path.relpath(os.path.join(d, n), SOURCE_ROOT) for n in names]
    for rel in files:
        src = os.path.join(SOURCE_ROOT, rel)
        if not rel or not os.path.isfile(src):
            continue
        dst = os.path.join(tree, rel)
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        shutil.copy2(src, dst)
    os.symlink(os.path.abspath(BUILD_ROOT), os.path.join(tree, "build"))
    return tree


def run_docs(R, tree, tmp, docs, label=""):
    """Run every snippet of docs (paths relative to tree); returns the
    names of the snippets that failed."""
    work = os.path.join(tmp, "snippets" + label)
    os.makedirs(work)
    shell = Shell(tree, user_env(tmp), work)
    failed = []
    try:
        for doc in docs:
            with open(os.path.join(tree, doc)) as f:
                blocks = parse(doc, f.read())
            R.check(f"{label}{doc}: has runnable snippets", any(not b.skip for b in blocks))
            for b in blocks:
                if b.skip:
                    R.skip(label + b.name, b.skip)
                    continue
                ok, out, why = shell.run(b)
                if not ok:
                    failed.append(b.name)
                R.check(label + b.name + (" + sample output" if b.expected is not None else ""), ok,
                        f"{why}\n--- snippet ---\n{b.text}--- output ---\n{out[-3000:]}")
    finally:
        conn = os.path.join(tmp, "xdg", "gearsim", "gearsimd.json")
        shell.close(f"[ -f {conn} ] && /usr/bin/python3 {tree}/clients/python/gearctl shutdown >/dev/null 2>&1; "
                    "wait")
    return failed


# ---------------------------------------------------------------- self-check
SELF_DOC = '''# t
## Quick start
```sh
exit 3
```
## S
```sh
export GREETING=hello
echo "x=1.00000001 E=2e-3 $GREETING"
```
```output
x=1 E=0.002 hello
```
```sh
false
echo "after a failure"
```
```python
import sys
sys.exit(2)
```
```sh
echo "x=2"
printf 'a\\nb\\nc\\n'
```
```output
x=1
...
```
```sh
printf 'one\\ntwo 3.5 s\\nthree\\n'
```
```output
one
two ... s
...
```
```text
not run
```
```sh
echo skipped; false
```
<!-- readme-test: skip (because) -->
'''


def self_check(R, tmp):
    """The engine on a document with known good and bad snippets."""
    os.makedirs(os.path.join(tmp, "self"))
    with open(os.path.join(tmp, "self", "DOC.md"), "w") as f:
        f.write(SELF_DOC)
    R.note("self-check: three FAIL lines of self:DOC.md are expected below (lines 14, 18, 22)")
    sub = Results("self-check (inner)")
    failed = run_docs(sub, os.path.join(tmp, "self"), tmp, ["DOC.md"], label="self:")
    lines = [int(n.split(":")[1].split()[0]) for n in failed]
    R.check("self-check: a failing command, a failing Python snippet and a wrong sample output are caught",
            lines == [14, 18, 22], f"failed: {failed}")
    R.check("self-check: good snippets and samples pass (numbers to 1e-6, `...`)",
            sub.passed == 3, f"{sub.passed} inner passes")
    R.check("self-check: output comparison unit cases",
            compare_output("t=0.5 E=1e-3\n", "t=0.5000000001 E=0.001\n") is None
            and compare_output("t=0.5\n", "t=0.6\n") is not None
            and compare_output("a\n", "a\nb\n") is not None
            and compare_output("...\nb\n", "a\nb\n") is None)


# ---------------------------------------------------------------- breaking
def replace_once(path, old, new):
    """Replace the first `old` in the file by `new`; returns the new text."""
    with open(path) as f:
        text = f.read()
    assert old in text, (path, old)
    text = text.replace(old, new, 1)
    with open(path, "w") as f:
        f.write(text)
    return text


def break_copy(tree):
    """One command and one sample output broken in the copy; returns the
    two (doc, line) that must fail."""
    text = replace_once(os.path.join(tree, "README.md"), "gearctl plot run.h5 -o run.png",
                        "gearctl plot no-such-record.h5 -o run.png")
    want = [("README.md", next(b.line for b in parse("README.md", text) if "no-such-record" in b.text))]
    doc = os.path.join("clients", "README.md")
    text = replace_once(os.path.join(tree, doc), "pinion=6.721805421", "pinion=6.731805421")
    want.append((doc, next(b.line for b in parse(doc, text) if b.expected and "6.731805421" in b.expected)))
    return want


def toctree_docs(d):
    """The pages of directory d (relative to the source) in the order of the
    toctree of its index.md."""
    with open(os.path.join(SOURCE_ROOT, d, "index.md")) as f:
        m = re.search(r"```\{toctree\}\n(.*?)```", f.read(), re.S)
    names = [ln.strip() for ln in (m.group(1) if m else "").splitlines()
             if ln.strip() and not ln.strip().startswith(":")]
    return [os.path.join(d, n + ".md") for n in names]


def run_tutorials(docs):
    docs = [p for d in docs for p in (toctree_docs(d) if os.path.isdir(os.path.join(SOURCE_ROOT, d)) else [d])]
    R = Results("tutorials run as typed: " + " ".join(docs))
    R.check("documents to run", len(docs) > 0, docs)
    with scratch_dir("gearsim-tutorials-") as tmp:
        tree = copy_tree(tmp)
        missing = [d for d in docs if not os.path.isfile(os.path.join(tree, d))]
        R.check("the documents exist", not missing, missing)
        run_docs(R, tree, tmp, [d for d in docs if d not in missing])
        out = os.environ.get("GEARSIM_DOC_PLOTS")
        if out:
            os.makedirs(out, exist_ok=True)
            plots = os.path.join(tree, "tutorial")
            for n in sorted(os.listdir(plots)) if os.path.isdir(plots) else []:
                if n.endswith(".png"):
                    shutil.copy(os.path.join(plots, n), os.path.join(out, n))
    R.finish()


def main():
    if "--docs" in sys.argv[1:]:
        return run_tutorials(sys.argv[sys.argv.index("--docs") + 1:])
    broken = "--broken" in sys.argv[1:]
    R = Results("README snippets run as typed" + (" (deliberately broken copy)" if broken else ""))
    with scratch_dir("gearsim-readme-") as tmp:
        if broken:
            tree = copy_tree(tmp)
            want = break_copy(tree)
            R.note("two FAIL lines are expected below: the broken plot command and the broken C sample")
            inner = Results("the broken copy (failures expected)")
            failed = run_docs(inner, tree, tmp, DOCS)
            got = [(n.split(":")[0], int(n.split(":")[1].split()[0])) for n in failed]
            R.check("broken copy: exactly the broken command and the broken sample fail", got == want,
                    f"failed {got}, expected {want}")
        else:
            R.guard("self-check", self_check, R, tmp)
            tree = copy_tree(tmp)
            run_docs(R, tree, tmp, DOCS)
    R.finish()


if __name__ == "__main__":
    main()
