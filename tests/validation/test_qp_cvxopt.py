#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Cross-check of the Goldfarb-Idnani QP solver against cvxopt.solvers.qp.

Generates 1170 problems (fixed seed; GEARSIM_QP_SEED overrides)
    minimise 1/2 x^T H x - c^T x  s.t.  E x = e,  G x >= g,   n = 2..60:
random; equality/inequality mixes; vertices with n active rows (known
optimum); degenerate vertices with more tight rows than unknowns and zero
multipliers (known optimum); duplicated and scaled rows; zero rows; redundant
equalities; clusters of nearly parallel rows (1e-6..1e-2 rad and 1e-14);
boxes; simplex projections; H with condition 1e4..1e6; plus infeasible
problems (five constructions) and H indefinite or semidefinite. Each goes
through tests/tools/qp_driver, which solves it three times: cold; "hot",
warm-started from the cold active set with the cached factor; "warm", from a
random guess. All three must agree with the reference.

Reference. cvxopt (interior point) is run with abstol = reltol = feastol =
1e-12 (down a ladder to 1e-8 only when it breaks down at 1e-12). On degenerate
problems an interior-point method stalls around 1e-8..1e-6 in x, so its
answer is polished: starting from the rows cvxopt makes strongly active, the
KKT system on a working set of rows is solved (numpy LU) and the set repaired
until the point is feasible; the point is then certified optimal by finding
multipliers (non-negative on the tight rows, Lawson-Hanson NNLS) that make the
relative KKT residuals at most 1e-10. A certified point of a strictly convex
QP is its unique optimum up to the conditioning; cvxopt's own point is then
checked not to beat it (f(x) - f(x_cvx) at most what x_cvx gains from its
infeasibility). Where the rows tight at the optimum are independent (LICQ)
the multipliers are unique, and x and the multipliers of the reference are
recomputed from that KKT system with iterative refinement in extended
precision. Nothing of the solver under test enters the reference.

Tolerances (relative to max(1, |reference|); objective relative to
max(1, |f|, |c^T x|), the size of its terms): x and objective 1e-9, a margin
of ~1e3 over the round-off of the well-posed problems generated (condition
numbers up to ~1e4; the nearly parallel clusters all pass through one point,
so x stays well conditioned). Multipliers where unique: max(1e-9,
eps kappa(K)), K the KKT matrix of the tight rows, since ill-conditioned
multipliers (vertices, nearly parallel rows) are determined by any
backward-stable method only to about eps kappa(K). KKT residuals of the
solver's own answer (stationarity, primal and dual feasibility,
complementarity): 1e-10. Infeasible problems must give "infeasible" (and be
confirmed infeasible without the solver: a zero row with a positive
right-hand side, inconsistent equalities by least squares, or cvxopt not
finding an optimum); H with a zero or negative eigenvalue must give
"singular".

Prints per-family counts, the largest deviations, iteration totals and
`N passed, N failed`; exits non-zero on any failure. A missing cvxopt is a
failure, not a skip.
"""
import json
import os
import subprocess
import sys
import time

import numpy as np

TOL_X = 1e-9
TOL_F = 1e-9
TOL_L = 1e-9
TOL_KKT = 1e-10

try:
    import cvxopt
    from cvxopt import solvers
except ImportError:
    print("FAIL: cvxopt is not importable by %s (apt-get install python3-cvxopt)" % sys.executable)
    print("0 passed, 1 failed")
    sys.exit(1)

solvers.options.update({"show_progress": False, "abstol": 1e-12, "reltol": 1e-12,
                        "feastol": 1e-12, "maxiters": 200})


# ---------------------------------------------------------------- generators
def spd(rng, n, cond=None):
    """Random symmetric positive definite matrix with the given condition number."""
    if cond is None:
        cond = 10.0 ** rng.uniform(0, 3)
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    ev = np.logspace(0, np.log10(cond), n) * 10.0 ** rng.uniform(-1, 1)
    h = (q * ev) @ q.T
    return 0.5 * (h + h.T)


def problem(kind, H, c, E=None, e=None, G=None, g=None, expect="ok", x_known=None, lam_known=None):
    n = len(c)
    E = np.zeros((0, n)) if E is None else np.asarray(E, float).reshape(-1, n)
    G = np.zeros((0, n)) if G is None else np.asarray(G, float).reshape(-1, n)
    e = np.zeros(0) if e is None else np.asarray(e, float)
    g = np.zeros(0) if g is None else np.asarray(g, float)
    return {"kind": kind, "H": H, "c": np.asarray(c, float), "E": E, "e": e, "G": G, "g": g,
            "expect": expect, "x_known": x_known, "lam_known": lam_known}


def feasible_rows(rng, n, m, x_feas, frac_tight=0.3):
    """m random rows satisfied at x_feas, a fraction of them tightly."""
    G = rng.standard_normal((m, n))
    slack = rng.exponential(1.0, m) * (rng.random(m) > frac_tight)
    return G, G @ x_feas - slack


def gen_random(rng):
    n = int(rng.integers(2, 61))
    m = int(rng.integers(1, 3 * n + 1))
    H = spd(rng, n)
    x_unc = rng.standard_normal(n)
    c = H @ x_unc
    # Put the feasible region away from the unconstrained minimum so that
    # many rows bind.
    x_feas = x_unc + rng.standard_normal(n) * 2.0
    G, g = feasible_rows(rng, n, m, x_feas)
    return problem("random", H, c, G=G, g=g)


def gen_mixed(rng):
    n = int(rng.integers(2, 61))
    p = int(rng.integers(1, max(1, n // 2) + 1))
    m = int(rng.integers(1, 2 * n + 1))
    H = spd(rng, n)
    c = rng.standard_normal(n) * 3
    x_feas = rng.standard_normal(n)
    E = rng.standard_normal((p, n))
    G, g = feasible_rows(rng, n, m, x_feas)
    return problem("mixed", H, c, E, E @ x_feas, G, g)


def known_optimum(rng, n, n_eq, n_act, n_weak, n_inact, rows=None):
    """Rows through x* with given multipliers: c = H x* - N^T lambda."""
    H = spd(rng, n)
    x = rng.standard_normal(n)
    total = n_eq + n_act + n_weak + n_inact
    N = rng.standard_normal((total, n)) if rows is None else rows
    E = N[:n_eq]
    Ga = N[n_eq:n_eq + n_act]
    Gw = N[n_eq + n_act:n_eq + n_act + n_weak]
    Gi = N[n_eq + n_act + n_weak:]
    lam_e = rng.standard_normal(n_eq)
    lam_a = rng.uniform(0.1, 2.0, n_act)
    c = H @ x - E.T @ lam_e - Ga.T @ lam_a
    G = np.vstack([Ga, Gw, Gi])
    g = np.concatenate([Ga @ x, Gw @ x, Gi @ x - rng.uniform(0.1, 1.0, n_inact)])
    lam_in = np.concatenate([lam_a, np.zeros(n_weak + n_inact)])
    perm = rng.permutation(len(g))
    return H, c, E, E @ x, G[perm], g[perm], x, lam_in[perm]


def gen_vertex(rng):
    n = int(rng.integers(2, 61))
    n_eq = int(rng.integers(0, n // 2 + 1))
    H, c, E, e, G, g, x, lam = known_optimum(rng, n, n_eq, n - n_eq, 0, int(rng.integers(0, n + 1)))
    return problem("vertex", H, c, E, e, G, g, x_known=x, lam_known=lam)


def gen_degenerate_vertex(rng):
    """More rows through x* than unknowns, some with zero multiplier."""
    n = int(rng.integers(2, 41))
    n_eq = int(rng.integers(0, n // 3 + 1))
    n_act = int(rng.integers(1, n - n_eq + 1))
    n_weak = int(rng.integers(1, n + 2))
    H, c, E, e, G, g, x, _ = known_optimum(rng, n, n_eq, n_act, n_weak, int(rng.integers(0, n + 1)))
    return problem("degenerate_vertex", H, c, E, e, G, g, x_known=x)


def gen_duplicated(rng):
    """Exact duplicates and positive multiples of rows, active ones included."""
    pr = gen_mixed(rng) if rng.random() < 0.5 else gen_random(rng)
    G, g = pr["G"], pr["g"]
    k = int(rng.integers(1, len(g) + 1))
    idx = rng.integers(0, len(g), k)
    scale = np.where(rng.random(k) < 0.5, 1.0, rng.uniform(0.1, 10.0, k))
    G2 = np.vstack([G, G[idx] * scale[:, None]])
    g2 = np.concatenate([g, g[idx] * scale])
    E, e = pr["E"], pr["e"]
    if len(e) and rng.random() < 0.7:
        j = rng.integers(0, len(e), int(rng.integers(1, len(e) + 1)))
        s = rng.uniform(-3, 3, len(j))
        E, e = np.vstack([E, E[j] * s[:, None]]), np.concatenate([e, e[j] * s])
    perm = rng.permutation(len(g2))
    return problem("duplicated", pr["H"], pr["c"], E, e, G2[perm], g2[perm])


def gen_zero_rows(rng):
    pr = gen_mixed(rng)
    n = len(pr["c"])
    kz = int(rng.integers(1, 4))
    G = np.vstack([pr["G"], np.zeros((kz, n))])
    g = np.concatenate([pr["g"], -rng.uniform(0, 1, kz) * (rng.random(kz) < 0.5)])
    E = np.vstack([pr["E"], np.zeros((1, n))])
    e = np.concatenate([pr["e"], [0.0]])
    return problem("zero_rows", pr["H"], pr["c"], E, e, G, g)


def gen_redundant_eq(rng):
    """Equalities that are linear combinations of others (consistent)."""
    n = int(rng.integers(3, 61))
    p = int(rng.integers(1, max(2, n // 2)))
    H = spd(rng, n)
    c = rng.standard_normal(n) * 3
    x_feas = rng.standard_normal(n)
    E0 = rng.standard_normal((p, n))
    comb = rng.standard_normal((int(rng.integers(1, p + 2)), p))
    E = np.vstack([E0, comb @ E0])
    E = E[rng.permutation(len(E))]
    G, g = feasible_rows(rng, n, int(rng.integers(0, 2 * n + 1)), x_feas)
    return problem("redundant_eq", H, c, E, E @ x_feas, G, g)


def gen_nearly_parallel(rng):
    """Clusters of rows within a small angle of each other (adjacent contact
    nodes on one flank), all through a common point so the optimum stays
    well conditioned. Angles 1e-6..1e-2 rad, and 1e-14 (duplicates up to
    round-off)."""
    n = int(rng.integers(2, 61))
    H = spd(rng, n)
    x_star = rng.standard_normal(n)
    rows, rhs = [], []
    for _ in range(int(rng.integers(1, max(2, n // 2) + 1))):
        base = rng.standard_normal(n)
        theta = 1e-14 if rng.random() < 0.2 else 10.0 ** rng.uniform(-6, -2)
        for _ in range(int(rng.integers(2, 5))):
            r = base + theta * np.linalg.norm(base) * rng.standard_normal(n) / np.sqrt(n)
            rows.append(r)
            rhs.append(r @ x_star)
    G = np.array(rows)
    g = np.array(rhs)
    # Pull the unconstrained minimum through the cluster's rows.
    c = H @ (x_star - 2.0 * G.T @ rng.uniform(0, 1, len(g)) / len(g))
    return problem("nearly_parallel", H, c, G=G, g=g)


def gen_box(rng):
    n = int(rng.integers(2, 61))
    H = spd(rng, n) if rng.random() < 0.5 else np.diag(rng.uniform(0.5, 2, n))
    c = rng.standard_normal(n) * 3
    lo = -rng.uniform(0.1, 1, n)
    hi = rng.uniform(0.1, 1, n)
    G = np.vstack([np.eye(n), -np.eye(n)])
    g = np.concatenate([lo, -hi])
    return problem("box", H, c, G=G, g=g)


def gen_simplex(rng):
    n = int(rng.integers(2, 61))
    y = rng.standard_normal(n)
    return problem("simplex", np.eye(n), y, np.ones((1, n)), [1.0], np.eye(n), np.zeros(n))


def gen_ill(rng):
    pr = gen_mixed(rng)
    n = len(pr["c"])
    pr["H"] = spd(rng, n, cond=10.0 ** rng.uniform(4, 6))
    pr["kind"] = "ill_conditioned_H"
    return pr


def gen_infeasible(rng):
    n = int(rng.integers(2, 61))
    H = spd(rng, n)
    c = rng.standard_normal(n)
    k = int(rng.integers(0, 5))
    if k == 0:  # a >= 1 and -a >= 0 along a random direction, among random rows
        a = rng.standard_normal(n)
        G0, g0 = feasible_rows(rng, n, int(rng.integers(0, n + 1)), rng.standard_normal(n))
        G = np.vstack([G0, a, -a * rng.uniform(0.5, 2)])
        g = np.concatenate([g0, [1.0, 0.0]])
        perm = rng.permutation(len(g))
        return problem("infeasible_pair", H, c, G=G[perm], g=g[perm], expect="infeasible")
    if k == 1:  # Farkas: y >= 0, G^T y = 0, g^T y > 0
        m = int(rng.integers(2, n + 2))
        G = rng.standard_normal((m, n))
        y = rng.uniform(0.5, 1.5, m)
        G[-1] = -(y[:-1] @ G[:-1]) / y[-1]
        g = rng.standard_normal(m)
        g[-1] += (1.0 - y @ g) / y[-1]  # now y^T g = 1 > 0
        return problem("infeasible_farkas", H, c, G=G, g=g, expect="infeasible")
    if k == 2:  # inconsistent dependent equalities
        p = int(rng.integers(1, n))
        E0 = rng.standard_normal((p, n))
        x = rng.standard_normal(n)
        w = rng.standard_normal(p)
        E = np.vstack([E0, w @ E0])
        e = np.concatenate([E0 @ x, [w @ E0 @ x + rng.choice([-1, 1]) * rng.uniform(0.01, 1)]])
        return problem("infeasible_eq", H, c, E, e, expect="infeasible")
    if k == 3:  # equality against inequalities
        a = rng.standard_normal(n)
        return problem("infeasible_eq_ineq", H, c, a[None, :], [0.0], np.vstack([a, rng.standard_normal(n)]),
                       [1.0, -1e3], expect="infeasible")
    zero = np.zeros((1, n))  # 0 >= positive
    G0, g0 = feasible_rows(rng, n, n, rng.standard_normal(n))
    return problem("infeasible_zero_row", H, c, G=np.vstack([G0, zero]), g=np.concatenate([g0, [0.5]]),
                   expect="infeasible")


def gen_singular(rng):
    pr = gen_mixed(rng)
    n = len(pr["c"])
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    ev = np.logspace(0, 2, n)
    if rng.random() < 0.5:
        ev[rng.integers(0, n)] = -rng.uniform(1e-3, 1)  # indefinite
        kind = "indefinite_H"
    else:
        ev[rng.integers(0, n)] = 0.0  # positive semidefinite, singular
        kind = "semidefinite_H"
    h = (q * ev) @ q.T
    pr["H"] = 0.5 * (h + h.T)
    pr["kind"] = kind
    pr["expect"] = "singular"
    return pr


FAMILIES = [  # (generator, count)
    (gen_random, 200), (gen_mixed, 150), (gen_vertex, 100), (gen_degenerate_vertex, 100),
    (gen_duplicated, 100), (gen_zero_rows, 50), (gen_redundant_eq, 80), (gen_nearly_parallel, 100),
    (gen_box, 50), (gen_simplex, 50), (gen_ill, 50), (gen_infeasible, 100), (gen_singular, 40),
]


# ---------------------------------------------------------------- reference
def independent_rows(N, first=0, tol=1e-10):
    """Indices of a well-conditioned maximal set of linearly independent rows
    of N: Gram-Schmidt with pivoting (each step takes the row with the
    largest part outside the span so far), rows below `first` taken first.
    Stops when no row has more than tol (relative to the largest row) left."""
    N = np.asarray(N, float)
    if len(N) == 0:
        return []
    scale = max(np.max(np.linalg.norm(N, axis=1)), 1e-300)
    res = N.copy()
    keep = []
    for _ in range(min(N.shape)):
        norms = np.linalg.norm(res, axis=1)
        norms[keep] = -1.0
        cand = [i for i in range(first) if i not in keep]
        pool = cand if cand and max(norms[cand]) > tol * scale else range(len(N))
        i = max(pool, key=lambda j: norms[j])
        if norms[i] <= tol * scale:
            break
        keep.append(i)
        q = res[i] / norms[i]
        res -= np.outer(res @ q, q)
        res -= np.outer(res @ q, q)  # twice is enough (Kahan-Parlett)
    return sorted(keep)


def cvxopt_solve(pr):
    H, c, E, e, G, g = pr["H"], pr["c"], pr["E"], pr["e"], pr["G"], pr["g"]
    n = len(c)
    # cvxopt needs rank(A) = rows: keep independent equality rows (the others
    # are consistent by construction); zero inequality rows are trivially met.
    ke = independent_rows(E) if len(e) else []
    kg = [j for j in range(len(g)) if np.any(G[j] != 0.0)]
    args = [cvxopt.matrix(H), cvxopt.matrix(-c)]
    if kg:
        args += [cvxopt.matrix(-G[kg]), cvxopt.matrix(-g[kg])]
    else:
        args += [cvxopt.matrix(np.zeros((1, n))), cvxopt.matrix(np.ones(1))]
    if ke:
        args += [cvxopt.matrix(E[ke]), cvxopt.matrix(e[ke])]
    # At 1e-12 cvxopt sometimes stalls ("unknown") or breaks down (division
    # by zero, domain error) on ill-conditioned or degenerate problems. Take
    # the first run, down a ladder of tolerances, that is "optimal" or whose
    # residuals are below 1e-6 (a stalled 1e-12 run is still closer to the
    # optimum than a converged 1e-8 one); else the run with the smallest
    # residuals.
    # (The answer is polished anyway; a looser run only has to find the
    # active set.)
    best = None
    for tol in (1e-12, 1e-10, 1e-8):
        try:
            sol = solvers.qp(*args, options={"show_progress": False, "abstol": tol,
                                             "reltol": tol, "feastol": tol, "maxiters": 200})
        except (ValueError, ArithmeticError):
            continue
        bad = max(abs(sol["relative gap"] if sol["relative gap"] is not None else 1.0),
                  sol["primal infeasibility"] if sol["primal infeasibility"] is not None else 1.0,
                  sol["dual infeasibility"] if sol["dual infeasibility"] is not None else 1.0)
        if sol["status"] not in ("optimal", "unknown"):
            bad = np.inf
        if best is None or bad < best[0]:
            best = (bad, sol)
        if sol["status"] == "optimal" or bad < 1e-6:
            break
    if best is None:
        raise ValueError("cvxopt broke down at every tolerance")
    sol = best[1]
    x = np.array(sol["x"]).ravel()
    lam_in = np.zeros(len(g))
    if kg:
        lam_in[kg] = np.array(sol["z"]).ravel()
    lam_eq = np.zeros(len(e))
    if ke:
        lam_eq[ke] = -np.array(sol["y"]).ravel()
    return sol, x, lam_eq, lam_in


def independent_infeasibility(pr):
    """Confirm infeasibility without the solver under test: a zero row with a
    positive right-hand side, inconsistent equalities (least-squares residual),
    or else cvxopt not finding an optimum. Returns an error string or ''."""
    G, g, E, e = pr["G"], pr["g"], pr["E"], pr["e"]
    if np.any(np.all(G == 0.0, axis=1) & (g > 0.0)):
        return ""
    if len(e):
        xe = np.linalg.lstsq(E, e, rcond=None)[0]
        if np.linalg.norm(E @ xe - e) > 1e-8 * max(1.0, np.linalg.norm(e)):
            return ""
    try:
        sol = cvxopt_solve(pr)[0]
    except (ValueError, ArithmeticError):
        return ""
    if sol["status"] == "optimal":
        return "cvxopt calls a problem optimal that the construction made infeasible"
    return ""


def objective(pr, x):
    return 0.5 * x @ pr["H"] @ x - pr["c"] @ x


def slacks(pr, x):
    return pr["G"] @ x - pr["g"]


def row_scale(pr, x):
    """Scale of row j's residual: |g_j| + |G_j| max(1, |x|) (never 0)."""
    return np.abs(pr["g"]) + np.linalg.norm(pr["G"], axis=1) * max(1.0, np.linalg.norm(x)) + 1e-300


def kkt_residuals(pr, x, lam_eq, lam_in):
    """Relative residuals: stationarity, primal (eq, ineq), dual, complementarity."""
    H, c, E, e, G, g = pr["H"], pr["c"], pr["E"], pr["e"], pr["G"], pr["g"]
    grad = H @ x - c - E.T @ lam_eq - G.T @ lam_in
    sc = (np.linalg.norm(H, 2) * np.linalg.norm(x) + np.linalg.norm(c)
          + np.linalg.norm(E.T @ np.abs(lam_eq)) + np.linalg.norm(G.T @ np.abs(lam_in)) + 1.0)
    stat = np.linalg.norm(grad) / sc
    res_e = E @ x - e
    peq = np.max(np.abs(res_e) / (np.abs(e) + np.linalg.norm(E, axis=1) * max(1, np.linalg.norm(x)) + 1e-300),
                 initial=0.0) if len(e) else 0.0
    s = slacks(pr, x)
    rs = row_scale(pr, x)
    pin = np.max(np.maximum(-s, 0) / rs, initial=0.0) if len(g) else 0.0
    lmax = max(1.0, np.max(np.abs(lam_in), initial=0.0))
    dual = np.max(np.maximum(-lam_in, 0), initial=0.0) / lmax
    comp = np.max(np.abs(lam_in * s) / (rs * lmax), initial=0.0) if len(g) else 0.0
    return max(stat, peq, pin, dual, comp), dict(stat=stat, peq=peq, pin=pin, dual=dual, comp=comp)


def kkt_solve(pr, act):
    """Minimiser and multipliers with the rows act (and all equalities) held
    as equalities. Rows numerically dependent on earlier ones (equalities
    first, then act in order) are left out of the solve (multiplier 0); the
    caller checks that they hold. Solved by LU, so x is accurate even when the
    remaining system is ill conditioned (LU with partial pivoting is backward
    stable; a truncated least-squares solve would not hold nearly parallel rows)."""
    H, c, E, e, G, g = pr["H"], pr["c"], pr["E"], pr["e"], pr["G"], pr["g"]
    n = len(c)
    act = list(act)
    N = np.vstack([E, G[act]]) if act else E
    b = np.concatenate([e, g[act]])
    keep = independent_rows(N, first=len(e)) if len(b) else []
    N = N[keep]
    b = b[keep]
    k = len(b)
    K = np.block([[H, -N.T], [N, np.zeros((k, k))]]) if k else H
    try:
        sol = np.linalg.solve(K, np.concatenate([c, b]))
    except np.linalg.LinAlgError:
        sol = np.linalg.lstsq(K, np.concatenate([c, b]), rcond=None)[0]
    lam = np.zeros(len(e) + len(act))
    lam[keep] = sol[n:]
    lam_in = np.zeros(len(g))
    lam_in[act] = lam[len(e):]
    return sol[:n], lam[:len(e)], lam_in


def kkt_refined(pr, tight):
    """Solve the KKT system with all equalities and the rows `tight` held as
    equalities, by LU and three steps of iterative refinement with residuals
    in extended precision (long double). Returns (x, lam_eq, lam_in,
    condition number of the KKT matrix)."""
    H, c, E, e, G, g = pr["H"], pr["c"], pr["E"], pr["e"], pr["G"], pr["g"]
    n = len(c)
    N = np.vstack([E, G[tight]])
    b = np.concatenate([e, g[tight]])
    k = len(b)
    K = np.block([[H, -N.T], [N, np.zeros((k, k))]])
    rhs = np.concatenate([c, b])
    sol = np.linalg.solve(K, rhs)
    Kl = K.astype(np.longdouble)
    rl = rhs.astype(np.longdouble)
    for _ in range(3):
        res = rl - Kl @ sol.astype(np.longdouble)
        sol = (sol.astype(np.longdouble) + np.linalg.solve(K, res.astype(float))).astype(float)
    lam_in = np.zeros(len(g))
    lam_in[tight] = sol[n + len(e):]
    return sol[:n], sol[n:n + len(e)], lam_in, np.linalg.cond(K)


def nnls(A, b, n_free):
    """Lawson-Hanson non-negative least squares: minimise |A y - b| with
    y[n_free:] >= 0 (the first n_free entries are free)."""
    k = A.shape[1]
    tol = 1e-14 * max(1.0, np.linalg.norm(A) * np.linalg.norm(b))

    def ls(P):
        z = np.zeros(k)
        if P:
            z[P] = np.linalg.lstsq(A[:, P], b, rcond=None)[0]
        return z

    passive = list(range(n_free))
    spent = set()
    y = ls(passive)
    for _ in range(3 * k + 10):
        w = A.T @ (b - A @ y)
        cand = [j for j in range(n_free, k) if j not in passive and j not in spent and w[j] > tol]
        if not cand:
            break
        j_new = max(cand, key=lambda j: w[j])
        passive.append(j_new)
        for _ in range(3 * k + 10):
            z = ls(passive)
            bad = [j for j in passive if j >= n_free and z[j] <= 0.0]
            if not bad:
                y = z
                break
            if j_new in bad and y[j_new] == 0.0:  # round-off: w_j > 0 but no progress
                passive.remove(j_new)
                spent.add(j_new)
                break
            alpha = min(y[j] / (y[j] - z[j]) for j in bad if y[j] > 0.0)
            y = y + alpha * (z - y)
            passive = [j for j in passive if j < n_free or y[j] > 1e-300]
            y[[j for j in range(n_free, k) if j not in passive]] = 0.0
    return y


def certify(pr, x):
    """Certify x as the optimum: feasible, and multipliers with lambda_in >= 0
    on the rows tight at x (zero elsewhere) found by NNLS that make the KKT
    residuals (relative) at most TOL_KKT. Returns (ok, lam_eq, lam_in,
    tight rows, residual parts)."""
    E, G = pr["E"], pr["G"]
    s = slacks(pr, x)
    rs = row_scale(pr, x)
    tight = [j for j in range(len(s)) if np.any(G[j] != 0.0) and s[j] <= 1e-10 * rs[j]]
    A = np.hstack([E.T, G[tight].T])
    y = nnls(A, pr["H"] @ x - pr["c"], len(pr["e"])) if A.shape[1] else np.zeros(0)
    lam_eq = y[:len(pr["e"])]
    lam_in = np.zeros(len(s))
    lam_in[tight] = y[len(pr["e"]):]
    worst, parts = kkt_residuals(pr, x, lam_eq, lam_in)
    return worst <= TOL_KKT, lam_eq, lam_in, tight, parts


def polish(pr, x_c, z_c):
    """Polish cvxopt's answer. Start from the rows cvxopt calls strongly
    active (multiplier above 1e-3 of the largest, small slack), take them as
    equalities and solve the KKT system; while the point violates a row, add
    the most violated; once it is feasible, certify it (NNLS multipliers),
    or else release the most negative multiplier of the KKT solve and go on.
    Returns (x, lam_eq, lam_in, tight) or a string saying why it failed."""
    G = pr["G"]
    nz = np.any(G != 0.0, axis=1)
    s = slacks(pr, x_c)
    rs = row_scale(pr, x_c)
    zmax = max(1e-300, np.max(z_c, initial=0.0))
    act = [j for j in range(len(s)) if nz[j] and z_c[j] > 1e-3 * zmax and s[j] < 1e-5 * rs[j]]
    parts = None
    for _ in range(4 * (len(s) + 1)):
        x, leq, lin = kkt_solve(pr, act)
        s = slacks(pr, x)
        rs = row_scale(pr, x)
        viol = [(s[j] / rs[j], j) for j in range(len(s)) if nz[j] and j not in act and s[j] < -1e-13 * rs[j]]
        if viol:
            act.append(min(viol)[1])
            continue
        ok, leq_c, lin_c, tight, parts = certify(pr, x)
        if ok:
            return x, leq_c, lin_c, tight
        neg = [(lin[j], j) for j in act if lin[j] < 0.0]
        if not neg:
            break
        act.remove(min(neg)[1])
    return "polished point not certified: %s" % parts


def reference(pr):
    """Certified reference (dict) or a string saying why there is none."""
    try:
        sol, x_c, leq_c, lin_c = cvxopt_solve(pr)
    except (ValueError, ArithmeticError) as ex:
        return "cvxopt failed: %s" % ex
    if sol["status"] not in ("optimal", "unknown"):
        return "cvxopt status %s" % sol["status"]
    pol = polish(pr, x_c, lin_c)
    if isinstance(pol, str):
        return pol
    x, leq, lin, tight = pol
    f = objective(pr, x)
    fscale = max(1.0, abs(f), abs(pr["c"] @ x))
    # cvxopt's own point must not beat the reference: by the KKT conditions
    # at x, f(x_c) - f(x) = 1/2 |x_c - x|_H^2 + lam_eq^T (E x_c - e)
    # + lam_in^T (G x_c - g), so f(x) - f(x_c) is at most what x_c gains by
    # violating rows.
    gain = (np.abs(leq) @ np.abs(pr["E"] @ x_c - pr["e"])
            + lin @ np.maximum(0.0, -slacks(pr, x_c)))
    if f - objective(pr, x_c) > gain + 1e-9 * fscale:
        return "cvxopt's point beats the polished one by %.2e" % (f - objective(pr, x_c))
    # Multipliers are unique when the rows tight at x are linearly
    # independent (LICQ), and compared only then. They may still be ill
    # conditioned (nearly parallel rows, vertices): a backward-stable solver
    # gets them to about eps kappa(K), K the KKT matrix of the tight rows, so
    # the tolerance is max(1e-9, eps kappa(K)). The reference itself is
    # refined in extended precision (see kkt_refined) so that its own error
    # is negligible next to that.
    N = np.vstack([pr["E"], pr["G"][tight]])
    unique = True
    kappa = 1.0
    if len(N):
        sv = np.linalg.svd(N, compute_uv=False)
        unique = len(N) <= len(x) and sv[-1] > 1e-6 * sv[0]
    if unique and len(N):
        x, leq, lin, kappa = kkt_refined(pr, tight)
        f = objective(pr, x)
    tol_l = max(TOL_L, np.finfo(float).eps * kappa)
    return dict(x=x, f=f, fscale=fscale, lam_eq=leq, lam_in=lin, unique=unique, tol_l=tol_l,
                kappa=kappa, x_cvx=x_c, f_cvx=objective(pr, x_c))


# ---------------------------------------------------------------- driver
def write_problems(path, probs, rng):
    with open(path, "w") as fh:
        for pr in probs:
            n = len(pr["c"])
            m = len(pr["g"])
            warm = []
            if m and rng.random() < 0.8:
                warm = sorted(rng.choice(m, int(rng.integers(1, min(m, n) + 1)), replace=False).tolist())
            pr["warm"] = warm
            fh.write("%d %d %d %d\n" % (n, len(pr["e"]), m, len(warm)))
            for a in (pr["H"], pr["c"], pr["E"], pr["e"], pr["G"], pr["g"]):
                if a.size:
                    fh.write(" ".join(repr(float(v)) for v in a.ravel()) + "\n")
            if warm:
                fh.write(" ".join(str(j) for j in warm) + "\n")


def rel(a, b):
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if a.size == 0:
        return 0.0
    return float(np.max(np.abs(a - b)) / max(1.0, np.max(np.abs(b))))


def main():
    build = os.environ.get("GEARSIM_BUILD_ROOT", "build")
    driver = os.path.join(build, "tests", "tools", "qp_driver")
    if not os.path.exists(driver):
        print("FAIL: %s not built" % driver)
        print("0 passed, 1 failed")
        return 1
    seed = int(os.environ.get("GEARSIM_QP_SEED", "20240605"))
    rng = np.random.default_rng(seed)
    probs = []
    for gen, count in FAMILIES:
        for _ in range(count):
            probs.append(gen(rng))
    tmp = os.path.join(build, "qp_cvxopt_problems.txt")
    write_problems(tmp, probs, rng)
    t0 = time.time()
    out = subprocess.run([driver, tmp], capture_output=True, text=True, timeout=600)
    t_drv = time.time() - t0
    if out.returncode != 0:
        print("FAIL: qp_driver exited %d: %s" % (out.returncode, out.stderr.strip()))
        print("0 passed, 1 failed")
        return 1
    results = [json.loads(line) for line in out.stdout.splitlines()]
    if len(results) != len(probs):
        print("FAIL: driver answered %d of %d problems" % (len(results), len(probs)))
        print("0 passed, 1 failed")
        return 1

    passed = failed = 0
    compared = 0
    mx = dict(x=0.0, f=0.0, lam=0.0, lam_base=0.0, lam_scaled=0.0, kappa=0.0, kkt=0.0,
              x_known=0.0, x_cvx_raw=0.0, f_cvx_raw=0.0)
    n_lam = n_lam_base = 0
    raw_hist = [0, 0, 0]
    iters = dict(cold=0, hot=0, warm=0)
    by_kind = {}
    t_ref = 0.0
    for pr, res in zip(probs, results):
        errs = []
        kind = pr["kind"]
        solves = [(name, res[name]) for name in ("cold", "hot", "warm") if res[name] is not None]
        if pr["expect"] == "ok":
            t0 = time.time()
            ref = reference(pr)
            t_ref += time.time() - t0
            if isinstance(ref, str):
                errs.append("reference: " + ref)
            else:
                compared += 1
                raw = rel(ref["x_cvx"], ref["x"])
                mx["x_cvx_raw"] = max(mx["x_cvx_raw"], raw)
                raw_hist[0 if raw <= 1e-9 else 1 if raw <= 1e-6 else 2] += 1
                mx["f_cvx_raw"] = max(mx["f_cvx_raw"], abs(ref["f_cvx"] - ref["f"]) / ref["fscale"])
                for name, s in solves:
                    if s["status"] != "ok":
                        errs.append("%s: status %s" % (name, s["status"]))
                        continue
                    iters[name] += s["iterations"]
                    dx = rel(s["x"], ref["x"])
                    df = abs(s["objective"] - ref["f"]) / ref["fscale"]
                    kkt, parts = kkt_residuals(pr, np.array(s["x"]), np.array(s["lambda_eq"]),
                                               np.array(s["lambda_in"]))
                    mx["x"] = max(mx["x"], dx)
                    mx["f"] = max(mx["f"], df)
                    mx["kkt"] = max(mx["kkt"], kkt)
                    if dx > TOL_X:
                        errs.append("%s: x deviates %.2e" % (name, dx))
                    if df > TOL_F:
                        errs.append("%s: objective deviates %.2e" % (name, df))
                    if kkt > TOL_KKT:
                        errs.append("%s: KKT residual %.2e %s" % (name, kkt, parts))
                    if ref["unique"]:
                        dl = max(rel(s["lambda_eq"], ref["lam_eq"]), rel(s["lambda_in"], ref["lam_in"]))
                        mx["lam"] = max(mx["lam"], dl)
                        mx["lam_scaled"] = max(mx["lam_scaled"], dl / ref["tol_l"])
                        mx["kappa"] = max(mx["kappa"], ref["kappa"])
                        n_lam += 1
                        if ref["tol_l"] == TOL_L:
                            n_lam_base += 1
                            mx["lam_base"] = max(mx["lam_base"], dl)
                        if dl > ref["tol_l"]:
                            errs.append("%s: multipliers deviate %.2e" % (name, dl))
                    if pr["x_known"] is not None:
                        dk = rel(s["x"], pr["x_known"])
                        mx["x_known"] = max(mx["x_known"], dk)
                        if dk > TOL_X:
                            errs.append("%s: x deviates %.2e from the constructed optimum" % (name, dk))
        elif pr["expect"] == "infeasible":
            for name, s in solves:
                if s["status"] != "infeasible":
                    errs.append("%s: status %s, expected infeasible" % (name, s["status"]))
            why = independent_infeasibility(pr)
            if why:
                errs.append(why)
        else:
            for name, s in solves:
                if s["status"] != "singular":
                    errs.append("%s: status %s, expected singular" % (name, s["status"]))
        k = by_kind.setdefault(kind, [0, 0])
        if errs:
            failed += 1
            k[1] += 1
            if failed <= 20:
                print("FAIL problem %d (%s, n=%d, n_eq=%d, n_in=%d): %s"
                      % (res["id"], kind, len(pr["c"]), len(pr["e"]), len(pr["g"]), "; ".join(errs)))
        else:
            passed += 1
            k[0] += 1
    print("problems by family (passed/failed):")
    for kind, (p, f) in by_kind.items():
        print("  %-20s %4d %4d" % (kind, p, f))
    print("compared with cvxopt: %d feasible problems x 3 solves (cold, hot, warm); "
          "multipliers unique in %d solves (%d at the base tolerance %.0e, the others at "
          "eps kappa(KKT), kappa up to %.1e)" % (compared, n_lam, n_lam_base, TOL_L, mx["kappa"]))
    print("multipliers: max deviation %.2e where the tolerance is 1e-9, max deviation / tolerance "
          "%.2f overall" % (mx["lam_base"], mx["lam_scaled"]))
    print("max relative deviation: x %.2e, objective %.2e, multipliers %.2e, KKT residual %.2e, "
          "x vs constructed optimum %.2e" % (mx["x"], mx["f"], mx["lam"], mx["kkt"], mx["x_known"]))
    print("raw cvxopt vs polished reference: max x %.2e, objective %.2e; x within 1e-9 in %d "
          "problems, within 1e-6 in %d more, beyond in %d (cvxopt stalls on degenerate ones)"
          % (mx["x_cvx_raw"], mx["f_cvx_raw"], raw_hist[0], raw_hist[1], raw_hist[2]))
    print("total iterations: cold %d, hot (warm from cold active set) %d, warm (random guess) %d"
          % (iters["cold"], iters["hot"], iters["warm"]))
    print("time: driver %.2f s for %d problems x 3 solves; cvxopt + polishing %.1f s"
          % (t_drv, len(probs), t_ref))
    print("%d passed, %d failed" % (passed, failed))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
