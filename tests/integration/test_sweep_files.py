#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The `sweep` job's files under the data directory's file rules
(docs/RELIABILITY.md, "File rules"; docs/explanation/modal.md, "Sweeps"): a symlink
planted at any of the sweep's output names (BASE.csv, BASE.h5,
BASE.sweep.json) or in a directory of its path, a FIFO at one of them, and
the record being written as one of them are refused naming args.path
before anything is computed or written; symlinks planted at the old
temporary names (BASE.csv.tmp, ...) are not followed; a hard link to an
outside file at an output name is replaced, never written through; resume
refuses a table that another user owns or others may write, or that has
two names, and takes a table whose last line an interrupted append tore
(that point is computed again; the table ends equal to the uninterrupted
one). Nothing outside the data directory changes."""
import json
import os
import stat
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
import gearsim  # noqa: E402
from harness import Results, tree_digest, victim_and_data  # noqa: E402

R = Results("test_sweep_files: the sweep job's files follow the data directory's file rules")
SECRET = b"outside the data directory: never written\n"
SPEC = {"builtin": "pair", "parameters": [{"path": "driver_rpm", "values": [1500, 2000, 2500]}],
        "settle": 0.0003, "measure": 0.0003}
NAMES = (".csv", ".h5", ".sweep.json")


def refused(c, name, args, words):
    """The sweep refused naming args.path with one of words in the message."""
    try:
        c.request("sweep", dict(SPEC, **args), timeout=60)
        R.check(f"{name}: refused", False, "accepted")
        return None
    except gearsim.GearsimError as e:
        ok = e.field == "args.path" and e.code != "timeout" and any(w in str(e) for w in words)
        R.check(f"{name}: refused naming args.path ({e.code}: {e})", ok, f"{e.code} {e.field} {e}")
        return e


def run_sweep(c, **args):
    rid = c.send("sweep", dict(SPEC, **args))
    reply = c.wait_reply(rid, timeout=60)
    return reply, c.wait_done(rid, timeout=300)


def read(p):
    with open(p, "rb") as f:
        return f.read()


def case(tmp):
    victim, data = victim_and_data(tmp, SECRET)
    outside = os.path.dirname(victim)
    before = tree_digest(outside)
    with dmod.Daemon(ranks=1, data_dir=data) as d, d.client(timeout=60.0, retries=0) as c:
        c.subscribe()
        # A symlink at each output name, in a directory of the path, a FIFO.
        for i, ext in enumerate(NAMES):
            os.symlink(victim, d.path(f"l{i}{ext}"))
            refused(c, f"symlink to a file outside at BASE{ext}", {"path": f"l{i}"}, ["symbolic link"])
            others = [f"l{i}{x}" for x in NAMES if x != ext]
            R.check(f"... nothing written at the other names of l{i}",
                    not any(os.path.lexists(d.path(n)) for n in others), os.listdir(data))
        os.symlink(outside, d.path("esc"))
        refused(c, "a directory symlink leading outside in the path", {"path": "esc/s"},
                ["symbolic link", "outside"])
        os.makedirs(d.path("sub"))
        os.symlink(d.path("sub"), d.path("sublink"))
        refused(c, "a directory symlink staying inside", {"path": "sublink/s"}, ["symbolic link"])
        os.mkfifo(d.path("f.csv"))
        refused(c, "a FIFO at BASE.csv", {"path": "f"}, ["FIFO"])

        # Symlinks at the old temporary names are not followed.
        for ext in NAMES:
            os.symlink(victim, d.path(f"t{ext}.tmp"))
        reply, done = run_sweep(c, path="t")
        R.check("a sweep beside symlinks planted at the old temporary names completes",
                done.get("points_done") == 3 and "error" not in done, done)
        ok = True
        for ext in NAMES:
            st = os.lstat(d.path(f"t{ext}"))
            ok = ok and stat.S_ISREG(st.st_mode) and stat.S_IMODE(st.st_mode) == 0o644
            ok = ok and os.readlink(d.path(f"t{ext}.tmp")) == victim
        R.check("... its files are new regular files of mode 0644 and the planted links untouched", ok)
        left = [n for n in os.listdir(data) if n.endswith(".tmp") and not os.path.islink(d.path(n))]
        R.check("... no temporary file is left", not left, left)
        table = read(d.path("t.csv"))
        R.check("... the table has a header and 3 rows in point order",
                [ln.split(b",")[0] for ln in table.splitlines()] == [b"point", b"0", b"1", b"2"], table[:200])

        # A hard link to an outside file at an output name: replaced by rename.
        os.link(victim, d.path("h.csv"))
        _, done = run_sweep(c, path="h")
        R.check("a hard link at BASE.csv is replaced, not written through",
                done.get("points_done") == 3 and read(d.path("h.csv")) == table and read(victim) == SECRET and
                os.stat(victim).st_nlink == 1, done)

        # Resume: an unfinished sweep made from t's files, 2 of 3 rows.
        state = json.loads(read(d.path("t.sweep.json")))
        R.check("the finished state file says so", state.get("finished") is True and state.get("points") == 3, state)
        state["finished"] = False
        lines = table.splitlines(keepends=True)

        def unfinished(base, rows, mode=0o644, tail=b""):
            with open(d.path(base + ".sweep.json"), "w") as f:
                json.dump(state, f)
            with open(d.path(base + ".csv"), "wb") as f:
                f.write(b"".join(lines[:1 + rows]) + tail)
            for ext in (".sweep.json", ".csv"):
                os.chmod(d.path(base + ext), mode)

        unfinished("r1", 2, mode=0o666)
        refused(c, "resume from a table others may write", {"path": "r1", "resume": True}, ["writable by others"])
        refused(c, "a new sweep over a state file others may write", {"path": "r1"}, ["writable by others"])
        if os.geteuid() == 0:
            unfinished("r2", 2)
            os.chown(d.path("r2.csv"), 65534, 65534)
            refused(c, "resume from a table of another user", {"path": "r2", "resume": True}, ["another user"])
        else:
            R.skip("resume from a table of another user", "needs root to chown")
        unfinished("r3", 2)
        os.link(d.path("r3.csv"), d.path("r3-other.csv"))
        refused(c, "resume from a table with two names", {"path": "r3", "resume": True}, ["hard link"])
        os.remove(d.path("r3-other.csv"))
        # An interrupted append: the torn start of point 2's row after 1 row.
        unfinished("r3", 1, tail=lines[3][:15])
        _, done = run_sweep(c, path="r3", resume=True)
        R.check("resume over a torn last line computes the 2 missing points (the torn one again)",
                done.get("resumed") == 1 and done.get("computed") == 2 and done.get("points_done") == 3, done)
        R.check("... and its table is the uninterrupted one", read(d.path("r3.csv")) == table)

        # The record being written is never a sweep's output.
        c.load(builtin="pair")
        c.record("rec.h5")
        c.advance(steps=10)
        ino = os.stat(d.path("rec.h5")).st_ino
        refused(c, "the record being written as BASE.h5", {"path": "rec"}, ["record"])
        c.record(stop=True)
        R.check("... the record was not replaced, nothing written at rec.csv",
                os.stat(d.path("rec.h5")).st_ino == ino and not os.path.lexists(d.path("rec.csv")) and
                not os.path.lexists(d.path("rec.sweep.json")))
        R.check("the daemon still answers", c.status().get("state") == "loaded")
    after = tree_digest(outside)
    R.check("nothing outside the data directory changed", before == after, (before, after))


with tempfile.TemporaryDirectory(prefix="gearsim-sweepfiles-") as tmp:
    R.guard("sweep files", case, tmp)
R.finish()
