"""Additive CCD against an exact time-of-impact reference and against ipctk.

For every query (random and adversarial, more than 10,000 in all) the step α must

* come before the exact first impact on the linear trajectory (reference below), or be 0 when
  the primitives touch at the start;
* leave a positive distance, at least min_gap_fraction · d0 (ipctk's distance functions);
* be collision free according to ipctk's ``is_step_collision_free`` (Tight-Inclusion CCD).

Exact reference. Floats are dyadic rationals, so after scaling by a power of two all
coordinates are integers and the trajectory is exact. A PT or EE contact needs the four points
to be coplanar, i.e. a root of the cubic det(v1(t), v2(t), v3(t)) (PT: t1-t0, t2-t0, p-t0; EE:
a1-a0, b0-a0, b1-a0). Its real roots in [0, 1] are isolated exactly (square-free part, Sturm
sequence, bisection helped by float guesses) into brackets of relative width about 2^-50.
A root is an impact when the point lies in the closed triangle (PT) or the closest points of
the two lines lie in both closed segments (EE; parallel edges: collinear and overlapping),
checked in exact arithmetic at both bracket ends; the check errs towards "impact" (a degenerate
triangle at a root, or a constraint that flips inside the bracket, count as impact), which only
makes the test stricter.
When the cubic vanishes identically (always coplanar, e.g. parallel edges) there is no exact
reference; those queries are checked against ipctk and analytic expectations only.
"""

from __future__ import annotations

import time
from fractions import Fraction

import numpy as np
import pytest

from ipcsim.kernels.contact import ccd

GAP = ccd.DEFAULT_MIN_GAP_FRACTION


# ----------------------------------------------------------------------------- exact reference

def _exact(q0, q1):
    """Integer coordinates (4, 3) at t = 0 and integer displacements: q(t) = (P + t D) / den."""
    vals = [Fraction(float(v)) for v in np.concatenate([q0.ravel(), q1.ravel()])]
    den = max(v.denominator for v in vals)  # powers of two: the largest is their lcm
    ints = [int(v * den) for v in vals]
    P = [ints[3 * i:3 * i + 3] for i in range(4)]
    D = [[ints[12 + 3 * i + a] - P[i][a] for a in range(3)] for i in range(4)]
    return P, D


def _sub(a, b):
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _det(a, b, c):
    return _dot(a, _cross(b, c))


_VECTORS = {True: ((2, 1), (3, 1), (0, 1)), False: ((1, 0), (2, 0), (3, 0))}


def _coplanarity_cubic(P, D, is_pt):
    """Coefficients c0..c3 of det(u1 + t v1, u2 + t v2, u3 + t v3)."""
    u = [_sub(P[i], P[j]) for i, j in _VECTORS[is_pt]]
    v = [_sub(D[i], D[j]) for i, j in _VECTORS[is_pt]]
    return [_det(u[0], u[1], u[2]),
            _det(v[0], u[1], u[2]) + _det(u[0], v[1], u[2]) + _det(u[0], u[1], v[2]),
            _det(u[0], v[1], v[2]) + _det(v[0], u[1], v[2]) + _det(v[0], v[1], u[2]),
            _det(v[0], v[1], v[2])]


def _trim(p):
    p = [Fraction(c) for c in p]
    while p and p[-1] == 0:
        p.pop()
    return p


def _ev(p, t):
    r = Fraction(0)
    for c in reversed(p):
        r = r * t + c
    return r


def _deriv(p):
    return [i * p[i] for i in range(1, len(p))]


def _divmod(a, b):
    a = list(a)
    q = [Fraction(0)] * max(1, len(a) - len(b) + 1)
    while len(a) >= len(b) and a:
        k = len(a) - len(b)
        f = a[-1] / b[-1]
        q[k] = f
        for i in range(len(b)):
            a[i + k] -= f * b[i]
        a = _trim(a)
    return _trim(q), a


def _gcd(a, b):
    while b:
        a, b = b, _divmod(a, b)[1]
    return [c / a[-1] for c in a]


def _sign(x):
    return (x > 0) - (x < 0)


def _sturm(p):
    chain = [p, _deriv(p)]
    while len(chain[-1]) > 1:
        r = _divmod(chain[-2], chain[-1])[1]
        if not r:
            break
        chain.append([-c for c in r])
    return chain


def _variations(chain, t):
    s = [_sign(_ev(p, t)) for p in chain]
    s = [x for x in s if x]
    return sum(1 for a, b in zip(s, s[1:]) if a != b)


def _refine(p, a, b, hints):
    """Bracket (lo, hi) of the one simple root of p in (a, b), p(a), p(b) != 0."""
    sa = _sign(_ev(p, a))
    for h in hints:
        if not float(a) <= h <= float(b):
            continue
        r = Fraction(h).limit_denominator(2 ** 20)  # constructed cases: small rational roots
        if a < r < b and _ev(p, r) == 0:
            return r, r
        w = Fraction(abs(h) * 2.0 ** -50 + 2.0 ** -70)
        hf = Fraction(h)
        lo, hi = max(a, hf - w), min(b, hf + w)
        if _ev(p, hf) == 0:
            return hf, hf
        if _sign(_ev(p, lo)) == sa and _sign(_ev(p, hi)) == -sa:
            return lo, hi
    while b - a > Fraction(1, 2 ** 60):
        m = (a + b) / 2
        sm = _sign(_ev(p, m))
        if sm == 0:
            return m, m
        if sm == sa:
            a = m
        else:
            b = m
    return a, b


def _roots(coeffs, T):
    """Brackets (lo, hi) holding every real root in [0, T] of a nonzero polynomial."""
    p = _trim(coeffs)
    out = []
    p = _divmod(p, _gcd(p, _deriv(p)))[0] if len(p) > 2 else p  # square-free part
    for e in (Fraction(0), T):  # roots at the ends, then divide them out
        if len(p) > 1 and _ev(p, e) == 0:
            out.append((e, e))
            p = _divmod(p, [-e, Fraction(1)])[0]
    if len(p) <= 1:
        return sorted(out)
    chain = _sturm(p)
    hints = [float(r.real) for r in np.roots([float(c) for c in reversed(p)])
             if abs(r.imag) <= 1e-6 * max(1.0, abs(r))]
    todo = [(Fraction(0), T)]
    while todo:
        a, b = todo.pop()
        n = _variations(chain, a) - _variations(chain, b)
        if n == 1:
            out.append(_refine(p, a, b, hints))
        elif n > 1:
            for frac in (Fraction(1, 2), Fraction(1, 3), Fraction(2, 5), Fraction(3, 7)):
                m = a + (b - a) * frac
                if _ev(p, m) != 0:
                    break
            todo += [(a, m), (m, b)]
    return sorted(out)


def _constraints(P, D, is_pt, t):
    """Signs of the closed 'touching' constraints at time t = num/den (exact integers)."""
    n_, d_ = t.numerator, t.denominator
    X = [[P[i][a] * d_ + n_ * D[i][a] for a in range(3)] for i in range(4)]
    if is_pt:
        p, t0, t1, t2 = X
        nrm = _cross(_sub(t1, t0), _sub(t2, t0))
        if _dot(nrm, nrm) == 0:
            return None
        tri = (t0, t1, t2)
        return [_dot(_cross(_sub(tri[(k + 1) % 3], tri[k]), _sub(p, tri[k])), nrm)
                for k in range(3)]
    a0, a1, b0, b1 = X
    ea, eb, w = _sub(a1, a0), _sub(b1, b0), _sub(b0, a0)
    nrm = _cross(ea, eb)
    nn = _dot(nrm, nrm)
    if nn == 0:  # parallel: they touch only if collinear and overlapping
        ll = _dot(ea, ea)
        if ll == 0 or _dot(eb, eb) == 0:
            return None
        if any(_cross(w, ea)):
            return [-1]
        s0, s1 = _dot(w, ea), _dot(_sub(b1, a0), ea)  # b's ends on a, times |ea|²
        return [min(max(s0, s1), ll) - max(min(s0, s1), 0)]
    s, u = _dot(_cross(w, eb), nrm), _dot(_cross(w, ea), nrm)
    return [s, nn - s, u, nn - u]


def _linear_cross(P, D, i, j, k, l):
    """Coefficients (c0, c1, c2) of (q_j - q_i) × (q_l - q_k) for q = P + t D, per axis."""
    u, v = _sub(P[j], P[i]), _sub(D[j], D[i])
    u2, v2 = _sub(P[l], P[k]), _sub(D[l], D[k])
    c0, c2 = _cross(u, u2), _cross(v, v2)
    c1 = [x + y for x, y in zip(_cross(u, v2), _cross(v, u2))]
    return [[c0[a], c1[a], c2[a]] for a in range(3)]


def _collinear_times(P, D, T):
    """Always-parallel edges: brackets of the times in [0, T] when the lines coincide (the
    common roots of the three components of (b0 - a0) × (a1 - a0))."""
    comps = [c for c in _linear_cross(P, D, 0, 2, 0, 1) if any(c)]
    if not comps:
        return [(Fraction(0), Fraction(0))]
    g = _trim(comps[0])
    for c in comps[1:]:
        g = _gcd(g, _trim(c))
    return _roots(g, T) if len(g) > 1 else []


def first_impact(q0, q1, is_pt, T=Fraction(1)):
    """('none', None), ('impact', t_lo) with the first impact at or after t_lo, or
    ('degenerate', None) when the four points stay coplanar (other than parallel edges)."""
    P, D = _exact(q0, q1)
    cubic = _coplanarity_cubic(P, D, is_pt)
    if any(cubic):
        brackets = _roots(cubic, T)
    elif not is_pt and not any(any(c) for c in _linear_cross(P, D, 0, 1, 2, 3)):
        brackets = _collinear_times(P, D, T)  # edges parallel at all times
    else:
        return "degenerate", None
    for lo, hi in brackets:
        c_lo = _constraints(P, D, is_pt, lo)
        c_hi = _constraints(P, D, is_pt, hi)
        if c_lo is None or c_hi is None:
            return "impact", lo
        if all(c >= 0 for c in c_lo) or all(c >= 0 for c in c_hi) \
                or all(max(a, b) >= 0 for a, b in zip(c_lo, c_hi)):
            return "impact", lo
    return "none", None


def test_reference_on_known_cases():
    """The reference itself: impacts where they are, none where there is none."""
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    q0 = np.vstack([[0.25, 0.25, 1.0], tri])
    q1 = q0.copy()
    q1[0, 2] = -1.0
    assert first_impact(q0, q1, True) == ("impact", Fraction(1, 2))
    q0[0, :2] = q1[0, :2] = [2.0, 2.0]  # passes beside the triangle
    assert first_impact(q0, q1, True) == ("none", None)
    q0[0, :2] = q1[0, :2] = [0.5, 0.5]  # exactly through the hypotenuse
    assert first_impact(q0, q1, True) == ("impact", Fraction(1, 2))
    q0[0, :2] = q1[0, :2] = [0.5, 0.5 + 2.0 ** -40]  # misses it by 2^-40
    assert first_impact(q0, q1, True) == ("none", None)
    e0 = np.array([[-1.0, 0, 1], [1, 0, 1], [0, -1, 0], [0, 1, 0]])
    e1 = e0.copy()
    e1[:2, 2] = -3.0
    assert first_impact(e0, e1, False) == ("impact", Fraction(1, 4))
    assert first_impact(e0, e1, False, Fraction(1, 5)) == ("none", None)
    # parallel edges (always coplanar): they meet only when collinear and overlapping
    par = np.array([[0.0, 0, 1], [1, 0, 1], [0.5, 1, 0], [3, 1, 0]])
    down = [[0, 0, -2], [0, 0, -2], [0, 0, 0], [0, 0, 0]]
    assert first_impact(par, par + down, False) == ("none", None)
    par1 = par + [[0, 2, -2], [0, 2, -2], [0, 0, 0], [0, 0, 0]]  # collinear at t = 1/2
    assert first_impact(par, par1, False) == ("impact", Fraction(1, 2))
    par1 = par + [[-3, 2, -2], [-3, 2, -2], [0, 0, 0], [0, 0, 0]]  # ... but apart by then
    assert first_impact(par, par1, False) == ("none", None)
    # edges that turn parallel (and coplanar) at t = 1/3 without touching
    e0 = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 1], [1, 1, 1]])
    e1 = e0 + [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 3, 0]]
    e0[3, 1] -= 1.0
    assert first_impact(e0, e1, False) == ("none", None)
    # a point in the plane of its triangle all along: no reference
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    flat = np.vstack([[2.0, 2, 0], tri])
    slide = flat - [[3, 3, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]]
    assert first_impact(flat, slide, True)[0] == "degenerate"


# ----------------------------------------------------------------------------- query sets

def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _rigid(rng, q0, q1, scale=1.0):
    R = _rotation(rng)
    c = rng.uniform(-1, 1, 3) * scale
    return q0 @ R.T + c, q1 @ R.T + c


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _uniform(rng, n):
    q0 = rng.uniform(0, 1, (n, 4, 3))
    q1 = q0 + 10.0 ** rng.uniform(-2, 0.5, (n, 1, 1)) * rng.normal(size=(n, 4, 3))
    return q0, q1


def _approach_pt(rng, n):
    """A point a height h (1e-7..1e-1) above a random triangle, moving through its plane."""
    tri = rng.uniform(0, 1, (n, 3, 3))
    nrm = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    bary = rng.dirichlet([1, 1, 1], n) * 1.4 - 0.1  # some land just outside
    h = 10.0 ** rng.uniform(-7, -1, (n, 1))
    p = np.einsum("ni,nia->na", bary, tri) + h * nrm
    tangential = 10.0 ** rng.uniform(-4, 0, (n, 1)) * h * rng.normal(size=(n, 3))
    dp = -h * rng.uniform(0.5, 3, (n, 1)) * nrm + tangential
    q0 = np.concatenate([p[:, None], tri], 1)
    q1 = q0 + np.concatenate([dp[:, None], 0.1 * h[:, None] * rng.normal(size=(n, 3, 3))], 1)
    return q0, q1


def _approach_ee(rng, n):
    """Two random edges, one a height h over the other's line, moving across it."""
    a0, a1 = rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, (n, 3))
    d = _unit(rng.normal(size=(n, 3)))
    s = rng.uniform(-0.1, 1.1, (n, 1))
    nrm = _unit(np.cross(a1 - a0, d))
    h = 10.0 ** rng.uniform(-7, -1, (n, 1))
    mid = a0 + s * (a1 - a0) + h * nrm
    half = rng.uniform(0.05, 0.5, (n, 1))
    b0, b1 = mid - half * d, mid + half * d
    q0 = np.stack([a0, a1, b0, b1], 1)
    tangential = 10.0 ** rng.uniform(-4, 0, (n, 1)) * h * _unit(rng.normal(size=(n, 3)))
    move = -h * rng.uniform(0.5, 3, (n, 1)) * nrm + tangential
    noise = 0.05 * h[:, None] * rng.normal(size=(n, 4, 3))
    q1 = q0 + np.stack([0 * a0, 0 * a1, move, move], 1) + noise
    return q0, q1


def _face_on(rng, n_scenes):
    """Two parallel triangles, the top one a height h above, approaching face-on by 2h.
    Returns PT queries (both ways) and the 9 EE queries of every scene, plus t* = 1/2."""
    pt0, pt1, ee0, ee1 = [], [], [], []
    for k in range(n_scenes):
        h = 10.0 ** rng.uniform(-5, -1)
        bot = np.c_[rng.uniform(0, 1, (3, 2)), np.zeros(3)]
        top = bot.copy()
        if k % 3:
            top[:, :2] += rng.uniform(-0.2, 0.2, (3, 2))
        top[:, 2] = h
        slide = np.r_[rng.uniform(-1, 1, 2) * h * (k % 2), 0.0]
        top1 = top + [0.0, 0.0, -2 * h] + slide
        if k % 4 == 1:  # not exactly parallel: a tilt of 1e-3 h
            top1[:, 2] += 1e-3 * h * rng.uniform(-1, 1, 3)
        X0, X1 = np.vstack([bot, top]), np.vstack([bot, top1])
        if k % 2:
            X0, X1 = _rigid(rng, X0, X1)
        for p, t in [(p, (0, 1, 2)) for p in (3, 4, 5)] + [(p, (3, 4, 5)) for p in (0, 1, 2)]:
            pt0.append(X0[[p, *t]])
            pt1.append(X1[[p, *t]])
        for ea in ((0, 1), (1, 2), (2, 0)):
            for eb in ((3, 4), (4, 5), (5, 3)):
                ee0.append(X0[[*ea, *eb]])
                ee1.append(X1[[*ea, *eb]])
    return np.array(pt0), np.array(pt1), np.array(ee0), np.array(ee1)


def _grazing_ee(rng, n):
    """Edge a sweeps down over edge b's end: touching it exactly (endpoint on endpoint,
    endpoint on edge, edge over endpoint) or missing it by 2^-k."""
    q0, q1 = [], []
    for k in range(n):
        h = 2.0 ** -rng.integers(1, 20)
        miss = 0.0 if k % 2 == 0 else 2.0 ** -rng.integers(10, 45)
        case = k % 6
        b = np.array([[-1.0, 0, 0], [0.0, 0, 0]])
        if case < 2:  # a ends on b's end
            a = np.array([[miss, 0, h], [miss, 1.0, h]])
        elif case < 4:  # a's end lands on the inside of b
            a = np.array([[-0.5, miss, h], [-0.5, 1.0, h]])
        else:  # a crosses just past b's end
            a = np.array([[miss, -1.0, h], [miss, 1.0, h]])
        X0 = np.vstack([a, b])
        X1 = X0 + np.array([[0, 0, -2 * h]] * 2 + [[0, 0, 0]] * 2)
        if k % 5 == 4:
            X0, X1 = _rigid(rng, X0, X1)
        q0.append(X0)
        q1.append(X1)
    return np.array(q0), np.array(q1)


def _vertex_through_edge(rng, n):
    """A point moving straight down through a triangle's edge or vertex (touches it)."""
    q0, q1 = [], []
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    for k in range(n):
        h = 2.0 ** -rng.integers(0, 25)
        target = [np.array([0.5, 0.0]), np.array([0.5, 0.5]), np.array([0.0, 0.25]),
                  np.array([0.0, 0.0]), np.array([1.0, 0.0])][k % 5]
        p0 = np.r_[target, h]
        X0 = np.vstack([p0, tri])
        X1 = X0.copy()
        X1[0, 2] = -h
        if k % 7 == 6:
            X0, X1 = _rigid(rng, X0, X1)
        q0.append(X0)
        q1.append(X1)
    return np.array(q0), np.array(q1)


def _zero_and_common_motion(rng, n):
    q0 = rng.uniform(0, 1, (n, 4, 3))
    q1 = q0.copy()
    q1[n // 2:] += rng.normal(size=(n - n // 2, 1, 3))  # the same translation for all four
    return q0, q1


def _huge_motion(rng, n):
    q0, q1 = _approach_pt(rng, n)
    q1 = q0 + (q1 - q0) * 1e6
    e0, e1 = _uniform(rng, n)
    e1 = e0 + (e1 - e0) * 1e6
    return q0, q1, e0, e1


def _touching(rng, n):
    """Touching at t = 0: a point on an axis-aligned triangle, edges crossing in z = 0."""
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    pts = np.c_[rng.integers(0, 8, (n, 2)) / 16.0, np.zeros(n)]
    q0 = np.concatenate([pts[:, None], np.broadcast_to(tri, (n, 3, 3))], 1)
    q1 = q0 + rng.normal(size=q0.shape)
    e0 = np.array([[[-1.0, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0]]] * n)
    e0[:, 2:, 0] = rng.integers(-4, 5, (n, 1)) / 8.0
    e1 = e0 + rng.normal(size=e0.shape)
    return q0, q1, e0, e1


def _parallel_sliding(rng, n):
    """Parallel edges a height h apart, sliding along each other by up to 100 h; every
    other one also approaches by 2h (impact at t = 1/2)."""
    q0, q1, toi = [], [], []
    for k in range(n):
        h = 10.0 ** rng.uniform(-6, -1)
        L = h * 10.0 ** rng.uniform(0, 2)
        a = np.array([[-L, 0, h], [1, 0, h]])  # covers b's span all along
        b = np.array([[0.2, 0, 0], [0.9, 0, 0]])
        X0 = np.vstack([a, b])
        shift = np.array([L, 0.0, -2 * h if k % 2 else 0.0])
        X1 = X0 + np.vstack([shift, shift, [0, 0, 0], [0, 0, 0]])
        toi.append(0.5 if k % 2 else np.inf)
        q0.append(X0)
        q1.append(X1)
    return np.array(q0), np.array(q1), np.array(toi)


def _build_queries():
    rng = np.random.default_rng(20240607)
    fam = []  # (name, is_pt, q0 (n,4,3), q1, analytic toi or None)

    def add(name, is_pt, q0, q1, toi=None):
        fam.append((name, is_pt, np.asarray(q0, float), np.asarray(q1, float), toi))

    add("uniform", True, *_uniform(rng, 2500))
    add("uniform", False, *_uniform(rng, 2500))
    add("approach", True, *_approach_pt(rng, 2000))
    add("approach", False, *_approach_ee(rng, 2000))
    p0, p1, e0, e1 = _face_on(rng, 150)
    add("face_on", True, p0, p1)
    add("face_on", False, e0, e1)
    add("grazing_edges", False, *_grazing_ee(rng, 240))
    add("vertex_through_edge", True, *_vertex_through_edge(rng, 200))
    z0, z1 = _zero_and_common_motion(rng, 200)
    add("zero_or_common_motion", True, z0, z1, np.full(200, np.inf))
    z0, z1 = _zero_and_common_motion(rng, 200)
    add("zero_or_common_motion", False, z0, z1, np.full(200, np.inf))
    p0, p1, e0, e1 = _huge_motion(rng, 150)
    add("huge_motion", True, p0, p1)
    add("huge_motion", False, e0, e1)
    p0, p1, e0, e1 = _touching(rng, 100)
    add("touching_start", True, p0, p1, np.zeros(100))
    add("touching_start", False, e0, e1, np.zeros(100))
    s0, s1, toi = _parallel_sliding(rng, 200)
    add("parallel_sliding", False, s0, s1, toi)
    return fam


@pytest.fixture(scope="module")
def queries():
    fam = _build_queries()
    results = []
    for name, is_pt, q0, q1, toi in fam:
        n = len(q0)
        x0, x1 = q0.reshape(-1, 3), q1.reshape(-1, 3)
        stencils = np.arange(4 * n).reshape(n, 4)
        empty = np.empty((0, 4), np.int64)
        steps, iters = ccd.ccd_query_steps(x0, x1, stencils if is_pt else empty,
                                           empty if is_pt else stencils)
        ref = [first_impact(q0[k], q1[k], is_pt) for k in range(n)]
        results.append((name, is_pt, q0, q1, toi, steps, iters, ref))
    return results


def _label(name, is_pt, k):
    return f"{name} {'PT' if is_pt else 'EE'} #{k}"


def _dist_sq_ipctk(ipctk, q, is_pt):
    if is_pt:
        return ipctk.point_triangle_distance(q[0], q[1], q[2], q[3])
    return ipctk.edge_edge_distance(q[0], q[1], q[2], q[3])


def _own_dist(q, is_pt):
    q = np.ascontiguousarray(q, float)
    f = ccd.point_triangle_distance_sq if is_pt else ccd.edge_edge_distance_sq
    return np.sqrt(f(q))


# ----------------------------------------------------------------------------- tests

def test_query_count(queries):
    assert sum(len(r[2]) for r in queries) >= 10_000


def test_step_never_reaches_exact_impact(queries):
    """α < the exact first impact (or α = 0 when touching at the start), for every query
    whose coplanarity cubic is not identically zero."""
    n_checked = n_impacts = 0
    ratios = []
    for name, is_pt, q0, q1, toi, steps, _, ref in queries:
        for k in range(len(q0)):
            a = steps[k]
            assert 0.0 <= a <= 1.0
            status, t_imp = ref[k]
            if status == "degenerate":
                continue
            n_checked += 1
            if status == "impact":
                n_impacts += 1
                if t_imp == 0:
                    assert a == 0.0, _label(name, is_pt, k)
                else:
                    assert Fraction(a) < t_imp, (_label(name, is_pt, k), a, float(t_imp))
                    ratios.append(a / float(t_imp))
    print(f"\n[ccd] exact reference: {n_checked} queries, {n_impacts} with an impact in [0, 1]; "
          f"alpha / TOI: min {min(ratios):.3f}, 5th percentile {np.percentile(ratios, 5):.3f}, "
          f"median {np.median(ratios):.3f}")
    assert n_checked > 9000 and n_impacts > 3000


def test_analytic_expectations(queries):
    for name, is_pt, q0, q1, toi, steps, _, _ in queries:
        if toi is None:
            continue
        for k in range(len(q0)):
            if toi[k] == 0:
                assert steps[k] == 0.0, _label(name, is_pt, k)
            elif np.isinf(toi[k]):
                assert steps[k] == 1.0, (_label(name, is_pt, k), steps[k])
            else:  # a clean approach: before the impact, and not overly cautious
                assert 0.8 * toi[k] <= steps[k] < toi[k], (_label(name, is_pt, k), steps[k])


def test_head_on_and_face_on_are_cheap_and_close(queries):
    """Face-on and through-edge approaches: few iterations, α close to the impact."""
    for name, is_pt, q0, q1, toi, steps, iters, _ in queries:
        if name == "face_on":
            assert iters.max() <= 12, iters.max()
            assert steps.min() >= 0.8 * 0.5  # the faces meet at t = 1/2
            assert steps.min() < 0.5
        if name == "vertex_through_edge":
            assert iters.max() <= 3
            assert np.all(steps >= 0.8 * 0.5) and np.all(steps < 0.5)


def test_positive_gap_at_step(queries):
    """At α the distance (ipctk's functions) is at least ~min_gap_fraction · d0 > 0."""
    ipctk = pytest.importorskip("ipctk")
    for name, is_pt, q0, q1, toi, steps, _, _ in queries:
        for k in range(len(q0)):
            d0 = _own_dist(q0[k], is_pt)
            if steps[k] == 0.0:
                assert d0 <= 1e-12 * np.abs(np.r_[q0[k].ravel(), q1[k].ravel()]).max()
                continue
            qa = q0[k] + steps[k] * (q1[k] - q0[k])
            d = np.sqrt(_dist_sq_ipctk(ipctk, qa, is_pt))
            assert d > 0.0 and d >= 0.99 * GAP * d0, (_label(name, is_pt, k), d, d0)


def test_ipctk_agrees_step_is_collision_free(queries):
    """ipctk's Tight-Inclusion CCD finds no collision on [0, α].

    ipctk reports a collision once the gap falls under min(0.2·d0, 1e-4) (an absolute 1e-4;
    see the ipctk conventions, section 4), a stricter rule than the 0.1·d0 kept here. Each
    query is therefore scaled by a power of two (exact in floating point) to d0 in [1, 2), so
    ipctk's threshold is 1e-4 of the initial gap and its answer is about actual contact.
    The huge-motion family is left to the exact reference: on it Tight-Inclusion takes up to a
    minute per query or runs out of memory (its heavy tail)."""
    ipctk = pytest.importorskip("ipctk")
    f = np.asfortranarray
    tri_edges = f(np.array([[1, 2], [2, 3], [3, 1]], np.int32))
    tri_face = f(np.array([[1, 2, 3]], np.int32))
    ee_edges = f(np.array([[0, 1], [2, 3]], np.int32))
    no_face = f(np.empty((0, 3), np.int32))
    worst, n = 0.0, 0
    for name, is_pt, q0, q1, toi, steps, _, _ in queries:
        if name == "huge_motion":
            continue
        for k in range(len(q0)):
            if steps[k] == 0.0:
                continue
            qa = q0[k] + steps[k] * (q1[k] - q0[k])
            scale = 2.0 ** -np.floor(np.log2(_own_dist(q0[k], is_pt)))
            mesh = ipctk.CollisionMesh(f(scale * q0[k]), tri_edges if is_pt else ee_edges,
                                       tri_face if is_pt else no_face)
            t0 = time.perf_counter()
            free = ipctk.is_step_collision_free(mesh, f(scale * q0[k]), f(scale * qa))
            worst = max(worst, time.perf_counter() - t0)
            assert free, (_label(name, is_pt, k), steps[k])
            n += 1
    print(f"\n[ccd] ipctk is_step_collision_free: {n} steps free; "
          f"slowest ipctk call {1e3 * worst:.2f} ms")


def test_max_step_over_batches(queries):
    """ccd_max_step (rounds with pruning) is at least the smallest per-query step and is safe
    for every query of the batch: before its exact impact, with the gap kept."""
    rng = np.random.default_rng(1)
    for name, is_pt, q0, q1, toi, steps, _, ref in queries:
        n = len(q0)
        x0, x1 = q0.reshape(-1, 3), q1.reshape(-1, 3)
        st = np.arange(4 * n).reshape(n, 4)
        empty = np.empty((0, 4), np.int64)
        for sub in (np.arange(n), rng.choice(n, min(n, 7), replace=False)):
            pt, ee = (st[sub], empty) if is_pt else (empty, st[sub])
            a = ccd.ccd_max_step(x0, x1, pt, ee)
            assert steps[sub].min() <= a <= 1.0, name
            for k in sub:
                status, t_imp = ref[k]
                if status == "impact":
                    assert Fraction(a) < t_imp or a == t_imp == 0, _label(name, is_pt, k)
                d0 = _own_dist(q0[k], is_pt)
                if a > 0:
                    d = _own_dist(q0[k] + a * (q1[k] - q0[k]), is_pt)
                    assert d >= GAP * d0, _label(name, is_pt, k)


def test_the_serial_and_the_parallel_variant_give_the_same_step(queries):
    """``max_step``'s rounds run their queries in a loop (the serial variant, and few
    queries) or in parallel chunks (many queries on more than one thread): the same α bit
    for bit, on whole families, random subsets, batches of PT and EE queries, and with
    small iteration caps."""
    from ipcsim.compiler import threads

    rng = np.random.default_rng(7)
    compared = 0
    for name, is_pt, q0, q1, *_ in queries[:6]:
        n = len(q0)
        x0 = np.ascontiguousarray(q0.reshape(-1, 3))
        x1 = np.ascontiguousarray(q1.reshape(-1, 3))
        st = np.arange(4 * n, dtype=np.int64).reshape(n, 4)
        many = np.resize(np.arange(n), max(n, 600))  # past the serial threshold
        for sub in (many, np.sort(rng.choice(n, min(n, 9), replace=False))):
            # EE families: their first n_pt stencils read as point-triangle queries too
            n_pt = len(sub) if is_pt else int(rng.integers(0, len(sub) + 1))
            stencils = np.ascontiguousarray(st[sub])
            for cap in (ccd.DEFAULT_MAX_ITERATIONS, 3, 40):
                results = []
                for parallel in (False, True):
                    threads.run_parallel(parallel)
                    try:
                        results.append(ccd.max_step(x0, x1, stencils, n_pt, 0.1, cap))
                    finally:
                        threads.run_parallel(False)
                assert results[0] == results[1], (name, cap)
                compared += 1
    assert compared > 20


def test_single_query_times(queries):
    """Largest single-query wall time (printed; never asserted). Every query is timed once
    through the Python entry point (call overhead included); the 20 slowest and the 20 with
    the most iterations are timed again and keep their best of 5, so a hiccup of the machine
    does not pass for a slow query."""
    st = np.array([[0, 1, 2, 3]])
    empty = np.empty((0, 4), np.int64)

    def call(is_pt, a, b):
        t0 = time.perf_counter()
        ccd.ccd_query_steps(a, b, st if is_pt else empty, empty if is_pt else st)
        return time.perf_counter() - t0

    timed = []
    for name, is_pt, q0, q1, toi, steps, iters, _ in queries:
        for k in range(len(q0)):
            timed.append((call(is_pt, q0[k], q1[k]), name, is_pt, k, int(iters[k]), q0[k], q1[k]))
    slowest = sorted(timed, key=lambda r: r[0], reverse=True)[:20]
    slowest += sorted(timed, key=lambda r: r[4], reverse=True)[:20]  # most iterations
    again = [(min(call(r[2], r[5], r[6]) for _ in range(5)),) + r[1:5] for r in slowest]
    worst = max(again, key=lambda r: r[0])
    it_max = max(int(r[6].max()) for r in queries)
    # the tail the iteration cap cuts: sliding a million gaps over a triangle
    x0, x1 = _sliding_query()
    capped = min(call(True, x0, x1) for _ in range(5))
    median = np.median([r[0] for r in timed])
    print(f"\n[ccd] single-query call time: median {1e6 * median:.1f} us, "
          f"max {1e6 * worst[0]:.1f} us ({_label(*worst[1:4])}, {worst[4]} iterations); "
          f"most iterations of any query: {it_max}; a query cut at the cap of "
          f"{ccd.DEFAULT_MAX_ITERATIONS} iterations: {1e6 * capped:.0f} us")


def _sliding_query():
    tri = np.array([[-10.0, -10, 0], [10, -10, 0], [0, 10, 0]])
    x0 = np.vstack([[-1.0, 0.0, 1e-6], tri])
    x1 = x0.copy()
    x1[0, 0] += 1.0
    return x0, x1


def test_sliding_tail_is_cut_and_stays_safe():
    """A point sliding 1e6 gaps over a triangle: the iteration cap ends the query early with
    a safe (smaller) step instead of running a million iterations."""
    x0, x1 = _sliding_query()
    pt = np.array([[0, 1, 2, 3]])
    empty = np.empty((0, 4), np.int64)
    steps, iters = ccd.ccd_query_steps(x0, x1, pt, empty, max_iterations=1000)
    assert iters[0] == 1000 and 0.0 < steps[0] < 1.0
    assert first_impact(x0, x1, True) == ("none", None)
    full, _ = ccd.ccd_query_steps(x0, x1, pt, empty, max_iterations=2_000_000)
    assert full[0] == 1.0  # given enough iterations it reaches the end: no impact
    assert ccd.ccd_max_step(x0, x1, pt, empty, max_iterations=1000) == steps[0]


def test_distance_helpers_match_ipctk():
    """The CCD's own distances agree with ipctk's, and never exceed them (rounding aside)."""
    ipctk = pytest.importorskip("ipctk")
    rng = np.random.default_rng(5)
    qs = rng.uniform(0, 1, (3000, 4, 3))
    qs[:300, 3] = qs[:300, 1] + 1e-9 * rng.normal(size=(300, 3))  # nearly degenerate
    qs[300:600, 3] = qs[300:600, 2] + (qs[300:600, 1] - qs[300:600, 0])  # parallel edges
    for is_pt in (True, False):
        for q in qs:
            ref = _dist_sq_ipctk(ipctk, q, is_pt)
            own = _own_dist(q, is_pt) ** 2
            assert own <= ref * (1 + 1e-9) + 1e-24
            assert own >= ref * (1 - 1e-6) - 1e-18


def test_rejects_bad_arguments():
    x = np.zeros((4, 3))
    st = np.array([[0, 1, 2, 3]])
    with pytest.raises(ValueError):
        ccd.ccd_max_step(x, x, st, st, min_gap_fraction=1.0)
    with pytest.raises(ValueError):
        ccd.ccd_max_step(x, np.zeros((3, 3)), st, st)
    assert ccd.ccd_max_step(x, x, np.empty((0, 4), np.int64), np.empty((0, 4), np.int64)) == 1.0


# ----------------------------------------------------------------------------- mesh-level step

def _box_mesh(n):
    """Unit-cube surface, n x n quads per side: (vertices, triangles, edges)."""
    s = np.linspace(0.0, 1.0, n + 1)
    u, v = (a.ravel() for a in np.meshgrid(s, s, indexing="ij"))
    ids = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quad = np.stack([ids[:-1, :-1], ids[1:, :-1], ids[1:, 1:], ids[:-1, 1:]], -1).reshape(-1, 4)
    pts, tris = [], []
    for ax in range(3):
        o = [a for a in range(3) if a != ax]
        for side in (0.0, 1.0):
            p = np.empty((len(u), 3))
            p[:, ax], p[:, o[0]], p[:, o[1]] = side, u, v
            tris.append(len(pts) * len(u) + np.concatenate([quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]]))
            pts.append(p)
    pts = np.concatenate(pts)
    _, first, inv = np.unique(np.round(pts * n).astype(np.int64), axis=0, return_index=True,
                              return_inverse=True)
    tris = inv.reshape(-1)[np.concatenate(tris)]
    edges = np.unique(np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]),
                              axis=1), axis=0)
    return pts[first], tris, edges


def _two_box_step(n=4, seed=0):
    x, tris, edges = _box_mesh(n)
    th = np.deg2rad(10.0)
    rot = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    gap = 1e-3
    top = (x - 0.5) @ rot.T + 0.5 + np.array([0.1, 0.07, 1.0 + gap])
    X0 = np.vstack([x, top])
    T = np.vstack([tris, tris + len(x)])
    E = np.vstack([edges, edges + len(x)])
    body = np.repeat([0, 1], len(x))
    rng = np.random.default_rng(seed)
    X1 = X0.copy()
    X1[body == 1, 2] -= 3 * gap
    X1 += rng.uniform(-0.1 * gap, 0.1 * gap, X1.shape)
    return X0, X1, T, E, body


def test_collision_free_step_on_two_boxes():
    from ipcsim.contact.ccd import collision_free_step as on_mesh
    from ipcsim.contact.collision_mesh import CollisionMesh

    def collision_free_step(X0, X1, sv, E, T, body_of_vertex=None, self_collision=True,
                            kinematic_vertex_mask=None):
        mesh = CollisionMesh.of(len(X0), sv, E, T, body_of_vertex, kinematic_vertex_mask,
                                self_collision)
        return on_mesh(mesh, X0, X1)

    X0, X1, T, E, body = _two_box_step()
    sv = np.arange(len(X0))
    alpha = collision_free_step(X0, X1, sv, E, T, body_of_vertex=body)
    # the top moves 3·gap (± 0.1·gap noise per vertex): faces meet by t = 1 / 2.8 at the latest
    assert 0.25 < alpha < 1.0 / 2.8
    # without self-collision the same cross-body pairs decide the step
    assert collision_free_step(X0, X1, sv, E, T, body_of_vertex=body,
                               self_collision=False) == alpha
    # both boxes kinematic: no pair is left, the full step is free
    kin = np.ones(len(X0), bool)
    assert collision_free_step(X0, X1, sv, E, T, body_of_vertex=body,
                               kinematic_vertex_mask=kin) == 1.0
    # a step that moves nothing closer is taken whole
    assert collision_free_step(X0, X0 + [0.0, 0.0, 1e-2], sv, E, T) == 1.0

    ipctk = pytest.importorskip("ipctk")
    f = np.asfortranarray
    scale = 2.0 ** 10  # gap -> about 1 (exact), so ipctk's absolute 1e-4 rule is 1e-4 of it
    mesh = ipctk.CollisionMesh(f(scale * X0), f(E.astype(np.int32)), f(T.astype(np.int32)))
    Xa = X0 + alpha * (X1 - X0)
    assert ipctk.is_step_collision_free(mesh, f(scale * X0), f(scale * Xa))
    a_accd = ipctk.compute_collision_free_stepsize(mesh, f(scale * X0), f(scale * X1), 0.0,
                                                   ipctk.LBVH(), ipctk.AdditiveCCD())
    print(f"\n[ccd] two boxes: alpha {alpha:.4f}, ipctk AdditiveCCD {a_accd:.4f}")
    assert 0.95 * a_accd <= alpha  # same rule, tighter bound: no more cautious than ipctk's


def test_parallel_coplanar_edges_of_a_falling_face_do_not_block_the_step():
    """Two parallel diagonals of one flat face, moved together by a free-fall step, with
    round-off in their coordinates: their distance is 0.2/√2, never zero, so the step is free."""
    from ipcsim.kernels.contact import ccd as kccd

    y = 0.82838363
    x0 = np.array([[0.2, y, 0.6], [0.4, y, 0.8], [0.4, y, 0.6], [0.6, y, 0.8]])
    d = np.array([5.55111512e-17, -4.903325e-02, 0.0])
    x1 = x0 + d
    x1[3, 0] += 5.55e-17
    ee = np.array([[0, 1, 2, 3]], dtype=np.int64)
    pt = np.zeros((0, 4), dtype=np.int64)
    assert kccd.edge_edge_distance_sq(x0) == pytest.approx(0.02, rel=1e-12)
    assert kccd.ccd_max_step(x0, x1, pt, ee) == 1.0
