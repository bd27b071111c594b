#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim.sweep and gearsim.modal without a daemon: peaks of sampled
parabolas found at their vertices (closed form), --param parsing, the table
read back, the offline spec, the sweep request's parameters, the mode a peak
sits at (mesh frequency or harmonic), the modal table, and sweep_service
against a stand-in client (progress lines, the fetched table, the modal
request)."""
import argparse
import contextlib
import io
import os
import unittest

from gearsim import modal as M
from gearsim import sweep as W


def opts(**kw):
    base = dict(rpm_from=None, rpm_to=None, points=40, param=None, driver_rpm=None, settle=0.01, measure=0.01,
                time_step=None, mesh=None, groups=None, path=None, resume=False, json=False)
    base.update(kw)
    return argparse.Namespace(**base)


class Peaks(unittest.TestCase):
    def test_parabola_vertex(self):
        # two resonances, each a downward parabola sampled off its vertex
        for (x0, y0, a) in ((1234.5, 3.0, 1e-3), (873.2, 0.7, 5e-5)):
            xs = [800.0 + 37.0 * i for i in range(20)]
            rows = [{"mesh_hz": x, "dte_rms_um": y0 - a * (x - x0) ** 2} for x in xs]
            peaks = W.sweep_peaks(rows)
            self.assertEqual(len(peaks), 1)
            self.assertAlmostEqual(peaks[0][0], x0, places=6)
            best = max(rows, key=lambda r: r["dte_rms_um"])
            self.assertEqual(peaks[0][1], best["dte_rms_um"])

    def test_no_peak_on_monotone(self):
        rows = [{"mesh_hz": float(i), "dte_rms_um": float(i)} for i in range(10)]
        self.assertEqual(W.sweep_peaks(rows), [])

    def test_peak_text(self):
        modes = [{"frequency_hz": 3000.0, "kind": "rotational", "multiplicity": 1},
                 {"frequency_hz": 5000.0, "kind": "planet", "multiplicity": 2}]
        self.assertEqual(W.peak_text(1500.0, 1.25, modes), "peak at mesh frequency 1500.0 Hz, DTE rms 1.250 um; "
                         "harmonic 2 at the rotational mode 3000.0 Hz (+0.00%)")
        self.assertIn("mesh frequency at the planet mode 5000.0 Hz (+1.00%)", W.peak_text(5050.0, 1.0, modes))
        self.assertEqual(W.peak_text(10.0, 2.0, []), "peak at mesh frequency 10.0 Hz, DTE rms 2.000 um")


class Parse(unittest.TestCase):
    def test_param(self):
        self.assertEqual(W.sweep_param("loads[0].moment=10:50:5"),
                         {"path": "loads[0].moment", "from": 10.0, "to": 50.0, "points": 5})
        self.assertEqual(W.sweep_param("a.b=1,2,3"), {"path": "a.b", "values": [1.0, 2.0, 3.0]})
        for bad in ("nopath", "a=1:x:3", "a=x,y"):
            with self.assertRaises(ValueError):
                W.sweep_param(bad)

    def test_rows(self):
        header, rows = W.sweep_rows("point,mesh_hz,dte_rms_um\n0,100,1.5\n1,200,\n\n")
        self.assertEqual(header, ["point", "mesh_hz", "dte_rms_um"])
        self.assertEqual(rows, [{"point": 0.0, "mesh_hz": 100.0, "dte_rms_um": 1.5},
                                {"point": 1.0, "mesh_hz": 200.0, "dte_rms_um": None}])

    def test_spec_and_parameters(self):
        o = opts(rpm_from=100.0, rpm_to=900.0, points=9, param=["x=1,2"], mesh="m1", time_step=1e-5)
        spec = W.offline_spec(o, "s.json")
        self.assertEqual(spec["scene_file"], os.path.abspath("s.json"))
        self.assertEqual(spec["parameters"], [{"path": "driver_rpm", "from": 100.0, "to": 900.0, "points": 9},
                                              {"path": "x", "values": [1.0, 2.0]}])
        self.assertEqual((spec["mesh"], spec["time_step"]), ("m1", 1e-5))
        self.assertNotIn("driver_rpm", spec)
        self.assertEqual(W.service_parameters(o), spec["parameters"])
        self.assertEqual(W.service_parameters(opts(param=["x=0:1:3"])), [{"path": "x", "from": 0.0, "to": 1.0,
                                                                           "points": 3}])


class FakeClient:
    def __init__(self):
        self.fetched = []
        self.requests = []

    def sweep(self, params, on_progress=None, **kw):
        self.params, self.kw = params, kw
        on_progress({"point": 0, "points_done": 1, "points": 2, "values": {"dte_rms_um": 0.5, "mesh_hz": 100.0}})
        on_progress({"point": 1, "points_done": 2, "points": 2, "error": {"message": "diverged"}})
        return {"points_done": 2, "points": 2, "computed": 2, "groups": 1, "points_per_second": 4.0,
                "csv": "sw.csv", "h5": "sw.h5", "failed": [{"point": 1, "message": "diverged"}]}

    def fetch(self, path, out):
        self.fetched.append(path)
        with open(out, "w") as f:
            f.write("point,mesh_hz,dte_rms_um\n0,100,0.5\n")

    def request(self, cmd, args):
        self.requests.append((cmd, args))
        return {"groups": []}


class Service(unittest.TestCase):
    def test_service(self):
        c = FakeClient()
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            text, modal = W.sweep_service(c, opts(rpm_from=1.0, rpm_to=2.0, points=2, groups=1), "builtin:pair")
        self.assertEqual(text, "point,mesh_hz,dte_rms_um\n0,100,0.5\n")
        self.assertEqual(modal, {"groups": []})
        self.assertEqual(c.fetched, ["sw.csv"])
        self.assertEqual(c.kw["builtin"], "pair")
        self.assertEqual(c.kw["groups"], 1)
        self.assertIsNone(c.kw["resume"])
        self.assertEqual(c.requests, [("modal", {"shapes": False, "builtin": "pair"})])
        lines = out.getvalue().splitlines()
        self.assertEqual(lines[0], "point 0: 1/2 done, DTE rms 0.5000 um at 100.0 Hz")
        self.assertEqual(lines[1], "point 1: 2/2 done, failed: diverged")
        self.assertTrue(lines[2].startswith("2 of 2 points (2 computed here, 1 group(s), 4 points/s)"))
        self.assertEqual(err.getvalue(), "point 1 failed: diverged\n")
        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
            W.sweep_service(FakeClient(), opts(rpm_from=1.0, rpm_to=2.0, json=True), "builtin:pair")
        self.assertEqual(out.getvalue(), "")


class Modal(unittest.TestCase):
    def test_text_and_modes(self):
        res = {"scene": "s", "dof": 7, "groups_by_kind": {"rotational": 2, "translational": 1, "planet": 0, "mixed": 0},
               "groups": [{"frequency_hz": 0.0, "kind": "rotational", "multiplicity": 1},
                          {"frequency_hz": 1234.5678, "kind": "rotational", "multiplicity": 1},
                          {"frequency_hz": 2000.0, "kind": "translational", "multiplicity": 2}]}
        lines = M.modal_text(res).splitlines()
        self.assertEqual(lines[0], "s: 7 coordinates; groups: 2 rotational, 1 translational, 0 planet, 0 mixed")
        self.assertEqual(lines[3].split(), ["1234.568", "rotational", "1"])
        self.assertEqual([m["frequency_hz"] for m in M.modes_of(res)], [1234.5678, 2000.0])
        self.assertEqual(M.modes_of(None), [])


if __name__ == "__main__":
    unittest.main()
