"""Inertia: ½ (x − x̃)ᵀ M (x − x̃) with the lumped (diagonal) mass matrix M; x̃ is the
integrator's prediction of the step (``ctx.x_tilde``)."""

from __future__ import annotations

from functools import cached_property
from typing import ClassVar

from msgspec import Struct
from msgspec.structs import force_setattr
import numpy as np

from ..kernels.terms.simple import inertia_value
from .base import StepContext, Triplets


class Inertia(Struct, frozen=True, eq=False, dict=True):
    """½ ‖x − x̃‖²_M with the lumped masses M."""

    mass: np.ndarray  # (n,) lumped masses
    name: ClassVar[str] = "inertia"
    constant_pattern: ClassVar[bool] = True  # the same triplet index arrays on every call

    def __post_init__(self):
        # a private writeable copy: the compiled kernels take writeable arrays
        mass = np.array(self.mass, dtype=float)
        force_setattr(self, "mass", mass)

    @cached_property
    def _hessian(self) -> Triplets:
        dofs = np.arange(3 * len(self.mass), dtype=np.int32)  # as elasticity's: one variant
        return Triplets(dofs, dofs, np.repeat(self.mass, 3))

    def value(self, x, ctx: StepContext):
        return inertia_value(self.mass, x, ctx.x_tilde)

    def gradient(self, x, ctx: StepContext):
        return (self.mass[:, None] * (x - ctx.x_tilde)).reshape(-1)

    def hessian(self, x, ctx: StepContext):
        return self._hessian
