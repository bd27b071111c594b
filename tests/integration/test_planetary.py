#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The elastic planetary train in tooth contact (deploy/scenes/planetary_contact.json:
five elastic gears, six contact meshes, one QP per step) through the real
daemon at mpirun -n 1, 2, 3 and 4: identical telemetry and final state (to
1e-12 relative; in practice bit for bit), planet load sharing in telemetry,
and the timing breakdown with each body's work in `status`."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import daemon as dmod  # noqa: E402
from harness import Results  # noqa: E402

R = Results("test_planetary: elastic planetary train in contact at 1 to 4 ranks")
STEPS = 400


def run(ranks):
    scene = dmod.load_scene("planetary_contact")
    scene["outputs"] = {"telemetry_every": 20}
    with dmod.Daemon(ranks=ranks) as d:
        with d.client() as c:
            c.load(scene=scene)
            tel = []
            done = c.advance(steps=STEPS, on_telemetry=tel.append, timeout=900)
            R.check(f"-n {ranks}: run completed", not done.get("cancelled") and not done.get("error"), done)
            st = c.status()
            final = c.state()
    return tel, final, st


def flat(x, path=""):
    if isinstance(x, dict):
        for k in sorted(x):
            yield from flat(x[k], f"{path}.{k}")
    elif isinstance(x, list):
        for i, v in enumerate(x):
            yield from flat(v, f"{path}[{i}]")
    else:
        yield path, x


def differences(a, b):
    """Fields that differ by more than 1e-12 relative (numbers) or at all. The
    balance residual is itself a round-off difference of energies: it is
    compared relative to the largest energy figure of the same message."""
    fa, fb = dict(flat(a)), dict(flat(b))
    out = []
    for k in sorted(set(fa) | set(fb)):
        x, y = fa.get(k), fb.get(k)
        if isinstance(x, float) and isinstance(y, float):
            ref = max(abs(x), abs(y), 1e-300)
            if k.endswith("balance_residual"):
                base = k[: -len("balance_residual")]
                ref = max([abs(fa.get(base + f, 0.0) or 0.0) for f in ("total", "work_in", "dissipated")] + [ref])
            if abs(x - y) > 1e-12 * ref:
                out.append(f"{k}: {x!r} vs {y!r}")
        elif x != y:
            out.append(f"{k}: {x!r} vs {y!r}")
    return out


def main():
    base_tel, base_final, st1 = run(1)
    keep = ("step", "time", "energy", "bodies", "meshes", "planets")
    base = [{k: ev.get(k) for k in keep} for ev in base_tel]
    R.check(f"-n 1: {len(base)} telemetry messages", len(base) == STEPS // 20, len(base))
    last = base_tel[-1] if base_tel else {}
    shares = last.get("planets", [])
    R.check("telemetry carries the planets' load shares", len(shares) == 3 and
            all(s.get("share", -1) >= 0 for s in shares), shares)
    if shares:
        R.check("shares average to 1 (normalised to equal sharing)",
                abs(sum(s["share"] for s in shares) / 3 - 1) < 1e-12, shares)
    tm = st1.get("timing", {})
    bd = tm.get("breakdown", {})
    R.check("status: timing breakdown over the run's steps", bd.get("steps") == STEPS and
            all(bd.get(k, -1) >= 0 for k in ("prepare", "records", "reduce", "solve", "bcast", "apply", "sync")), bd)
    works = {b["name"]: b.get("work_seconds", 0) for b in tm.get("bodies", [])}
    R.check("status: each elastic gear's work measured", all(works.get(n, 0) > 0 for n in
            ("sun", "planet1", "planet2", "planet3", "ring")), works)
    R.note("-n 1 breakdown per step (ms): " + ", ".join(
        f"{k} {1e3 * bd.get(k, 0) / max(STEPS, 1):.3f}" for k in ("prepare", "records", "reduce", "solve", "bcast", "apply", "sync")))
    for ranks in (2, 3, 4):
        tel, final, st = run(ranks)
        cur = [{k: ev.get(k) for k in keep} for ev in tel]
        diffs = differences(base, cur) + differences(
            {k: base_final.get(k) for k in keep}, {k: final.get(k) for k in keep})
        R.check(f"-n {ranks}: telemetry and final state identical to -n 1 (1e-12 relative)", not diffs,
                "\n".join(diffs[:10]))
        owners = {b["name"]: b.get("rank") for b in st.get("timing", {}).get("bodies", [])}
        R.note(f"-n {ranks}: owners {owners}")
        R.check(f"-n {ranks}: gears spread over the ranks", len(set(owners.values())) == ranks, owners)


R.guard("planetary train in contact at 1 to 4 ranks", main)
R.finish()
