#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""`meson install` gives a complete, usable gearsim under a prefix.

Default mode: `meson install --destdir D` of the build under test (no
rebuild), P = D + prefix. GEARSIM_LONG=1: a fresh `git clone` of the source
tree, `meson setup b --prefix=P && meson install -C b` (a full build).

Then, from an empty working directory, with only P/bin before /usr/bin:/bin
on PATH, no checkout variables and no PYTHONPATH (except the documented
P/lib/python3/dist-packages for the Python session):
  * the layout: daemon, tools, gearctl (shebang /usr/bin/python3), the Python
    package, headers, libraries, pkg-config files, schemas, scenes, the
    trade-off table, systemd unit and Slurm script (pointing at P/bin),
    env.sh, man pages;
  * the installed env.sh, systemd unit and Slurm script name the installed
    loopback shim (P/<libdir>/gearsim/gearsim-loopback.so), which exists;
  * gearsimd --help, gearctl --help and `python3 -m gearsim --help`; the
    man pages format, and `man gearsimd` finds the installed page (man-db
    derives the manual path from P/bin on PATH);
  * gearctl modal builtin:lin_parker_3, gearctl stiffness
    builtin:stiffness_pair, gearctl sweep --offline builtin:planetary_sweep
    (the installed scenes and tools, no daemon);
  * gearsimd under `mpirun` typed after sourcing the installed env.sh (its
    mpirun preloads the shim), found through the default connection file;
    `ss -ltnp`: every listening socket of its process tree on loopback;
    hello lists every installed scene as builtin, including one added to
    share/gearsim/scenes, which loads by name;
  * gearctl run (telemetry and record downloaded, no copy left in the data
    directory), gearctl plot, gearctl advise (the installed table), gearctl
    mesh (the installed gearsim-mesh);
  * a C program built with `pkg-config gearsim-client` against the installed
    header and library, run against the daemon; one built with
    `pkg-config gearsim` calling libgearsim;
  * a Python session importing gearsim from P;
  * pip, the Debian way (Debian's Python refuses pip outside a virtual
    environment): `python3 -m venv --system-site-packages V`, then
    `V/bin/pip install --no-deps --no-build-isolation` of clients/python (a
    copy): the package imports, V/bin/gearctl (the entry point) talks to the
    daemon and finds the installed scenes."""
import glob
import ipaddress
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from daemon import BUILD_ROOT, MPI_ENV, SOURCE_ROOT  # noqa: E402
from harness import Results, scratch_dir  # noqa: E402

LONG = os.environ.get("GEARSIM_LONG") == "1"
CHECKOUT_VARS = ("GEARSIM_SOURCE_ROOT", "GEARSIM_BUILD_ROOT", "PYTHONPATH", "PKG_CONFIG_PATH", "LD_PRELOAD", "MANPATH",
                 "GEARSIM_LOOPBACK_PRELOAD")
PREFIX = []   # the configured prefix (P itself, or P without the --destdir part)


def run(cmd, env, cwd, timeout=300, **kw):
    return subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout, **kw)


def install(R, tmp):
    """Install; returns (P, libdir relative to P)."""
    if LONG:
        src = os.path.join(tmp, "clone")
        r = subprocess.run(["git", "clone", "-q", SOURCE_ROOT, src], capture_output=True, text=True)
        if not R.check("git clone of the source tree", r.returncode == 0, r.stderr):
            return None, None
        P = os.path.join(tmp, "prefix")
        env = dict(os.environ, **MPI_ENV)
        r = subprocess.run(["meson", "setup", "b", f"--prefix={P}"], cwd=src, env=env, capture_output=True, text=True)
        if not R.check("meson setup b --prefix=P", r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]):
            return None, None
        r = subprocess.run(["nice", "meson", "install", "-C", "b"], cwd=src, env=env, capture_output=True, text=True)
        R.check("meson install -C b (fresh clone)", r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:])
        intro = os.path.join(src, "b")
    else:
        D = os.path.join(tmp, "destdir")
        r = subprocess.run(["meson", "install", "-C", BUILD_ROOT, "--no-rebuild", "--destdir", D],
                           capture_output=True, text=True)
        R.check("meson install --destdir", r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:])
        intro = BUILD_ROOT
    opts = json.loads(subprocess.run(["meson", "introspect", "--buildoptions", intro], capture_output=True,
                                     text=True).stdout)
    o = {x["name"]: x["value"] for x in opts}
    P = o["prefix"] if LONG else os.path.join(tmp, "destdir", o["prefix"].lstrip("/"))
    PREFIX[:] = [o["prefix"]]
    return P, o["libdir"]


def check_layout(R, P, libdir):
    want = ["bin/gearsimd", "bin/gearctl", "bin/gearsim-mesh", "bin/gearsim-impact", "bin/gearsim-stiffness",
            "bin/gearsim-client-c", "lib/python3/dist-packages/gearsim/__init__.py",
            "lib/python3/dist-packages/gearsim/client.py", "include/gearsim/engine.h", "include/gearsim/types.h",
            "include/gearsim_client.h", f"{libdir}/libgearsim.a", f"{libdir}/libgearsim_client.a",
            f"{libdir}/pkgconfig/gearsim.pc", f"{libdir}/pkgconfig/gearsim-client.pc",
            "share/gearsim/proto/v1/request.json", "share/gearsim/proto/v1/README.md",
            "share/gearsim/scenes/pair.json", "share/gearsim/tradeoff.csv",
            "share/gearsim/deploy/env.sh", "share/gearsim/deploy/gearsimd.conf",
            "share/gearsim/deploy/gearsimd.slurm", "lib/systemd/system/gearsimd.service",
            "share/man/man1/gearsimd.1", "share/man/man1/gearctl.1"]
    missing = [w for w in want if not os.path.exists(os.path.join(P, w))]
    R.check("installed layout complete", not missing, f"missing: {missing}")
    src_scenes = sorted(os.path.basename(p) for p in glob.glob(os.path.join(SOURCE_ROOT, "deploy", "scenes", "*.json")))
    inst_scenes = sorted(os.path.basename(p) for p in glob.glob(os.path.join(P, "share", "gearsim", "scenes", "*.json")))
    R.check("every example scene installed", src_scenes == inst_scenes, f"{src_scenes} vs {inst_scenes}")
    for exe in ("gearctl",):
        with open(os.path.join(P, "bin", exe)) as f:
            first = f.readline().strip()
        R.check(f"{exe}: shebang /usr/bin/python3", first == "#!/usr/bin/python3", first)
        R.check(f"{exe}: executable", os.access(os.path.join(P, "bin", exe), os.X_OK))
    with open(os.path.join(P, "lib/systemd/system/gearsimd.service")) as f:
        unit = f.read()
    R.check("systemd unit starts the installed gearsimd", f" {os.path.join(P, 'bin', 'gearsimd')} " in unit
            if LONG else "/bin/gearsimd " in unit, [ln for ln in unit.splitlines() if "ExecStart" in ln])
    with open(os.path.join(P, "share/gearsim/deploy/gearsimd.slurm")) as f:
        slurm = f.read()
    R.check("Slurm script defaults to the installed gearsimd", "/bin/gearsimd}" in slurm and "build/src" not in slurm)
    # The shim's installed path as the files name it (the final prefix, also
    # under --destdir), and the file under P.
    shim = os.path.join(P, libdir, "gearsim", "gearsim-loopback.so")
    R.check("the loopback shim is installed", os.path.isfile(shim), shim)
    named = os.path.join(PREFIX[0], libdir, "gearsim", "gearsim-loopback.so")
    with open(os.path.join(P, "share/gearsim/deploy/env.sh")) as f:
        env_sh = f.read()
    for name, text, pat in (("env.sh", env_sh, r"GEARSIM_LOOPBACK_PRELOAD:-([^}]*)\}"),
                            ("systemd unit", unit, r"^Environment=LD_PRELOAD=(\S+)$"),
                            ("Slurm script", slurm, r"GEARSIM_LOOPBACK_PRELOAD:-([^}]*)\}")):
        m = re.search(pat, text, re.M)
        R.check(f"installed {name} points the shim at the installed one", m is not None and m.group(1) == named,
                (m.group(1) if m else None, named))


def user_env(P, tmp):
    env = {k: v for k, v in os.environ.items() if k not in CHECKOUT_VARS}
    env["PATH"] = os.path.join(P, "bin") + ":/usr/bin:/bin"
    env["XDG_RUNTIME_DIR"] = os.path.join(tmp, "xdg")
    env["HOME"] = tmp
    os.makedirs(env["XDG_RUNTIME_DIR"], mode=0o700, exist_ok=True)
    return env


C_CLIENT = r"""
#include <stdio.h>
#include <gearsim_client.h>
int main(void)
{
    gsc_client *c;
    gsc_error err;
    json_object *res;
    if (gsc_client_new(NULL, &c, &err) != 0) {
        fprintf(stderr, "connect: %s\n", err.message);
        return 1;
    }
    if (gsc_request(c, "hello", NULL, 10000, 2, &res, &err) != 0) {
        fprintf(stderr, "hello: %s\n", err.message);
        gsc_client_free(&c);
        return 1;
    }
    json_object *p;
    json_object_object_get_ex(res, "protocol", &p);
    printf("protocol %d\n", json_object_get_int(p));
    json_object_put(res);
    gsc_client_free(&c);
    return 0;
}
"""

C_LIB = r"""
#include <stdio.h>
#include <gearsim/scene.h>
int main(void)
{
    int n = 0;
    for (const char *const *s = gs_scene_builtin_names(); *s; s++)
        n++;
    printf("builtins %d pair %s\n", n, gs_scene_builtin("pair") ? "yes" : "no");
    return 0;
}
"""


def build_c(R, P, libdir, env, work, name, source, pc):
    src = os.path.join(work, name + ".c")
    with open(src, "w") as f:
        f.write(source)
    e = dict(env, PKG_CONFIG_PATH=os.path.join(P, libdir, "pkgconfig"))
    flags = run(["pkg-config", "--cflags", "--libs", pc], e, work)
    if not R.check(f"pkg-config {pc} resolves", flags.returncode == 0, flags.stderr):
        return None
    R.check(f"pkg-config {pc} points into the prefix", os.path.realpath(P) in
            " ".join(os.path.realpath(a[2:]) for a in flags.stdout.split() if a.startswith(("-I", "-L"))),
            flags.stdout)
    exe = os.path.join(work, name)
    r = run(["cc", "-std=c11", "-Wall", "-Werror", src, "-o", exe] + flags.stdout.split(), e, work)
    R.check(f"{name}.c builds against the installed {pc}", r.returncode == 0, r.stderr[-3000:])
    return exe if r.returncode == 0 else None


def with_daemon(R, P, libdir, tmp):
    env = user_env(P, tmp)
    work = os.path.join(tmp, "work")
    os.makedirs(work)
    r = run(["gearsimd", "--help"], env, work, timeout=60)
    R.check("gearsimd --help", r.returncode == 0 and "--data-dir" in r.stdout, r.stdout + r.stderr)
    r = run(["gearctl", "--help"], env, work, timeout=60)
    R.check("gearctl --help", r.returncode == 0 and "run" in r.stdout, r.stdout + r.stderr)
    pyenv = dict(env, PYTHONPATH=os.path.join(P, "lib", "python3", "dist-packages"))
    m = run(["/usr/bin/python3", "-m", "gearsim", "--help"], pyenv, work, timeout=60)
    R.check("python3 -m gearsim --help (the installed package) = gearctl --help", m.returncode == 0 and
            m.stdout == r.stdout and "advise" in m.stdout, m.stdout[-500:] + m.stderr[-1000:])
    for page in ("gearsimd", "gearctl"):
        r = run(["man", "-l", "-P", "cat", os.path.join(P, "share", "man", "man1", page + ".1")],
                dict(env, MANWIDTH="80"), work, timeout=60)
        R.check(f"man page {page}(1) formats", r.returncode == 0 and "SYNOPSIS" in r.stdout, r.stderr[-500:])
        r = run(["man", "-w", page], env, work, timeout=60)
        R.check(f"man {page}: the installed page, found through P/bin on PATH",
                r.returncode == 0 and r.stdout.strip() == os.path.join(P, "share", "man", "man1", page + ".1"),
                r.stdout + r.stderr)
    r = run(["man", "-P", "cat", "gearsimd"], dict(env, MANWIDTH="80"), work, timeout=60)
    R.check("man gearsimd", r.returncode == 0 and "--data-dir" in r.stdout.replace("\u2010", "-"), r.stderr[-500:])
    offline(R, env, work)
    # A scene added to the installation is a builtin too. With --destdir the
    # daemon's compiled-in scenes directory is the final prefix's, so point
    # it at P (GEARSIM_SCENE_DIR); the fresh-clone mode uses the default.
    scenes = os.path.join(P, "share", "gearsim", "scenes")
    with open(os.path.join(scenes, "pair.json")) as f:
        mine = json.load(f)
    mine["name"] = "my own pair"
    with open(os.path.join(scenes, "my_pair.json"), "w") as f:
        json.dump(mine, f)
    if not LONG:
        env["GEARSIM_SCENE_DIR"] = scenes
    # The documented start: source the installed env.sh, then `mpirun`
    # (env.sh's mpirun preloads the shim it names). With --destdir the name
    # is the final prefix's, so point it at P the same way.
    if not LONG:
        env["GEARSIM_LOOPBACK_PRELOAD"] = os.path.join(P, libdir, "gearsim", "gearsim-loopback.so")
    env_sh = os.path.join(P, "share", "gearsim", "deploy", "env.sh")
    daemon = subprocess.Popen(["bash", "-c", f'. "{env_sh}" && mpirun -n 2 gearsimd --data-dir data'],
                              env=env, cwd=work, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              stdin=subprocess.DEVNULL, start_new_session=True)
    conn = os.path.join(env["XDG_RUNTIME_DIR"], "gearsim", "gearsimd.json")
    deadline = time.monotonic() + 90
    while not os.path.exists(conn) and daemon.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    try:
        if not R.check("installed gearsimd starts, default connection file", os.path.exists(conn)):
            return
        listeners(R, daemon.pid)
        r = run(["gearctl", "hello"], env, work, timeout=60)
        hello = json.loads(r.stdout) if r.returncode == 0 else {}
        inst = sorted(os.path.splitext(os.path.basename(p))[0]
                      for p in glob.glob(os.path.join(P, "share", "gearsim", "scenes", "*.json")))
        R.check("gearctl hello: every installed scene is a builtin", sorted(hello.get("builtin_scenes", [])) == inst,
                f"{hello.get('builtin_scenes')} vs {inst}; {r.stderr}")
        R.check("a scene added to share/gearsim/scenes is listed as builtin", "my_pair" in hello.get("builtin_scenes", []))
        r = run(["gearctl", "run", "builtin:my_pair", "--until", "0.002"], env, work)
        R.check("gearctl run builtin:my_pair (the added scene)", r.returncode == 0 and "done:" in r.stdout,
                r.stdout[-1000:] + r.stderr[-1000:])
        r = run(["gearctl", "run", "builtin:pair", "--until", "0.02", "--telemetry", "out.jsonl",
                 "--record", "run.h5"], env, work)
        ok = r.returncode == 0 and os.path.isfile(os.path.join(work, "run.h5"))
        R.check("gearctl run builtin:pair --record run.h5", ok, r.stdout[-2000:] + r.stderr[-2000:])
        left = [n for n in os.listdir(os.path.join(work, "data")) if n.startswith("gearctl-")]
        R.check("gearctl run --record: no copy left in the data directory", not left, left)
        lines = open(os.path.join(work, "out.jsonl")).read().splitlines() if ok else []
        R.check("gearctl run: telemetry lines", len(lines) > 0 and json.loads(lines[-1]).get("time", 0) > 0.019,
                lines[-1:] if lines else r.stderr)
        scene = os.path.join(P, "share", "gearsim", "scenes", "rattle.json")
        r = run(["gearctl", "run", scene, "--until", "0.005"], env, work)
        R.check("gearctl run on an installed scene file", r.returncode == 0, r.stderr[-2000:])
        r = run(["gearctl", "plot", "run.h5", "-o", "run.png"], env, work)
        png = os.path.join(work, "run.png")
        R.check("gearctl plot run.h5 -o run.png", r.returncode == 0 and os.path.isfile(png)
                and open(png, "rb").read(8) == b"\x89PNG\r\n\x1a\n", r.stderr[-2000:])
        r = run(["gearctl", "advise", "pair", "--target", "speed=1e-2", "--json"], env, work)
        R.check("gearctl advise with the installed table", r.returncode == 0 and "choice" in r.stdout,
                r.stdout[-1000:] + r.stderr[-1000:])
        r = run(["gearctl", "mesh", "builtin:elastic_spin", "-o", "mesh.png"], env, work)
        R.check("gearctl mesh runs the installed gearsim-mesh on an installed scene",
                r.returncode == 0 and os.path.isfile(os.path.join(work, "mesh.png")), r.stderr[-2000:])
        exe = build_c(R, P, libdir, env, work, "hello_client", C_CLIENT, "gearsim-client")
        if exe:
            r = run([exe], env, work, timeout=60)
            R.check("C program (installed client library) gets hello", r.returncode == 0 and
                    r.stdout.strip() == "protocol 1", r.stdout + r.stderr)
        exe = build_c(R, P, libdir, env, work, "builtins", C_LIB, "gearsim")
        if exe:
            r = run([exe], env, work, timeout=60)
            R.check("C program (installed libgearsim) runs", r.returncode == 0 and
                    r.stdout.strip() == f"builtins {len(inst)} pair yes", r.stdout + r.stderr)
        r = run(["gearsim-client-c", "builtin:pair", "--until", "0.001"], env, work, timeout=120)
        R.check("installed gearsim-client-c prints telemetry", r.returncode == 0 and r.stdout.startswith("t="),
                r.stdout[-500:] + r.stderr[-500:])
        pyenv = dict(env, PYTHONPATH=os.path.join(P, "lib", "python3", "dist-packages"))
        session = ("import gearsim\n"
                   "print(gearsim.__file__)\n"
                   "c = gearsim.Client()\n"
                   "c.load(builtin='planetary')\n"
                   "d = c.advance(time=0.01)\n"
                   "print(round(c.state()['time'], 6))\n")
        r = run(["/usr/bin/python3", "-c", session], pyenv, work)
        out = r.stdout.splitlines()
        ok = (r.returncode == 0 and len(out) == 2 and
              os.path.realpath(out[0]).startswith(os.path.realpath(P) + "/") and abs(float(out[1]) - 0.01) < 1e-9)
        R.check("Python session with the installed package (imported from P)", ok, r.stdout + r.stderr[-2000:])
        pip_install(R, P, env, tmp, work)
    finally:
        r = run(["gearctl", "shutdown"], env, work, timeout=60)
        try:
            daemon.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(daemon.pid, signal.SIGKILL)
            daemon.wait()
        R.check("gearctl shutdown stops the installed daemon", daemon.returncode == 0,
                daemon.stdout.read().decode(errors="replace")[-2000:])


def offline(R, env, work):
    """gearctl's commands that run the installed tools on installed scenes."""
    r = run(["gearctl", "modal", "builtin:lin_parker_3"], env, work)
    R.check("gearctl modal builtin:lin_parker_3", r.returncode == 0 and "rotational" in r.stdout
            and "planet" in r.stdout, r.stdout[-1000:] + r.stderr[-1000:])
    r = run(["gearctl", "stiffness", "builtin:stiffness_pair", "--positions", "4", "--refine", "0"], env, work)
    R.check("gearctl stiffness builtin:stiffness_pair", r.returncode == 0 and "peak-to-peak" in r.stdout,
            r.stdout[-1000:] + r.stderr[-1000:])
    r = run(["gearctl", "sweep", "builtin:planetary_sweep", "--offline", "--from", "1000", "--to", "3000",
             "--points", "3", "--settle", "0.002", "--measure", "0.002", "--json"], env, work)
    try:
        res = json.loads(r.stdout) if r.returncode == 0 else {}
    except ValueError:
        res = {}
    R.check("gearctl sweep --offline builtin:planetary_sweep: 3 points and the modes",
            len(res.get("points", [])) == 3 and len(res.get("modes", [])) > 0, r.stdout[-1000:] + r.stderr[-1000:])


def listeners(R, sid):
    """`ss -ltnp`: the listening TCP sockets of the daemon's process tree
    (session sid: bash, mpirun, the ranks), each on a loopback address."""
    time.sleep(0.5)   # mpirun's runtime listeners are up before the ranks start; the ranks' too by now
    tree = set()
    for n in os.listdir("/proc"):
        try:
            if n.isdigit() and os.getsid(int(n)) == sid:
                tree.add(int(n))
        except OSError:
            pass
    r = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True, timeout=60)
    if not R.check("ss -ltnp lists sockets", r.returncode == 0, r.stderr):
        return
    mine = []
    for line in r.stdout.splitlines():
        f = line.split()
        pids = {int(x) for x in re.findall(r"pid=(\d+)", line)}
        if len(f) >= 4 and pids & tree:
            addr = f[3].rsplit(":", 1)[0].strip("[]").split("%")[0]
            mine.append((addr, line.split("users:")[-1]))
    R.note(f"listening sockets of the installed daemon's tree: {mine}")
    R.check("the daemon's tree listens (commands, telemetry, mpirun's runtime)", len(mine) >= 3, mine)

    def loopback(a):
        try:
            return ipaddress.ip_address(a).is_loopback
        except ValueError:   # "*": every address
            return False
    bad = [m for m in mine if not loopback(m[0])]
    R.check("no listener outside loopback (mpirun started after the installed env.sh)", not bad, bad)


def pip_install(R, P, env, tmp, work):
    """The Debian way: a virtual environment that sees the system's packages
    (python3-zmq and the rest), pip inside it, offline."""
    src = os.path.join(tmp, "pysrc")
    shutil.copytree(os.path.join(SOURCE_ROOT, "clients", "python"), src,
                    ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
    venv = os.path.join(tmp, "venv")
    r = run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv], env, work)
    if not R.check("python3 -m venv --system-site-packages V", r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]):
        return
    r = run([os.path.join(venv, "bin", "pip"), "install", "--no-deps", "--no-build-isolation", "--no-index", src],
            dict(env, PIP_DISABLE_PIP_VERSION_CHECK="1"), work)
    if not R.check("V/bin/pip install --no-deps --no-build-isolation ./clients/python (offline)", r.returncode == 0,
                   r.stdout[-2000:] + r.stderr[-2000:]):
        return
    ctl = os.path.join(venv, "bin", "gearctl")
    R.check("pip install: the gearctl entry point", os.access(ctl, os.X_OK), ctl)
    r = run([ctl, "status"], env, work, timeout=60)
    R.check("pip-installed gearctl status", r.returncode == 0 and '"ranks": 2' in r.stdout, r.stderr[-2000:])
    r = run([ctl, "modal", "builtin:lin_parker_3"], env, work, timeout=120)
    R.check("pip-installed gearctl finds the installed scenes and tools (gearsimd's prefix on PATH)",
            r.returncode == 0 and "rotational" in r.stdout, r.stdout[-500:] + r.stderr[-1000:])
    py = os.path.join(venv, "bin", "python3")
    r = run([py, "-c", "import gearsim; print(gearsim.__file__); print(gearsim.Client().hello()['protocol'])"],
            env, work, timeout=60)
    out = r.stdout.split()
    R.check("pip-installed package imports from V and connects", r.returncode == 0 and len(out) == 2 and
            os.path.realpath(out[0]).startswith(os.path.realpath(venv) + "/") and out[1] == "1", r.stdout + r.stderr)
    r = run([py, "-m", "gearsim", "--help"], env, work, timeout=60)
    R.check("V/bin/python3 -m gearsim --help", r.returncode == 0 and "advise" in r.stdout, r.stderr[-1000:])


def main():
    R = Results("meson install into a prefix, then only the installed programs")
    with scratch_dir("gearsim-install-") as tmp:
        P, libdir = R.guard("install", install, R, tmp) or (None, None)
        if P and os.path.isdir(P):
            R.guard("layout", check_layout, R, P, libdir)
            R.guard("installed programs", with_daemon, R, P, libdir, tmp)
    R.finish()


if __name__ == "__main__":
    main()
