#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""HDF5 record, checkpoint/restore and fetch.

* record during a run: the file has the documented layout and its time series
  agree with the telemetry events;
* checkpoint at step N, continue to 2N; restore, continue to 2N again: the two
  final states (and the telemetry of both continuations) are identical bit for bit;
* fetch the record in chunks: the bytes equal the file in the data directory."""
import hashlib
import json
import os
import sys

os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import h5py  # noqa: E402
import numpy as np  # noqa: E402

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results, json_diff, replay_after_restore, snap  # noqa: E402

R = Results("test_record: HDF5 record, checkpoint/restore, fetch")
N = 1500
COLUMNS = ["kinetic", "potential", "total", "work_in", "dissipated", "balance_residual", "contact_work"]


def attr_text(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.ndarray) and v.shape == ():
        v = v.item()
        return v.decode() if isinstance(v, bytes) else v
    return v


def names(v):
    v = attr_text(v)
    if isinstance(v, str):
        return json.loads(v)
    return [x.decode() if isinstance(x, bytes) else str(x) for x in v]


def check_layout(path, scene, tel):
    with h5py.File(path, "r") as f:
        R.check("record: file attribute 'scene' is JSON of the scene",
                "scene" in f.attrs and isinstance(json.loads(attr_text(f.attrs["scene"])), dict),
                list(f.attrs))
        if "scene" in f.attrs:
            s = json.loads(attr_text(f.attrs["scene"]))
            R.check("record: scene attribute names the scene's bodies",
                    [b["name"] for b in s.get("bodies", [])] == [b["name"] for b in scene["bodies"]], s.get("bodies"))
        R.check("record: file attribute 'gearsim_version'", "gearsim_version" in f.attrs, list(f.attrs))
        R.check("record: group /telemetry", "telemetry" in f, list(f))
        if "telemetry" not in f:
            return
        g = f["telemetry"]
        need = ["time", "step", "energy", "angle", "omega", "mesh_force"]
        R.check("record: datasets " + ", ".join(need), all(k in g for k in need), list(g))
        if not all(k in g for k in need):
            return
        n = g["time"].shape[0]
        nb, nm = len(scene["bodies"]), len(scene.get("meshes", []))
        R.check(f"record: {n} rows", n > 0)
        R.check("record: time is (n)", g["time"].shape == (n,), g["time"].shape)
        R.check("record: step is (n) int64", g["step"].shape == (n,) and g["step"].dtype == np.int64,
                (g["step"].shape, g["step"].dtype))
        R.check("record: energy is (n x 7)", g["energy"].shape == (n, 7), g["energy"].shape)
        cols = names(g["energy"].attrs["columns"]) if "columns" in g["energy"].attrs else None
        R.check("record: energy attribute columns", cols == COLUMNS, cols)
        R.check(f"record: angle is (n x {nb})", g["angle"].shape == (n, nb), g["angle"].shape)
        R.check(f"record: omega is (n x {nb})", g["omega"].shape == (n, nb), g["omega"].shape)
        R.check(f"record: mesh_force is (n x {nm})", g["mesh_force"].shape == (n, nm), g["mesh_force"].shape)
        bodies = names(g.attrs["bodies"]) if "bodies" in g.attrs else None
        R.check("record: attribute bodies", bodies == [b["name"] for b in scene["bodies"]], bodies)
        meshes = names(g.attrs["meshes"]) if "meshes" in g.attrs else None
        R.check("record: attribute meshes", meshes == [m["name"] for m in scene.get("meshes", [])], meshes)
        steps = g["step"][()]
        R.check("record: steps increase", np.all(np.diff(steps) > 0), steps[:10])
        t = g["time"][()]
        R.check("record: time increases", np.all(np.diff(t) > 0), t[:10])
        # consistency with telemetry (record_every = telemetry_every by default)
        row = {int(s): i for i, s in enumerate(steps)}
        missing = [ev["step"] for ev in tel if ev["step"] not in row]
        R.check(f"record: every telemetry step is a row ({len(tel)} telemetry events)", not missing, missing[:10])
        worst, exact = 0.0, True
        for ev in tel:
            i = row.get(ev["step"])
            if i is None:
                continue
            rec = [t[i]] + list(g["energy"][i]) + list(g["omega"][i]) + list(g["angle"][i])
            ref = [ev["time"]] + [ev["energy"][k] for k in COLUMNS] + [b["omega"] for b in ev["bodies"]] + \
                  [b["angle"] for b in ev["bodies"]]
            for a, b in zip(rec, ref):
                if float(a) != float(b):
                    exact = False
                    worst = max(worst, abs(a - b) / max(abs(a), abs(b), 1e-300))
        R.check(f"record: time, energy, omega, angle agree with telemetry (worst rel. diff {worst:.2e})",
                worst <= 1e-12, worst)
        R.note(f"record rows equal telemetry bit for bit: {exact}")
        if tel and nm:
            i = row.get(tel[-1]["step"])
            if i is not None:
                f_rec = list(np.atleast_1d(g["mesh_force"][i]))
                f_tel = [m["force"] for m in tel[-1]["meshes"]]
                R.check("record: mesh_force agrees with telemetry", np.allclose(f_rec, f_tel, rtol=1e-12, atol=0),
                        (f_rec, f_tel))


def names_file(value, rel):
    """The path as given, or (a leak of the server's layout, but usable) absolute and ending with it."""
    return isinstance(value, str) and (value == rel or value.endswith("/" + rel))


def strip(tel):
    return [{k: ev[k] for k in ("step", "time", "energy", "bodies", "meshes") if k in ev} for ev in tel]


def main():
    scene = dmod.load_scene("pair")
    with dmod.Daemon(ranks=2) as d:
        with d.client() as c:
            c.load(scene=scene)
            r = c.record("rec.h5")
            R.check("record: reply names the file", names_file(r.get("recording"), "rec.h5"), r)
            if r.get("recording") != "rec.h5":
                R.note(f"record replies with {r.get('recording')!r}, not the path as given ('rec.h5')")
            st = c.status()
            R.check("status shows the recording", names_file(st.get("recording"), "rec.h5"), st.get("recording"))
            tel = []
            c.advance(steps=2 * N, on_telemetry=tel.append, timeout=600)
            R.check("telemetry without gaps", c.gaps == 0, c.gaps)
            r = c.record(stop=True)
            R.check("record stop: recording null", r.get("recording") is None, r)
            path = d.path("rec.h5")
            R.check("record file exists in the data directory", os.path.exists(path))
            if os.path.exists(path):
                R.guard("record layout", check_layout, path, scene, tel)

            # fetch in chunks (small chunks to exercise offsets) and whole
            if os.path.exists(path):
                with open(path, "rb") as f:
                    local = f.read()
                got = c.fetch("rec.h5", chunk=4096)
                R.check(f"fetch in 4 KiB chunks: {len(got)} bytes equal the file ({len(local)} bytes, "
                        f"{(len(local) + 4095) // 4096} chunks)", got == local,
                        (hashlib.sha1(got).hexdigest(), hashlib.sha1(local).hexdigest()))
                out = os.path.join(d.dir, "fetched.h5")
                n = c.fetch("rec.h5", out)
                with open(out, "rb") as f:
                    R.check("fetch to a file (1 MiB chunks)", n == len(local) and f.read() == local, n)
                r = c.request("fetch", {"path": "rec.h5", "offset": len(local) - 10, "length": 100})
                R.check("fetch past the end: short chunk with eof", r.get("length") == 10 and r.get("eof") is True
                        and r.get("size") == len(local), {k: v for k, v in r.items() if k != "data_b64"})

            # checkpoint / restore, bit for bit
            c.unload()
            c.load(scene=scene)
            c.advance(steps=N, timeout=600)
            cp = c.checkpoint("cp.h5")
            R.check(f"checkpoint at step {N}", cp.get("step") == N and cp.get("path") == "cp.h5", cp)
            R.check("checkpoint file exists", os.path.exists(d.path("cp.h5")))
            at_n = snap(c)
            tel_a = []
            c.advance(steps=N, on_telemetry=tel_a.append, timeout=600)
            a = snap(c)
            r = c.restore("cp.h5")
            R.check(f"restore: back at step {N}", r.get("step") == N and r.get("time") == cp.get("time"), r)
            restored = snap(c)
            R.check("restore: state equals the state at the checkpoint, bit for bit", restored == at_n,
                    "restored vs at checkpoint: " + "; ".join(json_diff(restored, at_n)))
            tel_b = []
            c.advance(steps=N, on_telemetry=tel_b.append, timeout=600)
            b = snap(c)
            R.check(f"state at step {2 * N} identical after restore, bit for bit", a == b, "; ".join(json_diff(a, b)))
            R.check("telemetry of both continuations identical", strip(tel_a) == strip(tel_b) and len(tel_a) > 0,
                    (len(tel_a), len(tel_b)))
            # restore into a freshly loaded scene too
            c.unload()
            c.load(scene=scene)
            c.restore("cp.h5")
            c.advance(steps=N, timeout=600)
            fresh = snap(c)
            R.check("restore into a fresh load gives the same state", fresh == a, "; ".join(json_diff(fresh, a)))
            def cp_is_hdf5():
                with h5py.File(d.path("cp.h5"), "r") as f:
                    R.check("checkpoint is an HDF5 file with the scene attribute", "scene" in f.attrs, list(f.attrs))
            R.guard("checkpoint is an HDF5 file", cp_is_hdf5)


def elastic():
    """Elastic bodies on two ranks: field snapshots with their XDMF file, and
    checkpoint/restore of the bodies' internal states (gathered from their
    owners), bit for bit, through tooth contact."""
    scene = dmod.load_scene("contact_impact")
    scene["outputs"] = {"telemetry_every": 20, "fields_every": 100}
    steps = 600
    with dmod.Daemon(ranks=2) as d:
        with d.client() as c:
            c.load(scene=scene)
            c.record("fields.h5")
            c.advance(steps=steps, timeout=600)
            c.record(stop=True)
            path = d.path("fields.h5")
            with h5py.File(path, "r") as f:
                names = json.loads(attr_text(f["/fields"].attrs["names"]))
                R.check("fields: both elastic gears recorded", names == ["wheel", "pinion"], names)
                for name in names:
                    g = f["/fields/" + name]
                    n = f["/bodies/" + name + "/nodes"].shape[0]
                    R.check(f"fields/{name}: {steps // 100 + 1} frames (the first at step 0 is not "
                            f"gathered: frames at steps 100..{steps})",
                            list(g["step"][:]) == list(range(100, steps + 1, 100)), list(g["step"][:]))
                    R.check(f"fields/{name}: displacement (T, {n}, 3) and von Mises (T, {n})",
                            g["displacement"].shape[1:] == (n, 3) and g["von_mises"].shape[1:] == (n,),
                            (g["displacement"].shape, g["von_mises"].shape))
                    umax = float(abs(g["displacement"][...]).max())
                    vmax = float(g["von_mises"][...].max())
                    R.note(f"fields/{name}: max |u| {umax:.3e} m, max von Mises {vmax:.3e} Pa")
                    R.check(f"fields/{name}: the teeth deform and carry stress after the impacts",
                            umax > 1e-9 and vmax > 1e5, (umax, vmax))
            xmf = os.path.splitext(path)[0] + ".xmf"
            R.check("fields: XDMF side file written", os.path.exists(xmf))

            # the quasi-static stiffness command on the loaded scene
            k = c.request("stiffness", {"mesh": "wheel-pinion", "positions": 6, "path": "k.h5", "wait": True}, timeout=300)
            km = k.get("k", {}).get("mean")
            R.note(f"stiffness: k min/mean/max {k.get('k')} N/(mm um), te {k.get('te_um')} um")
            R.check("stiffness: 6 points, mean mesh stiffness in the steel spur range 8-30 N/(mm um)",
                    len(k.get("points", [])) == 6 and km is not None and 8 < km < 30, k.get("k"))
            with h5py.File(d.path("k.h5"), "r") as f:
                R.check("stiffness: written to HDF5 (/stiffness)", "stiffness" in f, list(f))
            try:
                c.request("stiffness", {"mesh": "nope"})
                R.check("stiffness: unknown mesh refused", False)
            except gearsim.GearsimError as e:
                R.check("stiffness: unknown mesh refused naming args.mesh", e.field == "args.mesh", (e.code, e.field))

            c.unload()
            c.load(scene=scene)
            c.advance(steps=300, timeout=600)
            c.checkpoint("ecp.h5")
            at_n = snap(c)
            c.advance(steps=300, timeout=600)
            a = snap(c)
            c.restore("ecp.h5")
            R.check("elastic restore: state equals the state at the checkpoint, bit for bit", snap(c) == at_n,
                    "; ".join(json_diff(snap(c), at_n)))
            c.advance(steps=300, timeout=600)
            b = snap(c)
            R.check("elastic restore: the continuation is identical bit for bit (internal states restored)",
                    a == b, "; ".join(json_diff(a, b)))

            # the adaptive step's level is part of the checkpoint
            c.unload()
            scene["numerics"] = {"time_step": 1e-5, "adaptive": {"penetration_um": 1.0, "levels": 3}}
            c.load(scene=scene)
            a, b = replay_after_restore(c, "acp.h5", 40, 40)
            R.check("adaptive restore: the continuation is identical bit for bit (step level restored)",
                    a == b, "; ".join(json_diff(a, b)))
            R.check("adaptive: time is exactly step * time_step", b.get("time") == 80 * 1e-5, b.get("time"))


def contact_early():
    """contact_impact checkpointed at step 50 (teeth in contact) and continued
    50 steps, against the same daemon's continuation, for every contact
    treatment, at 1 and 2 ranks: the restored bodies start with empty
    compliance caches and must continue bit for bit."""
    for ranks in (1, 2):
        with dmod.Daemon(ranks=ranks) as d:
            with d.client() as c:
                for mode in ("seed", "closure", "closure_energy"):
                    scene = dmod.load_scene("contact_impact")
                    scene["numerics"]["contact"] = mode
                    c.load(scene=scene)
                    a, b = replay_after_restore(c, f"early_{mode}.h5", 50, 50)
                    R.check(f"contact_impact {mode}, {ranks} rank(s): checkpoint at 50, continuation "
                            "identical bit for bit", a == b, "; ".join(json_diff(a, b)))
                    c.unload()


R.guard("record/checkpoint/fetch against the real daemon", main)
R.guard("elastic fields and checkpoint", elastic)
R.guard("elastic contact: checkpoint at step 50", contact_early)
R.finish()
