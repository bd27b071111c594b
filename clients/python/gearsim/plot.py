# SPDX-License-Identifier: MIT
"""The plots of gearctl (PNG files through matplotlib's Agg backend):
mesh stiffness and TE, the Harris map, mode shapes, sweep responses and the
trade-off Pareto plot. matplotlib is imported on first use (ImportError
when it is not installed: Debian package python3-matplotlib)."""
import csv
import math


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_stiffness(res, path):
    """Mesh stiffness and transmission error against roll angle (one mesh cycle)."""
    plt = _pyplot()
    pts = res["points"]
    ang = [p["angle_deg"] for p in pts]
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    a1.plot(ang, [p["k"] for p in pts], "o-", label="secant k = F / TE")
    if all(p.get("k_tan") is not None for p in pts):
        a1.plot(ang, [p["k_tan"] for p in pts], "s--", ms=3, label="tangent dF/dTE (F/2 to F)")
    a1.set_ylabel("mesh stiffness, N/(mm um)")
    a1.legend(loc="best", fontsize=8)
    a1.grid(True, alpha=0.3)
    a2.plot(ang, [p.get("te_loaded_um", p.get("te_um")) for p in pts], "o-", color="tab:red",
            label="loaded static TE")
    if res.get("modified"):
        a2.plot(ang, [p.get("te_elastic_um", p.get("te_um")) for p in pts], "s--", ms=3, color="tab:gray",
                label="elastic part (without the modifications' geometric TE)")
        a2.legend(loc="best", fontsize=8)
    a2.set_ylabel("loaded static TE, um")
    a2.set_xlabel(f"driver roll angle, deg (one mesh cycle = {360.0 / res['teeth'][0]:.4g} deg)")
    a2.grid(True, alpha=0.3)
    for ax in (a1, a2):
        for x0, p in zip(ang, pts):
            if p["pairs"] >= 2:
                ax.axvspan(x0 - 0.5 * (ang[1] - ang[0] if len(ang) > 1 else 1), x0 + 0.5 * (ang[1] - ang[0] if len(ang) > 1 else 1),
                           color="0.9", lw=0, zorder=0)
    fig.suptitle(f"{res['mesh']}: {res['driver']} (z={res['teeth'][0]}) drives {res['driven']} (z={res['teeth'][1]}), "
                 f"T = {res['torque_nm']:.3g} N m, b = {res['face_width_mm']:.3g} mm, refine {res['refine'][0]}\n"
                 f"k min/mean/max {res['k']['min']:.2f}/{res['k']['mean']:.2f}/{res['k']['max']:.2f} N/(mm um); "
                 f"shaded: two pairs in contact", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)



def plot_harris(out, path, relief_given=False):
    """The Harris map: peak-to-peak static TE against line load, one line per relief."""
    plt = _pyplot()
    rows = out["rows"]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    from .harris import series_labels
    for lab in series_labels(rows):
        rr = [r for r in rows if r["label"] == lab]
        ax.plot([r["line_load_n_per_mm"] for r in rr], [r["te_loaded_pp_um"] for r in rr], "o-",
                label=("relief " + lab) if relief_given else lab)
    ax.set_xlabel("line load, N/mm")
    ax.set_ylabel("peak-to-peak static TE, um")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"Harris map, {out['mesh']}: z {out['teeth'][0]}/{out['teeth'][1]}, {out['relief_shape']} tip relief "
                 f"on both gears over {out['relief_length_mm']:.3g} mm of roll,\n{out['positions']} positions, "
                 f"refine {out['refine'][0]}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_modes(res, path, max_groups=16):
    """Mode shapes, one panel per group of equal frequency (its first mode):
    every body drawn at its centre, grey undeformed, coloured displaced by
    the shape (translation and rotation, exaggerated)."""
    plt = _pyplot()
    groups = res["groups"][:max_groups]
    modes = res.get("modes") or []
    bodies = {b["name"]: b for b in res["bodies"]}
    extent = max(math.hypot(*b["centre"]) + b["radius"] for b in res["bodies"]) or 1.0
    amp = 0.12 * extent
    ncol = min(4, len(groups))
    nrow = (len(groups) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.2 * ncol, 3.3 * nrow), squeeze=False)
    colours = {"rotational": "tab:blue", "translational": "tab:red", "planet": "tab:green", "mixed": "tab:purple"}
    for k, g in enumerate(groups):
        ax = axes[k // ncol][k % ncol]
        ax.set_aspect("equal")
        ax.axis("off")
        ax.set_title(f"{g['frequency_hz']:.1f} Hz {g['kind']} x{g['multiplicity']}", fontsize=8)
        mode = modes[g["first_mode"]] if g["first_mode"] < len(modes) else None
        for b in res["bodies"]:
            cx, cy = b["centre"]
            r = b["radius"] if b["radius"] > 0 else 0.05 * extent
            ax.add_patch(plt.Circle((cx, cy), r, fill=False, color="0.8", lw=0.8))
        if not mode:
            continue
        for sh in mode["shape"]:
            b = bodies[sh["body"]]
            cx, cy = b["centre"]
            r = b["radius"] if b["radius"] > 0 else 0.05 * extent
            x, y = cx + amp * sh["x"], cy + amp * sh["y"]
            th = amp * sh["u"] / r if r > 0 else 0.0
            col = colours.get(g["kind"], "k")
            ax.add_patch(plt.Circle((x, y), r, fill=False, color=col, lw=1.2))
            ax.plot([x, x + r * math.cos(math.pi / 2 + th)], [y, y + r * math.sin(math.pi / 2 + th)], color=col, lw=1.0)
        ax.set_xlim(-1.25 * extent, 1.25 * extent)
        ax.set_ylim(-1.25 * extent, 1.25 * extent)
    for k in range(len(groups), nrow * ncol):
        axes[k // ncol][k % ncol].axis("off")
    fig.suptitle(f"{res['scene']}: mode shapes (grey: at rest; line: rotation)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)



def plot_sweep(res, rows, xkey, path, title):
    """Response against the mesh frequency (or the first parameter): DTE rms,
    dynamic factor and load-sharing factor, natural frequencies marked (and
    their halves and thirds: harmonics of the mesh frequency)."""
    plt = _pyplot()
    keys = [k for k in ("dte_rms_um", "dynamic_factor", "lsf") if any(r.get(k) is not None for r in rows)]
    labels = {"dte_rms_um": "DTE rms, um", "dynamic_factor": "dynamic factor", "lsf": "load-sharing factor"}
    fig, axes = plt.subplots(len(keys), 1, figsize=(7, 2.2 + 1.6 * len(keys)), sharex=True, squeeze=False)
    xs = [r[xkey] for r in rows]
    lo, hi = min(xs), max(xs)
    for ax, k in zip(axes[:, 0], keys):
        ax.plot(xs, [r[k] for r in rows], "o-", ms=3)
        ax.set_ylabel(labels[k])
        if xkey != "mesh_hz":
            continue
        for m in res["modes"]:
            for h in (1, 2, 3):
                f = m["frequency_hz"] / h
                if lo <= f <= hi:
                    ax.axvline(f, color="tab:red" if h == 1 else "tab:orange", lw=0.8, ls="--")
                    if k == keys[0]:
                        ax.text(f, ax.get_ylim()[1], f" {m['kind'][0]} {m['frequency_hz']:.0f}" + (f"/{h}" if h > 1 else ""),
                                fontsize=7, rotation=90, va="top")
    axes[-1, 0].set_xlabel("mesh frequency, Hz" if xkey == "mesh_hz" else xkey)
    axes[0, 0].set_title(f"sweep: {title} (dashed: natural frequencies, orange: /2, /3)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)



def plot_tradeoff(csv_path, png):
    """Pareto plot: wall time per simulated second against the error of the
    output speed and of the dynamic transmission error, per scene."""
    plt = _pyplot()
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    scenes = sorted({r["scene"] for r in rows})
    fig, axes = plt.subplots(len(scenes), 2, figsize=(11, 4.2 * len(scenes)), squeeze=False)
    known = {"kinematic": "o", "impact": "v", "lumped": "s", "calibrated": "D", "ltca": "X", "compliant": "P",
             "adaptive": "*", "contact_seed": "<", "contact": "^"}
    # every level of the table, in the ladder's order, unknown ones after
    levels = [lv for lv in known if any(r["level"] == lv for r in rows)]
    levels += sorted({r["level"] for r in rows} - set(known))
    marks = {lv: known.get(lv, "x") for lv in levels}
    colours = {lv: f"C{k % 10}" for k, lv in enumerate(levels)}  # the same in every panel
    for i, sc in enumerate(scenes):
        for j, (key, label) in enumerate((("err_speed", "output speed error vs reference"),
                                          ("err_dte", "DTE rms error vs reference"))):
            ax = axes[i][j]
            for lv in marks:
                # the reference row (error 0 by definition) is not a point
                pts = [r for r in rows if r["scene"] == sc and r["level"] == lv and float(r[key]) > 0]
                if not pts:
                    continue
                xs = [float(r["cost"]) for r in pts]
                ys = [float(r[key]) for r in pts]
                ax.loglog(xs, ys, marks[lv], color=colours[lv], label=lv, ms=7)
                for r, x, y in zip(pts, xs, ys):
                    ax.annotate(f"h {float(r['h']):g}" + (f" r{r['refine']}" if r["refine"] != "0" else "")
                                + (f" s{float(r['scale']):g}" if float(r.get("scale") or 1) != 1 else ""),
                                (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
            ax.set_xlabel("CPU seconds per simulated second" if "zeta" in rows[0] else "wall seconds per simulated second")
            ax.set_ylabel(label)
            ax.set_title(sc)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
