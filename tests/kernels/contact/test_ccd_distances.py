"""CCD measures with the distance kernels (kernels/contact/distance.py): rounding and edge cases.

ACCD advances by δ = s·d/l_p with s = (1 − f)(1 − 1e-3): a computed distance that is too
large by a relative e ≤ 1e-3 still keeps the gap fraction, and one too large by less than
1/s − 1 ≈ 11 % still keeps the distance positive (module docstring of kernels/contact/ccd.py). These
tests measure the distances against 60-digit references (closest points found in mpmath) and
run CCD on the edge cases: parallel edges, degenerate triangles, touching stencils and
distances tiny next to the coordinates.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest

from ipcsim.kernels.contact import ccd
from ipcsim.kernels.contact import distance as D

EPS = np.finfo(float).eps
GAP = ccd.DEFAULT_MIN_GAP_FRACTION
EMPTY = np.empty((0, 4), np.int64)
ONE = np.array([[0, 1, 2, 3]], np.int64)
mp.mp.dps = 60


# ------------------------------------------------------------------ 60-digit references

def _mpv(a):
    return [mp.mpf(float(v)) for v in a]


def _sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def _dot(a, b):
    return sum(a[i] * b[i] for i in range(3))


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _point_segment(p, a, b):
    ab, ap = _sub(b, a), _sub(p, a)
    den = _dot(ab, ab)
    t = 0 if den == 0 else min(max(_dot(ap, ab) / den, 0), 1)
    r = [ap[i] - t * ab[i] for i in range(3)]
    return mp.sqrt(_dot(r, r))


def ref_pt(q):
    """Distance from q[0] to the closed triangle q[1..3] (its edges when degenerate)."""
    p, a, b, c = (_mpv(r) for r in q)
    d = min(_point_segment(p, a, b), _point_segment(p, b, c), _point_segment(p, c, a))
    n = _cross(_sub(b, a), _sub(c, a))
    nn = _dot(n, n)
    if nn > 0:
        w = [_dot(_cross(_sub(c, b), _sub(p, b)), n), _dot(_cross(_sub(a, c), _sub(p, c)), n),
             _dot(_cross(_sub(b, a), _sub(p, a)), n)]
        if min(w) >= 0:
            d = min(d, abs(_dot(_sub(p, a), n)) / mp.sqrt(nn))
    return d


def ref_ee(q):
    """Distance between the closed segments q[0]q[1] and q[2]q[3]."""
    a0, a1, b0, b1 = (_mpv(r) for r in q)
    d = min(_point_segment(a0, b0, b1), _point_segment(a1, b0, b1),
            _point_segment(b0, a0, a1), _point_segment(b1, a0, a1))
    u, v, w = _sub(a1, a0), _sub(b1, b0), _sub(b0, a0)
    n = _cross(u, v)
    nn = _dot(n, n)
    if nn > 0:
        s = _dot(_cross(w, v), n) / nn
        t = _dot(_cross(w, u), n) / nn
        if 0 <= s <= 1 and 0 <= t <= 1:
            d = min(d, abs(_dot(w, n)) / mp.sqrt(nn))
    return d


def _ccd_distance(q, is_pt):
    q = np.ascontiguousarray(q, dtype=np.float64)
    f = ccd.point_triangle_distance_sq if is_pt else ccd.edge_edge_distance_sq
    return np.sqrt(f(q))


def _c(q, is_pt):
    """|d_ccd − d| in units of ε · (largest coordinate magnitude)."""
    ref = ref_pt(q) if is_pt else ref_ee(q)
    return float(abs(mp.mpf(_ccd_distance(q, is_pt)) - ref) / (EPS * np.abs(q).max()))


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _min_angle_deg(tri):
    ang = []
    for k in range(3):
        u, v = tri[(k + 1) % 3] - tri[k], tri[(k + 2) % 3] - tri[k]
        ang.append(np.degrees(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v),
                                                -1, 1))))
    return min(ang)


# ------------------------------------------------------------------ the same functions

def test_ccd_measures_with_the_distance_kernels():
    rng = np.random.default_rng(0)
    for q in rng.normal(size=(200, 4, 3)):
        assert ccd.point_triangle_distance_sq(q) == D.point_triangle_distance_sq(*q)
        assert ccd.edge_edge_distance_sq(q) == D.edge_edge_distance_sq(*q)


# ------------------------------------------------------------------ rounding

def _pt_near(rng, rel, off):
    # a well-shaped triangle (no angle under 10°) and a point rel·scale above its plane,
    # over the interior, an edge or a vertex
    while True:
        tri = rng.uniform(-1, 1, (3, 2))
        if _min_angle_deg(tri) > 10:
            break
    bary = rng.dirichlet([1, 1, 1])
    where = rng.integers(3)
    if where == 1:
        bary[rng.integers(3)] = 0.0
    elif where == 2:
        bary = np.eye(3)[rng.integers(3)]
    foot = bary @ tri
    o = off * rng.uniform(-1, 1, 3)
    h = rel * (np.abs(o).max() + 1.0) * rng.choice([-1, 1])
    local = np.array([[foot[0], foot[1], h]] + [[t[0], t[1], 0.0] for t in tri])
    return local @ _rotation(rng).T + o


def _ee_near(rng, rel, off):
    # two segments crossing at an angle of at least 3° (seen along the normal), rel·scale apart
    th = rng.uniform(0.05, np.pi - 0.05)
    a = np.array([[-1.0, 0, 0], [1, 0, 0]]) * rng.uniform(0.3, 1) + [rng.uniform(-0.5, 0.5), 0, 0]
    o = off * rng.uniform(-1, 1, 3)
    h = rel * (np.abs(o).max() + 1.0)
    b = np.array([[-np.cos(th), -np.sin(th), h], [np.cos(th), np.sin(th), h]]) * [1, 1, 1]
    b[:, :2] *= rng.uniform(0.3, 1)
    return np.vstack([a, b]) @ _rotation(rng).T + o


@pytest.mark.parametrize("is_pt", [True, False], ids=["PT", "EE"])
def test_rounding_is_a_few_ulps_of_the_coordinate_scale(is_pt):
    """|d_ccd − d| ≤ 4 ε · scale on well-shaped stencils from 1e-12 to 1e-1 of the scale:
    the relative error is at most 4 · 2.2e-4 < 1e-3 at the touching threshold
    (1e-12 · scale) and at most 4 · 2.2e-6 from 1e-10 · scale on: within the 1e-3 margin of
    the ACCD step."""
    rng = np.random.default_rng(1 if is_pt else 2)
    worst = 0.0
    for rel in (1e-12, 1e-11, 1e-10, 1e-8, 1e-6, 1e-3, 1e-1):
        for off in (0.0, 1.0, 10.0, 1000.0):
            for _ in range(25):
                q = _pt_near(rng, rel, off) if is_pt else _ee_near(rng, rel, off)
                worst = max(worst, _c(q, is_pt))
    print(f"\n[ccd distances] {'PT' if is_pt else 'EE'}: largest error {worst:.2f} ε·scale")
    assert worst <= 4.0


@pytest.mark.parametrize("sin_theta", [0.0, 1e-12, 1e-9, 1e-8, 1e-7, 1e-6, 1e-3])
def test_parallel_and_nearly_parallel_edges(sin_theta):
    """Overlapping segments at angle θ: the error stays within the documented bounds
    (a few ulps plus ε·L/sin θ and L·sin θ, L the edge length), and CCD's step towards
    each other is before the impact and keeps a positive gap."""
    rng = np.random.default_rng(3)
    for _ in range(40):
        L = rng.uniform(0.5, 2.0)
        d = 10.0 ** rng.uniform(-6, -2)
        shift = rng.uniform(-0.5, 0.5) * L
        local = np.array([[0, 0, 0], [L, 0, 0], [shift, -0.5 * L * sin_theta, d],
                          [shift + L, 0.5 * L * sin_theta, d]])
        R = _rotation(rng)
        o = rng.uniform(-1, 1, 3)
        q = local @ R.T + o
        ref = ref_ee(q)
        err = abs(_ccd_distance(q, False) - float(ref))
        bound = 12 * EPS * np.abs(q).max()
        if sin_theta > 0:
            bound += min(4 * EPS * L / sin_theta, L * sin_theta)
        assert err <= bound, (d, err, bound)
        # move b straight onto a: exact impact at t = 1/2 (for θ = 0, the contact is a line)
        q1 = q.copy()
        q1[2:] -= 2 * d * R[:, 2]
        steps, _ = ccd.ccd_query_steps(q, q1, EMPTY, ONE)
        assert 0.0 < steps[0] < 0.5
        da = float(ref_ee(q + steps[0] * (q1 - q)))
        # the computed gap is kept: f·d0 up to the error at both ends
        assert da > 0.0 and da >= GAP * float(ref) - 2 * bound


def test_exactly_parallel_collinear_and_disjoint_edges():
    # collinear and apart, collinear and overlapping (touching), parallel side by side
    q = np.array([[0, 0, 0], [1, 0, 0], [1.5, 0, 0], [3, 0, 0]], float)
    assert ccd.edge_edge_distance_sq(q) == 0.25
    q = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0, 0], [3, 0, 0]], float)
    assert ccd.edge_edge_distance_sq(q) == 0.0
    q = np.array([[0, 0, 0], [1, 0, 0], [0.25, 0.5, 0], [0.75, 0.5, 0]], float)
    assert ccd.edge_edge_distance_sq(q) == 0.25
    # approaching side by side: impact at t = 1/2
    q1 = q.copy()
    q1[2:, 1] -= 1.0
    steps, _ = ccd.ccd_query_steps(q, q1, EMPTY, ONE)
    assert 0.8 * 0.5 <= steps[0] < 0.5


# ------------------------------------------------------------------ degenerate triangles

DEGENERATE = {
    "collinear": np.array([[0, 0, 0], [1, 0, 0], [2.5, 0, 0]], float),
    "repeated vertex": np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0]], float),
    "a point": np.array([[0.5, 0.5, 0.5]] * 3, float),
}


@pytest.mark.parametrize("name", list(DEGENERATE))
def test_degenerate_triangles_are_measured_by_their_edges(name):
    tri = DEGENERATE[name]
    rng = np.random.default_rng(4)
    for p in rng.uniform(-1, 3, (200, 3)):
        q = np.vstack([p, tri])
        d = _ccd_distance(q, True)
        assert abs(d - float(ref_pt(q))) <= 8 * EPS * np.abs(q).max()
        t = D.point_triangle_distance_type(*q)
        assert t != D.PT_P_T  # never the (undefined) plane
        g = D.point_triangle_distance_sq_gradient(*q, t)
        assert np.isfinite(g).all()
    # a point approaching the degenerate triangle head-on stops before the impact
    p0 = tri.mean(axis=0) + [0.0, 0.0, 1.0]
    q0 = np.vstack([p0, tri])
    q1 = q0.copy()
    q1[0, 2] -= 2.0  # through the segment at t = 1/2
    steps, _ = ccd.ccd_query_steps(q0, q1, ONE, EMPTY)
    assert 0.8 * 0.5 <= steps[0] < 0.5


def test_nearly_degenerate_triangle_is_close_to_the_degenerate_one():
    tri = DEGENERATE["collinear"].copy()
    p = np.array([1.2, 0.7, -0.3])
    flat = _ccd_distance(np.vstack([p, tri]), True)
    tri[2, 1] = 1e-9
    thin = _ccd_distance(np.vstack([p, tri]), True)
    assert abs(thin - flat) <= 1e-8


# ------------------------------------------------------------------ touching and tiny

def test_touching_stencils_get_no_step():
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    for p in ([0.2, 0.3, 0.0], [0.5, 0.5, 0.0], [0.0, 0.0, 0.0]):  # face, edge, vertex
        q0 = np.vstack([p, tri])
        assert ccd.point_triangle_distance_sq(q0) == 0.0
        q1 = q0 + [0.0, 0.0, 1.0] * np.array([[1], [0], [0], [0]])  # moving away
        steps, _ = ccd.ccd_query_steps(q0, q1, ONE, EMPTY)
        assert steps[0] == 0.0
    q0 = np.array([[0, 0, 0], [1, 0, 0], [0.5, -0.5, 0], [0.5, 0.5, 0]], float)  # crossing
    assert ccd.edge_edge_distance_sq(q0) == 0.0
    steps, _ = ccd.ccd_query_steps(q0, q0 + 0.1, EMPTY, ONE)
    assert steps[0] == 0.0


@pytest.mark.parametrize("offset", [1.0, 1e3, 1e6])
@pytest.mark.parametrize("is_pt", [True, False], ids=["PT", "EE"])
def test_tiny_distances_next_to_large_coordinates(offset, is_pt):
    """Below 1e-12 of the coordinate scale a stencil counts as touching (step 0); just above
    it the step is positive, before the impact, and keeps a positive gap of about f·d0."""
    R = _rotation(np.random.default_rng(5))
    if is_pt:
        local = np.array([[0.3, 0.3, 1.0], [0, 0, 0], [1, 0, 0], [0, 1, 0]])
    else:
        local = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 1.0], [0, 1, 1.0]])
    moving = [0] if is_pt else [2, 3]
    for rel, touching in ((1e-13, True), (5e-12, False), (1e-10, False), (1e-6, False)):
        q = local.copy()
        gap = rel * offset
        q[moving, 2] = gap
        q0 = q @ R.T + offset * np.array([1.0, -0.5, 0.25])
        q1 = q0.copy()
        q1[moving] -= 2 * gap * R[:, 2]  # impact at t ≈ 1/2
        steps, _ = ccd.ccd_query_steps(q0, q1, ONE if is_pt else EMPTY,
                                       EMPTY if is_pt else ONE)
        if touching:
            assert steps[0] == 0.0
            continue
        ref = ref_pt if is_pt else ref_ee
        d0 = float(ref(q0))
        da = float(ref(q0 + steps[0] * (q1 - q0)))
        assert 0.0 < steps[0] < 0.5 + 1e-3 and da > 0.0
        assert da >= (1 - 5e-3) * GAP * d0, (rel, da / d0)
