"""The lecture's half-plane barrier (phys-sim-book, lessons 3-8): a 2D scene's contact
with its lines when the scene asks for the lecture's barrier.

For a vertex x_j and a line (o, n) with unit normal n, d = n·(x_j − o) as for the
paper's planes (``plane_barrier.signed_distance``), and the barrier works on d itself:

    B = Σ_{k, j: d < d̂} w_j b_L(d_kj, d̂),   w_j = A_j d̂ / 2

(A_j the vertex's contact length, ``barrier.lecture_barrier_and_derivatives`` b_L), at
unit stiffness. ∇B = w b_L'(d) n, ∇²B = w b_L''(d) n nᵀ with b_L'' = (d + d̂)/(d² d̂) > 0:
every block is PSD as it is. The step bound is the planes' (``plane_ccd_max_step``) and
friction's normal force λ = −κ w b_L'(d).
"""

from __future__ import annotations

import numpy as np

from ipcsim.compiler.jit import njit
from ipcsim.kernels.contact.barrier import lecture_barrier_and_derivatives
from ipcsim.kernels.contact.friction import lag_vertex_plane_pairs
from ipcsim.kernels.contact.plane_barrier import normal_gradient, normal_hessian_triplets
from ipcsim.kernels.contact.plane_barrier import plane_distances


@njit(cache=True)
def _weighted(d, dhat, weights, order):
    """w_j b_L⁽ᵒʳᵈᵉʳ⁾(d_kj, d̂) (order 0, 1 or 2) of the pairs within d̂, 0 elsewhere."""
    c = np.zeros_like(d)
    for k in range(d.shape[0]):
        for j in range(d.shape[1]):
            if d[k, j] < dhat:
                c[k, j] = weights[j] * lecture_barrier_and_derivatives(d[k, j], dhat)[order]
    return c


@njit(cache=True)
def line_barrier_value(x, vertices, origins, normals, dhat, weights):
    d = plane_distances(x, vertices, origins, normals)
    if (d <= 0.0).any():
        return np.inf  # on or beyond a line: infeasible
    terms = _weighted(d, dhat, weights, 0)
    total = 0.0
    for k in range(d.shape[0]):  # in pair order, as the terms were always summed
        for j in range(d.shape[1]):
            total += terms[k, j]
    return total


@njit(cache=True)
def line_barrier_gradient(x, vertices, origins, normals, dhat, weights):
    # ∂B/∂d = w b_L'(d) per active pair
    d = plane_distances(x, vertices, origins, normals)
    return normal_gradient(x.shape[0], vertices, normals, _weighted(d, dhat, weights, 1))


@njit(cache=True)
def line_barrier_hessian(x, vertices, origins, normals, dhat, weights):
    """COO triplets, 9 per active pair (PSD: b_L'' > 0)."""
    d = plane_distances(x, vertices, origins, normals)
    return normal_hessian_triplets(vertices, normals, d < dhat, _weighted(d, dhat, weights, 2))


@njit(cache=True)
def lag_line_pairs(x_lag, vertices, origins, normals, dhat, weights, kappa):
    """Lagged friction data of the active vertex–line pairs (0 < d < d̂), in the layout of
    ``friction.lag_vertex_plane_pairs``: (line (m,), verts (m, 4), coeffs (m, 4), basis
    (m, 3, 2), λ (m,)), λ = −κ w b_L'(d)."""
    d = plane_distances(x_lag, vertices, origins, normals)
    return lag_vertex_plane_pairs(vertices, normals, (d > 0.0) & (d < dhat),
                                  _weighted(d, dhat, -kappa * weights, 1))
