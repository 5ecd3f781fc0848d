"""Body forces (gravity and Neumann accelerations): −Σ mᵢ aᵢ·xᵢ over free vertices.

``ctx.acceleration`` holds gravity plus every active NBC on each vertex and zero on
kinematic vertices (which never feel gravity or NBC). The term is linear in x, so its
Hessian is zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .base import StepContext, Triplets


@dataclass(frozen=True, eq=False)
class BodyForce:
    mass: np.ndarray  # (n,) lumped masses
    name: ClassVar[str] = "body force"
    constant_pattern: ClassVar[bool] = False

    def value(self, x, ctx: StepContext):
        return -float(np.einsum("i,ij,ij->", self.mass, ctx.acceleration, x))

    def gradient(self, x, ctx: StepContext):
        return -(self.mass[:, None] * ctx.acceleration).reshape(-1)

    def hessian(self, x, ctx: StepContext):
        return Triplets.empty()
