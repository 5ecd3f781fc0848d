"""The penalty baseline's penetration depth (kernels/contact/penalty.py): a vertex inside
a closed surface (by its winding number, solid angles of intersection.solid_angle) is as
deep as its distance to the nearest triangle; one outside is 0."""

import numpy as np
from scipy.spatial import ConvexHull

from ipcsim.kernels.contact.penalty import penetration_depths


def _unit_cube_surface():
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    triangles = ConvexHull(corners).simplices.astype(np.int64)
    for t in triangles:  # outward: the normal points away from the centre
        a, b, c = corners[t]
        if np.dot(np.cross(b - a, c - a), a - 0.5) < 0:
            t[1], t[2] = t[2], t[1]
    return corners, triangles


def test_inside_as_deep_as_the_nearest_face_outside_zero():
    corners, triangles = _unit_cube_surface()
    queries = np.array([[0.5, 0.5, 0.5], [0.2, 0.6, 0.5], [0.9, 0.5, 0.95],
                        [1.5, 0.5, 0.5], [-0.1, -0.1, 0.5]])
    x = np.vstack([corners, queries])
    depth = penetration_depths(x, np.arange(8, 13, dtype=np.int64), triangles)
    np.testing.assert_allclose(depth, [0.5, 0.2, 0.05, 0.0, 0.0], atol=1e-12)
