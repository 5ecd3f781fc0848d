"""Lagged, smoothed Coulomb friction (IPC, Li et al. 2020), displacement form.

    D(x) = Σ_k  w_k f0(y_k, ε),   y_k = |P_kᵀ r_k(u)|,   u = x − x_lag,   ε = ε_v h
    r_k  = Σ_i c_ki u_{v_ki}          (relative displacement of the closest points)
    w_k  = μ_k λ_k,   λ_k = −κ b'(d_k², d̂²) · 2 d_k   (normal force magnitude at x_lag)

Everything but u is frozen at x_lag by the lagging kernels: the stencil vertices v_k of the
closest feature (1 to 4 vertices), the closest-point coefficients c_k (c_k0 = 1; the
others are minus the barycentric / edge-parameter weights of the opposite feature), and an
orthonormal tangent basis P_k (3 x 2) of the plane orthogonal to the feature's normal.
Only |P_kᵀ r| enters D, so the in-plane orientation of P_k is arbitrary (as in ipctk).

2D scenes (point–edge pairs at z = 0, ``lag_point_edge_pairs``) use the same formulas:
their closest feature is a point–point or point–line one, whose normal lies in the
plane, so one column of P is exactly e_z (``basis_from_normal`` takes the axis least
aligned with n, z, and n̂ × (n̂ × e_z) has no x, y parts). Nothing moves along z (u_z = 0),
so |Pᵀr| is the slip along the 1D tangent of the plane (ipctk's 2D basis), the gradient
has no z parts, and the Hessian couples no z DOF with an in-plane one (its z-z entries,
w c_i c_j f1/y ≥ 0, act on z alone, where the gradient is 0).

Smoothed friction magnitude (C² at y = ε since f1(ε) = 1, f1'(ε) = 0):
    f0(y) = −y³/(3ε²) + y²/ε + ε/3      (y < ε),   y  otherwise
    f1(y) = f0'(y) = −y²/ε² + 2y/ε      (y < ε),   1  otherwise
    f1(y)/y = 2/ε − y/ε²                (y < ε),   1/y         (finite at y = 0)
    (f1'(y) y − f1(y))/y³ = −1/(ε² y)   (y < ε),   −1/y³

Per pair, with τ = Pᵀr:
    ∇_{u_i} D_k  = w c_i (f1/y) P τ
    ∇²_{u_i u_j} D_k = w c_i c_j P M Pᵀ,   M = (f1/y) I₂ + ((f1' y − f1)/y³) τ τᵀ
M has eigenvalue f1/y (⊥ τ) and f1'(y) (along τ), both ≥ 0 analytically; the projected
form writes M with the eigenvalues clamped at 0, so each local block is PSD by
construction (w ≥ 0). At y = 0, M = (2/ε) I₂.

Lagged data layout (one row per frictional pair, m rows):
    verts  (m, 4) int64   stencil vertices, −1 in unused slots
    coeffs (m, 4)         c, 0 in unused slots
    basis  (m, 3, 2)      P
    weight (m,)           μλ
    offsets (m + 1,)      triplet offsets: pair k owns [offsets[k], offsets[k+1]),
                          (3 nv_k)² entries, row-major over its local Hessian
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.contact.barrier import barrier_first_derivative, barrier_of_form
from ipcsim.kernels.contact.pair_barrier import classify_and_distance
from ipcsim.kernels.contact.distance import (
    EE_FEATURES,
    PE_FEATURES,
    POINT_LINE,
    POINT_PLANE,
    POINT_POINT,
    PT_FEATURES,
)
from ipcsim.kernels.algebra.linalg import cross3, dot3, ordered_sum, scale3, squared_norm3, sub3
from ipcsim.kernels.contact.mollifier import edge_edge_cross_sq
from ipcsim.kernels.algebra.scatter import scatter_local_gradients
from ipcsim.kernels.contact.plane_barrier import (
    plane_active_count_and_min_distance,
    plane_distances,
)
from ipcsim.kernels.contact.point_edge_barrier import pe_classify_and_distance
from ipcsim.compiler.twin import kernel


# =========================================================================================
# Smoothed friction magnitude
# =========================================================================================

@njit(cache=True, error_model="numpy")
def f0(y, eps):
    # f0 = −y³/(3ε²) + y²/ε + ε/3  (y < ε),  y  otherwise
    if y >= eps:
        return y
    return y * y * (1.0 / eps - y / (3.0 * eps * eps)) + eps / 3.0


@njit(cache=True, error_model="numpy")
def f1_over_y(y, eps):
    # f1/y = 2/ε − y/ε²  (y < ε),  1/y  otherwise
    if y >= eps:
        return 1.0 / y
    return 2.0 / eps - y / (eps * eps)


@njit(cache=True, error_model="numpy")
def f1_prime(y, eps):
    # f1' = 2/ε − 2y/ε²  (y < ε),  0  otherwise
    if y >= eps:
        return 0.0
    return 2.0 / eps - 2.0 * y / (eps * eps)


# =========================================================================================
# Lagging: closest-point coefficients, tangent basis, normal force
# =========================================================================================

@njit(cache=True, error_model="numpy")
def basis_from_normal(n, P):
    """Orthonormal P (3 x 2) spanning n⊥: t1 = n̂ × e_a / |·| with e_a the axis least
    aligned with n, t2 = n̂ × t1."""
    L = np.sqrt(squared_norm3(n))
    nh = scale3(1.0 / L, n)
    a = 0
    if abs(nh[1]) < abs(nh[a]):
        a = 1
    if abs(nh[2]) < abs(nh[a]):
        a = 2
    ea = (1.0 if a == 0 else 0.0, 1.0 if a == 1 else 0.0, 1.0 if a == 2 else 0.0)
    t1 = cross3(nh, ea)
    t1 = scale3(1.0 / np.sqrt(squared_norm3(t1)), t1)
    t2 = cross3(nh, t1)
    for i in range(3):
        P[i, 0] = t1[i]
        P[i, 1] = t2[i]


@njit(cache=True, error_model="numpy")
def _lag_feature(x, pair, f, verts, coeffs, P):
    """Write the closest feature's stencil (verts, coeffs) and tangent basis P for the
    pair `pair` (4 global ids) whose closest feature is the *_FEATURES row f."""
    for k in range(4):
        verts[k] = -1
        coeffs[k] = 0.0
    g = (pair[f[1]], pair[f[2]],
         pair[f[3]] if f[3] >= 0 else -1, pair[f[4]] if f[4] >= 0 else -1)
    sub = f[0]
    if sub == POINT_POINT:
        # r = u_p − u_q,  n = p − q
        p = x[g[0]]
        q = x[g[1]]
        verts[0], verts[1] = g[0], g[1]
        coeffs[0], coeffs[1] = 1.0, -1.0
        n = sub3(p, q)
    elif sub == POINT_LINE:
        # t = (p − e0)·e/|e|²,  r = u_p − (1−t) u_e0 − t u_e1,  n = e × ((p − e0) × e)
        p = x[g[0]]
        e0 = x[g[1]]
        e1 = x[g[2]]
        e = sub3(e1, e0)
        r = sub3(p, e0)
        t = dot3(r, e) / squared_norm3(e)
        verts[0], verts[1], verts[2] = g[0], g[1], g[2]
        coeffs[0], coeffs[1], coeffs[2] = 1.0, -(1.0 - t), -t
        n = cross3(e, cross3(r, e))
    elif sub == POINT_PLANE:
        # n = e1×e2, β1 = ((r×e2)·n)/|n|², β2 = ((e1×r)·n)/|n|²  (r = p − t0)
        # r_rel = u_p − (1−β1−β2) u_t0 − β1 u_t1 − β2 u_t2
        p = x[g[0]]
        t0 = x[g[1]]
        e1 = sub3(x[g[2]], t0)
        e2 = sub3(x[g[3]], t0)
        r = sub3(p, t0)
        n = cross3(e1, e2)
        N = squared_norm3(n)
        b1 = dot3(cross3(r, e2), n) / N
        b2 = dot3(cross3(e1, r), n) / N
        for k in range(4):
            verts[k] = g[k]
        coeffs[0], coeffs[1], coeffs[2], coeffs[3] = 1.0, -(1.0 - b1 - b2), -b1, -b2
    else:  # LINE_LINE
        # u = ea1 − ea0, v = eb1 − eb0, w = ea0 − eb0, n = u×v
        # s = −((w×v)·n)/|n|², t = −((w×u)·n)/|n|²
        # r_rel = (1−s) u_ea0 + s u_ea1 − (1−t) u_eb0 − t u_eb1
        ea0 = x[g[0]]
        uu = sub3(x[g[1]], ea0)
        vv = sub3(x[g[3]], x[g[2]])
        w = sub3(ea0, x[g[2]])
        n = cross3(uu, vv)
        N = squared_norm3(n)
        s = -dot3(cross3(w, vv), n) / N
        t = -dot3(cross3(w, uu), n) / N
        for k in range(4):
            verts[k] = g[k]
        coeffs[0], coeffs[1], coeffs[2], coeffs[3] = 1.0 - s, s, -(1.0 - t), -t
    basis_from_normal(n, P)


@kernel(parallel=True, error_model="numpy")
def lag_mesh_pairs(x_lag, pt_pairs, ee_pairs, ee_eps_x, s_hat, kappa):
    """Lagged friction data of every PT pair then every EE pair at x_lag.

    Returns (keep (k+j,) bool, verts (k+j, 4), coeffs (k+j, 4), basis (k+j, 3, 2),
    lam (k+j,)). keep: active (d² < ŝ) and, for EE, not mollified (|u×v|² ≥ ε_x, as
    ipctk, which gives near-parallel edge pairs no friction). lam = −κ b'(d², ŝ) 2d.
    Rows of dropped pairs are left unspecified."""
    k = pt_pairs.shape[0]
    j = ee_pairs.shape[0]
    pt_type, pt_d2, ee_type, ee_d2 = classify_and_distance(x_lag, pt_pairs, ee_pairs)
    m = k + j
    keep, verts, coeffs, basis, lam = _lag_arrays(m)
    for i in prange(m):
        if i < k:
            pair = pt_pairs[i]
            d2 = pt_d2[i]
            if not d2 < s_hat:
                continue
            f = PT_FEATURES[pt_type[i]]
        else:
            pair = ee_pairs[i - k]
            d2 = ee_d2[i - k]
            if not d2 < s_hat:
                continue
            if edge_edge_cross_sq(x_lag[pair[0]], x_lag[pair[1]], x_lag[pair[2]],
                                  x_lag[pair[3]]) < ee_eps_x[i - k]:
                continue  # mollified: no friction
            f = EE_FEATURES[ee_type[i - k]]
        keep[i] = True
        _lag_feature(x_lag, pair, f, verts[i], coeffs[i], basis[i])
        # λ = −κ b'(d², ŝ) · 2d
        lam[i] = -kappa * barrier_first_derivative(d2, s_hat) * 2.0 * np.sqrt(d2)
    return keep, verts, coeffs, basis, lam


@njit(cache=True)
def _lag_arrays(m):
    """(keep, verts, coeffs, basis, lam) of m lagged pairs, none kept yet."""
    return (np.zeros(m, dtype=np.bool_), np.full((m, 4), -1, dtype=np.int64),
            np.zeros((m, 4)), np.zeros((m, 3, 2)), np.zeros(m))


@kernel(parallel=True, error_model="numpy")
def lag_point_edge_pairs(x_lag, pe_pairs, weights, s_hat, kappa, form):
    """Lagged friction data of every point–edge pair of a 2D scene at x_lag (module
    docstring), in the layout of ``lag_mesh_pairs``: (keep (k,) bool, verts (k, 4), coeffs
    (k, 4), basis (k, 3, 2), lam (k,)). keep: active (d² < ŝ). The normal force is that
    of the pair's barrier (``point_edge_barrier``: weight w, barrier ``form``),
    lam = −w κ b'(d², ŝ) 2d. Rows of dropped pairs are left unspecified."""
    types, d2 = pe_classify_and_distance(x_lag, pe_pairs)
    m = pe_pairs.shape[0]
    keep, verts, coeffs, basis, lam = _lag_arrays(m)
    for i in prange(m):
        if not d2[i] < s_hat:
            continue
        keep[i] = True
        _lag_feature(x_lag, pe_pairs[i], PE_FEATURES[types[i]], verts[i], coeffs[i],
                     basis[i])
        _, db, _ = barrier_of_form(form, d2[i], s_hat)
        # λ = −w κ b'(d², ŝ) · 2d
        lam[i] = -weights[i] * kappa * db * 2.0 * np.sqrt(d2[i])
    return keep, verts, coeffs, basis, lam


@njit(cache=True, error_model="numpy")
def lag_vertex_plane_pairs(vertices, normals, active, lam):
    """Lagged friction data of the (plane k, vertex j) pairs where active[k, j] (normals
    unit length), each with normal force lam[k, j].

    Returns (plane (m,) int64, verts (m, 4), coeffs (m, 4), basis (m, 3, 2), lam (m,)); the
    stencil is the vertex alone (r = u_v, the plane does not move), P spans the plane."""
    count = 0
    for k in range(active.shape[0]):
        for j in range(active.shape[1]):
            count += active[k, j]
    plane = np.empty(count, dtype=np.int64)
    verts = np.full((count, 4), -1, dtype=np.int64)
    coeffs = np.zeros((count, 4))
    basis = np.zeros((count, 3, 2))
    lam_out = np.empty(count)
    i = 0
    for k in range(active.shape[0]):
        for j in range(active.shape[1]):
            if not active[k, j]:
                continue
            plane[i] = k
            verts[i, 0] = vertices[j]
            coeffs[i, 0] = 1.0
            basis_from_normal(normals[k], basis[i])
            lam_out[i] = lam[k, j]
            i += 1
    return plane, verts, coeffs, basis, lam_out


@njit(cache=True, error_model="numpy")
def lag_plane_pairs(x_lag, vertices, origins, normals, s_hat, kappa):
    """``lag_vertex_plane_pairs`` of the active vertex–plane pairs (0 < d, d² < ŝ, with
    d = n·(x − o) the signed distance), λ = −κ b'(d², ŝ) 2d."""
    d = plane_distances(x_lag, vertices, origins, normals)
    active = (d > 0.0) & (d * d < s_hat)
    lam = np.zeros_like(d)
    for k in range(d.shape[0]):
        for j in range(d.shape[1]):
            if active[k, j]:
                lam[k, j] = -kappa * barrier_first_derivative(d[k, j] * d[k, j], s_hat) \
                    * 2.0 * d[k, j]
    return lag_vertex_plane_pairs(vertices, normals, active, lam)


@kernel(error_model="numpy")
def lag_pairs(x_lag, mesh, planes, s_hat, kappa):
    """Every frictional pair's lagged data at x_lag: the mesh's active pairs, then the
    vertex–plane pairs of the planes with μ > 0 if any vertex is within d̂ of any plane
    (``contact.friction_lag.lag_friction``). ``mesh`` = (pt, ee, ε_x, μ, whether any pair
    may be within d̂), ``planes`` = (vertices, origins, normals, μ per plane). Returns
    (verts (f, 4), coeffs (f, 4), basis (f, 3, 2), μλ (f,), triplet offsets (f + 1,))."""
    pt, ee, eps_x, mu_mesh, mesh_active = mesh
    vertices, origins, normals, mu_planes = planes
    verts, coeffs = np.empty((0, 4), dtype=np.int64), np.empty((0, 4))
    basis, weight = np.empty((0, 3, 2)), np.empty(0)
    if mu_mesh > 0.0 and mesh_active:
        keep, v, c, b, lam = lag_mesh_pairs(x_lag, pt, ee, eps_x, s_hat, kappa)
        verts, coeffs, basis = v[keep], c[keep], b[keep]
        weight = mu_mesh * lam[keep]
    use = mu_planes > 0.0
    if vertices.shape[0] > 0 and use.any() and \
            plane_active_count_and_min_distance(x_lag, vertices, origins, normals, s_hat)[0] > 0:
        plane, v, c, b, lam = lag_plane_pairs(x_lag, vertices, origins[use], normals[use],
                                              s_hat, kappa)
        verts = np.concatenate((verts, v))
        coeffs = np.concatenate((coeffs, c))
        basis = np.concatenate((basis, b))
        weight = np.concatenate((weight, mu_planes[use][plane] * lam))
    return verts, coeffs, basis, weight, triplet_offsets(verts)


# =========================================================================================
# Potential, gradient, Hessian over lagged pairs (u = x − x_lag, (n, 3))
# =========================================================================================

@njit(cache=True, error_model="numpy")
def _tangential(u, verts, coeffs, P):
    # r = Σ_i c_i u_{v_i};  τ = Pᵀ r;  returns τ0, τ1 and the slip y = |τ|
    r0 = 0.0
    r1 = 0.0
    r2 = 0.0
    for k in range(4):
        v = verts[k]
        if v < 0:
            continue
        c = coeffs[k]
        r0 += c * u[v, 0]
        r1 += c * u[v, 1]
        r2 += c * u[v, 2]
    t0 = P[0, 0] * r0 + P[1, 0] * r1 + P[2, 0] * r2
    t1 = P[0, 1] * r0 + P[1, 1] * r1 + P[2, 1] * r2
    return t0, t1, np.sqrt(t0 * t0 + t1 * t1)


@kernel(parallel=True, error_model="numpy")
def friction_value(u, verts, coeffs, basis, weight, eps):
    """D = Σ_k w_k f0(|P_kᵀ r_k|, ε); per-pair terms summed in a fixed order."""
    m = verts.shape[0]
    terms = np.empty(m)
    for k in prange(m):
        terms[k] = weight[k] * f0(_tangential(u, verts[k], coeffs[k], basis[k])[2], eps)
    return ordered_sum(terms)


@kernel(parallel=True, error_model="numpy")
def _local_gradients(u, verts, coeffs, basis, weight, eps):
    # row k (12,): c_i w (f1/y) P τ on stencil vertex i (unused slots, verts = −1, hold
    # c_i = 0 times it; the scatter skips them)
    m = verts.shape[0]
    G = np.empty((m, 12))
    for k in prange(m):
        P = basis[k]
        t0, t1, y = _tangential(u, verts[k], coeffs[k], P)
        s = weight[k] * f1_over_y(y, eps)
        for a in range(3):
            f = s * (P[a, 0] * t0 + P[a, 1] * t1)  # the force direction, shared by the stencil
            for i in range(4):
                G[k, 3 * i + a] = coeffs[k, i] * f
    return G


@kernel(error_model="numpy")
def friction_gradient(u, verts, coeffs, basis, weight, eps):
    """∇D (3n,): ∇_{u_i} D_k = c_i w (f1/y) P τ. Per-pair gradients in parallel, then the
    shared serial scatter (``scatter.scatter_local_gradients``; unused slots, −1, skipped)."""
    G = _local_gradients(u, verts, coeffs, basis, weight, eps)
    return scatter_local_gradients(G, verts, u.shape[0])


@njit(cache=True, error_model="numpy")
def _inner_block(t0, t1, y, eps, project):
    """M (2 x 2). Unprojected: (f1/y) I + ((f1' y − f1)/y³) τ τᵀ.
    Projected: max(f1/y, 0) (I − τ̂τ̂ᵀ) + max(f1', 0) τ̂τ̂ᵀ (the same matrix with its
    eigenvalues clamped at 0). At y = 0: (2/ε) I."""
    a = f1_over_y(y, eps)
    M = np.zeros((2, 2))
    if y == 0.0:
        M[0, 0] = a
        M[1, 1] = a
        return M
    if project:
        b = max(f1_prime(y, eps), 0.0)
        a = max(a, 0.0)
        h0 = t0 / y
        h1 = t1 / y
        # a I + (b − a) τ̂ τ̂ᵀ
        M[0, 0] = a + (b - a) * h0 * h0
        M[1, 1] = a + (b - a) * h1 * h1
        M[0, 1] = (b - a) * h0 * h1
        M[1, 0] = M[0, 1]
        return M
    # (f1' y − f1)/y³ = −1/(ε² y) (y < ε),  −1/y³ otherwise
    if y < eps:
        c = -1.0 / (eps * eps * y)
    else:
        c = -1.0 / (y * y * y)
    M[0, 0] = a + c * t0 * t0
    M[1, 1] = a + c * t1 * t1
    M[0, 1] = c * t0 * t1
    M[1, 0] = M[0, 1]
    return M


@njit(cache=True, error_model="numpy")
def _hessian_into(u, verts, coeffs, P, w, eps, project, rows, cols, vals, base):
    # K = w P M Pᵀ (3 x 3); block (i, j) = c_i c_j K over the pair's nv stencil vertices
    M = _inner_block(*_tangential(u, verts, coeffs, P), eps, project)
    K = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            s = 0.0
            for p in range(2):
                for q in range(2):
                    s += P[a, p] * M[p, q] * P[b, q]
            K[a, b] = w * s
    nv = 0
    for i in range(4):
        nv += verts[i] >= 0
    nd = 3 * nv
    for r in range(nd):
        i, a = r // 3, r % 3
        gr = 3 * verts[i] + a
        for c in range(nd):
            j, b = c // 3, c % 3
            o = base + nd * r + c
            rows[o] = gr
            cols[o] = 3 * verts[j] + b
            vals[o] = coeffs[i] * coeffs[j] * K[a, b]


@kernel(parallel=True, error_model="numpy")
def friction_hessian_triplets(u, verts, coeffs, basis, weight, eps, project, offsets):
    """∇²D as COO triplets (rows, cols, vals), int32/int32/float64 as the contact
    barrier's; pair k writes the slots [offsets[k], offsets[k+1]) only (parallel,
    disjoint). With `project` every local block is PSD (clamped 2 x 2 inner block,
    w ≥ 0)."""
    m = verts.shape[0]
    total = offsets[m]
    rows = np.empty(total, dtype=np.int32)
    cols = np.empty(total, dtype=np.int32)
    vals = np.empty(total)
    for k in prange(m):
        _hessian_into(u, verts[k], coeffs[k], basis[k], weight[k], eps, project,
                      rows, cols, vals, offsets[k])
    return rows, cols, vals


@njit(cache=True, error_model="numpy")
def triplet_offsets(verts):
    """offsets (m + 1,): pair k owns (3 nv_k)² triplet slots."""
    m = verts.shape[0]
    off = np.zeros(m + 1, dtype=np.int64)
    for k in range(m):
        nv = 0
        for i in range(4):
            nv += verts[k, i] >= 0
        off[k + 1] = off[k] + 9 * nv * nv
    return off




@njit(cache=True, error_model="numpy")
def ramp_unresolved(u, p, verts, coeffs, basis, weight, body, eps, fraction):
    """True when the pairs of some body that are in the static ramp (slip y = |τ(u)| < ε,
    τ(v) = Pᵀ Σ c_i v_i) but must slide would still change their friction force by
    fraction·ε·Σ w or more along the direction p (n, 3): Σ_k w_k |τ_k(p)| over those
    pairs against ε·Σ_k w_k over all pairs of the body, w_k = μλ_k. A pair's body is its
    first vertex's (body (n,) per vertex).

    To first order along p a ramp pair's friction force is μλ ρ, ρ = |(f1/y) τ + M d|,
    d = τ(p), M its tangent stiffness / μλ (above). ρ < 1: the pair sticks, whatever the
    solve's last digits of its slip. ρ ≥ 1: it must leave the ramp, which ‖p‖∞ < tol
    alone does not wait for (the ramp is a stiff spring, ~2μλ/ε, so p is small). A body
    slides on all its pairs together, so its ramp pairs' force changes, ~ w_k |d_k| / ε,
    are summed and compared with its whole friction capacity Σ w_k."""
    m = verts.shape[0]
    n_bodies = 0
    for k in range(m):
        n_bodies = max(n_bodies, body[verts[k, 0]] + 1)
    capacity = np.zeros(n_bodies)
    change = np.zeros(n_bodies)
    for k in range(m):
        b = body[verts[k, 0]]
        capacity[b] += weight[k]
        P = basis[k]
        t0, t1, y = _tangential(u, verts[k], coeffs[k], P)
        if y >= eps:
            continue  # sliding: the plain test decides
        d0, d1, dy = _tangential(p, verts[k], coeffs[k], P)
        # M d = (f1/y) d + ((f1' y − f1)/y³)(τ·d) τ, and (f1' y − f1)/y³ = −1/(ε² y)
        f1y = f1_over_y(y, eps)
        along = -(t0 * d0 + t1 * d1) / (eps * eps * y) if y > 0.0 else 0.0
        g0 = f1y * (t0 + d0) + along * t0
        g1 = f1y * (t1 + d1) + along * t1
        if g0 * g0 + g1 * g1 >= 1.0:
            change[b] += weight[k] * dy
    for b in range(n_bodies):
        if change[b] > 0.0 and change[b] >= fraction * eps * capacity[b]:
            return True
    return False
