"""Two tetrahedralised unit cubes, the upper one a small gap above the lower one (turned
and shifted), as the contact and friction oracle tests use them. Built from the
project's own mesh generator and surface extraction."""

from __future__ import annotations

import numpy as np

from ipcsim.model.generate import box_tet_mesh
from ipcsim.model.surface import boundary_triangles, unique_edges


def two_cubes(n, gap, shift, angle_deg):
    """(vertices, tets): cube 2 is cube 1 turned by angle_deg about z and placed
    1 + gap above it, shifted by (shift[0], shift[1])."""
    V0, T0 = box_tet_mesh(n, n, n)
    th = np.deg2rad(angle_deg)
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    V1 = (V0 - 0.5) @ R.T + 0.5 + np.array([shift[0], shift[1], 1.0 + gap])
    return np.vstack([V0, V1]), np.vstack([T0, T0 + len(V0)])


def boundary_faces(T):
    return boundary_triangles(np.asarray(T, dtype=np.int64))


def surface_edges(F):
    return unique_edges(np.asarray(F, dtype=np.int64))
