"""Lagged Rayleigh damping, as the original's ``dampingStiff`` / ``dampingRatio``:

    ½ Δxᵀ D Δx,   Δx = x − xₙ,   D = (k/h) · w K(xₙ)

where w K is the (PSD-projected) Hessian of the weighted elastic term at the start of the
step (w = h² for backward Euler) and k the damping stiffness. Kinematic rows drop out
with the rest of the kinematic DOFs in the Newton solve.
"""

from __future__ import annotations

import numpy as np

from .base import Triplets


class Damping:
    name = "damping"

    def __init__(self, stiffness: float, h: float, elastic_weight: float):
        self.scale = stiffness / h * elastic_weight
        self.x_start = None
        self.D = None

    def start_step(self, x_start, elastic_hessian: Triplets):
        n = x_start.size
        self.x_start = x_start.copy()
        self.D = (elastic_hessian.tocsr(n) * self.scale).tocsr()
        coo = self.D.tocoo()
        self._triplets = Triplets(coo.row.astype(np.int64), coo.col.astype(np.int64), coo.data)

    def value(self, x):
        dx = (x - self.x_start).reshape(-1)
        return 0.5 * float(dx @ (self.D @ dx))

    def gradient(self, x):
        return self.D @ (x - self.x_start).reshape(-1)

    def hessian(self, x):
        return self._triplets
