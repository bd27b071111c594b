#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Every README line, typed verbatim on a minimal Debian root.

Long mode only: runs with GEARSIM_LONG=1, as root, with debootstrap
installed (`deploy/install-deps.sh --minimal-root`); otherwise it skips
(exit status 77) saying which of the three is missing. It takes some 20 to
40 minutes: a Debian install, about 350 packages and a full build.

  1. `debootstrap --variant=minbase bookworm ROOT MIRROR`, MIRROR the Debian
     mirror apt already uses on this machine (/etc/apt/sources.list or
     sources.list.d), or GEARSIM_DEBIAN_MIRROR;
  2. a fresh `git clone` of the source tree into ROOT/root/gearsim; /proc,
     /sys, /dev/pts and a tmpfs on /dev/shm mounted in ROOT, always
     unmounted at the end (also on failure or interruption);
  3. in `chroot ROOT`, as root, with a bare login environment: the quick
     start, `deploy/demo.sh` exactly as the README has it, then every
     runnable snippet of README.md and clients/README.md in order, by
     tests/integration/test_readme.py of the clone (the same engine as the
     default suite's `readme` test, here on the clone's own build);
  4. a line per README snippet: passed, failed or skipped (and why).
GEARSIM_MINROOT_SUITE=1 also runs the quick start's `deploy/test.sh`.
  5. the snippets the readme test skips (marked `readme-test: skip`, e.g.
     the install to a prefix and pip in a virtual environment), each typed
     verbatim in its own shell in the root (`bash -e -o pipefail`).
GEARSIM_MINROOT_KEEP=1 leaves ROOT (unmounted) for inspection;
GEARSIM_MINROOT_REUSE=DIR reuses such a kept DIR (no debootstrap, no clone if
DIR/root has one: for working on the test itself)."""
import glob
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
SOURCE_ROOT = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.abspath(os.path.join(HERE, "..", ".."))

SKIP = 77
SUITE = "bookworm"
CLONE = "/root/gearsim"          # inside the root
# A login shell's environment on a fresh machine: nothing of the test's.
BARE_ENV = {"HOME": "/root", "USER": "root", "LOGNAME": "root", "SHELL": "/bin/bash", "TERM": "dumb",
            "LANG": "C.UTF-8", "PATH": "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"}


def why_skip():
    if os.environ.get("GEARSIM_LONG") != "1":
        return "a long test (a Debian install and a full build): GEARSIM_LONG=1 runs it"
    if os.geteuid() != 0:
        return "needs root (debootstrap, chroot, mounts)"
    if not shutil.which("debootstrap", path=os.environ.get("PATH", "") + ":/usr/sbin:/sbin"):
        return "needs debootstrap (deploy/install-deps.sh --minimal-root installs it)"
    return None


def debian_mirror():
    """The Debian mirror apt uses here (the first source serving SUITE)."""
    if os.environ.get("GEARSIM_DEBIAN_MIRROR"):
        return os.environ["GEARSIM_DEBIAN_MIRROR"]
    files = ["/etc/apt/sources.list"] + sorted(glob.glob("/etc/apt/sources.list.d/*"))
    for path in files:
        try:
            with open(path) as f:
                text = f.read()
        except OSError:
            continue
        # one-line format: deb [options] URI suite components
        for ln in text.splitlines():
            m = re.match(r"^\s*deb\s+(?:\[[^]]*\]\s+)?(\S+)\s+(\S+)", ln)
            if m and m.group(2) == SUITE:
                return m.group(1)
        # deb822 format: stanzas with URIs: and Suites:
        for stanza in re.split(r"\n\s*\n", text):
            fields = dict((k.strip().lower(), v.strip()) for k, v in
                          (ln.split(":", 1) for ln in stanza.splitlines()
                           if ":" in ln and not ln.lstrip().startswith("#")))
            if "deb" in fields.get("types", "").split() and SUITE in fields.get("suites", "").split():
                return fields.get("uris", "").split()[0]
    return "http://deb.debian.org/debian"


class Mounts:
    """Mounts in the root, unmounted in reverse order whatever happens."""

    def __init__(self, root):
        self.root, self.done = root, []

    def mount(self, fstype, target, *opts):
        path = os.path.join(self.root, target.lstrip("/"))
        os.makedirs(path, exist_ok=True)
        subprocess.run(["mount", "-t", fstype, *opts, fstype, path], check=True)
        self.done.append(path)

    def release(self):
        # anything still running in the root first (a daemon a snippet left)
        for pid in os.listdir("/proc"):
            if pid.isdigit():
                try:
                    if os.readlink(f"/proc/{pid}/root").startswith(self.root.rstrip("/") + "/") or \
                            os.readlink(f"/proc/{pid}/root") == self.root.rstrip("/"):
                        os.kill(int(pid), signal.SIGKILL)
                except OSError:
                    pass
        time.sleep(1)
        left = []
        for path in reversed(self.done):
            if subprocess.run(["umount", path]).returncode != 0 and \
                    subprocess.run(["umount", "-l", path]).returncode != 0:
                left.append(path)
        self.done = []
        return left


def timed(cmd, log, **kw):
    """Run cmd, its output appended to log and echoed; (status, seconds)."""
    t0 = time.monotonic()
    with open(log, "a") as f:
        f.write("$ " + " ".join(cmd) + "\n")
        f.flush()
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
        for ln in p.stdout:
            f.write(ln)
            f.flush()
            print("  | " + ln.rstrip(), flush=True)
        p.wait()
    return p.returncode, time.monotonic() - t0


def in_root(root, script):
    return ["chroot", root, "/bin/bash", "-c", script]


def run_skipped(R, root, log, env):
    """The snippets the readme test skips (the quick start aside: it ran
    above), each verbatim in its own shell in the root, in document order."""
    from test_readme import DOCS, SKIP_SECTIONS, parse
    n = 0
    for doc in DOCS:
        with open(os.path.join(root + CLONE, doc)) as f:
            blocks = parse(doc, f.read())
        for b in blocks:
            if not b.skip or b.section in SKIP_SECTIONS:
                continue
            n += 1
            script = f"/tmp/skipped{n:02d}.{'py' if b.lang == 'python' else 'sh'}"
            with open(root + script, "w") as f:
                f.write(b.text)
            run = f"/usr/bin/python3 {script}" if b.lang == "python" else f"bash -e -o pipefail {script}"
            rc, dt = timed(in_root(root, f"cd {CLONE} && {run}"), log, env=env)
            R.check(f"{b.name}, skipped by the readme test, typed in the root ({dt:.0f} s)", rc == 0,
                    f"exit {rc}; see {log}\n--- snippet ---\n{b.text}")


def main():
    reason = why_skip()
    if reason:
        print(f"SKIP: {reason}")
        sys.exit(SKIP)
    from harness import Results
    R = Results("every README line verbatim on a minimal Debian root")
    t_all = time.monotonic()
    reuse = os.environ.get("GEARSIM_MINROOT_REUSE")
    tmp = reuse or tempfile.mkdtemp(prefix="gearsim-minroot-", dir=os.environ.get("GEARSIM_MINROOT_TMP", "/var/tmp"))
    root = os.path.join(tmp, "root")
    log = os.path.join(tmp, "minroot.log")
    R.note(f"root {root}, full log {log}")
    mounts = Mounts(root)
    try:
        mirror = debian_mirror()
        if reuse and os.path.isfile(os.path.join(root, "etc", "debian_version")):
            R.note(f"reusing the root {root}")
        else:
            rc, dt = timed(["debootstrap", "--variant=minbase", SUITE, root, mirror], log)
            if not R.check(f"debootstrap --variant=minbase {SUITE} ROOT {mirror} ({dt:.0f} s)", rc == 0,
                           f"see {log}"):
                return R
        if not (reuse and os.path.isdir(root + CLONE)):
            rc, dt = timed(["git", "clone", "-q", SOURCE_ROOT, root + CLONE], log)
            if not R.check("git clone of the source tree into ROOT" + CLONE, rc == 0, f"see {log}"):
                return R
        shutil.copy2("/etc/resolv.conf", os.path.join(root, "etc", "resolv.conf"))
        mounts.mount("proc", "/proc")
        mounts.mount("sysfs", "/sys")
        mounts.mount("devpts", "/dev/pts", "-o", "newinstance,ptmxmode=0666")
        mounts.mount("tmpfs", "/dev/shm", "-o", "mode=1777")
        env = dict(BARE_ENV)
        rc, dt = timed(in_root(root, f"cd {CLONE} && deploy/demo.sh"), log, env=env)
        R.check(f"quick start: deploy/demo.sh ({dt / 60:.1f} min)", rc == 0, f"exit {rc}; see {log}")
        made = [p for p in ("out/demo.h5", "out/demo.png") if os.path.isfile(os.path.join(root + CLONE, p))]
        R.check("quick start: out/demo.h5 and out/demo.png written", len(made) == 2, made)
        if rc != 0:
            return R
        if os.environ.get("GEARSIM_MINROOT_SUITE") == "1":
            rc, dt = timed(in_root(root, f"cd {CLONE} && deploy/test.sh"), log, env=env)
            R.check(f"quick start: deploy/test.sh ({dt / 60:.1f} min)", rc == 0, f"exit {rc}; see {log}")
        else:
            R.skip("quick start: deploy/test.sh", "GEARSIM_MINROOT_SUITE=1 runs it")
        # The snippets, by the clone's own engine, in the root.
        out = os.path.join(tmp, "readme.out")
        start = os.path.getsize(log)
        rc, dt = timed(in_root(root, f"cd {CLONE} && /usr/bin/python3 tests/integration/test_readme.py"),
                       log, env=env)
        with open(log) as f:
            f.seek(start)
            text = f.read()
        with open(out, "w") as f:
            f.write(text)
        R.note(f"README snippets ({dt / 60:.1f} min):")
        seen = 0
        for ln in text.splitlines():
            m = re.match(r"^\s*\|?\s*(ok|FAIL|skip) - ((?:README\.md|clients/README\.md):\d+ .*?)(?::\s(.*))?$", ln)
            if not m:
                continue
            seen += 1
            kind, name, why = m.group(1), m.group(2), (m.group(3) or "")
            if kind == "skip":
                R.skip(name, why)
            else:
                R.check(name, kind == "ok", why)
        R.check("README snippets found and run", seen > 0, f"see {out}")
        R.check("test_readme.py in the root passed as a whole", rc == 0, f"exit {rc}; see {out}")
        run_skipped(R, root, log, env)
    finally:
        left = mounts.release()
        R.check("every mount in the root released", not left, left)
        if not left and not reuse and os.environ.get("GEARSIM_MINROOT_KEEP") != "1":
            shutil.rmtree(tmp, ignore_errors=True)   # only once nothing is mounted under it
        else:
            R.note(f"left for inspection: {tmp}")
        R.note(f"total {(time.monotonic() - t_all) / 60:.1f} min")
    return R


if __name__ == "__main__":
    main().finish()
