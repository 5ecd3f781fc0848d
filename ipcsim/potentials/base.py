"""What every term of the incremental potential looks like to the solver.

A term is a frozen value with

    value(x, ctx) -> float
    gradient(x, ctx) -> (3n,)
    hessian(x, ctx) -> Triplets       every local block already projected to PSD

and, where it bounds the line search, ``max_step(x, p, ctx) -> α ∈ [0, 1]``. ``x`` is the
(n, 3) array of all vertex positions (DOF 3i+a is vertex i, axis a) and ``ctx`` the frozen
``StepContext`` of the step: everything a term needs beyond x. A term's answer depends on
its arguments alone; nothing is assigned to a term after it is built.

``constant_pattern`` marks terms whose Hessian triplets have the same index arrays on every
call (assembly keeps their sparsity pattern).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
import scipy.sparse as sp

if TYPE_CHECKING:
    from ..contact.collisions import Collisions
    from ..contact.friction_lag import FrictionLag


@dataclass(frozen=True)
class Triplets:
    """A sparse matrix as COO triplets, ``scale`` times (rows, cols, vals); duplicates
    are summed by ``tocsr``. ``scaled(w)`` changes the factor only, so weighting a large
    Hessian copies nothing."""

    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    scale: float = 1.0

    @staticmethod
    def empty() -> "Triplets":
        z = np.zeros(0, dtype=np.int64)
        return Triplets(z, z, np.zeros(0))

    @property
    def values(self) -> np.ndarray:
        """The entries' values, the scale applied."""
        return self.vals if self.scale == 1.0 else self.scale * self.vals

    @staticmethod
    def concat(parts: list["Triplets"]) -> "Triplets":
        parts = [p for p in parts if len(p.vals)]
        if not parts:
            return Triplets.empty()
        return Triplets(
            np.concatenate([p.rows for p in parts]),
            np.concatenate([p.cols for p in parts]),
            np.concatenate([p.values for p in parts]),
        )

    def scaled(self, w: float) -> "Triplets":
        """The same triplets, w times."""
        return self if w == 1.0 else Triplets(self.rows, self.cols, self.vals, self.scale * w)

    def tocsr(self, n_dofs: int) -> sp.csr_matrix:
        return sp.csr_matrix((self.values, (self.rows, self.cols)), shape=(n_dofs, n_dofs))


@dataclass(frozen=True, eq=False)
class LaggedDamping:
    """Rayleigh damping frozen at the start of a step: D = (k/h)·w∇²Ψ(xₙ)."""

    x_start: np.ndarray  # (n, 3) xₙ
    triplets: Triplets  # D as triplets (the elastic Hessian's pattern)
    matrix: sp.csr_matrix  # D, for the value and the gradient


@dataclass(frozen=True, eq=False)
class StepContext:
    """Everything the terms of one time step need beyond the positions x.

    Built once per step by the simulation; a new one (``dataclasses.replace``) is made
    whenever the collision set or the friction lag change. Nothing here is ever written
    to after construction. A field a term does not read may be left out (None)."""

    x_start: np.ndarray | None = None  # (n, 3) xₙ, positions at the start of the step
    x_tilde: np.ndarray | None = None  # (n, 3) x̃, the prediction (targets on kinematic rows)
    acceleration: np.ndarray | None = None  # (n, 3) gravity + active NBCs, 0 on kinematic
    kinematic: np.ndarray | None = None  # (n,) bool, vertices prescribed during the step
    target: np.ndarray | None = None  # (n, 3) where kinematic vertices must end the step
    dhat: float = 0.0  # barrier activation distance d̂ (m)
    collisions: "Collisions | None" = None  # mesh pairs near x (None: no mesh contact)
    friction: "FrictionLag | None" = None  # normal forces and bases lagged at x_lag
    damping: LaggedDamping | None = None


class Potential(Protocol):
    """A term of the incremental potential (see the module docstring)."""

    name: str
    constant_pattern: bool

    def value(self, x: np.ndarray, ctx: StepContext) -> float: ...

    def gradient(self, x: np.ndarray, ctx: StepContext) -> np.ndarray: ...

    def hessian(self, x: np.ndarray, ctx: StepContext) -> Triplets: ...
