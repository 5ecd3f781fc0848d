"""Inertia: ½ (x − x̃)ᵀ M (x − x̃) with the lumped (diagonal) mass matrix M."""

from __future__ import annotations

import numpy as np

from .base import Triplets


class Inertia:
    name = "inertia"
    constant_pattern = True  # same triplet index arrays on every call

    def __init__(self, mass: np.ndarray):
        self.mass = np.asarray(mass, dtype=float)
        self.x_tilde = None  # (n, 3), the predicted positions; set once per step
        n = len(self.mass)
        dofs = np.arange(3 * n, dtype=np.int64)
        self._hessian = Triplets(dofs, dofs, np.repeat(self.mass, 3))

    def value(self, x):
        dx = x - self.x_tilde
        return 0.5 * float(np.einsum("i,ij,ij->", self.mass, dx, dx))

    def gradient(self, x):
        return (self.mass[:, None] * (x - self.x_tilde)).reshape(-1)

    def hessian(self, x):
        return self._hessian
