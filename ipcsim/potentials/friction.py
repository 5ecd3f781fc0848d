"""Lagged, smoothed Coulomb friction (IPC, Li et al. 2020) in displacement form:

    D(x) = Σ_k μ_k λ_k f0(|P_kᵀ r_k(x − x_start)|, ε_v h)

over the pairs frozen in ``ctx.friction`` (``contact.friction_lag``): mesh PT/EE pairs and
vertex–plane pairs active at x_lag, with their normal forces λ_k, closest-point
coefficients and tangent bases P_k. With ε = ε_v h and u = x − x_start this equals ipctk's
FrictionPotential(ε) at V = u.

Where a pair's slip y = |P_kᵀ r_k(u)| is below ε, friction is the static ramp, a spring of
stiffness ~ 2μλ/ε: there a Newton step is tiny even far from the solution, and ‖p‖∞ <
tol cannot tell a pair that sticks from one that must start sliding. ``resolved`` is the
extra stopping test for the second kind: a ramp pair whose linearised friction force
along p exceeds μλ (it must slide) blocks convergence while p still changes its slip by
``ramp_resolution``·ε or more, summed in force over its body's ramp pairs and
measured against the body's whole friction capacity Σ μλ.
Without it a body that should start sliding stops inside the ramp at every step and
creeps at ε_v instead (at the default tolerance, slopeTest_highSchoolPhysics_0.49 without
its ``tol`` line moves 1.3 mm instead of 0.27 m); a ramp softens towards y = ε
(f1'(ε) = 0), so such a pair gets long steps there and leaves it. Sticking pairs (force
below μλ), sliding pairs and free bodies keep the plain test, as in the original: how
closely a sticking pair's creep is resolved is the scene's tolerance's business.
"""

from __future__ import annotations

from typing import ClassVar

from msgspec import Struct
from msgspec.structs import force_setattr
import numpy as np

from ..kernels.terms import all_terms as terms_kernels
from ..kernels.contact import friction as kf
from .base import StepContext, Triplets


class Friction(Struct, frozen=True, eq=False):
    """Lagged, smoothed friction of the mesh and plane contacts (module docstring)."""

    eps: float  # ε_v·h, the sliding displacement below which friction ramps up
    project: bool = True
    ramp_resolution: float = 0.1  # pairs that must slide: resolved when p moves them < this·ε
    body: np.ndarray | None = None  # (n,) body id of each vertex; None: one body
    name: ClassVar[str] = "friction"
    kind: ClassVar[int] = terms_kernels.FRICTION  # its data in the all-terms kernels
    constant_pattern: ClassVar[bool] = False

    def __post_init__(self):
        if not self.eps > 0.0:
            raise ValueError(f"friction threshold eps_v*h must be > 0, got {self.eps}")
        force_setattr(self, "eps", float(self.eps))

    @staticmethod
    def _u(x, lag):
        return np.ascontiguousarray(np.asarray(x, dtype=float).reshape(-1, 3) - lag.x_start)

    def value(self, x, ctx: StepContext):
        f = ctx.friction
        if f is None or f.count == 0:
            return 0.0
        return kf.friction_value(self._u(x, f), f.verts, f.coeffs, f.basis, f.weight, self.eps)

    def gradient(self, x, ctx: StepContext):
        f = ctx.friction
        if f is None or f.count == 0:
            return np.zeros(np.asarray(x).size)
        return kf.friction_gradient(self._u(x, f), f.verts, f.coeffs, f.basis, f.weight,
                                    self.eps)

    def hessian(self, x, ctx: StepContext):
        f = ctx.friction
        if f is None or f.count == 0:
            return Triplets.empty()
        return Triplets(*kf.friction_hessian_triplets(
            self._u(x, f), f.verts, f.coeffs, f.basis, f.weight, self.eps, self.project,
            f.offsets))

    def resolved(self, x, p, ctx: StepContext) -> bool:
        """False while some pair in the static ramp (slip < ε at x) must slide (the
        direction p (3n,) asks more than μλ of it) and p still changes its slip by
        ramp_resolution·ε or more (summed in force over its body's pairs, against the
        body's friction capacity Σ μλ)."""
        f = ctx.friction
        if f is None or f.count == 0:
            return True
        body = self.body if self.body is not None else np.zeros(len(f.x_start), np.int64)
        return not kf.ramp_unresolved(self._u(x, f), np.ascontiguousarray(p.reshape(-1, 3)),
                                      f.verts, f.coeffs, f.basis, f.weight, body, self.eps,
                                      self.ramp_resolution)
