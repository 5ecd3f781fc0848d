"""Lagged Rayleigh damping, as the original's ``dampingStiff`` / ``dampingRatio``:

    ½ Δxᵀ D Δx,   Δx = x − xₙ,   D = (k/h) · w K(xₙ)

where w K is the (PSD-projected) Hessian of the weighted elastic term at the start of the
step (w = h² for backward Euler) and k the damping stiffness. D is fixed during the step;
its triplets reuse the elastic term's index arrays, so assembly reuses their pattern.
"""

from __future__ import annotations

from .base import Triplets


class Damping:
    name = "damping"
    constant_pattern = True

    def __init__(self, stiffness: float, h: float, elastic_weight: float):
        self.scale = stiffness / h * elastic_weight
        self.x_start = None
        self.D = None

    def start_step(self, x_start, elastic_hessian: Triplets):
        n = x_start.size
        self.x_start = x_start.copy()
        self._triplets = Triplets(elastic_hessian.rows, elastic_hessian.cols,
                                  self.scale * elastic_hessian.vals)
        self.D = self._triplets.tocsr(n)  # for the value and gradient

    def value(self, x):
        dx = (x - self.x_start).reshape(-1)
        return 0.5 * float(dx @ (self.D @ dx))

    def gradient(self, x):
        return self.D @ (x - self.x_start).reshape(-1)

    def hessian(self, x):
        return self._triplets
