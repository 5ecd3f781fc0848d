"""Vertex–plane contact: the IPC barrier on the squared signed distance, and its exact CCD.

For a vertex x and a plane (o, n) with unit normal n, the signed distance is
d = n·(x − o) and the barrier works on s = d² (ŝ = d̂²), as for mesh contact:

    B = κ b(s, ŝ),   ∇B = κ b'(s) 2d n,   ∇²B = κ (4 s b''(s) + 2 b'(s)) n nᵀ

The Hessian is rank one, so its PSD projection just clamps the scalar coefficient at 0.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.contact.barrier import barrier, barrier_first_derivative, barrier_second_derivative
from ipcsim.compiler.twin import kernel


@njit(cache=True)
def signed_distance(x, v, o, nrm):
    """Signed distance n·(x[v] − o) of vertex v to the plane through o with unit normal n
    (shared with the penalty kernels)."""
    return (nrm[0] * (x[v, 0] - o[0]) + nrm[1] * (x[v, 1] - o[1])
            + nrm[2] * (x[v, 2] - o[2]))


@njit(cache=True)
def plane_distances(x, vertices, origins, normals):
    """Signed distance of every (plane, vertex) pair: (n_planes, n_vertices)."""
    d = np.empty((origins.shape[0], vertices.shape[0]))
    for k in range(origins.shape[0]):
        for j in range(vertices.shape[0]):
            d[k, j] = signed_distance(x, vertices[j], origins[k], normals[k])
    return d


@njit(cache=True)
def plane_barrier_value(x, vertices, origins, normals, s_hat, kappa):
    total = 0.0
    for k in range(origins.shape[0]):
        for j in range(vertices.shape[0]):
            d = signed_distance(x, vertices[j], origins[k], normals[k])
            if d <= 0.0:
                return np.inf  # on or below the plane: infeasible
            s = d * d
            if s < s_hat:
                total += barrier(s, s_hat)
    return kappa * total


@njit(cache=True)
def normal_gradient(n_vertices, vertices, normals, coeff):
    """Flat (3n,) gradient of an energy of the signed distances: Σ_k coeff[k, j] n_k on
    vertex j, where coeff[k, j] = ∂E/∂d of pair (plane k, vertex j) (0 when inactive)."""
    g = np.zeros(n_vertices * 3)
    for k in range(normals.shape[0]):
        for j in range(vertices.shape[0]):
            v = vertices[j]
            for a in range(3):
                g[3 * v + a] += coeff[k, j] * normals[k, a]
    return g


@njit(cache=True)
def normal_hessian_triplets(vertices, normals, active, coeff):
    """COO triplets coeff[k, j] n_k n_kᵀ on vertex j, 9 per active pair."""
    n_active = 0
    for k in range(normals.shape[0]):
        for j in range(vertices.shape[0]):
            if active[k, j]:
                n_active += 1
    rows = np.empty(9 * n_active, dtype=np.int64)
    cols = np.empty(9 * n_active, dtype=np.int64)
    vals = np.empty(9 * n_active)
    i = 0
    for k in range(normals.shape[0]):
        for j in range(vertices.shape[0]):
            if not active[k, j]:
                continue
            v = vertices[j]
            for a in range(3):
                for b in range(3):
                    rows[i] = 3 * v + a
                    cols[i] = 3 * v + b
                    vals[i] = coeff[k, j] * normals[k, a] * normals[k, b]
                    i += 1
    return rows, cols, vals


@njit(cache=True)
def plane_barrier_gradient(x, vertices, origins, normals, s_hat, kappa):
    # ∂B/∂d = κ b'(s) 2d per active pair
    d = plane_distances(x, vertices, origins, normals)
    coeff = np.zeros_like(d)
    for k in range(d.shape[0]):
        for j in range(d.shape[1]):
            s = d[k, j] * d[k, j]
            if s < s_hat:
                coeff[k, j] = kappa * barrier_first_derivative(s, s_hat) * 2.0 * d[k, j]
    return normal_gradient(x.shape[0], vertices, normals, coeff)


@njit(cache=True)
def plane_barrier_hessian(x, vertices, origins, normals, s_hat, kappa):
    """COO triplets, 9 per active pair, already PSD (clamped rank-one coefficient)."""
    d = plane_distances(x, vertices, origins, normals)
    active = d * d < s_hat
    coeff = np.zeros_like(d)
    for k in range(d.shape[0]):
        for j in range(d.shape[1]):
            if active[k, j]:
                s = d[k, j] * d[k, j]
                c = kappa * (4.0 * s * barrier_second_derivative(s, s_hat)
                             + 2.0 * barrier_first_derivative(s, s_hat))
                coeff[k, j] = max(c, 0.0)
    return normal_hessian_triplets(vertices, normals, active, coeff)


@njit(cache=True)
def plane_active_count_and_min_distance(x, vertices, origins, normals, s_hat):
    """Number of pairs with d² < ŝ, and the smallest signed distance (inf if none)."""
    count = 0
    dmin = np.inf
    for k in range(origins.shape[0]):
        for j in range(vertices.shape[0]):
            d = signed_distance(x, vertices[j], origins[k], normals[k])
            if d * d < s_hat:
                count += 1
            dmin = min(dmin, d)
    return count, dmin


@kernel(parallel=True)
def plane_ccd_max_step(x, p, vertices, origins, normals, keep_fraction):
    """Largest α ≤ 1 such that every vertex keeps ≥ keep_fraction of its gap to each plane.

    Along the step the distance is linear, d(α) = d0 + α n·p, so the exact time of impact
    is -d0 / (n·p) when n·p < 0; stopping at (1 - keep_fraction) of it stays off d = 0.
    """
    n_planes = origins.shape[0]
    best = np.ones(vertices.shape[0])
    for j in prange(vertices.shape[0]):
        v = vertices[j]
        for k in range(n_planes):
            d0 = signed_distance(x, v, origins[k], normals[k])
            rate = normals[k, 0] * p[3 * v] + normals[k, 1] * p[3 * v + 1] \
                + normals[k, 2] * p[3 * v + 2]
            if rate < 0.0:
                alpha = (1.0 - keep_fraction) * d0 / (-rate)
                if alpha < best[j]:
                    best[j] = alpha
    return best.min() if best.shape[0] else 1.0
