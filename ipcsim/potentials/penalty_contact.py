"""Quadratic penalty contact: the baseline that IPC's barrier is measured against.

Chosen with the scene's ``contact.formulation = "penalty"`` (see ``potentials.terms``).
``PenaltyPlaneContact`` and ``PenaltyMeshContact`` use the same planes and collision sets
as the barrier terms and replace the energy by

    P = ½ k Σ max(0, d̂ − d)²

over the same pairs (signed d for planes, the unsigned closest-feature distance for mesh
pairs; see ``ipcsim/kernels/contact/penalty.py``), with a fixed stiffness k. There is no
feasibility filter: ``max_step`` is 1, so nothing stops a step from crossing a surface.
"""

from __future__ import annotations

from typing import ClassVar

from msgspec import Struct

from ..kernels.terms import all_terms as terms_kernels
from ..contact.planes import Planes
from ..kernels.contact import penalty as kp
from .base import ContactTerm, StepContext, Triplets


class PenaltyPlaneContact(Struct, ContactTerm, frozen=True, eq=False):
    """The penalty baseline's plane contact: a stiff quadratic inside d̂, no barrier."""

    planes: Planes
    dhat: float
    stiffness: float
    name: ClassVar[str] = "plane penalty contact"
    kind: ClassVar[int] = terms_kernels.PLANE_PENALTY  # its data in the all-terms kernels

    def _args(self):
        p = self.planes
        return p.vertices, p.origins, p.normals, self.dhat, self.stiffness

    def value(self, x, ctx: StepContext | None = None):
        return kp.plane_penalty_value(x, *self._args())

    def gradient(self, x, ctx: StepContext | None = None):
        return kp.plane_penalty_gradient(x, *self._args())

    def hessian(self, x, ctx: StepContext | None = None):
        return Triplets(*kp.plane_penalty_hessian(x, *self._args()))

    def max_step(self, x, p, ctx: StepContext | None = None):
        return 1.0


class PenaltyMeshContact(Struct, ContactTerm, frozen=True, eq=False):
    """The penalty baseline's mesh contact: a stiff quadratic inside d̂, no barrier."""

    dhat: float
    stiffness: float
    name: ClassVar[str] = "mesh penalty contact"
    kind: ClassVar[int] = terms_kernels.MESH_PENALTY  # its data in the all-terms kernels

    def value(self, x, ctx: StepContext):
        c = ctx.collisions
        return kp.mesh_penalty_value(x, c.pt, c.ee, self.dhat, self.stiffness)

    def gradient(self, x, ctx: StepContext):
        c = ctx.collisions
        return kp.mesh_penalty_gradient(x, c.pt, c.ee, self.dhat, self.stiffness)

    def hessian(self, x, ctx: StepContext):
        c = ctx.collisions
        return Triplets(*kp.mesh_penalty_hessian(x, c.pt, c.ee, self.dhat, self.stiffness,
                                                 True))

    def max_step(self, x, p, ctx: StepContext | None = None):
        return 1.0
