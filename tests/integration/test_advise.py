#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""`gearctl advise`: the cheapest fidelity of the measured trade-off table
(docs/data/tradeoff.csv; here a frozen copy of one) that meets relative-error targets. No daemon: gearctl
reads the table and the scene. Checks two targets with different answers
(mean speed within 1% on the pair -> kinematic; DTE within 20% on the
planetary train -> contact), the reasons given (measured errors, cheaper
settings rejected on which output), the scene mapping (pair / planetary /
refused), a table with an extra column and an extra level read by header
name, and the errors: unknown output, bad value, no level meets (naming the
best achievable error), a scene the table does not cover."""
import csv
import json
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from harness import Results  # noqa: E402

SOURCE_ROOT = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.abspath(
    os.path.join(os.path.dirname(__file__), "..", ".."))
GEARCTL = os.path.join(SOURCE_ROOT, "clients", "python", "gearctl")
# A frozen copy of a measured table (docs/data/tradeoff.csv of 2026-11-22, before
# the compliant and adaptive rows): the answers asserted here must not move
# when the benchmark is run again on a noisy machine.
TABLE = os.path.join(SOURCE_ROOT, "tests", "integration", "tradeoff_fixture.csv")
R = Results("test_advise: gearctl advise")


# The converged peak force of bench_tradeoff.c (force_ref), N.
FORCE_REF = {"contact_drive": 630.553}

def advise(*args):
    if "--table" not in args:
        args = (*args, "--table", TABLE)
    return subprocess.run(["/usr/bin/python3", GEARCTL, "advise", *args], capture_output=True, text=True,
                          timeout=60)


def advise_json(*args):
    r = advise(*args, "--json")
    R.check(f"advise {' '.join(args)}: exit 0", r.returncode == 0, r.stderr)
    return json.loads(r.stdout) if r.returncode == 0 else {}


def main():
    rows = list(csv.DictReader(open(TABLE)))

    # 1. Mean speed within 1% on the pair: the cheapest row meeting it.
    a = advise_json("contact_drive", "--target", "speed=1e-2", "--table", TABLE)
    c = a.get("choice", {})
    R.check("speed 1e-2 on contact_drive -> kinematic h 1e-4", (c.get("level"), c.get("h")) == ("kinematic", 1e-4), c)
    R.check("scene mapped to the pair rows", a.get("table_scene") == "contact_drive" and a.get("scene_kind") == "pair", a)
    want = min((r for r in rows if r["scene"] == "contact_drive" and float(r["err_speed"]) <= 1e-2
                and float(r["err_speed"]) > 0), key=lambda r: float(r["cost"]))
    R.check("it is the cheapest row meeting the target", c.get("cost") == float(want["cost"]), (c, want))
    rej = a.get("rejected", [])
    R.check("cheaper impact h 1e-4 rejected on speed (0.317)",
            any(r["level"] == "impact" and abs(r["failed"].get("speed", 0) - 0.317264) < 1e-6 for r in rej), rej)
    R.check("every rejected setting is cheaper and fails a target",
            all(r["cost"] < c.get("cost", 0) and r["failed"] for r in rej), rej)

    # 2. DTE within 20% on the planetary train: only contact meets it.
    b = advise_json("planetary", "--target", "dte=0.2")
    c2 = b.get("choice", {})
    R.check("dte 0.2 on planetary -> contact h 2e-5", (c2.get("level"), c2.get("h")) == ("contact", 2e-5), c2)
    R.check("planetary scene mapped to the planetary_contact rows", b.get("table_scene") == "planetary_contact", b)
    R.check("the two targets give different answers", c.get("level") != c2.get("level"))
    R.check("lumped and calibrated rejected on dte",
            {r["level"] for r in b.get("rejected", [])} >= {"kinematic", "lumped", "calibrated"}
            and all("dte" in r["failed"] for r in b.get("rejected", [])), b.get("rejected"))
    # The same in text: level, step, cost and the reasons.
    t = advise("planetary", "--target", "dte=0.2")
    R.check("text advice names level, step and cost", t.returncode == 0 and "advice: contact, time step 2e-05 s"
            in t.stdout and "wall s per simulated s" in t.stdout and "dte 0.79" in t.stdout, t.stdout + t.stderr)

    # 3. Scene files: a planetary written with `train`, a pair, a chain (refused).
    with tempfile.TemporaryDirectory(prefix="advise-") as tmp:
        def scene_file(name, obj):
            p = os.path.join(tmp, name)
            with open(p, "w") as f:
                json.dump(obj, f)
            return p
        tr = scene_file("train.json", {"train": {"type": "planetary", "module_mm": 2.5, "sun": {"teeth": 24}}})
        R.check("train short form -> planetary rows",
                advise_json(tr, "--target", "speed=1e-3").get("table_scene") == "planetary_contact")
        pair = json.load(open(os.path.join(SOURCE_ROOT, "deploy", "scenes", "pair.json")))
        R.check("pair.json file -> pair rows",
                advise_json(scene_file("p.json", pair), "--target", "speed=1e-2").get("table_scene")
                == "contact_drive")
        chain = dict(pair, meshes=pair["meshes"] * 2)
        r = advise(scene_file("chain.json", chain), "--target", "speed=1e-2")
        R.check("a chain of two meshes is refused clearly", r.returncode == 1 and "chain of 2 meshes" in r.stderr,
                r.stderr)
        r = advise("elastic_spin", "--target", "speed=1e-2")
        R.check("a scene without meshes is refused", r.returncode == 1 and "no gear mesh" in r.stderr, r.stderr)
        r = advise(os.path.join(tmp, "missing.json"), "--target", "speed=1e-2")
        R.check("a missing scene is reported", r.returncode == 1 and "no such file" in r.stderr, r.stderr)

        # 4. Extra column and extra level (read by header name, columns reordered).
        fields = list(rows[0].keys())
        ext = os.path.join(tmp, "ext.csv")
        with open(ext, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=["adaptive"] + fields[::-1])
            w.writeheader()
            for row in rows:
                w.writerow(dict(row, adaptive="0"))
            w.writerow(dict(rows[0], level="compliant", h="1e-4", cost="0.006", err_speed="0.002",
                            err_dte="0.05", err_force="0.3", adaptive="1"))
        e = advise_json("contact_drive", "--target", "dte=0.1", "--table", ext)
        R.check("extra level chosen from a table with an extra column",
                e.get("choice", {}).get("level") == "compliant", e)

        # 4b. The elastic rows' contact scheme (column `scheme`, tables since
        # issue 15): the advice says which numerics.contact was measured.
        sch = os.path.join(tmp, "scheme.csv")
        with open(sch, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=fields + ["scheme"])
            w.writeheader()
            for row in rows:
                w.writerow(dict(row, scheme="closure_energy" if row["level"] == "contact" else ""))
        t = advise("planetary", "--target", "dte=0.2", "--table", sch)
        R.check("a contact row's scheme is named in the advice", t.returncode == 0 and
                'advice: contact, time step 2e-05 s, refine 0, numerics.contact "closure_energy"' in t.stdout,
                t.stdout + t.stderr)
        j = advise_json("planetary", "--target", "dte=0.2", "--table", sch)
        R.check("and in the JSON choice", j.get("choice", {}).get("scheme") == "closure_energy", j)

    # 4c. The outputs' longer names (dte_rms, peak_force, mesh_order, output_speed).
    e1, e2 = advise_json("contact_drive", "--target", "dte_rms=0.2"), advise_json("contact_drive", "--target", "dte=0.2")
    R.check("dte_rms is the dte output", e1.get("choice") == e2.get("choice") and e1.get("targets") == {"dte": 0.2},
            (e1, e2))

    # 5. Errors.
    r = advise("contact_drive", "--target", "stress=0.1")
    R.check("unknown output: exit 2, names the known outputs",
            r.returncode == 2 and "unknown output 'stress'" in r.stderr and "speed, dte, force" in r.stderr, r.stderr)
    for bad in ("speed=abc", "speed=0", "speed=-1", "speed=nan", "speed"):
        r = advise("contact_drive", "--target", bad)
        R.check(f"bad target {bad!r}: exit 2", r.returncode == 2 and "error" in r.stderr, r.stderr)
    r = subprocess.run(["/usr/bin/python3", GEARCTL, "advise", "contact_drive", "--target", "speed=1e-2"],
                       capture_output=True, text=True, timeout=60)
    R.check("without --table: the measured table docs/data/tradeoff.csv", r.returncode == 0 and
            os.path.join("docs", "data", "tradeoff.csv") in r.stdout, r.stdout + r.stderr)
    r = advise("contact_drive")
    R.check("no target: exit 2", r.returncode == 2 and "--target" in r.stderr, r.stderr)
    r = advise("contact_drive", "--target", "speed=1e-3", "--target", "dte=0.2")
    R.check("no level meets speed 1e-3 and dte 0.2: exit 1, best achievable named",
            r.returncode == 1 and "no level meets the target" in r.stderr
            and "speed 0.000835 (contact h 2e-05)" in r.stderr and "dte 0.123 (lumped" in r.stderr, r.stderr)
    r = advise("contact_drive", "--target", "force=0.1")
    R.check("force 0.1 unreachable: best achievable 0.567",
            r.returncode == 1 and "force 0.567" in r.stderr, r.stderr)
    r = advise("contact_drive", "--target", "speed=1e-2", "--table", "/nonexistent.csv")
    R.check("missing table reported", r.returncode == 1 and "cannot read the table" in r.stderr, r.stderr)
    measured_table()
    R.finish()


def measured_table():
    """The measured table itself (docs/data/tradeoff.csv, regenerated against the
    converged references of docs/validation/calculix.md): per scene one reference
    row, a damped closure_energy elastic row on a mesh finer than the
    default (the converged setting: reduced bodies, refine or counts scale
    above the default); every other row's errors are its figures against
    that row's; and advise, reading it by default, names that reference
    (its mesh too) and proposes the cheapest row meeting a DTE target."""
    path = os.path.join(SOURCE_ROOT, "docs", "data", "tradeoff.csv")
    rows = list(csv.DictReader(open(path)))
    cols = {"speed": "speed", "dte": "dte", "force": "force", "mesh": "mesh"}
    for scene, alias in (("contact_drive", "contact_drive"), ("planetary_contact", "planetary")):
        mine = [r for r in rows if r["scene"] == scene]
        # Peak force is against the top rung converged in the step where
        # the bench has one (tests/bench/bench_tradeoff.c, force_ref), so the
        # reference row is the one with no speed, DTE or mesh-force error.
        refs = [r for r in mine if all(float(r["err_" + o]) == 0 for o in cols if o != "force")]
        R.check(f"{scene}: one reference row, elastic closure_energy, damped, finer than the default mesh",
                len(refs) == 1 and refs[0]["level"] in ("contact", "reduced")
                and refs[0]["scheme"] == "closure_energy" and float(refs[0].get("zeta") or 0) > 0
                and (int(refs[0]["refine"]) > 0 or float(refs[0].get("scale") or 1) > 1), refs)
        if len(refs) != 1:
            continue
        ref = refs[0]
        bad = []
        for r in mine:
            for o, c in cols.items():
                a, b = float(r[c]), FORCE_REF.get(scene, float(ref[c])) if o == "force" else float(ref[c])
                want = abs(a - b) / abs(b) if b else abs(a)
                if abs(float(r["err_" + o]) - want) > 1e-3 * (1 + want):
                    bad.append((r["level"], r["h"], o, r["err_" + o], want))
        R.check(f"{scene}: every row's errors are against the reference row", not bad and len(mine) > 10, bad)
        j = advise_json(alias, "--target", "dte=0.5", "--table", path)
        R.check(f"{scene}: advise on the measured table names its reference",
                j.get("reference", {}).get("h") == float(ref["h"])
                and j.get("reference", {}).get("scheme") == "closure_energy"
                and j.get("reference", {}).get("refine") == int(ref["refine"])
                and j.get("reference", {}).get("scale", 1.0) == float(ref.get("scale") or 1), j.get("reference"))
        cands = [r for r in mine if r is not ref and float(r["err_dte"]) <= 0.5]
        want = min(cands, key=lambda r: float(r["cost"])) if cands else None
        R.check(f"{scene}: advise dte 0.5 -> the cheapest row within it",
                want is not None and (j.get("choice", {}).get("level"), j.get("choice", {}).get("h"))
                == (want["level"], float(want["h"])), (j.get("choice"), want))


if __name__ == "__main__":
    main()
