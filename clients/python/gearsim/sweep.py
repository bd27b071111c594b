# SPDX-License-Identifier: MIT
"""Parameter sweeps (gearctl sweep): the daemon's `sweep` job on groups of
ranks or, offline, the gearsim-sweep tool point after point; the table they
write, its resonance peaks and the natural frequencies they sit at.

`opts` below is any object with the attributes of gearctl sweep's options
(rpm_from, rpm_to, points, param, driver_rpm, settle, measure, time_step,
mesh, groups, path, resume, json)."""
import json
import os
import subprocess
import sys
import tempfile

from .errors import GearsimError
from .paths import find_tool, tool_missing


def parabola_vertex(xs, ys, i):
    """Abscissa of the vertex of the parabola through points i-1, i, i+1 of
    (xs, ys) (0 < i < len - 1); xs[i] when that parabola does not open
    downwards."""
    x0, x1, x2 = xs[i - 1], xs[i], xs[i + 1]
    y0, y1, y2 = ys[i - 1], ys[i], ys[i + 1]
    den = (x0 - x1) * (x0 - x2) * (x1 - x2)
    a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den
    b = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / den
    return -b / (2 * a) if a < 0 else x1


def sweep_peaks(rows, key="dte_rms_um"):
    """Local maxima of the response against mesh frequency, each refined by a
    parabola through it and its neighbours: [(mesh_hz, value)]."""
    xs = [r["mesh_hz"] for r in rows]
    ys = [r[key] for r in rows]
    peaks = []
    for i in range(1, len(ys) - 1):
        if ys[i] > ys[i - 1] and ys[i] >= ys[i + 1]:
            peaks.append((parabola_vertex(xs, ys, i), ys[i]))
    return peaks


def sweep_param(text):
    """--param PATH=FROM:TO:N or PATH=V1,V2,... as a sweep parameter."""
    if "=" not in text:
        raise ValueError(f"--param {text}: give PATH=FROM:TO:N or PATH=V1,V2,...")
    path, vals = text.split("=", 1)
    if vals.count(":") == 2:
        a, b, n = vals.split(":")
        return {"path": path, "from": float(a), "to": float(b), "points": int(n)}
    return {"path": path, "values": [float(v) for v in vals.split(",") if v != ""]}


def sweep_rows(text):
    """Rows of a sweep table (CSV text) as dicts; empty fields are None."""
    lines = [ln for ln in text.splitlines() if ln.strip()]
    header = lines[0].strip().split(",")
    rows = []
    for line in lines[1:]:
        v = line.strip().split(",")
        rows.append({k: (float(x) if x != "" else None) for k, x in zip(header, v)})
    return header, rows


def offline_spec(opts, scene):
    """The gearsim-sweep --spec document for a grid (--param or --driver-rpm)."""
    spec = {"scene_file": os.path.abspath(scene), "parameters": [sweep_param(p) for p in opts.param or []],
            "settle": opts.settle, "measure": opts.measure}
    if opts.rpm_from is not None:
        spec["parameters"].insert(0, {"path": "driver_rpm", "from": opts.rpm_from, "to": opts.rpm_to,
                                      "points": opts.points})
    for k, v in (("time_step", opts.time_step), ("mesh", opts.mesh), ("driver_rpm", opts.driver_rpm)):
        if v is not None:
            spec[k] = v
    return spec


def sweep_offline(opts, scene):
    """The points in this process with gearsim-sweep (no daemon); its rows
    echoed as they come unless opts.json. Returns the table's CSV text."""
    tool = find_tool("gearsim-sweep")
    if not tool:
        raise GearsimError("not_found", tool_missing("gearsim-sweep"))
    if opts.param or opts.driver_rpm is not None:
        tmp = tempfile.NamedTemporaryFile("w", suffix=".json", delete=False)
        json.dump(offline_spec(opts, scene), tmp)
        tmp.close()
        cmd = [tool, "--spec", tmp.name]
    else:
        tmp = None
        cmd = [tool, scene, "--from", repr(opts.rpm_from), "--to", repr(opts.rpm_to), "--points", str(opts.points),
               "--settle", repr(opts.settle), "--measure", repr(opts.measure)]
        if opts.time_step:
            cmd += ["--time-step", repr(opts.time_step)]
        if opts.mesh:
            cmd += ["--mesh", opts.mesh]
    try:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        out = []
        for line in proc.stdout:
            out.append(line)
            if not opts.json and len(out) > 1:
                print(line.rstrip(), flush=True)   # progress: one row per point
        err = proc.stderr.read()
        rc = proc.wait()
    finally:
        if tmp:
            os.unlink(tmp.name)
    if rc != 0:
        raise GearsimError("internal", f"gearsim-sweep failed ({rc}): {err.strip()}")
    return "".join(out)


def service_parameters(opts):
    """The sweep request's parameters: driver speed first, then --param."""
    params = []
    if opts.rpm_from is not None:
        params.append({"path": "driver_rpm", "from": opts.rpm_from, "to": opts.rpm_to, "points": opts.points})
    return params + [sweep_param(p) for p in opts.param or []]


def progress_line(ev):
    """One line per point of the daemon's sweep progress events."""
    v = ev.get("values") or {}
    extra = f", DTE rms {v['dte_rms_um']:.4f} um at {v['mesh_hz']:.1f} Hz" if v.get("dte_rms_um") is not None else ""
    err = f", failed: {ev['error']['message']}" if ev.get("error") else ""
    return f"point {ev.get('point')}: {ev.get('points_done')}/{ev.get('points')} done{extra}{err}"


def sweep_service(c, opts, scene):
    """The `sweep` job of the daemon behind client `c` (groups of ranks); the
    table fetched back. Returns (CSV text, the scene's modal result or None)."""
    kw = dict(settle=opts.settle, measure=opts.measure, time_step=opts.time_step, mesh=opts.mesh,
              driver_rpm=opts.driver_rpm, groups=opts.groups, path=opts.path, resume=True if opts.resume else None)
    if scene.startswith("builtin:"):
        kw["builtin"] = scene[len("builtin:"):]
    else:
        kw["scene"] = scene

    def progress(ev):
        if not opts.json:
            print(progress_line(ev), flush=True)

    done = c.sweep(service_parameters(opts), on_progress=progress, **kw)
    if not opts.json:
        print(f"{done.get('points_done')} of {done.get('points')} points ({done.get('computed')} computed here, "
              f"{done.get('groups')} group(s), {done.get('points_per_second', 0):.3g} points/s); table "
              f"{done.get('csv')}, {done.get('h5')} in the daemon's data directory")
    for f in done.get("failed") or []:
        print(f"point {f['point']} failed: {f['message']}", file=sys.stderr)
    with tempfile.TemporaryDirectory() as td:
        local = os.path.join(td, "t.csv")
        c.fetch(done["csv"], local)
        with open(local) as f:
            text = f.read()
    modal = None
    try:
        margs = {"shapes": False}
        if "builtin" in kw:
            margs["builtin"] = kw["builtin"]
        else:
            with open(scene) as f:
                margs["scene"] = json.load(f)
        modal = c.request("modal", margs)
    except (GearsimError, OSError):
        modal = None
    return text, modal


def peak_text(x, y, modes):
    """A peak and the mode it sits at: the mesh frequency or its 2nd or 3rd
    harmonic nearest to a natural frequency."""
    near = min(((abs(x * k / m["frequency_hz"] - 1), k, m) for m in modes for k in (1, 2, 3)),
               key=lambda t: t[0], default=None)
    txt = ""
    if near:
        _, k, m = near
        txt = (f"; {'mesh frequency' if k == 1 else f'harmonic {k}'} at the {m['kind']} mode "
               f"{m['frequency_hz']:.1f} Hz ({(x * k / m['frequency_hz'] - 1) * 100:+.2f}%)")
    return f"peak at mesh frequency {x:.1f} Hz, DTE rms {y:.3f} um{txt}"
