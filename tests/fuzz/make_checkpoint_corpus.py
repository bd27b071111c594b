#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Write the seed corpus of the checkpoint fuzz target (fuzz_checkpoint.c)
from real checkpoints: a daemon (the build's gearsimd) loads the `pair` and
`planetary` scenes, advances and writes a checkpoint; each snapshot becomes
seeds with the target's 30-byte header: restore as written, --resume with
an /autosave group, the snapshot two-dimensional, and a declared length
of 2 GiB with nothing stored, and a step count its time does not match.

    tests/fuzz/make_checkpoint_corpus.py     # rewrite tests/fuzz/corpus/checkpoint/
"""
import hashlib
import os
import shutil
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))
os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")

import h5py  # noqa: E402

import daemon as dmod  # noqa: E402


def header(flags, declared, start, target, rows, frames):
    return struct.pack("<BIqqqB", flags, declared, start, target, rows, frames)


def main():
    out = os.path.join(HERE, "corpus", "checkpoint")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    seeds = []
    with dmod.Daemon(ranks=1) as d:
        c = d.client()
        for name in ("pair", "planetary"):
            c.request("load", {"builtin": name} if name in c.hello()["builtin_scenes"] else
                      {"scene": dmod.load_scene(name)})
            c.advance(steps=20, wait=True, timeout=120)
            c.request("checkpoint", {"path": name + ".h5"})
            with h5py.File(d.path(name + ".h5"), "r") as f:
                snap = f["snapshot"][()].tobytes()
            step, = struct.unpack_from("<q", snap, 12)
            seeds.append(header(0, 0, 0, 0, 0, 0) + snap)
            seeds.append(header(64, 0, 0, step + 100, 0, 0) + snap)
            seeds.append(header(64, 0, 0, step + 100, 5, 2) + snap)
            seeds.append(header(1, 0, 0, 0, 0, 0) + snap)
            seeds.append(header(32, 1 << 31, 0, 0, 0, 0) + snap[:64])
            # A step count the stored time does not match: refused after
            # the scene is built, so the refusal must not read what it frees.
            seeds.append(header(0, 0, 0, 0, 0, 0) + snap[:12] + struct.pack("<q", step + 1000) + snap[20:])
    for s in seeds:
        with open(os.path.join(out, hashlib.sha1(s).hexdigest()[:16]), "wb") as f:
            f.write(s)
    print(f"{len(seeds)} seeds in {out}")


if __name__ == "__main__":
    main()
