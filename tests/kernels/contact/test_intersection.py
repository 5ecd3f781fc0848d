"""Exact intersection checker: orientation predicates against Fraction arithmetic, the
segment-triangle predicate against an independent rational reference and hand cases,
mesh-level checks on tetrahedralised boxes, the broad phase against brute force, and
ipctk's has_intersections as an oracle."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ipcsim.contact.intersection import (
    FrameCheck,
    check_frame,
    count_inverted_tets,
    edges_of_triangles,
    find_intersections,
    inverted_tets,
)
from ipcsim.kernels.contact import intersection as K

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# ------------------------------------------------------------------ exact references


def _F(v):
    return [Fraction(float(c)) for c in v]


def _sub(a, b):
    return [x - y for x, y in zip(a, b)]


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _sgn(f):
    return (f > 0) - (f < 0)


def ref_orient3d(a, b, c, d):
    a, b, c, d = _F(a), _F(b), _F(c), _F(d)
    return _sgn(_dot(_cross(_sub(b, a), _sub(c, a)), _sub(d, a)))


def ref_orient2d(a, b, c, k):
    i, j = (k + 1) % 3, (k + 2) % 3
    a, b, c = _F(a), _F(b), _F(c)
    return _sgn((b[i] - a[i]) * (c[j] - a[j]) - (b[j] - a[j]) * (c[i] - a[i]))


def _bary(r, e1, e2):
    # r = u e1 + v e2 for r in the plane of e1, e2 (Gram system, exact)
    g11, g12, g22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
    r1, r2 = _dot(e1, r), _dot(e2, r)
    det = g11 * g22 - g12 * g12
    return (r1 * g22 - r2 * g12) / det, (g11 * r2 - g12 * r1) / det


def ref_segment_triangle(p, q, a, b, c):
    """Closed segment vs closed nondegenerate triangle, by exact rational solving (plane
    crossing point and barycentrics; Liang-Barsky clipping in barycentrics when coplanar).
    Shares no code path with the predicate under test."""
    P, Q, A, B, C = _F(p), _F(q), _F(a), _F(b), _F(c)
    e1, e2 = _sub(B, A), _sub(C, A)
    n = _cross(e1, e2)
    assert any(n), "reference needs a nondegenerate triangle"
    dp, dq = _dot(n, _sub(P, A)), _dot(n, _sub(Q, A))
    if dp * dq > 0:
        return False
    if dp != 0 or dq != 0:
        t = dp / (dp - dq)
        X = [pi + t * (qi - pi) for pi, qi in zip(P, Q)]
        u, v = _bary(_sub(X, A), e1, e2)
        return u >= 0 and v >= 0 and u + v <= 1
    up, vp = _bary(_sub(P, A), e1, e2)
    uq, vq = _bary(_sub(Q, A), e1, e2)
    lo, hi = Fraction(0), Fraction(1)
    for f0, f1 in ((up, uq), (vp, vq), (1 - up - vp, 1 - uq - vq)):
        slope = f1 - f0  # constraint f0 + t * slope >= 0
        if slope == 0:
            if f0 < 0:
                return False
        elif slope > 0:
            lo = max(lo, -f0 / slope)
        else:
            hi = min(hi, -f0 / slope)
    return lo <= hi


def _arr(*v):
    return np.array(v, dtype=np.float64)


def _nudge(v, k):
    # move a float k ulps (k may be negative)
    for _ in range(abs(k)):
        v = np.nextafter(v, np.inf if k > 0 else -np.inf)
    return v


# ------------------------------------------------------------------ orient3d / orient2d


def _check_orient3d_all_tiers(a, b, c, d):
    want = ref_orient3d(a, b, c, d)
    assert K.orient3d(a, b, c, d) == want
    assert K.orient3d_exact(a, b, c, d) == want
    vals = np.concatenate([a, b, c, d])
    assert K.bigint_sign(vals, K.ORIENT3D_TERMS, K.ORIENT3D_SIGNS) == want
    if all(v == 0 or 2.0**-250 <= abs(v) <= 2.0**250 for v in vals):
        assert K.expansion_sign(vals, K.ORIENT3D_TERMS, K.ORIENT3D_SIGNS) == want
    return want


def test_orient3d_convention_matches_positive_tet():
    a, b, c, d = _arr(0, 0, 0), _arr(1, 0, 0), _arr(0, 1, 0), _arr(0, 0, 1)
    assert K.orient3d(a, b, c, d) == 1  # det[b-a, c-a, d-a] = 1
    assert K.orient3d(a, c, b, d) == -1
    assert K.orient3d(a, b, c, _arr(0.3, 0.2, 0)) == 0


@SETTINGS
@given(
    st.lists(
        st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False),
        min_size=12,
        max_size=12,
    )
)
def test_orient3d_random_matches_fraction(coords):
    v = np.array(coords).reshape(4, 3)
    _check_orient3d_all_tiers(*v)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(-4, 4), st.integers(0, 2))
def test_orient3d_near_coplanar_matches_fraction(seed, ulps, axis):
    # d is a float rounding of a point of plane abc, then moved a few ulps off it: the float
    # determinant is pure rounding noise here, so the exact tiers decide
    rng = np.random.default_rng(seed)
    a, b, c = rng.uniform(-1, 1, (3, 3)) * 10.0 ** rng.integers(-3, 4)
    s, t = rng.uniform(-2, 2, 2)
    d = a + s * (b - a) + t * (c - a)
    d[axis] = _nudge(d[axis], ulps)
    _check_orient3d_all_tiers(a, b, c, d)


def test_orient3d_near_coplanar_hits_every_sign():
    rng = np.random.default_rng(1)
    seen = set()
    for _ in range(300):
        a, b, c = rng.uniform(-1, 1, (3, 3))
        d = a + 0.5 * (b - a) + 0.25 * (c - a)
        d[2] = _nudge(d[2], int(rng.integers(-2, 3)))
        seen.add(_check_orient3d_all_tiers(a, b, c, d))
    assert seen == {-1, 0, 1}


def test_orient3d_exactly_coplanar_is_zero():
    rng = np.random.default_rng(2)
    for _ in range(200):
        # dyadic coordinates: d = a + (b - a) + (c - a) holds exactly in floats
        a, b, c = rng.integers(-1000, 1000, (3, 3)) / 64.0
        d = b + c - a
        assert K.orient3d(a, b, c, d) == 0
        assert K.orient3d(a, b, c, _arr(d[0], d[1], _nudge(d[2], 1))) != 0


@SETTINGS
@given(
    st.lists(st.integers(-(2**53) + 1, 2**53 - 1), min_size=12, max_size=12),
    st.lists(st.integers(-1074 + 53, 1000), min_size=12, max_size=12),
)
def test_orient3d_extreme_exponents_match_fraction(mants, exps):
    # subnormals, 1e-300, 1e+300 mixed: the big-integer tier decides
    v = np.array([np.ldexp(float(m), e - 53) for m, e in zip(mants, exps)]).reshape(4, 3)
    assert np.isfinite(v).all()
    _check_orient3d_all_tiers(*v)


def test_orient3d_tiny_scales_near_coplanar():
    rng = np.random.default_rng(3)
    for scale in (2.0**-1000, 1e-300, 2.0**-260, 2.0**260, 1e300):
        for _ in range(20):
            a, b, c = rng.uniform(-1, 1, (3, 3))
            d = a + 0.5 * (b - a) + 0.25 * (c - a)
            d[1] = _nudge(d[1], int(rng.integers(-1, 2)))
            _check_orient3d_all_tiers(a * scale, b * scale, c * scale, d * scale)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(-3, 3), st.integers(0, 2))
def test_orient2d_matches_fraction(seed, ulps, k):
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(-1, 1, (2, 3)) * 10.0 ** rng.integers(-300, 300)
    c = a + rng.uniform(-2, 2) * (b - a)
    c[(k + 1) % 3] = _nudge(c[(k + 1) % 3], ulps)
    want = ref_orient2d(a, b, c, k)
    assert K.orient2d(a, b, c, k) == want
    assert K.orient2d_exact(a, b, c, k) == want


# ------------------------------------------------------------------ segment-triangle

T0, T1, T2 = _arr(0, 0, 0), _arr(1, 0, 0), _arr(0, 1, 0)  # triangle in z = 0
S0, S1, S2 = _arr(1, 0, 0), _arr(0, 1, 0), _arr(0, 0, 1)  # triangle in x + y + z = 1
TINY = 1e-300
SUB = 5e-324  # smallest subnormal

HAND_CASES = [
    # name, p, q, triangle, expected kind
    ("interior", (0.2, 0.2, -1), (0.2, 0.2, 1), (T0, T1, T2), 1),
    ("oblique interior", (-0.3, 0.1, -1), (0.7, 0.4, 1), (T0, T1, T2), 1),
    ("through edge", (0.5, 0, -1), (0.5, 0, 1), (T0, T1, T2), 1),
    ("through hypotenuse", (0.5, 0.5, -1), (0.5, 0.5, 1), (T0, T1, T2), 1),
    ("through vertex", (0, 0, -1), (0, 0, 1), (T0, T1, T2), 1),
    ("endpoint on interior", (0.2, 0.2, 0), (0.2, 0.2, 1), (T0, T1, T2), 1),
    ("endpoint on vertex", (1, 0, 0), (2, 3, 4), (T0, T1, T2), 1),
    ("endpoint on edge", (0.5, 0, 0), (0.5, -1, 1), (T0, T1, T2), 1),
    ("misses outside", (1, 1, -1), (1, 1, 1), (T0, T1, T2), 0),
    ("stops short", (0.2, 0.2, -1), (0.2, 0.2, -TINY), (T0, T1, T2), 0),
    ("stops a subnormal short", (0.2, 0.2, -1), (0.2, 0.2, -SUB), (T0, T1, T2), 0),
    ("parallel above", (-1, 0.2, 1), (2, 0.2, 1), (T0, T1, T2), 0),
    ("parallel 1e-300 above", (-1, 0.2, TINY), (2, 0.2, TINY), (T0, T1, T2), 0),
    ("1e-300 outside an edge", (0.5, -TINY, -1), (0.5, -TINY, 1), (T0, T1, T2), 0),
    ("1e-300 inside an edge", (0.5, TINY, -1), (0.5, TINY, 1), (T0, T1, T2), 1),
    ("subnormal outside a vertex", (-SUB, 0, -1), (-SUB, 0, 1), (T0, T1, T2), 0),
    ("coplanar crossing", (0.75, 0.5, -0.25), (-0.25, 0.5, 0.75), (S0, S1, S2), 2),
    ("coplanar inside", (0.25, 0.25, 0.5), (0.5, 0.25, 0.25), (S0, S1, S2), 2),
    ("coplanar one end inside", (0.25, 0.25, 0.5), (2, -0.5, -0.5), (S0, S1, S2), 2),
    ("coplanar disjoint", (1, 1, -1), (2, 0, -1), (S0, S1, S2), 0),
    ("coplanar along an edge", (1.5, -0.5, 0), (0.5, 0.5, 0), (T0, T1, T2), 2),
    ("coplanar touching a vertex", (2, -1, 0), (1, 0, 0), (T0, T1, T2), 2),
    ("coplanar collinear apart", (3, -2, 0), (2, -1, 0), (T0, T1, T2), 0),
    ("coplanar 1e-300 outside", (-1, -TINY, 0), (2, -TINY, 0), (T0, T1, T2), 0),
    ("point inside", (0.25, 0.25, 0), (0.25, 0.25, 0), (T0, T1, T2), 2),
    ("point above", (0.25, 0.25, 1), (0.25, 0.25, 1), (T0, T1, T2), 0),
]


@pytest.mark.parametrize("name,p,q,tri,kind", HAND_CASES, ids=[c[0] for c in HAND_CASES])
def test_segment_triangle_hand_cases(name, p, q, tri, kind):
    p, q = _arr(*p), _arr(*q)
    a, b, c = tri
    assert K.segment_triangle_intersection(p, q, a, b, c) == kind
    assert ref_segment_triangle(p, q, a, b, c) == (kind > 0)
    # the answer does not depend on the order of the segment's ends or the triangle's vertices
    assert K.segment_triangle_intersection(q, p, c, a, b) == kind
    assert K.segment_triangle_intersection(p, q, b, a, c) == kind


@pytest.mark.parametrize(
    "p,q,tri,hit",
    [
        ((0.5, -1, 0), (0.5, 1, 0), ((0, 0, 0), (1, 0, 0), (2, 0, 0)), True),  # crosses a flat triangle
        ((0.5, -1, 1), (0.5, 1, 1), ((0, 0, 0), (1, 0, 0), (2, 0, 0)), False),  # skew to it
        ((3, -1, 0), (3, 1, 0), ((0, 0, 0), (1, 0, 0), (2, 0, 0)), False),  # coplanar, beyond it
        ((1, 1, 1), (1, -1, -1), ((1, 0, 0), (1, 0, 0), (1, 0, 0)), True),  # a point triangle on pq
        ((1, 1, 1), (1, -1, -0.5), ((1, 0, 0), (1, 0, 0), (1, 0, 0)), False),
        ((0, 0, 0), (4, 0, 0), ((1, 0, 0), (2, 0, 0), (3, 0, 0)), True),  # all collinear, overlapping
        ((0, 0, 0), (0.5, 0, 0), ((1, 0, 0), (2, 0, 0), (3, 0, 0)), False),  # collinear, apart
    ],
)
def test_segment_against_degenerate_triangle(p, q, tri, hit):
    tri = [_arr(*v) for v in tri]
    assert K.segment_triangle_intersection(_arr(*p), _arr(*q), *tri) == (2 if hit else 0)


def test_segment_one_ulp_from_a_slanted_edge():
    # vertical segments through points within a few ulps of the hypotenuse x + y = 1
    for x in (0.3, 0.1, 0.7, 1 / 3):
        for k in range(-3, 4):
            y = _nudge(1.0 - x, k)
            p, q = _arr(x, y, -1), _arr(x, y, 1)
            got = K.segment_triangle_intersection(p, q, T0, T1, T2)
            assert (got > 0) == ref_segment_triangle(p, q, T0, T1, T2)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(-3, 3), st.sampled_from(["edge", "vertex", "plane", "free"]))
def test_segment_triangle_matches_rational_reference(seed, ulps, where):
    rng = np.random.default_rng(seed)
    a, b, c = rng.uniform(-1, 1, (3, 3))
    n = np.cross(b - a, c - a)
    if where == "edge":  # through a float point of an edge, nudged
        x = a + rng.uniform(0, 1) * (b - a)
        i = rng.integers(3)
        x[i] = _nudge(x[i], ulps)
        p, q = x - n * rng.uniform(0.1, 2), x + n * rng.uniform(0.1, 2)
    elif where == "vertex":
        x = a.copy()
        i = rng.integers(3)
        x[i] = _nudge(x[i], ulps)
        p, q = x - rng.uniform(-1, 1, 3), x + rng.uniform(-1, 1, 3)
    elif where == "plane":  # an endpoint within ulps of the plane
        x = a + rng.uniform(0, 0.5) * (b - a) + rng.uniform(0, 0.5) * (c - a)
        x[2] = _nudge(x[2], ulps)
        p, q = x, x + rng.uniform(-1, 1, 3)
    else:
        p, q = rng.uniform(-1, 1, (2, 3))
    got = K.segment_triangle_intersection(p, q, a, b, c)
    assert (got > 0) == ref_segment_triangle(p, q, a, b, c)


def test_segment_triangle_matches_ipctk_on_generic_input():
    ipctk = pytest.importorskip("ipctk")
    rng = np.random.default_rng(4)
    hits = 0
    for _ in range(400):
        p, q, a, b, c = rng.uniform(-1, 1, (5, 3))
        ours = K.segment_triangle_intersection(p, q, a, b, c) > 0
        assert ours == ipctk.is_edge_intersecting_triangle(p, q, a, b, c)
        hits += ours
    assert 20 < hits < 380


# ------------------------------------------------------------------ meshes


def box_tet_mesh(cells=(2, 2, 2), lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0)):
    """Structured box: each cell split into 6 positively oriented tets around its main
    diagonal (Kuhn). Returns vertices, tets, boundary triangles (outward), boundary edges."""
    nx, ny, nz = cells
    axes = [np.linspace(lo[i], hi[i], cells[i] + 1) for i in range(3)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)

    def vid(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k

    tets = []
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                corner = [vid(i + (s & 1), j + (s >> 1 & 1), k + (s >> 2 & 1)) for s in range(8)]
                for axes_order in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
                    s, path = 0, [corner[0]]
                    for ax in axes_order:
                        s |= 1 << ax
                        path.append(corner[s])
                    tets.append(path)
    tets = np.array(tets, dtype=np.int64)
    e = v[tets]
    vol = np.einsum("ij,ij->i", np.cross(e[:, 1] - e[:, 0], e[:, 2] - e[:, 0]), e[:, 3] - e[:, 0])
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    tris = faces[count[inv.ravel()] == 1]
    return v, tets, tris, edges_of_triangles(tris)


def two_bodies(m1, m2):
    v1, t1, f1, e1 = m1
    v2, t2, f2, e2 = m2
    n = len(v1)
    v = np.concatenate([v1, v2])
    return (
        v,
        np.concatenate([t1, t2 + n]),
        np.concatenate([f1, f2 + n]),
        np.concatenate([e1, e2 + n]),
        np.repeat([0, 1], [len(e1), len(e2)]),
        np.repeat([0, 1], [len(f1), len(f2)]),
    )


def brute_force(x, edges, tris):
    ee, tt = np.meshgrid(np.arange(len(edges)), np.arange(len(tris)), indexing="ij")
    pairs = np.stack([ee.ravel(), tt.ravel()], axis=1).astype(np.int64)
    shared = (edges[pairs[:, 0]][:, :, None] == tris[pairs[:, 1]][:, None, :]).any(axis=(1, 2))
    pairs = np.ascontiguousarray(pairs[~shared])
    kinds = K.classify_edge_triangle_pairs(x, edges, tris, pairs)
    return pairs[kinds > 0]


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_single_box_is_intersection_free_despite_coplanar_faces():
    v, tets, tris, edges = box_tet_mesh((3, 2, 2))
    assert len(tris) == 2 * 2 * (3 * 2 + 3 * 2 + 2 * 2)
    assert len(find_intersections(v, edges, tris)) == 0  # many exactly coplanar pairs
    rot = v @ _rotation(np.random.default_rng(5)).T + 0.1  # coplanar only up to rounding
    assert len(find_intersections(rot, edges, tris)) == 0
    assert count_inverted_tets(v, tets) == 0


def test_two_boxes_separated_overlapping_and_touching():
    a = box_tet_mesh((2, 2, 2))
    b = box_tet_mesh((2, 2, 2), lo=(1.5, 0.2, 0.1), hi=(2.5, 1.2, 1.1))
    x, tets, tris, edges, eb, tb = two_bodies(a, b)
    assert len(find_intersections(x, edges, tris)) == 0
    assert check_frame(x, tets, tris, edges).ok

    overlap = box_tet_mesh((2, 2, 2), lo=(0.5, 0.3, 0.2), hi=(1.5, 1.3, 1.2))
    x, tets, tris, edges, eb, tb = two_bodies(a, overlap)
    found = find_intersections(x, edges, tris)
    assert len(found) > 0
    np.testing.assert_array_equal(found, brute_force(x, edges, tris))
    assert (eb[found[:, 0]] != tb[found[:, 1]]).all()  # each box alone is clean

    # face to face contact (distance exactly 0) counts, as coplanar overlaps
    touch = box_tet_mesh((2, 2, 2), lo=(1.0, 0.25, 0.25), hi=(2.0, 0.75, 0.75))
    x, tets, tris, edges, eb, tb = two_bodies(a, touch)
    found, kinds = find_intersections(x, edges, tris, return_kinds=True)
    assert len(found) > 0 and (kinds == 2).any()


@pytest.mark.parametrize("scale", [2.0**-1000, 2.0**-200, 2.0**1000])
def test_answers_do_not_depend_on_scale(scale):
    # power-of-two scaling is exact, so every exact sign is unchanged; these scales push
    # the predicates onto the big-integer tier (and the grid onto tiny or huge cells)
    a = box_tet_mesh((2, 2, 2))
    for lo in ((0.5, 0.3, 0.2), (1.0, 0.25, 0.25), (1.5, 0.2, 0.1)):  # overlap, touch, apart
        b = box_tet_mesh((2, 2, 2), lo=lo, hi=tuple(v + 1 for v in lo))
        x, tets, tris, edges, eb, tb = two_bodies(a, b)
        want, want_kinds = find_intersections(x, edges, tris, return_kinds=True)
        got, kinds = find_intersections(x * scale, edges, tris, return_kinds=True)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(kinds, want_kinds)
        assert count_inverted_tets(x * scale, tets) == 0


def test_interlocked_bars_edge_through_face_detected():
    # a cross of two bars: no vertex of either lies inside the other, yet edges of each
    # pass through faces of the other
    bar_a = box_tet_mesh((1, 1, 1), lo=(-2, -0.25, -0.25), hi=(2, 0.25, 0.25))
    bar_b = box_tet_mesh((1, 1, 1), lo=(-0.25, -2, -0.5), hi=(0.25, 2, 0.5))
    x, tets, tris, edges, eb, tb = two_bodies(bar_a, bar_b)
    va, vb = x[:8], x[8:]
    assert not ((np.abs(va[:, 0]) <= 0.25) & (np.abs(va[:, 1]) <= 2)).any()
    assert not ((np.abs(vb[:, 1]) <= 0.25) & (np.abs(vb[:, 2]) <= 0.25)).any()
    found = find_intersections(x, edges, tris)
    assert len(found) > 0
    np.testing.assert_array_equal(found, brute_force(x, edges, tris))
    # an axis edge of bar A (y = z = 0.25) crosses bar B's face x = 0.25
    e = np.flatnonzero((x[edges[:, 0], 1:] == 0.25).all(1) & (x[edges[:, 1], 1:] == 0.25).all(1))
    t = np.flatnonzero((x[tris, 0] == 0.25).all(1))
    assert len(e) == 1 and len(t) == 2
    assert any((row[0] == e[0] and row[1] in t) for row in found)
    # body filter: skipping same-body pairs changes nothing here, all hits are between bodies
    np.testing.assert_array_equal(find_intersections(x, edges, tris, eb, tb), found)
    frame = check_frame(x, tets, tris, edges)
    assert not frame.ok and frame.n_intersections == len(found) and frame.n_inverted == 0


def test_body_filter_skips_pairs_within_one_body():
    v, tets, tris, edges = box_tet_mesh((2, 2, 2))
    # pull a corner through the opposite face: a self-intersection within body 0
    x = v.copy()
    assert (x[0] == 0).all()
    x[0] = (2.5, 0.6, 0.7)
    assert len(find_intersections(x, edges, tris)) > 0
    eb, tb = np.zeros(len(edges), np.int64), np.zeros(len(tris), np.int64)
    assert len(find_intersections(x, edges, tris, eb, tb)) == 0


@pytest.mark.parametrize("depth,hit", [(0.05, False), (0.0, True), (-0.05, True)])
def test_box_on_a_huge_floor(depth, hit):
    # two floor triangles and their edges span thousands of grid cells: they bypass the
    # grid and are tested against everything
    floor_v = np.array([[-50, 0, -50], [50, 0, -50], [50, 0, 50], [-50, 0, 50]], dtype=float)
    floor_t = np.array([[0, 2, 1], [0, 3, 2]])
    floor = (floor_v, np.zeros((0, 4), np.int64), floor_t, edges_of_triangles(floor_t))
    box = box_tet_mesh((3, 3, 3), lo=(0.1, depth, 0.2), hi=(0.4, depth + 0.3, 0.5))
    x, tets, tris, edges, eb, tb = two_bodies(floor, box)
    found = find_intersections(x, edges, tris)
    assert (len(found) > 0) == hit
    np.testing.assert_array_equal(found, brute_force(x, edges, tris))
    if hit:
        assert (eb[found[:, 0]] != tb[found[:, 1]]).all()


@pytest.mark.parametrize("seed", range(3))
def test_broad_phase_matches_brute_force_on_a_soup(seed):
    rng = np.random.default_rng(seed)
    n = 300
    x = rng.uniform(0, 1, (n, 3))
    # small triangles and edges around random centres, plus a few huge ones
    tris = rng.integers(0, n, (150, 3))
    tris = tris[(tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])]
    edges = rng.integers(0, n, (200, 2))
    edges = edges[edges[:, 0] != edges[:, 1]]
    centres = rng.uniform(0, 1, (n, 3))
    x = centres + 0.08 * (x - 0.5)
    x[:5] = rng.uniform(-1, 2, (5, 3))  # some long primitives
    found = find_intersections(x, edges, tris)
    want = brute_force(x, np.ascontiguousarray(edges, dtype=np.int64), np.ascontiguousarray(tris, dtype=np.int64))
    assert len(want) > 0
    np.testing.assert_array_equal(found, want)


def test_has_intersections_agrees_with_ipctk_on_random_pairs_of_meshes():
    ipctk = pytest.importorskip("ipctk")
    rng = np.random.default_rng(6)
    a = box_tet_mesh((1, 1, 2), lo=(-0.5, -0.5, -1), hi=(0.5, 0.5, 1))
    outcomes = []
    for _ in range(60):
        b = list(box_tet_mesh((2, 1, 1), lo=(-0.6, -0.3, -0.3), hi=(0.6, 0.3, 0.3)))
        b[0] = b[0] @ _rotation(rng).T + rng.uniform(-1.6, 1.6, 3)
        first = list(a)
        first[0] = a[0] @ _rotation(rng).T
        x, tets, tris, edges, eb, tb = two_bodies(first, b)
        ours = len(find_intersections(x, edges, tris)) > 0
        mesh = ipctk.CollisionMesh(
            np.asfortranarray(x), np.asfortranarray(edges, dtype=np.int32), np.asfortranarray(tris, dtype=np.int32)
        )
        assert ours == ipctk.has_intersections(mesh, np.asfortranarray(x))
        outcomes.append(ours)
    assert 5 < sum(outcomes) < 55


# ------------------------------------------------------------------ tets and frames


def test_inverted_tets_exact_signs():
    v, tets, tris, edges = box_tet_mesh((2, 2, 2))
    assert count_inverted_tets(v, tets) == 0
    x = v.copy()
    centre = 13  # the middle vertex of a 2x2x2 box; moving it far inverts some of its tets
    x[centre] = (0.5, 0.5, 3.0)
    want = [i for i, t in enumerate(tets) if ref_orient3d(*x[t]) <= 0]
    assert len(want) > 0
    np.testing.assert_array_equal(inverted_tets(x, tets), want)
    assert count_inverted_tets(x, tets) == len(want)
    # a flat tet (exactly zero volume) counts; one with 1e-300 of height does not
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, 0]], dtype=float)
    assert count_inverted_tets(flat, [[0, 1, 2, 3]]) == 1
    flat[3, 2] = 1e-300
    assert count_inverted_tets(flat, [[0, 1, 2, 3]]) == 0
    assert count_inverted_tets(flat, [[0, 2, 1, 3]]) == 1
    frame = check_frame(x, tets, tris, edges)
    assert frame.n_inverted == len(want)
    assert frame.min_signed_volume < 0
    np.testing.assert_array_equal(frame.first_inverted, want[:10])


def test_check_frame_fields_and_non_finite_input():
    v, tets, tris, edges = box_tet_mesh((1, 1, 1))
    frame = check_frame(v, tets, tris)  # edges derived from the triangles
    assert isinstance(frame, FrameCheck) and frame.ok
    assert frame.n_intersections == 0 and frame.n_inverted == 0
    assert frame.min_signed_volume == pytest.approx(1.0 / 6.0)  # 6 equal tets fill the cube
    assert "0 intersecting" in frame.summary()
    bad = v.copy()
    bad[3, 1] = np.nan
    frame = check_frame(bad, tets, tris, edges)
    assert not frame.ok and frame.n_nonfinite == 1
    with pytest.raises(ValueError):
        find_intersections(bad, edges, tris)
    with pytest.raises(ValueError):
        find_intersections(v, edges, tris, edge_body=np.zeros(len(edges)))
    with pytest.raises(ValueError):
        find_intersections(v, tris, tris)


# ------------------------------------------------------------------ containment


def _box(cells, size, origin):
    from ipcsim.model.generate import box_tet_mesh

    return box_tet_mesh(*cells, size=size, origin=origin)


def _scene(*boxes):
    """Points, tets and outward boundary triangles of several tet boxes."""
    from ipcsim.model.surface import boundary_triangles

    points, tets, offset = [], [], 0
    for p, t in boxes:
        points.append(p)
        tets.append(t + offset)
        offset += len(p)
    tets = np.concatenate(tets)
    return np.concatenate(points), tets, boundary_triangles(tets)


def _containments(points, tets, triangles):
    from ipcsim.contact.intersection import find_containments, solids_of

    solids = solids_of(len(points), tets, triangles)
    return {tuple(int(solids.labels[v]) for v in pair)
            for pair in find_containments(points, solids)}


BIG = _box((2, 2, 2), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
SMALL_INSIDE = _box((1, 1, 1), (0.2, 0.2, 0.2), (0.4, 0.4, 0.4))


def test_a_cube_inside_a_cube_is_contained_and_apart_is_not():
    assert _containments(*_scene(BIG, SMALL_INSIDE)) == {(1, 0)}
    apart = (SMALL_INSIDE[0] + [2.0, 0.0, 0.0], SMALL_INSIDE[1])
    assert _containments(*_scene(BIG, apart)) == set()


def test_three_nested_cubes_each_inside_those_around_it():
    tiny = _box((1, 1, 1), (0.05, 0.05, 0.05), (0.475, 0.475, 0.475))
    assert _containments(*_scene(BIG, SMALL_INSIDE, tiny)) == {(1, 0), (2, 0), (2, 1)}


def test_a_body_in_a_hollow_bodys_cavity_is_not_inside_it():
    """A 3x3x3 block of cells without its middle cell: its boundary has an outer and a
    cavity wall, both of the one part; a cube in the cavity is outside the solid."""
    points, tets = _box((3, 3, 3), (0.9, 0.9, 0.9), (0.0, 0.0, 0.0))
    middle = np.all((points[tets] > 0.3 - 1e-9) & (points[tets] < 0.6 + 1e-9), axis=(1, 2))
    shell = (points, tets[~middle])
    in_cavity = _box((1, 1, 1), (0.1, 0.1, 0.1), (0.4, 0.4, 0.4))
    in_wall = _box((1, 1, 1), (0.05, 0.05, 0.05), (0.1, 0.1, 0.1))
    assert _containments(*_scene(shell, in_cavity)) == set()
    assert _containments(*_scene(shell, in_wall)) == {(1, 0)}


def test_only_closed_outward_surfaces_contain():
    points, tets, triangles = _scene(BIG, SMALL_INSIDE)
    big = np.isin(triangles, np.arange(len(BIG[0]))).all(axis=1)
    none = np.zeros((0, 4), np.int64)
    surface = np.concatenate([triangles[big], triangles[~big]])
    assert _containments(points, none, surface) == {(1, 0)}  # a closed .obj solid
    room = np.concatenate([triangles[big][:, ::-1], triangles[~big]])  # faces inward
    assert _containments(points, none, room) == set()
    assert _containments(points, none, np.concatenate([triangles[big][1:],
                                                        triangles[~big]])) == set()  # open


@pytest.mark.parametrize("gap", [1e-3, 1e-9, 1e-14])
def test_a_vertex_just_off_a_face_is_decided_by_its_side(gap):
    """The winding number rounds the right way however close the vertex is, the sign of
    each solid angle coming from the exact orient3d."""
    for height, inside in ((gap, True), (1.0 + gap, False)):  # over the bottom, the top
        # the small box's first vertex, its part's representative, is `gap` off the face
        small = _box((1, 1, 1), (0.1, 0.1, 0.1), (0.3, height, 0.3))
        assert _containments(*_scene(BIG, small)) == ({(1, 0)} if inside else set()), height


def test_winding_numbers_match_a_box_test_on_random_points():
    rng = np.random.default_rng(7)
    points, tets, triangles = _scene(BIG)
    from ipcsim.kernels.contact.intersection import solid_angle

    for q in rng.uniform(-0.5, 1.5, size=(200, 3)):
        total = sum(solid_angle(tuple(q), *(tuple(points[i]) for i in tri)) for tri in triangles)
        inside = bool(np.all((q > 0.0) & (q < 1.0)))
        assert total / (4 * np.pi) == pytest.approx(1.0 if inside else 0.0, abs=1e-9)
