#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The reply cache is bounded: a few hundred 1 MiB fetches (each reply
~1.4 MB of base64) from one client and from several keep the resident
memory of rank 0 within the cache's byte bound (hello.limits) plus a margin,
where an unbounded cache grows by the sum of all replies (~420 MB); a
retried id within the lifetime is still answered from the cache (the
command does not run twice)."""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import RawDealer, Results  # noqa: E402

R = Results("test_reply_cache: bounded reply cache, retries still answered")
FETCHES = 300


def rss_kib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS")


def rank0_pid(d):
    for p in d.session_pids():
        try:
            with open(f"/proc/{p}/comm") as f:
                if f.read().strip() == "gearsimd":
                    return p
        except OSError:
            pass
    raise RuntimeError("no gearsimd process")


def fetch(dealer, rid):
    rep, _ = dealer.request({"v": 1, "id": rid, "cmd": "fetch",
                             "args": {"path": "blob.bin", "offset": 0, "length": 1 << 20}}, timeout=60)
    return rep


def run():
    with dmod.Daemon() as d:
        with open(d.path("blob.bin"), "wb") as f:
            f.write(os.urandom(1 << 20))
        lim = d.hello["limits"]
        bound = lim.get("reply_cache_bytes", 32 << 20)
        R.check("hello.limits names the cache bounds",
                all(k in lim for k in ("reply_cache_bytes", "reply_cache_entries", "reply_cache_client_bytes",
                                       "reply_cache_client_entries", "reply_cache_lifetime_s")), lim)
        pid = rank0_pid(d)
        dealers = [RawDealer(d.conn_file) for _ in range(4)]
        # Warm up (allocator, first replies) before the baseline.
        for i, c in enumerate(dealers):
            fetch(c, f"warm{i}")
        base = rss_kib(pid)
        ok = 0
        for i in range(FETCHES):
            c = dealers[0] if i < FETCHES // 2 else dealers[i % 4]
            rep = fetch(c, f"f{i}")
            ok += bool(rep and rep.get("ok") and rep["result"]["length"] == 1 << 20)
        grown = (rss_kib(pid) - base) * 1024
        R.check(f"{FETCHES} fetches of 1 MiB all answered", ok == FETCHES, ok)
        margin = 48 << 20
        R.note(f"rank 0 RSS grew by {grown / 2**20:.1f} MiB over {FETCHES} fetches "
               f"({FETCHES * 1.4:.0f} MB of replies); bound {bound / 2**20:.0f} MiB cache + "
               f"{margin / 2**20:.0f} MiB margin")
        R.check("rank 0 RSS stays under the cache bound plus margin", grown < bound + margin,
                f"grew {grown} bytes")

        # A retried id within the lifetime: answered from the cache.
        c = dealers[1]
        rep, _ = c.request({"v": 1, "id": "ld", "cmd": "load", "args": {"builtin": "pair"}}, timeout=60)
        R.check("load pair", rep and rep.get("ok"), rep)
        first, _ = c.request({"v": 1, "id": "adv-1", "cmd": "advance", "args": {"steps": 200}})
        again, _ = c.request({"v": 1, "id": "adv-1", "cmd": "advance", "args": {"steps": 200}})
        R.check("retried advance id: the same accepted reply (not run twice, not refused)",
                first and first.get("ok") and again == first, (first, again))
        # The last fetch of client 0 is still answered (its reply is in the cache).
        rep = fetch(dealers[0], f"f{FETCHES // 2 - 1}")
        R.check("a retried 1 MiB fetch of the same client is answered", rep and rep.get("ok"), rep)
        for c in dealers:
            c.close()


R.guard("reply cache run", run)
R.finish()
