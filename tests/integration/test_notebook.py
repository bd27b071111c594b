#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The example notebook clients/python/examples/gearsim_tour.ipynb runs
headless (jupyter-nbconvert --execute, Debian's jupyter-nbconvert and
python3-ipykernel) against a real 2-rank daemon: every cell runs without an
error (its own asserts check the kinematic ratio, the energy balance of
every fidelity and of the record), the live plot and the record plot are
rendered as PNGs and the fidelity table has its three rows. Skipped (exit
77) with a message when jupyter-nbconvert or the kernel is not installed."""
import json
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from daemon import SOURCE_ROOT, Daemon  # noqa: E402
from harness import Results  # noqa: E402

NB = os.path.join(SOURCE_ROOT, "clients", "python", "examples", "gearsim_tour.ipynb")


def main():
    nbconvert = shutil.which("jupyter-nbconvert")
    if not nbconvert or subprocess.run(["/usr/bin/python3", "-c", "import ipykernel"],
                                       capture_output=True).returncode != 0:
        print("skip: jupyter-nbconvert or python3-ipykernel is not installed "
              "(apt-get install jupyter-nbconvert python3-ipykernel; deploy/install-deps.sh does)")
        sys.exit(77)
    R = Results("example notebook executed headless")
    tmp = tempfile.mkdtemp(prefix="gearsim-nb-")
    try:
        # The notebook's own place in a tree: clients/python/examples, with
        # the package beside it and deploy/scenes three levels up.
        ex = os.path.join(tmp, "clients", "python", "examples")
        os.makedirs(ex)
        shutil.copy(NB, ex)
        os.symlink(os.path.join(SOURCE_ROOT, "clients", "python", "gearsim"),
                   os.path.join(tmp, "clients", "python", "gearsim"))
        os.symlink(os.path.join(SOURCE_ROOT, "deploy"), os.path.join(tmp, "deploy"))
        out = os.path.join(tmp, "executed.ipynb")
        with Daemon(ranks=2) as d:
            env = dict(os.environ, GEARSIM_CONNECTION_FILE=d.conn_file, PYDEVD_DISABLE_FILE_VALIDATION="1",
                       MPLBACKEND="module://matplotlib_inline.backend_inline")
            env.pop("PYTHONPATH", None)   # the notebook finds the package by itself
            r = subprocess.run([nbconvert, "--to", "notebook", "--execute", "--output", out,
                                "--ExecutePreprocessor.timeout=600", os.path.basename(NB)],
                               cwd=ex, env=env, capture_output=True, text=True, timeout=900)
        R.check("jupyter-nbconvert --execute succeeds", r.returncode == 0, r.stderr[-1200:])
        if r.returncode != 0:
            R.finish()
        with open(out) as f:
            nb = json.load(f)
        code = [c for c in nb["cells"] if c["cell_type"] == "code"]
        outputs = [o for c in code for o in c.get("outputs", [])]
        R.check("every code cell ran", all(c.get("execution_count") for c in code))
        R.check("no error output", not any(o.get("output_type") == "error" for o in outputs))
        live = next(c for c in code if "on_telemetry" in "".join(c["source"]))
        R.check("live plot rendered as PNG", any("image/png" in o.get("data", {}) for o in live["outputs"]))
        text = "".join("".join(o.get("text", "")) for o in outputs if o.get("output_type") == "stream")
        for level in ("kinematic", "lumped", "compliant"):
            R.check(f"fidelity table has {level}", f"\n{level} " in "\n" + text, text[-2000:])
        R.check("record read back", "largest |energy balance|" in text and "rows, bodies" in text, text[-2000:])
        pngs = sum("image/png" in o.get("data", {}) for o in outputs)
        R.check("two plots (live telemetry, record)", pngs >= 2, pngs)
        R.check("record downloaded next to the notebook", os.path.getsize(os.path.join(ex, "notebook.h5")) > 1000)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    R.finish()


if __name__ == "__main__":
    main()
