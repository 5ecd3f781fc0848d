"""Procedural meshes for tests, benchmarks and the project's own scenes.

``box_tet_mesh`` splits each cell of a regular grid into 6 tets sharing the cell's main
diagonal (Kuhn / Freudenthal subdivision). Every cell is split the same way, so the faces
of neighbouring cells match and the mesh is conforming; all tets are positively oriented.

``rectangle_mesh`` is the 2D counterpart, in the plane z = 0: each cell of a regular grid
split into two triangles, the diagonal alternating from cell to cell (cell (i, j) takes
the diagonal (i, j)-(i+1, j+1) where i + j is even, the other one where it is odd), which
is how the lecture's square_mesh triangulates its squares, with its node numbering
(node (i, j) is i (ny + 1) + j: columns of nodes from left to right). ``rectangle_springs``
gives the springs of its mass-spring squares: every cell side and both cell diagonals.
"""

from __future__ import annotations

from itertools import permutations
from pathlib import Path

import numpy as np

from .surface import tet_signed_volumes

# Kuhn subdivision of the unit cube: for each permutation (a, b, c) of the axes the path
# 0 -> e_a -> e_a + e_b -> (1, 1, 1). Corners are numbered i + 2 j + 4 k.
_AXIS_BIT = (1, 2, 4)
_KUHN = np.array([[0, _AXIS_BIT[a], _AXIS_BIT[a] + _AXIS_BIT[b], 7]
                  for a, b, _ in permutations(range(3))], dtype=np.int64)


def box_tet_mesh(nx: int, ny: int, nz: int, size=(1.0, 1.0, 1.0),
                 origin=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Tet mesh of the box [origin, origin + size] with nx * ny * nz cells of 6 tets.

    Returns (points ((nx+1)(ny+1)(nz+1), 3) float64, tets (6 nx ny nz, 4) int64); vertex
    (i, j, k) has index i + (nx + 1) (j + (ny + 1) k); every tet has positive volume.
    """
    nx, ny, nz = int(nx), int(ny), int(nz)
    if min(nx, ny, nz) < 1:
        raise ValueError("box_tet_mesh needs at least one cell per axis")
    size = np.asarray(size, dtype=np.float64)
    origin = np.asarray(origin, dtype=np.float64)
    if np.any(size <= 0):
        raise ValueError("box size must be positive")
    xs = [np.arange(n + 1) / n for n in (nx, ny, nz)]  # i / n, exact at the ends
    gx, gy, gz = np.meshgrid(*xs, indexing="ij")  # (nx+1, ny+1, nz+1)
    # vertex index i + (nx+1) j + (nx+1)(ny+1) k  <=>  Fortran order of the (i, j, k) grid
    unit = np.stack([gx.ravel(order="F"), gy.ravel(order="F"), gz.ravel(order="F")], axis=1)
    points = origin + unit * size

    sx, sy = nx + 1, (nx + 1) * (ny + 1)
    ci, cj, ck = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    base = (ci + sx * cj + sy * ck).ravel()  # lowest corner of each cell, (cells,)
    # corner c = i + 2 j + 4 k of a cell -> offset i + sx j + sy k
    corner = np.array([(c & 1) + sx * ((c >> 1) & 1) + sy * ((c >> 2) & 1) for c in range(8)])
    tets = (base[:, None, None] + corner[_KUHN][None, :, :]).reshape(-1, 4)

    # orient positively: swap two vertices where det[x1 - x0, x2 - x0, x3 - x0] < 0
    neg = tet_signed_volumes(points, tets) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return points, tets.astype(np.int64)


def write_msh(path, points: np.ndarray, tets: np.ndarray) -> Path:
    """Write a tet mesh (or, given (m, 3) cells, a triangle mesh) as Gmsh MSH 4.1 ASCII
    (through meshio); returns the path."""
    import meshio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cells = np.asarray(tets, dtype=np.int64)
    mesh = meshio.Mesh(np.asarray(points, dtype=np.float64),
                       [("tetra" if cells.shape[1] == 4 else "triangle", cells)])
    meshio.write(str(path), mesh, file_format="gmsh", binary=False)
    return path


def _grid(nx: int, ny: int, size, origin) -> tuple[int, int, np.ndarray, np.ndarray]:
    nx, ny = int(nx), int(ny)
    if min(nx, ny) < 1:
        raise ValueError("a rectangle needs at least one cell per axis")
    size = np.asarray(size, dtype=np.float64)
    origin = np.asarray(origin, dtype=np.float64)
    if size.shape != (2,) or np.any(size <= 0):
        raise ValueError("rectangle size must be two positive lengths")
    return nx, ny, size, origin


def rectangle_mesh(nx: int, ny: int, size=(1.0, 1.0),
                   origin=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of the rectangle [origin, origin + size] in the plane z = 0 with
    nx * ny cells of 2 triangles (module docstring). Returns (points ((nx+1)(ny+1), 3)
    float64 with z = 0, triangles (2 nx ny, 3) int64), every triangle counter-clockwise
    (positive area seen from +z); node (i, j) is at origin + (i/nx, j/ny) size and has
    index i (ny + 1) + j."""
    nx, ny, size, origin = _grid(nx, ny, size, origin)
    gi, gj = np.meshgrid(np.arange(nx + 1) / nx, np.arange(ny + 1) / ny, indexing="ij")
    points = np.zeros(((nx + 1) * (ny + 1), 3))
    points[:, 0] = origin[0] + gi.ravel() * size[0]
    points[:, 1] = origin[1] + gj.ravel() * size[1]
    ci, cj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    ci, cj = ci.ravel(), cj.ravel()
    a = ci * (ny + 1) + cj  # corners of cell (i, j): a = (i, j), b = (i+1, j),
    b, c, d = a + ny + 1, a + ny + 2, a + 1  # c = (i+1, j+1), d = (i, j+1)
    odd = ((ci % 2) ^ (cj % 2)).astype(bool)
    first = np.where(odd[:, None], np.column_stack([a, b, d]), np.column_stack([a, b, c]))
    second = np.where(odd[:, None], np.column_stack([b, c, d]), np.column_stack([a, c, d]))
    triangles = np.stack([first, second], axis=1).reshape(-1, 3)
    return points, triangles.astype(np.int64)


def rectangle_springs(nx: int, ny: int) -> np.ndarray:
    """The springs (k, 2) int64 of the lecture's mass-spring rectangle over the nodes of
    ``rectangle_mesh(nx, ny)``, in its order: the springs along x, then along y, then
    both diagonals of every cell."""
    nx, ny, _, _ = _grid(nx, ny, (1.0, 1.0), (0.0, 0.0))
    node = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    along_x = np.column_stack([node[:-1, :].ravel(), node[1:, :].ravel()])
    along_y = np.column_stack([node[:, :-1].ravel(), node[:, 1:].ravel()])
    diagonals = np.stack([np.column_stack([node[:-1, :-1].ravel(), node[1:, 1:].ravel()]),
                          np.column_stack([node[1:, :-1].ravel(), node[:-1, 1:].ravel()])],
                         axis=1).reshape(-1, 2)
    return np.concatenate([along_x, along_y, diagonals]).astype(np.int64)
