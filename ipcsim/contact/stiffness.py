"""Adaptive barrier stiffness κ, as the original IPC program and the IPC Toolkit set it.

    d₀    = (1e-8 · l)², or ½ d̂² when that is not below d̂²  (a squared distance)
    κ_min = c · m̄ / (4 d₀ · b''(d₀, d̂²))                   c = kappaMinMultiplier (1e11)
    κ_max = 100 κ_min
    κ     = clamp(−(g_B · g_E) / ‖g_B‖², κ_min, κ_max)     when contacts exist

g_B is the barrier gradient at κ = 1 and g_E the gradient of the rest of the incremental
potential, both over free DOFs: κ balances the two forces. During Newton, κ doubles (up to
κ_max) when the closest contact is closer than ε = dTol·l and still approaching.
"""

from __future__ import annotations

import math

from msgspec import Struct
from msgspec.structs import replace
import numpy as np

from ..kernels.contact.barrier import balanced_stiffness, barrier_second_derivative


def kappa_bounds(bbox_diagonal: float, dhat: float, mean_mass: float,
                 multiplier: float = 1e11) -> tuple[float, float]:
    d0 = (1e-8 * bbox_diagonal) ** 2
    if d0 >= dhat * dhat:  # d̂ below 1e-8·l: b'' is 0 there; take the middle of the range
        d0 = 0.5 * dhat * dhat  # (as ipctk)
    kappa_min = multiplier * mean_mass / (4.0 * d0 * barrier_second_derivative(d0, dhat * dhat))
    return kappa_min, 100.0 * kappa_min


def balanced_kappa(g_barrier: np.ndarray, g_rest: np.ndarray, kappa_min: float,
                   kappa_max: float) -> float:
    """The κ that balances the two gradients (a kernel: two sums in index order)."""
    return float(balanced_stiffness(np.ascontiguousarray(g_barrier, dtype=np.float64),
                                    np.ascontiguousarray(g_rest, dtype=np.float64),
                                    float(kappa_min), float(kappa_max)))


def should_double(prev_min_d_sq: float, min_d_sq: float, eps_sq: float) -> bool:
    """The original's doubling of κ: the closest contact is tighter than dTol (ε² =
    eps_sq) and getting tighter (squared distances)."""
    return prev_min_d_sq < eps_sq and min_d_sq < eps_sq and min_d_sq < prev_min_d_sq


class BarrierStiffness(Struct, frozen=True):
    """κ and the state its adaptation carries through one time step.

    ``adaptive`` False: κ is the scene's fixed value. Otherwise κ is balanced once, at the
    first Newton iterate of the step with a contact, and doubled while the closest
    contact keeps closing in below dTol (``min_distance_sq`` is the last iterate's)."""

    kappa: float
    kappa_min: float
    kappa_max: float
    eps_sq: float  # (dTol·l)²
    adaptive: bool = True
    balanced: bool = False
    min_distance_sq: float = math.inf

    def new_step(self) -> "BarrierStiffness":
        """The state at the start of a step: κ carried over, nothing balanced yet."""
        return replace(self, balanced=not self.adaptive, min_distance_sq=math.inf)

    def needs_balance(self, contacts: int) -> bool:
        return self.adaptive and contacts > 0 and not self.balanced

    def at_iterate(self, contacts: int, min_distance: float, g_barrier=None,
                   g_rest=None) -> "BarrierStiffness":
        """κ for the Newton iterate with ``contacts`` active pairs and closest distance
        ``min_distance``; ``g_barrier`` / ``g_rest`` (free DOFs) when it needs balance."""
        if not self.adaptive:
            return self
        kappa, balanced = self.kappa, self.balanced
        if self.needs_balance(contacts):
            kappa = balanced_kappa(g_barrier, g_rest, self.kappa_min, self.kappa_max)
            balanced = True
        d_sq = min_distance * min_distance
        if should_double(self.min_distance_sq, d_sq, self.eps_sq):
            kappa = min(self.kappa_max, 2.0 * kappa)
        return replace(self, kappa=kappa, balanced=balanced, min_distance_sq=d_sq)
