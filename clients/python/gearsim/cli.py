# SPDX-License-Identifier: MIT
"""gearctl's command line: the argument parser and one handler per
subcommand; the logic lives in the package's modules (advise, harris,
stiffness, modal, sweep, plot, live, record). `python3 -m gearsim` and the
installed `gearctl` both run main().

Exit status 0 on success; on failure the error message goes to stderr and the
status is 1 (2 for usage errors, 130 when interrupted)."""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from . import advise as advice
from . import plot
from .client import Client
from .connection import default_connection_file
from .errors import GearsimError
from .paths import DATA, find_tool, scene_file, tool_missing
from .stiffness import ToolError

SIMPLE = ["hello", "status", "state", "jobs", "pause", "resume", "cancel", "unload", "shutdown"]
USAGE = 2   # exit status of a usage error (argparse's too)


def fail(msg, code=1):
    print(f"gearctl: error: {msg}", file=sys.stderr)
    return code


def write_plot(draw, path, quiet=False):
    """draw(path) (a gearsim.plot function bound to its data), then "wrote
    PATH" unless quiet; a missing matplotlib is an error, not a traceback."""
    try:
        draw(path)
    except ImportError as e:
        return fail(f"matplotlib is not available: {e}")
    if not quiet:
        print(f"wrote {path}")
    return 0


def need_tool(name):
    """The path of a gearsim-* tool; ToolError (exit 1) naming where it was looked for."""
    tool = find_tool(name)
    if not tool:
        raise ToolError(tool_missing(name))
    return tool


def client(args):
    return Client(args.connection_file, timeout=args.timeout, curve_key=args.curve_key)


def cmd_simple(args):
    with client(args) as c:
        result = getattr(c, args.command)()
    if args.command == "shutdown":
        print("gearsimd is shutting down (it finishes the reply, then every rank exits)")
    else:
        print(json.dumps(result, indent=2))
    return 0


def load_scene(c, spec):
    """Load SCENE.json or builtin:NAME; replaces an idle scene if one is loaded."""
    if spec.startswith("builtin:"):
        kw = {"builtin": spec[len("builtin:"):]}
    else:
        try:
            with open(spec) as f:
                kw = {"scene": json.load(f)}
        except OSError as e:
            raise GearsimError("io_error", f"cannot read scene {spec}: {e.strerror}") from None
        except ValueError as e:
            raise GearsimError("bad_json", f"scene {spec} is not valid JSON: {e}") from None
    try:
        return c.load(**kw)
    except GearsimError as e:
        if e.code != "wrong_state" or c.status().get("state") != "loaded":
            raise
        c.unload()
        return c.load(**kw)


def fetch_xdmf(c, remote, local):
    """Field snapshots come with an XDMF file beside the record: fetch it too
    and point it at the local record's name. A record without fields has none."""
    rx, lx = os.path.splitext(remote)[0] + ".xmf", os.path.splitext(local)[0] + ".xmf"
    try:
        text = c.fetch(rx, remove=True).decode("utf-8")
    except GearsimError as e:
        if e.code == "not_found":
            return
        raise
    with open(lx, "w") as f:
        f.write(text.replace(os.path.basename(remote) + ":", os.path.basename(local) + ":"))


def drop_remote(c, remote):
    """Remove the daemon's copy of a record (and its XDMF file) that is not
    downloaded: fetched to nowhere with remove."""
    for path in (remote, os.path.splitext(remote)[0] + ".xmf"):
        try:
            c.fetch(path, remove=True)
        except GearsimError as e:
            if e.code != "not_found":
                raise


def cmd_run(args):
    from .live import LiveDisplay
    tel = open(args.telemetry, "w") if args.telemetry else None
    remote = None
    live = None
    try:
        with client(args) as c:
            info = load_scene(c, args.scene)
            start = float(c.status().get("time", 0.0))
            duration = args.until - start
            if not duration > 0:
                return fail(f"--until {args.until:g} is not after the current time {start:g} s")
            c.subscribe()
            if args.record:
                remote = f"gearctl-{os.getpid()}-{int(time.time())}-{os.path.basename(args.record)}"
                c.record(remote)
            if args.live:
                live = LiveDisplay(title=info.get("name", args.scene), target_time=args.until, start_time=start)
            else:
                print(f"loaded {info.get('name', args.scene)!r}: {len(info.get('bodies', []))} bodies, "
                      f"time step {info.get('time_step', 0):g} s; running to t = {args.until:g} s", flush=True)

            def on_telemetry(ev):
                if tel:
                    tel.write(json.dumps(ev, separators=(",", ":")) + "\n")
                if live:
                    live.on_telemetry(ev)

            try:
                done = c.advance(time=duration, on_telemetry=on_telemetry,
                                 on_progress=live.on_progress if live else None)
            except KeyboardInterrupt:
                c.cancel()
                if args.record:
                    # The daemon's copy goes (nothing is left behind); the
                    # local file is not written (no partial copy).
                    c.record(stop=True)
                    drop_remote(c, remote)
                print("\ngearctl: interrupted; run cancelled" + ("; nothing recorded" if args.record else ""),
                      file=sys.stderr)
                return 130
            if live:
                live.close(done)
            if args.record:
                c.record(stop=True)
                fetch_xdmf(c, remote, args.record)
                size = c.fetch(remote, args.record, remove=True)
                if not args.live:
                    print(f"record: {args.record} ({size} bytes)")
            if c.gaps:
                print(f"gearctl: warning: {c.gaps} events were dropped (seq gaps)", file=sys.stderr)
            if done.get("lost"):
                print("gearctl: warning: the done event was lost; the run has ended", file=sys.stderr)
            wall = done.get("wall_seconds")
            print(f"done: {done.get('steps', '?')} steps, t = {done.get('time', 0):.6g} s"
                  + (f", {wall:.3f} s wall" if wall is not None else "")
                  + (" (cancelled)" if done.get("cancelled") else ""))
            return 0
    finally:
        if tel:
            tel.close()




def cmd_plot(args):
    from .record import plot_record
    if not os.path.exists(args.file):
        return fail(f"no such file: {args.file}")
    plot_record(args.file, args.output)
    print(f"wrote {args.output}")
    return 0


def cmd_mesh(args):
    scene = scene_file(args.scene)
    tool = need_tool("gearsim-mesh")
    with tempfile.TemporaryDirectory(prefix="gearctl-mesh-") as tmp:
        h5 = os.path.join(tmp, "mesh.h5")
        r = subprocess.run([tool, scene, "-o", h5], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
        if r.returncode != 0:
            return fail(f"gearsim-mesh failed ({r.returncode}): {r.stdout.strip()}")
        try:
            from .meshplot import plot_mesh
        except ImportError as e:
            return fail(f"gearsim.meshplot is not available: {e}")
        plot_mesh(h5, args.output, zoom_tooth=args.zoom_tooth)
    print(f"wrote {args.output}")
    return 0


def cmd_harris(args, tool, scene):
    """`gearctl stiffness --loads`: the Harris map (gearsim.harris)."""
    from .harris import harris_csv, harris_map, harris_text, parse_list, parse_loads
    loads = parse_loads(args.loads)
    reliefs = parse_list(args.relief, "--relief") if args.relief else None
    out = harris_map(tool, scene, loads, reliefs=reliefs, relief_length=args.relief_length,
                     relief_shape=args.relief_shape, positions=args.positions, mesh=args.mesh,
                     refine=args.refine, driver=args.driver, nearfield=not args.no_nearfield)
    if args.table:
        with open(args.table, "w") as f:
            f.write(harris_csv(out["rows"]))
    print(json.dumps(out) if args.json else harris_text(out, loads))
    if args.plot:
        return write_plot(lambda p: plot.plot_harris(out, p, relief_given=bool(reliefs)), args.plot, args.json)
    return 0


def cmd_stiffness(args):
    from .stiffness import run_json, stiffness_command, stiffness_text
    from .harris import parse_list, parse_loads
    if args.loads:
        try:
            parse_loads(args.loads)
            parse_list(args.relief or "", "--relief")
        except ValueError as e:
            return fail(str(e), USAGE)
    elif args.relief or args.table:
        return fail("--relief and --table belong to the Harris map: give --loads", USAGE)
    scene = scene_file(args.scene)
    tool = need_tool("gearsim-stiffness")
    if args.loads:
        return cmd_harris(args, tool, scene)
    res = run_json(stiffness_command(tool, scene, positions=args.positions, mesh=args.mesh, torque=args.torque,
                                     refine=args.refine, driver=args.driver, nearfield=not args.no_nearfield,
                                     out=args.out), "gearsim-stiffness")
    print(json.dumps(res) if args.json else stiffness_text(res))
    if args.plot:
        return write_plot(lambda p: plot.plot_stiffness(res, p), args.plot, args.json)
    return 0


def cmd_modal(args):
    from .modal import modal_text, run_modal
    scene = scene_file(args.scene)
    tool = need_tool("gearsim-modal")
    res = run_modal(tool, scene)
    print(json.dumps(res) if args.json else modal_text(res))
    if args.plot:
        return write_plot(lambda p: plot.plot_modes(res, p), args.plot, args.json)
    return 0


def cmd_sweep(args):
    from .modal import modes_of, run_modal
    from .sweep import peak_text, sweep_offline, sweep_param, sweep_peaks, sweep_rows, sweep_service
    scene = args.scene
    if args.rpm_from is None and not args.param:
        return fail("give --from/--to (driver speed) or --param PATH=...", USAGE)
    if (args.rpm_from is None) != (args.rpm_to is None):
        return fail("--from and --to go together", USAGE)
    try:
        for p in args.param or []:
            sweep_param(p)
    except ValueError as e:
        return fail(str(e), USAGE)
    if args.offline:
        scene = scene_file(scene)
    try:
        modal = None
        if args.offline:
            text = sweep_offline(args, scene)
            mt = find_tool("gearsim-modal")
            if mt:
                try:
                    modal = run_modal(mt, scene)
                except ToolError:
                    modal = None
        else:
            with client(args) as c:
                text, modal = sweep_service(c, args, scene)
    except ValueError as e:
        return fail(str(e), USAGE)
    header, rows = sweep_rows(text)
    if args.csv:
        with open(args.csv, "w") as f:
            f.write(text)
    xkey = "mesh_hz" if args.rpm_from is not None else header[1]
    ok_rows = [r for r in rows if r.get("dte_rms_um") is not None]
    peaks = sweep_peaks(ok_rows) if xkey == "mesh_hz" and len(ok_rows) > 2 else []
    res = {"columns": header, "points": rows, "peaks": [{"mesh_hz": x, "dte_rms_um": y} for x, y in peaks],
           "modes": modes_of(modal)}
    if args.json:
        print(json.dumps(res))
    else:
        for x, y in peaks:
            print(peak_text(x, y, res["modes"]))
    if args.plot:
        return write_plot(lambda p: plot.plot_sweep(res, ok_rows, xkey, p, os.path.basename(args.scene)),
                          args.plot, args.json)
    return 0


def cmd_impact(args):
    tool = need_tool("gearsim-impact")
    r = subprocess.run([tool, args.case], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        return fail(f"gearsim-impact failed ({r.returncode}): {r.stderr.strip()}")
    print(r.stdout.strip())
    return 0


def cmd_bench(args):
    """`gearctl bench tradeoff`: run bench_tradeoff (the fidelity ladder,
    speed against accuracy) or take its CSV, and draw the Pareto plot."""
    csv_path = args.csv
    if not args.from_csv:
        exe = None
        roots = [os.environ.get("GEARSIM_BUILD_ROOT", ""), DATA.get("build") or ""]
        for r in roots:
            cand = os.path.join(r, "tests", "bench", "bench_tradeoff")
            if r and os.access(cand, os.X_OK):
                exe = os.path.abspath(cand)
                break
        if not exe:
            return fail("bench_tradeoff not found (build it: ninja -C build tests/bench/bench_tradeoff)")
        env = dict(os.environ, OPENBLAS_NUM_THREADS=os.environ.get("OPENBLAS_NUM_THREADS", "1"))
        r = subprocess.run([exe, csv_path], env=env, stdout=subprocess.PIPE, text=True)
        if r.returncode != 0:
            return fail(f"bench_tradeoff failed ({r.returncode})")
        if args.markdown:
            with open(args.markdown, "w") as f:
                f.write(r.stdout)
        print(r.stdout)
    if args.plot:
        return write_plot(lambda p: plot.plot_tradeoff(csv_path, p), args.plot)
    return 0


def cmd_advise(args):
    """`gearctl advise`: the cheapest fidelity (level, time step, refine) of
    the measured trade-off table that meets relative-error targets."""
    try:
        scene = advice.read_scene_spec(args.scene)
        res = advice.advise(scene, args.table, args.target or [], args.scene)
    except advice.AdviceError as e:
        return fail(str(e), e.code)
    print(json.dumps(res, indent=2) if args.json else advice.advice_text(res))
    return 0


def cmd_fetch(args):
    with client(args) as c:
        size = c.fetch(args.path, args.output)
    print(f"{args.output}: {size} bytes")
    return 0


def cmd_keys(args):
    """CURVE key pairs for gearsimd's --curve-server-key / --curve-allow and
    the clients' --curve-key (docs/reference/protocol.md, Authentication)."""
    from .connection import write_key_files
    os.makedirs(args.dir, exist_ok=True)
    for name in args.names:
        if not name or "/" in name or name.startswith("."):
            return fail(f"bad key name {name!r}: a plain file name without '/'", 2)
        pub, key, public = write_key_files(os.path.join(args.dir, name), force=args.force)
        print(f"{name}: public key {public}\n  {key} (secret, mode 0600)\n  {pub}")
    return 0


def wait_for_daemon(args):
    """Until a hello is answered or args.wait seconds have passed: the
    connection file may not exist yet and the daemon may not answer yet."""
    deadline = time.monotonic() + args.wait
    while True:
        try:
            with Client(args.connection_file, timeout=min(2.0, args.wait), retries=0,
                                curve_key=args.curve_key) as c:
                c.hello()
            return
        except GearsimError as e:
            if e.code not in ("not_found", "timeout", "bad_json") or time.monotonic() >= deadline:
                raise
        time.sleep(0.2)




def parser():
    """gearctl's argparse parser (every subcommand and option)."""
    default_table = advice.DEFAULT_TABLE
    ap = argparse.ArgumentParser(prog="gearctl", description="Drive gearsimd, the gear-train simulation service.")
    ap.add_argument("--connection-file", metavar="PATH",
                    help=f"daemon connection file (default {default_connection_file()})")
    ap.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for a reply (default 10)")
    ap.add_argument("--curve-key", metavar="FILE",
                    help="client CURVE key (.key of `gearctl keys`) for a daemon that requires CURVE "
                         "(default $GEARSIM_CURVE_KEY)")
    ap.add_argument("--wait", type=float, default=0.0, metavar="S",
                    help="first wait up to S seconds for the daemon to answer (a daemon just started)")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in SIMPLE:
        sub.add_parser(name, help=f"send '{name}' and print the result as JSON")
    p = sub.add_parser("run", help="load a scene and run it")
    p.add_argument("scene", metavar="SCENE.json|builtin:NAME")
    p.add_argument("--until", type=float, required=True, metavar="T", help="simulated end time, s")
    p.add_argument("--telemetry", metavar="OUT.jsonl", help="write every telemetry event as one JSON line")
    p.add_argument("--record", metavar="OUT.h5", help="record to HDF5 and download the file")
    p.add_argument("--live", action="store_true", help="live display of progress, speeds and energies")
    p = sub.add_parser("plot", help="plot energies and speeds of an HDF5 record")
    p.add_argument("file", metavar="FILE.h5")
    p.add_argument("-o", "--output", required=True, metavar="FILE.png")
    p = sub.add_parser("mesh", help="mesh a scene with gearsim-mesh and plot it")
    p.add_argument("scene", metavar="SCENE.json|builtin:NAME")
    p.add_argument("-o", "--output", required=True, metavar="MESH.png")
    p.add_argument("--zoom-tooth", metavar="BODY", help="also zoom on one tooth of BODY")
    p = sub.add_parser("stiffness", help="quasi-static mesh stiffness and transmission error (gearsim-stiffness)")
    p.add_argument("scene", metavar="SCENE.json|builtin:NAME")
    p.add_argument("--mesh", metavar="NAME", help="the scene mesh (default: the first)")
    p.add_argument("--positions", type=int, default=24, metavar="N", help="roll positions over one mesh cycle")
    p.add_argument("--torque", type=float, metavar="T", help="moment on the driver, N m (default: scene load or 200 N/mm)")
    p.add_argument("--refine", type=int, metavar="R", help="mesh refinement of both gears (default: the scene's)")
    p.add_argument("--driver", type=int, choices=[0, 1], help="gear of the mesh carrying the torque (default 0)")
    p.add_argument("--no-nearfield", action="store_true", help="the plain FE contact, without the near-field "
                   "(Hertz) correction that is on by default on quadratic meshes")
    p.add_argument("--json", action="store_true", help="print the tool's JSON instead of a table")
    p.add_argument("--plot", metavar="FILE.png", help="plot k and TE against roll angle")
    p.add_argument("--out", metavar="FILE.h5", help="also write the HDF5 result")
    p.add_argument("--loads", metavar="W1,W2,..", help="Harris map: line loads, N/mm (one analysis each)")
    p.add_argument("--relief", metavar="C1,C2,..", help="Harris map: tip relief amounts, um, on both gears "
                   "(default: the scene's own modifications)")
    p.add_argument("--relief-length", type=float, metavar="MM", help="roll length of the relief from the tip "
                   "(default (eps - 1) p_b: from the highest point of single-tooth contact)")
    p.add_argument("--relief-shape", choices=["linear", "parabolic"], default="linear")
    p.add_argument("--table", metavar="F.csv", help="Harris map: write the table")
    p = sub.add_parser("modal", help="natural frequencies and mode shapes of the lumped train (gearsim-modal)")
    p.add_argument("scene", metavar="SCENE.json|builtin:NAME")
    p.add_argument("--json", action="store_true", help="print the result as JSON (modes with shapes)")
    p.add_argument("--plot", metavar="FILE.png", help="draw the mode shapes, one panel per group")
    p = sub.add_parser("sweep", help="parameter sweep (the daemon's sweep job on groups of ranks, or --offline), "
                       "response against mesh frequency")
    p.add_argument("scene", metavar="SCENE.json|builtin:NAME")
    p.add_argument("--from", dest="rpm_from", type=float, metavar="RPM", help="driver speed of the first point")
    p.add_argument("--to", dest="rpm_to", type=float, metavar="RPM", help="driver speed of the last point")
    p.add_argument("--points", type=int, default=40, help="driver speeds from --from to --to (default 40)")
    p.add_argument("--param", action="append", metavar="PATH=FROM:TO:N|PATH=V1,V2,..",
                   help="another swept parameter: a JSON path into the scene (e.g. loads[0].moment); repeat for a grid")
    p.add_argument("--driver-rpm", type=float, metavar="RPM", help="start every point in steady state at this speed "
                   "(when the speed is not swept)")
    p.add_argument("--settle", type=float, default=0.01, metavar="S", help="seconds before measuring (default 0.01)")
    p.add_argument("--measure", type=float, default=0.01, metavar="S", help="seconds measured (default 0.01)")
    p.add_argument("--time-step", type=float, metavar="H", help="override the scene's time step")
    p.add_argument("--mesh", metavar="NAME", help="the mesh whose response is measured (default: the first)")
    p.add_argument("--groups", type=int, metavar="G", help="groups of ranks computing points at once "
                   "(default: one per rank)")
    p.add_argument("--path", metavar="BASE", help="the table in the daemon's data directory: BASE.csv, BASE.h5 "
                   "(default sweep)")
    p.add_argument("--resume", action="store_true", help="continue the unfinished sweep at --path")
    p.add_argument("--offline", action="store_true", help="no daemon: the points one after the other in "
                   "gearsim-sweep")
    p.add_argument("--csv", metavar="FILE.csv", help="write the table here too")
    p.add_argument("--json", action="store_true", help="print columns, points, peaks and modes as JSON")
    p.add_argument("--plot", metavar="FILE.png", help="plot DTE rms, dynamic factor and load sharing against mesh "
                   "frequency with the natural frequencies")
    p = sub.add_parser("keys", help="make CURVE key pairs (NAME.key secret, NAME.pub public)")
    p.add_argument("names", nargs="+", metavar="NAME")
    p.add_argument("--dir", default=".", help="where to write the files (default: here)")
    p.add_argument("--force", action="store_true", help="replace existing files")
    p = sub.add_parser("impact", help="frictional impact of two bodies (gearsim-impact), printed as JSON")
    p.add_argument("case", metavar="CASE.json")
    p = sub.add_parser("bench", help="benchmarks: `bench tradeoff` runs the fidelity ladder and plots it")
    p.add_argument("which", choices=["tradeoff"])
    p.add_argument("--csv", default="tradeoff.csv", metavar="FILE.csv", help="the table (written, or read with --from-csv)")
    p.add_argument("--from-csv", action="store_true", help="do not run: plot an existing CSV")
    p.add_argument("--markdown", metavar="FILE.md", help="also write the Markdown table")
    p.add_argument("--plot", metavar="FILE.png", help="Pareto plot of time against error")
    p = sub.add_parser("advise", help="the cheapest fidelity meeting accuracy targets, from the trade-off table")
    p.add_argument("scene", metavar="SCENE.json|NAME", help="a scene file or a builtin scene name")
    p.add_argument("--target", action="append", metavar="OUTPUT=REL_ERR",
                   help="relative error allowed on an output of the table (speed, dte, force, mesh, ...) against "
                        "its reference; repeat for several")
    p.add_argument("--table", default=default_table, metavar="FILE.csv",
                   help=f"the measured table (default {default_table})")
    p.add_argument("--json", action="store_true", help="print the advice as JSON")
    p = sub.add_parser("fetch", help="download a file from the daemon's data directory")
    p.add_argument("path")
    p.add_argument("-o", "--output", required=True, metavar="OUT")
    return ap


LOCAL = {"plot", "mesh", "stiffness", "impact", "keys", "bench", "advise", "modal", "sweep"}


def main(argv=None):
    args = parser().parse_args(argv)
    handler = {"run": cmd_run, "plot": cmd_plot, "mesh": cmd_mesh, "stiffness": cmd_stiffness,
               "fetch": cmd_fetch, "impact": cmd_impact, "keys": cmd_keys,
               "bench": cmd_bench, "advise": cmd_advise, "modal": cmd_modal,
               "sweep": cmd_sweep}.get(args.command, cmd_simple)
    try:
        # `sweep` is local only with --offline; otherwise it talks to the daemon.
        if args.wait > 0 and (args.command not in LOCAL or (args.command == "sweep" and not args.offline)):
            wait_for_daemon(args)
        return handler(args)
    except GearsimError as e:
        return fail(e.message + (f" [{e.code}" + (f", field {e.field}" if e.field else "") + "]"))
    except (ToolError, ValueError) as e:
        return fail(str(e))
    except KeyboardInterrupt:
        return 130
    except OSError as e:
        return fail(str(e))
