"""Quadratic penalty contact (the baseline IPC is compared against), and a penetration
depth measure for checking runs.

For a pair at distance d < d̂ the energy is

    P(d) = ½ k (d̂ − d)²

with d the signed distance for vertex–plane pairs and the unsigned closest-feature distance
for point–triangle and edge–edge pairs (as the barrier's pairs, without the mollifier). A
penalty only pushes back once d < d̂ and nothing keeps d > 0: with the unsigned distance a
vertex that gets through a surface is pushed on through it.

Mesh pairs work with the squared distance s = d² (the distance kernels' currency):

    f(s)   = ½ k (d̂ − √s)²
    f'(s)  = −k (d̂ − √s) / (2√s)
    f''(s) = k d̂ / (4 s^{3/2})
    ∇P = f' ∇s,   ∇²P = f' ∇²s + f'' ∇s ∇sᵀ

(f'' > 0 but f' < 0 times the indefinite ∇²s: each local Hessian is projected to PSD on
the block of its closest feature). Planes: ∇P = −k (d̂ − d) n, ∇²P = k n nᵀ (PSD).
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.contact.pair_barrier import (
    HESSIAN_BLOCK,
    classify_and_distance,
    gather_stencil,
    project_psd_on_feature,
    write_hessian_block,
)
from ipcsim.kernels.contact import distance as kd
from ipcsim.kernels.contact.intersection import solid_angle
from ipcsim.kernels.contact.plane_barrier import (
    normal_gradient,
    normal_hessian_triplets,
    plane_distances,
    signed_distance,
)
from ipcsim.kernels.algebra.linalg import chain_gradient, chain_hessian, ordered_sum
from ipcsim.kernels.algebra.scatter import scatter_stencil_gradients
from ipcsim.compiler.twin import kernel


# =========================================================================================
# Vertex–plane pairs
# =========================================================================================

@njit(cache=True)
def plane_penalty_value(x, vertices, origins, normals, dhat, k):
    # Σ ½ k max(0, d̂ − d)²
    total = 0.0
    for p in range(origins.shape[0]):
        for j in range(vertices.shape[0]):
            gap = dhat - signed_distance(x, vertices[j], origins[p], normals[p])
            if gap > 0.0:
                total += 0.5 * k * gap * gap
    return total


@njit(cache=True)
def plane_penalty_gradient(x, vertices, origins, normals, dhat, k):
    # ∂P/∂d = −k (d̂ − d) per active pair
    gap = dhat - plane_distances(x, vertices, origins, normals)
    return normal_gradient(x.shape[0], vertices, normals, -k * np.maximum(gap, 0.0))


@njit(cache=True)
def plane_penalty_hessian(x, vertices, origins, normals, dhat, k):
    """COO triplets k n nᵀ, 9 per active pair (PSD as it stands)."""
    d = plane_distances(x, vertices, origins, normals)
    return normal_hessian_triplets(vertices, normals, d < dhat, np.full(d.shape, k))


# =========================================================================================
# Point–triangle and edge–edge pairs
# =========================================================================================

@njit(cache=True, error_model="numpy")
def _penalty_of_sq(s, dhat, k):
    """(f, f', f'') of f(s) = ½ k (d̂ − √s)² for s < d̂²."""
    d = np.sqrt(s)
    gap = dhat - d
    return 0.5 * k * gap * gap, -k * gap / (2.0 * d), k * dhat / (4.0 * s * d)


@njit(cache=True, error_model="numpy")
def _closest_feature(V, is_pt):
    """The closest-feature row (``distance.PT_FEATURES`` / ``EE_FEATURES``) of a gathered
    stencil."""
    if is_pt:
        return kd.PT_FEATURES[kd.point_triangle_distance_type(V[0], V[1], V[2], V[3])]
    return kd.EE_FEATURES[kd.edge_edge_distance_type(V[0], V[1], V[2], V[3])]


@njit(cache=True, error_model="numpy")
def _pair_derivatives(V, is_pt):
    """(d², ∇d², ∇²d², closest-feature row) of a gathered stencil."""
    f = _closest_feature(V, is_pt)
    return (kd.feature_distance_sq(V, f), kd.feature_distance_sq_gradient(V, f),
            kd.feature_distance_sq_hessian(V, f), f)


@njit(cache=True, error_model="numpy")
def _pair_value(x, pair, is_pt, dhat, k):
    V = gather_stencil(x, pair)
    s = kd.feature_distance_sq(V, _closest_feature(V, is_pt))
    if s >= dhat * dhat:
        return 0.0
    return _penalty_of_sq(s, dhat, k)[0]


@njit(cache=True, error_model="numpy")
def _pair_gradient(x, pair, is_pt, dhat, k):
    # ∇P = f'(s) ∇s
    s, g, _, _ = _pair_derivatives(gather_stencil(x, pair), is_pt)
    if s >= dhat * dhat:
        return np.zeros(12)
    _, f1, _ = _penalty_of_sq(s, dhat, k)
    return chain_gradient(g, f1)


@njit(cache=True, error_model="numpy")
def _pair_hessian_into(x, pair, is_pt, dhat, k, project, rows, cols, vals, base):
    # ∇²P = f'(s) ∇²s + f''(s) ∇s ∇sᵀ, projected to PSD on the closest feature's block
    s, g, H, feature = _pair_derivatives(gather_stencil(x, pair), is_pt)
    _, f1, f2 = _penalty_of_sq(s, dhat, k)
    chain_hessian(H, g, f1, f2, 1.0)
    if project:
        H = project_psd_on_feature(H, feature)
    write_hessian_block(rows, cols, vals, base, pair, H)


@kernel(parallel=True, error_model="numpy")
def mesh_penalty_value(x, pt_pairs, ee_pairs, dhat, k):
    """Σ ½ k (d̂ − d)² over the pairs closer than d̂ (per-pair terms summed in order, so
    the value is deterministic)."""
    n_pt = pt_pairs.shape[0]
    terms = np.empty(n_pt + ee_pairs.shape[0])
    for i in prange(n_pt):
        terms[i] = _pair_value(x, pt_pairs[i], True, dhat, k)
    for i in prange(ee_pairs.shape[0]):
        terms[n_pt + i] = _pair_value(x, ee_pairs[i], False, dhat, k)
    return ordered_sum(terms)


@kernel(parallel=True, error_model="numpy")
def _local_gradients(x, pt_pairs, ee_pairs, dhat, k):
    n_pt = pt_pairs.shape[0]
    G = np.empty((n_pt + ee_pairs.shape[0], 12))
    for i in prange(n_pt):
        G[i] = _pair_gradient(x, pt_pairs[i], True, dhat, k)
    for i in prange(ee_pairs.shape[0]):
        G[n_pt + i] = _pair_gradient(x, ee_pairs[i], False, dhat, k)
    return G


@kernel(error_model="numpy")
def mesh_penalty_gradient(x, pt_pairs, ee_pairs, dhat, k):
    """∇P as a flat (3n,) vector: local gradients in parallel, then a serial scatter."""
    G = _local_gradients(x, pt_pairs, ee_pairs, dhat, k)
    return scatter_stencil_gradients(G, pt_pairs, ee_pairs, x.shape[0])


@kernel(parallel=True, error_model="numpy")
def mesh_penalty_hessian(x, pt_pairs, ee_pairs, dhat, k, project):
    """∇²P as COO triplets, 144 per active pair (d < d̂), active point–triangle pairs
    first; the same layout as ``contact_barrier.barrier_hessian_triplets``."""
    _, pt_d2, _, ee_d2 = classify_and_distance(x, pt_pairs, ee_pairs)
    s_hat = dhat * dhat
    pt_act = np.flatnonzero(pt_d2 < s_hat)
    ee_act = np.flatnonzero(ee_d2 < s_hat)
    na = pt_act.shape[0]
    total = HESSIAN_BLOCK * (na + ee_act.shape[0])
    rows = np.empty(total, dtype=np.int64)
    cols = np.empty(total, dtype=np.int64)
    vals = np.empty(total)
    for a in prange(na):
        _pair_hessian_into(x, pt_pairs[pt_act[a]], True, dhat, k, project,
                           rows, cols, vals, HESSIAN_BLOCK * a)
    for a in prange(ee_act.shape[0]):
        _pair_hessian_into(x, ee_pairs[ee_act[a]], False, dhat, k, project,
                           rows, cols, vals, HESSIAN_BLOCK * (na + a))
    return rows, cols, vals


# =========================================================================================
# Penetration depth (for checking runs, not for simulating)
# =========================================================================================

@kernel(parallel=True)
def penetration_depths(x, query, triangles):
    """For each query vertex, its distance to the closed, outward-oriented surface
    ``triangles`` when it lies inside it (winding number > ½), else 0."""
    depth = np.zeros(query.shape[0])
    for i in prange(query.shape[0]):
        p = x[query[i]]
        winding = 0.0
        for t in range(triangles.shape[0]):
            winding += solid_angle(p, x[triangles[t, 0]], x[triangles[t, 1]],
                                   x[triangles[t, 2]])
        if abs(winding) < 2.0 * np.pi:  # |winding number| = |Σ Ω| / 4π < ½: outside
            continue
        best = np.inf
        for t in range(triangles.shape[0]):
            tri = triangles[t]
            best = min(best, kd.point_triangle_distance_sq(p, x[tri[0]], x[tri[1]], x[tri[2]]))
        depth[i] = np.sqrt(best)
    return depth
