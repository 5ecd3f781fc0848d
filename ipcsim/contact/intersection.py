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
- A connected part of the mesh (its vertices connected through tets and triangles) lies
  *inside* another when one of its vertices is strictly inside the other's closed
  surface: a solid inside a solid intersects it, though no surface crosses (a cube
  placed wholly in a bigger one, two nested parts of one mesh). Containers are the parts
  whose triangles make a closed, consistently oriented surface: a tet mesh's boundary
  (every part of it, a cavity's wall too, so a body in a hollow body's cavity is not
  inside it) and closed ``.obj`` surfaces, whose solid side is the one their normals
  point away from (an inward-facing room holds no solid). Open surfaces, segments and
  points contain nothing. Where no surface crosses another, a part is inside another
  wholly or not at all, so one vertex of each part is tested: by the winding number of
  the container's triangles about it (solid angles summed, the sign of each from the
  exact ``orient3d``), which rounds safely since the vertex is off the surface (a
  vertex on a surface is contact, found by the edge-triangle test).
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
    if not a.flags.writeable:  # a Model's arrays: the compiled kernels take writeable ones
        a = a.copy()
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


def crossing_edges_2d(x, edges, body=None) -> np.ndarray:
    """Pairs (i, j), i < j, of the edges (k, 2) of a 2D scene (z = 0) that share a point
    (exact), among edges that share no vertex; with ``body`` (one id per vertex) only
    pairs of two bodies count."""
    x = _positions(x)
    edges = _connectivity(edges, 2, x.shape[0], "edges")
    pairs = _k.edge_edge_candidates_2d(x, edges)
    if body is not None and len(pairs):
        body = np.asarray(body)
        pairs = pairs[body[edges[pairs[:, 0], 0]] != body[edges[pairs[:, 1], 0]]]
    pairs = pairs[_k.crossing_edge_pairs_2d(x, edges, pairs)] if len(pairs) else pairs
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
    return pairs[order]


def inverted_triangles(x, triangles) -> np.ndarray:
    """Indices of the triangles of a 2D scene whose exact orientation is <= 0 (inverted
    or flat)."""
    x = _positions(x)
    triangles = _connectivity(triangles, 3, x.shape[0], "triangles")
    signs = np.empty(len(triangles), dtype=np.int8)
    areas = np.empty(len(triangles))
    if len(triangles):
        _k.triangle_orientations(x, triangles, signs, areas)
    return np.flatnonzero(signs <= 0)


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


class Solids(Struct, frozen=True, eq=False):
    """The connected parts of a mesh and which of them can contain others (built once
    per mesh by :func:`solids_of`; positions change, connectivity does not)."""

    labels: np.ndarray  # (n,) the part of each vertex, -1 for a vertex in no cell
    representatives: np.ndarray  # (k,) one vertex of each part (its lowest)
    triangles: np.ndarray  # (t, 3) every triangle given
    triangle_part: np.ndarray  # (t,) the part of each triangle
    closed: np.ndarray  # (k,) bool: its triangles make a closed, oriented surface


def solids_of(n: int, tets, triangles) -> Solids:
    """The parts of a mesh of ``n`` vertices: connected through ``tets`` and
    ``triangles`` (a tet mesh's boundary triangles with outward normals, and surface
    triangles)."""
    # writeable copies of a model's frozen arrays: the types compiled ahead of time
    tets = np.require(_connectivity(tets, 4, n, "tets"), requirements="W")
    triangles = np.require(_connectivity(triangles, 3, n, "triangles"), requirements="W")
    labels = _k.component_labels(n, tets, triangles)
    k = int(labels.max()) + 1 if n else 0
    used = np.flatnonzero(labels >= 0)
    representatives = np.full(k, -1, np.int64)
    representatives[labels[used][::-1]] = used[::-1]  # the lowest vertex of each part
    part = labels[triangles[:, 0]] if len(triangles) else np.zeros(0, np.int64)
    return Solids(labels, representatives, triangles, part, _closed_parts(n, k, triangles,
                                                                            part))


def _closed_parts(n: int, k: int, triangles: np.ndarray, part: np.ndarray) -> np.ndarray:
    """Which of ``k`` parts have triangles that make a closed, consistently oriented
    surface: every edge of them is crossed as often from i to j as from j to i (so the
    winding number about a point off the surface is a whole number)."""
    closed = np.zeros(k, dtype=bool)
    if not len(triangles):
        return closed
    closed[part] = True
    directed = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    keys, inverse = np.unique(lo * np.int64(n) + hi, return_inverse=True)
    balance = np.bincount(inverse, weights=np.where(directed[:, 0] < directed[:, 1], 1, -1),
                          minlength=len(keys))
    closed[np.repeat(part, 3)[balance[inverse] != 0]] = False
    return closed


def find_containments(x, solids: Solids) -> np.ndarray:
    """Every (vertex of a part, vertex of a closed part it lies inside), as a (m, 2)
    int64 array of the parts' representative vertices (module docstring). Meaningful
    where no surface crosses or touches another (``find_intersections`` finds none)."""
    x = _positions(x)
    if len(x) != len(solids.labels):
        raise ValueError(f"positions of {len(x)} vertices for a mesh of {len(solids.labels)}")
    if not solids.closed.any() or len(solids.representatives) < 2:
        return np.zeros((0, 2), np.int64)
    parts = _k.containments(x, solids.representatives, solids.triangles,
                            solids.triangle_part, solids.closed)
    return solids.representatives[parts]


def moving_parts(solids: Solids, kinematic) -> np.ndarray:
    """(k,) bool: the parts with a vertex that is not kinematic (a part of kinematic
    vertices only is an obstacle: two of them are never judged, as two obstacles' crossing
    edges are not)."""
    kinematic = np.asarray(kinematic, dtype=bool)
    moving = np.zeros(len(solids.representatives), dtype=bool)
    moving[solids.labels[(solids.labels >= 0) & ~kinematic]] = True
    return moving


def start_containment(model, mesh, x) -> tuple[int, int] | None:
    """The first (vertex, vertex of the part it lies inside) at the start that IPC must
    refuse, or None: two parts of one shape always (its tets overlap), parts of two
    shapes where they can collide (``mesh``, the collision mesh, or None without mesh
    contact: its body ids say which pairs count), never two obstacles."""
    solids = solids_of(model.n_vertices, model.tets, model.surface_triangles)
    pairs = find_containments(x, solids)
    if not len(pairs):
        return None
    moving = moving_parts(solids, model.always_kinematic)[solids.labels[pairs]].any(axis=1)
    shape = np.asarray(model.vertex_shape)[pairs]
    same_shape = shape[:, 0] == shape[:, 1]
    if mesh is None:
        collide = np.zeros(len(pairs), dtype=bool)
    else:
        body = mesh.body[pairs]
        collide = np.full(len(pairs), bool(mesh.self_collision)) | (body[:, 0] != body[:, 1])
    judged = np.flatnonzero(moving & (same_shape | collide))
    return None if not len(judged) else (int(pairs[judged[0], 0]), int(pairs[judged[0], 1]))
