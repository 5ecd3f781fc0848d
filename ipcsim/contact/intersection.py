"""Exact intersection and inversion checks for a frame, independent of the barrier.

IPC promises that no surface edge crosses a surface triangle and that no tet inverts.
These functions verify a frame with exact predicates (see ``ipcsim.kernels.contact.intersection``)
so a run can be checked without trusting the method being checked.

Semantics
---------
- An edge and a triangle *intersect* when the closed segment and the closed triangle share
  a point: crossing, touching (distance exactly 0) and coplanar overlap all count.
- Pairs that share a vertex index are skipped (adjacent primitives meet at that vertex by
  construction); an edge folded over an adjacent triangle is therefore not reported.
- A tet is *inverted* when its exact orientation det[b - a, c - a, d - a] is <= 0 (zero
  volume counts as inverted: it is degenerate).
"""

from __future__ import annotations

from msgspec import Struct
import numpy as np

from ipcsim.kernels.contact import intersection as _k
from ipcsim.model.surface import unique_edges

COPLANAR = 2
TRANSVERSAL = 1


def _positions(x) -> np.ndarray:
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"positions must have shape (n, 3), got {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError("positions contain NaN or infinity")
    return x


def _connectivity(a, width: int, n: int, name: str) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.int64)
    if a.size == 0:
        return a.reshape(0, width)
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"{name} must have shape (m, {width}), got {a.shape}")
    if a.min() < 0 or a.max() >= n:
        raise ValueError(f"{name} refer to vertices outside 0..{n - 1}")
    return a


def edges_of_triangles(triangles) -> np.ndarray:
    """The unique undirected edges (i < j) of a triangle list, sorted
    (``model.surface.unique_edges``)."""
    return unique_edges(triangles)


def find_intersections(
    x,
    edges,
    triangles,
    edge_body=None,
    triangle_body=None,
    *,
    return_kinds: bool = False,
):
    """Every (edge index, triangle index) whose closed segment meets the closed triangle,
    over pairs that share no vertex index, as a (k, 2) int64 array sorted by edge then
    triangle.

    ``edge_body`` / ``triangle_body`` (give both or neither): a body id per edge and per
    triangle; pairs within one body are skipped (a scene with self-collision off).
    With ``return_kinds`` also returns a (k,) int8 array: 1 transversal, 2 coplanar
    (segment in the triangle's plane, or a degenerate triangle).
    """
    x = _positions(x)
    n = x.shape[0]
    edges = _connectivity(edges, 2, n, "edges")
    triangles = _connectivity(triangles, 3, n, "triangles")
    if (edge_body is None) != (triangle_body is None):
        raise ValueError("give both edge_body and triangle_body, or neither")
    if edge_body is None:
        eb = tb = np.zeros(0, dtype=np.int64)
    else:
        eb = np.ascontiguousarray(edge_body, dtype=np.int64)
        tb = np.ascontiguousarray(triangle_body, dtype=np.int64)
        if eb.shape != (len(edges),) or tb.shape != (len(triangles),):
            raise ValueError("edge_body / triangle_body need one entry per edge / triangle")
        if len(eb) == 0:  # an empty array means "no body filter" to the kernel
            tb = eb
    pairs = _k.edge_triangle_candidates(x, edges, triangles, eb, tb)
    kinds = _k.classify_edge_triangle_pairs(x, edges, triangles, pairs)
    hit = kinds > 0
    pairs, kinds = pairs[hit], kinds[hit]
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
    pairs, kinds = pairs[order], kinds[order]
    return (pairs, kinds) if return_kinds else pairs


def _tet_orientations(x, tets):
    x = _positions(x)
    tets = _connectivity(tets, 4, x.shape[0], "tets")
    signs = np.empty(len(tets), dtype=np.int8)
    volumes = np.empty(len(tets), dtype=np.float64)
    if len(tets):
        _k.tet_orientations(x, tets, signs, volumes)
    return signs, volumes


def inverted_tets(x, tets) -> np.ndarray:
    """Indices of tets whose exact orientation det[b-a, c-a, d-a] is <= 0."""
    signs, _ = _tet_orientations(x, tets)
    return np.flatnonzero(signs <= 0)


def count_inverted_tets(x, tets) -> int:
    """Number of tets with exact orientation <= 0 (inverted or flat)."""
    signs, _ = _tet_orientations(x, tets)
    return int(np.count_nonzero(signs <= 0))


class FrameCheck(Struct, frozen=True, eq=False):
    """What ``check_frame`` found in one frame (``ok`` when nothing is wrong)."""

    n_intersections: int  # intersecting (edge, triangle) pairs
    first_pairs: np.ndarray  # (<= max_pairs, 2) of them
    n_coplanar: int  # how many of those are coplanar overlaps
    n_inverted: int  # tets with orientation <= 0
    first_inverted: np.ndarray
    min_signed_volume: float  # float, smallest det/6 over tets (inf without tets)
    n_nonfinite: int = 0  # vertices with NaN/inf coordinates; other counts are then -1

    @property
    def ok(self) -> bool:
        return self.n_nonfinite == 0 and self.n_intersections == 0 and self.n_inverted == 0

    def summary(self) -> str:
        if self.n_nonfinite:
            return f"{self.n_nonfinite} vertices with non-finite coordinates"
        parts = [f"{self.n_intersections} intersecting edge-triangle pairs"]
        if self.n_intersections:
            shown = ", ".join(f"(e{e}, t{t})" for e, t in self.first_pairs)
            parts[0] += f" ({self.n_coplanar} coplanar; first: {shown})"
        parts.append(f"{self.n_inverted} inverted tets")
        parts.append(f"min signed volume {self.min_signed_volume:.6g}")
        return "; ".join(parts)


def check_frame(
    points,
    tets,
    surface_triangles,
    surface_edges=None,
    *,
    edge_body=None,
    triangle_body=None,
    max_pairs: int = 10,
) -> FrameCheck:
    """Check one frame: exact edge-triangle intersections among the surface primitives and
    exact tet orientations. ``surface_edges`` defaults to the edges of the triangles; the
    body arrays are passed to ``find_intersections``."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    bad = int(np.count_nonzero(~np.isfinite(points).all(axis=1))) if points.size else 0
    empty = np.zeros((0, 2), dtype=np.int64)
    if bad:
        return FrameCheck(-1, empty, -1, -1, np.zeros(0, np.int64), float("nan"), bad)
    if surface_edges is None:
        surface_edges = edges_of_triangles(surface_triangles)
    pairs, kinds = find_intersections(
        points, surface_edges, surface_triangles, edge_body, triangle_body, return_kinds=True
    )
    tets = np.zeros((0, 4), np.int64) if tets is None else tets
    signs, volumes = _tet_orientations(points, tets)
    inverted = np.flatnonzero(signs <= 0)
    return FrameCheck(
        n_intersections=len(pairs),
        first_pairs=pairs[:max_pairs],
        n_coplanar=int(np.count_nonzero(kinds == COPLANAR)),
        n_inverted=len(inverted),
        first_inverted=inverted[:max_pairs],
        min_signed_volume=float(volumes.min()) if len(volumes) else float("inf"),
    )
