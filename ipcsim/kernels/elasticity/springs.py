"""Mass-spring edges: the lecture's spring energy (phys-sim-book, lessons 1-5), its
gradient and PSD-projected Hessian.

Per spring (i, j) with rest length l (l² given), stiffness k and d = x_i − x_j:

    E  = ½ k l² (|d|²/l² − 1)²
    ∇_{x_i} E = −∇_{x_j} E = 2k (|d|²/l² − 1) d
    ∇² E = [[H_d, −H_d], [−H_d, H_d]],   H_d = (2k/l²) (2 d dᵀ + (|d|² − l²) I)

exactly as the lecture's MassSpringEnergy writes it (its ``l2`` is l², its ``k`` this k).
H_d has the eigenvalue (2k/l²)(3|d|² − l²) along d and (2k/l²)(|d|² − l²) across it (every
direction across d, z among them), so the 6 x 6 block's eigenvalues are twice those and
0: the projection clamps the two at 0 (the lecture clamps the same with an eigen-
decomposition). A compressed spring (|d| < l) has no stiffness across d after the
projection; at |d| = 0 there is none at all.

A spring cannot invert: its energy stays finite through |d| = 0, so it adds no bound to
the line search.

Layout: x (n, 3), springs (m, 2) int64, rest_length_sq (m,), stiffness (m,). Gradients
are flat (3n,); Hessians 36 values per spring at offset 36·e, row-major over the local
DOFs 3·v + a (``assembly.block_triplet_indices(springs)`` gives their rows and columns).
In a 2D scene d has no z part, so neither has the gradient, and H_d couples no z DOF with
an in-plane one.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.algebra.linalg import ordered_sum
from ipcsim.kernels.algebra.scatter import scatter_local_gradients
from ipcsim.compiler.twin import kernel


@njit(cache=True, inline="always")
def _stretch(x, springs, e):
    # d = x_i − x_j and |d|²
    i, j = springs[e, 0], springs[e, 1]
    d = (x[i, 0] - x[j, 0], x[i, 1] - x[j, 1], x[i, 2] - x[j, 2])
    return d, d[0] * d[0] + d[1] * d[1] + d[2] * d[2]


@kernel(parallel=True)
def spring_energy(x, springs, rest_length_sq, stiffness):
    """Σ ½ k l² (|d|²/l² − 1)², the per-spring terms summed in spring order."""
    m = springs.shape[0]
    terms = np.empty(m)
    for e in prange(m):
        _, dd = _stretch(x, springs, e)
        s = dd / rest_length_sq[e] - 1.0
        terms[e] = 0.5 * stiffness[e] * rest_length_sq[e] * s * s
    return ordered_sum(terms)


@kernel(parallel=True)
def spring_local_gradients(x, springs, rest_length_sq, stiffness):
    """Per-spring gradients (m, 6): 2k (|d|²/l² − 1) d on x_i, its negative on x_j."""
    m = springs.shape[0]
    out = np.empty((m, 6))
    for e in prange(m):
        d, dd = _stretch(x, springs, e)
        c = 2.0 * stiffness[e] * (dd / rest_length_sq[e] - 1.0)
        for a in range(3):
            out[e, a] = c * d[a]
            out[e, 3 + a] = -c * d[a]
    return out


@kernel()
def spring_gradient(x, springs, rest_length_sq, stiffness):
    """∂E/∂x as a flat (3n,) vector (the shared serial scatter of the local gradients)."""
    local = spring_local_gradients(x, springs, rest_length_sq, stiffness)
    return scatter_local_gradients(local, springs, x.shape[0])


@njit(cache=True, inline="always")
def _block_along_across(d, dd, l2, k, project):
    # H_d = a d̂d̂ᵀ + b (I − d̂d̂ᵀ): a along d, b across it, clamped at 0 when projecting;
    # returns (a, b) and the 1/|d|² that turns d dᵀ into d̂d̂ᵀ (0 at |d| = 0)
    a = 2.0 * k / l2 * (3.0 * dd - l2)
    b = 2.0 * k / l2 * (dd - l2)
    if project:
        a = max(a, 0.0)
        b = max(b, 0.0)
    inv = 1.0 / dd if dd > 0.0 else 0.0
    if dd == 0.0:
        a = b  # no direction: H_d = b I
    return a, b, inv


@kernel(parallel=True)
def spring_hessian_values(x, springs, rest_length_sq, stiffness, project):
    """Values (36 m,) of the 6 x 6 spring blocks [[H_d, −H_d], [−H_d, H_d]] (module
    docstring), each projected to PSD when ``project``."""
    m = springs.shape[0]
    vals = np.empty(36 * m)
    for e in prange(m):
        d, dd = _stretch(x, springs, e)
        a, b, inv = _block_along_across(d, dd, rest_length_sq[e], stiffness[e], project)
        for r in range(3):
            for c in range(3):
                h = (a - b) * d[r] * d[c] * inv + (b if r == c else 0.0)
                for vi in range(2):
                    for vj in range(2):
                        sign = 1.0 if vi == vj else -1.0
                        vals[36 * e + 6 * (3 * vi + r) + 3 * vj + c] = sign * h
    return vals
