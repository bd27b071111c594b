#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Benchmark: the elastic planetary train in tooth contact (planetary_contact:
five elastic gears, six contact meshes) through the real daemon at mpirun
-n 1 and -n 2, with the step's timing breakdown from `status` and each
gear's measured work; then a projection of strong scaling to one rank per
gear from those measurements. Ratios, not absolute times, are the result:
the machine is shared and noisy.

    meson test -C build --benchmark --suite bench planetary
"""
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "integration"))

import daemon as dmod  # noqa: E402

STEPS = int(os.environ.get("GEARSIM_BENCH_STEPS", "1500"))
PHASES = ("prepare", "records", "reduce", "solve", "bcast", "apply", "sync")


def run(ranks):
    scene = dmod.load_scene("planetary_contact")
    scene["outputs"] = {"telemetry_every": 1000}
    with dmod.Daemon(ranks=ranks) as d:
        with d.client() as c:
            c.load(scene=scene)
            t0 = time.monotonic()
            done = c.advance(steps=STEPS, timeout=3600)
            wall = time.monotonic() - t0
            st = c.status()
    tm = st["timing"]
    return {"wall": done.get("wall_seconds", wall), "breakdown": tm["breakdown"],
            "bodies": tm["bodies"]}


def main():
    res = {n: run(n) for n in (1, 2)}
    print(f"# bench_planetary: planetary_contact, {STEPS} steps, OPENBLAS_NUM_THREADS="
          f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    print(f"{'ranks':>5} {'ms/step':>9} " + " ".join(f"{p:>8}" for p in PHASES) + "   (ms per step on rank 0)")
    for n, r in res.items():
        b = r["breakdown"]
        print(f"{n:>5} {1e3 * r['wall'] / STEPS:9.3f} " + " ".join(f"{1e3 * b[p] / STEPS:8.3f}" for p in PHASES))
    print(f"speed-up -n 2 vs -n 1: {res[1]['wall'] / res[2]['wall']:.2f}")
    print("\nwork per gear (condensation + back-substitution on its owner, ms per step, from -n 1):")
    w = {x["name"]: x["work_seconds"] / STEPS for x in res[1]["bodies"] if x["work_seconds"] > 0}
    for name, v in sorted(w.items(), key=lambda kv: -kv[1]):
        print(f"  {name:10s} {1e3 * v:8.3f}")
    # Projection to one rank per gear: the largest gear's work, plus rank 0's
    # own serial part (search, QP, energy sync), plus communication. The
    # communication estimate comes from -n 2: its reduce + bcast time on rank
    # 0 minus the time rank 0 waited for the busier rank (load imbalance).
    b1, b2 = res[1]["breakdown"], res[2]["breakdown"]
    serial = (b1["prepare"] + b1["solve"] + b1["sync"]) / STEPS
    per_rank = {}
    for x in res[2]["bodies"]:
        per_rank[x["rank"]] = per_rank.get(x["rank"], 0.0) + x["work_seconds"] / STEPS
    wait = max(0.0, max(per_rank.values()) - per_rank.get(0, 0.0))
    comm = max(0.0, (b2["reduce"] + b2["bcast"]) / STEPS - wait)
    proj = max(w.values()) + serial + comm
    t1 = res[1]["wall"] / STEPS
    print(f"\nprojection, one rank per gear ({len(w)} gears + QP on rank 0):")
    print(f"  largest gear {1e3 * max(w.values()):.3f} ms + serial (search, QP, sync) {1e3 * serial:.3f} ms"
          f" + communication {1e3 * comm:.3f} ms = {1e3 * proj:.3f} ms per step")
    print(f"  projected speed-up vs -n 1: {t1 / proj:.2f} (ideal with this work split: "
          f"{t1 / (max(w.values()) + serial):.2f})")


if __name__ == "__main__":
    main()
