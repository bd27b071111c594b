#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""`gearctl impact CASE.json` end to end: gearctl finds gearsim-impact in
$GEARSIM_BUILD_ROOT/src/tools, runs it and prints its JSON. Checks a slender
rod on a rough floor under the three hypotheses against the closed form of
the sliding case (all laws agree there: P_n = (1 + e) P_c, P_t = -mu P_n along
the slip), the energy balance, a frictionless multi-contact step (Lemke and
the QP agree), and that a bad field is reported by name with exit status 1.
Tolerances: 1e-9 relative (JSON carries ~15 significant digits)."""
import json
import math
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from harness import Results  # noqa: E402

SOURCE_ROOT = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.abspath(
    os.path.join(os.path.dirname(__file__), "..", ".."))
GEARCTL = os.path.join(SOURCE_ROOT, "clients", "python", "gearctl")
R = Results("test_impact_cli: gearctl impact")


def gearctl_impact(case, tmp):
    path = os.path.join(tmp, "case.json")
    with open(path, "w") as f:
        json.dump(case, f)
    return subprocess.run(["/usr/bin/python3", GEARCTL, "impact", path], capture_output=True, text=True,
                          timeout=60)


def close(a, b, tol=1e-9):
    return abs(a - b) <= tol * max(1.0, abs(b))


def rod_case(th, vx, vy, e, mu, hyp):
    m, length = 1.0, 1.0
    return {"bodies": [{"mass": m, "inertia": m * length ** 2 / 12,
                        "centre": [0.5 * length * math.cos(th), 0.5 * length * math.sin(th)],
                        "velocity": [vx, vy], "omega": 0.0},
                       {"fixed": True}],
            "contact": {"point": [0.0, 0.0], "normal": [0.0, 1.0]},
            "e": e, "mu": mu, "hypothesis": hyp}


def main():
    with tempfile.TemporaryDirectory(prefix="impact-cli-") as tmp:
        th, vx, vy, e, mu = math.pi / 4, 3.0, -1.0, 0.5, 0.3
        r = gearctl_impact(rod_case(th, vx, vy, e, mu, "all"), tmp)
        R.check("gearctl impact: exit 0", r.returncode == 0, r.stderr[-2000:])
        out = json.loads(r.stdout) if r.returncode == 0 else {"results": []}
        res = out.get("results", [])
        R.check("three results, one per hypothesis",
                [x.get("hypothesis") for x in res] == ["newton", "poisson", "stronge"], res)
        s, c = math.sin(th), math.cos(th)
        wxy, wyy = -3 * s * c, 1 + 3 * c * c
        a1 = wyy - mu * wxy  # dv_n/dP_n while sliding in +x
        pn = (1 + e) * (-vy) / a1
        for x in res:
            h = x["hypothesis"]
            R.check(f"{h}: process sliding", x["process"] == "sliding", x["process"])
            R.check(f"{h}: P_n = (1+e) P_c = {pn:.12g}", close(x["impulse"]["normal"], pn), x["impulse"])
            # t = (-n_y, n_x) = (-1, 0): friction along -x is +P_t
            R.check(f"{h}: P_t = mu P_n", close(x["impulse"]["tangential"], mu * pn), x["impulse"])
            en, ds = x["energy"], x["dissipation"]
            R.check(f"{h}: energy balance", close(en["before"] - en["after"], ds["total"]), (en, ds))
            R.check(f"{h}: v_n after = -e v_n before", close(x["contact_velocity"]["after"][1], -e * vy))
            R.check(f"{h}: bodies and frame present", len(x["bodies"]) == 2 and "W_tt_tn_nn" in x["frame"])

        # a case where the laws differ: slip reverses in restitution
        r = gearctl_impact(rod_case(th, 1.0, -1.0, 0.5, 0.3, "stronge"), tmp)
        x = json.loads(r.stdout) if r.returncode == 0 else {}
        R.check("stronge, slip reversal in restitution", x.get("process") == "reversal_restitution", x)
        R.check("stronge: work ratio e^2", x and close(x["work"]["normal_restitution"],
                                                       -0.25 * x["work"]["normal_compression"]), x.get("work"))

        multi = {"bodies": [{"fixed": True},
                            {"mass": 1.0, "inertia": 1 / 6, "centre": [0, 0.5], "velocity": [0.2, -1.0],
                             "omega": 0.3}],
                 "contacts": [{"bodies": [1, 0], "point": [-0.5, 0], "normal": [0, 1]},
                              {"bodies": [1, 0], "point": [0.5, 0], "normal": [0, 1]}],
                 "e": 0.0, "mu": 0.0}
        r = gearctl_impact(multi, tmp)
        x = json.loads(r.stdout) if r.returncode == 0 else {}
        R.check("multi: Lemke solved", x.get("lcp", {}).get("status") == "solved", r.stdout[-1000:] + r.stderr)
        R.check("multi: QP cross-check agrees",
                x.get("qp_check", {}).get("max_velocity_difference", 1.0) < 1e-9, x.get("qp_check"))
        R.check("multi: box stopped (e = 0)", x and abs(x["bodies"][1]["velocity"][1]) < 1e-12
                and abs(x["bodies"][1]["omega"]) < 1e-12, x.get("bodies"))

        bad = rod_case(th, vx, vy, e, mu, "stronge")
        bad["bodies"][0]["mass"] = -2.0
        r = gearctl_impact(bad, tmp)
        R.check("bad mass: exit 1", r.returncode == 1, r.returncode)
        R.check("bad mass: field named", "bodies[0].mass" in r.stderr, r.stderr)
        bad = rod_case(th, vx, vy, e, mu, "hooke")
        r = gearctl_impact(bad, tmp)
        R.check("bad hypothesis: field named", r.returncode == 1 and "hypothesis" in r.stderr, r.stderr)

        # Large finite inputs: refused naming the input field, never Infinity/NaN with exit 0.
        def huge(path_set, value, multi_case=False):
            c = json.loads(json.dumps(multi if multi_case else rod_case(th, vx, vy, e, mu, "all")))
            obj = c
            for k in path_set[:-1]:
                obj = obj[k]
            obj[path_set[-1]] = value
            return gearctl_impact(c, tmp)

        for label, path, value, multi_case, field in (
                ("velocity 1e160", ["bodies", 0, "velocity"], [1e160, -1e160], False, "bodies[0].velocity"),
                ("mass 1e300", ["bodies", 0, "mass"], 1e300, False, "bodies[0].mass"),
                ("inertia 1e-300", ["bodies", 0, "inertia"], 1e-300, False, "bodies[0].inertia"),
                ("centre 1e200", ["bodies", 0, "centre"], [1e200, 1e200], False, "bodies[0].centre"),
                ("omega 1e200", ["bodies", 0, "omega"], 1e200, False, "bodies[0].omega"),
                ("mu 1e300", ["mu"], 1e300, False, "mu"),
                ("multi: velocity 1e160", ["bodies", 1, "velocity"], [0.2, -1e160], True, "bodies[1].velocity"),
                ("multi: time_step 1e300", ["time_step"], 1e300, True, "time_step"),
                ("multi: gravity 1e300", ["gravity"], [0, -1e300], True, "gravity")):
            r = huge(path, value, multi_case)
            R.check(f"{label}: refused (non-zero exit, no Infinity/NaN printed), naming {field}",
                    r.returncode != 0 and "Infinity" not in r.stdout and "NaN" not in r.stdout
                    and f"{field}:" in r.stderr, (r.returncode, r.stdout[-300:], r.stderr))
        # The extremes of the accepted ranges: finite output, or an error naming an input.
        ext = {"bodies": [{"mass": 1e9, "inertia": 1e-15, "centre": [1e3, -1e3], "velocity": [1e4, -1e4],
                           "omega": 1e6}, {"fixed": True}],
               "contact": {"point": [-1e3, 1e3], "normal": [1e-300, 1]}, "e": 1, "mu": 1e3, "hypothesis": "all"}
        r = gearctl_impact(ext, tmp)
        R.check("range extremes: finite result or an error naming an input field (not the internal W)",
                (r.returncode == 0 and "Infinity" not in r.stdout and "NaN" not in r.stdout) or
                (r.returncode != 0 and "error: bodies" in r.stderr and " W:" not in r.stderr),
                (r.returncode, r.stderr))
    R.finish()


if __name__ == "__main__":
    main()
