#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim.advise on tables and scenes built here: the kind of a scene, the
targets' syntax (usage errors exit 2), the cheapest row meeting every target,
the cheaper rows rejected with the output that failed, and the message when
no row meets the targets. Each expected choice is fixed by the table's
construction, so a wrong ordering or comparison fails."""
import json
import os
import tempfile
import unittest

from gearsim import advise as A

HEADER = "scene,level,h,refine,cost,err_speed,err_dte\n"
ROWS = [  # scene, level, h, refine, cost, err_speed, err_dte
    ("contact_drive", "contact", 1e-6, 2, 50.0, 0, 0),          # the reference
    ("contact_drive", "kinematic", 1e-4, 0, 0.01, 1e-3, 1.0),
    ("contact_drive", "lumped", 1e-5, 0, 0.5, 5e-3, 0.05),
    ("contact_drive", "compliant", 1e-5, 0, 2.0, 2e-4, 0.01),
    ("contact_drive", "contact", 1e-5, 1, 10.0, 1e-5, 0.002),
    ("planetary_contact", "contact", 1e-6, 1, 80.0, 0, 0),
    ("planetary_contact", "lumped", 1e-5, 0, 1.0, 0.02, 0.3),
]

PAIR = {"bodies": [{"name": "p", "type": "gear"}, {"name": "w", "type": "gear"}],
        "meshes": [{"gears": ["p", "w"]}]}
PLANETARY = {"bodies": [{"name": "c", "type": "carrier"}], "meshes": [{}, {}]}


class Advise(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.table = os.path.join(self.tmp.name, "t.csv")
        with open(self.table, "w") as f:
            f.write(HEADER + "".join(",".join(map(str, r)) + "\n" for r in ROWS))

    def tearDown(self):
        self.tmp.cleanup()

    def test_classify(self):
        self.assertEqual(A.classify_scene(PAIR)[0], "pair")
        self.assertEqual(A.classify_scene(PLANETARY)[0], "planetary")
        self.assertEqual(A.classify_scene({"train": {"type": "planetary"}})[0], "planetary")
        ring = {"bodies": [{"name": "r", "kind": "internal"}], "meshes": [{}]}
        self.assertEqual(A.classify_scene(ring)[0], "planetary")
        with self.assertRaisesRegex(A.AdviceError, "no gear mesh"):
            A.classify_scene({"bodies": []})
        with self.assertRaisesRegex(A.AdviceError, "chain of 2 meshes"):
            A.classify_scene({"bodies": [], "meshes": [{}, {}]})
        with self.assertRaises(A.AdviceError):
            A.classify_scene([1, 2])

    def test_targets(self):
        outs = ["speed", "dte"]
        self.assertEqual(A.parse_targets(["speed=1e-3", "dte_rms=0.1"], outs), {"speed": 1e-3, "dte": 0.1})
        for bad, why in ((["speed"], "OUTPUT=REL_ERR"), (["mass=1"], "unknown output"),
                         (["speed=-1"], "positive"), (["speed=1", "speed=2"], "twice"), ([], "at least one")):
            with self.assertRaisesRegex(A.AdviceError, why) as cm:
                A.parse_targets(bad, outs)
            self.assertEqual(cm.exception.code, 2, bad)

    def test_cheapest_meeting(self):
        res = A.advise(PAIR, self.table, ["speed=1e-2", "dte=0.06"], "pair")
        c = res["choice"]
        self.assertEqual((c["level"], c["h"]), ("lumped", 1e-5))
        self.assertEqual(c["errors"], {"speed": 5e-3, "dte": 0.05})
        self.assertEqual([r["level"] for r in res["rejected"]], ["kinematic"])
        self.assertEqual(res["rejected"][0]["failed"], {"dte": 1.0})
        self.assertEqual(res["reference"]["level"], "contact")
        self.assertEqual(res["reference"]["h"], 1e-6)
        # a tighter speed target moves the choice to the compliant row
        res = A.advise(PAIR, self.table, ["speed=1e-3", "dte=0.06"], "pair")
        self.assertEqual(res["choice"]["level"], "compliant")
        self.assertEqual(sorted(r["level"] for r in res["rejected"]), ["kinematic", "lumped"])
        text = A.advice_text(res)
        self.assertIn("advice: compliant, time step 1e-05 s", text)
        self.assertIn("lumped h 1e-05 (0.5 s/s): speed 0.005 > 0.001", text)
        # planetary scenes read the planetary rows only
        res = A.advise(PLANETARY, self.table, ["speed=0.05"], "planetary")
        self.assertEqual((res["table_scene"], res["choice"]["level"]), ("planetary_contact", "lumped"))

    def test_none_meets(self):
        with self.assertRaisesRegex(A.AdviceError, r"no level meets.*Best achievable error: speed 1e-05 "
                                                   r"\(contact h 1e-05 refine 1\)") as cm:
            A.advise(PAIR, self.table, ["speed=1e-9"], "pair")
        self.assertEqual(cm.exception.code, 1)

    def test_table_errors(self):
        bad = os.path.join(self.tmp.name, "bad.csv")
        with open(bad, "w") as f:
            f.write("scene,level,cost,err_speed\n")
        with self.assertRaisesRegex(A.AdviceError, "no column h"):
            A.read_table(bad)
        with self.assertRaisesRegex(A.AdviceError, "cannot read the table"):
            A.read_table(os.path.join(self.tmp.name, "missing.csv"))
        rows, outs = A.read_table(self.table)
        self.assertEqual((len(rows), outs), (len(ROWS), ["speed", "dte"]))

    def test_scene_spec(self):
        d = os.path.join(self.tmp.name, "scenes")
        os.makedirs(d)
        with open(os.path.join(d, "mine.json"), "w") as f:
            json.dump(PAIR, f)
        self.assertEqual(A.read_scene_spec("mine", d), PAIR)
        self.assertEqual(A.read_scene_spec("builtin:mine", d), PAIR)
        self.assertEqual(A.read_scene_spec(os.path.join(d, "mine.json"), d), PAIR)
        with self.assertRaisesRegex(A.AdviceError, "no builtin scene"):
            A.read_scene_spec("other", d)
        with self.assertRaisesRegex(A.AdviceError, "no builtin scene"):
            A.read_scene_spec("builtin:../scenes/mine", d)


if __name__ == "__main__":
    unittest.main()
