"""Broad phase: the BVH finds exactly the pairs a brute-force box test finds.

The oracle builds boxes with numpy (lo = min over the primitive's vertices and both positions,
minus inflation/2; hi likewise) and tests every pair; the same filters (shared vertex, body,
kinematic) are applied. Candidate sets must be identical after sorting.
"""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.contact.candidates import find_candidates as _find_candidates
from ipcsim.contact.collision_mesh import CollisionMesh
from ipcsim.kernels.contact import broad_phase as bp


def find_candidates(x, points, edges, triangles, inflation, body=None, self_collision=True,
                    kinematic=None, **options):
    """The broad phase on a collision mesh made of the given primitives."""
    mesh = CollisionMesh.of(len(x), points, edges, triangles, body, kinematic, self_collision)
    return _find_candidates(mesh, x, inflation, **options)


# ----------------------------------------------------------------------------- oracle

def _boxes(x0, x1, prims, r):
    pts = np.concatenate([x0[prims], x1[prims]], axis=1)  # (m, 2k, 3)
    return pts.min(axis=1) - 0.5 * r, pts.max(axis=1) + 0.5 * r


def _brute_pairs(x0, x1, a_prims, b_prims, r):
    alo, ahi = _boxes(x0, x1, a_prims, r)
    blo, bhi = _boxes(x0, x1, b_prims, r)
    hit = np.ones((len(a_prims), len(b_prims)), bool)
    for ax in range(3):
        hit &= (alo[:, None, ax] <= bhi[None, :, ax]) & (blo[None, :, ax] <= ahi[:, None, ax])
    return hit


def _brute_force(x0, x1, points, edges, tris, r, body, self_collision, kin):
    def keep(hit, a_prims, b_prims):
        share = np.zeros_like(hit)
        for i in range(a_prims.shape[1]):
            for j in range(b_prims.shape[1]):
                share |= a_prims[:, None, i] == b_prims[None, :, j]
        hit &= ~share
        if not self_collision:
            hit &= body[a_prims[:, 0]][:, None] != body[b_prims[:, 0]][None, :]
        ka = kin[a_prims].all(axis=1)
        kb = kin[b_prims].all(axis=1)
        hit &= ~(ka[:, None] & kb[None, :])
        return hit

    p = points.reshape(-1, 1)
    pt = keep(_brute_pairs(x0, x1, p, tris, r), p, tris)
    ee = keep(_brute_pairs(x0, x1, edges, edges, r), edges, edges)
    ee &= np.triu(np.ones_like(ee), 1)
    pi, ti = np.nonzero(pt)
    ea, eb = np.nonzero(ee)
    pt_rows = np.concatenate([p[pi], tris[ti]], axis=1)
    ee_rows = np.concatenate([edges[ea], edges[eb]], axis=1)
    return _sorted(pt_rows), _sorted(ee_rows)


def _sorted(rows):
    rows = np.asarray(rows, np.int64).reshape(-1, 4)
    return rows[np.lexsort(rows.T[::-1])]


# ----------------------------------------------------------------------------- scenes

def _edges_of(tris):
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0)


def _triangle_soup(rng, n_tris, size):
    centres = rng.uniform(0.0, 1.0, (n_tris, 1, 3))
    x = (centres + size * rng.normal(size=(n_tris, 3, 3))).reshape(-1, 3)
    tris = np.arange(3 * n_tris).reshape(-1, 3)
    return x, tris


def _box_surface(n, lo, hi):
    """Surface of an axis-aligned box, n x n quads per side, vertices merged."""
    s = np.linspace(0.0, 1.0, n + 1)
    u, v = np.meshgrid(s, s, indexing="ij")
    quads = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    q = np.stack([quads[:-1, :-1], quads[1:, :-1], quads[1:, 1:], quads[:-1, 1:]], -1)
    q = q.reshape(-1, 4)
    pts, tris = [], []
    for ax in range(3):
        for side in (0.0, 1.0):
            p = np.empty(((n + 1) ** 2, 3))
            o = [a for a in range(3) if a != ax]
            p[:, ax] = side
            p[:, o[0]] = u.ravel()
            p[:, o[1]] = v.ravel()
            base = sum(len(a) for a in pts)
            pts.append(p)
            tris.append(base + np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]))
    pts = np.concatenate(pts)
    key = np.round(pts * n).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    tris = inverse.reshape(-1)[np.concatenate(tris)]
    return lo + pts[first] * (np.asarray(hi) - lo), tris


def _two_boxes(n, gap, angle_deg):
    xa, ta = _box_surface(n, np.zeros(3), np.ones(3))
    th = np.deg2rad(angle_deg)
    rot = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    xb = (xa - 0.5) @ rot.T + 0.5 + np.array([0.1, 0.07, 1.0 + gap])
    x = np.vstack([xa, xb])
    tris = np.vstack([ta, ta + len(xa)])
    body = np.repeat([0, 1], len(xa))
    return x, tris, body


def _slivers(rng, n_tris):
    """Long thin triangles: one edge ~1, height ~1e-4, random orientation."""
    a = rng.uniform(0, 1, (n_tris, 3))
    d = rng.normal(size=(n_tris, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    b = a + d
    c = 0.5 * (a + b) + 1e-4 * rng.normal(size=(n_tris, 3))
    x = np.stack([a, b, c], 1).reshape(-1, 3)
    return x, np.arange(3 * n_tris).reshape(-1, 3)


def _degenerate(rng):
    """Zero-size boxes: vertices on an integer lattice (exactly touching boxes), collapsed
    triangles and edges (repeated vertices), duplicated positions."""
    x = rng.integers(0, 4, (60, 3)).astype(float)
    tris = rng.integers(0, 60, (80, 3))
    tris[:10, 1] = tris[:10, 0]  # collapsed to an edge
    tris[10:20, 1:] = tris[10:20, :1]  # collapsed to a point
    return x, tris


def _check(x0, x1, tris, r, body, self_collision, kin, points=None, edges=None):
    edges = _edges_of(tris) if edges is None else edges
    points = np.unique(tris) if points is None else points
    got_pt, got_ee, pt_idx, ee_idx = find_candidates(
        x0, points, edges, tris, r, body, self_collision, kin, x1=x1, return_indices=True)
    want_pt, want_ee = _brute_force(x0, x0 if x1 is None else x1, points, edges, tris, r,
                                    body, self_collision, kin)
    np.testing.assert_array_equal(_sorted(got_pt), want_pt)
    np.testing.assert_array_equal(_sorted(got_ee), want_ee)
    # the index arrays describe the same rows; EE pairs are (a, b) with a < b, each once
    np.testing.assert_array_equal(got_pt[:, 0], points[pt_idx[:, 0]])
    np.testing.assert_array_equal(got_pt[:, 1:], tris[pt_idx[:, 1]])
    assert np.all(ee_idx[:, 0] < ee_idx[:, 1])
    np.testing.assert_array_equal(got_ee[:, :2], edges[ee_idx[:, 0]])
    np.testing.assert_array_equal(got_ee[:, 2:], edges[ee_idx[:, 1]])
    assert len(np.unique(ee_idx, axis=0)) == len(ee_idx)
    return len(want_pt), len(want_ee)


SCENES = ["soup_small", "soup_large", "two_boxes", "slivers", "degenerate"]


def _scene(name, seed):
    rng = np.random.default_rng(seed)
    if name == "soup_small":
        x, tris = _triangle_soup(rng, 300, 0.03)
        body = rng.integers(0, 3, len(x))
    elif name == "soup_large":  # sizes over three orders of magnitude
        x, tris = _triangle_soup(rng, 250, 0.0)
        size = 10.0 ** rng.uniform(-3, -0.5, (len(tris), 1, 1))
        x += (size * rng.normal(size=(len(tris), 3, 3))).reshape(-1, 3)
        body = rng.integers(0, 2, len(x))
    elif name == "two_boxes":
        x, tris, body = _two_boxes(6, 0.01, 10.0)
    elif name == "slivers":
        x, tris = _slivers(rng, 200)
        body = rng.integers(0, 4, len(x))
    else:
        x, tris = _degenerate(rng)
        body = rng.integers(0, 2, len(x))
    kin = rng.random(len(x)) < 0.3
    return rng, x, tris, body, kin


@pytest.mark.parametrize("self_collision", [True, False])
@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("seed", [0, 1])
def test_static_inflated_matches_brute_force(name, seed, self_collision):
    rng, x, tris, body, kin = _scene(name, seed)
    for r in (0.0, 0.02, 0.3):
        _check(x, None, tris, r, body, self_collision, kin)


@pytest.mark.parametrize("self_collision", [True, False])
@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("seed", [0, 1])
def test_swept_matches_brute_force(name, seed, self_collision):
    rng, x, tris, body, kin = _scene(name, seed)
    scale = 0.05 if name != "degenerate" else 1.0
    x1 = x + scale * rng.normal(size=x.shape)
    still = rng.random(len(x)) < 0.2
    x1[still] = x[still]
    x1[:5] += 10.0  # a few huge motions: boxes across the scene
    for r in (0.0, 1e-3):
        _check(x, x1, tris, r, body, self_collision, kin)


def test_two_boxes_counts_are_nontrivial():
    """The two-box scene has cross-body candidates in its contact patch, and dropping
    self-collision keeps exactly those (an oracle that found nothing would pass vacuously)."""
    x, tris, body = _two_boxes(8, 0.01, 10.0)
    kin = np.zeros(len(x), bool)
    n_self = _check(x, None, tris, 0.02, body, True, kin)
    n_cross = _check(x, None, tris, 0.02, body, False, kin)
    assert n_cross[0] > 0 and n_cross[1] > 0
    assert n_self[0] > n_cross[0] and n_self[1] > n_cross[1]
    # every remaining pair joins the two bodies
    pt, ee = find_candidates(x, np.unique(tris), _edges_of(tris), tris, 0.02, body, False)
    assert np.all(body[pt[:, 0]] != body[pt[:, 1]])
    assert np.all(body[ee[:, 0]] != body[ee[:, 2]])


def test_kinematic_pairs_dropped():
    x, tris, body = _two_boxes(4, 0.01, 0.0)
    kin = np.ones(len(x), bool)  # everything kinematic: nothing left
    pt, ee = find_candidates(x, np.unique(tris), _edges_of(tris), tris, 0.05, body, True, kin)
    assert len(pt) == 0 and len(ee) == 0
    kin[body == 0] = False  # one free body: its pairs stay
    _check(x, None, tris, 0.05, body, True, kin)
    pt, ee = find_candidates(x, np.unique(tris), _edges_of(tris), tris, 0.05, body, True, kin)
    assert len(pt) > 0 and not np.any(kin[pt].all(axis=1))


def test_subset_of_surface_vertices_and_empty_inputs():
    rng = np.random.default_rng(3)
    x, tris = _triangle_soup(rng, 100, 0.05)
    points = np.arange(0, len(x), 3)  # only some vertices act as points
    body = np.zeros(len(x), np.int64)
    kin = np.zeros(len(x), bool)
    _check(x, None, tris, 0.05, body, True, kin, points=points)
    pt, ee = find_candidates(x, np.empty(0, np.int64), np.empty((0, 2), np.int64),
                             np.empty((0, 3), np.int64), 0.1)
    assert pt.shape == (0, 4) and ee.shape == (0, 4)
    # a single primitive of each kind
    pt, ee = find_candidates(x, [9], [[0, 1]], [[0, 1, 2]], 10.0)
    assert pt.tolist() == [[9, 0, 1, 2]] and ee.shape == (0, 4)


def test_deterministic_and_thread_order_free():
    rng, x, tris, body, kin = _scene("soup_small", 5)
    edges = _edges_of(tris)
    a = find_candidates(x, np.unique(tris), edges, tris, 0.05, body, True, kin)
    b = find_candidates(x, np.unique(tris), edges, tris, 0.05, body, True, kin)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_many_hits_per_query_overflow_path():
    """Queries with more hits than the first-pass buffer take the second walk."""
    rng = np.random.default_rng(7)
    x, tris = _triangle_soup(rng, 120, 0.02)
    x[:3] = [[-5, -5, -5], [5, 5, 5], [5, -5, 0]]  # one triangle across everything
    body = np.zeros(len(x), np.int64)
    kin = np.zeros(len(x), bool)
    n_pt, n_ee = _check(x, None, tris, 0.0, body, True, kin)
    assert n_pt > bp._BUFFER and n_ee > bp._BUFFER


def test_a_group_of_queries_meeting_more_leaves_than_it_keeps():
    """Queries walk the tree in groups; a group whose boxes span more leaves than the
    walk keeps (a few points swept across the whole scene) walks again, and each query
    still gets every pair."""
    rng = np.random.default_rng(8)
    n_tris = bp.LEAF_SIZE * bp._GROUP_LEAVES * 2
    x, tris = _triangle_soup(rng, n_tris, 0.003)
    x[:9] -= 1.0
    x1 = x.copy()
    x1[:9] += 3.0  # three triangles swept across everything
    body = np.zeros(len(x), np.int64)
    kin = np.zeros(len(x), bool)
    n_pt, n_ee = _check(x, x1, tris, 0.0, body, True, kin)
    assert n_pt > bp.LEAF_SIZE * bp._GROUP_LEAVES and n_ee > bp._BUFFER


def test_bvh_root_box_holds_everything():
    rng = np.random.default_rng(11)
    x, tris = _triangle_soup(rng, 37, 0.1)
    boxes = bp.primitive_boxes(x, x, tris, 0.0)
    nodes, leaf_boxes, order, last_slot = bp.build_bvh(boxes)
    np.testing.assert_array_equal(np.sort(order), np.arange(len(tris)))
    np.testing.assert_array_equal(leaf_boxes, boxes[order])
    np.testing.assert_array_equal(nodes[0, :3], boxes[:, :3].min(0))
    np.testing.assert_array_equal(nodes[0, 3:], boxes[:, 3:].max(0))
    assert last_slot[0] == len(tris) - 1


def test_rejects_bad_input():
    x = np.zeros((3, 3))
    with pytest.raises(ValueError):
        find_candidates(x, [0], [[0, 1]], [[0, 1, 3]], 0.1)
    with pytest.raises(ValueError):
        find_candidates(x, [0], [[0, 1]], [[0, 1, 2]], -1.0)


@pytest.mark.parametrize("name", SCENES)
def test_filtering_a_swept_set_to_part_of_the_step_equals_a_new_query(name):
    """The line search's shortcut: pairs swept over x -> x1, filtered to x -> x + α(x1 − x),
    are exactly the pairs a broad phase over the shorter motion finds."""
    rng, x, tris, body, kin = _scene(name, 3)
    x1 = x + 0.1 * rng.normal(size=x.shape)
    edges = _edges_of(tris)
    verts = np.unique(tris)
    pt, ee = find_candidates(x, verts, edges, tris, 0.01, body, True, kin, x1=x1)
    for alpha in (0.5, 0.05, 0.0):
        xa = x + alpha * (x1 - x)
        want_pt, want_ee = find_candidates(x, verts, edges, tris, 0.01, body, True, kin, x1=xa)
        got_pt = pt[bp.swept_pairs_within(x, xa, pt, 1, 0.01)]
        got_ee = ee[bp.swept_pairs_within(x, xa, ee, 2, 0.01)]
        assert np.array_equal(_sorted(got_pt), _sorted(want_pt))
        assert np.array_equal(_sorted(got_ee), _sorted(want_ee))
        if alpha == 0.5 and name != "degenerate":  # (a lattice: everything overlaps)
            assert 0 < len(want_pt) < len(pt)  # the filter removed something, kept something
