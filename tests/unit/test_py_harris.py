#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim.stiffness and gearsim.harris without the tool: the command line
built from the options, the long relief (eps - 1) p_b against its closed
form, the relief written into a copy of the scene (only the mesh's gears,
removed at 0), the torque of each line load (T = w b r_b1, the sign of the
scene's load) passed to a stand-in for gearsim-stiffness, and the CSV and
table formats."""
import json
import math
import os
import tempfile
import unittest

from gearsim import harris as H
from gearsim import stiffness as S

SCENE = {"bodies": [{"name": "pin", "modification": {"x": 1}}, {"name": "wheel"}, {"name": "shaft"}],
         "meshes": [{"gears": ["pin", "wheel"]}]}


def probe_result(torque, te_pp, relief=None):
    return {"mesh": "m", "driver": "pin", "driven": "wheel", "teeth": [20, 40], "base_radius_mm": 28.19,
            "face_width_mm": 20.0, "torque_nm": torque, "contact_ratio": 1.6, "refine": [1, 1],
            "te_um": {"peak_to_peak": te_pp, "mean": 1.0, "min": 0.5, "max": 0.5 + te_pp},
            "k": {"mean": 14.0}, "fraction_multi_pair": 0.6, "relief": relief}


class Stiffness(unittest.TestCase):
    def test_command(self):
        self.assertEqual(S.stiffness_command("t", "s.json"), ["t", "s.json", "--positions", "24", "--json"])
        cmd = S.stiffness_command("t", "s.json", positions=8, mesh="m", torque=-1.5, refine=2, driver=1,
                                  nearfield=False, out="o.h5", tangent=False)
        self.assertEqual(cmd, ["t", "s.json", "--positions", "8", "--json", "--no-tangent", "--mesh", "m",
                               "--torque", "-1.5", "--refine", "2", "--driver", "1", "--no-nearfield",
                               "--out", "o.h5"])

    def test_run_json_failure(self):
        with self.assertRaisesRegex(S.ToolError, r"gearsim-x failed \(3\): boom"):
            S.run_json(["/bin/sh", "-c", "echo boom >&2; exit 3"], "gearsim-x")
        self.assertEqual(S.run_json(["/bin/echo", '{"a": 1}'], "echo"), {"a": 1})

    def test_text(self):
        res = {"mesh": "m", "driver": "a", "driven": "b", "teeth": [20, 40], "torque_nm": 100.0, "force_n": 3547.2,
               "face_width_mm": 20.0, "contact_ratio": 1.6123, "modified": False,
               "points": [{"roll": 0.0, "angle_deg": 0.0, "k": 14.5, "k_tan": None, "te_um": 2.5, "pairs": 2,
                           "pair_forces": [{"teeth": [0, 0], "force_n": 2000.4}, {"teeth": [1, 1], "force_n": 1546.8}]}],
               "k": {"min": 14.5, "mean": 14.5, "max": 14.5},
               "te_um": {"min": 2.5, "mean": 2.5, "max": 2.5, "peak_to_peak": 0.0}}
        lines = S.stiffness_text(res).splitlines()
        self.assertEqual(len(lines), 5)
        self.assertIn("contact ratio 1.612", lines[0])
        self.assertEqual(lines[2].split(), ["0.000", "0.0000", "14.5000", "nan", "2.5000", "2", "0/0:2000", "1/1:1547"])


class Harris(unittest.TestCase):
    def test_parse(self):
        self.assertEqual(H.parse_loads("100, 200,"), [100.0, 200.0])
        for bad in ("", "0,100", "-5", "a,b"):
            with self.assertRaises(ValueError):
                H.parse_loads(bad)
        self.assertEqual(H.parse_list("0,5.5", "--relief"), [0.0, 5.5])

    def test_long_relief(self):
        p = probe_result(100.0, 1.0)
        pb = 2 * math.pi * 28.19 / 20   # base pitch, mm
        self.assertAlmostEqual(H.long_relief_length(p), 0.6 * pb, places=12)

    def test_relief_scene(self):
        sc = H.relief_scene(SCENE, {"pin", "wheel"}, 12.0, 3.0, "parabolic")
        want = {"tip_relief": {"amount_um": 12.0, "length_mm": 3.0, "shape": "parabolic"}}
        self.assertEqual([b.get("modification") for b in sc["bodies"]], [want, want, None])
        self.assertEqual(SCENE["bodies"][0]["modification"], {"x": 1})   # the original untouched
        sc = H.relief_scene(SCENE, {"pin", "wheel"}, 0.0, 3.0, "linear")
        self.assertNotIn("modification", sc["bodies"][0])

    def test_map(self):
        calls = []

        def fake(cmd, what):
            with open(cmd[1]) as f:
                scene = json.load(f)
            torque = float(cmd[cmd.index("--torque") + 1]) if "--torque" in cmd else None
            calls.append((scene, torque, cmd))
            mod = scene["bodies"][0].get("modification", {}).get("tip_relief", {})
            # a stand-in: TE p-p grows with load and falls with relief
            te = 0.1 if torque is None else abs(torque) / 100.0 / (1.0 + mod.get("amount_um", 0.0))
            return probe_result(-200.0 if torque is None else torque, te)

        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "s.json")
            with open(path, "w") as f:
                json.dump(SCENE, f)
            out = H.harris_map("tool", path, [100.0, 300.0], reliefs=[0.0, 9.0], relief_length=2.5,
                               positions=6, refine=2, run=fake)
        self.assertEqual(len(calls), 1 + 2 * 2)
        self.assertIsNone(calls[0][1])
        rb_m, b = 28.19e-3, 20.0
        torques = [t for _, t, _ in calls[1:]]
        for t, w in zip(torques, (100.0, 300.0, 100.0, 300.0)):
            self.assertAlmostEqual(t, -w * b * rb_m, places=12)   # the probe's sign (negative)
        self.assertTrue(all("--no-tangent" in c and "--refine" in c for _, _, c in calls))
        self.assertEqual([r["label"] for r in out["rows"]], ["0 um", "0 um", "9 um", "9 um"])
        self.assertAlmostEqual(out["rows"][3]["te_loaded_pp_um"], 300.0 * b * rb_m / 100.0 / 10.0, places=12)
        self.assertEqual(out["relief_length_mm"], 2.5)
        self.assertEqual(calls[3][0]["bodies"][1]["modification"]["tip_relief"]["length_mm"], 2.5)
        csv = H.harris_csv(out["rows"]).splitlines()
        self.assertEqual(csv[0], H.CSV_HEADER)
        self.assertEqual(csv[1].split(",")[:3], ["0", "100", f"{-100 * b * rb_m:.6g}"])
        text = H.harris_text(out, [100.0, 300.0]).splitlines()
        self.assertEqual(len(text), 4)
        self.assertEqual(text[1].split()[-2:], ["um", "(um)"])
        self.assertEqual([float(x) for x in text[3].split()], [300.0, round(300 * b * rb_m / 100, 4),
                                                               round(300 * b * rb_m / 1000, 4)])


if __name__ == "__main__":
    unittest.main()
