"""Contact between mesh surfaces: Σ m·b(d², d̂²) over the point–triangle and edge–edge
pairs of ``ctx.collisions``, at unit stiffness (the incremental potential multiplies barrier
terms by κ). A collision set with distances is the one found at the x the term is evaluated
at (the objective keeps it so); when they show no pair within d̂ the term is zero.

Each pair enters with its closest-feature distance and, for edge–edge pairs, the mollifier
m of nearly parallel edges (ε_x from rest positions). Which pairs: at a Newton iterate, the
collision set built at x; in the line search, every pair swept within d̂ along the step
(``contact.ccd.line_search_bound``). The CCD step bound itself lives in ``contact/``.
"""

from __future__ import annotations

from typing import ClassVar

from msgspec import Struct
import numpy as np

from ..kernels.terms import all_terms as terms_kernels
from ..kernels.contact import pair_barrier as kb
from .base import BlockHessian, ContactTerm, StepContext, Triplets


class MeshContact(Struct, ContactTerm, frozen=True, eq=False):
    """The barrier of the mesh's collision set at unit κ: Σ b(d², d̂²)."""

    dhat: float
    name: ClassVar[str] = "mesh contact"
    kind: ClassVar[int] = terms_kernels.MESH_CONTACT  # its data in the all-terms kernels

    def value(self, x, ctx: StepContext):
        c = ctx.collisions
        if not c.may_be_active(self.dhat):
            return 0.0
        return kb.barrier_value(x, c.pt, c.ee, c.ee_eps_x, self.s_hat, 1.0)

    def gradient(self, x, ctx: StepContext):
        c = ctx.collisions
        if not c.may_be_active(self.dhat):  # also: a kernel not used is not compiled
            return np.zeros(x.size)
        return kb.barrier_gradient(x, c.pt, c.ee, c.ee_eps_x, self.s_hat, 1.0)

    def hessian(self, x, ctx: StepContext):
        c = ctx.collisions
        if not c.may_be_active(self.dhat):
            return Triplets.empty()
        return BlockHessian(*kb.barrier_hessian_blocks(x, c.pt, c.ee, c.ee_eps_x, self.s_hat,
                                                       1.0, True))
