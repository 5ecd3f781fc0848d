"""Batched IPC barrier over candidate contact pairs (point-triangle and edge-edge).

    B(x) = Σ_{PT pairs, d² < ŝ}  κ b(d², ŝ)  +  Σ_{EE pairs, d² < ŝ}  κ m(x) b(d², ŝ)

with b(s, ŝ) = −(s − ŝ)² ln(s/ŝ), ŝ = d̂², d² the pair's squared distance to its closest
feature (distance type chosen at x, ipctk's AUTO rule) and m the edge-edge mollifier
(kernels/contact/mollifier.py, ε from rest positions, passed in as ``ee_eps_x``).

No deduplication: ipctk merges candidates whose closest features coincide into one
collision with weight = multiplicity; a plain sum over all candidate pairs gives the same
value, gradient and (PSD-clamped, per-stencil) Hessian, since merged stencils are
identical and proj(w H) = w proj(H) for w > 0.

Inputs: x (n, 3) float64 positions, pt_pairs (k, 4) int64 rows (p, t0, t1, t2),
ee_pairs (j, 4) int64 rows (ea0, ea1, eb0, eb1), ee_eps_x (j,), s_hat = d̂², kappa.
Global DOF of vertex i, axis a is 3i + a.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.algebra.assembly import block_triplet_indices
from ipcsim.kernels.contact.broad_phase import swept_pairs_within
from ipcsim.kernels.contact.barrier import (
    BARRIER_IPC,
    barrier,
    barrier_and_derivatives,
    barrier_of_form,
)
from ipcsim.kernels.contact.distance import (
    EE_FEATURES,
    PT_FEATURES,
    edge_edge_distance_sq,
    edge_edge_distance_type,
    feature_distance_sq,
    feature_distance_sq_gradient,
    feature_distance_sq_hessian,
    point_triangle_distance_sq,
    point_triangle_distance_type,
)
from ipcsim.kernels.algebra.linalg import (
    chain_gradient,
    chain_hessian,
    ordered_sum,
    point3,
    project_psd,
    project_psd_on_dofs,
)
from ipcsim.kernels.algebra.scatter import scatter_stencil_gradients
from ipcsim.kernels.contact.mollifier import (
    edge_edge_cross_sq,
    edge_edge_cross_sq_gradient,
    edge_edge_cross_sq_hessian,
    mollifier_scalar,
    mollifier_scalar_first_derivative,
    mollifier_scalar_second_derivative,
)
from ipcsim.compiler.twin import kernel

HESSIAN_BLOCK = 144  # triplets per active pair (12 x 12 local Hessian)


# =========================================================================================
# One stencil. V holds its vertices as a tuple of 3-tuples (gather_stencil), f the row of
# its closest feature (distance.PT_FEATURES, EE_FEATURES or PE_FEATURES; the edge-edge
# functions take its distance type); every function returns 0 / zeros for an inactive
# stencil (d² ≥ ŝ). The barrier b is of ``form`` (barrier.barrier_of_form).
# =========================================================================================

@njit(cache=True, error_model="numpy")
def stencil_barrier(V, f, s_hat, kappa, form):
    # κ b(d²)
    d = feature_distance_sq(V, f)
    if d >= s_hat:
        return 0.0
    b, _, _ = barrier_of_form(form, d, s_hat)
    return kappa * b


@njit(cache=True, error_model="numpy")
def stencil_barrier_gradient(V, f, s_hat, kappa, form):
    # ∇(κb) = κ b' ∇d
    d = feature_distance_sq(V, f)
    if d >= s_hat:
        return np.zeros(3 * len(V))
    _, db, _ = barrier_of_form(form, d, s_hat)
    return chain_gradient(feature_distance_sq_gradient(V, f), kappa * db)


@njit(cache=True, error_model="numpy")
def stencil_barrier_hessian(V, f, s_hat, kappa, form):
    # ∇²(κb) = κ (b' ∇²d + b'' ∇d ∇dᵀ)
    d = feature_distance_sq(V, f)
    if d >= s_hat:
        return np.zeros((3 * len(V), 3 * len(V)))
    _, db, d2b = barrier_of_form(form, d, s_hat)
    return chain_hessian(feature_distance_sq_hessian(V, f), feature_distance_sq_gradient(V, f),
                         db, d2b, kappa)


@njit(cache=True, error_model="numpy")
def edge_edge_barrier(V, dtype, eps_x, s_hat, kappa):
    # κ m b(d²)
    d = feature_distance_sq(V, EE_FEATURES[dtype])
    if d >= s_hat:
        return 0.0
    m = mollifier_scalar(edge_edge_cross_sq(V[0], V[1], V[2], V[3]), eps_x)
    return kappa * m * barrier(d, s_hat)


@njit(cache=True, error_model="numpy")
def edge_edge_barrier_gradient(V, dtype, eps_x, s_hat, kappa):
    # ∇(κmb) = κ (m b' ∇d + b ∇m),  ∇m = m'(c) ∇c
    f = EE_FEATURES[dtype]
    c = edge_edge_cross_sq(V[0], V[1], V[2], V[3])
    m = mollifier_scalar(c, eps_x)
    g = stencil_barrier_gradient(V, f, s_hat, kappa * m, BARRIER_IPC)  # κ m b' ∇d
    if c < eps_x:  # else m ≡ 1, ∇m = 0
        b = barrier(feature_distance_sq(V, f), s_hat)
        gc = edge_edge_cross_sq_gradient(V[0], V[1], V[2], V[3])
        dm = mollifier_scalar_first_derivative(c, eps_x)
        for i in range(12):
            g[i] += kappa * b * dm * gc[i]
    return g


@njit(cache=True, error_model="numpy")
def edge_edge_barrier_hessian(V, dtype, eps_x, s_hat, kappa):
    # ∇²(κmb) = κ [ m (b' ∇²d + b'' ∇d ∇dᵀ) + b ∇²m + b' (∇m ∇dᵀ + ∇d ∇mᵀ) ]
    # ∇m = m' ∇c,  ∇²m = m' ∇²c + m'' ∇c ∇cᵀ   (c = |(ea1 − ea0)×(eb1 − eb0)|²)
    f = EE_FEATURES[dtype]
    c = edge_edge_cross_sq(V[0], V[1], V[2], V[3])
    m = mollifier_scalar(c, eps_x)
    H = stencil_barrier_hessian(V, f, s_hat, m, BARRIER_IPC)  # m (b' ∇²d + b'' ∇d ∇dᵀ)
    d = feature_distance_sq(V, f)
    if d >= s_hat:
        return H
    if c < eps_x:  # else m ≡ 1 and its derivatives vanish
        b, db, _ = barrier_and_derivatives(d, s_hat)
        gd = feature_distance_sq_gradient(V, f)
        gc = edge_edge_cross_sq_gradient(V[0], V[1], V[2], V[3])
        Hc = edge_edge_cross_sq_hessian(V[0], V[1], V[2], V[3])
        dm = mollifier_scalar_first_derivative(c, eps_x)
        d2m = mollifier_scalar_second_derivative(c, eps_x)
        for i in range(12):
            for j in range(12):
                Hm = dm * Hc[i, j] + d2m * gc[i] * gc[j]
                H[i, j] += b * Hm + db * dm * (gc[i] * gd[j] + gd[i] * gc[j])
    for i in range(12):
        for j in range(12):
            H[i, j] *= kappa
    return H


# --- stencil helpers, public: penalty.py builds its pairs with them too ------------------

@njit(cache=True, error_model="numpy")
def gather_stencil(x, pair):
    """The stencil's four vertex positions, V[k] = x[pair[k]], as a tuple of 3-tuples:
    plain values, not an array, so the distance functions they go to are compiled for
    values in registers (an array per pair, and a view of it per vertex, made a pair's
    classification and distance 8× slower: 560 against 67 ns)."""
    return point3(x, pair[0]), point3(x, pair[1]), point3(x, pair[2]), point3(x, pair[3])


# --- one pair of the global arrays (keeps the parallel loop bodies small) -----------------

@njit(cache=True, error_model="numpy")
def _pt_classify(x, pair):
    V = gather_stencil(x, pair)
    t = point_triangle_distance_type(V[0], V[1], V[2], V[3])
    return t, point_triangle_distance_sq(V[0], V[1], V[2], V[3], t)


@njit(cache=True, error_model="numpy")
def _ee_classify(x, pair):
    V = gather_stencil(x, pair)
    t = edge_edge_distance_type(V[0], V[1], V[2], V[3])
    return t, edge_edge_distance_sq(V[0], V[1], V[2], V[3], t)


@njit(cache=True, error_model="numpy")
def _pt_value_at(x, pair, s_hat, kappa):
    V = gather_stencil(x, pair)
    return stencil_barrier(V, PT_FEATURES[point_triangle_distance_type(V[0], V[1], V[2], V[3])],
                           s_hat, kappa, BARRIER_IPC)


@njit(cache=True, error_model="numpy")
def _ee_value_at(x, pair, eps_x, s_hat, kappa):
    V = gather_stencil(x, pair)
    return edge_edge_barrier(V, edge_edge_distance_type(V[0], V[1], V[2], V[3]),
                             eps_x, s_hat, kappa)


@njit(cache=True, error_model="numpy")
def _pt_gradient_at(x, pair, s_hat, kappa):
    V = gather_stencil(x, pair)
    return stencil_barrier_gradient(
        V, PT_FEATURES[point_triangle_distance_type(V[0], V[1], V[2], V[3])], s_hat, kappa,
        BARRIER_IPC)


@njit(cache=True, error_model="numpy")
def _ee_gradient_at(x, pair, eps_x, s_hat, kappa):
    V = gather_stencil(x, pair)
    return edge_edge_barrier_gradient(
        V, edge_edge_distance_type(V[0], V[1], V[2], V[3]), eps_x, s_hat, kappa)


@njit(cache=True, error_model="numpy")
def project_psd_on_feature(H, feature):
    """project_psd(H) for a stencil's Hessian H (3w x 3w: 12 x 12 for point-triangle and
    edge-edge, 9 x 9 for point-edge) that is zero outside the vertices named in `feature`
    (a row of distance.PT_FEATURES / EE_FEATURES / PE_FEATURES: slots 1..4 name the
    stencil vertices of the closest feature, −1 unused): only that 6/9/12 block is
    decomposed (eigh costs ~n³). Returns a new 3w x 3w array."""
    nv = 0
    for k in range(1, 5):
        nv += feature[k] >= 0
    if 3 * nv == H.shape[0]:
        return project_psd(H)
    dof = np.empty(3 * nv, dtype=np.int64)
    for k in range(nv):
        for a in range(3):
            dof[3 * k + a] = 3 * feature[1 + k] + a
    return project_psd_on_dofs(H, dof)


@njit(cache=True, error_model="numpy")
def _pt_hessian_into(x, pair, s_hat, kappa, project, vals, base):
    V = gather_stencil(x, pair)
    f = PT_FEATURES[point_triangle_distance_type(V[0], V[1], V[2], V[3])]
    H = stencil_barrier_hessian(V, f, s_hat, kappa, BARRIER_IPC)
    if project:
        H = project_psd_on_feature(H, f)
    _write_block(vals, base, H)


@njit(cache=True, error_model="numpy")
def _ee_hessian_into(x, pair, eps_x, s_hat, kappa, project, vals, base):
    V = gather_stencil(x, pair)
    t = edge_edge_distance_type(V[0], V[1], V[2], V[3])
    H = edge_edge_barrier_hessian(V, t, eps_x, s_hat, kappa)
    if project:
        if edge_edge_cross_sq(V[0], V[1], V[2], V[3]) < eps_x:
            H = project_psd(H)  # the mollifier couples all four vertices
        else:
            H = project_psd_on_feature(H, EE_FEATURES[t])
    _write_block(vals, base, H)


@njit(cache=True)
def _write_block(vals, base, H):
    # the 12 x 12 local Hessian H at slots [base, base + 144), row-major
    for r in range(12):
        for c in range(12):
            vals[base + 12 * r + c] = H[r, c]


@njit(cache=True, error_model="numpy")
def write_hessian_block(rows, cols, vals, base, pair, H):
    """Write the 12 x 12 local Hessian H of the stencil ``pair`` (4 global vertex ids) as
    144 COO triplets at slots [base, base + 144), row-major:
    slot base + 12 r + c  <-  (3 pair[r//3] + r%3, 3 pair[c//3] + c%3, H[r, c])."""
    for r in range(12):
        gr = 3 * pair[r // 3] + r % 3
        for c in range(12):
            o = base + 12 * r + c
            rows[o] = gr
            cols[o] = 3 * pair[c // 3] + c % 3
            vals[o] = H[r, c]


# =========================================================================================
# Batched kernels
# =========================================================================================

@kernel(parallel=True, error_model="numpy")
def classify_and_distance(x, pt_pairs, ee_pairs):
    """Distance type (ipctk enum codes) and squared distance of every candidate pair.
    Returns (pt_type (k,) int64, pt_d2 (k,), ee_type (j,) int64, ee_d2 (j,)); a pair is
    active iff d2 < ŝ (strict, as ipctk)."""
    k = pt_pairs.shape[0]
    j = ee_pairs.shape[0]
    pt_type = np.empty(k, dtype=np.int64)
    pt_d2 = np.empty(k)
    ee_type = np.empty(j, dtype=np.int64)
    ee_d2 = np.empty(j)
    for i in prange(k):
        pt_type[i], pt_d2[i] = _pt_classify(x, pt_pairs[i])
    for i in prange(j):
        ee_type[i], ee_d2[i] = _ee_classify(x, ee_pairs[i])
    return pt_type, pt_d2, ee_type, ee_d2


@njit(cache=True)
def active_pairs(pt_d2, ee_d2, s_hat):
    """(point–triangle pairs with d² < ŝ, edge–edge pairs with d² < ŝ, the smallest d²:
    inf without pairs)."""
    n_pt = n_ee = 0
    smallest = np.inf
    for d2 in pt_d2:
        n_pt += d2 < s_hat
        smallest = min(smallest, d2)
    for d2 in ee_d2:
        n_ee += d2 < s_hat
        smallest = min(smallest, d2)
    return n_pt, n_ee, smallest


@kernel()
def near_pairs(x, pt_pairs, ee_pairs, ee_eps_x, pt_id, ee_id, inflation):
    """The pairs whose boxes at x, grown by inflation/2, overlap (the broad phase's test,
    ``broad_phase.swept_pairs_within`` over no motion), in their order, with their
    thresholds and ids, and each kept pair's closest-feature type and squared distance
    at x: (pt, ee, ε_x, pt ids, ee ids, pt types, pt d², ee types, ee d²)."""
    keep_pt = swept_pairs_within(x, x, pt_pairs, 1, inflation)
    keep_ee = swept_pairs_within(x, x, ee_pairs, 2, inflation)
    pt = pt_pairs[keep_pt]
    ee = ee_pairs[keep_ee]
    pt_type, pt_d2, ee_type, ee_d2 = classify_and_distance(x, pt, ee)
    return (pt, ee, ee_eps_x[keep_ee], pt_id[keep_pt], ee_id[keep_ee], pt_type, pt_d2,
            ee_type, ee_d2)


@kernel(parallel=True, error_model="numpy")
def barrier_value(x, pt_pairs, ee_pairs, ee_eps_x, s_hat, kappa):
    """Σ κ m b(d², ŝ) over the active pairs (m ≡ 1 for point-triangle).
    Per-pair terms go to an array first so that the sum is deterministic."""
    k = pt_pairs.shape[0]
    j = ee_pairs.shape[0]
    terms = np.empty(k + j)
    for i in prange(k):
        terms[i] = _pt_value_at(x, pt_pairs[i], s_hat, kappa)
    for i in prange(j):
        terms[k + i] = _ee_value_at(x, ee_pairs[i], ee_eps_x[i], s_hat, kappa)
    return ordered_sum(terms)


@kernel(parallel=True, error_model="numpy")
def _local_gradients(x, pt_pairs, ee_pairs, ee_eps_x, s_hat, kappa):
    # (k + j, 12) local gradients (zero rows for inactive pairs); row i written by i only
    k = pt_pairs.shape[0]
    j = ee_pairs.shape[0]
    G = np.empty((k + j, 12))
    for i in prange(k):
        g = _pt_gradient_at(x, pt_pairs[i], s_hat, kappa)
        for a in range(12):
            G[i, a] = g[a]
    for i in prange(j):
        g = _ee_gradient_at(x, ee_pairs[i], ee_eps_x[i], s_hat, kappa)
        for a in range(12):
            G[k + i, a] = g[a]
    return G


@kernel(error_model="numpy")
def barrier_gradient(x, pt_pairs, ee_pairs, ee_eps_x, s_hat, kappa):
    """∇B as a flat (3n,) vector: local gradients in parallel, then a serial scatter."""
    G = _local_gradients(x, pt_pairs, ee_pairs, ee_eps_x, s_hat, kappa)
    return scatter_stencil_gradients(G, pt_pairs, ee_pairs, x.shape[0])


@kernel(parallel=True, error_model="numpy")
def barrier_hessian_blocks(x, pt_pairs, ee_pairs, ee_eps_x, s_hat, kappa, project):
    """∇²B as one 12 x 12 block per ACTIVE pair (d² < ŝ): (stencils (k, 4) int64, vals
    (144 k,) float64), active point-triangle pairs first (in input order), then active
    edge-edge pairs; block a holds slots [144 a, 144 (a + 1)) of vals, row-major over
    its stencil's 12 DOFs (``assembly.block_triplet_indices`` gives each entry's row and
    column),
    so the parallel writes never overlap. With ``project`` each block is clamped to PSD
    (negative eigenvalues -> 0); only the part of the vertices the pair's closest
    feature involves is decomposed (all four when mollified). Rows and columns of
    stencil vertices that the closest feature does not involve hold zeros. Blocks of
    pairs that share vertices are to be summed."""
    _, pt_d2, _, ee_d2 = classify_and_distance(x, pt_pairs, ee_pairs)
    pt_act = np.flatnonzero(pt_d2 < s_hat)
    ee_act = np.flatnonzero(ee_d2 < s_hat)
    na = pt_act.shape[0]
    nb = ee_act.shape[0]
    stencils = np.empty((na + nb, 4), dtype=np.int64)
    vals = np.empty(HESSIAN_BLOCK * (na + nb))
    for a in prange(na):
        i = pt_act[a]
        for j in range(4):
            stencils[a, j] = pt_pairs[i, j]
        _pt_hessian_into(x, pt_pairs[i], s_hat, kappa, project, vals, HESSIAN_BLOCK * a)
    for a in prange(nb):
        i = ee_act[a]
        for j in range(4):
            stencils[na + a, j] = ee_pairs[i, j]
        _ee_hessian_into(x, ee_pairs[i], ee_eps_x[i], s_hat, kappa, project,
                         vals, HESSIAN_BLOCK * (na + a))
    return stencils, vals


@kernel(error_model="numpy")
def barrier_hessian_triplets(x, pt_pairs, ee_pairs, ee_eps_x, s_hat, kappa, project):
    """∇²B as COO triplets (rows, cols, vals), int32/int32/float64: the entries of
    ``barrier_hessian_blocks`` with their rows and columns, in the same order (144 per
    active pair). Duplicate (row, col) entries are to be summed (Triplets.tocsr)."""
    stencils, vals = barrier_hessian_blocks(x, pt_pairs, ee_pairs, ee_eps_x, s_hat, kappa,
                                            project)
    rows, cols = block_triplet_indices(stencils)
    return rows, cols, vals
