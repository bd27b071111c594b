#!/usr/bin/python3
"""Speed sweep of helical_pair at the ltca rung beside the spur pair of the
same transverse section (docs/explanation/helical.md "Helical pairs in the
ltca rung").

    /usr/bin/python3 docs/tools/helical_sweep.py [--build build] [--no-run]

Runs gearsim-sweep (41 pinion speeds 6000-48000 rpm, settle 20 ms, measure
20 ms, h = 2e-6 s) on both scenes, writes docs/data/helical_sweep_helical.csv
and docs/data/helical_sweep_spur.csv and draws docs/img/helical_sweep.png;
--no-run redraws from the CSVs. The spur scene is helical_pair.json with the
helix removed and the normal rack turned into transverse values (module
m_n / cos b, pressure angle atan(tan a_n / cos b), addendum, dedendum and
fillet times cos b, in plane strain as the helical gears of a 30 mm face are),
so both have the same transverse section."""
import argparse
import csv
import json
import math
import os
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DATA = os.path.join(ROOT, "docs", "data")
IMG = os.path.join(ROOT, "docs", "img", "helical_sweep.png")
SWEEP = ["--from", "6000", "--to", "48000", "--points", "41", "--settle", "0.02", "--measure", "0.02",
         "--time-step", "2e-6"]


def spur_section(hel, plane="strain"):
    """The spur pair of a helical scene's transverse section (helix removed,
    the normal rack of 20 deg, addendum 1, dedendum 1.25 and fillet 0.38 in
    transverse values), its bodies in the given plane state."""
    spur = json.loads(json.dumps(hel))
    c = math.cos(math.radians(hel["bodies"][0]["helix_angle_deg"]))
    for b in spur["bodies"]:
        del b["helix_angle_deg"], b["hand"]
        b["module_mm"] = round(b["module_mm"] / c, 9)
        b["pressure_angle_deg"] = round(math.degrees(math.atan(math.tan(math.radians(20.0)) / c)), 9)
        b["addendum"], b["dedendum"], b["fillet"] = round(c, 9), round(1.25 * c, 9), round(0.38 * c, 9)
        b["material"] = {"plane": plane}
    return spur


def scenes():
    with open(os.path.join(ROOT, "deploy", "scenes", "helical_pair.json")) as f:
        hel = json.load(f)
    hel["fidelity"] = "ltca"
    # the helical gears' section is in plane strain (face >= 5 m_n): the spur pair's too
    spur = spur_section(hel)
    spur["name"] = "spur pair of helical_pair's transverse section"
    return {"helical": hel, "spur": spur}


def run(build):
    exe = os.path.join(build, "src", "tools", "gearsim-sweep")
    with tempfile.TemporaryDirectory() as tmp:
        for name, sc in scenes().items():
            path = os.path.join(tmp, name + ".json")
            with open(path, "w") as f:
                json.dump(sc, f)
            out = subprocess.run([exe, path] + SWEEP, check=True, capture_output=True, text=True).stdout
            with open(os.path.join(DATA, "helical_sweep_%s.csv" % name), "w") as f:
                f.write(out)


def read(name):
    with open(os.path.join(DATA, "helical_sweep_%s.csv" % name)) as f:
        return list(csv.DictReader(f))


def plot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for name, style in (("spur", "o-"), ("helical", "s-")):
        rows = read(name)
        hz = [float(r["mesh_hz"]) for r in rows]
        ax[0].plot(hz, [float(r["dte_rms_um"]) for r in rows], style, ms=3, label=name)
        ax[1].plot(hz, [float(r["dynamic_factor"]) for r in rows], style, ms=3, label=name)
    ax[0].set_ylabel("DTE rms (um)")
    ax[0].set_yscale("log")
    ax[1].set_ylabel("dynamic factor")
    ax[1].set_xlabel("mesh frequency (Hz)")
    ax[0].legend()
    ax[0].set_title("helical_pair (beta 15 deg) and its transverse section as a spur pair, ltca rung")
    fig.tight_layout()
    fig.savefig(IMG, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--no-run", action="store_true")
    a = ap.parse_args()
    if not a.no_run:
        run(a.build)
    plot()


if __name__ == "__main__":
    main()
