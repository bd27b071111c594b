#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Every output is written by rename (docs/RELIABILITY.md, "File rules"):
a record (`record`, and a job's record), a stiffness table and a
checkpoint written at a name where a file already exists replace that
file with a new one (a new inode, the daemon's owner, mode 0644); the old
file is never written into, so another name of it (a hard link made
beforehand) is refused, and a descriptor of the old file opened beforehand
still reads the old content. Run as root, the file planted beforehand
belongs to another user (nobody), which must not keep the output."""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_output_rename: every output written by rename")
OLD = b"planted before the daemon wrote here\n"


def plant(d, rel):
    p = d.path(rel)
    with open(p, "wb") as f:
        f.write(OLD)
    os.chmod(p, 0o600)
    if os.geteuid() == 0:
        os.chown(p, 65534, 65534)
    return os.stat(p).st_ino, open(p, "rb")


def replaced(d, rel, planted, what):
    ino, old = planted
    p = d.path(rel)
    st = os.stat(p)
    old.seek(0)
    other = old.read()
    old.close()
    R.check(f"{what}: a new file at the name", st.st_ino != ino, f"inode {st.st_ino} (was {ino})")
    R.check(f"{what}: the daemon's owner, mode 0644", st.st_uid == os.geteuid() and (st.st_mode & 0o777) == 0o644,
            f"uid {st.st_uid} mode {oct(st.st_mode & 0o777)}")
    R.check(f"{what}: the old file keeps its content", other == OLD, other[:60])
    with open(p, "rb") as f:
        R.check(f"{what}: the name holds an HDF5 file", f.read(8) == b"\x89HDF\r\n\x1a\n")


def main():
    with dmod.Daemon(ranks=1) as d:
        c = d.client()
        c.request("load", {"builtin": "pair"})
        ino = plant(d, "rec.h5")
        c.request("record", {"path": "rec.h5"})
        c.advance(steps=20, wait=True, timeout=120)
        c.request("record", {"stop": True})
        replaced(d, "rec.h5", ino, "record")
        ino = plant(d, "ck.h5")
        c.request("checkpoint", {"path": "ck.h5"})
        replaced(d, "ck.h5", ino, "checkpoint")
        ino = plant(d, "k.h5")
        c.request("stiffness", {"mesh": "pinion-wheel", "positions": 4, "path": "k.h5", "wait": True}, timeout=300)
        replaced(d, "k.h5", ino, "stiffness table")
        p = d.path("k2.h5")
        with open(p, "wb") as f:
            f.write(OLD)
        os.link(p, d.path("k2.other"))
        for cmd, args in (("record", {"path": "k2.h5"}),
                          ("stiffness", {"mesh": "pinion-wheel", "positions": 4, "path": "k2.h5", "wait": True})):
            try:
                c.request(cmd, args, timeout=300)
                R.check(f"{cmd} onto a name with two links is refused", False, "accepted")
            except Exception as e:  # noqa: BLE001
                R.check(f"{cmd} onto a name with two links is refused", "hard link" in str(e), repr(e))
        c.request("unload")
        ino = plant(d, "job.h5")
        job = c.request("submit", {"scene": dmod.load_scene("pair"), "duration": 1e-3, "record": "job.h5"})["job"]
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60:
            js = {j["job"]: j for j in c.request("jobs")["jobs"]}
            if js.get(job, {}).get("state") in ("done", "failed", "cancelled"):
                break
            time.sleep(0.2)
        R.check("the job ran", js.get(job, {}).get("state") == "done", js.get(job))
        replaced(d, "job.h5", ino, "job record")
    R.finish()


if __name__ == "__main__":
    main()
