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


# The two-body oracle scenes of the barrier and friction tests.
SCENES = {
    # generic contact: vertex-face, edge-edge crossings, edges and corners over faces
    "rotated": dict(n=3, gap=0.05, shift=(0.13, 0.07), angle_deg=17.0, dhat=0.1, kappa=1e3),
    # almost aligned faces: many nearly parallel (mollified, frictionless) edge pairs
    "aligned": dict(n=3, gap=0.02, shift=(0.05, 0.03), angle_deg=0.5, dhat=0.05, kappa=1e4),
}


def ipctk_scene(ipctk, name):
    """(ipctk CollisionMesh, its surface positions X, the scene's parameters)."""
    p = SCENES[name]
    V, T = two_cubes(p["n"], p["gap"], p["shift"], p["angle_deg"])
    F = boundary_faces(T).astype(np.int32)
    E = ipctk.edges(np.asfortranarray(F))
    mesh = ipctk.CollisionMesh.build_from_full_mesh(np.asfortranarray(V), E, F)
    X = np.ascontiguousarray(mesh.vertices(np.asfortranarray(V)))
    return mesh, X, p
