"""Body forces (gravity and Neumann accelerations): −Σ mᵢ aᵢ·xᵢ over free vertices.

``ctx.acceleration`` holds gravity plus every active NBC on each vertex and zero on
kinematic vertices (which never feel gravity or NBC). The term is linear in x, so its
Hessian is zero.
"""

from __future__ import annotations

from typing import ClassVar

from msgspec import Struct
from msgspec.structs import force_setattr
import numpy as np

from ..kernels.terms import all_terms as terms_kernels
from ..kernels.terms.simple import body_force_gradient, body_force_value
from .base import StepContext, Triplets


class BodyForce(Struct, frozen=True, eq=False):
    """−Σ mᵢ aᵢ·xᵢ: gravity and the step's prescribed forces (``StepContext.acceleration``)."""

    mass: np.ndarray  # (n,) lumped masses
    name: ClassVar[str] = "body force"
    kind: ClassVar[int] = terms_kernels.BODY_FORCE  # its data in the all-terms kernels
    constant_pattern: ClassVar[bool] = False

    def __post_init__(self):
        # a private writeable copy: the compiled kernels take writeable arrays
        force_setattr(self, "mass", np.array(self.mass, dtype=float))

    def value(self, x, ctx: StepContext):
        return body_force_value(self.mass, ctx.acceleration, x)

    def gradient(self, x, ctx: StepContext):
        return body_force_gradient(self.mass, ctx.acceleration)

    def hessian(self, x, ctx: StepContext):
        return Triplets.empty()
