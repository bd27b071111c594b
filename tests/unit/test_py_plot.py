#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim.plot draws every plot of gearctl into a PNG file from results
shaped as the tools and the daemon give them (stiffness, Harris map, mode
shapes, sweep, trade-off table): each file exists and is a PNG of a
plausible size. Skipped without matplotlib (python3-matplotlib)."""
import os
import tempfile
import unittest

try:
    import matplotlib  # noqa: F401
    HAVE_MPL = True
except ImportError:
    HAVE_MPL = False

from gearsim import plot as P

PNG = b"\x89PNG\r\n\x1a\n"


def is_png(path):
    with open(path, "rb") as f:
        data = f.read()
    return data.startswith(PNG) and len(data) > 2000


@unittest.skipUnless(HAVE_MPL, "matplotlib is not installed")
class Plots(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()

    def tearDown(self):
        self.tmp.cleanup()

    def out(self, name):
        return os.path.join(self.tmp.name, name)

    def test_stiffness(self):
        pts = [{"angle_deg": 3.0 * i, "k": 14 + (i % 3), "k_tan": 15.0, "te_um": 2 + 0.1 * i, "pairs": 1 + i % 2}
               for i in range(6)]
        res = {"points": pts, "teeth": [20, 40], "mesh": "m", "driver": "a", "driven": "b", "torque_nm": 100.0,
               "face_width_mm": 20.0, "refine": [0, 0], "k": {"min": 14.0, "mean": 15.0, "max": 16.0}}
        P.plot_stiffness(res, self.out("k.png"))
        self.assertTrue(is_png(self.out("k.png")))

    def test_harris(self):
        rows = [{"label": lab, "line_load_n_per_mm": w, "te_loaded_pp_um": w / (1 + c)} for c, lab in ((0, "0 um"), (9, "9 um"))
                for w in (100.0, 200.0)]
        out = {"rows": rows, "mesh": "m", "teeth": [20, 40], "relief_shape": "linear", "relief_length_mm": 4.0,
               "positions": 6, "refine": [0, 0]}
        P.plot_harris(out, self.out("h.png"), relief_given=True)
        self.assertTrue(is_png(self.out("h.png")))

    def test_modes(self):
        res = {"scene": "s", "bodies": [{"name": "a", "centre": [0, 0], "radius": 0.05},
                                        {"name": "b", "centre": [0.1, 0], "radius": 0.05}],
               "groups": [{"frequency_hz": 1000.0, "kind": "rotational", "multiplicity": 1, "first_mode": 0}],
               "modes": [{"shape": [{"body": "a", "x": 0, "y": 0, "u": 1.0}, {"body": "b", "x": 0.1, "y": 0, "u": -1.0}]}]}
        P.plot_modes(res, self.out("m.png"))
        self.assertTrue(is_png(self.out("m.png")))

    def test_sweep(self):
        rows = [{"mesh_hz": 100.0 * i, "dte_rms_um": 1.0 / (1 + (i - 5) ** 2), "dynamic_factor": 1.1, "lsf": None}
                for i in range(1, 10)]
        res = {"modes": [{"frequency_hz": 500.0, "kind": "rotational", "multiplicity": 1}]}
        P.plot_sweep(res, rows, "mesh_hz", self.out("s.png"), "scene")
        self.assertTrue(is_png(self.out("s.png")))

    def test_tradeoff(self):
        csv = self.out("t.csv")
        with open(csv, "w") as f:
            f.write("scene,level,h,refine,cost,err_speed,err_dte,scale\n"
                    "contact_drive,lumped,1e-05,0,0.5,0.01,0.1,1\n"
                    "contact_drive,contact,1e-05,1,10,0.001,0.01,1\n"
                    "contact_drive,contact,1e-06,2,50,0,0,1\n")
        P.plot_tradeoff(csv, self.out("t.png"))
        self.assertTrue(is_png(self.out("t.png")))


if __name__ == "__main__":
    unittest.main()
