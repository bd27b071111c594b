#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Checkpoint files are input (docs/RELIABILITY.md, "Files as input").

A crafted-checkpoint corpus is built from a real checkpoint of the `pair`
scene: the snapshot dataset of another shape (two dimensions, a scalar),
another type (int64, float), a declared size far beyond the file (2 GiB in
a few KB), a chunked layout, non-finite values (time, energies, coordinates,
speeds, body counters), step counts near 2^63 and negative, truncations at
many lengths and trailing bytes, a scene that does not match the state, a
scene above --max-scene-mb, and copies with random bit flips anywhere in
the file. Every file goes through `restore` on a running daemon: each must
be answered (an error naming the problem for every crafted case), the
daemon must stay up, and no reply may carry a non-JSON number (NaN,
Infinity). A subset, turned into automatic checkpoints (plus /autosave
attributes out of range), goes through `gearsimd --resume`: the daemon
starts, reports why it does not resume, and answers. The seed of the flips
is printed; GEARSIM_CKPT_SEED replays it."""
import json
import os
import shutil
import struct
import sys

os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import h5py  # noqa: E402
import numpy as np  # noqa: E402

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results, strict_json  # noqa: E402

R = Results("test_checkpoint_input: crafted checkpoints through restore and --resume")
RNG = R.seeded_rng("GEARSIM_CKPT_SEED")
MAX_SCENE_MB = 64
N_FLIPS = int(os.environ.get("GEARSIM_CKPT_FLIPS", "40"))



class Snap:
    """The engine snapshot's fields (src/engine/engine.c layout)."""

    def __init__(self, b):
        self.magic, self.nc, self.nm = struct.unpack_from("<III", b, 0)
        self.step, = struct.unpack_from("<q", b, 12)
        self.head = list(struct.unpack_from("<5d", b, 20))
        o = 60
        self.qw = list(struct.unpack_from(f"<{2 * self.nc}d", b, o))
        o += 16 * self.nc
        self.mesh = list(struct.unpack_from(f"<{8 * self.nm}d", b, o))
        o += 64 * self.nm
        ns, = struct.unpack_from("<d", b, o)
        o += 8
        self.states = list(struct.unpack_from(f"<{int(ns)}d", b, o))
        o += 8 * int(ns)
        rest = b[o:]
        i = rest.index(b"\0")
        self.scene = rest[:i]
        self.loads = rest[i + 1:-1]

    def pack(self):
        b = struct.pack("<III", self.magic, self.nc, self.nm) + struct.pack("<q", self.step)
        b += struct.pack("<5d", *self.head) + struct.pack(f"<{len(self.qw)}d", *self.qw)
        b += struct.pack(f"<{len(self.mesh)}d", *self.mesh) + struct.pack("<d", float(len(self.states)))
        b += struct.pack(f"<{len(self.states)}d", *self.states)
        return b + self.scene + b"\0" + self.loads + b"\0"


def write_ckpt(path, snapshot=None, raw=None, autosave=None, attrs=True):
    """A checkpoint file: snapshot bytes (or raw(f) makes the dataset)."""
    with h5py.File(path, "w") as f:
        if raw is not None:
            raw(f)
        elif snapshot is not None:
            f.create_dataset("snapshot", data=np.frombuffer(snapshot, dtype=np.uint8))
        if attrs:
            f.attrs["scene"] = np.bytes_(b"{}")
            f.attrs["step"] = np.int64(0)
            f.attrs["time"] = np.float64(0)
        if autosave is not None:
            g = f.create_group("autosave")
            for k, v in autosave.items():
                if k == "field_frames":
                    g.create_dataset(k, data=v)
                elif isinstance(v, str):
                    g.attrs[k] = np.bytes_(v.encode())
                else:
                    g.attrs[k] = v


def corpus(good, big_scene, other_scene):
    """(name, builder(path, autosave)) of every crafted case; each must be refused."""
    cases = []

    def add(name, fn):
        cases.append((name, fn))

    def with_snap(mut):
        def build(path, autosave=None):
            s = Snap(good)
            mut(s)
            write_ckpt(path, s.pack(), autosave=autosave)
        return build

    def with_bytes(b):
        return lambda path, autosave=None: write_ckpt(path, b, autosave=autosave)

    def with_raw(fn):
        return lambda path, autosave=None: write_ckpt(path, raw=fn, autosave=autosave)

    arr = np.frombuffer(good, dtype=np.uint8)
    half = len(good) // 2 * 2
    # shapes and types
    add("shape: two dimensions", with_raw(lambda f: f.create_dataset("snapshot", data=arr[:half].reshape(-1, 2))))
    add("shape: two dimensions, transposed",
        with_raw(lambda f: f.create_dataset("snapshot", data=arr[:half].reshape(2, -1))))
    add("shape: scalar", with_raw(lambda f: f.create_dataset("snapshot", data=np.uint8(7))))
    add("type: int64 values", with_raw(lambda f: f.create_dataset("snapshot", data=arr.astype(np.int64))))
    add("type: float values", with_raw(lambda f: f.create_dataset("snapshot", data=arr.astype(np.float64))))
    add("type: a string", with_raw(lambda f: f.create_dataset("snapshot", data=np.bytes_(good[:200]))))
    add("missing snapshot", with_raw(lambda f: f.create_dataset("other", data=arr)))
    add("empty snapshot", with_raw(lambda f: f.create_dataset("snapshot", shape=(0,), dtype=np.uint8)))
    # sizes: declared far beyond the file
    add("size: 2 GiB declared, nothing stored",
        with_raw(lambda f: f.create_dataset("snapshot", shape=(1 << 31,), dtype=np.uint8)))
    add("size: 2^40 declared, chunked",
        with_raw(lambda f: f.create_dataset("snapshot", shape=(1 << 40,), dtype=np.uint8, chunks=(4096,))))
    add("size: real bytes but chunked and compressed",
        with_raw(lambda f: f.create_dataset("snapshot", data=arr, chunks=(256,), compression="gzip")))
    # values
    for name, idx in (("time", 0), ("work_in", 1), ("dissipated", 2), ("energy0", 3), ("level", 4)):
        for v in (float("nan"), float("inf"), -float("inf")):
            def mut(s, idx=idx, v=v):
                s.head[idx] = v
            add(f"value: {name} = {v}", with_snap(mut))
    add("value: level = 2.5", with_snap(lambda s: s.head.__setitem__(4, 2.5)))
    add("value: level = 1e6", with_snap(lambda s: s.head.__setitem__(4, 1e6)))
    add("value: time negative", with_snap(lambda s: s.head.__setitem__(0, -1.0)))
    add("value: time far from the step count", with_snap(lambda s: s.head.__setitem__(0, 1e6)))
    add("value: coordinate NaN", with_snap(lambda s: s.qw.__setitem__(0, float("nan"))))
    add("value: speed Infinity", with_snap(lambda s: s.qw.__setitem__(len(s.qw) - 1, float("inf"))))
    add("value: mesh force NaN", with_snap(lambda s: s.mesh.__setitem__(0, float("nan"))))
    add("value: mesh active count 1e300", with_snap(lambda s: s.mesh.__setitem__(1, 1e300)))
    add("value: mesh active count -1", with_snap(lambda s: s.mesh.__setitem__(1, -1.0)))
    add("value: mesh impacts 1e20", with_snap(lambda s: s.mesh.__setitem__(4, 1e20)))
    add("value: mesh rows 0.5", with_snap(lambda s: s.mesh.__setitem__(2, 0.5)))
    # counters
    for st in ((1 << 63) - 1, (1 << 63) - 10, 1 << 62, -1, -(1 << 63)):
        add(f"counter: step {st}", with_snap(lambda s, st=st: setattr(s, "step", st)))
    add("counter: coordinates 2^31", with_snap(lambda s: setattr(s, "nc", 1 << 31)))
    add("counter: meshes 2^32-1", with_snap(lambda s: setattr(s, "nm", (1 << 32) - 1)))
    add("magic", with_snap(lambda s: setattr(s, "magic", 0)))
    # consistency with the scene
    add("scene: another scene than the state's", with_snap(lambda s: setattr(s, "scene", other_scene)))
    add("scene: above --max-scene-mb", with_snap(lambda s: setattr(s, "scene", big_scene)))
    add("scene: not JSON", with_snap(lambda s: setattr(s, "scene", b"{not json")))
    add("loads: not an array", with_snap(lambda s: setattr(s, "loads", b"{}")))
    def missing_state(s):
        s.states = [0.0, 0.0, 0.0]
    def drop_state(path, autosave=None):
        s = Snap(good)
        missing_state(s)
        b = s.pack()
        cut = 60 + 16 * s.nc + 64 * s.nm + 8
        write_ckpt(path, b[:cut] + b[cut + 24:], autosave=autosave)
    add("state: declared but missing", drop_state)
    # truncations and trailing bytes
    for n in sorted({0, 1, 11, 12, 19, 20, 59, 60, 61, len(good) // 3, len(good) // 2, len(good) - 2,
                     len(good) - 1}):
        if n == 0:
            continue
        add(f"truncated to {n} bytes", with_bytes(good[:n]))
    add("trailing bytes", with_bytes(good + b"junk"))
    return cases


def restore_case(c, d, name, path, expect_error=True):
    """restore one file; True when the daemon answered as it must."""
    try:
        r = c.request("restore", {"path": path}, timeout=30.0, retries=0)
        ok, err = True, None
    except gearsim.GearsimError as e:
        ok, err = False, e
        r = e.reply if hasattr(e, "reply") else None
    alive = d.alive()
    if expect_error:
        R.check(f"restore refuses: {name}", not ok and alive and err.field == "args.path" and len(str(err)) > 20
                and err.code != "bad_json",
                f"ok={ok} alive={alive} err={err!r}")
    else:
        R.check(f"restore answers: {name}", alive, f"alive={alive}")
    if r is not None and not strict_json(r):
        R.check(f"restore reply is strict JSON: {name}", False, str(r)[:300])
    if ok and alive:
        st = c.request("state", timeout=30.0, retries=0)
        stat = c.request("status", timeout=30.0, retries=0)
        R.check(f"state and status strict JSON after: {name}", strict_json(st) and strict_json(stat), str(st)[:300])
    return alive


def main():
    base = dmod.load_scene("pair")
    elastic = dmod.load_scene("elastic_pair")
    big = json.loads(json.dumps(elastic))
    for b in big["bodies"]:
        if "mesh" in b:
            b["mesh"]["refine"] = 3
    big_text = json.dumps(big, separators=(",", ":")).encode()
    other_text = json.dumps(dmod.load_scene("planetary"), separators=(",", ":")).encode()

    with dmod.Daemon(ranks=1, extra_args=["--max-scene-mb", str(MAX_SCENE_MB)]) as d:
        c = d.client()
        # The big scene is over the limit for load too: the same limit on both paths.
        try:
            c.request("load", {"scene": big}, timeout=60.0)
            R.check("load refuses the scene above --max-scene-mb", False, "loaded")
        except gearsim.GearsimError as e:
            R.check("load refuses the scene above --max-scene-mb", e.code == "too_large", repr(e))
        c.request("load", {"scene": base})
        c.advance(steps=50, wait=True, timeout=120)
        c.request("checkpoint", {"path": "good.h5"})
        with h5py.File(d.path("good.h5"), "r") as f:
            good = f["snapshot"][()].tobytes()
        R.check("the snapshot layout is the one parsed here", Snap(good).pack() == good)
        restore_case(c, d, "the real checkpoint", "good.h5", expect_error=False)
        R.check("the real checkpoint restores", c.request("status")["step"] == Snap(good).step)
        cases = corpus(good, big_text, other_text)
        R.note(f"{len(cases)} crafted checkpoints")
        for i, (name, build) in enumerate(cases):
            p = f"crafted{i}.h5"
            build(d.path(p))
            if not restore_case(c, d, name, p):
                R.note(d.log_tail())
                break
        # random bit flips anywhere in the file
        with open(d.path("good.h5"), "rb") as f:
            raw = f.read()
        for k in range(N_FLIPS):
            b = bytearray(raw)
            for _ in range(RNG.randrange(1, 9)):
                i = RNG.randrange(len(b))
                b[i] ^= 1 << RNG.randrange(8)
            p = f"flip{k}.h5"
            with open(d.path(p), "wb") as f:
                f.write(bytes(b))
            if not restore_case(c, d, f"bit flips #{k}", p, expect_error=False):
                R.note(d.log_tail())
                break
        R.check("the daemon answers after the corpus", c.hello()["protocol"] == 1)

    # --resume: automatic checkpoints built from a subset
    s = Snap(good)
    good_auto = {"parent_id": "a1", "start_step": np.int64(0), "target_step": np.int64(s.step + 100),
                 "record": "", "record_rows": np.int64(0)}
    auto_cases = [(n, b, good_auto) for n, b in corpus(good, big_text, other_text)
                  if n.split(":")[0] in ("shape", "size", "counter", "scene") or n in (
                      "value: time = nan", "value: coordinate NaN", "truncated to 61 bytes", "trailing bytes")]
    for name, bad in (("target_step 2^63-1", {"target_step": np.int64((1 << 63) - 1)}),
                      ("start_step -5", {"start_step": np.int64(-5)}),
                      ("target below start", {"start_step": np.int64(10), "target_step": np.int64(5)}),
                      ("record_rows -1", {"record_rows": np.int64(-1)}),
                      ("start_step an array of 1000", {"start_step": np.arange(1000, dtype=np.int64)}),
                      ("field_frames two-dimensional", {"field_frames": np.zeros((4, 4), dtype=np.int64)}),
                      ("field_frames negative", {"field_frames": np.array([-3], dtype=np.int64)}),
                      ("advance over the step cap", {"target_step": np.int64(1 << 40)})):
        a = dict(good_auto)
        a.update(bad)
        auto_cases.append((f"autosave: {name}", lambda path, autosave=None: write_ckpt(path, good, autosave=autosave), a))
    R.note(f"{len(auto_cases)} crafted automatic checkpoints through --resume")
    for name, build, auto in auto_cases:
        tmp = dmod.tempfile.mkdtemp(prefix="gearsim-ckpt-")
        try:
            build(os.path.join(tmp, "autosave.h5"), auto)
            with dmod.Daemon(ranks=1, data_dir=tmp, resume=True,
                             extra_args=["--max-scene-mb", str(MAX_SCENE_MB)]) as d2:
                c = d2.client()
                st = c.request("status", timeout=30.0)
                log = d2.log_tail()
                R.check(f"--resume refuses: {name}", st["state"] != "running" and "--resume failed:" in log
                        and strict_json(st), f"state={st['state']} log={log[-400:]}")
        except Exception as e:  # noqa: BLE001
            R.check(f"--resume refuses: {name}", False, f"{type(e).__name__}: {e}")
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    # and the real one resumes
    tmp = dmod.tempfile.mkdtemp(prefix="gearsim-ckpt-")
    try:
        write_ckpt(os.path.join(tmp, "autosave.h5"), good, autosave=good_auto)
        with dmod.Daemon(ranks=1, data_dir=tmp, resume=True) as d2:
            st = d2.client().request("status", timeout=30.0)
            R.check("--resume continues the real automatic checkpoint", st["state"] in ("running", "loaded")
                    and "--resume failed" not in d2.log_tail(), f"{st['state']} {d2.log_tail()[-300:]}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    R.finish()


if __name__ == "__main__":
    main()
