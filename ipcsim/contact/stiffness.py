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

import numpy as np

from ..kernels.barrier import barrier_second_derivative


def kappa_bounds(bbox_diagonal: float, dhat: float, mean_mass: float,
                 multiplier: float = 1e11) -> tuple[float, float]:
    d0 = (1e-8 * bbox_diagonal) ** 2
    if d0 >= dhat * dhat:  # d̂ below 1e-8·l: b'' is 0 there; take the middle of the range
        d0 = 0.5 * dhat * dhat  # (as ipctk)
    kappa_min = multiplier * mean_mass / (4.0 * d0 * barrier_second_derivative(d0, dhat * dhat))
    return kappa_min, 100.0 * kappa_min


def balanced_kappa(g_barrier: np.ndarray, g_rest: np.ndarray, kappa_min: float,
                   kappa_max: float) -> float:
    gb2 = float(g_barrier @ g_barrier)
    if gb2 == 0.0:
        return kappa_min
    return float(np.clip(-(g_barrier @ g_rest) / gb2, kappa_min, kappa_max))


def should_double(prev_min_d_sq: float, min_d_sq: float, eps_sq: float) -> bool:
    """The original's update: contacts tighter than dTol and getting tighter."""
    return prev_min_d_sq < eps_sq and min_d_sq < eps_sq and min_d_sq < prev_min_d_sq
