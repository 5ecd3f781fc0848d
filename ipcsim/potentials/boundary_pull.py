"""The pull of prescribed vertices towards targets the Newton step could not take them to:
an augmented Lagrangian, as the original's moving boundary conditions (IPC, section 4.2):

    E_pull(x) = Σ_k (ρ/2) m_k ‖x_k − x̂_k‖² − √m_k λ_k · (x_k − x̂_k)

over the pulled vertices k (prescribed vertices of bodies: m_k > 0), with targets x̂_k.
While it acts, those vertices are free DOFs of the step, so the Newton direction balances
the pull against contact instead of forcing the prescribed motion through it (which CCD
then cuts to a sliver of a step, iteration after iteration). ``StepProblem`` adds it to
the step's potential and tightens it (``PullSchedule``): ρ doubles while the vertices do
not close in, until

    completion = 1 − √(Σ_k ‖x_k − x̂_k‖² / Σ_k ‖x̂_k − x_k⁰‖²) ≥ 1 − 10⁻³

(x⁰: the step's start), when the vertices stay where they are for the rest of the step.
Once they have nearly closed in (the Newton step small, 99 % done), the objective places
them on their targets, where moving them there alone meets no contact and inverts no tet;
the pull ends with their motion done. Where that move is not free,
λ_k ← λ_k − ρ √m_k (x_k − x̂_k), as the original does at that point.
"""

from __future__ import annotations

from typing import ClassVar

from msgspec import Struct
from msgspec.structs import replace
import numpy as np

from ..kernels.terms import all_terms as terms_kernels
from ..kernels.terms.simple import pull_gradient, pull_hessian_diagonal, pull_value
from .base import StepContext, Triplets

START_RHO = 1e6  # ρ at the start of a pull (the original's)
MAX_RHO = 1e8  # ρ is doubled up to this


class BoundaryPull(Struct, frozen=True, eq=False):
    """The augmented-Lagrangian pull of prescribed vertices towards their targets (module
    docstring)."""

    vertices: np.ndarray  # (k,) int64, the pulled vertices
    mass: np.ndarray  # (k,) their lumped masses
    target: np.ndarray  # (k, 3) their targets x̂
    start: np.ndarray  # (k, 3) their positions at the step's start
    rho: float = START_RHO
    lam: np.ndarray | None = None  # (k, 3) multipliers λ; zero when None
    name: ClassVar[str] = "boundary_pull"
    kind: ClassVar[int] = terms_kernels.PULL  # its data in the all-terms kernels
    constant_pattern: ClassVar[bool] = False

    def _offset(self, x) -> np.ndarray:
        return x[self.vertices] - self.target

    def _args(self):
        lam = self.lam if self.lam is not None else np.zeros_like(self.target)
        return self.vertices, self.mass, self.target, float(self.rho), lam, \
            self.lam is not None

    def value(self, x, ctx: StepContext | None = None) -> float:
        return pull_value(x, *self._args())

    def gradient(self, x, ctx: StepContext | None = None) -> np.ndarray:
        return pull_gradient(x, *self._args())

    def hessian(self, x, ctx: StepContext | None = None) -> Triplets:
        dofs, diagonal = pull_hessian_diagonal(self.vertices, self.mass, float(self.rho))
        return Triplets(dofs, dofs, diagonal)

    def completion(self, x) -> float:
        """The part of the pulled vertices' prescribed motion done at x (1: all)."""
        total = float(np.sum((self.target - self.start) ** 2))
        if total == 0.0:
            return 1.0
        return 1.0 - float(np.sqrt(np.sum(self._offset(x) ** 2) / total))

    def stiffer(self) -> "BoundaryPull":
        return replace(self, rho=min(2.0 * self.rho, MAX_RHO))

    def with_updated_multipliers(self, x) -> "BoundaryPull":
        """λ_k ← λ_k − ρ √m_k (x_k − x̂_k): the first-order multiplier update."""
        lam = np.zeros_like(self.target) if self.lam is None else self.lam
        return replace(self, lam=lam - self.rho * np.sqrt(self.mass)[:, None] * self._offset(x))


class PullSchedule(Struct, frozen=True):
    """When a pull tightens, as the original's: after a Newton iteration that ended at x
    with direction p, ρ doubles if the vertices fell back behind where the pull started
    (``completion < started_at``); otherwise, once the step is small (‖p‖∞ below
    ``small_step``, the original's √(10⁻⁴ l² h²) = 0.01·l·h), ρ doubles while less than
    99 % is done; after that the pull is in its tail (``in_tail``), where the objective
    places the vertices on their targets if nothing is in their way, else the
    multipliers update."""

    started_at: float  # the completion when the pull started
    small_step: float
    done: ClassVar[float] = 1.0 - 1e-3  # the completion at which a pull ends
    tail: ClassVar[float] = 0.99  # the completion from which a pull is in its tail

    def in_tail(self, pull: BoundaryPull, x, p) -> bool:
        """Whether the vertices have nearly closed in: the step small, ``tail`` done and
        the pull not yet done. Pulled on with ρ and λ, they took iterations of α < 1 to
        cover the last percent (half of a tb1 step's, at h = 0.2 s)."""
        completion = pull.completion(x)
        return (self.tail <= completion < self.done
                and np.abs(p).max(initial=0.0) < self.small_step)

    def next(self, pull: BoundaryPull, x, p) -> tuple[BoundaryPull | None, bool]:
        """(the pull for the next iteration, None when it is done; whether it changed)."""
        completion = pull.completion(x)
        if completion >= self.done:
            return None, True
        if completion < self.started_at and pull.rho < MAX_RHO:
            return pull.stiffer(), True
        if np.abs(p).max(initial=0.0) < self.small_step:
            if completion < self.tail and pull.rho < MAX_RHO:
                return pull.stiffer(), True
            return pull.with_updated_multipliers(x), True
        return pull, False
