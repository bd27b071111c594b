# SPDX-License-Identifier: MIT
"""Read a gearsim HDF5 record and plot it.

Layout (written by gearsimd's `record`):
  file attributes  scene (JSON text), gearsim_version
  /telemetry       time (n), step (n, int64),
                   energy (n x 7; attribute columns: kinetic, potential, total,
                   work_in, dissipated, balance_residual, contact_work),
                   angle (n x nbodies), omega (n x nbodies), mesh_force (n x nmeshes);
                   group attributes bodies, meshes (JSON lists of names)
Attributes may be stored as strings or bytes; both are accepted. Set
HDF5_USE_FILE_LOCKING=FALSE to read a file the daemon still has open."""
import json
import math
import os

ENERGY_COLUMNS = ["kinetic", "potential", "total", "work_in", "dissipated", "balance_residual", "contact_work"]


def _text(v):
    if isinstance(v, bytes):
        return v.decode()
    if hasattr(v, "tolist") and not isinstance(v, str):   # numpy scalar or array of strings
        v = v.tolist()
        if isinstance(v, bytes):
            return v.decode()
        if isinstance(v, list):
            return [x.decode() if isinstance(x, bytes) else x for x in v]
    return v


def _names(v):
    v = _text(v)
    if isinstance(v, str):
        return json.loads(v)
    return list(v)


def _matrix(a, n):
    """(n x k) view of a per-row dataset; a 1-D dataset of n rows is one column."""
    return a.reshape(n, -1) if a.ndim == 1 else a


def read_record(path):
    """The record as a dict of numpy arrays and lists (see the module doc)."""
    os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
    import h5py
    import numpy as np
    with h5py.File(path, "r") as f:
        g = f["telemetry"]
        rec = {
            "scene": json.loads(_text(f.attrs["scene"])) if "scene" in f.attrs else None,
            "gearsim_version": _text(f.attrs.get("gearsim_version", "")),
            "time": np.asarray(g["time"][()], dtype=float),
            "step": np.asarray(g["step"][()]),
            "energy": np.asarray(g["energy"][()], dtype=float),
            "columns": _names(g["energy"].attrs["columns"]) if "columns" in g["energy"].attrs else ENERGY_COLUMNS,
            "angle": np.asarray(g["angle"][()], dtype=float),
            "omega": np.asarray(g["omega"][()], dtype=float),
            "bodies": _names(g.attrs["bodies"]),
            "mesh_force": np.asarray(g["mesh_force"][()], dtype=float) if "mesh_force" in g else None,
            "meshes": _names(g.attrs["meshes"]) if "meshes" in g.attrs else [],
        }
    n = rec["time"].shape[0]
    for k in ("energy", "angle", "omega", "mesh_force"):
        if rec[k] is not None:
            rec[k] = _matrix(rec[k], n)
    return rec


def plot_record(h5_path, png_path, title=None):
    """Energies (top) and rpm of each body (bottom) against time; returns png_path."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rec = read_record(h5_path)
    t = rec["time"]
    fig, (ax_e, ax_w) = plt.subplots(2, 1, sharex=True, figsize=(9, 7), constrained_layout=True)
    ncols = rec["energy"].shape[1] if rec["energy"].ndim == 2 else 0
    for j, name in enumerate(rec["columns"][:ncols]):
        ax_e.plot(t, rec["energy"][:, j], label=name.replace("_", " "),
                  linestyle="--" if name == "balance_residual" else "-")
    ax_e.set_ylabel("energy (J)")
    ax_e.legend(loc="best", fontsize="small")
    ax_e.grid(True, alpha=0.3)
    rpm = rec["omega"] * (60.0 / (2.0 * math.pi))
    for i, name in enumerate(rec["bodies"]):
        if rpm.ndim == 2 and i < rpm.shape[1]:
            ax_w.plot(t, rpm[:, i], label=name)
    ax_w.set_ylabel("speed (rpm)")
    ax_w.set_xlabel("time (s)")
    ax_w.legend(loc="best", fontsize="small")
    ax_w.grid(True, alpha=0.3)
    scene_name = (rec["scene"] or {}).get("name", "") if isinstance(rec["scene"], dict) else ""
    fig.suptitle(title or f"gearsim record {os.path.basename(h5_path)}" + (f" - {scene_name}" if scene_name else ""))
    fig.savefig(png_path, dpi=110)
    plt.close(fig)
    return png_path
