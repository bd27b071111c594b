#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The `sweep` job (docs/explanation/modal.md, "Sweeps"; docs/reference/protocol.md) on a daemon
of 2 ranks: a short speed sweep of the lumped planetary (planetary_sweep)
at 1 group of 2 ranks and at 2 groups of 1 rank gives byte-identical CSV
tables and equal HDF5 tables, one progress event per point (schemas
checked), `status` shows the sweep and engine commands are refused while
it runs; cancel keeps the finished points and a resumed sweep computes only
the missing ones, ending with the same table; the Slurm array script run
task by task without Slurm (deploy/sweep_array.slurm) and its collect step
give the same values; `gearctl sweep` drives the job; bad input is refused
naming the field. Points handed out in batches: 200 cheap points on 2
groups, cancelled and resumed, give the 1-group table; with a dedicated
dispatcher (rank 0 only hands out points) the table is the same, requests
are answered meanwhile and rank 0 sleeps while the group computes."""
import csv
import io
import json
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import h5py  # noqa: E402
import numpy as np  # noqa: E402

import daemon as dmod  # noqa: E402
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "bench"))
from bench_dispatch import cpu_of, ranks_of  # noqa: E402
from harness import Results  # noqa: E402
from protoschema import Proto  # noqa: E402

R = Results("test_sweep_service: sweeps on groups of ranks, identical tables, cancel and resume")
PROTO = Proto()
GEARCTL = os.path.join(dmod.SOURCE_ROOT, "clients", "python", "gearctl")
POINTS = 6
BUSY_POINTS = 2000  # far more than a busy machine computes while a load is sent
SPEC = {"builtin": "planetary_sweep",
        "parameters": [{"path": "driver_rpm", "from": 17000, "to": 25000, "points": POINTS}],
        "settle": 0.0006, "measure": 0.0006, "time_step": 2e-6}


def run_sweep(c, path, groups, **extra):
    """(reply, done event, progress events) of a sweep run to its end."""
    events = []
    args = dict(SPEC, groups=groups, path=path, **extra)
    rid = c.send("sweep", args)
    reply = c.wait_reply(rid, timeout=120)
    done = c.wait_done(rid, on_progress=events.append, timeout=600)
    return reply, done, events


def schema_ok(name, errs):
    R.check(name, not errs, "; ".join(errs[:3]))


def error_of(c, args):
    try:
        c.request("sweep", args, timeout=120)
    except dmod.gearsim.GearsimError as e:
        return e
    return None


def table(path):
    with open(path) as f:
        return f.read()


CHEAP = {"builtin": "pair", "parameters": [{"path": "driver_rpm", "from": 500, "to": 3000, "points": 200}],
         "settle": 0.0, "measure": 1e-5, "time_step": 1e-5}


def dedicated_and_batches(d, c, t2):
    """Batches of cheap points, cancel and resume on 2 groups; the dedicated
    dispatcher's table, its answers and its sleep."""
    _, done_a, ev_a = run_sweep(c, "c1", 1, **CHEAP)
    ref = table(d.path("c1.csv"))
    R.check("200 cheap points on 1 group: all done, one event each",
            done_a.get("points_done") == 200 and sorted(e["point"] for e in ev_a) == list(range(200)), done_a)
    # 2 groups, cancelled after the first point, resumed: the 1-group table.
    rid = c.send("sweep", dict(CHEAP, groups=2, path="c2"))
    c.wait_reply(rid)
    while True:
        ev = c.next_event(10.0)
        if ev is None or (ev.get("type") == "progress" and ev.get("parent_id") == rid):
            break
    c.cancel()
    done_b = c.wait_done(rid, timeout=120)
    k = done_b.get("points_done", -1)
    R.check("batched sweep cancelled: the finished points kept",
            0 <= k <= 200 and len(table(d.path("c2.csv")).splitlines()) == k + 1, done_b)
    if k < 200:
        before = {int(r.split(",")[0]) for r in table(d.path("c2.csv")).splitlines()[1:]}
        _, done_c, ev_c = run_sweep(c, "c2", 2, resume=True, **CHEAP)
        R.check("resumed on 2 groups: the missing points, once each",
                done_c.get("computed") == 200 - k and sorted(e["point"] for e in ev_c) ==
                sorted(set(range(200)) - before), done_c)
    R.check("cheap points on 2 groups, cancelled and resumed: the 1-group table", table(d.path("c2.csv")) == ref)
    # A dedicated dispatcher: groups default to the ranks but rank 0.
    rid = c.send("sweep", dict(SPEC, dispatcher="dedicated", path="dd"))
    reply = c.wait_reply(rid, timeout=120)
    schema_ok("dedicated sweep reply validates", PROTO.errors("results/sweep.json", reply))
    st = c.status()
    done = c.wait_done(rid, timeout=600)
    R.check("dedicated dispatcher: 1 group on 2 ranks, status answered meanwhile",
            reply.get("dispatcher") == "dedicated" and reply.get("groups") == 1 and
            (st.get("sweep") or {}).get("parent_id") in (rid, None), (reply, st.get("sweep")))
    R.check("dedicated dispatcher: the same table", done.get("points_done") == POINTS and table(d.path("dd.csv")) == t2,
            done)
    # Rank 0 sleeps while the group computes: on a busy machine a spinning
    # rank 0 would get as much CPU as the computing rank 1.
    pids = ranks_of(d)
    cpu0 = [cpu_of(p) for p in pids]
    long = dict(SPEC, settle=0.01, measure=0.01, dispatcher="dedicated", path="dl",
                parameters=[{"path": "driver_rpm", "from": 17000, "to": 25000, "points": 12}])
    rid = c.send("sweep", long)
    c.wait_reply(rid, timeout=120)
    done = c.wait_done(rid, timeout=900)
    cpu = [cpu_of(p) - c0 for p, c0 in zip(pids, cpu0)]
    R.check(f"dedicated rank 0 sleeps while the group computes (CPU s rank 0 {cpu[0]:.2f}, rank 1 {cpu[1]:.2f})",
            done.get("points_done") == 12 and len(cpu) == 2 and cpu[0] < 0.35 * cpu[1], (cpu, done))


def run():
    with dmod.Daemon(ranks=2) as d, d.client(timeout=60) as c:
        c.subscribe()
        # Bad input, each refused with the field named.
        for args, field in (
                ({"builtin": "planetary_sweep"}, "args.parameters"),
                (dict(SPEC, parameters=[{"path": "loads[7].moment", "values": [1, 2]}]), "args.parameters[0].path"),
                (dict(SPEC, parameters=[{"path": "driver_rpm", "from": 1, "to": 2}]), "args.parameters[0].points"),
                (dict(SPEC, groups=3), "args.groups"),
                (dict(SPEC, mesh="nope"), "args.mesh"),
                (dict(SPEC, settle=-1), "args.settle"),
                (dict(SPEC, path="../x"), "args.path"),
                (dict(SPEC, parameters=[{"path": "bodies[0].inertia", "values": [1e-4, -1.0]}]), "args.parameters"),
                (dict(SPEC, resume=True, path="none"), "args.resume"),
                (dict(SPEC, dispatcher="rank0"), "args.dispatcher"),
                (dict(SPEC, dispatcher="dedicated", groups=2), "args.groups")):
            e = error_of(c, args)
            R.check(f"refused naming {field}", e is not None and e.field == field,
                    f"{e.code}: {e.field}: {e}" if e else "accepted")
        # The same sweep at 1 group of 2 ranks and at 2 groups of 1 rank.
        reply1, done1, ev1 = run_sweep(c, "g1", 1)
        schema_ok("sweep reply validates", PROTO.errors("results/sweep.json", reply1))
        reply2, done2, ev2 = run_sweep(c, "g2", 2)
        R.check("both sweeps complete", done1.get("points_done") == POINTS and done2.get("points_done") == POINTS,
                (done1, done2))
        R.check("groups as asked", done1.get("groups") == 1 and done2.get("groups") == 2)
        R.check("one progress event per point", sorted(e["point"] for e in ev1) == list(range(POINTS)) and
                sorted(e["point"] for e in ev2) == list(range(POINTS)), [e.get("point") for e in ev2])
        for ev in ev1[:2] + ev2[:2] + [done1, done2]:
            schema_ok(f"{ev['type']} event validates", PROTO.event_errors(ev))
        t1, t2 = table(d.path("g1.csv")), table(d.path("g2.csv"))
        R.check("tables at 1 and 2 groups are byte-identical", t1 == t2 and len(t1.splitlines()) == POINTS + 1,
                t1[:300] + " | " + t2[:300])
        rows = list(csv.DictReader(io.StringIO(t2)))
        R.check("balance at round-off at every point", all(float(r["balance_rel"]) < 1e-9 for r in rows),
                [r["balance_rel"] for r in rows])
        R.check("mean sun speed is the point's driver speed (0.1%)",
                all(abs(float(r["rpm_sun"]) / float(r["driver_rpm"]) - 1) < 1e-3 for r in rows))
        R.check("progress values equal the table's row",
                all(abs(e["values"]["dte_rms_um"] - float(rows[e["point"]]["dte_rms_um"])) == 0 for e in ev2))
        with h5py.File(d.path("g1.h5"), "r") as a, h5py.File(d.path("g2.h5"), "r") as b:
            same = all(np.array_equal(a["sweep"][k][()], b["sweep"][k][()], equal_nan=True) for k in reply1["columns"])
            R.check("HDF5 tables equal, one dataset per column", same and list(a["sweep"]["point"][()]) == list(range(POINTS)))
        # While a sweep runs: status shows it, engine commands wait. A sweep
        # of many points, so that it cannot end before the load is read (six
        # points can, on a busy machine); cancelled once checked.
        many = dict(SPEC, groups=1, path="g_busy",
                    parameters=[dict(SPEC["parameters"][0], points=BUSY_POINTS)])
        busy = c.send("sweep", many)
        c.wait_reply(busy)
        st = c.status()
        schema_ok("status during a sweep validates", PROTO.errors("results/status.json", st))
        R.check("status shows the sweep", (st.get("sweep") or {}).get("parent_id") == busy, st.get("sweep"))
        try:
            c.load(builtin="pair")
            R.check("load refused while a sweep runs", False, "accepted")
        except dmod.gearsim.GearsimError as e:
            R.check("load refused while a sweep runs", e.code == "wrong_state", e)
        c.cancel()
        busy_done = c.wait_done(busy, timeout=120)
        R.check("the long sweep ends cancelled", busy_done.get("cancelled") is True, busy_done)
        rid = c.send("sweep", dict(SPEC, groups=1, path="g3"))
        c.wait_reply(rid)
        # Cancel after the first point, then resume: only the rest computed.
        first = []
        while not first:
            ev = c.next_event(5.0)
            if ev and ev.get("type") == "progress" and ev.get("parent_id") == rid:
                first.append(ev)
        c.cancel()
        done3 = c.wait_done(rid, timeout=120)
        k = done3.get("points_done", -1)
        # On a fast machine the 6 points can all finish before the cancel is
        # read (a lumped point takes a few ms): then the done event says not
        # cancelled and the table is whole; either way nothing finished is lost.
        raced = done3.get("cancelled") is False and k == POINTS
        R.check("cancelled sweep keeps its finished points (or finished before the cancel)",
                (raced or (done3.get("cancelled") is True and 1 <= k <= POINTS)) and
                len(table(d.path("g3.csv")).splitlines()) == k + 1, done3)
        if k < POINTS:
            e = error_of(c, dict(SPEC, groups=2, path="g3"))
            R.check("an unfinished sweep is not overwritten", e is not None and e.field == "args.resume", e)
            _, done4, ev4 = run_sweep(c, "g3", 2, resume=True)
            R.check(f"resume computes only the {POINTS - k} missing points",
                    done4.get("computed") == POINTS - k and done4.get("resumed") == k and len(ev4) == POINTS - k,
                    done4)
        else:
            R.note("the sweep finished before the cancel arrived; resume not exercised")
        R.check("the resumed table is the uninterrupted one", table(d.path("g3.csv")) == t2)
        dedicated_and_batches(d, c, t2)
        # The Slurm array, task by task without Slurm, and its collect step.
        with tempfile.TemporaryDirectory() as td:
            spec = os.path.join(td, "spec.json")
            with open(spec, "w") as f:
                json.dump(SPEC, f)
            env = dict(os.environ, GEARSIM_SWEEP=os.path.join(dmod.BUILD_ROOT, "src", "tools", "gearsim-sweep"))
            script = os.path.join(dmod.SOURCE_ROOT, "deploy", "sweep_array.slurm")
            ok = True
            for i in range(3):
                r = subprocess.run([script, spec, os.path.join(td, "out")], env=dict(
                    env, SLURM_ARRAY_TASK_ID=str(i), SLURM_ARRAY_TASK_COUNT="3"), capture_output=True, text=True)
                ok = ok and r.returncode == 0
            r = subprocess.run([script, spec, os.path.join(td, "out")], env=env, capture_output=True, text=True)
            R.check("array tasks and collect step succeed", ok and r.returncode == 0, r.stderr[-500:])
            if r.returncode == 0:
                srows = list(csv.DictReader(io.StringIO(table(os.path.join(td, "out", "sweep.csv")))))
                worst = max(abs(float(a[k]) - float(b[k])) / max(abs(float(b[k])), 1e-300)
                            for a, b in zip(srows, rows) for k in rows[0] if b[k] not in ("", None))
                R.check(f"Slurm-array table equals the daemon's (largest relative difference {worst:.1e})",
                        len(srows) == POINTS and worst < 1e-12)
            os.remove(os.path.join(td, "out", "part-1.csv"))
            r = subprocess.run([script, spec, os.path.join(td, "out")], env=env, capture_output=True, text=True)
            R.check("collect fails naming the missing points", r.returncode != 0 and "missing points: 1,4" in r.stderr,
                    r.stderr[-300:])
        # gearctl drives the job.
        r = subprocess.run([sys.executable, GEARCTL, "--connection-file", d.conn_file, "sweep", "builtin:planetary_sweep",
                            "--from", "17000", "--to", "25000", "--points", str(POINTS), "--settle", "0.0006",
                            "--measure", "0.0006", "--time-step", "2e-6", "--groups", "2", "--path", "g5", "--json"],
                           capture_output=True, text=True)
        out = json.loads(r.stdout) if r.returncode == 0 else {}
        R.check("gearctl sweep drives the daemon's job", r.returncode == 0 and len(out.get("points", [])) == POINTS and
                table(d.path("g5.csv")) == t2, r.stderr[-500:])


R.guard("sweep service", run)
R.finish()
