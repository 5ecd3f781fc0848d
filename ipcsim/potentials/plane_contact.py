"""Contact of surface vertices with planes (``ground``, ``halfSpace``): Σ b(d², d̂²) over
every (plane, vertex) pair, d the signed distance, at unit stiffness (the incremental
potential multiplies barrier terms by κ). Its ``max_step`` is the planes' exact CCD."""

from __future__ import annotations

from typing import ClassVar

from msgspec import Struct

from ..kernels.terms import all_terms as terms_kernels
from ..contact.planes import Planes
from ..kernels.contact import plane_barrier as k
from .base import ContactTerm, StepContext, Triplets

# CCD stops a vertex at 10% of its current gap to a plane: never at zero distance.
CCD_KEEP_FRACTION = 0.1


class PlaneContact(Struct, ContactTerm, frozen=True, eq=False):
    """The barrier of the vertices near the contact planes at unit κ."""

    planes: Planes
    dhat: float
    name: ClassVar[str] = "plane contact"
    kind: ClassVar[int] = terms_kernels.PLANE_CONTACT  # its data in the all-terms kernels

    def _args(self, ctx=None):
        planes = self.planes.at(ctx)  # where a 2D scene's lines move
        return planes.vertices, planes.origins, planes.normals

    def value(self, x, ctx: StepContext | None = None):
        return k.plane_barrier_value(x, *self._args(ctx), self.s_hat, 1.0)

    def gradient(self, x, ctx: StepContext | None = None):
        return k.plane_barrier_gradient(x, *self._args(ctx), self.s_hat, 1.0)

    def hessian(self, x, ctx: StepContext | None = None):
        return Triplets(*k.plane_barrier_hessian(x, *self._args(ctx), self.s_hat, 1.0))

    def max_step(self, x, p, ctx: StepContext | None = None):
        return k.plane_ccd_max_step(x, p, *self._args(ctx), CCD_KEEP_FRACTION)
