"""The incremental potential of a time step, as an ordered, weighted sum of terms:

    E(x) = ½‖x − x̃‖²_M + w·(Ψ(x) − Σ mᵢ aᵢ·xᵢ) + ½ Δxᵀ D Δx + κ Σ b(d², d̂²) + D_f(x)

with w = h² for backward Euler and β h² for Newmark. Barrier terms are evaluated at unit
stiffness and scaled by κ here, so that κ can be balanced and doubled without evaluating
anything again. ``evaluate`` returns every term's value (and gradient and Hessian) at one
x as a ``TermValues``; the sums at a given κ are taken from it. A potential made
``fusing()`` evaluates its terms together, one kernel call each for the values, the
gradients and the Hessians (``fused.py``: the same numbers, a fraction of the calls), for
small scenes whose Newton matrix is dense.
"""

from __future__ import annotations

from functools import cached_property

from msgspec import Struct
from msgspec.structs import replace
import numpy as np

from .base import Potential, StepContext, Triplets
from .fused import FusedTerms


class WeightedTerm(Struct, frozen=True, eq=False):
    """One term of the incremental potential with its weight (and κ, for a barrier)."""

    term: Potential
    weight: float = 1.0  # fixed weight (h² or βh² for forces and elasticity)
    barrier: bool = False  # also scaled by κ

    def factor(self, kappa: float) -> float:
        return self.weight * kappa if self.barrier else self.weight


class TermValues(Struct, frozen=True, eq=False, dict=True):
    """Each term's value, and with order ≥ 1 its gradient, with order 2 its Hessian, at
    one x (unweighted; the weights and κ are applied by the sums).

    The values are evaluated when first read: at a Newton iterate the line search that
    reached x has given E(x) already, and Newton reads them again only where κ or the
    potential itself changed there."""

    terms: tuple[WeightedTerm, ...]
    x: np.ndarray
    ctx: StepContext
    gradients: tuple[np.ndarray, ...] | None = None
    hessians: tuple[Triplets, ...] | None = None  # None with ``fused``: made at κ
    fused: FusedTerms | None = None  # the terms evaluated together
    known: tuple[float, ...] | None = None  # the values, where a line search gave them

    @cached_property
    def values(self) -> tuple[float, ...]:
        if self.known is not None:
            return self.known
        if self.fused is not None:
            return self.fused.values(self.x, self.ctx)
        return tuple(float(t.term.value(self.x, self.ctx)) for t in self.terms)

    def energy(self, kappa: float) -> float:
        return float(sum(t.factor(kappa) * v for t, v in zip(self.terms, self.values)))

    def value_of(self, name: str) -> float | None:
        """The unweighted value of the term called ``name`` (None if absent)."""
        for t, v in zip(self.terms, self.values):
            if t.term.name == name:
                return v
        return None

    def gradient(self, kappa: float) -> np.ndarray:
        g = np.zeros_like(self.gradients[0])
        for t, gi in zip(self.terms, self.gradients):
            g += t.factor(kappa) * gi
        return g

    def split_gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """(Σ barrier gradients at κ = 1, Σ of every other term's): what κ balances."""
        g_barrier, g_rest = np.zeros_like(self.gradients[0]), np.zeros_like(self.gradients[0])
        for t, gi in zip(self.terms, self.gradients):
            if t.barrier:
                g_barrier += t.weight * gi
            else:
                g_rest += t.weight * gi
        return g_barrier, g_rest

    def hessian(self, kappa: float) -> tuple[list[Triplets], list[Triplets]]:
        """Weighted PSD triplets split into terms whose sparsity pattern never changes
        (``constant_pattern``) and the rest (contact, friction); fused, one part that
        adds them all into a dense matrix."""
        if self.fused is not None:
            return [self.fused.hessian(self.x, self.ctx, kappa)], []
        static, dynamic = [], []
        for t, h in zip(self.terms, self.hessians):
            (static if t.term.constant_pattern else dynamic).append(h.scaled(t.factor(kappa)))
        return static, dynamic


class IncrementalPotential(Struct, frozen=True, eq=False, dict=True):
    """The step's potential: its weighted terms, evaluated together where ``fused``."""

    terms: tuple[WeightedTerm, ...]
    fused: FusedTerms | None = None  # set by ``fusing``

    def fusing(self) -> "IncrementalPotential":
        """The same potential with its terms evaluated together (``fused.py``) where they
        all can be; its Hessians then go into a dense matrix only."""
        return replace(self, fused=FusedTerms.of(self.terms))

    def with_term(self, term: WeightedTerm) -> "IncrementalPotential":
        """This potential plus ``term`` (last), fused if this one is."""
        terms = self.terms + (term,)
        return IncrementalPotential(terms, None if self.fused is None
                                    else FusedTerms.of(terms))

    def term(self, name: str) -> Potential | None:
        """The term called ``name`` ("elasticity", "friction", ...), None if absent."""
        return self._terms_by_name.get(name)

    @cached_property
    def _terms_by_name(self) -> dict:
        # asked a few times a step; the first term of a name, as a search in order finds
        by_name = {}
        for weighted in self.terms:
            by_name.setdefault(weighted.term.name, weighted.term)
        return by_name

    def evaluate(self, x: np.ndarray, ctx: StepContext, order: int = 0) -> TermValues:
        """The terms at x: their gradients (order ≥ 1) and Hessians (order 2) now, their
        values when first read (``TermValues.values``)."""
        if self.fused is not None:
            gradients = self.fused.gradients(x, ctx) if order >= 1 else None
            return TermValues(self.terms, x, ctx, gradients, None, self.fused)
        gradients = tuple(t.term.gradient(x, ctx) for t in self.terms) if order >= 1 else None
        hessians = tuple(t.term.hessian(x, ctx) for t in self.terms) if order >= 2 else None
        return TermValues(self.terms, x, ctx, gradients, hessians)

    def value(self, x: np.ndarray, ctx: StepContext, kappa: float) -> float:
        return self.evaluate(x, ctx, 0).energy(kappa)

    def max_step(self, x: np.ndarray, p: np.ndarray, ctx: StepContext) -> float:
        """Largest feasible step fraction of the terms that bound one (the inversion bound
        of neo-Hookean elasticity, the planes' CCD)."""
        alpha = 1.0
        for t in self.terms:
            bound = getattr(t.term, "max_step", None)
            if bound is not None:
                alpha = min(alpha, bound(x, p, ctx))
        return alpha

    def resolved(self, x: np.ndarray, p: np.ndarray, ctx: StepContext) -> bool:
        """Whether every term that has a stopping test of its own (friction's static
        ramp) accepts the Newton direction p at x."""
        return all(t.term.resolved(x, p, ctx) for t in self.terms
                   if getattr(t.term, "resolved", None) is not None)

    def nonfinite_terms(self, x: np.ndarray, ctx: StepContext, p=None) -> list[str]:
        """Names of the terms whose value, gradient or Hessian at ``x`` (or, with ``p``,
        whose step bound along p) is NaN or infinite: what a failure report names."""
        bad = []
        for t in self.terms:
            term = t.term
            with np.errstate(all="ignore"):
                finite = (np.isfinite(term.value(x, ctx))
                          and np.isfinite(term.gradient(x, ctx)).all()
                          and np.isfinite(term.hessian(x, ctx).vals).all())
            if finite and p is not None and getattr(term, "max_step", None) is not None:
                finite = not np.isnan(term.max_step(x, p, ctx))
            if not finite:
                bad.append(term.name)
        return bad
