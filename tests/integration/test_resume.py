#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Automatic checkpoints, kill-and-resume, disk full while recording, scene
size limits (docs/RELIABILITY.md).

* kill-and-resume: a recorded advance with outputs.checkpoint_every is killed
  (SIGKILL to the daemon's whole process group) at a random moment after the
  first autosave; gearsimd --resume on the same data directory continues it
  to its target step. The final state equals an uninterrupted run's bit for
  bit, and the record equals the uninterrupted run's record: no row lost, no
  row twice, steps strictly increasing without a gap. Scenes: `pair` (rigid,
  one rank) and `elastic_pair` (elastic bodies on two ranks, field snapshots),
  `contact_drive` with both gears reduced (bodies[i].reduction, two ranks).
  The seed is printed; GEARSIM_RESUME_SEED replays it.
* disk full: RLIMIT_FSIZE on the daemon's processes makes record writes fail
  (EFBIG, SIGXFSZ ignored): one error event, status.recording null, the
  advance goes on, and its state equals a run without recording.
* client limit: --max-clients 3 serves three clients and refuses a fourth.
* size limits: refine 6 on a large elastic gear is refused at load naming
  the field, at once; --max-scene-mb refuses a scene above it naming the
  largest elastic body's mesh, and is reported in hello.limits."""
import os
import shutil
import signal
import sys
import tempfile
import time

os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import h5py  # noqa: E402
import numpy as np  # noqa: E402

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results, json_diff, snap  # noqa: E402

R = Results("test_resume: autosave, kill and --resume, disk full, size limits")
RNG = R.seeded_rng("GEARSIM_RESUME_SEED")


def read_record(path):
    """Every dataset of the record, by path, as numpy arrays."""
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]
        f.visititems(visit)
    return out


def same_array(a, b):
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def session_of(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            stat = f.read()
        return int(stat[stat.rindex(")") + 2:].split()[3])
    except (OSError, ValueError, IndexError):
        return None


def wait_until_done(c, target, timeout):
    """Poll status until the advance is over; the final status."""
    deadline = time.monotonic() + timeout
    while True:
        st = c.status()
        if st.get("advance") is None:
            return st
        if time.monotonic() > deadline:
            raise TimeoutError(f"advance not done after {timeout:g} s: {st.get('step')} of {target}")
        time.sleep(0.2)


def reference(scene, ranks, steps):
    with dmod.Daemon(ranks=ranks) as d:
        with d.client(timeout=30.0) as c:
            c.load(scene=scene)
            c.record("rec.h5")
            t0 = time.monotonic()
            c.advance(steps=steps, timeout=900)
            wall = time.monotonic() - t0
            final = snap(c)
            c.record(stop=True)
            R.check("reference: no autosave.h5 left after a completed advance",
                    not os.path.exists(d.path("autosave.h5")))
            return final, read_record(d.path("rec.h5")), wall


def kill_and_resume(label, scene, ranks, steps):
    every = scene["outputs"]["checkpoint_every"]
    rec_every = scene["outputs"]["record_every"]
    ref, ref_rec, wall = reference(scene, ranks, steps)
    R.note(f"{label}: uninterrupted {steps} steps in {wall:.2f} s")
    tmp = tempfile.mkdtemp(prefix="gearsim-resume-")
    try:
        d1 = dmod.Daemon(ranks=ranks, data_dir=tmp).start()
        auto = os.path.join(tmp, "autosave.h5")
        with d1.client(timeout=30.0) as c:
            c.load(scene=scene)
            c.record("rec.h5")
            adv = c.advance(steps=steps, wait=False)
            pid = adv["id"]
            deadline = time.monotonic() + 300
            while not os.path.exists(auto):
                if time.monotonic() > deadline:
                    raise TimeoutError("no autosave.h5 within 300 s")
                time.sleep(0.005)
            # Kill at a random step of the remaining run: poll for it (a
            # delay computed from the measured rate overshoots on a machine
            # whose load changes during the run).
            st = c.status()
            target = st["step"] + int(RNG.uniform(0.0, 0.7) * (steps - st["step"]))
            t_kill = time.monotonic()
            while st.get("advance") is not None and st["step"] < target:
                time.sleep(0.005)
                st = c.status()
            delay = time.monotonic() - t_kill
        running = st.get("advance") is not None
        sess = d1.proc.pid
        d1.kill()
        d1_left = [p for p in os.listdir("/proc") if p.isdigit() and session_of(int(p)) == sess]
        R.check(f"{label}: no process of the killed daemon left", not d1_left, d1_left)
        R.check(f"{label}: killed while the advance ran (after {delay:.3f} s, near step {st['step']} "
                f"of {steps})", running and st["step"] < steps, st.get("step"))
        with h5py.File(auto, "r") as f:
            cp_step = int(f.attrs["step"])
            snap_len = f["snapshot"].shape[0] if "snapshot" in f else 0
            g = f["autosave"]
            info = {k: (g.attrs[k].decode() if isinstance(g.attrs[k], bytes) else g.attrs[k].item())
                    for k in g.attrs}
        R.note(f"{label}: last autosave at step {cp_step}: {info}")
        R.check(f"{label}: autosave at a chunk boundary at or after a multiple of {every}",
                cp_step >= every and cp_step < steps, cp_step)
        R.check(f"{label}: autosave names the advance and the record",
                info.get("parent_id") == pid and info.get("target_step") == steps and
                info.get("start_step") == 0 and info.get("record") == "rec.h5" and info.get("record_rows", 0) >= 1,
                info)
        R.check(f"{label}: autosave.h5 holds the snapshot ({snap_len} bytes)", snap_len > 0, snap_len)

        t0 = time.monotonic()
        with dmod.Daemon(ranks=ranks, data_dir=tmp, resume=True) as d2:
            with d2.client(timeout=30.0) as c:
                st0 = c.status()
                adv = st0.get("advance")
                R.check(f"{label}: --resume: the advance runs again at once with its parent id (or is "
                        "already done)", (adv is not None and adv.get("parent_id") == pid and
                                          adv.get("target_step") == steps) or
                        (adv is None and st0.get("step") == steps), st0.get("advance"))
                st = wait_until_done(c, steps, 900)
                R.note(f"{label}: resumed from step {cp_step} and finished in {time.monotonic() - t0:.2f} s "
                       "(restart included)")
                R.check(f"{label}: resumed advance reached its target step {steps}", st.get("step") == steps,
                        st.get("step"))
                got = snap(c)
                R.check(f"{label}: final state equals the uninterrupted run's, bit for bit", got == ref,
                        "; ".join(json_diff(got, ref))[:1500])
                c.record(stop=True)
                R.check(f"{label}: autosave.h5 removed once the advance completed", not os.path.exists(auto))
            rec = read_record(d2.path("rec.h5"))
        steps_col = rec.get("telemetry/step")
        ok = steps_col is not None and len(steps_col) > 1
        R.check(f"{label}: record has telemetry rows", ok)
        if ok:
            dif = np.diff(steps_col)
            R.check(f"{label}: record steps strictly increasing, no gap (every {rec_every}), "
                    f"{len(steps_col)} rows up to step {steps_col[-1]}",
                    np.all(dif == rec_every) and steps_col[0] == 0 and steps_col[-1] == steps,
                    (steps_col[:3], steps_col[-3:], np.unique(dif)))
        keys = sorted(ref_rec)
        R.check(f"{label}: record has the same datasets as the uninterrupted run's", sorted(rec) == keys,
                (sorted(set(rec) ^ set(keys))))
        bad = [k for k in keys if k in rec and not same_array(rec[k], ref_rec[k])]
        R.check(f"{label}: every dataset of the record equals the uninterrupted run's bit for bit "
                f"({len(keys)} datasets)", not bad,
                [(k, rec[k].shape, ref_rec[k].shape) for k in bad][:6])
        fields = [k for k in keys if k.startswith("fields/") and k.endswith("/step")]
        if scene["outputs"].get("fields_every"):
            R.check(f"{label}: field frames recorded ({', '.join(f'{k}: {len(rec[k])}' for k in fields)})",
                    fields and all(len(rec[k]) == steps // scene["outputs"]["fields_every"] for k in fields),
                    {k: list(rec[k]) for k in fields})
    finally:
        if os.environ.get("GEARSIM_KEEP_TMP") != "1":
            shutil.rmtree(tmp, ignore_errors=True)


def resume_pair():
    scene = dmod.load_scene("pair")
    scene["outputs"] = {"telemetry_every": 50, "record_every": 10, "checkpoint_every": 20000}
    kill_and_resume("pair", scene, 1, 1000000)


def resume_elastic():
    """The elastic pair on its default mesh (curved quadratic elements,
    mesh.order 2): checkpoint and Triangle_6 field frames bit for bit."""
    scene = dmod.load_scene("elastic_pair")
    scene["outputs"] = {"telemetry_every": 20, "record_every": 5, "fields_every": 100, "checkpoint_every": 200}
    kill_and_resume("elastic_pair order 2", scene, 2, 1000)


def resume_elastic_linear():
    """The same with linear triangles (mesh.order 1, the cheaper setting)."""
    scene = dmod.load_scene("elastic_pair")
    for b in scene["bodies"]:
        if b.get("model") == "elastic":
            b["mesh"] = dict(b.get("mesh", {}), order=1)
    scene["outputs"] = {"telemetry_every": 20, "record_every": 5, "fields_every": 100, "checkpoint_every": 200}
    kill_and_resume("elastic_pair order 1", scene, 2, 3000)


def disk_full():
    scene = dmod.load_scene("pair")
    scene["outputs"] = {"telemetry_every": 50, "record_every": 1}
    steps = 60000
    limit = 256 * 1024
    with dmod.Daemon(ranks=1, fsize=limit) as d:
        with d.client(timeout=30.0) as c:
            c.load(scene=scene)
            c.record("full.h5")
            errors = []
            t0 = time.monotonic()
            done = c.advance(steps=steps, timeout=600,
                             on_event=lambda ev: errors.append(ev) if ev.get("type") == "error" else None)
            R.note(f"disk full: {steps} steps in {time.monotonic() - t0:.2f} s; errors: "
                   f"{[e.get('message') for e in errors]}")
            R.check("disk full: one error event (io_error) naming the record", len(errors) == 1 and
                    errors[0].get("code") == "io_error" and "full.h5" in errors[0].get("message", ""), errors)
            R.check("disk full: the advance completed", done.get("steps") == steps and not done.get("error"), done)
            st = c.status()
            R.check("disk full: status.recording is null", st.get("recording") is None, st.get("recording"))
            got = snap(c)
            size = os.path.getsize(d.path("full.h5"))
            R.check(f"disk full: the record stayed within the limit ({size} <= {limit} bytes)", size <= limit, size)
            # still serving: the same run without recording gives the same state
            c.unload()
            c.load(scene=scene)
            c.advance(steps=steps, timeout=600)
            ref = snap(c)
            R.check("disk full: state equals a run without recording, bit for bit", got == ref,
                    "; ".join(json_diff(got, ref))[:1500])
            R.check("disk full: daemon still answers hello", c.hello().get("protocol") == 1)


def big_gear_scene(refine):
    scene = dmod.load_scene("elastic_pair")
    scene["bodies"][1]["teeth"] = 120
    scene["bodies"][1]["hub_radius_mm"] = 60
    scene["joints"][1]["centre_mm"] = [175.0, 0]
    scene["bodies"][1]["mesh"] = {"refine": refine}
    return scene


def size_limits():
    with dmod.Daemon(ranks=1) as d:
        lim = d.hello.get("limits", {})
        R.check("hello.limits.max_scene_mb = 4096 by default", lim.get("max_scene_mb") == 4096, lim)
        with d.client(timeout=30.0) as c:
            t0 = time.monotonic()
            try:
                c.load(scene=big_gear_scene(6))
                R.check("refine 6 on a 120-tooth elastic gear refused", False, "loaded")
            except gearsim.GearsimError as e:
                dt = time.monotonic() - t0
                R.note(f"refused in {dt * 1000:.1f} ms: {e.code} {e.field}: {e}")
                R.check("refine 6 on a 120-tooth elastic gear refused: too_large, field "
                        "args.scene.bodies[1].mesh.refine", e.code == "too_large" and
                        e.field == "args.scene.bodies[1].mesh.refine", (e.code, e.field))
                R.check("refused at once (< 1 s, nothing meshed)", dt < 1.0, dt)
            try:
                c.request("submit", {"scene": big_gear_scene(6), "duration": 0.01})
                R.check("submit of the same scene refused", False)
            except gearsim.GearsimError as e:
                R.check("submit of the same scene refused naming args.scene.bodies[1].mesh.refine",
                        e.code == "too_large" and e.field == "args.scene.bodies[1].mesh.refine", (e.code, e.field))
            r = c.load(scene=dmod.load_scene("elastic_pair"))
            R.check("elastic_pair still loads under the default limit", r.get("dofs", 0) > 0, r)
            R.check("status: loaded", c.status().get("state") == "loaded")
    with dmod.Daemon(ranks=1, extra_args=["--max-scene-mb", "16"]) as d:
        R.check("--max-scene-mb 16 in hello.limits", d.hello.get("limits", {}).get("max_scene_mb") == 16,
                d.hello.get("limits"))
        with d.client(timeout=30.0) as c:
            try:
                c.load(scene=dmod.load_scene("elastic_pair"))
                R.check("--max-scene-mb 16: elastic_pair refused", False, "loaded")
            except gearsim.GearsimError as e:
                R.note(f"--max-scene-mb 16: {e}")
                R.check("--max-scene-mb 16: elastic_pair refused: too_large naming the wheel's mesh "
                        "(args.scene.bodies[1].mesh)", e.code == "too_large" and
                        e.field == "args.scene.bodies[1].mesh", (e.code, e.field))
            r = c.load(scene=dmod.load_scene("pair"))
            R.check("--max-scene-mb 16: the rigid pair loads", r.get("dofs", 0) > 0, r)


def record_limit():
    """--max-record-mb 1: the recording stops with an error event at the
    limit, the run goes on, hello reports the limit."""
    scene = dmod.load_scene("pair")
    scene["outputs"] = {"telemetry_every": 50, "record_every": 1}
    steps = 60000
    with dmod.Daemon(ranks=1, extra_args=("--max-record-mb", "1")) as d:
        with d.client(timeout=30.0) as c:
            R.check("--max-record-mb 1: hello reports it",
                    c.hello().get("limits", {}).get("max_record_mb") == 1, c.hello().get("limits"))
            c.load(scene=scene)
            c.record("big.h5")
            errors = []
            done = c.advance(steps=steps, timeout=600,
                             on_event=lambda ev: errors.append(ev) if ev.get("type") == "error" else None)
            R.check("record limit: one error event naming the limit", len(errors) == 1 and
                    "record size limit" in errors[0].get("message", ""), errors)
            R.check("record limit: the advance completed", done.get("steps") == steps and not done.get("error"), done)
            R.check("record limit: status.recording is null", c.status().get("recording") is None)
            size = os.path.getsize(d.path("big.h5"))
            R.note(f"record limit: the record stopped at {size} bytes")
            R.check("record limit: the file is near the limit (one flush past it at most)",
                    1048576 < size < 4 * 1048576, size)


def client_limit():
    """--max-clients 3: the harness's start-up probe and two clients are
    served (a client counts until 60 s of silence, connected or not), a
    fourth is answered too_large naming the option, the others still work,
    hello reports it."""
    with dmod.Daemon(ranks=1, extra_args=("--max-clients", "3")) as d:
        with d.client(timeout=10.0) as a, d.client(timeout=10.0) as b:
            R.check("--max-clients 3: hello reports it", a.hello().get("limits", {}).get("max_clients") == 3)
            R.check("--max-clients 3: the third client is served", "limits" in b.hello())
            with d.client(timeout=10.0) as c:
                try:
                    c.hello()
                    R.check("--max-clients 3: a fourth client is refused", False, "it was served")
                except gearsim.GearsimError as e:
                    R.check("--max-clients 3: a fourth client gets too_large naming --max-clients",
                            e.code == "too_large" and "--max-clients" in str(e), (e.code, str(e)))
            R.check("--max-clients 3: the admitted ones still work", "limits" in a.hello() and "limits" in b.hello())


def resume_reduced():
    """contact_drive with both gears reduced (bodies[i].reduction, the static
    residual at 30 kHz, 2 % damping) on two ranks: modal and residual state,
    the residual's support order and the energy books come back bit for bit
    in the new processes (docs/explanation/elastic_body.md "Reduced elastic body", "Checkpoints")."""
    scene = dmod.load_scene("contact_drive")
    for b in scene["bodies"]:
        b["material"] = dict(b.get("material", {}), damping_ratio=0.02, damping_hz=9200)
        b["reduction"] = {"f_max_hz": 3e4, "residual": "static"}
    scene["numerics"]["contact"] = "closure_energy"
    scene["outputs"] = {"telemetry_every": 50, "record_every": 10, "fields_every": 250, "checkpoint_every": 250}
    kill_and_resume("contact_drive reduced", scene, 2, 2000)


CASES = [("scene size limits", size_limits), ("record size limit", record_limit), ("client limit", client_limit), ("kill and resume: pair", resume_pair),
         ("kill and resume: elastic_pair", resume_elastic),
         ("kill and resume: elastic_pair order 1", resume_elastic_linear), ("disk full while recording", disk_full),
         ("kill and resume: contact_drive reduced", resume_reduced)]
ONLY = os.environ.get("GEARSIM_RESUME_ONLY")   # e.g. "pair" to run one case while debugging
for name, fn in CASES:
    if not ONLY or ONLY in name:
        R.guard(name, fn)
R.finish()
