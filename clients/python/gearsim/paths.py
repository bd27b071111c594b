# SPDX-License-Identifier: MIT
"""Where gearctl finds its data and the build's tools.

Three layouts: the source checkout (clients/python/gearsim beside
deploy/scenes and docs/data/tradeoff.csv, the tools in build/src/tools), a
`meson install` prefix P (the package in P/lib/python3/dist-packages, the
data in P/share/gearsim, the tools in P/bin), and a pip install (the package
in some site-packages: the data of the meson install whose gearsimd is on
PATH, else under /usr/local or /usr; the tools on PATH)."""
import os
import shutil

PKG = os.path.dirname(os.path.realpath(__file__))


def _checkout_root(pkg):
    root = os.path.normpath(os.path.join(pkg, "..", "..", ".."))
    if os.path.isdir(os.path.join(root, "deploy", "scenes")) and os.path.isdir(os.path.join(root, "clients", "python")):
        return root
    return None


def layout(pkg=PKG, extra_prefixes=()):
    """Dict of data paths: scenes (directory of the example scenes), table
    (the measured trade-off CSV), tools (directory of gearsim-* tools, or
    None: PATH only), build (the checkout's build directory or None)."""
    root = _checkout_root(pkg)
    if root:
        return {"scenes": os.path.join(root, "deploy", "scenes"),
                "table": os.path.join(root, "docs", "data", "tradeoff.csv"),
                "tools": os.path.join(root, "build", "src", "tools"),
                "build": os.path.join(root, "build")}
    # P/lib/python3/dist-packages/gearsim -> P; then the prefix of the
    # gearsimd on PATH (a pip install beside a meson install), then others
    prefixes = [os.path.normpath(os.path.join(pkg, "..", "..", "..", ".."))]
    prefixes += [os.path.normpath(p) for p in extra_prefixes]
    daemon = shutil.which("gearsimd")
    if daemon:
        prefixes.append(os.path.dirname(os.path.dirname(os.path.realpath(daemon))))
    prefixes += ["/usr/local", "/usr"]
    for p in prefixes:
        share = os.path.join(p, "share", "gearsim")
        if os.path.isdir(os.path.join(share, "scenes")):
            return {"scenes": os.path.join(share, "scenes"), "table": os.path.join(share, "tradeoff.csv"),
                    "tools": os.path.join(p, "bin"), "build": None}
    share = os.path.join(prefixes[0], "share", "gearsim")
    return {"scenes": os.path.join(share, "scenes"), "table": os.path.join(share, "tradeoff.csv"),
            "tools": None, "build": None}


DATA = layout()


def find_tool(name, data=None):
    """A build tool: on PATH, else $GEARSIM_BUILD_ROOT/src/tools, else the
    layout's tools directory (build/src/tools of the checkout, P/bin)."""
    data = data or DATA
    p = shutil.which(name)
    if p:
        return p
    dirs = []
    if os.environ.get("GEARSIM_BUILD_ROOT"):
        dirs.append(os.path.join(os.environ["GEARSIM_BUILD_ROOT"], "src", "tools"))
    if data.get("tools"):
        dirs.append(data["tools"])
    for d in dirs:
        p = os.path.join(d, name)
        if os.access(p, os.X_OK):
            return os.path.abspath(p)
    return None


def tool_missing(name):
    return f"{name} not found (on PATH, in $GEARSIM_BUILD_ROOT/src/tools or build/src/tools)"


def scene_file(spec, data=None):
    """SCENE.json as given; builtin:NAME as the file of that example scene
    (the checkout's deploy/scenes or the installed share/gearsim/scenes).
    ValueError when there is none."""
    data = data or DATA
    if not spec.startswith("builtin:"):
        return spec
    name = spec[len("builtin:"):]
    path = os.path.join(data["scenes"], name + ".json")
    if not name or "/" in name or not os.path.isfile(path):
        raise ValueError(f"no scene file for {spec} in {data['scenes']}")
    return path
