#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Independent 3D reference of a loaded helical gear pair: gmsh (quadratic
tetrahedra, C3D10) + CalculiX ccx (frictionless surface-to-surface contact,
small deformation). See README.md beside this file.

Each gear is a sector of TEETH teeth (the teeth that can touch over the
face at the position, and one more either side) with its rim down to the
hub radius 0.6 r_f, the transverse section (../gearref.py: involute flank in
closed form and trochoid fillet, in the transverse module and pressure
angle) swept along the face with the helix twist (gmsh's twisted
extrusion: the section at height z turned by z tan(beta) / r). Driven wheel:
hub surface held (or, misaligned, moved rigidly by a tilt of its axis in the
plane of action: the gap grows linearly to f_ma across the face). Driver:
hub surface tied to a rigid small rotation theta about its axis (linear
*EQUATION ties, theta the first dof of an extra node that carries the
moment). Output per run: theta, TE = r_b1 theta (um, along the transverse
line of action), k = F / TE / b, the transverse load per unit face width of
each tooth pair along the face (from the contact pressure at the slave
nodes, integrated over the slave faces) and its peak.

Usage:  ./run_helical.py [--h 1.2 0.9] [--positions 8] [--rolls 0 3]
                         [--misalign 0 20] [--keep]
Appends one row per run to runs.csv and the face profile to profiles.csv
(runs already there are skipped). Never run by the test suite.
Units inside: mm, N, MPa, rad.
"""
import argparse
import csv
import json
import math
import os
import re
import resource
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))
import gearref  # noqa: E402

TEETH = 5          # teeth per gear sector (--teeth)
CONTACT = 5        # the central teeth whose flanks are contact surfaces
NBIN = 20          # face bins of the load profile


class Helical:
    """The transverse section of a helical gear cut by the normal basic
    rack: a spur outline in the transverse module and pressure angle (the
    flank is the exact transverse involute; the fillet is the trochoid of a
    rack tip round of radius rho m_n in the transverse plane)."""

    def __init__(self, z, mn, alpha_n_deg, beta_deg, hand, hub=0.0):
        self.beta = math.radians(beta_deg)
        cb = math.cos(self.beta)
        self.mt = mn / cb
        self.alpha_t = math.atan(math.tan(math.radians(alpha_n_deg)) / cb)
        self.g = gearref.Gear(z, self.mt, math.degrees(self.alpha_t), ha=cb, hf=1.25 * cb,
                              rho=0.38 * cb, hub=hub)
        self.hand = hand          # +1 right (section turns counter-clockwise with z), -1 left
        self.twist = hand * math.tan(self.beta) / self.g.r     # rad per mm of face


def load_pair(path):
    p = json.load(open(path))
    g1 = Helical(p["driver"]["teeth"], p["mn_mm"], p["alpha_n_deg"], p["beta_deg"], +1)
    g2 = Helical(p["driven"]["teeth"], p["mn_mm"], p["alpha_n_deg"], p["beta_deg"], -1)
    return p, g1, g2


def sector_geo(gw, h, centre, angle, k0, lines, loaded):
    """Sector of TEETH teeth (k0 .. k0+TEETH-1) of Helical h, its mid-face
    section turned by angle; the counter-clockwise outline: root arc, teeth,
    root arc, radial cut, hub arc, radial cut. Returns (surface, curve list,
    roles) where roles[i] names curve i: 'flank', 'tip', 'hub' or ''."""
    g = h.g
    fil, invl = g.half_tooth()
    cpt = gw.point(centre)
    curves, roles = [], []
    a0 = angle + (k0 - 0.5) * g.pitch
    a1 = angle + (k0 + TEETH - 0.5) * g.pitch
    p_start = gw.point(gearref.rot((g.rf, 0.0), a0, centre))
    prev = p_start
    for k in range(k0, k0 + TEETH):
        ang = angle + k * g.pitch
        cw_inv = [gearref.rot((p[0], -p[1]), ang, centre) for p in invl]
        cw_fil = [gearref.rot((p[0], -p[1]), ang, centre) for p in fil]
        ccw_fil = [gearref.rot(p, ang, centre) for p in fil]
        ccw_inv = [gearref.rot(p, ang, centre) for p in invl]
        pr = gw.point(cw_fil[0])
        curves.append(gw.curve("Circle", [prev, cpt, pr]))
        roles.append("")
        ids = [pr] + [gw.point(p) for p in cw_fil[1:-1]]
        pf = gw.point(cw_fil[-1])
        curves.append(gw.curve("Spline", ids + [pf]))
        roles.append("")
        ids = [pf] + [gw.point(p) for p in cw_inv[1:-1]]
        pt = gw.point(cw_inv[-1])
        curves.append(gw.curve("Spline", ids + [pt]))
        roles.append("")
        pt2 = gw.point(ccw_inv[-1])
        curves.append(gw.curve("Circle", [pt, cpt, pt2]))
        roles.append("tip" if k in loaded else "")
        ids = [pt2] + [gw.point(p) for p in reversed(ccw_inv[1:-1])]
        pf2 = gw.point(ccw_inv[0])
        curves.append(gw.curve("Spline", ids + [pf2]))
        roles.append("flank" if k in loaded else "")
        ids = [pf2] + [gw.point(p) for p in reversed(ccw_fil[1:-1])]
        prev = gw.point(ccw_fil[0])
        curves.append(gw.curve("Spline", ids + [prev]))
        roles.append("")
    p_end = gw.point(gearref.rot((g.rf, 0.0), a1, centre))
    curves.append(gw.curve("Circle", [prev, cpt, p_end]))
    roles.append("")
    q_end = gw.point(gearref.rot((g.hub, 0.0), a1, centre))
    q_start = gw.point(gearref.rot((g.hub, 0.0), a0, centre))
    curves.append(gw.curve("Line", [p_end, q_end]))
    roles.append("")
    # hub arc (clockwise): two arcs, each below pi
    q_mid = gw.point(gearref.rot((g.hub, 0.0), 0.5 * (a0 + a1), centre))
    curves.append(gw.curve("Circle", [q_end, cpt, q_mid]))
    roles.append("hub")
    curves.append(gw.curve("Circle", [q_mid, cpt, q_start]))
    roles.append("hub")
    curves.append(gw.curve("Line", [q_start, p_start]))
    roles.append("")
    gw.nc += 1
    loop = gw.nc
    lines.append("Curve Loop(%d) = {%s};" % (loop, ", ".join(map(str, curves))))
    gw.nc += 1
    surf = gw.nc
    lines.append("Plane Surface(%d) = {%d};" % (surf, loop))
    return surf, curves, roles


def read_msh3(path):
    nodes, elems = {}, []
    with open(path) as f:
        it = iter(f)
        for line in it:
            s = line.strip()
            if s == "$Nodes":
                for _ in range(int(next(it))):
                    a = next(it).split()
                    nodes[int(a[0])] = (float(a[1]), float(a[2]), float(a[3]))
            elif s == "$Elements":
                for _ in range(int(next(it))):
                    a = list(map(int, next(it).split()))
                    elems.append((a[1], a[3] if a[2] > 0 else 0, a[3 + a[2]:]))
    return nodes, elems


def path_of_contact(g1, g2, a):
    """End points of the transverse path of contact (the line of action
    between the two tip circles) for the driver at the origin turning
    counter-clockwise and the driven gear at (a, 0)."""
    at = g1.alpha_t
    d = (math.sin(at), math.cos(at))                     # force on the driven gear
    t1 = (g1.g.rb * math.cos(at), -g1.g.rb * math.sin(at))
    t2 = (a - g2.g.rb * math.cos(at), g2.g.rb * math.sin(at))
    L = math.hypot(t2[0] - t1[0], t2[1] - t1[1])
    s_e = math.sqrt(g1.g.ra ** 2 - g1.g.rb ** 2)         # from t1: the driver's tip
    s_a = L - math.sqrt(g2.g.ra ** 2 - g2.g.rb ** 2)     # the driven gear's tip
    pa = (t1[0] + s_a * d[0], t1[1] + s_a * d[1])
    pe = (t1[0] + s_e * d[0], t1[1] + s_e * d[1])
    return pa, pe, d


def size_field(L, g1, g2, a, h, hmax, grow=0.35, zone=None, algorithm="Mesh.Algorithm3D = 1;"):
    """gmsh lines of the mesh size (h within zone, default 1.5 h, of the
    transverse path of contact, growing by grow per mm, at most hmax) and
    the quadratic-element options; returns the line of action d."""
    pa, pe, d = path_of_contact(g1, g2, a)
    ux, uy = pe[0] - pa[0], pe[1] - pa[1]
    ln = math.hypot(ux, uy)
    ux, uy = ux / ln, uy / ln
    if zone is None:
        zone = 1.5 * h
    t = "Min(Max((x-(%.9f))*(%.9f)+(y-(%.9f))*(%.9f), 0), %.9f)" % (pa[0], ux, pa[1], uy, ln)
    dist = "Sqrt((x-(%.9f)-%s*(%.9f))^2+(y-(%.9f)-%s*(%.9f))^2)" % (pa[0], t, ux, pa[1], t, uy)
    L.append("Field[1] = MathEval;")
    L.append('Field[1].F = "Min(%.9g + %.9g * Max(%s - %.9g, 0), %.9g)";' % (h, grow, dist, zone, hmax))
    L.append("Background Field = 1;")
    for opt in ("Mesh.MeshSizeExtendFromBoundary = 0;", "Mesh.MeshSizeFromPoints = 0;",
                "Mesh.MeshSizeFromCurvature = 0;", "Mesh.MeshSizeMax = %.9g;" % hmax,
                "Mesh.ElementOrder = 2;", "Mesh.SecondOrderLinear = 0;", "Mesh.HighOrderOptimize = 0;",
                algorithm, "Mesh.MshFileVersion = 2.2;", "Mesh.Binary = 0;"):
        L.append(opt)
    return d


def placing(pair, g1, g2, roll):
    """Mid-face angles of both gears at a roll position and the teeth the
    sectors centre on (the nearest the pitch point)."""
    th1 = roll * g1.g.pitch
    th2 = pair["driven_angle0_rad"] - th1 * g1.g.z / g2.g.z
    return th1, th2, int(round(-th1 / g1.g.pitch)), int(round((math.pi - th2) / g2.g.pitch))


def build(work, pair, g1, g2, roll, h, misalign_um, grow=0.35, zone=None):
    """Mesh and write the ccx deck of one position; returns info."""
    os.makedirs(work, exist_ok=True)
    a = pair["centre_mm"]
    b = pair["face_width_mm"]
    th1, th2, k1, k2 = placing(pair, g1, g2, roll)
    half = TEETH // 2
    hc = CONTACT // 2
    loaded1 = set(range(k1 - hc, k1 + hc + 1))
    loaded2 = set(range(k2 - hc, k2 + hc + 1))
    gw = gearref.GeoWriter()
    L = gw.lines
    L.insert(0, 'SetFactory("Built-in");')
    # sections at z = 0: mid-face angle minus half the twist
    s1, c1, r1 = sector_geo(gw, g1, (0.0, 0.0), th1 - 0.5 * b * g1.twist, k1 - half, L, loaded1)
    s2, c2, r2 = sector_geo(gw, g2, (a, 0.0), th2 - 0.5 * b * g2.twist, k2 - half, L, loaded2)
    L.append("e1[] = Extrude {{0, 0, %.12g}, {0, 0, 1}, {0, 0, 0}, %.15g} { Surface{%d}; };"
             % (b, b * g1.twist, s1))
    L.append("e2[] = Extrude {{0, 0, %.12g}, {0, 0, 1}, {%.12g, 0, 0}, %.15g} { Surface{%d}; };"
             % (b, a, b * g2.twist, s2))
    L.append("Physical Volume(1) = {e1[1]};")
    L.append("Physical Volume(2) = {e2[1]};")
    for tag, roles, e in ((11, r1, "e1"), (12, r2, "e2")):
        idx = [i for i, r in enumerate(roles) if r in ("flank", "tip")]
        L.append("Physical Surface(%d) = {%s};" % (tag, ", ".join("%s[%d]" % (e, 2 + i) for i in idx)))
    for tag, roles, e in ((21, r1, "e1"), (22, r2, "e2")):
        idx = [i for i, r in enumerate(roles) if r == "hub"]
        L.append("Physical Surface(%d) = {%s};" % (tag, ", ".join("%s[%d]" % (e, 2 + i) for i in idx)))
    d = size_field(L, g1, g2, a, h, pair["mn_mm"], grow, zone, "Mesh.Algorithm3D = 1;")
    geo = os.path.join(work, "pair.geo")
    msh = os.path.join(work, "pair.msh")
    text = "\n".join(L) + "\n"
    t0 = time.time()
    # an interrupted run's mesh of the same geometry is reused
    if not (os.path.exists(msh) and os.path.exists(geo) and open(geo).read() == text
            and open(msh).read()[-13:].strip() == "$EndElements"):
        with open(geo, "w") as f:
            f.write(text)
        subprocess.run(["nice", "gmsh", "-3", "-nt", "1", geo, "-o", msh, "-v", "1"], check=True,
                       stdout=subprocess.DEVNULL)
    tmesh = time.time() - t0
    nodes, elems = read_msh3(msh)
    # a curved tetrahedron that folds (on the fillets, of radius 0.38 m_n):
    # its mid-edge nodes moved to the straight mid-points, repeated until
    # none folds (the fillets are far from the contact)
    straightened = 0
    for _ in range(5):
        bad = tet10_check(nodes, elems, want_conn=True)
        if not bad:
            break
        for _, _, conn in bad:
            for i, (p, q) in enumerate(((0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1))):
                nodes[conn[4 + i]] = tuple(0.5 * (nodes[conn[p]][k] + nodes[conn[q]][k]) for k in range(3))
            straightened += 1
    bad = tet10_check(nodes, elems)
    if bad:
        raise RuntimeError("%d curved tetrahedra fold over (worst det J ratio %.3f at (%.2f, %.2f, %.2f) mm) "
                           "in %s" % (len(bad), bad[0][0], *bad[0][1], msh))
    info = write_inp(os.path.join(work, "pair.inp"), nodes, elems, pair, g1, a, b, misalign_um, d)
    info.update(mesh_s=tmesh, straightened=straightened, teeth1=sorted(loaded1), teeth2=sorted(loaded2), d=d)
    return info


def tet10_check(nodes, elems, floor=0.05, want_conn=False):
    """10-node tetrahedra (gmsh type 11) whose Jacobian determinant at the
    corners, the centroid and the four integration points changes sign or falls below floor times its
    largest value: [(min/max, centroid)], worst first."""
    ga, gb = 0.1381966011250105, 0.5854101966249685     # ccx's 4 integration points
    pts = ((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0.25, 0.25, 0.25),
           (ga, ga, ga), (gb, ga, ga), (ga, gb, ga), (ga, ga, gb))
    bad = []
    for typ, _, conn in elems:
        if typ != 11:
            continue
        P = [nodes[n] for n in conn]
        ds = []
        for r, s, t in pts:
            l0 = 1.0 - r - s - t
            # gmsh order: corners 0-3, edges 01, 12, 20, 30, 32, 31
            dr = (1 - 4 * l0, 4 * r - 1, 0, 0, 4 * (l0 - r), 4 * s, -4 * s, -4 * t, 0, 4 * t)
            ds_ = (1 - 4 * l0, 0, 4 * s - 1, 0, -4 * r, 4 * r, 4 * (l0 - s), -4 * t, 4 * t, 0)
            dt = (1 - 4 * l0, 0, 0, 4 * t - 1, -4 * r, 0, -4 * s, 4 * (l0 - t), 4 * s, 4 * r)
            J = [[sum(d[k] * P[k][i] for k in range(10)) for i in range(3)] for d in (dr, ds_, dt)]
            ds.append(J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1])
                      - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0])
                      + J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]))
        lo, hi = min(ds), max(ds)
        if hi < 0:
            lo, hi = -hi, -lo
        if hi <= 0 or lo < floor * hi:
            bad.append((lo / hi if hi > 0 else -1.0,
                        tuple(sum(p[i] for p in P[:4]) / 4 for i in range(3))) + ((conn,) if want_conn else ()))
    bad.sort(key=lambda v: v[0])
    return bad


# gmsh tet10 -> ccx C3D10 (the last two mid-edge nodes swapped)
TET_ORDER = (0, 1, 2, 3, 4, 5, 6, 7, 9, 8)
# C3D10 faces (corner indices, ccx numbering S1..S4)
TET_FACES = ((0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0))
# their mid-edge nodes (C3D10 numbering: edges 01 12 20 03 13 23 -> 4..9)
FACE_MIDS = ((4, 5, 6), (7, 8, 4), (8, 9, 5), (9, 7, 6))


def write_inp(path, nodes, elems, pair, g1, a, b, misalign_um, d):
    tets = {1: [], 2: []}
    for typ, ph, conn in elems:
        if typ == 11 and ph in tets:
            c = [conn[i] for i in TET_ORDER]
            p0, p1, p2, p3 = (nodes[n] for n in c[:4])
            v1 = [p1[i] - p0[i] for i in range(3)]
            v2 = [p2[i] - p0[i] for i in range(3)]
            v3 = [p3[i] - p0[i] for i in range(3)]
            det = (v1[0] * (v2[1] * v3[2] - v2[2] * v3[1]) - v1[1] * (v2[0] * v3[2] - v2[2] * v3[0])
                   + v1[2] * (v2[0] * v3[1] - v2[1] * v3[0]))
            if det < 0:      # ccx wants a positive volume: swap corners 1, 2 and their edges
                c = [c[0], c[2], c[1], c[3], c[6], c[5], c[4], c[7], c[9], c[8]]
            tets[ph].append(c)
    face_of = {}
    eid = 0
    numbered = {1: [], 2: []}
    for ph in (1, 2):
        for c in tets[ph]:
            eid += 1
            numbered[ph].append((eid, c))
    surf_keys = {11: [], 12: []}
    hubn = {21: set(), 22: set()}
    for typ, ph, conn in elems:
        if typ == 9 and ph in surf_keys:
            surf_keys[ph].append(frozenset(conn[:3]))
        if typ == 9 and ph in hubn:
            hubn[ph].update(conn)
    want = set(k for v in surf_keys.values() for k in v)
    for ph in (1, 2):
        for e, c in numbered[ph]:
            for fno, f in enumerate(TET_FACES):
                key = frozenset((c[f[0]], c[f[1]], c[f[2]]))
                if key in want:
                    face_of[key] = (e, fno + 1)
    surf = {ph: [face_of[k] for k in surf_keys[ph]] for ph in surf_keys}
    maxn = max(nodes)
    ref, rotn = maxn + 1, maxn + 2
    o = ["*NODE, NSET=NALL"]
    for n in sorted(nodes):
        x, y, z = nodes[n]
        o.append("%d, %.12f, %.12f, %.12f" % (n, x, y, z))
    o.append("*NODE, NSET=NREF")
    o.append("%d, 0, 0, 0" % ref)
    o.append("*NODE, NSET=NROT")
    o.append("%d, 0, 0, 0" % rotn)
    gearref.deck_sets(o, "C3D10", numbered, hubn, surf, pair["E_mpa"], pair["nu"])
    # the slave flank's nodes and every driven element holding one: their
    # internal nodal forces (from the stresses at the integration points)
    # are the contact forces on the flank
    slv = set()
    tets2 = dict(numbered[2])
    for e, fno in surf[12]:
        c = tets2[e]
        fc = TET_FACES[fno - 1]
        slv.update(c[i] for i in fc)
        slv.update(c[k] for k in FACE_MIDS[fno - 1])
    efl = sorted(e for e, c in numbered[2] if any(n in slv for n in c))
    o.append("*NSET, NSET=SLV")
    ids = sorted(slv)
    for i in range(0, len(ids), 12):
        o.append(", ".join(map(str, ids[i:i + 12])) + ",")
    o.append("*ELSET, ELSET=EFL")
    for i in range(0, len(efl), 12):
        o.append(", ".join(map(str, efl[i:i + 12])) + ",")
    o.append("*SOLID SECTION, ELSET=E0, MATERIAL=STEEL")
    o.append("*SOLID SECTION, ELSET=E1, MATERIAL=STEEL")
    # driver hub: u_x = -y theta, u_y = x theta (theta: dof 1 of NROT), u_z = 0
    o.append("*EQUATION")
    for n in sorted(hubn[21]):
        x, y, _ = nodes[n]
        o.append("2")
        o.append("%d, 1, 1., %d, 1, %.12f" % (n, rotn, y))
        o.append("2")
        o.append("%d, 2, 1., %d, 1, %.12f" % (n, rotn, -x))
    gearref.contact_cards(o, pair["penalty"])
    # driven hub: held, or a rigid tilt of its axis in the plane of action
    # about the axis point at z = 0: u = (f/b) [z d - (d . rho) e_z],
    # rho = (x - a, y): the gap along the line of action grows from 0 at
    # z = 0 to f at z = b.
    f = misalign_um * 1e-3
    hub1 = []
    for n in sorted(hubn[22]):
        x, y, z = nodes[n]
        ux, uy = f / b * z * d[0], f / b * z * d[1]
        uz = -f / b * (d[0] * (x - a) + d[1] * y)
        hub1.append((n, ux, uy, uz))

    def restate(op):
        o.append("*BOUNDARY" + op)
        for n, ux, uy, uz in hub1:
            for dof, u in ((1, ux), (2, uy), (3, uz)):
                o.append("%d, %d, %d, %.12f" % (n, dof, dof, u))
        o.append("HUB0, 3, 3, 0")
        o.append("NREF, 1, 3, 0")
        o.append("NROT, 2, 3, 0")
    T = pair["torque_nmm"]
    rb = g1.g.rb
    # step 1: theta prescribed at about half its expected value (the contact
    # established); step 2: theta released, the moment applied (frictionless
    # small-strain contact: no path dependence)
    theta0 = 0.5 * (T / rb) / (20.0 * b) * 1e-3 / rb
    o += ["*STEP, INC=200", "*STATIC", "1., 1."]
    restate("")
    o += ["NROT, 1, 1, %.10g" % theta0, "*END STEP"]
    o += ["*STEP, INC=200", "*STATIC", "1., 1."]
    restate(", OP=NEW")
    o.append("*CLOAD")
    o.append("%d, 1, %.12g" % (rotn, T))
    o.append("*NODE PRINT, NSET=NROT")
    o.append("U")
    o.append("*NODE PRINT, NSET=HUB1, TOTALS=ONLY")
    o.append("RF")
    o.append("*CONTACT FILE")
    o.append("CSTR")
    o.append("*NODE PRINT, NSET=SLV")
    o.append("RF")
    o.append("*EL PRINT, ELSET=EFL")
    o.append("S")
    o.append("*END STEP")
    with open(path, "w") as fo:
        fo.write("\n".join(o) + "\n")
    return dict(nodes=len(nodes), elements=sum(len(v) for v in tets.values()),
                slave_faces=[(e, fno) for e, fno in surf[12]], tets=dict(numbered[2]),
                coords=nodes)


def read_dat_last(path, head):
    """The rows of the last block of a ccx .dat file whose title starts with
    head (e.g. "stresses", "forces"): [[numbers]]."""
    rows, cur = [], None
    with open(path) as f:
        for ln in f:
            s = ln.strip()
            if not s:
                continue
            if s[0].isalpha():
                if cur is not None:
                    rows = cur
                cur = [] if s.startswith(head) else None
                continue
            if cur is not None:
                cur.append([float(v) for v in s.split()])
    if cur is not None:
        rows = cur
    return rows


# C3D10 (ccx numbering: corners 1-4 at (0,0,0), (1,0,0), (0,1,0), (0,0,1);
# mid-edge nodes 12, 23, 31, 14, 24, 34): shape function derivatives
def tet10_grad(r, s, t):
    l0 = 1.0 - r - s - t
    return ((1 - 4 * l0, 4 * r - 1, 0.0, 0.0, 4 * (l0 - r), 4 * s, -4 * s, -4 * t, 4 * t, 0.0),
            (1 - 4 * l0, 0.0, 4 * s - 1, 0.0, -4 * r, 4 * r, 4 * (l0 - s), -4 * t, 0.0, 4 * t),
            (1 - 4 * l0, 0.0, 0.0, 4 * t - 1, -4 * r, 0.0, -4 * s, 4 * (l0 - t), 4 * r, 4 * s))


# ccx's 4 integration points of C3D10 (weight 1/24 each), in its order
_GA, _GB = 0.1381966011250105, 0.5854101966249685
TET_IP = ((_GA, _GA, _GA), (_GB, _GA, _GA), (_GA, _GB, _GA), (_GA, _GA, _GB))


def inv3(J):
    a, b, c = J[0]
    d, e, f = J[1]
    g, h, i = J[2]
    A, B, C = e * i - f * h, -(d * i - f * g), d * h - e * g
    det = a * A + b * B + c * C
    inv = [[A / det, -(b * i - c * h) / det, (b * f - c * e) / det],
           [B / det, (a * i - c * g) / det, -(a * f - c * d) / det],
           [C / det, -(a * h - b * g) / det, (a * e - b * d) / det]]
    return inv, det


def nodal_forces(info, stress):
    """Internal nodal forces (N) of the driven elements printed (EFL, from
    their stresses at the integration points, ccx's rule): at a free node
    they equal the external force there, i.e. at a slave flank node the
    contact force on the wheel. stress: rows (element, point, sxx, syy,
    szz, sxy, sxz, syz). Returns {node: [fx, fy, fz]}."""
    X = info["coords"]
    by = {}
    for r in stress:
        by.setdefault(int(r[0]), {})[int(r[1])] = r[2:8]
    grads = [tet10_grad(*p) for p in TET_IP]
    f = {}
    for e, sig in by.items():
        c = info["tets"][e]
        P = [X[n] for n in c]
        fe = [[0.0, 0.0, 0.0] for _ in range(10)]
        for ip in range(4):
            sxx, syy, szz, sxy, sxz, syz = sig[ip + 1]
            S = ((sxx, sxy, sxz), (sxy, syy, syz), (sxz, syz, szz))
            G = grads[ip]
            J = [[sum(G[k][a] * P[a][i] for a in range(10)) for i in range(3)] for k in range(3)]
            Ji, det = inv3(J)
            w = abs(det) / 24.0
            for a in range(10):
                gx = [Ji[i][0] * G[0][a] + Ji[i][1] * G[1][a] + Ji[i][2] * G[2][a] for i in range(3)]
                for i in range(3):
                    fe[a][i] += w * (S[i][0] * gx[0] + S[i][1] * gx[1] + S[i][2] * gx[2])
        for a in range(10):
            acc = f.setdefault(c[a], [0.0, 0.0, 0.0])
            for i in range(3):
                acc[i] += fe[a][i]
    return f


def slave_nodes(info):
    """The slave flank's faces as (6 nodes: corners then mid-edges 01, 12, 20)."""
    out = []
    for e, fno in info["slave_faces"]:
        c = info["tets"][e]
        fc = TET_FACES[fno - 1]
        mids = FACE_MIDS[fno - 1]
        # FACE_MIDS follow the face's edges (c0 c1), (c1 c2), (c2 c0)
        out.append([c[i] for i in fc] + [c[k] for k in mids])
    return out


def tri6(xi, eta):
    l0 = 1.0 - xi - eta
    N = (l0 * (2 * l0 - 1), xi * (2 * xi - 1), eta * (2 * eta - 1), 4 * l0 * xi, 4 * xi * eta, 4 * eta * l0)
    dxi = (1 - 4 * l0, 4 * xi - 1, 0.0, 4 * (l0 - xi), 4 * eta, -4 * eta)
    deta = (1 - 4 * l0, 0.0, 4 * eta - 1, -4 * xi, 4 * xi, 4 * (l0 - eta))
    return N, dxi, deta


# 6-point rule on the triangle (degree 4), (xi, eta, weight) on the unit triangle of area 1/2
_W1, _A1, _B1 = 0.223381589678011, 0.445948490915965, 0.108103018168070
_W2, _A2, _B2 = 0.109951743655322, 0.091576213509771, 0.816847572980459
TRI_GP = ((_A1, _A1, _W1), (_A1, _B1, _W1), (_B1, _A1, _W1), (_A2, _A2, _W2), (_A2, _B2, _W2), (_B2, _A2, _W2))


def face_profile(info, fnode, rb1, b, nbin=NBIN, sub=4):
    """Transverse load per unit face width (N/mm) in nbin bins over the
    face, per driven tooth, from the contact forces at the slave nodes
    (fnode: {node: force on the wheel}). Each node's share of the
    transverse load is the moment of its force about the driver axis over
    r_b1; that nodal field is turned back into a load per unit area q on
    the slave surface whose work-equivalent nodal loads it is (M q = m, M
    the surface's consistent mass matrix of the 6-node faces; conjugate
    gradients), and q is integrated over each bin (each face cut into
    sub x sub triangles, 6 points on each). Returns ({tooth: [N/mm] *
    nbin}, total of the nodal shares N, total of the integral N)."""
    X = info["coords"]
    faces = slave_nodes(info)
    m = {}
    for n, F in fnode.items():
        x, y, _ = X[n]
        m[n] = (x * F[1] - y * F[0]) / rb1
    # on the slave nodes only (the rest of the printed nodes are inside)
    snodes = sorted(set(n for fc in faces for n in fc))
    idx = {n: i for i, n in enumerate(snodes)}
    rhs = [m.get(n, 0.0) for n in snodes]
    total_nodes = sum(rhs)
    sgn = 1.0 if total_nodes >= 0 else -1.0
    rhs = [sgn * v for v in rhs]
    total_nodes *= sgn
    # consistent mass matrix, stored per face (6 x 6)
    fmass = []
    for fc in faces:
        P = [X[n] for n in fc]
        Mf = [[0.0] * 6 for _ in range(6)]
        for xi, eta, w in TRI_GP:
            N, dxi, deta = tri6(xi, eta)
            t1 = [sum(dxi[k] * P[k][i] for k in range(6)) for i in range(3)]
            t2 = [sum(deta[k] * P[k][i] for k in range(6)) for i in range(3)]
            da = 0.5 * w * math.sqrt((t1[1] * t2[2] - t1[2] * t2[1]) ** 2 + (t1[2] * t2[0] - t1[0] * t2[2]) ** 2
                                     + (t1[0] * t2[1] - t1[1] * t2[0]) ** 2)
            for a in range(6):
                for c in range(6):
                    Mf[a][c] += N[a] * N[c] * da
        fmass.append(([idx[n] for n in fc], Mf))
    nn = len(snodes)
    diag = [0.0] * nn
    for ids, Mf in fmass:
        for a in range(6):
            diag[ids[a]] += Mf[a][a]

    def matvec(v):
        out = [0.0] * nn
        for ids, Mf in fmass:
            vv = [v[i] for i in ids]
            for a in range(6):
                out[ids[a]] += sum(Mf[a][c] * vv[c] for c in range(6))
        return out
    # Jacobi-preconditioned conjugate gradients
    q = [0.0] * nn
    r = rhs[:]
    z = [r[i] / diag[i] for i in range(nn)]
    p = z[:]
    rz = sum(r[i] * z[i] for i in range(nn))
    r0 = math.sqrt(sum(v * v for v in rhs)) or 1.0
    for _ in range(2000):
        Ap = matvec(p)
        al = rz / sum(p[i] * Ap[i] for i in range(nn))
        for i in range(nn):
            q[i] += al * p[i]
            r[i] -= al * Ap[i]
        if math.sqrt(sum(v * v for v in r)) < 1e-10 * r0:
            break
        z = [r[i] / diag[i] for i in range(nn)]
        rz1 = sum(r[i] * z[i] for i in range(nn))
        p = [z[i] + rz1 / rz * p[i] for i in range(nn)]
        rz = rz1
    # integrate q over the bins
    prof = {}
    total = 0.0
    pitch2, a, z2 = info["pitch2"], info["centre"], info["z2"]
    subpts = []
    for i in range(sub):
        for j in range(sub - i):
            # upright and (if any) inverted sub-triangles of the unit triangle
            subpts.append(((i, j), (i + 1, j), (i, j + 1)))
            if i + j + 1 < sub:
                subpts.append(((i + 1, j), (i + 1, j + 1), (i, j + 1)))
    for fc in faces:
        P = [X[n] for n in fc]
        qv = [q[idx[n]] for n in fc]
        if max(abs(v) for v in qv) == 0.0:
            continue
        for tri in subpts:
            (u0, v0), (u1, v1), (u2, v2) = [(c[0] / sub, c[1] / sub) for c in tri]
            for s1, s2, w in TRI_GP:
                xi = u0 + s1 * (u1 - u0) + s2 * (u2 - u0)
                eta = v0 + s1 * (v1 - v0) + s2 * (v2 - v0)
                N, dxi, deta = tri6(xi, eta)
                t1 = [sum(dxi[k] * P[k][i] for k in range(6)) for i in range(3)]
                t2 = [sum(deta[k] * P[k][i] for k in range(6)) for i in range(3)]
                da = 0.5 * w / (sub * sub) * math.sqrt(
                    (t1[1] * t2[2] - t1[2] * t2[1]) ** 2 + (t1[2] * t2[0] - t1[0] * t2[2]) ** 2
                    + (t1[0] * t2[1] - t1[1] * t2[0]) ** 2)
                x = [sum(N[k] * P[k][i] for k in range(6)) for i in range(3)]
                val = sum(N[k] * qv[k] for k in range(6)) * da
                ang = math.atan2(x[1], x[0] - a) - info["th2_z0"] - x[2] * info["twist2"]
                tooth = int(round(ang / pitch2)) % z2
                ib = min(max(int(x[2] / b * nbin), 0), nbin - 1)
                prof.setdefault(tooth, [0.0] * nbin)[ib] += val
                total += val
    w = b / nbin
    return {k: [v / w for v in vals] for k, vals in prof.items()}, total_nodes, total


def parse_ccx(work):
    """theta (rad) of the driver and the driven hub's total force from
    pair.dat of a finished run."""
    dat = open(os.path.join(work, "pair.dat")).read()
    blocks = re.split(r"\n\s*displacements", dat)
    rot = None
    for ln in blocks[-1].strip().splitlines():
        v = ln.split()
        if len(v) == 4:
            try:
                rot = float(v[1])
                break
            except ValueError:
                pass
    rf = [0.0, 0.0, 0.0]
    fblocks = re.split(r"\n\s*total force", dat)
    if len(fblocks) > 1:
        for ln in fblocks[-1].splitlines()[1:]:
            v = ln.split()
            if len(v) == 3:
                rf = [float(x) for x in v]
                break
    return rot, rf


def run_ccx(work):
    env = dict(os.environ)
    env["OMP_NUM_THREADS"] = "1"
    env["CCX_NPROC_EQUATION_SOLVER"] = "1"
    t0 = time.time()
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    # niceness 10 in all (the caller may already be niced)
    r = subprocess.run(["nice", "-n", str(max(0, 10 - os.nice(0))), "ccx", "-i", "pair"], cwd=work, env=env,
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    dt = time.time() - t0
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
    with open(os.path.join(work, "ccx.log"), "w") as f:
        f.write(r.stdout)
        f.write("\nCPU seconds (user + system, this process): %.2f\n" % cpu)
        f.write("wall seconds: %.2f\n" % dt)
    if r.returncode != 0 or "*ERROR" in r.stdout:
        raise RuntimeError("ccx failed in %s (see ccx.log)" % work)
    rot, rf = parse_ccx(work)
    return rot, rf, dt, cpu


FIELDS = ["roll", "h_mm", "misalign_um", "penalty", "nodes", "elements", "dofs", "theta_rad", "te_um",
          "k_n_per_mm_um", "force_n", "hub_force_n", "contact_force_n", "peak_n_per_mm", "mesh_s", "ccx_s",
          "ccx_cpu_s", "driver_teeth", "driven_teeth", "sector_teeth"]


PFIELDS = ["roll", "h_mm", "misalign_um", "driven_tooth"] + ["q%02d" % i for i in range(NBIN)] + ["sector_teeth"]


def sector_of(r):
    """The sector size of a stored row (rows before the column: 5 teeth)."""
    return int(r.get("sector_teeth") or 5)


def ccx_times(work):
    """CPU and wall seconds of the ccx run in work (from ccx.log; wall nan
    where the log predates its record)."""
    cpu = wall = float("nan")
    for ln in open(os.path.join(work, "ccx.log")):
        if ln.startswith("CPU seconds"):
            cpu = float(ln.split(":")[1])
        elif ln.startswith("wall seconds"):
            wall = float(ln.split(":")[1])
    return cpu, wall


def store(runs, profs, row, prow, replace=False):
    """Append the run's row and profile rows; replace: the stored rows of
    the same run (h, roll, misalignment) are replaced (keeping their times
    where the log has none)."""
    key = (float(row["h_mm"]), round(float(row["roll"]), 6), float(row["misalign_um"]), sector_of(row))
    same = (lambda r: (float(r["h_mm"]), round(float(r["roll"]), 6), float(r["misalign_um"]), sector_of(r)) == key)
    if not replace:
        gearref.append_row(runs, FIELDS, row)
        for p in prow:
            gearref.append_row(profs, PFIELDS, p)
        return
    for path, fields, new in ((runs, FIELDS, [row]), (profs, PFIELDS, prow)):
        old = list(csv.DictReader(open(path))) if os.path.exists(path) else []
        if path == runs:
            for r in old:
                if same(r):
                    for k in ("ccx_s", "ccx_cpu_s", "mesh_s"):
                        if row[k] in ("nan", "") or float(row[k]) != float(row[k]):
                            row[k] = r[k]
        kept = [r for r in old if not same(r)]
        with open(path, "w", newline="") as fo:
            w = csv.DictWriter(fo, fieldnames=fields)
            w.writeheader()
            w.writerows(kept + new)


def main():
    global TEETH
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--h", type=float, nargs="+", default=[1.2])
    ap.add_argument("--positions", type=int, default=8)
    ap.add_argument("--rolls", type=int, nargs="*", help="roll indices j of j/N to run (default all)")
    ap.add_argument("--misalign", type=float, nargs="+", default=[0.0])
    ap.add_argument("--teeth", type=int, default=TEETH,
                    help="teeth per gear sector (odd; the central %d carry the contact surfaces)" % CONTACT)
    ap.add_argument("--keep", action="store_true")
    ap.add_argument("--post", action="store_true",
                    help="read the outputs of a finished ccx run kept in the work directory again (not run "
                         "again; its row and profile replace the stored ones, CPU and wall time from ccx.log "
                         "or the stored row)")
    ap.add_argument("--work", default=os.path.join("/tmp", "helical_pair_%d" % os.getpid()))
    args = ap.parse_args()
    if args.teeth < CONTACT or args.teeth % 2 == 0:
        ap.error("--teeth must be odd and at least %d" % CONTACT)
    TEETH = args.teeth
    pair, g1, g2 = load_pair(os.path.join(HERE, "pair.json"))
    b = pair["face_width_mm"]
    F = pair["torque_nmm"] / g1.g.rb
    runs = os.path.join(HERE, "runs.csv")
    profs = os.path.join(HERE, "profiles.csv")
    done = set()
    if os.path.exists(runs):
        for r in csv.DictReader(open(runs)):
            done.add((float(r["h_mm"]), round(float(r["roll"]), 6), float(r["misalign_um"]), sector_of(r)))
    js = args.rolls if args.rolls else range(args.positions)
    for h in args.h:
        for f in args.misalign:
            for j in js:
                roll = j / args.positions
                if (h, round(roll, 6), f, TEETH) in done and not args.post:
                    continue
                work = os.path.join(args.work, "h%g_f%g_r%d" % (h, f, j) + ("_t%d" % TEETH if TEETH != 5 else ""))
                if args.post and not os.path.exists(os.path.join(work, "pair.dat")):
                    continue
                info = build(work, pair, g1, g2, roll, h, f)
                info["pitch2"] = g2.g.pitch
                info["centre"] = pair["centre_mm"]
                info["z2"] = g2.g.z
                info["twist2"] = g2.twist
                info["th2_z0"] = (pair["driven_angle0_rad"] - roll * g1.g.pitch * g1.g.z / g2.g.z
                                  - 0.5 * b * g2.twist)
                if args.post:
                    rot, rf = parse_ccx(work)
                    cpu, dt = ccx_times(work)
                else:
                    rot, rf, dt, cpu = run_ccx(work)
                dat = os.path.join(work, "pair.dat")
                fnode = nodal_forces(info, read_dat_last(dat, "stresses"))
                prof, total, integral = face_profile(info, fnode, g1.g.rb, b)
                te = g1.g.rb * rot * 1e3
                peak = max((max(v) for v in prof.values()), default=0.0)
                row = dict(roll="%.6f" % roll, h_mm=h, misalign_um=f, penalty=pair["penalty"],
                           nodes=info["nodes"], elements=info["elements"], dofs=3 * info["nodes"],
                           theta_rad="%.10e" % rot, te_um="%.6f" % te, k_n_per_mm_um="%.5f" % (F / te / b),
                           force_n="%.3f" % F, hub_force_n="%.3f" % math.hypot(rf[0], rf[1]),
                           contact_force_n="%.3f" % total, peak_n_per_mm="%.3f" % peak,
                           mesh_s="%.1f" % info["mesh_s"], ccx_s="%.1f" % dt, ccx_cpu_s="%.1f" % cpu,
                           driver_teeth=" ".join(map(str, info["teeth1"])),
                           driven_teeth=" ".join(map(str, info["teeth2"])), sector_teeth=TEETH)
                prow = [dict(roll="%.6f" % roll, h_mm=h, misalign_um=f, driven_tooth=tooth, sector_teeth=TEETH,
                             **{"q%02d" % i: "%.4f" % v for i, v in enumerate(vals)})
                        for tooth, vals in sorted(prof.items())]
                store(runs, profs, row, prow, replace=args.post)
                print("roll %.4f h %g f %g: nodes %d TE %.4f um k %.4f N/(mm um) peak %.1f N/mm "
                      "contact %.1f N (integral %.1f) of %.1f, hub %.1f; ccx cpu %.1f s" %
                      (roll, h, f, info["nodes"], te, F / te / b, peak, total, integral, F,
                       math.hypot(rf[0], rf[1]), cpu), flush=True)
                if not args.keep:
                    for fn in os.listdir(work):
                        os.remove(os.path.join(work, fn))
                    os.rmdir(work)


if __name__ == "__main__":
    main()
