"""The collision set: mesh pairs close enough to matter, as one value.

``build_collisions(mesh, x, d̂)`` gives the point–triangle and edge–edge candidates at x
(boxes grown by d̂, so every pair closer than d̂ is among them), the edge–edge mollifier
thresholds ε_x (from rest positions) and each pair's closest-feature type and squared
distance at x. ``swept_collisions`` gives the candidates over a motion x -> x1 (every pair
that comes within d̂ anywhere on it), which is what a line search's energies need.

The barrier sums over every candidate without merging duplicates, which equals the IPC
Toolkit's merged, weighted set: pairs farther than d̂ contribute nothing.

A planar mesh (a 2D scene) has one kind of pair, a point against an edge: its set holds
them where point–triangle pairs are (``pt`` (k, 3) rows (p, e0, e1), ids
point·n_edges + edge, their types and distances as ``pt_type``, ``pt_d2``) and no
edge–edge pairs.
"""

from __future__ import annotations

import math
from functools import cached_property

from msgspec import Struct
import numpy as np

from ..kernels.contact.broad_phase import point_edge_candidate_pairs
from ..kernels.contact.pair_barrier import active_pairs, classify_and_distance, near_pairs
from ..kernels.contact.point_edge_barrier import pe_classify_and_distance, pe_near_pairs
from ..kernels.contact.mollifier import edge_edge_mollifier_thresholds
from .candidates import find_candidates
from .collision_mesh import CollisionMesh


class PairDistances(Struct, frozen=True, eq=False):
    """Closest-feature type (ipctk's enum codes) and squared distance of every pair."""

    pt_type: np.ndarray  # (k,) int64
    pt_d2: np.ndarray  # (k,)
    ee_type: np.ndarray  # (j,) int64
    ee_d2: np.ndarray  # (j,)


class MeshContactCount(Struct, frozen=True):
    """Active mesh contacts at one x, by kind, and the closest distance."""

    point_triangle: int  # active pairs: d² < d̂²
    edge_edge: int
    min_distance: float  # smallest distance over the candidates (inf without any)


class Collisions(Struct, frozen=True, eq=False, dict=True):
    """Candidate pairs (rows of global vertex numbers): pt (k, 4) = (p, t0, t1, t2),
    ee (j, 4) = (ea0, ea1, eb0, eb1), with ee_eps_x (j,) their mollifier thresholds, the
    distances at the positions they were found at (None for a swept set) and each pair's
    id in its mesh (``pair_ids``; None where the pairs came from elsewhere)."""

    pt: np.ndarray
    ee: np.ndarray
    ee_eps_x: np.ndarray
    distances: PairDistances | None = None
    pt_id: np.ndarray | None = None
    ee_id: np.ndarray | None = None

    @staticmethod
    def empty() -> "Collisions":
        z = np.zeros((0, 4), dtype=np.int64)
        return Collisions(z, z, np.zeros(0), None, np.zeros(0, np.int64),
                          np.zeros(0, np.int64))

    def __len__(self) -> int:
        return len(self.pt) + len(self.ee)

    def may_be_active(self, dhat: float) -> bool:
        """False when the distances show no pair closer than d̂ (at the positions the set
        was found at); True when some is, or when the set has no distances (swept)."""
        if self.distances is None:
            return len(self) > 0
        return self._min_d2 < dhat * dhat

    @cached_property
    def _min_d2(self) -> float:
        """The smallest squared distance at the positions found at (inf without pairs);
        asked by each term at each evaluation, so found once."""
        d = self.distances
        return float(active_pairs(d.pt_d2, d.ee_d2, 0.0)[2])

    def count(self, dhat: float) -> MeshContactCount:
        """Active pairs and the smallest distance (needs the distances)."""
        d = self.distances
        n_pt, n_ee, min_d2 = active_pairs(d.pt_d2, d.ee_d2, float(dhat) * float(dhat))
        return MeshContactCount(int(n_pt), int(n_ee), math.sqrt(min_d2))

    def in_canonical_order(self) -> "Collisions":
        """The same pairs, each kind by increasing id (every set this module builds has
        ids): a set found by a fresh query and one narrowed from a sweep then sum the
        barrier in the same order, bit for bit (how a step hands its end's set to the
        next). The ids are unique, so any sort gives the one order."""
        pt_order = np.argsort(self.pt_id)
        ee_order = np.argsort(self.ee_id)
        d = self.distances
        if d is not None:
            d = PairDistances(d.pt_type[pt_order], d.pt_d2[pt_order], d.ee_type[ee_order],
                              d.ee_d2[ee_order])
        return Collisions(self.pt[pt_order], self.ee[ee_order], self.ee_eps_x[ee_order], d,
                          self.pt_id[pt_order], self.ee_id[ee_order])


def pair_ids(mesh: CollisionMesh, pt_index: np.ndarray, ee_index: np.ndarray):
    """One int64 per candidate pair, unique in the mesh: point·n_triangles + triangle for
    (point, triangle), edge_a·n_edges + edge_b for (edge a, edge b)."""
    n_tri, n_edges = len(mesh.triangles), len(mesh.edges)
    return (pt_index[:, 0] * n_tri + pt_index[:, 1],
            ee_index[:, 0] * n_edges + ee_index[:, 1])


def _mollifier_thresholds(mesh: CollisionMesh, ee) -> np.ndarray:
    return edge_edge_mollifier_thresholds(mesh.rest, ee) if len(ee) else np.zeros(0)


_NO_EE = np.zeros((0, 4), dtype=np.int64)


def _point_edge_pairs(mesh: CollisionMesh, x0, x1, inflation: float):
    """(pairs (k, 3), ids) of a planar mesh whose boxes over x0 -> x1 grown by
    inflation / 2 overlap."""
    pe, index = point_edge_candidate_pairs(
        np.ascontiguousarray(x0, dtype=float), np.ascontiguousarray(x1, dtype=float),
        mesh.vertices.reshape(-1, 1), mesh.edges, mesh.tags[:2], float(inflation),
        bool(mesh.self_collision))
    return pe, index[:, 0] * len(mesh.edges) + index[:, 1]


def _planar_set(pe, ids, distances) -> Collisions:
    return Collisions(pe, _NO_EE, np.zeros(0), distances, ids, np.zeros(0, np.int64))


def _planar_distances(types, d2) -> PairDistances:
    return PairDistances(types, d2, np.zeros(0, np.int64), np.zeros(0))


def build_collisions(mesh: CollisionMesh, x: np.ndarray, dhat: float) -> Collisions:
    """Every pair of ``mesh`` that may be closer than d̂ at x, with its distance at x."""
    if mesh.planar:
        pe, ids = _point_edge_pairs(mesh, x, x, dhat)
        return _planar_set(pe, ids, _planar_distances(*pe_classify_and_distance(x, pe)))
    pt, ee, pt_index, ee_index = find_candidates(mesh, x, dhat, return_indices=True)
    distances = PairDistances(*classify_and_distance(x, pt, ee))
    return Collisions(pt, ee, _mollifier_thresholds(mesh, ee), distances,
                      *pair_ids(mesh, pt_index, ee_index))


def narrowed_collisions(swept: Collisions, x: np.ndarray, dhat: float) -> Collisions:
    """``build_collisions`` at x, taken from a set swept over a motion that passes
    through x (a point x0 + α(x1 − x0) of it, α in [0, 1], computed as x0 + α·p, or one
    within the reach the sweep's boxes were grown by): the
    swept boxes hold x's boxes, so the pairs whose boxes overlap at x are all there, and
    the same box test keeps exactly those, without a new BVH query. Only the order of
    the pairs may differ from a fresh query's. The swept set has its pairs' ids, as
    every set this module builds."""
    if swept.pt.shape[1] == 3:  # point–edge pairs
        pe, _, ids, types, d2 = pe_near_pairs(x, swept.pt, np.zeros(len(swept.pt)),
                                              swept.pt_id, dhat)
        return _planar_set(pe, ids, _planar_distances(types, d2))
    pt, ee, eps_x, pt_id, ee_id, *distances = near_pairs(
        x, swept.pt, swept.ee, swept.ee_eps_x, swept.pt_id, swept.ee_id, dhat)
    return Collisions(pt, ee, eps_x, PairDistances(*distances), pt_id, ee_id)


def swept_collisions(mesh: CollisionMesh, x0: np.ndarray, x1: np.ndarray,
                     dhat: float) -> Collisions:
    """Every pair that may come within d̂ while the vertices move linearly x0 -> x1."""
    if mesh.planar:
        return _planar_set(*_point_edge_pairs(mesh, x0, x1, dhat), None)
    pt, ee, pt_index, ee_index = find_candidates(mesh, x0, dhat, x1=x1, return_indices=True)
    return Collisions(pt, ee, _mollifier_thresholds(mesh, ee), None,
                      *pair_ids(mesh, pt_index, ee_index))


def pair_distances(x: np.ndarray, collisions: Collisions) -> PairDistances:
    """Types and squared distances of a set's pairs at x."""
    if collisions.pt.shape[1] == 3:
        return _planar_distances(*pe_classify_and_distance(x, collisions.pt))
    return PairDistances(*classify_and_distance(x, collisions.pt, collisions.ee))
