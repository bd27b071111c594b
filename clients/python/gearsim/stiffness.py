# SPDX-License-Identifier: MIT
"""Quasi-static mesh stiffness and transmission error through the
gearsim-stiffness tool: its command line, its JSON result and the table
gearctl prints of it."""
import json
import subprocess


class ToolError(RuntimeError):
    """A gearsim-* tool ended with a non-zero status."""


def stiffness_command(tool, scene, positions=24, mesh=None, torque=None, refine=None, driver=None,
                      nearfield=True, out=None, tangent=True):
    """The gearsim-stiffness command line (JSON output)."""
    cmd = [tool, scene, "--positions", str(positions), "--json"]
    if not tangent:
        cmd += ["--no-tangent"]
    if mesh:
        cmd += ["--mesh", mesh]
    if torque is not None:
        cmd += ["--torque", repr(torque)]
    if refine is not None:
        cmd += ["--refine", str(refine)]
    if driver is not None:
        cmd += ["--driver", str(driver)]
    if not nearfield:
        cmd += ["--no-nearfield"]
    if out:
        cmd += ["--out", out]
    return cmd


def run_json(cmd, what):
    """Run a tool printing JSON; ToolError with its stderr when it fails."""
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        raise ToolError(f"{what} failed ({r.returncode}): {r.stderr.strip()}")
    return json.loads(r.stdout)


def stiffness_text(res):
    """The table gearctl stiffness prints: one row per roll position, then
    the ranges of k and TE."""
    lines = [f"mesh {res['mesh']}: {res['driver']} (z={res['teeth'][0]}) drives {res['driven']} "
             f"(z={res['teeth'][1]}), T = {res['torque_nm']:.4g} N m, F = {res['force_n']:.1f} N, "
             f"b = {res['face_width_mm']:.3g} mm, contact ratio {res['contact_ratio']:.3f}",
             f"{'roll':>6} {'angle deg':>10} {'k N/(mm um)':>12} {'k_tan':>8} {'TE um':>9} {'pairs':>5}  pair forces N"
             "   (TE: the loaded static TE)"]
    for p in res["points"]:
        kt = p["k_tan"] if p.get("k_tan") is not None else float("nan")
        forces = " ".join(f"{q['teeth'][0]}/{q['teeth'][1]}:{q['force_n']:.0f}" for q in p["pair_forces"])
        lines.append(f"{p['roll']:6.3f} {p['angle_deg']:10.4f} {p['k']:12.4f} {kt:8.4f} "
                     f"{p.get('te_loaded_um', p.get('te_um')):9.4f} "
                     f"{p['pairs']:5d}  {forces}")
    k, te = res["k"], res.get("te_loaded_um", res.get("te_um"))
    lines.append(f"k  min {k['min']:.4f}  mean {k['mean']:.4f}  max {k['max']:.4f} N/(mm um)")
    lines.append(f"TE min {te['min']:.4f}  mean {te['mean']:.4f}  max {te['max']:.4f} um  "
                 f"(peak-to-peak {te['peak_to_peak']:.4f}; loaded static TE)")
    if res.get("modified"):
        te = res.get("te_elastic_um", res.get("te_um"))
        lines.append(f"elastic part, without the modifications' geometric TE: min {te['min']:.4f}  mean {te['mean']:.4f}"
                     f"  max {te['max']:.4f} um  (peak-to-peak {te['peak_to_peak']:.4f})")
    sl = res.get("slice_analysis")
    if sl:
        sec = sl["transverse_section"]
        lines.append(f"slice analysis: {sl['slices']} slices, coupling length {sl['coupling_mm']:.3f} mm, "
                     f"overlap ratio {sl['overlap_ratio']:.4f}, K_Hbeta {sl['k_hbeta']:.4f}")
        lines.append(f"transverse section (the spur pair): k min {sec['k_min']:.4f} max {sec['k_max']:.4f}, "
                     f"TE peak-to-peak {sec['te_loaded_peak_to_peak_um']:.4f} um")
        lines.append("peak load per unit face width on one contact line, N/mm: " +
                     " ".join(f"{x:.1f}" for x in sl["peak_load_n_per_mm"]))
    return "\n".join(lines)
