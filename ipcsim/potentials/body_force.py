"""Body forces (gravity and Neumann accelerations): −Σ mᵢ aᵢ·xᵢ over free vertices.

The accelerations array holds gravity plus every active NBC on each vertex and zero on
kinematic vertices (which never feel gravity or NBC). The term is linear in x, so its
Hessian is zero.
"""

from __future__ import annotations

import numpy as np

from .base import Triplets


class BodyForce:
    name = "body force"

    def __init__(self, mass: np.ndarray):
        self.mass = np.asarray(mass, dtype=float)
        self.acceleration = np.zeros((len(self.mass), 3))  # set once per step

    def value(self, x):
        return -float(np.einsum("i,ij,ij->", self.mass, self.acceleration, x))

    def gradient(self, x):
        return -(self.mass[:, None] * self.acceleration).reshape(-1)

    def hessian(self, x):
        return Triplets.empty()
