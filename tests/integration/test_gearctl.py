#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearctl against the real daemon: run with telemetry and record files, plot,
a bad scene, mesh (needs the gearsim-mesh tool), live display on a pipe and
on a terminal, the simple commands, fetch, and a missing connection file."""
import json
import os
import pty
import select
import subprocess
import sys
import time

os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import h5py  # noqa: E402

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402
from protoschema import Proto, strict_loads  # noqa: E402

R = Results("test_gearctl: the gearctl command line")
P = Proto()
GEARCTL = os.path.join(dmod.SOURCE_ROOT, "clients", "python", "gearctl")
PNG = b"\x89PNG\r\n\x1a\n"


def gearctl(d, *args, timeout=300, conn=True):
    cmd = [GEARCTL] + (["--connection-file", d.conn_file] if conn else []) + list(args)
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=d.dir)


def is_png(path, min_size=5000):
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return False
    return data.startswith(PNG) and len(data) >= min_size


def run_and_plot(d):
    scene = os.path.join(dmod.SOURCE_ROOT, "deploy", "scenes", "pair.json")
    out_j, out_h = os.path.join(d.dir, "out.jsonl"), os.path.join(d.dir, "out.h5")
    r = gearctl(d, "run", scene, "--until", "0.01", "--telemetry", out_j, "--record", out_h)
    R.check("gearctl run: exit 0", r.returncode == 0, r.stdout[-1000:] + r.stderr[-2000:])
    R.note("gearctl run prints: " + " | ".join(r.stdout.strip().splitlines()[-3:]))
    lines = open(out_j).read().splitlines() if os.path.exists(out_j) else []
    bad = []
    for ln in lines:
        try:
            ev = strict_loads(ln)
            bad += P.errors("events/telemetry.json", ev)
        except ValueError as e:
            bad.append(str(e))
    s = dmod.load_scene("pair")
    expect = int(round(0.01 / s["numerics"]["time_step"])) // s["outputs"]["telemetry_every"]
    R.check(f"telemetry file: {len(lines)} JSON lines (expected {expect})", len(lines) == expect, len(lines))
    R.check("telemetry file: every line is a valid telemetry event", lines and not bad, bad[:3])
    ok_h5 = False
    try:
        with h5py.File(out_h, "r") as f:
            g = f["telemetry"]
            ok_h5 = "scene" in f.attrs and g["energy"].shape[1] == 7 and g["omega"].shape[1] == 2 and \
                g["time"].shape[0] >= expect
            R.check(f"record file: valid HDF5 with the record layout ({g['time'].shape[0]} rows)", ok_h5,
                    {k: g[k].shape for k in g})
    except Exception as e:  # noqa: BLE001
        R.check("record file: valid HDF5", False, repr(e))
    left = [n for n in os.listdir(d.dir) if n.startswith("gearctl-")]
    R.check("gearctl run --record: no copy left in the data directory", not left, left)
    png = os.path.join(d.dir, "out.png")
    r = gearctl(d, "plot", out_h, "-o", png, conn=False)
    R.check("gearctl plot: exit 0 and a PNG", r.returncode == 0 and is_png(png), r.stderr[-2000:])
    r = gearctl(d, "plot", os.path.join(d.dir, "none.h5"), "-o", png, conn=False)
    R.check("gearctl plot of a missing file: non-zero", r.returncode != 0 and "error" in r.stderr, r.stderr)


def bad_scene(d):
    s = dmod.load_scene("pair")
    s["bodies"][1]["module_mm"] = 0
    path = os.path.join(d.dir, "bad.json")
    with open(path, "w") as f:
        json.dump(s, f)
    with d.client() as c:
        try:
            if c.status()["state"] == "loaded":
                c.unload()
            c.load(scene=s)
            msg = None
        except dmod.gearsim.GearsimError as e:
            msg = e.message
    r = gearctl(d, "run", path, "--until", "0.01")
    R.check("gearctl run of a bad scene: non-zero exit", r.returncode != 0, r.returncode)
    R.check("... printing the daemon's error message", msg is not None and msg in r.stderr, (msg, r.stderr))
    r = gearctl(d, "run", os.path.join(d.dir, "missing.json"), "--until", "0.01")
    R.check("gearctl run of a missing file: non-zero with a message", r.returncode != 0 and "error" in r.stderr,
            r.stderr)
    r = gearctl(d, "run", "builtin:nonesuch", "--until", "0.01")
    R.check("gearctl run of an unknown builtin: non-zero", r.returncode != 0 and "error" in r.stderr, r.stderr)


def mesh(d):
    sys.path.insert(0, os.path.join(dmod.SOURCE_ROOT, "clients", "python"))
    tool = os.path.join(dmod.BUILD_ROOT, "src", "tools", "gearsim-mesh")
    import shutil
    if not (shutil.which("gearsim-mesh") or os.access(tool, os.X_OK)):
        R.skip("gearctl mesh", f"gearsim-mesh is not built ({tool})")
        return
    png = os.path.join(d.dir, "mesh.png")
    scene = os.path.join(dmod.SOURCE_ROOT, "deploy", "scenes", "pair.json")
    env = dict(os.environ, GEARSIM_BUILD_ROOT=dmod.BUILD_ROOT)
    r = subprocess.run([GEARCTL, "mesh", scene, "-o", png], capture_output=True, text=True, timeout=600, env=env)
    R.check("gearctl mesh: exit 0 and a PNG", r.returncode == 0 and is_png(png), r.stdout[-500:] + r.stderr[-2000:])
    png2 = os.path.join(d.dir, "mesh_zoom.png")
    r = subprocess.run([GEARCTL, "mesh", scene, "-o", png2, "--zoom-tooth", "pinion"], capture_output=True, text=True,
                       timeout=600, env=env)
    R.check("gearctl mesh --zoom-tooth pinion: exit 0 and a PNG", r.returncode == 0 and is_png(png2),
            r.stderr[-2000:])


def harris(d):
    """gearctl stiffness --loads --relief: the Harris map's plumbing (table,
    plot, JSON) on a coarse, short analysis; the physics is in
    tests/validation/test_modification.c."""
    import shutil
    tool = os.path.join(dmod.BUILD_ROOT, "src", "tools", "gearsim-stiffness")
    if not (shutil.which("gearsim-stiffness") or os.access(tool, os.X_OK)):
        R.skip("gearctl stiffness --loads", f"gearsim-stiffness is not built ({tool})")
        return
    scene = os.path.join(dmod.SOURCE_ROOT, "deploy", "scenes", "stiffness_pair.json")
    csv, png = os.path.join(d.dir, "harris.csv"), os.path.join(d.dir, "harris.png")
    env = dict(os.environ, GEARSIM_BUILD_ROOT=dmod.BUILD_ROOT)
    r = subprocess.run([GEARCTL, "stiffness", scene, "--mesh", "pw", "--loads", "100,200", "--relief", "0,9.6",
                        "--positions", "6", "--refine", "0", "--table", csv, "--plot", png, "--json"],
                       capture_output=True, text=True, timeout=600, env=env)
    R.check("gearctl stiffness --loads --relief: exit 0, a table and a PNG",
            r.returncode == 0 and os.path.exists(csv) and is_png(png), r.stdout[-500:] + r.stderr[-2000:])
    if r.returncode != 0:
        return
    out = json.loads(r.stdout)
    rows = out["rows"]
    R.check("... 4 rows (2 reliefs x 2 loads), the long relief's default extent (eps - 1) p_b = 4.47 mm",
            len(rows) == 4 and abs(out["relief_length_mm"] - 4.466) < 0.01, out)
    with open(csv) as f:
        lines = f.read().strip().splitlines()
    R.check("... the CSV has a header and 4 rows", len(lines) == 5 and lines[0].startswith("relief_um,"), lines)
    head = lines[0].split(",")
    R.check("... the CSV names the loaded static TE te_loaded_*, the former te_pp_um .. te_max_um kept "
            "as equal alias columns", head[3:7] == ["te_loaded_pp_um", "te_loaded_mean_um", "te_loaded_min_um",
                                                    "te_loaded_max_um"]
            and all(ln.split(",")[3:7] == ln.split(",")[-4:] for ln in lines[1:])
            and head[-4:] == ["te_pp_um", "te_mean_um", "te_min_um", "te_max_um"], lines)
    pp = {(r_["relief_um"], r_["line_load_n_per_mm"]): r_["te_loaded_pp_um"] for r_ in rows}
    R.check("... the relief changes the peak-to-peak TE", pp[(0.0, 200.0)] != pp[(9.6, 200.0)], pp)
    r = subprocess.run([GEARCTL, "stiffness", scene, "--relief", "5"], capture_output=True, text=True,
                       timeout=600, env=env)
    R.check("... --relief without --loads: refused", r.returncode != 0 and "--loads" in r.stderr, r.stderr)


def live_pipe(d):
    r = gearctl(d, "run", "builtin:planetary", "--until", "0.01", "--live")
    pct = [ln for ln in r.stdout.splitlines() if "%" in ln]
    R.check("gearctl run --live on a pipe: exit 0", r.returncode == 0, r.stderr[-2000:])
    R.check(f"... one line per ~10% ({len(pct)} lines), no escape codes",
            5 <= len(pct) <= 13 and "\x1b[" not in r.stdout, r.stdout[-1500:])
    R.check("... the last line is at 100%", pct and "100.0%" in pct[-1], pct[-1:] if pct else r.stdout)


def live_tty(d):
    pid, fd = pty.fork()
    if pid == 0:   # child: gearctl on a terminal
        os.execv(GEARCTL, [GEARCTL, "--connection-file", d.conn_file, "run", "builtin:pair", "--until", "0.02",
                           "--live"])
    out = b""
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        r, _, _ = select.select([fd], [], [], 1.0)
        if r:
            try:
                chunk = os.read(fd, 65536)
            except OSError:
                break
            if not chunk:
                break
            out += chunk
    _, status = os.waitpid(pid, 0)
    os.close(fd)
    text = out.decode(errors="replace")
    R.check("gearctl run --live on a terminal: exit 0", os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0,
            text[-1000:])
    R.check("... redraws in place (ANSI cursor movement) with a progress bar, rpm and energies",
            "\x1b[" in text and "100.0%" in text and "rpm" in text and "energy" in text and "residual" in text,
            text[-1500:])


def simple(d):
    for cmd in ("hello", "status", "state", "jobs"):
        r = gearctl(d, cmd)
        try:
            res = json.loads(r.stdout)
        except ValueError:
            res = None
        R.check(f"gearctl {cmd}: exit 0 with a JSON result", r.returncode == 0 and isinstance(res, dict),
                r.stdout[-500:] + r.stderr[-500:])
        if cmd in ("hello", "status", "state") and isinstance(res, dict):
            errs = P.errors(f"results/{cmd}.json", res)
            R.check(f"gearctl {cmd}: result validates", not errs, errs)
    with open(os.path.join(d.dir, "blob.bin"), "wb") as f:
        f.write(os.urandom(3 * 1024 * 1024 + 17))
    out = os.path.join(d.dir, "blob.copy")
    r = gearctl(d, "fetch", "blob.bin", "-o", out)
    same = os.path.exists(out) and open(out, "rb").read() == open(os.path.join(d.dir, "blob.bin"), "rb").read()
    R.check("gearctl fetch of a 3 MiB file (4 chunks): identical bytes", r.returncode == 0 and same, r.stderr)
    r = gearctl(d, "fetch", "../etc/passwd", "-o", out)
    R.check("gearctl fetch ../etc/passwd: non-zero with the error", r.returncode != 0 and "error" in r.stderr,
            r.stderr)
    r = subprocess.run([GEARCTL, "--connection-file", os.path.join(d.dir, "nope.json"), "hello"],
                       capture_output=True, text=True, timeout=60)
    R.check("gearctl with a missing connection file: non-zero with a message",
            r.returncode != 0 and "connection file" in r.stderr, r.stderr)
    r = subprocess.run([GEARCTL], capture_output=True, text=True, timeout=60)
    R.check("gearctl without a command: usage error", r.returncode == 2, r.returncode)


def shutdown(d):
    r = gearctl(d, "shutdown")
    R.check("gearctl shutdown: exit 0", r.returncode == 0, r.stderr)
    R.check("gearctl shutdown: says so in words", "shutting down" in r.stdout and "{}" not in r.stdout, r.stdout)
    try:
        d.proc.wait(timeout=30)
        R.check("daemon exited after gearctl shutdown", True)
    except subprocess.TimeoutExpired:
        R.check("daemon exited after gearctl shutdown", False, d.log_tail())


def main():
    with dmod.Daemon(ranks=1) as d:
        R.guard("run and plot", run_and_plot, d)
        R.guard("bad scene", bad_scene, d)
        R.guard("mesh", mesh, d)
        R.guard("Harris map", harris, d)
        R.guard("live display on a pipe", live_pipe, d)
        R.guard("live display on a terminal", live_tty, d)
        R.guard("simple commands and fetch", simple, d)
        R.guard("shutdown", shutdown, d)


R.guard("gearctl against the real daemon", main)
R.finish()
