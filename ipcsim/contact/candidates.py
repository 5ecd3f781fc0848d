"""Broad-phase candidates: point-triangle (PT) and edge-edge (EE) pairs whose boxes overlap.

Two uses:

* the active set at positions x: every box is grown by ``inflation / 2`` (pass d̂), so a pair is
  a candidate when its two primitives' boxes are at most d̂ apart on every axis, which holds
  for every pair closer than d̂;
* CCD over a step x -> x1 (``x1=...``): each box covers both positions of its vertices, so it
  holds the whole linear trajectory of the primitive; ``inflation`` is then a small margin.

Pairs that share a vertex are never candidates. With ``self_collision=False`` only pairs of
primitives from different bodies remain (the body of a primitive is that of its first vertex).
Pairs whose primitives are both kinematic (every vertex kinematic) are dropped.
The method (a BVH over Morton-ordered boxes) lives in ``ipcsim.kernels.broad_phase``.
"""

from __future__ import annotations

import numpy as np

from ..kernels import broad_phase as _bp


def _index_array(a, cols, name):
    a = np.ascontiguousarray(a, dtype=np.int64)
    if a.size == 0:
        return a.reshape(0, cols)
    if a.ndim != 2 or a.shape[1] != cols:
        raise ValueError(f"{name} must be an (m, {cols}) integer array")
    return a


def find_candidates(x, surface_vertices, edges, triangles, inflation, body_of_vertex=None,
                    self_collision=True, kinematic_vertex_mask=None, *, x1=None,
                    return_indices=False):
    """Candidate pairs at positions ``x`` (or swept over ``x -> x1``).

    Parameters: ``x (n, 3)`` positions of all vertices; ``surface_vertices (nv,)``,
    ``edges (ne, 2)`` and ``triangles (nt, 3)`` in global vertex numbers; ``inflation`` ≥ 0;
    ``body_of_vertex (n,)`` body id of each vertex (default: one body); ``self_collision``;
    ``kinematic_vertex_mask (n,)`` bool (default: none kinematic).

    Returns ``(pt_pairs, ee_pairs)``, int64 arrays of rows ``(p, t0, t1, t2)`` and
    ``(ea0, ea1, eb0, eb1)``. With ``return_indices=True`` also ``(pt_index, ee_index)``:
    rows (index into surface_vertices, triangle index) and (edge a, edge b) with a < b.
    """
    x0 = np.ascontiguousarray(x, dtype=np.float64)
    xs = x0 if x1 is None else np.ascontiguousarray(x1, dtype=np.float64)
    if x0.ndim != 2 or x0.shape[1] != 3 or xs.shape != x0.shape:
        raise ValueError("positions must be (n, 3) arrays of equal shape")
    if not inflation >= 0.0:
        raise ValueError("inflation must be >= 0")
    n = x0.shape[0]
    points = _index_array(np.asarray(surface_vertices).reshape(-1, 1), 1, "surface_vertices")
    edges = _index_array(edges, 2, "edges")
    triangles = _index_array(triangles, 3, "triangles")
    body = (np.zeros(n, np.int64) if body_of_vertex is None
            else np.ascontiguousarray(body_of_vertex, dtype=np.int64))
    kin = (np.zeros(n, np.bool_) if kinematic_vertex_mask is None
           else np.ascontiguousarray(kinematic_vertex_mask, dtype=np.bool_))
    if body.shape != (n,) or kin.shape != (n,):
        raise ValueError("body_of_vertex and kinematic_vertex_mask need one entry per vertex")
    for prims in (points, edges, triangles):
        if prims.size and (prims.min() < 0 or prims.max() >= n):
            raise ValueError("vertex index out of range")

    r = float(inflation)
    point_tags = _bp.primitive_tags(points, body, kin)
    edge_tags = _bp.primitive_tags(edges, body, kin)
    tri_tags = _bp.primitive_tags(triangles, body, kin)
    point_boxes = _bp.primitive_boxes(x0, xs, points, r)
    edge_boxes = _bp.primitive_boxes(x0, xs, edges, r)
    tri_boxes = _bp.primitive_boxes(x0, xs, triangles, r)

    tri_tree = _bp.build_bvh(tri_boxes) + (triangles, tri_tags)
    pt_index = _bp.query_bvh((point_boxes, points, point_tags), tri_tree, False,
                             bool(self_collision))
    edge_tree = _bp.build_bvh(edge_boxes) + (edges, edge_tags)
    ee_index = _bp.query_bvh((edge_boxes, edges, edge_tags), edge_tree, True,
                             bool(self_collision))
    pt_pairs = _bp.gather_rows(points, triangles, pt_index)
    ee_pairs = _bp.gather_rows(edges, edges, ee_index)
    if return_indices:
        return pt_pairs, ee_pairs, pt_index, ee_index
    return pt_pairs, ee_pairs
