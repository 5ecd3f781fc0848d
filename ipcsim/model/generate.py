"""Procedural tet meshes for tests, benchmarks and the project's own scenes.

``box_tet_mesh`` splits each cell of a regular grid into 6 tets sharing the cell's main
diagonal (Kuhn / Freudenthal subdivision). Every cell is split the same way, so the faces
of neighbouring cells match and the mesh is conforming; all tets are positively oriented.
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
    """Write a tet mesh as Gmsh MSH 4.1 ASCII (through meshio); returns the path."""
    import meshio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh = meshio.Mesh(np.asarray(points, dtype=np.float64),
                       [("tetra", np.asarray(tets, dtype=np.int64))])
    meshio.write(str(path), mesh, file_format="gmsh", binary=False)
    return path
