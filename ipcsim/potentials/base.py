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

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, ClassVar, Protocol

import numpy as np
import scipy.sparse as sp

from ..kernels import assembly as ka

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
    def size(self) -> int:
        return len(self.rows)

    @property
    def values(self) -> np.ndarray:
        """The entries' values, the scale applied."""
        return self.vals if self.scale == 1.0 else self.scale * self.vals

    @staticmethod
    def concat(parts: list) -> "Triplets":
        parts = [p for p in parts if p.size]
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

    def scatter_into(self, data, slots, free_index, p, coupling) -> None:
        """data[slots[t]] += scale·vals[t] (a constant pattern's CSC slots, −1 where a row
        or column is kinematic); free rows' entries in kinematic columns go to coupling."""
        ka.scatter_into_pattern(data, slots, self.vals, self.scale, self.rows, self.cols,
                                free_index, p, coupling)


@dataclass(frozen=True, eq=False)
class ElementHessian:
    """A Hessian of per-element blocks on a constant pattern (``rows``, ``cols``: ``block``
    entries per element, element after element), evaluated at ``x`` when it is used:
    ``element_values(x, lo, hi)`` gives the entries of elements lo..hi−1. Assembly adds it
    into the matrix ``CHUNK`` elements at a time, so the whole array of values (144 per
    tet: 230 MB for 200 K tets) never exists; ``vals`` builds it for whoever asks."""

    rows: np.ndarray
    cols: np.ndarray
    x: np.ndarray
    element_values: Callable[[np.ndarray, int, int], np.ndarray]
    n_elements: int
    block: int
    scale: float = 1.0
    CHUNK: ClassVar[int] = 8192  # elements per evaluation: 9 MB of values for tets

    @property
    def size(self) -> int:
        return len(self.rows)

    @property
    def vals(self) -> np.ndarray:
        return self.element_values(self.x, 0, self.n_elements)

    @property
    def values(self) -> np.ndarray:
        return self.vals if self.scale == 1.0 else self.scale * self.vals

    def scaled(self, w: float) -> "ElementHessian":
        return self if w == 1.0 else dataclasses.replace(self, scale=self.scale * w)

    def tocsr(self, n_dofs: int) -> sp.csr_matrix:
        return Triplets(self.rows, self.cols, self.values).tocsr(n_dofs)

    def scatter_into(self, data, slots, free_index, p, coupling) -> None:
        """As ``Triplets.scatter_into``, one chunk of elements at a time."""
        b = self.block
        for lo in range(0, self.n_elements, self.CHUNK):
            hi = min(lo + self.CHUNK, self.n_elements)
            part = slice(b * lo, b * hi)
            ka.scatter_into_pattern(data, slots[part], self.element_values(self.x, lo, hi),
                                    self.scale, self.rows[part], self.cols[part],
                                    free_index, p, coupling)


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
