"""Inertia: ½ (x − x̃)ᵀ M (x − x̃) with the lumped (diagonal) mass matrix M; x̃ is the
integrator's prediction of the step (``ctx.x_tilde``)."""

from __future__ import annotations

from functools import cached_property
from typing import ClassVar

from msgspec import Struct
from msgspec.structs import force_setattr
import numpy as np

from ..kernels.terms import all_terms as terms_kernels
from ..kernels.terms.simple import inertia_gradient, inertia_value, lumped_mass_diagonal
from .base import StepContext, Triplets


class Inertia(Struct, frozen=True, eq=False, dict=True):
    """½ ‖x − x̃‖²_M with the lumped masses M."""

    mass: np.ndarray  # (n,) lumped masses
    name: ClassVar[str] = "inertia"
    kind: ClassVar[int] = terms_kernels.INERTIA  # its data in the all-terms kernels
    constant_pattern: ClassVar[bool] = True  # the same triplet index arrays on every call

    def __post_init__(self):
        # a private writeable copy: the compiled kernels take writeable arrays
        mass = np.array(self.mass, dtype=float)
        force_setattr(self, "mass", mass)

    @cached_property
    def _hessian(self) -> Triplets:
        dofs = np.arange(3 * len(self.mass), dtype=np.int32)  # as elasticity's: one variant
        return Triplets(dofs, dofs, lumped_mass_diagonal(self.mass))

    def value(self, x, ctx: StepContext):
        return inertia_value(self.mass, x, ctx.x_tilde)

    def gradient(self, x, ctx: StepContext):
        return inertia_gradient(self.mass, x, ctx.x_tilde)

    def hessian(self, x, ctx: StepContext):
        return self._hessian
