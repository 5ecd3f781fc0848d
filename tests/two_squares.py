"""Two triangulated squares in the plane z = 0, the upper one a small gap above the lower
one (turned and shifted), as the 2D contact and friction oracle tests use them. Built
from the project's own rectangle generator and boundary extraction."""

from __future__ import annotations

import numpy as np

from ipcsim.model.generate import rectangle_mesh
from ipcsim.model.surface import boundary_edges


def two_squares(n, gap, shift, angle_deg):
    """(vertices (n, 3) with z = 0, triangles): square 2 is square 1 (the unit square,
    n x n cells) turned by angle_deg about its centre and placed 1 + gap above it, shifted
    by ``shift`` along x."""
    V0, T0 = rectangle_mesh(n, n)
    th = np.deg2rad(angle_deg)
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    V1 = (V0 - [0.5, 0.5, 0.0]) @ R.T + [0.5 + shift, 1.5 + gap, 0.0]
    return np.vstack([V0, V1]), np.vstack([T0, T0 + len(V0)])


# The two-square oracle scenes of the 2D barrier, CCD and friction tests: a turned square
# whose lowest corner is over the lower square's top edge, and two almost aligned edges.
SCENES = {
    "corner": dict(n=4, gap=-0.06, shift=0.13, angle_deg=30.0, dhat=0.08, kappa=1e3),
    "aligned": dict(n=4, gap=0.01, shift=0.11, angle_deg=0.5, dhat=0.03, kappa=1e4),
}


def scene(name):
    """(vertices, triangles, boundary edges, parameters) of a named scene; the corner
    scene's gap is negative (the squares' boxes overlap) so that the turned square's
    corner comes to lie just above the other's top edge."""
    p = SCENES[name]
    V, T = two_squares(p["n"], p["gap"], p["shift"], p["angle_deg"])
    if name == "corner":  # lift the upper square until its corner is 0.3 d̂ above y = 1
        upper = np.arange(len(V) // 2, len(V))
        V[upper, 1] += 1.0 + 0.3 * p["dhat"] - V[upper, 1].min()
    return V, T, boundary_edges(T), p


def ipctk_mesh(ipctk, V, E):
    """ipctk's 2D collision mesh of the boundary edges E over the vertices V (their x, y),
    and the collision vertices' positions (n_c, 2)."""
    full = np.asfortranarray(V[:, :2])
    mesh = ipctk.CollisionMesh.build_from_full_mesh(full, np.asarray(E, dtype=np.int32),
                                                    np.zeros((0, 3), dtype=np.int32))
    return mesh, np.ascontiguousarray(mesh.vertices(full))


def brute_force_point_edge_pairs(V, E, inflation):
    """Every (p, e0, e1) of a boundary vertex p and a boundary edge not incident to it whose
    boxes, grown by ``inflation`` on every side, overlap."""
    points = np.unique(E)
    lo_p, hi_p = V[points] - inflation, V[points] + inflation
    lo_e = V[E].min(axis=1) - inflation
    hi_e = V[E].max(axis=1) + inflation
    overlap = np.all((lo_p[:, None] <= hi_e[None]) & (lo_e[None] <= hi_p[:, None]), axis=2)
    pi, ei = np.nonzero(overlap)
    keep = np.all(E[ei] != points[pi, None], axis=1)
    return np.ascontiguousarray(np.column_stack([points[pi[keep]], E[ei[keep]]]),
                                dtype=np.int64)
