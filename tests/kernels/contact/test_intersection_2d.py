"""Exact predicates of 2D frames (kernels/contact/intersection.py, the plane z = 0):
segment crossing against a rational reference that solves for the meeting point
(independent of the orientation logic), triangle orientation against Fraction
arithmetic, the edge broad phase against brute force, and ipctk's 2D has_intersections
as an oracle."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from ipcsim.kernels.algebra.linalg import triangle_signed_areas
from ipcsim.kernels.contact import intersection as K
from ipcsim.model.generate import rectangle_mesh
from ipcsim.model.surface import boundary_edges


def _F(v):
    return [Fraction(float(c)) for c in v[:2]]


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _on_segment(x, p, q):
    # x on the closed segment pq (p may equal q), exactly
    d = [q[0] - p[0], q[1] - p[1]]
    w = [x[0] - p[0], x[1] - p[1]]
    if _cross(d, w) != 0:
        return False
    return min(p[0], q[0]) <= x[0] <= max(p[0], q[0]) and \
        min(p[1], q[1]) <= x[1] <= max(p[1], q[1])


def ref_segments_meet(p, q, r, s):
    """Solve p + t (q − p) = r + u (s − r) in rationals: t, u in [0, 1]; parallel or
    degenerate segments: an endpoint of one lies on the other."""
    p, q, r, s = _F(p), _F(q), _F(r), _F(s)
    d1 = [q[0] - p[0], q[1] - p[1]]
    d2 = [s[0] - r[0], s[1] - r[1]]
    den = _cross(d1, d2)
    if den != 0:
        w = [r[0] - p[0], r[1] - p[1]]
        t = _cross(w, d2) / den
        u = _cross(w, d1) / den
        return 0 <= t <= 1 and 0 <= u <= 1
    return (_on_segment(r, p, q) or _on_segment(s, p, q) or _on_segment(p, r, s)
            or _on_segment(q, r, s))


def _pt(x, y):
    return np.array([x, y, 0.0])


@pytest.mark.parametrize("p, q, r, s, meet", [
    ((0, 0), (1, 1), (0, 1), (1, 0), True),        # proper crossing
    ((0, 0), (1, 0), (0.5, 0), (0.5, 1), True),     # an endpoint on the other segment
    ((0, 0), (1, 0), (1, 0), (2, 0), True),         # collinear, touching at an end
    ((0, 0), (1, 0), (1.5, 0), (2, 0), False),      # collinear, apart
    ((0, 0), (2, 0), (0.5, 0), (1.5, 0), True),     # collinear, one inside the other
    ((0, 0), (1, 0), (0, 1e-300), (1, 1e-300), False),  # parallel, a hair apart
    ((0, 0), (1, 0), (0.5, 0.5), (0.5, 0.5), False),    # a point off the segment
    ((0, 0), (1, 0), (0.25, 0.0), (0.25, 0.0), True),   # a point on it
])
def test_segment_hand_cases(p, q, r, s, meet):
    args = [_pt(*v) for v in (p, q, r, s)]
    assert K.segments_cross_2d(*args) == meet == ref_segments_meet(*args)
    assert K.segments_cross_2d(args[2], args[3], args[0], args[1]) == meet


@pytest.mark.parametrize("seed", range(6))
def test_segments_match_the_rational_reference_near_degeneracy(seed):
    """Segments whose endpoints lie within a few ulps of the other segment's line or end:
    every sign decided exactly, with both outcomes present."""
    rng = np.random.default_rng(seed)
    outcomes = set()
    for _ in range(400):
        p, q = rng.uniform(-1, 1, (2, 2))
        t = rng.choice([0.0, 1.0, rng.uniform(0, 1), rng.uniform(1, 1.01)])
        on = p + t * (q - p)
        r = np.nextafter(on, on + rng.choice([-1, 1], 2) * np.inf) if rng.random() < 0.7 else on
        s = r + rng.uniform(-1, 1, 2)
        if rng.random() < 0.3:  # collinear-ish continuation
            s = r + rng.uniform(-1, 1) * (q - p)
        args = [_pt(*v) for v in (p, q, r, s)]
        got = K.segments_cross_2d(*args)
        assert got == ref_segments_meet(*args)
        outcomes.add(got)
    assert outcomes == {True, False}


def test_triangle_orientations_are_exact_and_areas_are_the_floating_ones():
    rng = np.random.default_rng(3)
    x = np.zeros((300, 3))
    x[:, :2] = rng.uniform(-1, 1, (300, 2))
    tris = rng.choice(300, (100, 3), replace=True).astype(np.int64)
    # near-flat triangles: the third vertex an ulp off the line of the first two
    for t in range(0, 100, 3):
        a, b, c = tris[t]
        mid = 0.5 * (x[a, :2] + x[b, :2])
        x[c, :2] = np.nextafter(mid, mid + rng.choice([-1, 1], 2) * np.inf)
    signs = np.empty(100, np.int8)
    areas = np.empty(100)
    K.triangle_orientations(x, tris, signs, areas)
    for t, (a, b, c) in enumerate(tris):
        A, B, C = _F(x[a]), _F(x[b]), _F(x[c])
        ref = _cross([B[0] - A[0], B[1] - A[1]], [C[0] - A[0], C[1] - A[1]])
        assert signs[t] == (ref > 0) - (ref < 0)
        assert areas[t] == pytest.approx(float(ref) / 2, rel=1e-9, abs=1e-15)
    assert set(signs.tolist()) >= {-1, 1}
    P, T = rectangle_mesh(3, 2, (2.0, 1.0))
    np.testing.assert_allclose(triangle_signed_areas(P, T), 1.0 / 6.0, rtol=1e-14)


def test_edge_candidates_are_the_brute_force_ones():
    rng = np.random.default_rng(4)
    x = np.zeros((120, 3))
    x[:, :2] = rng.uniform(0, 1, (120, 2))
    edges = np.column_stack([np.arange(0, 120, 2), np.arange(1, 120, 2)]).astype(np.int64)
    edges = np.vstack([edges, [[0, 3], [1, 2]]])  # two that share vertices with others
    pairs = K.edge_edge_candidates_2d(x, edges)
    lo = np.minimum(x[edges[:, 0]], x[edges[:, 1]])
    hi = np.maximum(x[edges[:, 0]], x[edges[:, 1]])
    ref = {(i, j) for i in range(len(edges)) for j in range(i + 1, len(edges))
           if np.all(lo[i] <= hi[j]) and np.all(lo[j] <= hi[i])
           and not set(edges[i].tolist()) & set(edges[j].tolist())}
    found = [tuple(sorted(r)) for r in pairs.tolist()]
    assert len(found) == len(set(found)) and set(found) == ref and len(ref) > 50
    crossing = K.crossing_edge_pairs_2d(x, edges, pairs)
    for (i, j), c in zip(pairs.tolist(), crossing):
        assert c == ref_segments_meet(*x[edges[i]], *x[edges[j]])
    assert crossing.any() and not crossing.all()


def test_crossings_agree_with_ipctk_has_intersections():
    ipctk = pytest.importorskip("ipctk")
    rng = np.random.default_rng(6)
    V0, T0 = rectangle_mesh(3, 3)
    E0 = boundary_edges(T0)
    seen = set()
    for _ in range(60):
        th = rng.uniform(0, 2 * np.pi)
        R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
        V1 = (V0 - [0.5, 0.5, 0.0]) @ R.T + [0.5 + rng.uniform(-1.2, 1.2),
                                             0.5 + rng.uniform(-1.2, 1.2), 0.0]
        V = np.vstack([V0, V1])
        E = np.vstack([E0, E0 + len(V0)])
        pairs = K.edge_edge_candidates_2d(V, E)
        ours = bool(K.crossing_edge_pairs_2d(V, E, pairs).any())
        mesh = ipctk.CollisionMesh(np.asfortranarray(V[:, :2]), E.astype(np.int32))
        assert ours == ipctk.has_intersections(mesh, np.asfortranarray(V[:, :2]))
        seen.add(ours)
    assert seen == {True, False}
