"""Inertia: ½ (x − x̃)ᵀ M (x − x̃) with the lumped (diagonal) mass matrix M; x̃ is the
integrator's prediction of the step (``ctx.x_tilde``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..kernels.simple_terms import inertia_value
from .base import StepContext, Triplets


@dataclass(frozen=True, eq=False)
class Inertia:
    """½ ‖x − x̃‖²_M with the lumped masses M."""

    mass: np.ndarray  # (n,) lumped masses
    name: ClassVar[str] = "inertia"
    constant_pattern: ClassVar[bool] = True  # the same triplet index arrays on every call
    _hessian: Triplets = field(init=False, repr=False)

    def __post_init__(self):
        # a private writeable copy: the compiled kernels take writeable arrays
        mass = np.array(self.mass, dtype=float)
        object.__setattr__(self, "mass", mass)
        dofs = np.arange(3 * len(mass), dtype=np.int32)  # as elasticity's: one kernel variant
        object.__setattr__(self, "_hessian", Triplets(dofs, dofs, np.repeat(mass, 3)))

    def value(self, x, ctx: StepContext):
        return inertia_value(self.mass, x, ctx.x_tilde)

    def gradient(self, x, ctx: StepContext):
        return (self.mass[:, None] * (x - ctx.x_tilde)).reshape(-1)

    def hessian(self, x, ctx: StepContext):
        return self._hessian
