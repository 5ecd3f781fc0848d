"""The exact checker's broad phase is the package's BVH (kernels/contact/broad_phase.py), on exact
boxes: every edge–triangle pair whose closed boxes overlap, no pair sharing a vertex, and
with body ids no pair within one body; the checker's edges are model.surface's."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.contact.intersection import edges_of_triangles, find_intersections
from ipcsim.kernels.contact import intersection as K
from ipcsim.model.surface import unique_edges


def _box_pairs(x, edges, tris, eb=None, tb=None):
    """Brute force: closed boxes overlap, no shared vertex index, bodies differ (if given)."""
    elo, ehi = x[edges].min(axis=1), x[edges].max(axis=1)
    tlo, thi = x[tris].min(axis=1), x[tris].max(axis=1)
    ov = ((elo[:, None] <= thi[None]) & (tlo[None] <= ehi[:, None])).all(axis=2)
    shared = (edges[:, None, :, None] == tris[None, :, None, :]).any(axis=(2, 3))
    keep = ov & ~shared
    if eb is not None:
        keep &= eb[:, None] != tb[None, :]
    return {tuple(p) for p in np.argwhere(keep)}


def _candidates(x, edges, tris, eb=None, tb=None):
    empty = np.zeros(0, np.int64)
    pairs = K.edge_triangle_candidates(x, edges, tris, empty if eb is None else eb,
                                       empty if tb is None else tb)
    as_set = {tuple(p) for p in pairs}
    assert len(as_set) == len(pairs)  # each pair once
    return as_set


@pytest.mark.parametrize("seed", range(3))
def test_candidates_are_exactly_the_overlapping_closed_boxes(seed):
    rng = np.random.default_rng(seed)
    n = 200
    # coordinates on a coarse lattice: many boxes touch exactly (equal faces, edges, corners)
    x = rng.integers(0, 12, (n, 3)).astype(float) / 4.0
    tris = rng.integers(0, n, (150, 3))
    tris = tris[(tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])]
    edges = rng.integers(0, n, (180, 2))
    edges = edges[edges[:, 0] != edges[:, 1]]
    want = _box_pairs(x, edges, tris)
    assert len(want) > 100
    assert _candidates(x, edges, tris) == want
    eb = rng.integers(0, 3, len(edges))
    tb = rng.integers(0, 3, len(tris))
    assert _candidates(x, edges, tris, eb, tb) == _box_pairs(x, edges, tris, eb, tb)


def test_touching_at_a_single_point_is_a_candidate_and_a_hit():
    # the segment's end lies exactly on the triangle's edge: boxes meet in a point/face
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, 0.0, 0.0], [0.5, -1.0, 0.0],
                  [0.5, 0.0, 1e-300], [0.5, 0.0, 1.0]])
    tris = np.array([[0, 1, 2]])
    edges = np.array([[3, 4], [5, 6]])
    assert _candidates(x, edges, tris) == {(0, 0)}  # (1, 0): z-boxes [1e-300, 1] vs [0, 0]
    np.testing.assert_array_equal(find_intersections(x, edges, tris), [[0, 0]])


def test_shared_vertices_and_empty_inputs():
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, -1], [0.2, 0.2, 1]], float)
    tris = np.array([[0, 1, 2]])
    assert _candidates(x, np.array([[0, 4], [3, 4]]), tris) == {(1, 0)}
    none = np.zeros((0, 2), np.int64)
    assert K.edge_triangle_candidates(x, none, tris, none[:, 0], none[:, 0]).shape == (0, 2)
    assert K.edge_triangle_candidates(x, np.array([[3, 4]]), np.zeros((0, 3), np.int64),
                                      none[:, 0], none[:, 0]).shape == (0, 2)


def test_edges_of_triangles_is_the_surface_unique_edges():
    rng = np.random.default_rng(3)
    tris = rng.integers(0, 30, (80, 3))
    got = edges_of_triangles(tris)
    np.testing.assert_array_equal(got, unique_edges(tris))
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    np.testing.assert_array_equal(got, np.unique(e, axis=0))  # the checker's former result
    assert edges_of_triangles(np.zeros((0, 3), np.int64)).shape == (0, 2)
