"""Lagged Rayleigh damping, as the original's ``dampingStiff`` / ``dampingRatio``:

    ½ Δxᵀ D Δx,   Δx = x − xₙ,   D = (k/h) · ∇²Ψ(xₙ)

(for BDF2 Δx = x − x̂ = βh vₙ₊₁ and the scale βh·k/h_scene², so that the damping
coefficient is the scene's at any step: ``solver/integrator.damping_scale``)

where ∇²Ψ is the (PSD-projected) Hessian of the elastic energy itself at the start of the
step, without the h² (β h² for Newmark) that weighs elasticity in the potential, and k
the damping stiffness: the original's ``computeDampingMtr`` scales the elastic Hessian
by k/h alone. With ``dampingRatio r`` (k = ¾ r h³), D is ¾ r times the weighted elastic
Hessian h²∇²Ψ of backward Euler, whichever the integrator. D is fixed during the step
(``ctx.damping``, made by ``lag``); its triplets reuse the elastic term's index arrays,
so assembly reuses their pattern.
"""

from __future__ import annotations

from typing import ClassVar

from msgspec import Struct

from ..kernels.terms import all_terms as terms_kernels
from ..kernels.terms.simple import damping_value
from .base import ElementHessian, LaggedDamping, StepContext


class Damping(Struct, frozen=True, eq=False):
    """½ Δxᵀ D Δx with D the elastic Hessian lagged at the step's start, scaled by k/h."""

    scale: float  # k/h
    name: ClassVar[str] = "damping"
    kind: ClassVar[int] = terms_kernels.DAMPING  # its data in the all-terms kernels
    constant_pattern: ClassVar[bool] = True

    @staticmethod
    def of(stiffness: float, h: float) -> "Damping":
        return Damping(stiffness / h)

    def lag(self, x_start, elastic_hessian: ElementHessian) -> LaggedDamping:
        """D at the start of a step from the elastic term's Hessian there."""
        triplets = elastic_hessian.kept().scaled(self.scale)  # evaluated once per step
        return LaggedDamping(x_start.copy(), triplets)

    def value(self, x, ctx: StepContext):
        lag = ctx.damping
        D = lag.triplets
        return damping_value(x, lag.x_start, D.vals, float(D.scale), D.elements)

    def gradient(self, x, ctx: StepContext):
        return ctx.damping.times((x - ctx.damping.x_start).reshape(-1))

    def hessian(self, x, ctx: StepContext):
        return ctx.damping.triplets
