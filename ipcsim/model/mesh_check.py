"""What every mesh reader checks before a mesh is used: a ``MeshError`` naming the file
(and the scene line that asked for it) instead of a body with no surface, a vertex index
that silently wraps around, or an overflow far downstream.

* coordinates: finite and at most :data:`MAX_COORDINATE` in size (beyond that, volumes
  and barrier distances overflow or lose every digit);
* indices: every cell names vertices of the file; in an ASCII Gmsh file every node tag an
  element names is a node of the file (meshio maps tag 0 or a negative tag onto some other
  node by Python's negative indexing, so this is read from the file itself);
* tetrahedra: positive volume, no two with the same four vertices, no face shared by more
  than two of them or by two on the same side of it (they would overlap), and so a
  boundary that is closed and consistently oriented, with at least one triangle;
* triangle surfaces: at least one triangle, no triangle that repeats a vertex;
* triangle meshes of a 2D scene: in the plane z = 0, every triangle of non-negligible
  area (turned counter-clockwise where the file has it clockwise), no two with the same
  three vertices, every edge in at most two triangles and on opposite sides of it (else
  they overlap), so that the boundary is made of closed curves;
* segments: none that joins a vertex to itself.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import MeshError
from .gmsh import GmshText
from .gmsh import parse as parse_gmsh
from .surface import (TET_FACES, _row_keys, boundary_triangles, tet_signed_volumes,
                      triangle_signed_areas)

__all__ = [
    "MAX_COORDINATE",
    "check_gmsh_tags",
    "check_indices",
    "check_planar",
    "check_triangle_mesh",
    "check_points",
    "check_segments",
    "check_tet_mesh",
    "check_triangles",
]

MAX_COORDINATE = 1e9  # metres, or whatever unit the file is in before the shape's scale


def _err(path, line, message: str) -> MeshError:
    return MeshError(path, line, message)


def check_points(points, path, line, *, bound: float | None = MAX_COORDINATE,
                 what: str = "vertices") -> np.ndarray:
    """(n, 3) float64 with finite coordinates of at most ``bound`` in size (None: any
    finite size), else MeshError. A planar (n, 2) array gets z = 0."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise _err(path, line, f"expected 3-D vertex coordinates, got shape {p.shape}")
    if p.shape[1] == 2:  # planar file: z = 0
        p = np.concatenate([p, np.zeros((len(p), 1))], axis=1)
    bad = ~np.all(np.isfinite(p), axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise _err(path, line, f"{int(bad.sum())} {what} have NaN/inf coordinates "
                               f"(first: vertex {i + 1})")
    if bound is not None and p.size and np.abs(p).max() > bound:
        far = np.abs(p).max(axis=1) > bound
        i = int(np.flatnonzero(far)[0])
        raise _err(path, line, f"{int(far.sum())} {what} lie beyond {bound:.0e} from the "
                               f"origin (first: vertex {i + 1} at {p[i].tolist()}); no scene "
                               "is that large: is the file in another unit?")
    return np.ascontiguousarray(p)


def check_indices(cells, n_points: int, path, line, what: str) -> np.ndarray:
    """Connectivity with every index in [0, n_points), else MeshError (reported 1-based);
    ``what`` names one cell ('tet', 'triangle', 'segment')."""
    c = np.asarray(cells, dtype=np.int64)
    if c.size and (c.min() < 0 or c.max() >= n_points):
        bad = np.flatnonzero(np.any((c < 0) | (c >= n_points), axis=1))
        raise _err(path, line, f"{len(bad)} {what}s reference vertices outside 1..{n_points} "
                               f"(first: {what} {bad[0] + 1})")
    return c


def check_tet_mesh(points: np.ndarray, tets: np.ndarray, path, line) -> None:
    """Every tet positively oriented with non-negligible volume, no duplicate tets, every
    face in at most two tets and on opposite sides of it, a non-empty closed boundary."""
    if len(tets) == 0:
        raise _err(path, line, "no tetrahedra in mesh")
    _check_volumes(points, tets, path, line)
    keys = _row_keys(np.sort(tets, axis=1))
    _, first, counts = np.unique(keys, return_index=True, return_counts=True)
    if (counts > 1).any():
        dup = int(np.sort(first[counts > 1])[0])
        raise _err(path, line, f"{int((counts - 1).sum())} tetrahedra repeat another one's "
                               f"four vertices (first: tet {dup + 1}, vertices "
                               f"{(tets[dup] + 1).tolist()}); the body would have no surface")
    _check_faces(tets, path, line)
    _check_boundary(boundary_triangles(tets), path, line)


def _check_volumes(points, tets, path, line) -> None:
    """Degenerate: 6|V| <= 1e-12 * (longest edge)^3 (repeated vertices, flat slivers);
    inverted: det[x1 - x0, x2 - x0, x3 - x0] < 0."""
    vol6 = 6.0 * tet_signed_volumes(points, tets)
    x = points[tets]  # (m, 4, 3)
    pairs = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    longest = np.linalg.norm(x[:, pairs[:, 0]] - x[:, pairs[:, 1]], axis=2).max(axis=1)
    degenerate = np.abs(vol6) <= 1e-12 * longest**3
    inverted = (vol6 < 0) & ~degenerate
    if degenerate.any():
        i = int(np.flatnonzero(degenerate)[0])
        raise _err(path, line, f"{int(degenerate.sum())} tetrahedra have zero volume "
                               f"(first: tet {i + 1}, vertices {(tets[i] + 1).tolist()})")
    if inverted.any():
        i = int(np.flatnonzero(inverted)[0])
        raise _err(path, line, f"{int(inverted.sum())} tetrahedra are inverted (negative volume; "
                               f"first: tet {i + 1}, vertices {(tets[i] + 1).tolist()})")


def _permutation_parity(rows: np.ndarray) -> np.ndarray:
    """0 for rows (of three distinct values) that are an even permutation of their sorted
    order, 1 for odd ones: two faces with the same vertices and the same parity have the
    same orientation."""
    a, b, c = rows[:, 0], rows[:, 1], rows[:, 2]
    inversions = (a > b).astype(np.int64) + (a > c) + (b > c)
    return inversions % 2


def _check_faces(tets: np.ndarray, path, line) -> None:
    faces = tets[:, TET_FACES].reshape(-1, 3)  # outward for positively oriented tets
    keys = _row_keys(np.sort(faces, axis=1))
    order = np.argsort(keys, kind="stable")
    _, start, counts = np.unique(keys[order], return_index=True, return_counts=True)
    if (counts > 2).any():
        f = int(order[start[counts > 2][0]])
        raise _err(path, line, f"{int((counts > 2).sum())} faces are shared by more than two "
                               f"tetrahedra (first: vertices {(faces[f] + 1).tolist()}, in tet "
                               f"{f // 4 + 1}); the tetrahedra overlap")
    pair = start[counts == 2]
    one, two = order[pair], order[pair + 1]
    parity = _permutation_parity(faces)
    same = parity[one] == parity[two]
    if same.any():
        k = int(np.flatnonzero(same)[0])
        raise _err(path, line, f"{int(same.sum())} faces have their two tetrahedra on the same "
                               f"side (first: tets {one[k] // 4 + 1} and {two[k] // 4 + 1}); "
                               "the tetrahedra overlap")


def _check_boundary(triangles: np.ndarray, path, line) -> None:
    """A boundary that is a closed, consistently oriented surface: every directed edge is
    met exactly as often as its reverse."""
    if len(triangles) == 0:
        raise _err(path, line, "the tetrahedra have no boundary faces (no surface to collide)")
    directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                               triangles[:, [2, 0]]])
    top = int(directed.max()) + 1
    forward = np.sort(directed[:, 0] * top + directed[:, 1])
    backward = np.sort(directed[:, 1] * top + directed[:, 0])
    if not np.array_equal(forward, backward):
        raise _err(path, line, "the boundary of the tetrahedra is not a closed, consistently "
                               "oriented surface")


def check_triangles(points: np.ndarray, triangles: np.ndarray, path, line) -> None:
    """A usable triangle surface: at least one triangle, no repeated vertex in a face."""
    if len(triangles) == 0:
        raise _err(path, line, "no triangles in surface mesh")
    t = np.sort(triangles, axis=1)
    rep = (t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2])
    if rep.any():
        i = int(np.flatnonzero(rep)[0])
        raise _err(path, line, f"{int(rep.sum())} degenerate triangles with a repeated vertex "
                               f"(first: face {i + 1})")


def check_planar(points: np.ndarray, path, line) -> None:
    """A 2D scene's mesh lies in the plane z = 0."""
    off = points[:, 2] != 0.0
    if off.any():
        i = int(np.flatnonzero(off)[0])
        raise _err(path, line, f"{int(off.sum())} vertices are off the plane z = 0 (first: "
                               f"vertex {i + 1}, z = {points[i, 2]!r}); a 2D scene's meshes "
                               "lie in that plane")


def check_triangle_mesh(points: np.ndarray, triangles: np.ndarray, path, line) -> np.ndarray:
    """The triangles of a 2D body (module docstring), returned counter-clockwise."""
    if len(triangles) == 0:
        raise _err(path, line, "no triangles in mesh")
    area2 = 2.0 * triangle_signed_areas(points, triangles)
    x = points[triangles][:, :, :2]
    longest = np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2).max(axis=1)
    flat = np.abs(area2) <= 1e-12 * longest**2
    if flat.any():
        i = int(np.flatnonzero(flat)[0])
        raise _err(path, line, f"{int(flat.sum())} triangles have zero area (first: triangle "
                               f"{i + 1}, vertices {(triangles[i] + 1).tolist()})")
    tris = np.where((area2 < 0)[:, None], triangles[:, [0, 2, 1]], triangles)
    _, first, counts = np.unique(_row_keys(np.sort(tris, axis=1)), return_index=True,
                                 return_counts=True)
    if (counts > 1).any():
        dup = int(np.sort(first[counts > 1])[0])
        raise _err(path, line, f"{int((counts - 1).sum())} triangles repeat another one's "
                               f"three vertices (first: triangle {dup + 1})")
    directed = np.stack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]],
                        axis=1).reshape(-1, 2)
    _, counts = np.unique(_row_keys(directed), return_counts=True)
    _, undirected = np.unique(_row_keys(np.sort(directed, axis=1)), return_counts=True)
    if (counts > 1).any() or (undirected > 2).any():
        raise _err(path, line, "triangles overlap: an edge is shared by more than two "
                               "triangles, or by two on the same side of it")
    return np.ascontiguousarray(tris, dtype=np.int64)


def check_segments(edges: np.ndarray, path, line) -> None:
    """At least one segment, none joining a vertex to itself."""
    if len(edges) == 0:
        raise _err(path, line, "no segments ('s i j' lines) in segment mesh")
    loops = edges[:, 0] == edges[:, 1]
    if loops.any():
        i = int(np.flatnonzero(loops)[0])
        raise _err(path, line, f"degenerate segment {i + 1} joins a vertex to itself")


# ----------------------------------------------------------------------------- Gmsh tags


def check_gmsh_tags(path, line, parsed: GmshText | None = None) -> None:
    """In an ASCII Gmsh file (MSH 2.2 or 4.1), every node tag is positive and every node
    an element names is a node of the file. Binary files are left to meshio. ``parsed``:
    the file as ``gmsh.parse`` read it (else it is read here)."""
    if parsed is None:
        try:
            text = Path(path).read_text(encoding="utf-8", errors="replace")
        except OSError:
            return  # the reader itself reports why the file cannot be read
        parsed = parse_gmsh(text)
    if parsed is None:
        return  # binary or malformed: meshio's reader names the problem
    node_tags = parsed.node_tags
    if len(node_tags) and node_tags.min() < 1:
        raise _err(path, line, f"node tag {int(node_tags.min())} in $Nodes: Gmsh node tags "
                               "are positive")
    for _, block in parsed.blocks:
        used = block[:, 1:]
        missing = ~np.isin(used, node_tags)
        if missing.any():
            r = int(np.flatnonzero(missing.any(axis=1))[0])
            tag = int(used[r][missing[r]][0])
            raise _err(path, line, f"element {int(block[r, 0])} names node tag {tag}, which "
                                   f"is not a node of the file ($Nodes has {len(node_tags)} "
                                   "nodes)")
