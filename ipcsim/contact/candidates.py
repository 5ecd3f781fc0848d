"""Broad-phase candidates: point-triangle (PT) and edge-edge (EE) pairs whose boxes overlap.

Two uses:

* the active set at positions x: every box is grown by ``inflation / 2`` (pass d̂), so a pair is
  a candidate when its two primitives' boxes are at most d̂ apart on every axis, which holds
  for every pair closer than d̂;
* CCD over a step x -> x1 (``x1=...``): each box covers both positions of its vertices, so it
  holds the whole linear trajectory of the primitive; ``inflation`` is then a small margin.

Pairs that share a vertex are never candidates, and the collision mesh's filters apply (body
ids, self collision, kinematic–kinematic pairs; see ``CollisionMesh``). The method (a BVH over
Morton-ordered boxes) lives in ``ipcsim.kernels.contact.broad_phase``.
"""

from __future__ import annotations

import numpy as np

from ..kernels.contact import broad_phase as _bp
from .collision_mesh import CollisionMesh


def find_candidates(mesh: CollisionMesh, x, inflation: float, *, x1=None,
                    return_indices: bool = False):
    """Candidate pairs of ``mesh`` at positions ``x (n, 3)`` (or swept over ``x -> x1``).

    Returns ``(pt_pairs, ee_pairs)``, int64 arrays of rows ``(p, t0, t1, t2)`` and
    ``(ea0, ea1, eb0, eb1)``. With ``return_indices=True`` also ``(pt_index, ee_index)``:
    rows (index into mesh.vertices, triangle index) and (edge a, edge b) with a < b.
    """
    x0 = np.ascontiguousarray(x, dtype=np.float64)
    xs = x0 if x1 is None else np.ascontiguousarray(x1, dtype=np.float64)
    if x0.ndim != 2 or x0.shape[1] != 3 or xs.shape != x0.shape:
        raise ValueError("positions must be (n, 3) arrays of equal shape")
    if x0.shape[0] != mesh.n_vertices:
        raise ValueError(f"positions have {x0.shape[0]} vertices, the mesh {mesh.n_vertices}")
    if not inflation >= 0.0:
        raise ValueError("inflation must be >= 0")
    pt_pairs, ee_pairs, pt_index, ee_index = _bp.candidate_pairs(
        x0, xs, mesh.vertices.reshape(-1, 1), mesh.edges, mesh.triangles, mesh.tags,
        float(inflation), mesh.self_collision)
    if return_indices:
        return pt_pairs, ee_pairs, pt_index, ee_index
    return pt_pairs, ee_pairs
