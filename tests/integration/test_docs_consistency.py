#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Docs and schemas agree with the daemon (its `hello`, its command table
and its error table):

* commands: hello.commands (the command table of src/service/commands.c) =
  the `cmd` enum of proto/v1/request.json = its `allOf` dispatch =
  proto/v1/requests/*.json = proto/v1/results/*.json = the command tables
  of proto/v1/README.md and docs/reference/protocol.md = Client methods of the Python
  package (by name, where one exists);
* limits: every hello.limits entry is in proto/v1/results/hello.json and
  named in docs/reference/protocol.md and proto/v1/README.md;
* builtin scenes: hello.builtin_scenes = deploy/scenes/*.json, each named in
  README.md and docs/reference/protocol.md mentions `hello.builtin_scenes`;
* error codes: the wire codes of include/gearsim/error.h = the error_code
  enum of proto/v1/common.json = the list in docs/reference/protocol.md;
* options: every long option of `gearsimd --help` is in its man page and in
  docs/RELIABILITY.md or README.md; every gearctl command in gearctl(1) and
  clients/README.md."""
import glob
import json
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from daemon import SOURCE_ROOT, Daemon, gearsimd_path  # noqa: E402
from harness import Results  # noqa: E402

# Codes of error.h that never reach the wire: GS_OK, and GS_EREFINE (the
# step's request to retry with a smaller step, handled inside the engine).
NOT_ON_WIRE = {"ok", "refine"}


def src(*p):
    return os.path.join(SOURCE_ROOT, *p)


def read(*p):
    with open(src(*p)) as f:
        return f.read()


def table_commands(md):
    """First-column `cmd` names of the command table(s) of a Markdown text
    (rows like | `a` / `b` | or | `a`, `b` |)."""
    out = set()
    in_table = False
    for ln in md.splitlines():
        if re.match(r"^\|\s*cmd\s*\|", ln):
            in_table = True
            continue
        if in_table:
            if not ln.startswith("|"):
                in_table = False
                continue
            first = ln.split("|")[1]
            out.update(re.findall(r"`([a-z_]+)`", first))
    return out


def diff(a, b):
    return f"only in first: {sorted(set(a) - set(b))}; only in second: {sorted(set(b) - set(a))}"


# The stiffness analysis' outputs: the loaded static TE is te_loaded_um (JSON
# and HDF5 datasets, te_loaded_* HDF5 attributes and CSV columns), its elastic
# part te_elastic_um; te_um is the elastic part's former name, kept for one
# release as an equal alias (JSON key, HDF5 soft link, te_min/mean/max attrs).
TE_NAMES = ("te_loaded_um", "te_elastic_um")
TE_ALIAS = "te_um"


def names_check(R, r, rr, h5):
    """The TE names in the daemon's stiffness result, its HDF5 file, the
    result schema and the outputs page."""
    pts = r.get("points", [])
    R.check("stiffness result: te_loaded_um and te_elastic_um per point and as ranges",
            all(n in r and all(n in p for p in pts) for n in TE_NAMES), sorted(r))
    R.check("stiffness result: te_um is an equal alias of te_elastic_um (points and range)",
            r.get(TE_ALIAS) == r.get("te_elastic_um")
            and all(p.get(TE_ALIAS) == p.get("te_elastic_um") for p in pts), r.get(TE_ALIAS))
    R.check("stiffness result of an unmodified pair: the loaded static TE equals its elastic part",
            r.get("modified") is False and all(p["te_loaded_um"] == p["te_elastic_um"] for p in pts), pts)
    try:
        import h5py
        with h5py.File(h5, "r") as f:
            g = f["stiffness"]
            link = g.get(TE_ALIAS, getlink=True)
            R.check("stiffness HDF5: datasets te_loaded_um, te_elastic_um; te_um a soft link to te_elastic_um",
                    all(n in g for n in TE_NAMES) and isinstance(link, h5py.SoftLink)
                    and link.path == "te_elastic_um" and list(g[TE_ALIAS][()]) == list(g["te_elastic_um"][()]),
                    sorted(g))
            want = [f"te_{w}_{s}" for w in ("loaded", "elastic") for s in ("min", "mean", "max")]
            R.check("stiffness HDF5: attributes te_loaded_min/mean/max, te_elastic_min/mean/max and the "
                    "former te_min/mean/max equal to te_elastic_*",
                    all(a in g.attrs for a in want)
                    and all(g.attrs[f"te_{s}"] == g.attrs[f"te_elastic_{s}"] for s in ("min", "mean", "max")),
                    sorted(g.attrs))
    except ImportError:
        R.skip("stiffness HDF5 names", "python3-h5py is not installed")
    R.check("stiffness with path: the same TE names", all(n in rr for n in TE_NAMES), sorted(rr))
    schema = json.loads(read("proto", "v1", "results", "stiffness.json"))
    props = schema["properties"]
    item = props["points"]["items"]["properties"]
    R.check("results/stiffness.json: te_loaded_um, te_elastic_um documented (points and ranges), te_um "
            "described as the former name", all(n in props and n in item for n in TE_NAMES)
            and "former name" in item[TE_ALIAS].get("description", "")
            and "former name" in props[TE_ALIAS].get("description", ""), sorted(item))
    outputs = read("docs", "reference", "outputs.md")
    R.check("docs/reference/outputs.md names te_loaded_um, te_elastic_um and te_um as their alias",
            all(f"`{n}`" in outputs for n in TE_NAMES + (TE_ALIAS,)) and "alias" in outputs)


def main():
    R = Results("docs and schemas against the daemon's hello, command table and error table")
    with Daemon(ranks=1) as d:
        hello = d.hello
        # Client.stiffness (added with the command's schema entry) works
        with d.client() as c:
            c.load(builtin="stiffness_pair")
            mesh = c.state()["meshes"][0]["name"]
            r = c.stiffness(mesh, positions=2)
            rr = c.stiffness(mesh, positions=2, path="names.h5")
        R.check("Client.stiffness returns the schema's result", r.get("positions") == 2 and len(r.get("points", [])) == 2
                and 0 < r["k"]["min"] <= r["k"]["max"], r)
        h5 = os.path.join(d.dir, "names.h5")
        names_check(R, r, rr, h5)
    cmds = set(hello["commands"])
    R.check("hello lists commands", len(cmds) > 10, hello.get("commands"))

    req = json.loads(read("proto", "v1", "request.json"))
    enum = set(req["properties"]["cmd"]["enum"])
    R.check("request.json cmd enum = daemon commands", enum == cmds, diff(enum, cmds))
    dispatch = {a["if"]["properties"]["cmd"]["const"] for a in req.get("allOf", [])}
    R.check("request.json allOf dispatch covers every command", dispatch == cmds, diff(dispatch, cmds))
    for kind in ("requests", "results"):
        files = {os.path.splitext(os.path.basename(p))[0] for p in glob.glob(src("proto", "v1", kind, "*.json"))}
        R.check(f"proto/v1/{kind}/<cmd>.json for every command", files == cmds, diff(files, cmds))
    for doc in (("proto", "v1", "README.md"), ("docs", "reference", "protocol.md")):
        t = table_commands(read(*doc))
        R.check(f"{'/'.join(doc)}: command table = daemon commands", t == cmds, diff(t, cmds))

    sys.path.insert(0, src("clients", "python"))
    import gearsim
    methods = {m for m in dir(gearsim.Client) if not m.startswith("_")}
    # set_load, advance ... are methods of the same name; every daemon
    # command must be reachable by name (request() is the generic path).
    missing = sorted(c for c in cmds if c not in methods)
    R.check("Python Client has a method for every command", not missing, f"missing: {missing}")

    limits = set(hello["limits"])
    schema = json.loads(read("proto", "v1", "results", "hello.json"))
    props = set(schema["properties"]["limits"]["properties"])
    R.check("results/hello.json documents every hello.limits entry", limits <= props, diff(limits, props))
    for doc in (("docs", "reference", "protocol.md"), ("proto", "v1", "README.md")):
        text = read(*doc)
        miss = sorted(k for k in limits if k not in text)
        R.check(f"{'/'.join(doc)} names every hello.limits entry", not miss, f"missing: {miss}")

    builtins = set(hello["builtin_scenes"])
    scenes = {os.path.splitext(os.path.basename(p))[0] for p in glob.glob(src("deploy", "scenes", "*.json"))}
    R.check("builtin scenes = deploy/scenes/*.json", builtins == scenes, diff(builtins, scenes))
    readme = read("README.md")
    miss = sorted(b for b in builtins if f"`{b}`" not in readme)
    R.check("README.md lists every builtin scene", not miss, f"missing: {miss}")
    R.check("docs/reference/protocol.md points at hello.builtin_scenes", "hello.builtin_scenes" in read("docs", "reference", "protocol.md"))

    eh = read("include", "gearsim", "error.h")
    wire = set(re.findall(r'X\(GS_[A-Z0-9_]+,\s*"([a-z_]+)"', eh)) - NOT_ON_WIRE
    R.check("error.h has wire codes", len(wire) > 10, wire)
    common = json.loads(read("proto", "v1", "common.json"))
    senum = set(common["$defs"]["error_code"]["enum"])
    R.check("common.json error_code enum = error.h wire codes", senum == wire, diff(senum, wire))
    proto = read("docs", "reference", "protocol.md")
    m = re.search(r"Error codes:(.*?)\.\n", proto, re.S)
    listed = set(re.findall(r"`([a-z_]+)`", m.group(1))) if m else set()
    R.check("docs/reference/protocol.md error code list = error.h wire codes", listed == wire, diff(listed, wire))

    r = subprocess.run([gearsimd_path(), "--help"], capture_output=True, text=True, timeout=60,
                       env=dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1"))
    opts = set(re.findall(r"--([a-z][a-z-]+)", r.stdout))
    R.check("gearsimd --help lists options", r.returncode == 0 and len(opts) > 8, r.stdout + r.stderr)
    man = read("docs", "man", "gearsimd.1").replace("\\-", "-")
    miss = sorted(o for o in opts if f"--{o}" not in man)
    R.check("gearsimd(1) documents every option of --help", not miss, f"missing: {miss}")
    prose = read("README.md") + read("docs", "RELIABILITY.md")
    miss = sorted(o for o in opts if f"--{o}" not in prose)
    R.check("README.md/docs/RELIABILITY.md name every gearsimd option", not miss, f"missing: {miss}")

    g = subprocess.run(["/usr/bin/python3", src("clients", "python", "gearctl"), "--help"], capture_output=True,
                       text=True, timeout=60)
    sub = set(re.findall(r"^    ([a-z_]+)(?:\s|$)", g.stdout, re.M))
    R.check("gearctl --help lists commands", len(sub) > 10, g.stdout)
    man = re.sub(r"\\f[BIRP]", " ", read("docs", "man", "gearctl.1"))
    cr = read("clients", "README.md")
    cr = cr[cr.index("## gearctl"):]
    cr = cr[:cr.index("\n## ")]
    for name, text in (("gearctl(1)", man), ("clients/README.md, section gearctl", cr)):
        miss = sorted(c for c in sub if not re.search(r"\b" + c + r"\b", text))
        R.check(f"{name} names every gearctl command", not miss, f"missing: {miss}")
    R.finish()


if __name__ == "__main__":
    main()
