#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The tables and plots of the validation report (docs/validation/).

    docs/data/validation.py write  [FIGURE ...]   rerun, write docs/data/validation_FIGURE.csv and the plot
    docs/data/validation.py check  [FIGURE ...]   rerun, compare with the stored CSV (exit 1 on a difference)
    docs/data/validation.py plot   [FIGURE ...]   redraw the plots from the stored CSVs (runs nothing)
    docs/data/validation.py list                  the figures, their commands and whether they are cheap

Every figure runs the command its page names (COMMANDS below, printed by
`list`), parses what the command prints and writes one CSV, the table the
page includes (`csv-table` with `:file:`), so the page cannot say other
numbers than the file. `check` reruns a figure and compares every cell with
the stored file: text cells equal, numbers within the figure's tolerance
(TOLERANCE, printed by `list`). Without FIGURE: every cheap figure (a few
minutes of CPU in all); the expensive ones are rerun only when named.
Needs a build in build/ (GEARSIM_BUILD_ROOT overrides) and deploy/env.sh's
environment (the meson test sets it).
"""
import csv
import json
import math
import os
import re
import shlex
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.normpath(os.path.join(HERE, "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT") or os.path.join(ROOT, "build")
IMG = {"validation": os.path.join(ROOT, "docs", "validation", "img")}

# The command each figure runs, as its page prints it (run from the source root).
COMMANDS = {
    "calculix": ["tests/reference/compare.py --pair stiffness_30_20 --json",
                 "tests/reference/compare.py --pair stiffness_30_20 --json -- --fine",
                 "tests/reference/compare.py --pair stiffness_20s_30 --json",
                 "tests/reference/compare.py --pair stiffness_20s_30 --json -- --fine"],
    "iso6336": ["build/src/tools/gearsim-stiffness deploy/scenes/stiffness_pair.json --positions 24 --json"],
    "hertz": ["build/tests/validation/vtest_compliant"],
    "lin_parker": ["clients/python/gearctl modal deploy/scenes/lin_parker_%d.json --json" % n for n in (3, 4, 5)]
    + ["tests/integration/test_modal.py"],
    "impact": ["build/tests/validation/vtest_impact_sweep"],
    "seed": ["build/tests/validation/vtest_contact_pair"],
    "lowspeed": ["build/tests/validation/vtest_lowspeed_te"],
    "modes": ["build/src/tools/gearsim-modal deploy/scenes/contact_drive.json --fe --no-nearfield --json"],
    "calculix_modal": ["build/src/tools/gearsim-modal tests/reference/modal_30_20/scene.json --fe --positions 4 "
                       "--modes 1 --torque 20 --json",
                       "build/src/tools/gearsim-modal tests/reference/modal_30_20/scene.json --fe --positions 4 "
                       "--modes 1 --torque 20 --no-nearfield --json"],
}
# Relative and absolute tolerance of a number when a rerun is checked.
TOLERANCE = {"calculix": (1e-3, 0.02), "iso6336": (1e-3, 0.0), "hertz": (1e-4, 0.002),
             "lin_parker": (1e-6, 1e-12), "impact": (0.0, 0.0), "seed": (1e-3, 1e-11),
             "lowspeed": (1e-3, 0.02), "modes": (1e-3, 0.0), "calculix_modal": (1e-3, 0.02)}
CHEAP = ["calculix", "iso6336", "hertz", "lin_parker", "impact", "seed", "lowspeed", "modes", "calculix_modal"]


def run(cmd, check=True):
    env = dict(os.environ, GEARSIM_BUILD_ROOT=BUILD, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    env.pop("CMOCKA_MESSAGE_OUTPUT", None)  # the tests' own messages, as a user running them sees them
    env.pop("GEARSIM_LONG", None)  # the commands as the pages give them, not the tests' long modes
    argv = shlex.split(cmd)
    if argv[0].startswith("build/"):
        argv[0] = os.path.join(BUILD, argv[0][len("build/"):])
    elif argv[0].endswith(".py") or argv[0].endswith("gearctl"):
        argv = [sys.executable, os.path.join(ROOT, argv[0])] + argv[1:]
    if argv[0].endswith("compare.py"):
        argv[2:2] = ["--build", BUILD]
    r = subprocess.run(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0 and check:
        raise RuntimeError("%s: exit %d\n%s" % (cmd, r.returncode, r.stdout[-3000:]))
    return r.stdout


def pct(x, digits=2):
    return "%+.*f" % (digits, 100.0 * x)


# ---- figures: each returns (header, rows) -------------------------------------------------------------

def fig_calculix():
    runs = [json.loads(run(c))[0] for c in COMMANDS["calculix"]]
    a, af, b, bf = runs
    head = ["roll", "20/30 CalculiX k", "20/30 default %", "20/30 fine %",
            "shifted CalculiX k", "shifted default %", "shifted fine %"]
    rows = []
    for i, r in enumerate(a["rows"]):
        rows.append(["%.3f" % r["roll"], "%.3f" % r["ref_k"], pct(r["err_k"]), pct(af["rows"][i]["err_k"]),
                     "%.3f" % b["rows"][i]["ref_k"], pct(b["rows"][i]["err_k"]), pct(bf["rows"][i]["err_k"])])
    for label, key in (("max abs k error", "max_abs_err_k"), ("max abs TE error", "max_abs_err_te"),
                       ("cycle mean k error", "cycle_mean_err_k"), ("single-contact mean k error",
                                                                    "single_mean_err_k")):
        f = (lambda v: "%.2f" % (100 * v)) if key.startswith("max") else pct
        rows.append([label, "", f(a["summary"][key]), f(af["summary"][key]), "", f(b["summary"][key]),
                     f(bf["summary"][key])])
    rows.append(["unknowns (both gears)", "", str(2 * sum(a["summary"]["nodes"])),
                 str(2 * sum(af["summary"]["nodes"])), "", str(2 * sum(b["summary"]["nodes"])),
                 str(2 * sum(bf["summary"]["nodes"]))])
    return head, rows


def iso6336_range(z1, z2, eps_alpha):
    """ISO 6336-1 method B for unshifted steel spur gears: single stiffness
    c'_th = 1/q', q' = 0.04723 + 0.15551/z1 + 0.25791/z2 (N/(mm um)); c' =
    c'_th C_M C_R C_B (0.8, solid blanks 1, h_fP = 1.25 m 0.975); mesh
    stiffness c_gamma_alpha = c (0.75 eps_alpha + 0.25)."""
    cth = 1.0 / (0.04723 + 0.15551 / z1 + 0.25791 / z2)
    c = cth * 0.8 * 1.0 * 0.975
    return cth, c, c * (0.75 * eps_alpha + 0.25), cth * (0.75 * eps_alpha + 0.25)


def fig_iso6336():
    d = json.loads(run(COMMANDS["iso6336"][0]))
    pts = d["points"]
    single = [p["k"] for p in pts if p["pairs"] == 1]
    double = [p["k"] for p in pts if p["pairs"] >= 2]
    cth, c, cg_lo, cg_hi = iso6336_range(d["teeth"][0], d["teeth"][1], d["contact_ratio"])
    head = ["quantity", "gearsim (N/(mm um))", "ISO 6336-1 (N/(mm um))", "gearsim / ISO"]
    sm = sum(single) / len(single)
    rows = [["single-pair stiffness c'", "%.2f" % sm, "%.2f (c') .. %.2f (c'_th)" % (c, cth),
             "%.2f .. %.2f" % (sm / cth, sm / c)],
            ["mesh stiffness c_gamma_alpha (cycle mean)", "%.2f" % d["k"]["mean"],
             "%.2f .. %.2f" % (cg_lo, cg_hi), "%.2f .. %.2f" % (d["k"]["mean"] / cg_hi, d["k"]["mean"] / cg_lo)],
            ["double-pair mean / single-pair mean", "%.3f" % (sum(double) / len(double) / sm), "", ""],
            ["transverse contact ratio", "%.3f" % d["contact_ratio"], "%.3f" % d["contact_ratio"], ""]]
    return head, rows


def fig_hertz():
    out = run(COMMANDS["hertz"][0])
    head = ["strips N", "half-width a (mm)", "error of a", "peak pressure p0 (MPa)", "error of p0",
            "max |p - p_Hertz| / p0 (|x| < 0.9 a)"]
    rows = []
    for m in re.finditer(r"^#\s+(\d+)\s+([\d.]+)\s+([-+\d.]+)%\s+([\d.]+)\s+([-+\d.]+)%\s+([\d.]+)%", out, re.M):
        n, a, ea, p0, ep, dp = m.groups()
        rows.append([n, a, ea + " %", p0, ep + " %", dp + " %"])
    h = re.search(r"Hertz: a = ([\d.]+) mm, p0 = ([\d.]+) MPa", out)
    if not rows or not h:
        raise RuntimeError("vtest_compliant printed no Hertz table")
    rows.append(["Hertz (closed form)", h.group(1), "", h.group(2), "", ""])
    return head, rows


def fig_lin_parker():
    head = ["planets N", "rotational (Hz, single)", "translational (Hz, double)", "planet (Hz, N - 3 each)",
            "largest relative difference from the paper's model"]
    independent = run(COMMANDS["lin_parker"][3], check=False)  # its comparison lines decide, not its daemon checks
    rows = []
    for n, cmd in zip((3, 4, 5), COMMANDS["lin_parker"]):
        g = json.loads(run(cmd))["groups"]
        cell = [", ".join("%.1f" % x["frequency_hz"] for x in g if x["kind"] == k)
                for k in ("rotational", "translational", "planet")]
        m = re.search(r"ok - N=%d: every natural frequency within [^(]*\(max rel ([\d.e+-]+)\)" % n, independent)
        if not m:
            raise RuntimeError("test_modal.py did not pass its N=%d comparison:\n%s" % (n, independent[-2000:]))
        rows.append([str(n)] + [c or "none" for c in cell] + ["%.0e" % float(m.group(1))])
    return head, rows


def fig_impact():
    out = run(COMMANDS["impact"][0])
    head = ["process", "Newton", "Poisson", "Stronge"]
    rows = []
    for m in re.finditer(r"^# (none|frictionless|sliding|stick_\w+|reversal_\w+)\s+(\d+)\s+(\d+)\s+(\d+)\s*$",
                         out, re.M):
        rows.append(list(m.groups()))
    e = re.search(r"energy created: Newton (\d+) cases, Poisson (\d+) cases, Stronge (\d+)", out)
    c = re.search(r"# (\d+) cases, (\d+) impacts; (\d+) without friction", out)
    if len(rows) != 7 or not e or not c:
        raise RuntimeError("vtest_impact_sweep printed no process table")
    rows.append(["cases that gain kinetic energy"] + list(e.groups()))
    rows.append(["random cases / impacts / all laws agree (1e-11)", c.group(1), c.group(2), c.group(3)])
    return head, rows


def fig_seed():
    out = run(COMMANDS["seed"][0])
    m = re.search(r"seed 7\.1: (\d+) impacts in (\d+) steps \(([\d.]+) ms\); max \|E - E0\|/E0 = ([\d.e+-]+); "
                  r"elastic energy up to ([\d.]+)% of the total; peak normal force (\d+) N; max penetration "
                  r"([\d.]+) um", out)
    head = ["experiment", "quantity", "gearsim", "reference", "reference is"]
    if not m:
        raise RuntimeError("vtest_contact_pair printed no seed 7.1 line")
    rows = [["7.1 impacts", "impacts in 2 ms (h 1e-6 s)", m.group(1), "", ""],
            ["7.1 impacts", "max |E - E0| / E0", "%.1e" % float(m.group(4)), "0", "energy conservation"],
            ["7.1 impacts", "max penetration (um)", m.group(7), "about |v_rel| h", "order of the scheme"],
            ["7.1 impacts", "peak normal force (N)", m.group(6), "", ""]]
    expect = re.search(r"closed-form steady speed M0 \(z2/z1\)/c = ([\d.]+) rad/s", out)
    for label, name in (("coarse", "default mesh"), ("refine 1", "refine 1")):
        r = re.search(r"seed 7\.2: +%s +([-+\d.e]+) +([\d.]+) +([-+\d.e]+) +([-+\d.e]+) +balance ([\d.e+-]+) of "
                      r"([\d.e+-]+) J" % re.escape(label), out)
        if not r or not expect:
            raise RuntimeError("vtest_contact_pair printed no seed 7.2 %s line" % label)
        rows.append(["7.2 drive, %s" % name, "mean speed, 30-60 ms (rad/s)", r.group(2), expect.group(1),
                     "closed form M0 (z2/z1) / c"])
        rows.append(["7.2 drive, %s" % name, "speed oscillation rms / mean", "%.2f %%" % (100 * float(r.group(4))),
                     "", ""])
        rows.append(["7.2 drive, %s" % name, "energy balance residual / energy", "%.1e" % (float(r.group(5))
                     / float(r.group(6))), "0", "energy balance"])
    pen = re.findall(r"h (\de-\d+) s: max penetration ([\d.e+-]+) m", out)
    rate = re.search(r"rate over two decades ([\d.]+)", out)
    for h, p in pen:
        rows.append(["7.1 impacts, first 0.2 ms", "max penetration at h %s s (m)" % h, "%.3e" % float(p), "", ""])
    if not rate or len(pen) != 3:
        raise RuntimeError("vtest_contact_pair printed no penetration study")
    rows.append(["7.1 impacts, first 0.2 ms", "order of penetration in h", rate.group(1), "1",
                 "the scheme's order"])
    f = re.search(r"friction ([\d.]+), [^:]*: balance ([\d.e+-]+) of ([\d.e+-]+) J; .*?mesh efficiency "
                  r"([\d.]+)% \(ISO/TR 14179: H_v ([\d.]+), ([\d.]+)%\)", out)
    if not f:
        raise RuntimeError("vtest_contact_pair printed no friction run")
    rows.append(["7.2 drive, friction %s" % f.group(1), "mesh efficiency, 30-60 ms", f.group(4) + " %",
                 f.group(6) + " %", "ISO/TR 14179, loss factor H_v %s" % f.group(5)])
    rows.append(["7.2 drive, friction %s" % f.group(1), "energy balance residual / energy",
                 "%.1e" % (float(f.group(2)) / float(f.group(3))), "0", "energy balance"])
    return head, rows


def fig_lowspeed():
    out = run(COMMANDS["lowspeed"][0])
    head = ["contact treatment, window", "mean TE (um)", "quasi-static", "error", "rms about the mean (um)",
            "quasi-static", "error", "elastic mean (um)", "quasi-static", "error", "energy balance / scale"]
    rows = []
    for m in re.finditer(r"^# (closure|seed), ([^:]+): mean ([\d.]+) um \(static ([\d.]+), ([-+\d.]+)%\), "
                         r"rms ([\d.]+) um \(static ([\d.]+), ([-+\d.]+)%\), elastic mean ([\d.]+) um "
                         r"\(static ([\d.]+), ([-+\d.]+)%\), balance ([\d.e+-]+)", out, re.M):
        g = m.groups()
        rows.append(["%s, %s" % (g[0], g[1]), g[2], g[3], g[4] + " %", g[5], g[6], g[7] + " %", g[8], g[9],
                     g[10] + " %", g[11]])
    if len(rows) < 2:
        raise RuntimeError("vtest_lowspeed_te printed no comparison:\n" + out[-2000:])
    return head, rows


def fig_modes():
    d = json.loads(run(COMMANDS["modes"][0]))
    head = ["roll", "loaded rows", "FE mesh mode (Hz)", "rotation share", "closed form (Hz)", "FE / closed form",
            "next mode (Hz)"]
    rows = [["%.3f" % p["roll"], str(p["rows"]), "%.1f" % p["hz"][0], "%.4f" % p["rotation"][0],
             "%.1f" % p["lumped_hz"], "%.4f" % (p["hz"][0] / p["lumped_hz"]), "%.1f" % p["hz"][1]]
            for p in d["points"]]
    rows.append(["mean (%d unknowns)" % d["unknowns"], "", "%.1f" % d["mean_hz"], "", "%.1f" % d["lumped_mean_hz"],
                 "%.4f" % (d["mean_hz"] / d["lumped_mean_hz"]), ""])
    return head, rows


def fig_calculix_modal():
    """The first mesh mode against the CalculiX perturbation reference
    (tests/reference/modal_30_20/reference.csv)."""
    ref = list(csv.DictReader(open(os.path.join(ROOT, "tests", "reference", "modal_30_20", "reference.csv"))))
    nf, plain = (json.loads(run(c)) for c in COMMANDS["calculix_modal"])
    head = ["roll", "CalculiX f1 (Hz)", "CalculiX change h -> h/2 %", "near-field (Hz)", "near-field %",
            "plain FE (Hz)", "plain FE %"]
    rows, e0, e1 = [], [], []
    for r in ref:
        j = int(round(float(r["roll"]) * nf["positions"]))
        f0, f1, fr = nf["points"][j]["hz"][0], plain["points"][j]["hz"][0], float(r["f1_hz"])
        e0.append(f0 / fr - 1)
        e1.append(f1 / fr - 1)
        rows.append(["%.3f" % float(r["roll"]), "%.1f" % fr, "%+.3f" % float(r["change_pct"]), "%.1f" % f0,
                     pct(e0[-1]), "%.1f" % f1, pct(e1[-1])])
    rows.append(["max abs error", "", "", "", "%.2f" % (100 * max(map(abs, e0))), "",
                 "%.2f" % (100 * max(map(abs, e1)))])
    return head, rows


FIGURES = {"calculix": fig_calculix, "iso6336": fig_iso6336, "hertz": fig_hertz, "lin_parker": fig_lin_parker,
           "impact": fig_impact, "seed": fig_seed, "lowspeed": fig_lowspeed, "modes": fig_modes,
           "calculix_modal": fig_calculix_modal}


# ---- plots ------------------------------------------------------------------------------------------------

def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _num(s):
    s = s.replace("%", "").strip()
    return float(s) if s else float("nan")


def plot_calculix(head, rows):
    plt = _plt()
    pos = [r for r in rows if re.match(r"^\d\.\d{3}$", r[0])]
    x = [float(r[0]) for r in pos]
    fig, axs = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for ax, (c0, title) in zip(axs, ((1, "20/30 pair"), (4, "20/30 pair, pinion shifted x1 = +0.3"))):
        ax.axhspan(-1, 1, color="0.9", label="within 1 %")
        ax.plot(x, [_num(r[c0 + 1]) for r in pos], "o-", label="default mesh")
        ax.plot(x, [_num(r[c0 + 2]) for r in pos], "s-", label="fine setting")
        ax.axhline(0, color="k", lw=0.8)
        ax.set_title(title)
        ax.set_xlabel("roll position (mesh cycles)")
    axs[0].set_ylabel("k error against CalculiX (%)")
    axs[0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_hertz(head, rows):
    plt = _plt()
    pos = [r for r in rows if r[0].isdigit()]
    n = [int(r[0]) for r in pos]
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    ax.loglog(n, [abs(_num(r[2])) for r in pos], "o-", label="|error of the half-width a| (%)")
    ax.loglog(n, [max(abs(_num(r[4])), 1e-4) for r in pos], "s-", label="|error of the peak pressure| (%; under the printed 0.001 %: drawn at 1e-4)")
    ax.loglog(n, [max(_num(r[5]), 1e-4) for r in pos], "^-", label="max pressure deviation / p0 (%; likewise)")
    ax.set_xlabel("strips N")
    ax.set_ylabel("%")
    ax.legend(fontsize=8)
    ax.set_title("Compliant patch against Hertz (line contact)")
    fig.tight_layout()
    return fig


def plot_impact(head, rows):
    plt = _plt()
    pr = [r for r in rows[:7] if r[0] != "none"]
    fig, ax = plt.subplots(figsize=(6.5, 3.6))
    ax.barh([r[0].replace("_", " ") for r in pr], [int(r[3]) for r in pr])
    ax.set_xlabel("cases (identical under Newton, Poisson and Stronge)")
    ax.set_title("Routh's processes in 40 000 random impacts")
    fig.tight_layout()
    return fig


def plot_lowspeed(head, rows):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.6))
    labels = ["mean TE", "rms about the mean", "elastic mean"]
    w = 0.35
    for i, r in enumerate(rows[:2]):
        ax.bar([j + i * w for j in range(3)], [abs(_num(r[c])) for c in (3, 6, 9)], w, label=r[0])
    ax.axhline(5, color="r", ls="--", lw=1, label="rms bar 5 %")
    ax.axhline(1, color="r", ls=":", lw=1, label="mean bars 1 %")
    ax.set_xticks([j + w / 2 for j in range(3)], labels)
    ax.set_ylabel("|dynamic - quasi-static| (%)")
    ax.legend(fontsize=8)
    ax.set_title("contact_drive at 141 Hz mesh frequency")
    fig.tight_layout()
    return fig


PLOTS = {"calculix": plot_calculix, "hertz": plot_hertz, "impact": plot_impact, "lowspeed": plot_lowspeed}


# ---- files and checks -------------------------------------------------------------------------------------

def csv_path(name):
    return os.path.join(HERE, "validation_%s.csv" % name)


def read(name):
    with open(csv_path(name), newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def write(name, head, rows):
    with open(csv_path(name), "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(head)
        w.writerows(rows)


def plot(name, head, rows):
    if name in PLOTS:
        os.makedirs(IMG["validation"], exist_ok=True)
        fig = PLOTS[name](head, rows)
        out = os.path.join(IMG["validation"], "%s.png" % name)
        fig.savefig(out, dpi=110)
        print("wrote", os.path.relpath(out, ROOT))


NUM = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?", re.I)


def same_cell(a, b, rtol, atol):
    """Text equal once the numbers are taken out; each number within tolerance."""
    if NUM.sub("#", a) != NUM.sub("#", b):
        return False
    for x, y in zip(NUM.findall(a), NUM.findall(b)):
        x, y = float(x), float(y)
        if abs(x - y) > atol + rtol * max(abs(x), abs(y)):
            return False
    return True


def compare(name, head, rows):
    """Differences between a rerun (head, rows) and the stored file."""
    h0, r0 = read(name)
    rtol, atol = TOLERANCE[name]
    bad = []
    if h0 != head:
        bad.append("header %s != stored %s" % (head, h0))
    if len(r0) != len(rows):
        bad.append("%d rows, stored %d" % (len(rows), len(r0)))
    for a, b in zip(rows, r0):
        for i, (x, y) in enumerate(zip(a, b)):
            if not same_cell(x, y, rtol, atol):
                bad.append("row '%s', column '%s': rerun %r, stored %r" % (b[0], h0[i] if i < len(h0) else i, x, y))
    return bad


def main(argv):
    if not argv or argv[0] not in ("write", "check", "plot", "list"):
        print(__doc__)
        return 2
    mode, names = argv[0], argv[1:] or CHEAP
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        print("unknown figure(s): %s (known: %s)" % (", ".join(unknown), ", ".join(FIGURES)))
        return 2
    if mode == "list":
        for n in names:
            print("%s (%s; tolerance rel %g abs %g):" % (n, "cheap" if n in CHEAP else "long", *TOLERANCE[n]))
            for c in COMMANDS[n]:
                print("    " + c)
        return 0
    failed = 0
    for n in names:
        if mode == "plot":
            plot(n, *read(n))
            continue
        try:
            head, rows = FIGURES[n]()
        except (OSError, RuntimeError, ValueError, KeyError) as e:
            print("FAIL: %s\n    %s" % (n, str(e).replace("\n", "\n    ")))
            failed += 1
            continue
        if mode == "write":
            write(n, head, rows)
            print("wrote", os.path.relpath(csv_path(n), ROOT))
            plot(n, head, rows)
        else:
            bad = compare(n, head, rows)
            print("%s: %s" % ("ok" if not bad else "FAIL", n))
            for b in bad:
                print("    " + b)
            failed += bool(bad)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
