"""Squared distances, their gradients and Hessians (ipcsim.kernels.contact.distance).

Checked three ways:
  * against ipctk (the IPC Toolkit's Python bindings) on 10,000 random and near-degenerate
    configurations per stencil: closest-feature type, distance, gradient, Hessian;
  * against finite differences, for every sub-distance and every distance type;
  * against a brute-force closest-point computation written here in numpy (no ipctk).

Tolerances. Agreement is required to 1e-10 relative to ipctk's result (max-abs norm), plus
a floor for the rounding error that ANY floating-point evaluation carries. The inputs are
rounded to eps·|x|, and the closest-feature residual q (with d = |q|²) inherits that error
amplified by the geometric condition number κ of the feature:

    point-point: 1,   point-line: L/|e|,   point-plane: L²/|e1×e2|,   line-line: L²/|u×v|

(L = largest coordinate magnitude of the stencil; κ ~ 1/sin of the angle that defines the
line or normal). With δ = C·eps·κ·L the floors are

    d:    δ (2√d + δ)
    ∇d:   4δ (1 + κ√d/L)   (∇d = 2 c_i q: the closest-point parameters c shift by
                            ~eps·κ²·√d/L when the normal tilts by eps·κ)
    ∇²d:  C·eps·κ·(1 + min(κ, L/√d))·|∇²d|   (its q-dependent terms grow like (κ√d/L)²,
                            so its relative conditioning is up to eps·κ·L/√d, at most eps·κ²)

For well-shaped configurations these floors are far below 1e-10 relative; they matter
when d is near 0 (both results are then rounding noise of size eps·L) or for nearly
parallel edges, where d itself is ill-conditioned (the 60-digit test below shows ipcsim
is then as accurate as ipctk).
"""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.kernels.contact import distance as D

EPS = np.finfo(float).eps
C_FLOOR = 16.0  # rounding-error constant in the floor (see module doc)
N_CONFIGS = 10_000

PT_NAMES = ["P_T0", "P_T1", "P_T2", "P_E0", "P_E1", "P_E2", "P_T"]
EE_NAMES = ["EA0_EB0", "EA0_EB1", "EA1_EB0", "EA1_EB1", "EA_EB0", "EA_EB1", "EA0_EB",
            "EA1_EB", "EA_EB"]
PE_NAMES = ["P_E0", "P_E1", "P_E"]


@pytest.fixture(scope="module")
def ipctk():
    return pytest.importorskip("ipctk")


# =========================================================================================
# Configurations: random and near-degenerate (vectorised numpy, fixed seeds)
# =========================================================================================

def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _logu(rng, lo, hi, n):
    return 10.0 ** rng.uniform(lo, hi, n)


def _perp(rng, u):
    return _unit(np.cross(u, rng.standard_normal(u.shape)))


def pt_configs(n, seed=0):
    """(n, 4, 3) rows (p, t0, t1, t2), 8 families of n/8."""
    rng = np.random.default_rng(seed)
    m = n // 8
    out = []
    X = rng.standard_normal((m, 4, 3))  # 0: random
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 1: p near an edge line (also beyond its ends)
    a = rng.integers(0, 3, m)
    b = (a + rng.integers(1, 3, m)) % 3
    lam = rng.uniform(-0.3, 1.3, (m, 1))
    T = X[:, 1:]
    X[:, 0] = (T[np.arange(m), a] + lam * (T[np.arange(m), b] - T[np.arange(m), a])
               + _logu(rng, -12, -1, m)[:, None] * rng.standard_normal((m, 3)))
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 2: p near a vertex
    X[:, 0] = X[np.arange(m), 1 + rng.integers(0, 3, m)] + (
        _logu(rng, -12, -1, m)[:, None] * rng.standard_normal((m, 3)))
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 3: tiny triangle, p a few sizes away
    s = _logu(rng, -6, -2, m)[:, None]
    X[:, 1:] = X[:, 1:2] + s[:, None] * rng.standard_normal((m, 3, 3))
    X[:, 0] = X[:, 1:].mean(1) + s * _logu(rng, 0, 2, m)[:, None] * _unit(
        rng.standard_normal((m, 3)))
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 4: coplanar point (on the plane or 1e-12..1e-1 off)
    w = rng.uniform(-0.5, 1.5, (m, 2))
    T = X[:, 1:]
    nrm = _unit(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]))
    off = _logu(rng, -12, -1, m) * rng.integers(0, 2, m)
    X[:, 0] = (T[:, 0] + w[:, :1] * (T[:, 1] - T[:, 0]) + w[:, 1:] * (T[:, 2] - T[:, 0])
               + off[:, None] * nrm)
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 5: p just above the interior
    T = X[:, 1:]
    w = rng.dirichlet([1.0, 1.0, 1.0], m)
    nrm = _unit(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]))
    X[:, 0] = np.einsum("ij,ijk->ik", w, T) + _logu(rng, -10, -1, m)[:, None] * nrm
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 6: sliver triangle (t2 near line t0-t1)
    T = X[:, 1:]
    T[:, 2] = (T[:, 0] + rng.uniform(-0.5, 1.5, (m, 1)) * (T[:, 1] - T[:, 0])
               + _logu(rng, -6, -2, m)[:, None] * rng.standard_normal((m, 3)))
    X[:, 0] = T.mean(1) + 0.3 * rng.standard_normal((m, 3))
    out.append(X)
    X = rng.standard_normal((n - 7 * m, 4, 3))  # 7: random, different scales
    X *= _logu(rng, -3, 2, len(X))[:, None, None]
    out.append(X)
    return np.ascontiguousarray(np.concatenate(out))


def ee_configs(n, seed=1):
    """(n, 4, 3) rows (ea0, ea1, eb0, eb1), 8 families of n/8."""
    rng = np.random.default_rng(seed)
    m = n // 8
    out = []
    X = rng.standard_normal((m, 4, 3))  # 0: random
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 1: nearly parallel, sin θ from 1e-10 to 1e-1
    u = X[:, 1] - X[:, 0]
    v = u * (rng.uniform(0.3, 2.0, (m, 1)) * rng.choice([-1.0, 1.0], (m, 1)))
    v += (_logu(rng, -10, -1, m)[:, None] * np.linalg.norm(v, axis=1, keepdims=True)
          * _perp(rng, u))
    gap = rng.standard_normal((m, 3)) * rng.choice([1.0, 1e-3], (m, 1))
    X[:, 2] = X[:, 0] + rng.uniform(-1.0, 1.0, (m, 1)) * u + gap
    X[:, 3] = X[:, 2] + v
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 2: an endpoint of b near edge a's line
    u = X[:, 1] - X[:, 0]
    X[:, 2] = (X[:, 0] + rng.uniform(-0.3, 1.3, (m, 1)) * u
               + _logu(rng, -12, -1, m)[:, None] * rng.standard_normal((m, 3)))
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 3: coplanar (z = 0), optionally lifted slightly
    X[:, :, 2] = 0.0
    X[:, 3, 2] = _logu(rng, -12, -1, m) * rng.integers(0, 2, m)
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 4: exactly parallel / collinear
    u = X[:, 1] - X[:, 0]
    X[:, 2] = (X[:, 0] + rng.uniform(-1.0, 1.5, (m, 1)) * u
               + rng.integers(0, 2, (m, 1)) * _logu(rng, -10, -1, m)[:, None]
               * rng.standard_normal((m, 3)))
    X[:, 3] = X[:, 2] + rng.uniform(-2.0, 2.0, (m, 1)) * u
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 5: two endpoints close
    X[:, 2 + rng.integers(0, 2, m)] = X[np.arange(m), rng.integers(0, 2, m)] + (
        _logu(rng, -12, -1, m)[:, None] * rng.standard_normal((m, 3)))
    out.append(X)
    X = rng.standard_normal((m, 4, 3))  # 6: crossing segments with a small gap (line-line)
    c = rng.standard_normal((m, 3))
    u = rng.standard_normal((m, 3))
    v = rng.standard_normal((m, 3))
    nrm = _unit(np.cross(u, v))
    su, sv = rng.uniform(0.05, 0.95, (2, m, 1))
    X[:, 0], X[:, 1] = c - su * u, c + (1 - su) * u
    cb = c + _logu(rng, -10, -1, m)[:, None] * nrm
    X[:, 2], X[:, 3] = cb - sv * v, cb + (1 - sv) * v
    out.append(X)
    X = rng.standard_normal((n - 7 * m, 4, 3))  # 7: a short edge b
    X[:, 3] = X[:, 2] + _logu(rng, -6, -2, len(X))[:, None] * rng.standard_normal(
        (len(X), 3))
    out.append(X)
    return np.ascontiguousarray(np.concatenate(out))


def pe_configs(n, seed=2):
    """(n, 3, 3) rows (p, e0, e1), 5 families."""
    rng = np.random.default_rng(seed)
    m = n // 5
    out = []
    X = rng.standard_normal((m, 3, 3))  # random
    out.append(X)
    X = rng.standard_normal((m, 3, 3))  # near the line, inside and beyond the ends
    X[:, 0] = (X[:, 1] + rng.uniform(-0.3, 1.3, (m, 1)) * (X[:, 2] - X[:, 1])
               + _logu(rng, -12, -1, m)[:, None] * rng.standard_normal((m, 3)))
    out.append(X)
    X = rng.standard_normal((m, 3, 3))  # near an endpoint
    X[:, 0] = X[np.arange(m), 1 + rng.integers(0, 2, m)] + (
        _logu(rng, -12, -1, m)[:, None] * rng.standard_normal((m, 3)))
    out.append(X)
    X = rng.standard_normal((m, 3, 3))  # short edge
    X[:, 2] = X[:, 1] + _logu(rng, -6, -2, m)[:, None] * rng.standard_normal((m, 3))
    out.append(X)
    X = rng.standard_normal((n - 4 * m, 3, 3))  # exactly collinear
    X[:, 0] = X[:, 1] + rng.uniform(-1.0, 2.0, (len(X), 1)) * (X[:, 2] - X[:, 1])
    out.append(X)
    return np.ascontiguousarray(np.concatenate(out))


# =========================================================================================
# Condition-aware tolerance
# =========================================================================================

def _sub_stencil(X, kind, dtype):
    """(sub-distance name, its vertices) of a stencil evaluated with type dtype."""
    table = {"pt": D.PT_FEATURES, "ee": D.EE_FEATURES, "pe": D.PE_FEATURES}[kind]
    f = table[dtype]
    slots = [s for s in f[1:] if s >= 0]
    return int(f[0]), X[slots]


def condition(sub, V):
    """Geometric condition number κ of a sub-distance (module doc) and L."""
    L = max(np.abs(V).max(), 1e-300)
    if sub == D.POINT_POINT:
        k = 1.0
    elif sub == D.POINT_LINE:
        k = L / np.linalg.norm(V[2] - V[1])
    elif sub == D.POINT_PLANE:
        k = L * L / np.linalg.norm(np.cross(V[2] - V[1], V[3] - V[1]))
    else:
        k = L * L / np.linalg.norm(np.cross(V[1] - V[0], V[3] - V[2]))
    return max(k, 1.0), L


def check_close(mine, ref, d_ref, kappa, L, what):
    """Return (error / tolerance) for value, gradient or Hessian (max-abs norms)."""
    mine = np.ravel(mine)
    ref = np.ravel(ref)
    err = np.abs(mine - ref).max()
    nref = np.abs(ref).max()
    delta = C_FLOOR * EPS * kappa * L
    if what == "d":
        tol = 1e-10 * nref + delta * (2.0 * np.sqrt(max(d_ref, 0.0)) + delta)
    elif what == "g":
        tol = 1e-10 * nref + 4.0 * delta * (1.0 + kappa * np.sqrt(max(d_ref, 0.0)) / L)
    else:
        rho = min(kappa, L / np.sqrt(d_ref)) if d_ref > 0 else kappa
        tol = (1e-10 + C_FLOOR * EPS * kappa * (1.0 + rho)) * nref
    return err / max(tol, 1e-300), err / max(nref, 1e-300)


class Worst:
    """Collects error/tolerance ratios and plain relative errors; fails with context."""

    def __init__(self):
        self.ratio = {}
        self.rel = {}

    def add(self, key, res, info):
        ratio, rel = res
        if ratio > self.ratio.get(key, (0.0, None))[0]:
            self.ratio[key] = (ratio, info)
        if rel > self.rel.get(key, 0.0):
            self.rel[key] = rel

    def check(self):
        for k in sorted(self.ratio, key=str):
            print(f"  {k}: worst error/tolerance {self.ratio[k][0]:.2g} (config "
                  f"{self.ratio[k][1]}), worst relative error {self.rel[k]:.2g}")
        bad = {k: v for k, v in self.ratio.items() if v[0] > 1.0}
        assert not bad, f"error above tolerance: {bad}"


# =========================================================================================
# ipctk comparisons
# =========================================================================================

def _compare_stencil(ipctk, kind, configs, names):
    my_type = {"pt": D.point_triangle_distance_type, "ee": D.edge_edge_distance_type,
               "pe": D.point_edge_distance_type}[kind]
    mine = {"pt": (D.point_triangle_distance_sq, D.point_triangle_distance_sq_gradient,
                   D.point_triangle_distance_sq_hessian),
            "ee": (D.edge_edge_distance_sq, D.edge_edge_distance_sq_gradient,
                   D.edge_edge_distance_sq_hessian),
            "pe": (D.point_edge_distance_sq, D.point_edge_distance_sq_gradient,
                   D.point_edge_distance_sq_hessian)}[kind]
    ip_type = {"pt": ipctk.point_triangle_distance_type, "ee": ipctk.edge_edge_distance_type,
               "pe": ipctk.point_edge_distance_type}[kind]
    ip_enum = {"pt": ipctk.PointTriangleDistanceType, "ee": ipctk.EdgeEdgeDistanceType,
               "pe": ipctk.PointEdgeDistanceType}[kind]
    theirs = {"pt": (ipctk.point_triangle_distance, ipctk.point_triangle_distance_gradient,
                     ipctk.point_triangle_distance_hessian),
              "ee": (ipctk.edge_edge_distance, ipctk.edge_edge_distance_gradient,
                     ipctk.edge_edge_distance_hessian),
              "pe": (ipctk.point_edge_distance, ipctk.point_edge_distance_gradient,
                     ipctk.point_edge_distance_hessian)}[kind]
    enums = [ip_enum(i) for i in range(len(names))]
    counts = np.zeros(len(names), dtype=int)
    ties = 0
    worst = Worst()
    for i, X in enumerate(configs):
        args = tuple(X)
        t = int(my_type(*args))
        counts[t] += 1
        sub, V = _sub_stencil(X, kind, t)
        kappa, L = condition(sub, V)
        e = enums[t]
        d_ref = theirs[0](*args, e)
        worst.add(("d", names[t]), check_close(mine[0](*args, t), d_ref, d_ref, kappa, L, "d"),
                  i)
        worst.add(("g", names[t]), check_close(mine[1](*args, t), theirs[1](*args, e), d_ref,
                                               kappa, L, "g"), i)
        worst.add(("h", names[t]), check_close(mine[2](*args, t), theirs[2](*args, e), d_ref,
                                               kappa, L, "h"), i)
        t_ref = int(ip_type(*args))
        if t_ref != t:
            # a tie on a type boundary: both closest features must give the same distance
            ties += 1
            sub2, V2 = _sub_stencil(X, kind, t_ref)
            k2, _ = condition(sub2, V2)
            d_other = theirs[0](*args, enums[t_ref])
            worst.add(("tie", names[t]), check_close(mine[0](*args, t), d_other, d_other,
                                                     max(kappa, k2), L, "d"), i)
    worst.check()
    return counts, ties, worst


def test_type_codes_match_ipctk(ipctk):
    for names, enum, auto in ((PT_NAMES, ipctk.PointTriangleDistanceType, D.PT_AUTO),
                              (EE_NAMES, ipctk.EdgeEdgeDistanceType, D.EE_AUTO),
                              (PE_NAMES, ipctk.PointEdgeDistanceType, D.PE_AUTO)):
        for code, name in enumerate(names):
            assert int(getattr(enum, name)) == code
        assert int(enum.AUTO) == auto


@pytest.mark.parametrize("kind", ["pt", "ee", "pe"])
def test_stencil_distances_match_ipctk(ipctk, kind):
    configs, names = {"pt": (pt_configs(N_CONFIGS), PT_NAMES),
                      "ee": (ee_configs(N_CONFIGS), EE_NAMES),
                      "pe": (pe_configs(N_CONFIGS), PE_NAMES)}[kind]
    counts, ties, _ = _compare_stencil(ipctk, kind, configs, names)
    # every closest-feature type is exercised
    assert counts.min() >= 20, dict(zip(names, counts))
    # type selection agrees except on exact ties (none in these sets when last checked)
    assert ties <= 0.01 * len(configs), ties


def test_auto_type_values_match_ipctk(ipctk):
    """AUTO on both sides (each picks its own type): values agree, ties included."""
    for X in pt_configs(2000, seed=10):
        a = tuple(X)
        sub, V = _sub_stencil(X, "pt", int(D.point_triangle_distance_type(*a)))
        kappa, L = condition(sub, V)
        ref = ipctk.point_triangle_distance(*a)
        assert check_close(D.point_triangle_distance_sq(*a), ref, ref, kappa, L, "d")[0] <= 1
    for X in ee_configs(2000, seed=11):
        a = tuple(X)
        sub, V = _sub_stencil(X, "ee", int(D.edge_edge_distance_type(*a)))
        kappa, L = condition(sub, V)
        ref = ipctk.edge_edge_distance(*a)
        assert check_close(D.edge_edge_distance_sq(*a), ref, ref, kappa, L, "d")[0] <= 1


@pytest.mark.parametrize("name", ["point_point", "point_line", "point_plane", "line_line"])
def test_sub_distances_match_ipctk(ipctk, name):
    nv, sub = {"point_point": (2, D.POINT_POINT), "point_line": (3, D.POINT_LINE),
               "point_plane": (4, D.POINT_PLANE), "line_line": (4, D.LINE_LINE)}[name]
    rng = np.random.default_rng(5)
    X = rng.standard_normal((3000, nv, 3))
    # near-degenerate third: the point close to the line / plane / other line
    k = 1000
    if name == "point_line":
        X[:k, 0] = X[:k, 1] + rng.uniform(-1, 2, (k, 1)) * (X[:k, 2] - X[:k, 1])
    elif name in ("point_plane", "line_line"):
        X[:k, 0] = (X[:k, 1] + rng.uniform(-1, 2, (k, 1)) * (X[:k, 2] - X[:k, 1])
                    + rng.uniform(-1, 2, (k, 1)) * (X[:k, 3] - X[:k, 1]))
    X[:k, 0] += _logu(rng, -12, -1, k)[:, None] * rng.standard_normal((k, 3))
    mine = [getattr(D, f"{name}_distance_sq{s}") for s in ("", "_gradient", "_hessian")]
    theirs = [getattr(ipctk, f"{name}_distance{s}") for s in ("", "_gradient", "_hessian")]
    worst = Worst()
    for i, V in enumerate(np.ascontiguousarray(X)):
        a = tuple(V)
        kappa, L = condition(sub, V)
        d_ref = theirs[0](*a)
        for what, f, g in zip("dgh", mine, theirs):
            worst.add(what, check_close(f(*a), g(*a), d_ref, kappa, L, what), i)
    worst.check()


def test_near_parallel_line_line_against_60_digit_reference(ipctk):
    """For nearly parallel lines d² is ill-conditioned (κ ~ 1/sin θ): ipcsim must be within
    the rounding floor of a 60-digit reference (mpmath: the value, central differences for
    the gradient and Hessian). The printed ratios compare its error with ipctk's."""
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = 60
    rng = np.random.default_rng(8)

    def ll_exact(P):
        a0, a1, b0, b1 = P
        u = [a1[i] - a0[i] for i in range(3)]
        v = [b1[i] - b0[i] for i in range(3)]
        n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        s = sum((b0[i] - a0[i]) * n[i] for i in range(3))
        return s * s / sum(c * c for c in n)

    h = mp.mpf("1e-25")
    errs = []
    for _ in range(12):
        u = rng.standard_normal(3)
        sin = 10.0 ** rng.uniform(-7, -3)
        v = u * rng.uniform(0.5, 2.0) + sin * np.linalg.norm(u) * _perp(rng, u[None])[0]
        c = rng.standard_normal(3)
        X = np.array([c - 0.5 * u, c + 0.5 * u, c - 0.4 * v, c + 0.6 * v])
        X[2:] += 10.0 ** rng.uniform(-4, -1) * _unit(np.cross(u, v))
        a = tuple(X)
        assert int(D.edge_edge_distance_type(*a)) == D.EE_EA_EB
        P = [[mp.mpf(float(c_)) for c_ in x] for x in X]
        d_ex = ll_exact(P)
        g_ex = np.empty(12)
        for k in range(12):
            Pp = [r[:] for r in P]
            Pm = [r[:] for r in P]
            Pp[k // 3][k % 3] += h
            Pm[k // 3][k % 3] -= h
            g_ex[k] = float((ll_exact(Pp) - ll_exact(Pm)) / (2 * h))
        H_ex = np.empty((12, 12))
        hh = mp.mpf("1e-18")
        for k in range(12):
            for m_ in range(k, 12):
                acc = 0
                for sk, sm in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                    Q = [r[:] for r in P]
                    Q[k // 3][k % 3] += sk * hh
                    Q[m_ // 3][m_ % 3] += sm * hh
                    acc += sk * sm * ll_exact(Q)
                H_ex[k, m_] = H_ex[m_, k] = float(acc / (4 * hh * hh))
        e = ipctk.EdgeEdgeDistanceType.EA_EB
        d_mine, d_ip = D.line_line_distance_sq(*a), ipctk.edge_edge_distance(*a, e)
        g_mine = D.line_line_distance_sq_gradient(*a)
        g_ip = np.asarray(ipctk.edge_edge_distance_gradient(*a, e))
        err_d = (abs(d_mine - float(d_ex)), abs(d_ip - float(d_ex)))
        err_g = (np.abs(g_mine - g_ex).max(), np.abs(g_ip - g_ex).max())
        H_mine = D.line_line_distance_sq_hessian(*a)
        H_ip = np.asarray(ipctk.edge_edge_distance_hessian(*a, e))
        err_h = (np.abs(H_mine - H_ex).max(), np.abs(H_ip - H_ex).max())
        kappa, L = condition(D.LINE_LINE, X)
        assert check_close(d_mine, float(d_ex), float(d_ex), kappa, L, "d")[0] <= 1
        assert check_close(g_mine, g_ex, float(d_ex), kappa, L, "g")[0] <= 1
        assert check_close(H_mine, H_ex, float(d_ex), kappa, L, "h")[0] <= 1
        errs.append((err_d, err_g, err_h))
    errs = np.array(errs)  # (case, quantity, [ipcsim, ipctk])
    for q, name in enumerate(("d", "grad", "hess")):
        print(f"  near-parallel {name}: ipcsim/ipctk error to the 60-digit reference, "
              f"median ratio {np.median(errs[:, q, 0] / np.maximum(errs[:, q, 1], 1e-300)):.2g}")


# =========================================================================================
# Finite differences: every sub-distance and every distance type
# =========================================================================================

def _fd_gradient(f, X, h):
    x0 = X.ravel()
    g = np.empty(x0.size)
    for k in range(x0.size):
        xp, xm = x0.copy(), x0.copy()
        xp[k] += h
        xm[k] -= h
        g[k] = (f(xp.reshape(X.shape)) - f(xm.reshape(X.shape))) / (2 * h)
    return g


def _fd_jacobian(f, X, h):
    x0 = X.ravel()
    cols = []
    for k in range(x0.size):
        xp, xm = x0.copy(), x0.copy()
        xp[k] += h
        xm[k] -= h
        cols.append((np.ravel(f(xp.reshape(X.shape))) - np.ravel(f(xm.reshape(X.shape))))
                    / (2 * h))
    return np.array(cols).T


def _check_fd(val, grad, hess, X):
    h = 1e-6
    g = grad(X)
    H = hess(X)
    g_fd = _fd_gradient(val, X, h)
    H_fd = _fd_jacobian(grad, X, h)
    assert np.abs(g - g_fd).max() <= 1e-6 * max(np.abs(g).max(), 1.0)
    assert np.abs(H - H_fd).max() <= 1e-6 * max(np.abs(H).max(), 1.0)
    assert np.array_equal(H, H.T)


@pytest.mark.parametrize("name", ["point_point", "point_line", "point_plane", "line_line"])
def test_sub_distance_derivatives_finite_differences(name):
    nv = {"point_point": 2, "point_line": 3, "point_plane": 4, "line_line": 4}[name]
    f, g, H = (getattr(D, f"{name}_distance_sq{s}") for s in ("", "_gradient", "_hessian"))
    rng = np.random.default_rng(3)
    for _ in range(10):
        X = rng.standard_normal((nv, 3))
        _check_fd(lambda Y: f(*Y), lambda Y: g(*Y), lambda Y: H(*Y), X)


@pytest.mark.parametrize("kind", ["pt", "ee", "pe"])
def test_every_distance_type_finite_differences(kind):
    """The typed stencil functions (sub-distance embedded in the 12/9 DOFs), per type,
    on configurations of that type away from type boundaries."""
    configs, names, ftype, f, g, H = {
        "pt": (pt_configs(800, seed=4)[:100], PT_NAMES, D.point_triangle_distance_type,
               D.point_triangle_distance_sq, D.point_triangle_distance_sq_gradient,
               D.point_triangle_distance_sq_hessian),
        "ee": (ee_configs(800, seed=4), EE_NAMES, D.edge_edge_distance_type,
               D.edge_edge_distance_sq, D.edge_edge_distance_sq_gradient,
               D.edge_edge_distance_sq_hessian),
        "pe": (pe_configs(500, seed=4)[:100], PE_NAMES, D.point_edge_distance_type,
               D.point_edge_distance_sq, D.point_edge_distance_sq_gradient,
               D.point_edge_distance_sq_hessian),
    }[kind]
    seen = np.zeros(len(names), dtype=int)
    rng = np.random.default_rng(6)
    for X in configs:
        if kind == "ee" and seen.min() >= 3:
            break
        t = int(ftype(*X))
        # well-separated configurations only (FD needs d > 0 and a clear type)
        if seen[t] >= 3 or f(*X) < 1e-3:
            continue
        X = X + 1e-3 * rng.standard_normal(X.shape)
        if int(ftype(*X)) != t:
            continue
        seen[t] += 1
        _check_fd(lambda Y: f(*Y, t), lambda Y: g(*Y, t), lambda Y: H(*Y, t), X)
    # point-triangle/point-edge random families reach every type; edge-edge needs the
    # parallel/endpoint families too
    assert seen.min() >= 1, dict(zip(names, seen))


# =========================================================================================
# Brute-force closest points (no ipctk): the AUTO distance is the true minimum
# =========================================================================================

def _seg_dist2(p, a, b):
    # squared distance from points p to segments [a, b] (rows)
    e = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, e) / np.einsum("ij,ij->i", e, e), 0.0, 1.0)
    r = p - a - t[:, None] * e
    return np.einsum("ij,ij->i", r, r)


def brute_point_triangle(X):
    p, t0, t1, t2 = X[:, 0], X[:, 1], X[:, 2], X[:, 3]
    best = np.minimum(np.minimum(_seg_dist2(p, t0, t1), _seg_dist2(p, t1, t2)),
                      _seg_dist2(p, t2, t0))
    e1, e2, r = t1 - t0, t2 - t0, p - t0
    n = np.cross(e1, e2)
    N = np.einsum("ij,ij->i", n, n)
    b1 = np.einsum("ij,ij->i", np.cross(r, e2), n) / N
    b2 = np.einsum("ij,ij->i", np.cross(e1, r), n) / N
    inside = (b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1)
    plane = np.einsum("ij,ij->i", r, n) ** 2 / N
    return np.where(inside, np.minimum(best, plane), best)


def brute_edge_edge(X):
    a0, a1, b0, b1 = X[:, 0], X[:, 1], X[:, 2], X[:, 3]
    best = np.minimum.reduce([_seg_dist2(a0, b0, b1), _seg_dist2(a1, b0, b1),
                              _seg_dist2(b0, a0, a1), _seg_dist2(b1, a0, a1)])
    u, v, w = a1 - a0, b1 - b0, a0 - b0
    n = np.cross(u, v)
    N = np.einsum("ij,ij->i", n, n)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -np.einsum("ij,ij->i", np.cross(w, v), n) / N
        t = -np.einsum("ij,ij->i", np.cross(w, u), n) / N
        line = np.einsum("ij,ij->i", w, n) ** 2 / N
    inside = (N > 1e-20 * np.einsum("ij,ij->i", u, u) * np.einsum("ij,ij->i", v, v)) & (
        s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    return np.where(inside, np.minimum(best, line), best)


def test_auto_distance_is_the_minimum_over_features():
    X = pt_configs(4000, seed=20)
    mine = np.array([D.point_triangle_distance_sq(*x) for x in X])
    ref = brute_point_triangle(X)
    L = np.abs(X).max(axis=(1, 2))
    kappa = np.maximum(1.0, L**2 / np.linalg.norm(
        np.cross(X[:, 2] - X[:, 1], X[:, 3] - X[:, 1]), axis=1))
    delta = C_FLOOR * EPS * kappa * L
    assert np.all(np.abs(mine - ref) <= 1e-10 * ref + delta * (2 * np.sqrt(ref) + delta))

    X = ee_configs(4000, seed=21)
    mine = np.array([D.edge_edge_distance_sq(*x) for x in X])
    ref = brute_edge_edge(X)
    L = np.abs(X).max(axis=(1, 2))
    u, v = X[:, 1] - X[:, 0], X[:, 3] - X[:, 2]
    with np.errstate(divide="ignore"):
        kappa = np.maximum(1.0, L**2 / np.linalg.norm(np.cross(u, v), axis=1))
    kappa = np.minimum(kappa, 1e8)  # exactly parallel: the endpoint rule, κ irrelevant
    delta = C_FLOOR * EPS * kappa * L
    assert np.all(np.abs(mine - ref) <= 1e-10 * ref + delta * (2 * np.sqrt(ref) + delta))
