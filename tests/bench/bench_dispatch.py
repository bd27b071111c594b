#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: how many sweep groups one rank 0 can feed. The daemon's
`sweep` job on points that cost next to nothing (the lumped pair, no
settling, one step measured) at -n 1 (1 group) and -n 2 (2 groups): points
per second handed out and collected, all in (request to `done`: building
each point's scene, the step, the row written to CSV and HDF5, one
progress event per point), and rank 0's CPU per point (from
/proc/<pid>/stat, immune to other processes holding the core). Then the
same for the lumped pair's real point (settle and measure 0.01 s each, the
sweep's defaults) at -n 1, and the group count at which rank 0 would be
busy all the time: (seconds per real point) / (rank 0's CPU per empty
point). Both figures are in the same run; the machine's load is printed.

    meson test -C build --benchmark --suite bench dispatch
    GEARSIM_BENCH_EMPTY_POINTS=2000 ... for a longer run
"""
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import daemon as dmod  # noqa: E402

EMPTY = int(os.environ.get("GEARSIM_BENCH_EMPTY_POINTS", "400"))
REAL = int(os.environ.get("GEARSIM_BENCH_REAL_POINTS", "40"))
TICK = os.sysconf("SC_CLK_TCK")


def loadavg():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def cpu_of(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK   # utime + stime


def ranks_of(d):
    """[pid of rank 0, pid of rank 1, ...] of the daemon."""
    out = {}
    for p in d.session_pids():
        try:
            with open(f"/proc/{p}/environ", "rb") as f:
                env = dict(kv.split(b"=", 1) for kv in f.read().split(b"\0") if b"=" in kv)
            if os.path.basename(os.readlink(f"/proc/{p}/exe")) == "gearsimd":
                out[int(env[b"OMPI_COMM_WORLD_RANK"])] = p
        except (OSError, KeyError, ValueError):
            pass
    return [out[r] for r in sorted(out)]


def sweep(ranks, groups, points, settle, measure, h):
    """(wall s per point, [CPU s per point of each rank]) of one sweep on a fresh daemon."""
    with dmod.Daemon(ranks=ranks) as d, d.client(timeout=60) as c:
        c.subscribe()
        pids = ranks_of(d)
        args = dict(builtin="pair", groups=groups, path="bench", settle=settle, measure=measure)
        if h:
            args["time_step"] = h
        cpu0 = [cpu_of(p) for p in pids]
        t0 = time.perf_counter()
        done = c.sweep([{"path": "driver_rpm", "from": 500, "to": 3000, "points": points}], timeout=3600, **args)
        wall = time.perf_counter() - t0
        cpu = [cpu_of(p) - c for p, c in zip(pids, cpu0)]
    if done.get("points_done") != points:
        raise RuntimeError(f"sweep incomplete: {done}")
    return wall / points, [c / points for c in cpu]


def main():
    print(f"# bench_dispatch: sweep dispatcher on rank 0; load average (1, 5, 15 min) {loadavg()} "
          f"on {os.cpu_count()} cores")
    print(f"{'case':<34} {'ranks':>5} {'groups':>6} {'points':>6} {'points/s':>9} {'ms/point':>9} "
          f"{'CPU ms/pt: rank 0, 1':>21}")
    rows = {}
    for name, ranks, groups, points, settle, measure, h in (
            ("empty (1 step, no settling)", 1, 1, EMPTY, 0.0, 1e-5, 1e-5),
            ("empty (1 step, no settling)", 2, 2, EMPTY, 0.0, 1e-5, 1e-5),
            ("lumped pair (0.01 s + 0.01 s)", 1, 1, REAL, 0.01, 0.01, None)):
        wall, cpu = sweep(ranks, groups, points, settle, measure, h)
        rows[(name, ranks)] = (wall, cpu)
        print(f"{name:<34} {ranks:>5} {groups:>6} {points:>6} {1 / wall:9.1f} {1e3 * wall:9.3f} {' '.join(f'{1e3 * c:7.3f}' for c in cpu):>21}")
    e_wall, (e_cpu, e_cpu1) = rows[("empty (1 step, no settling)", 2)]
    _, (one_cpu,) = rows[("empty (1 step, no settling)", 1)]
    r_wall, (r_cpu,) = rows[("lumped pair (0.01 s + 0.01 s)", 1)]
    print(f"RESULT dispatch: rank 0 hands out and collects {1 / e_wall:.0f} empty points/s at 2 groups "
          f"(wall, all in); rank 0 CPU {1e3 * e_cpu:.3f} ms per empty point (its own share of the points "
          f"included); both ranks {1e3 * (e_cpu + e_cpu1):.3f} ms against {1e3 * one_cpu:.3f} ms on one rank")
    print(f"RESULT saturation: a lumped pair point costs {1e3 * r_cpu:.2f} ms CPU ({1e3 * r_wall:.2f} ms wall) at -n 1; "
          f"rank 0 saturates at about {r_cpu / e_cpu:.0f} groups (CPU) / {r_wall / e_wall:.0f} (wall)")
    print(f"# load average after: {loadavg()}")


main()
