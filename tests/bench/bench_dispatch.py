#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: how many sweep groups one rank 0 can feed. The daemon's
`sweep` job on points that cost next to nothing (the lumped pair, no
settling, one step measured): at -n 1 (1 group, the reference), at -n 2
(2 groups, rank 0 computing group 0's points between handing out the
others) and at -n 3 with a dedicated dispatcher (2 groups on ranks 1 and
2; rank 0 only hands out points and collects rows). Points per second,
all in (request to `done`: building each point's scene, the step, the row
written to CSV and HDF5, one progress event per point), and each rank's
CPU per point (from /proc/<pid>/stat, immune to other processes holding
the core). The dedicated rank 0's CPU per point is the dispatcher's cost:
its inverse is the points per second one rank 0 can hand out and collect.
Then the lumped pair's real point (settle and measure 0.01 s each, the
sweep's defaults) at -n 1, and the group count at which rank 0 would be
busy all the time: (CPU seconds per real point) / (rank 0's CPU per point).
All figures come from the same run; the machine's load is printed.

    meson test -C build --benchmark --suite bench dispatch
    GEARSIM_BENCH_EMPTY_POINTS=4000 ... for a longer run (at most 4096)
"""
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import daemon as dmod  # noqa: E402

EMPTY = int(os.environ.get("GEARSIM_BENCH_EMPTY_POINTS", "1000"))
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


def sweep(ranks, groups, points, settle, measure, h, dispatcher="shared"):
    """(wall s per point, [CPU s per point of each rank]) of one sweep on a fresh daemon."""
    with dmod.Daemon(ranks=ranks) as d, d.client(timeout=60) as c:
        c.subscribe()
        pids = ranks_of(d)
        args = dict(builtin="pair", groups=groups, path="bench", settle=settle, measure=measure, dispatcher=dispatcher)
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
    print(f"{'case':<34} {'ranks':>5} {'groups':>6} {'dispatcher':>10} {'points':>6} {'points/s':>9} "
          f"{'ms/point':>9}  CPU ms/point: rank 0, 1, ...")
    rows = {}
    empty = "empty (1 step, no settling)"
    real = "lumped pair (0.01 s + 0.01 s)"
    for name, ranks, groups, disp, points, settle, measure, h in (
            (empty, 1, 1, "shared", EMPTY, 0.0, 1e-5, 1e-5),
            (empty, 2, 2, "shared", EMPTY, 0.0, 1e-5, 1e-5),
            (empty, 3, 2, "dedicated", EMPTY, 0.0, 1e-5, 1e-5),
            (real, 1, 1, "shared", REAL, 0.01, 0.01, None)):
        wall, cpu = sweep(ranks, groups, points, settle, measure, h, disp)
        rows[(name, ranks)] = (wall, cpu)
        print(f"{name:<34} {ranks:>5} {groups:>6} {disp:>10} {points:>6} {1 / wall:9.1f} {1e3 * wall:9.3f}  "
              f"{' '.join(f'{1e3 * c:.3f}' for c in cpu)}")
    _, (one_cpu,) = rows[(empty, 1)]
    s_wall, s_cpu = rows[(empty, 2)]
    d_wall, d_cpu = rows[(empty, 3)]
    r_wall, (r_cpu,) = rows[(real, 1)]
    disp_cpu = max(d_cpu[0], 1.0 / TICK / EMPTY)   # at least one clock tick over the run
    print(f"RESULT dispatch: a dedicated rank 0 spends {1e3 * d_cpu[0]:.4f} ms CPU per empty point "
          f"(handing it out, collecting its row, its progress event, the table): it can hand out and collect "
          f"about {1 / disp_cpu:.0f} points/s; measured {1 / d_wall:.0f} points/s at 2 groups (wall, all in, "
          f"bounded by the groups); a computing group spends {1e3 * one_cpu:.3f} ms per empty point")
    print(f"RESULT shared: rank 0 computing group 0's points at -n 2: {1 / s_wall:.0f} points/s, rank 0 CPU "
          f"{1e3 * s_cpu[0]:.3f} ms per point (its own share of the points included)")
    print(f"RESULT saturation: a lumped pair point costs {1e3 * r_cpu:.2f} ms CPU ({1e3 * r_wall:.2f} ms wall) at -n 1; "
          f"a dedicated rank 0 saturates at about {r_cpu / disp_cpu:.0f} groups of such points")
    print(f"# load average after: {loadavg()}")


if __name__ == "__main__":
    main()
