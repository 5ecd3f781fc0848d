"""Batched barrier over point–edge stencils: the contact of a 2D scene.

A 2D scene lies in the plane z = 0 (positions stay (n, 3)); its bodies meet at their
boundary edges, and its one primitive pair is a point against an edge, the stencil
(p, e0, e1), 9 DOFs. The squared distance is the 3D point–edge distance of
``distance.py`` evaluated at z = 0 (closest feature as ipctk's PointEdgeDistanceType:
P_E0, P_E1 the endpoints, P_E the line), so every formula here is the 3D one:

    B(x) = Σ_{PE pairs, d² < ŝ}  w_k κ b(d_k², ŝ),   ŝ = d̂²

with w_k a per-stencil weight (1 for the paper's barrier; the lecture's A_p d̂ / 16, A_p
the point's contact length) and b the barrier of ``form`` (``barrier.barrier_of_form``:
the paper's −(s − ŝ)² ln(s/ŝ), or the lecture's (s/ŝ − 1) ln(s/ŝ)). No mollifier: two
segments in a plane that come close always do so at an endpoint of one of them.

As for point–triangle and edge–edge pairs (``pair_barrier.py``), every candidate pair is
summed without deduplication: ipctk's merged set (a vertex–vertex collision of weight 2
where a point is closest to the common endpoint of two edges) gives the same value,
gradient and PSD-clamped Hessian.

    ∇(w κ b) = w κ b' ∇d,   ∇²(w κ b) = w κ (b' ∇²d + b'' ∇d ∇dᵀ)

At z = 0 the gradient has no z components, and ∇²d couples no z DOF with an in-plane
one (every such entry is a product with an exactly zero z coordinate). Its z-block
(2 c_i c_j, from the point–line projector's e_z e_zᵀ and the point–point identity)
times b' < 0 is negative semi-definite, so the PSD projection of the whole block is the
projection of its in-plane part alone: that part (6 x 6 at most) is what is decomposed
(``project_psd_in_plane``), and a projected block has exactly zero z rows and columns,
so Newton's z components stay exactly 0.

Inputs: x (n, 3) float64, pe_pairs (k, 3) int64 rows (p, e0, e1), weights (k,), s_hat,
kappa, form. Global DOF of vertex i, axis a is 3i + a.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.algebra.assembly import block_triplet_indices
from ipcsim.kernels.algebra.linalg import ordered_sum, point3, project_psd_on_dofs
from ipcsim.kernels.algebra.scatter import scatter_local_gradients
from ipcsim.kernels.contact.broad_phase import swept_pairs_within
from ipcsim.kernels.contact import pair_barrier
from ipcsim.kernels.contact.distance import PE_FEATURES, point_edge_distance_sq
from ipcsim.kernels.contact.distance import point_edge_distance_type
from ipcsim.compiler.twin import kernel

PE_HESSIAN_BLOCK = 81  # entries per active pair (9 x 9 local Hessian)


# =========================================================================================
# One stencil, V = (p, e0, e1) as tuples (gather_point_edge): its barrier is
# ``pair_barrier.stencil_barrier`` on its closest feature's row of PE_FEATURES.
# =========================================================================================

@njit(cache=True, error_model="numpy")
def gather_point_edge(x, pair):
    """The stencil's three vertex positions as a tuple of 3-tuples (values, not views:
    see ``pair_barrier.gather_stencil``)."""
    return point3(x, pair[0]), point3(x, pair[1]), point3(x, pair[2])


@njit(cache=True, error_model="numpy")
def project_psd_in_plane(H, feature):
    """The PSD projection of a 9 x 9 point–edge block H at z = 0 (module docstring): only
    the x and y DOFs of the closest feature's vertices (``feature``, a row of
    ``distance.PE_FEATURES``) are decomposed; every other entry of the result is 0."""
    nv = 0
    for k in range(1, 5):
        nv += feature[k] >= 0
    dof = np.empty(2 * nv, dtype=np.int64)
    for k in range(nv):
        dof[2 * k] = 3 * feature[1 + k]
        dof[2 * k + 1] = 3 * feature[1 + k] + 1
    return project_psd_on_dofs(H, dof)


# --- one pair of the global arrays (keeps the parallel loop bodies small) -----------------

@njit(cache=True, error_model="numpy")
def _classify(x, pair):
    V = gather_point_edge(x, pair)
    t = point_edge_distance_type(V[0], V[1], V[2])
    return t, point_edge_distance_sq(V[0], V[1], V[2], t)


@njit(cache=True, error_model="numpy")
def _value_at(x, pair, s_hat, kappa, form):
    V = gather_point_edge(x, pair)
    f = PE_FEATURES[point_edge_distance_type(V[0], V[1], V[2])]
    return pair_barrier.stencil_barrier(V, f, s_hat, kappa, form)


@njit(cache=True, error_model="numpy")
def _gradient_at(x, pair, s_hat, kappa, form):
    V = gather_point_edge(x, pair)
    f = PE_FEATURES[point_edge_distance_type(V[0], V[1], V[2])]
    return pair_barrier.stencil_barrier_gradient(V, f, s_hat, kappa, form)


@njit(cache=True, error_model="numpy")
def _hessian_into(x, pair, s_hat, kappa, form, project, vals, base):
    # the 9 x 9 block (projected on its closest feature's vertices) at vals[base:base + 81]
    V = gather_point_edge(x, pair)
    f = PE_FEATURES[point_edge_distance_type(V[0], V[1], V[2])]
    H = pair_barrier.stencil_barrier_hessian(V, f, s_hat, kappa, form)
    if project:
        H = project_psd_in_plane(H, f)
    for r in range(9):
        for c in range(9):
            vals[base + 9 * r + c] = H[r, c]


# =========================================================================================
# Batched kernels
# =========================================================================================

@kernel(parallel=True, error_model="numpy")
def pe_classify_and_distance(x, pe_pairs):
    """Distance type (ipctk's PointEdgeDistanceType codes) and squared distance of every
    point–edge pair: (types (k,) int64, d2 (k,)); a pair is active iff d2 < ŝ."""
    k = pe_pairs.shape[0]
    types = np.empty(k, dtype=np.int64)
    d2 = np.empty(k)
    for i in prange(k):
        types[i], d2[i] = _classify(x, pe_pairs[i])
    return types, d2


@kernel()
def pe_near_pairs(x, pe_pairs, weights, pe_id, inflation):
    """The pairs whose boxes at x, grown by inflation/2, overlap (``broad_phase.
    swept_pairs_within`` over no motion, the point against the edge), in their order,
    with their weights and ids, and each kept pair's type and squared distance at x:
    (pairs, weights, ids, types, d²)."""
    keep = swept_pairs_within(x, x, pe_pairs, 1, inflation)
    pe = pe_pairs[keep]
    types, d2 = pe_classify_and_distance(x, pe)
    return pe, weights[keep], pe_id[keep], types, d2


@kernel(parallel=True, error_model="numpy")
def pe_barrier_value(x, pe_pairs, weights, s_hat, kappa, form):
    """Σ w κ b(d², ŝ) over the active pairs, the per-pair terms summed in pair order."""
    k = pe_pairs.shape[0]
    terms = np.empty(k)
    for i in prange(k):
        terms[i] = weights[i] * _value_at(x, pe_pairs[i], s_hat, kappa, form)
    return ordered_sum(terms)


@kernel(parallel=True, error_model="numpy")
def pe_local_gradients(x, pe_pairs, weights, s_hat, kappa, form):
    """(k, 9) per-pair gradients w κ b' ∇d (zero rows for inactive pairs)."""
    k = pe_pairs.shape[0]
    G = np.empty((k, 9))
    for i in prange(k):
        g = _gradient_at(x, pe_pairs[i], s_hat, kappa, form)
        for a in range(9):
            G[i, a] = weights[i] * g[a]
    return G


@kernel(error_model="numpy")
def pe_barrier_gradient(x, pe_pairs, weights, s_hat, kappa, form):
    """∇B as a flat (3n,) vector: local gradients in parallel, then the shared serial
    scatter (``scatter.scatter_local_gradients``)."""
    G = pe_local_gradients(x, pe_pairs, weights, s_hat, kappa, form)
    return scatter_local_gradients(G, pe_pairs, x.shape[0])


@kernel(parallel=True, error_model="numpy")
def pe_barrier_hessian_blocks(x, pe_pairs, weights, s_hat, kappa, form, project):
    """∇²B as one 9 x 9 block per ACTIVE pair (d² < ŝ), in pair order: (stencils (a, 3)
    int64, vals (81 a,)); block b holds vals[81 b : 81 (b + 1)], row-major over its
    stencil's 9 DOFs (``assembly.block_triplet_indices`` gives each entry's row and
    column). With ``project`` each block is clamped to PSD on the in-plane DOFs of its
    closest feature's vertices (w ≥ 0 commutes with the clamp; z rows and columns 0).
    Blocks of pairs that share vertices are to be summed."""
    _, d2 = pe_classify_and_distance(x, pe_pairs)
    act = np.flatnonzero(d2 < s_hat)
    na = act.shape[0]
    stencils = np.empty((na, 3), dtype=np.int64)
    vals = np.empty(PE_HESSIAN_BLOCK * na)
    for a in prange(na):
        i = act[a]
        for j in range(3):
            stencils[a, j] = pe_pairs[i, j]
        base = PE_HESSIAN_BLOCK * a
        _hessian_into(x, pe_pairs[i], s_hat, weights[i] * kappa, form, project, vals, base)
    return stencils, vals


@kernel(error_model="numpy")
def pe_barrier_hessian_triplets(x, pe_pairs, weights, s_hat, kappa, form, project):
    """∇²B as COO triplets (rows, cols, vals), int32/int32/float64: the entries of
    ``pe_barrier_hessian_blocks`` with their rows and columns, in the same order (81 per
    active pair). Duplicate (row, col) entries are to be summed."""
    stencils, vals = pe_barrier_hessian_blocks(x, pe_pairs, weights, s_hat, kappa, form,
                                               project)
    rows, cols = block_triplet_indices(stencils)
    return rows, cols, vals
