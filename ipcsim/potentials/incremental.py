"""The incremental potential of a time step, as an ordered, weighted sum of terms:

    E(x) = ½‖x − x̃‖²_M + w·(Ψ(x) − Σ mᵢ aᵢ·xᵢ) + ½ Δxᵀ D Δx + κ Σ b(d², d̂²) + D_f(x)

with w = h² for backward Euler and β h² for Newmark. Barrier terms are evaluated at unit
stiffness and scaled by κ here, so that κ can be balanced and doubled without evaluating
anything again. The terms are evaluated together, one kernel call for every value and
one for every gradient (``kernel_data.py``, ``kernels/terms/all_terms.py``); their
Hessians are added into a dense matrix in one call for a small system, or given term by
term for the sparse assembly. ``TermValues`` holds what one evaluation at x gave; the
sums at a given κ are taken from it.
"""

from __future__ import annotations

from functools import cached_property

from msgspec import Struct
import numpy as np

from ..kernels.terms import all_terms as kt
from .base import Potential, StepContext
from .kernel_data import DenseHessian, TermData


class WeightedTerm(Struct, frozen=True, eq=False):
    """One term of the incremental potential with its weight (and κ, for a barrier)."""

    term: Potential
    weight: float = 1.0  # fixed weight (h² or βh² for forces and elasticity)
    barrier: bool = False  # also scaled by κ

    def factor(self, kappa: float) -> float:
        return self.weight * kappa if self.barrier else self.weight


class IncrementalPotential(Struct, frozen=True, eq=False, dict=True):
    """The step's potential: its weighted terms, in the order they are summed."""

    terms: tuple[WeightedTerm, ...]

    @cached_property
    def kernel(self) -> TermData:
        """The terms packed for the all-terms kernels."""
        return TermData.of(self.terms)

    def with_term(self, term: WeightedTerm) -> "IncrementalPotential":
        """This potential plus ``term`` (last)."""
        return IncrementalPotential(self.terms + (term,))

    @property
    def barrier_weight(self) -> float:
        """The weight of the barriers (1 where there are none): κ times it is their
        stiffness in this potential."""
        return next((t.weight for t in self.terms if t.barrier), 1.0)

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

    def evaluate(self, x: np.ndarray, ctx: StepContext, data: tuple, order: int = 0,
                 known: tuple | None = None) -> "TermValues":
        """The terms at x in ``ctx`` (``data``: ``kernel.data(ctx)``; the mesh's pairs are
        ``ctx.collisions``): their gradients now (order ≥ 1), their values when first
        read, or ``known`` where a line search gave them at x."""
        pairs = self.kernel.pairs(ctx.collisions, ctx.dhat)
        gradients = None
        if order >= 1:
            gradients = kt.term_gradients(x, self.kernel.present, data, pairs)
        return TermValues(self, x, ctx, data, pairs, gradients, known)

    def hessian(self, x: np.ndarray, ctx: StepContext, data: tuple, kappa: float,
                dense: bool, factors: np.ndarray | None = None) -> tuple[list, list]:
        """The weighted, PSD-projected Hessian at x: one part that adds every term into a
        dense matrix (``dense``; ``factors`` each kind's factor at κ where known), or each
        term's triplets split into those whose sparsity pattern never changes
        (``constant_pattern``) and the rest (contact, friction)."""
        if dense:
            k = self.kernel
            return [DenseHessian(x.copy(), k.present,
                                 k.factors(kappa) if factors is None else factors, data,
                                 k.pairs(ctx.collisions, ctx.dhat))], []
        static, dynamic = [], []
        for t in self.terms:
            h = t.term.hessian(x, ctx).scaled(t.factor(kappa))
            (static if t.term.constant_pattern else dynamic).append(h)
        return static, dynamic

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
                          and np.isfinite(term.hessian(x, ctx).values).all())
            if finite and p is not None and getattr(term, "max_step", None) is not None:
                finite = not np.isnan(term.max_step(x, p, ctx))
            if not finite:
                bad.append(term.name)
        return bad


class TermValues(Struct, frozen=True, eq=False, dict=True):
    """Each term's value, and with order ≥ 1 its gradient, at one x (unweighted; the
    weights and κ are applied by the sums). The values are evaluated when first read: at
    a Newton iterate the line search that reached x has given them already (``known``),
    and Newton reads them only where it needs E(x) at another κ."""

    potential: IncrementalPotential
    x: np.ndarray
    ctx: StepContext
    data: tuple
    pairs: tuple
    gradients: np.ndarray | None = None  # (N_KINDS, 3n), by kind
    known: tuple[float, ...] | None = None  # the values, where a line search gave them

    @cached_property
    def values(self) -> tuple[float, ...]:
        """Each term's value, in the terms' order."""
        if self.known is not None:
            return self.known
        k = self.potential.kernel
        by_kind = kt.term_values(self.x, k.present, self.data, self.pairs).tolist()
        return tuple(by_kind[kind] for kind in k.kinds)

    @property
    def terms(self) -> tuple[WeightedTerm, ...]:
        return self.potential.terms

    def energy(self, kappa: float) -> float:
        return float(sum(t.factor(kappa) * v for t, v in zip(self.terms, self.values)))

    def value_of(self, name: str) -> float | None:
        """The unweighted value of the term called ``name`` (None if absent)."""
        for t, v in zip(self.terms, self.values):
            if t.term.name == name:
                return v
        return None

    def _rows(self):
        return zip(self.terms, (self.gradients[k] for k in self.potential.kernel.kinds))

    def weighted(self, kappa: float) -> tuple[np.ndarray, np.ndarray]:
        """(each kind's factor at κ, ∇E at κ)."""
        return kt.weighted_gradient(self.gradients, self.potential.kernel.weighing,
                                    float(kappa))

    def gradient(self, kappa: float) -> np.ndarray:
        return self.weighted(kappa)[1]

    def split_gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """(Σ barrier gradients at κ = 1, Σ of every other term's): what κ balances."""
        n = self.gradients.shape[1]
        g_barrier, g_rest = np.zeros(n), np.zeros(n)
        for t, gi in self._rows():
            if t.barrier:
                g_barrier += t.weight * gi
            else:
                g_rest += t.weight * gi
        return g_barrier, g_rest
