"""The IPC log barrier, written in squared distance as the original program does.

    b(s; ŝ) = -(s - ŝ)² ln(s / ŝ)   for 0 < s < ŝ,   0 for s ≥ ŝ

with s = d² and ŝ = d̂². It is C² at s = ŝ and grows without bound as s -> 0.
Derivatives are with respect to s.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit
from ipcsim.kernels.algebra.linalg import dot


@njit(cache=True)
def barrier_and_derivatives(s, s_hat):
    """(b, b', b'') at s in one pass (one logarithm); all three are 0 for s ≥ ŝ.
    For s ≤ 0 the value is +inf (the derivatives are then meaningless)."""
    if s >= s_hat:
        return 0.0, 0.0, 0.0
    if s <= 0.0:
        return np.inf, -np.inf, np.inf
    r = s - s_hat
    lg = np.log(s / s_hat)
    b = -r * r * lg  # b = −(s − ŝ)² ln(s/ŝ)
    db = -2.0 * r * lg - r * r / s  # b' = −2 (s − ŝ) ln(s/ŝ) − (s − ŝ)²/s
    d2b = -2.0 * lg - 4.0 * r / s + (r / s) ** 2  # b'' = −2 ln(s/ŝ) − 4 (s − ŝ)/s + (s − ŝ)²/s²
    return b, db, d2b


@njit(cache=True)
def barrier(s, s_hat):
    return barrier_and_derivatives(s, s_hat)[0]


@njit(cache=True)
def barrier_first_derivative(s, s_hat):
    return barrier_and_derivatives(s, s_hat)[1]


@njit(cache=True)
def barrier_second_derivative(s, s_hat):
    return barrier_and_derivatives(s, s_hat)[2]


# --- the lecture's barrier (phys-sim-book, lessons 3-8) ----------------------------------
# The course's simulator writes its barrier as
#
#     b_L(r; r̂) = (r/r̂ − 1) ln(r/r̂)   for 0 < r < r̂,   0 for r ≥ r̂
#
# on the distance itself for a half-plane (r = d, r̂ = d̂, weight A d̂ / 2) and on the
# squared distance for a point–edge pair (r = d², r̂ = d̂², weight A d̂ / 16), A the
# contact length of the node. It is C¹ at r = r̂ (b_L' = 0 there), not C² as b is.

BARRIER_IPC = 0  # b(s, ŝ) = −(s − ŝ)² ln(s/ŝ): the paper's, on squared distances
BARRIER_LECTURE = 1  # b_L(r, r̂) = (r/r̂ − 1) ln(r/r̂): the lecture's


@njit(cache=True)
def lecture_barrier_and_derivatives(r, r_hat):
    """(b_L, b_L', b_L'') at r (derivatives with respect to r); all 0 for r ≥ r̂, +inf
    value for r ≤ 0."""
    if r >= r_hat:
        return 0.0, 0.0, 0.0
    if r <= 0.0:
        return np.inf, -np.inf, np.inf
    rho = r / r_hat
    lg = np.log(rho)
    b = (rho - 1.0) * lg  # b_L = (r/r̂ − 1) ln(r/r̂)
    db = lg / r_hat + (rho - 1.0) / r  # b_L' = ln(r/r̂)/r̂ + (r/r̂ − 1)/r
    d2b = (r + r_hat) / (r * r * r_hat)  # b_L'' = (r + r̂)/(r² r̂)
    return b, db, d2b


@njit(cache=True)
def barrier_of_form(form, s, s_hat):
    """(b, b', b'') of the barrier ``form`` (BARRIER_IPC or BARRIER_LECTURE) at s."""
    if form == BARRIER_LECTURE:
        return lecture_barrier_and_derivatives(s, s_hat)
    return barrier_and_derivatives(s, s_hat)


@njit(cache=True)
def balanced_stiffness(g_barrier, g_rest, kappa_min, kappa_max):
    """κ = clamp(−(g_B · g_E) / ‖g_B‖², κ_min, κ_max), κ_min where g_B = 0: the κ that
    balances the barrier's force against the rest (``contact/stiffness.py``), summed in
    index order (``linalg.dot``) wherever it is taken."""
    gb2 = dot(g_barrier, g_barrier)
    if gb2 == 0.0:
        return kappa_min
    kappa = -dot(g_barrier, g_rest) / gb2
    if kappa < kappa_min:
        return kappa_min
    if kappa > kappa_max:
        return kappa_max
    return kappa
