"""The quadratic and linear terms of the incremental potential (``potentials/``):

    inertia        ½ Σᵢ mᵢ ‖xᵢ − x̃ᵢ‖²
    body force     −Σᵢ mᵢ aᵢ·xᵢ
    damping        ½ Δxᵀ D Δx,  Δx = x − xₙ, D as per-element blocks
    boundary pull  Σ_k (ρ/2) m_k ‖x_k − x̂_k‖² − √m_k λ_k·(x_k − x̂_k)

summed serially in vertex (element) order, so that a term called alone and the same term
in ``all_terms`` give the same bits.
"""

from __future__ import annotations

import math

import numpy as np
from ipcsim.compiler.jit import njit

from ipcsim.kernels.algebra.scatter import block_matvec


@njit(cache=True)
def inertia_value(mass, x, x_tilde):
    total = 0.0
    for i in range(x.shape[0]):
        for a in range(3):
            d = x[i, a] - x_tilde[i, a]
            total += mass[i] * d * d
    return 0.5 * total


@njit(cache=True)
def inertia_gradient(mass, x, x_tilde):
    """Flat (3n,): mᵢ (xᵢ − x̃ᵢ)."""
    g = np.empty(3 * x.shape[0])
    for i in range(x.shape[0]):
        for a in range(3):
            g[3 * i + a] = mass[i] * (x[i, a] - x_tilde[i, a])
    return g


@njit(cache=True)
def lumped_mass_diagonal(mass):
    """Flat (3n,): the diagonal of the lumped mass matrix, inertia's Hessian."""
    diagonal = np.empty(3 * mass.shape[0])
    for t in range(diagonal.shape[0]):
        diagonal[t] = mass[t // 3]
    return diagonal


@njit(cache=True)
def body_force_value(mass, acceleration, x):
    total = 0.0
    for i in range(x.shape[0]):
        for a in range(3):
            total += mass[i] * acceleration[i, a] * x[i, a]
    return -total


@njit(cache=True)
def body_force_gradient(mass, acceleration):
    """Flat (3n,): −mᵢ aᵢ (constant in x)."""
    g = np.empty(3 * mass.shape[0])
    for i in range(mass.shape[0]):
        for a in range(3):
            g[3 * i + a] = -(mass[i] * acceleration[i, a])
    return g


@njit(cache=True)
def damping_value(x, x_start, vals, scale, elements):
    """½ Δxᵀ D Δx with D = scale·Σₑ Bₑ (``scatter.block_matvec``'s blocks)."""
    dx = (x - x_start).reshape(-1)
    d_dx = block_matvec(vals, scale, elements, dx)
    total = 0.0
    for i in range(dx.shape[0]):
        total += dx[i] * d_dx[i]
    return 0.5 * total


@njit(cache=True)
def pull_value(x, vertices, mass, target, rho, lam, has_lam):
    """The pull's energy; λ is taken as zero unless ``has_lam``."""
    spring = 0.0
    multiplier = 0.0
    for k in range(vertices.shape[0]):
        root = math.sqrt(mass[k])
        for a in range(3):
            d = x[vertices[k], a] - target[k, a]
            spring += mass[k] * d * d
            if has_lam:
                multiplier += root * lam[k, a] * d
    energy = 0.5 * rho * spring
    if has_lam:
        energy -= multiplier
    return energy


@njit(cache=True)
def pull_gradient(x, vertices, mass, target, rho, lam, has_lam):
    """Flat (3n,): ρ m_k (x_k − x̂_k) − √m_k λ_k on the pulled vertices, zero elsewhere."""
    g = np.zeros(3 * x.shape[0])
    for k in range(vertices.shape[0]):
        v = vertices[k]
        for a in range(3):
            gk = rho * mass[k] * (x[v, a] - target[k, a])
            if has_lam:
                gk -= math.sqrt(mass[k]) * lam[k, a]
            g[3 * v + a] = gk
    return g


@njit(cache=True)
def pull_hessian_diagonal(vertices, mass, rho):
    """(DOFs (3k,), ρ m_k on each): the pull's Hessian, diagonal on the pulled vertices."""
    k = vertices.shape[0]
    dofs = np.empty(3 * k, dtype=np.int64)
    diagonal = np.empty(3 * k)
    for j in range(k):
        for a in range(3):
            dofs[3 * j + a] = 3 * vertices[j] + a
            diagonal[3 * j + a] = rho * mass[j]
    return dofs, diagonal
