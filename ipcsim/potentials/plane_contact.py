"""Contact of surface vertices with planes (``ground``, ``halfSpace``): κ Σ b(d², d̂²)."""

from __future__ import annotations

import numpy as np

from ..kernels import plane_contact as k
from .base import Triplets

# CCD stops a vertex at 10% of its current gap to a plane: never at zero distance.
CCD_KEEP_FRACTION = 0.1


class PlaneContact:
    name = "plane contact"

    def __init__(self, vertices, origins, normals, dhat: float):
        # writable copies: numba compiles a second version of every kernel for the
        # model's read-only arrays
        self.vertices = np.array(vertices, dtype=np.int64)
        self.origins = np.array(origins, dtype=float).reshape(-1, 3)
        self.normals = np.array(normals, dtype=float).reshape(-1, 3)
        self.s_hat = dhat * dhat
        self.kappa = 1.0

    def value(self, x):
        return k.plane_barrier_value(x, self.vertices, self.origins, self.normals,
                                     self.s_hat, self.kappa)

    def gradient(self, x):
        return k.plane_barrier_gradient(x, self.vertices, self.origins, self.normals,
                                        self.s_hat, self.kappa)

    def hessian(self, x):
        return Triplets(*k.plane_barrier_hessian(x, self.vertices, self.origins,
                                                 self.normals, self.s_hat, self.kappa))

    def max_step(self, x, p):
        return k.plane_ccd_max_step(x, p, self.vertices, self.origins, self.normals,
                                    CCD_KEEP_FRACTION)

    def statistics(self, x):
        """(active pair count, smallest vertex–plane distance)."""
        return k.plane_active_count_and_min_distance(x, self.vertices, self.origins,
                                                     self.normals, self.s_hat)

    def min_distance_sq(self, x):
        return self.statistics(x)[1] ** 2
