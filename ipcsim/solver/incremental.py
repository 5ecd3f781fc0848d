"""The incremental potential of one time step, as a weighted sum of terms:

    E(x) = ½‖x − x̃‖²_M + w·(Ψ(x) − Σ mᵢ aᵢ·xᵢ) + κ Σ b(d², d̂²) + ½ Δxᵀ D Δx

with w = h² for backward Euler and β h² for Newmark. The Newton solver sees only
``value``, ``gradient``, ``hessian`` and ``max_step``; it knows nothing of contact.
Each call is timed into the phase buckets that steps.csv reports.
"""

from __future__ import annotations

import time
from collections import defaultdict

import numpy as np

from ..potentials.base import Triplets


class PhaseTimer:
    """Accumulates wall time per phase: ``with timer("solve"): ...``."""

    def __init__(self):
        self.totals = defaultdict(float)

    def __call__(self, phase: str):
        return _Phase(self.totals, phase)

    def reset(self) -> dict[str, float]:
        out = dict(self.totals)
        self.totals.clear()
        return out


class _Phase:
    __slots__ = ("totals", "phase", "start")

    def __init__(self, totals, phase):
        self.totals, self.phase = totals, phase

    def __enter__(self):
        self.start = time.perf_counter()

    def __exit__(self, *exc):
        self.totals[self.phase] += time.perf_counter() - self.start


class IncrementalPotential:
    def __init__(self, terms, timer: PhaseTimer):
        """``terms``: list of [weight, potential]; weights may change between steps."""
        self.terms = terms
        self.timer = timer

    def value(self, x) -> float:
        with self.timer("energy"):
            return float(sum(w * t.value(x) for w, t in self.terms if w != 0.0))

    def gradient(self, x) -> np.ndarray:
        with self.timer("energy"):
            g = np.zeros(x.size)
            for w, t in self.terms:
                if w != 0.0:
                    g += w * t.gradient(x)
            return g

    def hessian(self, x) -> tuple[list[Triplets], list[Triplets]]:
        """Weighted PSD triplets of every term, split into terms whose sparsity pattern
        never changes (``constant_pattern``) and the rest (contact)."""
        with self.timer("energy"):
            static, dynamic = [], []
            for w, t in self.terms:
                if w == 0.0:
                    continue
                h = t.hessian(x)
                if w != 1.0:
                    h = Triplets(h.rows, h.cols, w * h.vals)
                (static if getattr(t, "constant_pattern", False) else dynamic).append(h)
            return static, dynamic

    def nonfinite_terms(self, x, p=None) -> list[str]:
        """Names of the terms whose value, gradient or Hessian at ``x`` (or, with ``p``,
        whose step bound along p) is NaN or infinite: what a failure report names."""
        bad = []
        for w, t in self.terms:
            if w == 0.0:
                continue
            with np.errstate(all="ignore"):
                finite = (np.isfinite(w * t.value(x)) and np.isfinite(w * t.gradient(x)).all()
                          and np.isfinite(w * t.hessian(x).vals).all())
            if finite and p is not None and getattr(t, "max_step", None) is not None:
                finite = not np.isnan(t.max_step(x, p))
            if not finite:
                bad.append(getattr(t, "name", type(t).__name__))
        return bad

    def max_step(self, x, p) -> float:
        """Largest feasible step fraction: CCD of contact terms, inversion bound of NH."""
        with self.timer("ccd_line_search"):
            alpha = 1.0
            p3 = p.reshape(-1, 3)
            for w, t in self.terms:
                bound = getattr(t, "max_step", None)
                if w != 0.0 and bound is not None:
                    alpha = min(alpha, bound(x, p3.reshape(-1)))
            return alpha
