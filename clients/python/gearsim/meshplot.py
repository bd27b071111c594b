# SPDX-License-Identifier: MIT
"""Drawings of gear meshes written by gearsim-mesh (HDF5 layout in
include/gearsim/mesh_io.h and docs/explanation/geometry.md).

    from gearsim.meshplot import plot_mesh
    plot_mesh("mesh.h5", "mesh.png")                       # every gear, placed
    plot_mesh("mesh.h5", "tooth.png", zoom_tooth="sun")    # plus a zoom on one tooth

Needs numpy, h5py and matplotlib (Debian: python3-numpy python3-h5py
python3-matplotlib); draws with the Agg backend, no display needed.
"""
import math

NODE_FLANK, NODE_FILLET, NODE_ROOT, NODE_TIP, NODE_CORE = 1, 2, 3, 4, 5

_COLOURS = ["#4C72B0", "#DD8452", "#55A868", "#C44E52", "#8172B3", "#937860",
            "#DA8BC3", "#8C8C8C", "#CCB974", "#64B5CD"]


def read_meshes(h5_path):
    """The gears of a mesh file, in file order: a list of dicts with name,
    xy (placed, n x 2), tri (m x 3), tag, fixed, flank_ptr, flank_nodes,
    centre, rotation and the gear attributes (kind, teeth, module_m, ...)."""
    import h5py
    import numpy as np
    out = []
    with h5py.File(h5_path, "r") as f:
        if f.attrs.get("format", b"") not in (b"gearsim-mesh", "gearsim-mesh"):
            raise ValueError(f"{h5_path} is not a gearsim mesh file")
        for name, g in f["gears"].items():
            d = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in g.attrs.items()}
            d["name"] = name
            d["xy"] = np.asarray(g["nodes_placed"])
            d["xy_body"] = np.asarray(g["nodes"])
            d["tri"] = np.asarray(g["triangles"])
            # quadratic meshes: Triangle_6 connectivity (corners, mid-side nodes)
            d["tri6"] = np.asarray(g["triangles6"]) if "triangles6" in g else None
            d["tag"] = np.asarray(g["node_tag"])
            d["fixed"] = np.asarray(g["fixed"])
            d["flank_ptr"] = np.asarray(g["flank_ptr"])
            d["flank_nodes"] = np.asarray(g["flank_nodes"])
            d["centre"] = np.asarray(d.get("centre_m", [0.0, 0.0]), dtype=float)
            d["rotation"] = float(d.get("rotation_rad", 0.0))
            out.append(d)
    out.sort(key=lambda d: int(d.get("index", 0)))
    return out


def _draw(ax, gears, lw, marks):
    from matplotlib.collections import PolyCollection
    for i, g in enumerate(gears):
        col = _COLOURS[int(g.get("index", i)) % len(_COLOURS)]
        xy = g["xy"] * 1e3
        if g.get("tri6") is not None:
            # curved edges: each edge the parabola through its corners and
            # mid-side node, drawn with 4 chords
            import numpy as np
            t6 = g["tri6"]
            s = np.linspace(0.0, 1.0, 5)[:-1]
            pieces = []
            for a, b, m in ((0, 1, 3), (1, 2, 4), (2, 0, 5)):
                pa, pb, pm = xy[t6[:, a]], xy[t6[:, b]], xy[t6[:, m]]
                for u in s:
                    pieces.append(((1 - u) * (1 - 2 * u))[None] * pa + (4 * u * (1 - u)) * pm
                                  + (u * (2 * u - 1)) * pb)
            polys = np.stack(pieces, axis=1)
        else:
            polys = xy[g["tri"]]
        ax.add_collection(PolyCollection(polys, facecolors=col, alpha=0.25, edgecolors="none"))
        ax.add_collection(PolyCollection(polys, facecolors="none", edgecolors="k", linewidths=lw))
        if marks:
            t = g["tag"]
            for tag, c, lab in ((NODE_FLANK, "#d62728", "flank"), (NODE_FILLET, "#1f77b4", "fillet"),
                                (NODE_ROOT, "#2ca02c", "root"), (NODE_TIP, "#9467bd", "tip"),
                                (NODE_CORE, "#17becf", "core (fixed)")):
                s = t == tag
                if s.any():
                    ax.plot(xy[s, 0], xy[s, 1], ".", color=c, ms=3.5,
                            label=lab if i == 0 else None)
        c = g["centre"] * 1e3
        ax.plot([c[0]], [c[1]], "+", color="k", ms=6)
        # tooth 0 marker: a short line from the centre along its axis
        if "pitch_radius_m" in g:
            r = float(g["pitch_radius_m"]) * 1e3
            a = g["rotation"]
            ax.plot([c[0], c[0] + 0.25 * r * math.cos(a)], [c[1], c[1] + 0.25 * r * math.sin(a)],
                    "-", color=col, lw=1.2)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")


def _pick_tooth(gears, zoom_tooth):
    """(gear, tooth index) for the zoom: tooth of the named gear (or of the
    first) that points towards the nearest other gear, unless given."""
    import numpy as np
    if isinstance(zoom_tooth, (tuple, list)):
        name, tooth = zoom_tooth[0], int(zoom_tooth[1])
    elif isinstance(zoom_tooth, int) and not isinstance(zoom_tooth, bool):
        name, tooth = gears[0]["name"], zoom_tooth
    else:
        name, tooth = str(zoom_tooth), None
    g = next((x for x in gears if x["name"] == name), None)
    if g is None:
        raise ValueError(f"no gear named {name!r} in the mesh file "
                         f"({', '.join(x['name'] for x in gears)})")
    z = int(g.get("teeth", max(1, (len(g["flank_ptr"]) - 1) // 2)))
    if tooth is None:
        tooth = 0
        others = [x for x in gears if x is not g and np.hypot(*(x["centre"] - g["centre"])) > 0]
        internal = g.get("kind") == "internal"
        if others:
            o = min(others, key=lambda x: np.hypot(*(x["centre"] - g["centre"])))
            v = o["centre"] - g["centre"]
            ang = math.atan2(v[1], v[0])
            tooth = int(round((ang - g["rotation"]) * z / (2 * math.pi))) % z
        elif internal:
            tooth = 0
    return g, tooth % z, z


def plot_mesh(h5_path, png_path, zoom_tooth=None, dpi=150, title=None, overview=True):
    """Draw every gear of the mesh file h5_path, placed and in mesh, to
    png_path. zoom_tooth: None (whole set only), a gear name (adds a panel
    zoomed on the tooth of that gear facing its nearest neighbour), a
    (name, tooth) pair, or a tooth index of the first gear. With a zoom and
    overview=False only the zoom is drawn. Returns png_path."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    gears = read_meshes(h5_path)
    if not gears:
        raise ValueError(f"{h5_path} holds no gear")
    n_nodes = sum(len(g["xy"]) for g in gears)
    n_tris = sum(len(g["tri"]) for g in gears)
    import textwrap
    head = title or "\n".join(textwrap.wrap(
        ", ".join(f"{g['name']} (z={g.get('teeth', '?')}{', internal' if g.get('kind') == 'internal' else ''})"
                  for g in gears), 90))
    if zoom_tooth is None:
        fig, ax = plt.subplots(figsize=(8, 8))
        _draw(ax, gears, 0.15 if n_tris > 20000 else 0.3, marks=False)
        ax.set_title(f"{head}\n{n_nodes} nodes, {n_tris} {'quadratic 6-node' if any(g.get('tri6') is not None for g in gears) else 'linear'} triangles", fontsize=9)
    else:
        g, tooth, z = _pick_tooth(gears, zoom_tooth)
        if overview:
            fig, (ax, az) = plt.subplots(1, 2, figsize=(15, 7.5))
            _draw(ax, gears, 0.15 if n_tris > 20000 else 0.3, marks=False)
            ax.set_title(f"{head}\n{n_nodes} nodes, {n_tris} {'quadratic 6-node' if any(g.get('tri6') is not None for g in gears) else 'linear'} triangles", fontsize=9)
        else:
            fig, az = plt.subplots(figsize=(8, 8))
        others = [x for x in gears if x is not g]
        if others:   # the neighbours, faint, to show the teeth in mesh
            _draw(az, others, 0.3, marks=False)
        _draw(az, [g], 0.5, marks=True)
        m = float(g.get("module_m", 0.0)) * 1e3
        r = float(g.get("pitch_radius_m", 0.0)) * 1e3
        if m <= 0 or r <= 0:   # no gear attributes: use the mesh extent
            ext = np.ptp(g["xy"], axis=0).max() * 1e3
            m, r = ext / 20, ext / 2
        a = g["rotation"] + 2 * math.pi * tooth / z
        c = g["centre"] * 1e3 + r * np.array([math.cos(a), math.sin(a)])
        w = 2.2 * m
        az.set_xlim(c[0] - w, c[0] + w)
        az.set_ylim(c[1] - w, c[1] + w)
        # mark the flank tables of the zoomed tooth: order root -> tip
        fp, fn = g["flank_ptr"], g["flank_nodes"]
        if len(fp) >= 2 * tooth + 3:
            xy = g["xy"] * 1e3
            for s, cl in ((0, "#d62728"), (1, "#ff7f0e")):
                ids = fn[fp[2 * tooth + s]:fp[2 * tooth + s + 1]]
                if len(ids):
                    az.plot(xy[ids, 0], xy[ids, 1], "-", color=cl, lw=1.6,
                            label=f"flank {s} ({'left' if s == 0 else 'right'}), root to tip")
                    az.annotate("", xy=xy[ids[-1]], xytext=xy[ids[-2]] if len(ids) > 1 else xy[ids[0]],
                                arrowprops=dict(arrowstyle="->", color=cl, lw=1.6))
        az.legend(loc="lower left", fontsize=7, framealpha=0.9)
        az.set_title(f"{g['name']}: tooth {tooth} of {z} ({len(g['xy'])} nodes, "
                     f"{len(g['tri'])} triangles in this gear)", fontsize=9)
    fig.tight_layout()
    fig.savefig(png_path, dpi=dpi)
    plt.close(fig)
    return png_path
