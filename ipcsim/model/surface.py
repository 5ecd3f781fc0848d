"""Surface extraction: boundary triangles of tet meshes, boundary edges of triangle meshes
(the collision "surface" of a 2D body) and unique edges of triangle sets.

Everything here is vectorised with sort + unique; no Python loop per face.

Boundary triangles follow the original IPC: tet (a, b, c, d) has the four faces
(a, c, b), (a, d, c), (a, b, d), (b, c, d), each oriented so that its normal
(x1 - x0) x (x2 - x0) points out of a positively oriented tet. A face is on the boundary
when no other tet has the same three vertices.
"""

from __future__ import annotations

import numpy as np

# Local vertex indices of the four outward faces of tet (a, b, c, d) = (0, 1, 2, 3).
TET_FACES = np.array([[0, 2, 1], [0, 3, 2], [0, 1, 3], [1, 2, 3]], dtype=np.int64)


def index_set(indices) -> np.ndarray:
    """The distinct entries of an int array of vertex indices, sorted, as ``np.unique``
    gives them, through a mask over 0..max: linear time, and no import of numpy.ma,
    which numpy's ``unique`` makes at its first call (10 ms of a tiny scene's start)."""
    a = np.asarray(indices, dtype=np.int64).ravel()
    if a.size == 0 or a.min() < 0:
        return np.unique(a)
    used = np.zeros(int(a.max()) + 1, dtype=bool)
    used[a] = True
    return np.flatnonzero(used).astype(np.int64, copy=False)


def _row_keys(rows: np.ndarray) -> np.ndarray:
    """One sortable key per row of a small non-negative int array (rows (k, c)).

    Packs the row into one int64 (base n = max + 1) when n^c fits, else views the rows as
    a structured void type; equal rows get equal keys either way.
    """
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    k, c = rows.shape
    if k == 0:
        return np.zeros(0, dtype=np.int64)
    base = int(rows.max()) + 1
    if base ** c < 2**62:
        key = np.zeros(k, dtype=np.int64)
        for j in range(c):  # c <= 3 columns, not a per-element loop
            key = key * base + rows[:, j]  # key = ((r0 * n) + r1) * n + r2
        return key
    return rows.view(np.dtype((np.void, rows.dtype.itemsize * c))).ravel()


def boundary_triangles(tets: np.ndarray) -> np.ndarray:
    """Outward boundary triangles (k, 3) int64 of a tet mesh (m, 4).

    Faces are returned in tet order (tet 0's boundary faces first, then tet 1's, ...),
    each with its vertices in the local order of ``TET_FACES`` (deterministic, unlike the
    original's hash-map order).
    """
    tets = np.asarray(tets, dtype=np.int64).reshape(-1, 4)
    if len(tets) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    faces = tets[:, TET_FACES].reshape(-1, 3)  # (4m, 3), face f of tet t at row 4t + f
    keys = _row_keys(np.sort(faces, axis=1))  # orientation-free identity of a face
    _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    on_boundary = counts[inverse] == 1  # interior faces appear twice (once per side)
    return faces[on_boundary]


def boundary_edges(triangles: np.ndarray) -> np.ndarray:
    """Boundary edges (k, 2) int64 of a triangle mesh (m, 3) in the plane: the edges that
    one triangle alone uses, each directed as in its triangle, so that a counter-clockwise
    triangle has its interior on the left of the edge and the outward normal (dy, −dx) on
    its right. In triangle order (triangle 0's boundary edges first), each triangle's
    edges in the order (0, 1), (1, 2), (2, 0)."""
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(triangles) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    # edge k of triangle t at row 3t + k
    edges = np.stack([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]],
                     axis=1).reshape(-1, 2)
    _, inverse, counts = np.unique(_row_keys(np.sort(edges, axis=1)), return_inverse=True,
                                   return_counts=True)
    return edges[counts[inverse] == 1]


def unique_edges(triangles: np.ndarray) -> np.ndarray:
    """Unique undirected edges (e, 2) int64 of a triangle set, each as (i, j) with i < j,
    sorted lexicographically."""
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(triangles) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    # edges (0,1), (1,2), (2,0) of every triangle
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    return unique_undirected(edges)


def unique_undirected(edges: np.ndarray) -> np.ndarray:
    """Deduplicate undirected edges (e, 2): rows (i, j) with i < j, lexicographically sorted.

    Degenerate edges (i == i) are kept once; callers decide whether they are errors."""
    edges = np.sort(np.asarray(edges, dtype=np.int64).reshape(-1, 2), axis=1)
    if len(edges) == 0:
        return edges
    keys = _row_keys(edges)
    _, first = np.unique(keys, return_index=True)
    out = edges[first]
    return out[np.lexsort((out[:, 1], out[:, 0]))]


def edge_use_counts(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges of a triangle set and how many triangles use each one
    (2 everywhere for a closed manifold surface)."""
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    edges = np.sort(
        np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1
    )
    if len(edges) == 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    _, first, counts = np.unique(_row_keys(edges), return_index=True, return_counts=True)
    return edges[first], counts


def enclosed_volume(points: np.ndarray, triangles: np.ndarray) -> float:
    """Volume enclosed by a closed, outward-oriented triangle surface (divergence theorem):
    V = (1/6) sum_f x0 . (x1 x x2)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(t) == 0:
        return 0.0
    # x0 . (x1 x x2) / 6 is the signed volume of the tet (origin, x0, x1, x2)
    apex = np.vstack([p, np.zeros((1, 3))])
    tets = np.column_stack([np.full(len(t), len(p), dtype=np.int64), t])
    return float(tet_signed_volumes(apex, tets).sum())


def triangle_signed_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Signed areas (m,) of triangles in the plane z = 0: A = det[x1 − x0, x2 − x0] / 2 of
    their x, y parts (``kernels.algebra.linalg.triangle_signed_areas``, for any
    array-like input)."""
    from ..kernels.algebra.linalg import triangle_signed_areas as kernel  # numba: on use

    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    t = np.ascontiguousarray(triangles, dtype=np.int64).reshape(-1, 3)
    return kernel(p, t)


def tet_signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes (m,) of tets: V = det[x1 - x0, x2 - x0, x3 - x0] / 6
    (``kernels.algebra.linalg.tet_signed_volumes``, for any array-like input)."""
    from ..kernels.algebra.linalg import tet_signed_volumes as kernel  # numba: imported on use

    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    t = np.ascontiguousarray(tets, dtype=np.int64).reshape(-1, 4)
    return kernel(p, t)
