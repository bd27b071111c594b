#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Files the daemon opens or writes for clients stay in the data directory
and never clobber what they must not (docs/RELIABILITY.md, "File rules"):
a symlink planted at a temporary name is not followed (connection file,
checkpoint), a symlink swapped in for a file while fetches run is never
served, hard links and FIFOs are refused by fetch (the daemon stays
responsive), a checkpoint or record onto the connection file, the lock file
or the record being written is refused. Each refusal names args.path, and
nothing outside the data directory changes."""
import os
import stat
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results, tree_digest, victim_and_data  # noqa: E402

R = Results("test_files: safe opening of client-named and internal files")
SECRET = b"outside the data directory: never served, never changed\n"


def refused(name, fn, *a, words=None, **kw):
    try:
        fn(*a, **kw)
        R.check(f"{name}: refused", False, "accepted")
        return None
    except gearsim.GearsimError as e:
        ok = e.field == "args.path" and e.code != "timeout"
        if words:
            ok = ok and any(w in str(e) for w in words)
        R.check(f"{name}: refused naming args.path ({e.code}: {e})", ok, f"{e.code} {e.field} {e}")
        return e


def case(tmp):
    victim, data = victim_and_data(tmp, SECRET)
    outside = os.path.dirname(victim)
    # Planted before the daemon starts: the old temporary names of the
    # connection file and of a checkpoint, as symlinks leading out.
    os.symlink(victim, os.path.join(data, "conn.json.tmp"))
    os.symlink(victim, os.path.join(data, "c.h5.tmp"))
    before = tree_digest(outside)
    with dmod.Daemon(ranks=1, data_dir=data) as d:
        R.check("the connection file was written beside a planted symlink",
                os.path.isfile(d.conn_file) and not os.path.islink(d.conn_file))
        with d.client(timeout=10.0, retries=0) as c:
            c.load(builtin="pair")
            c.advance(steps=20)
            r = c.checkpoint("c.h5")
            R.check("checkpoint beside a planted symlinked temporary name succeeds",
                    r.get("step") == 20 and os.path.isfile(d.path("c.h5")) and not os.path.islink(d.path("c.h5")), r)
            R.check("... and the planted symlinks are untouched",
                    os.readlink(d.path("c.h5.tmp")) == victim and os.readlink(d.path("conn.json.tmp")) == victim)
            R.check("... no temporary file is left",
                    not [n for n in os.listdir(data) if n.endswith(".tmp") and not os.path.islink(d.path(n))],
                    os.listdir(data))

            # hard links
            os.link(victim, d.path("hard.txt"))
            refused("fetch of a hard link to a file outside", c.fetch, "hard.txt", words=["hard link"])
            with open(d.path("mine.txt"), "wb") as f:
                f.write(b"inside\n")
            os.link(d.path("mine.txt"), d.path("mine2.txt"))
            refused("fetch of a file with two names", c.fetch, "mine2.txt", words=["hard link"])
            refused("record onto a hard link to a file outside", c.record, "hard.txt")
            refused("stiffness table onto a hard link", c.request, "stiffness",
                    {"mesh": "pinion-wheel", "positions": 2, "path": "hard.txt"})

            # FIFO: refused at once, the daemon stays responsive
            os.mkfifo(d.path("fifo"))
            t0 = time.monotonic()
            refused("fetch of a FIFO", c.fetch, "fifo", words=["FIFO"])
            refused("restore from a FIFO", c.restore, "fifo", words=["FIFO"])
            st = c.status()
            R.check("the daemon answers status right after the FIFO requests",
                    st.get("state") == "loaded" and time.monotonic() - t0 < 30, st)
            if os.geteuid() == 0:
                os.mknod(d.path("null"), stat.S_IFCHR | 0o600, os.makedev(1, 3))
                refused("fetch of a character device", c.fetch, "null", words=["device"])
            refused("checkpoint onto a FIFO", c.checkpoint, "fifo")

            # a symlink as the file itself, and in a directory component
            os.symlink(victim, d.path("leaf.txt"))
            refused("fetch of a symlink", c.fetch, "leaf.txt")
            os.makedirs(d.path("sub"))
            os.symlink(d.path("sub"), d.path("sublink"))
            with open(d.path("sub/x.txt"), "wb") as f:
                f.write(b"x\n")
            refused("fetch through a directory symlink (even one that stays inside)", c.fetch, "sublink/x.txt")
            R.check("a plain file in a subdirectory is served", c.fetch("sub/x.txt") == b"x\n")

            # the daemon's own files
            conn_before = open(d.conn_file, "rb").read()
            refused("checkpoint onto the connection file", c.checkpoint, "conn.json", words=["connection file"])
            refused("checkpoint onto the lock file", c.checkpoint, ".gearsimd.lock", words=["lock file"])
            refused("record onto the connection file", c.record, "conn.json", words=["connection file"])
            R.check("the connection file is unchanged", open(d.conn_file, "rb").read() == conn_before)
            c.record("rec.h5")
            c.advance(steps=20)
            refused("checkpoint onto the record being written", c.checkpoint, "rec.h5", words=["record"])
            refused("record again onto the record being written", c.record, "rec.h5", words=["record"])
            refused("stiffness table onto the record being written", c.request, "stiffness",
                    {"mesh": "pinion-wheel", "positions": 2, "path": "rec.h5"}, words=["record"])
            c.advance(steps=20)
            c.record(stop=True)
            import h5py
            with h5py.File(d.path("rec.h5"), "r") as f:
                rows = f["telemetry/step"].shape[0]
            R.check("the record is readable and kept its rows after the refused writes", rows >= 2, rows)

            # a symlink swapped in for a file while fetches run
            good = d.path("swap.txt")
            stop = threading.Event()

            def swapper():
                k = 0
                while not stop.is_set():
                    k += 1
                    tmpn = d.path(f".sw{k}")
                    if k % 2:
                        os.symlink(victim, tmpn)
                    else:
                        with open(tmpn, "wb") as f:
                            f.write(b"inside\n")
                    os.replace(tmpn, good)

            with open(good, "wb") as f:
                f.write(b"inside\n")
            th = threading.Thread(target=swapper, daemon=True)
            th.start()
            served, refusals, leaks = 0, 0, 0
            for _ in range(300):
                try:
                    got = c.fetch("swap.txt")
                    served += 1
                    leaks += got != b"inside\n"
                except gearsim.GearsimError as e:
                    refusals += e.field == "args.path"
            stop.set()
            th.join()
            R.check(f"300 fetches while a symlink is swapped in and out: none served the outside file "
                    f"({served} served, {refusals} refused)", leaks == 0 and served + refusals == 300,
                    (served, refusals, leaks))
            R.check("the daemon still answers", c.status().get("state") == "loaded")
    after = tree_digest(outside)
    R.check("nothing outside the data directory changed", before == after, (before, after))


with tempfile.TemporaryDirectory(prefix="gearsim-files-") as tmp:
    R.guard("file rules", case, tmp)
R.finish()
