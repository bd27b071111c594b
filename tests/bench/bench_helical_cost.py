#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Cost of the slice analysis of a helical pair against the planar analysis
of a spur pair on the same default mesh, one run each, same process
conditions (docs/explanation/helical.md "Cost"):

* spur: gearsim-stiffness deploy/scenes/stiffness_pair.json (20/30, m 2.5 mm,
  default mesh, near-field correction), N positions;
* helical: tests/validation/helical_crowned.json (20/30, m_n 2.5 mm, beta 15 deg,
  crowned and misaligned; the planar analysis of its transverse section plus
  the slice solve, 320 slices), N positions.

Prints the CPU seconds per position of each (all in: meshing, factorisation
and solves included) and their ratio. Asserts the ratio is below 20 (the
cost bar) when run as a benchmark."""
import json
import os
import subprocess
import sys

SRC = os.environ.get("GEARSIM_SOURCE_ROOT", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
BUILD = os.environ.get("GEARSIM_BUILD_ROOT", os.path.join(SRC, "build"))
TOOL = os.path.join(BUILD, "src", "tools", "gearsim-stiffness")
N = 24


def cpu_per_position(scene):
    out = subprocess.run([TOOL, scene, "--json", "--positions", str(N)], capture_output=True, text=True, check=True)
    r = json.loads(out.stdout)
    return r["cpu"]["cpu_s"] / N, r


spur, _ = cpu_per_position(os.path.join(SRC, "deploy", "scenes", "stiffness_pair.json"))
hel, r = cpu_per_position(os.path.join(SRC, "tests", "validation", "helical_crowned.json"))
ratio = hel / spur
print("CPU per position (all in, %d positions): spur %.4f s, helical (%d slices) %.4f s, ratio %.2f"
      % (N, spur, r["slice_analysis"]["slices"], hel, ratio))
if ratio > 20.0:
    print("FAILED: helical position costs more than 20 spur positions")
    sys.exit(1)
