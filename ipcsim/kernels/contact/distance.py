"""Squared distances between contact primitives, with gradients and Hessians.

All distances are SQUARED Euclidean distances d² (as in the original IPC code and in
ipctk). Derivatives are taken w.r.t. the stencil's stacked coordinates, vertex-major:

    point-point     (p, q)                 ->  6 DOFs
    point-line      (p, e0, e1)            ->  9 DOFs   (line through e0, e1)
    point-plane     (p, t0, t1, t2)        -> 12 DOFs   (plane through t0, t1, t2)
    line-line       (ea0, ea1, eb0, eb1)   -> 12 DOFs
    point-triangle  (p, t0, t1, t2), edge-edge (ea0, ea1, eb0, eb1), point-edge (p, e0, e1)

The stencil distances pick the closest feature pair ("distance type", integer codes equal
to ipctk's enums) and evaluate the matching sub-distance; their gradient and Hessian are
those of the sub-distance embedded in the stencil (the Hessian is not PSD).

Derivatives in closed form (one identity for every sub-distance)
----------------------------------------------------------------
Each sub-distance is the squared distance from an affine family to the origin,

    d(x) = min_β |q(x, β)|²,   q = Σ_i c_i(β) x_i   (affine in β, linear in x),

e.g. point-line: q = p − (1−t) e0 − t e1,  β = t.  At the minimiser (q ⟂ ∂q/∂β):

    ∇d  = 2 Bᵀq,   B = [c_0 I, c_1 I, ...]                  (envelope theorem)
    ∇²d = 2 BᵀB − 2 G M⁻¹ Gᵀ,   M = QᵀQ,  Q_k = ∂q/∂β_k,
          G_k (block i) = c_i Q_k + (∂c_i/∂β_k) q

(∇²d = f_xx − f_xβ f_ββ⁻¹ f_βx for f = |q|², with f_xx = 2BᵀB, f_ββ = 2M, f_xβ = 2G.)
Expanded with Σ_kl Q_k M⁻¹_kl Q_lᵀ = I − P⊥ (P⊥ projects onto the normal space of the
line/plane), each 3 x 3 block is

    ∇²d[i, j] = 2 c_i c_j P⊥ − 2 c_i a_j qᵀ − 2 c_j q a_iᵀ − 2 S_ij q qᵀ,
    a_j = Q M⁻¹ (∂c_j/∂β)ᵀ,   S = (∂c/∂β) M⁻¹ (∂c/∂β)ᵀ,

which is what _affine_hessian evaluates: no O(1/sin²θ) terms cancel, even for nearly
parallel lines. q, P⊥ and Q M⁻¹ come from cross products (not from β), so they stay
accurate when the point is close to the line/plane; det M = |cross product|² (Lagrange).
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit

from ipcsim.kernels.algebra.linalg import cross3, dot3, scale3, squared_norm3, sub3, symmetrize_from_upper

# --- distance-type codes (same integers as ipctk's enums) --------------------------------
PT_P_T0, PT_P_T1, PT_P_T2, PT_P_E0, PT_P_E1, PT_P_E2, PT_P_T, PT_AUTO = 0, 1, 2, 3, 4, 5, 6, 7
(EE_EA0_EB0, EE_EA0_EB1, EE_EA1_EB0, EE_EA1_EB1,
 EE_EA_EB0, EE_EA_EB1, EE_EA0_EB, EE_EA1_EB, EE_EA_EB, EE_AUTO) = range(10)
PE_P_E0, PE_P_E1, PE_P_E, PE_AUTO = 0, 1, 2, 3

# Edges count as parallel when |u×v|² < 2.5e-16 |u|²|v|²  (sin²θ below ~ machine eps, ipctk)
EE_PARALLEL_THRESHOLD = 2.5e-16


# =========================================================================================
# Shared closed-form Hessian of  min_β |Σ_i c_i(β) x_i|²
# =========================================================================================

@njit(cache=True, error_model="numpy")
def _affine_gradient(c, q):
    # ∇d = 2 Bᵀq: block i is 2 c_i q
    m = len(c)
    g = np.empty(3 * m)
    for i in range(m):
        for a in range(3):
            g[3 * i + a] = 2.0 * c[i] * q[a]
    return g


@njit(cache=True, error_model="numpy")
def _affine_hessian(c, dc, q, Pperp, R, Minv):
    """∇²d for d = min_β |Σ_i c_i(β) x_i|², block (i, j) (3 x 3):

        2 c_i c_j P⊥ − 2 c_i a_j qᵀ − 2 c_j q a_iᵀ − 2 S_ij q qᵀ,
        a_j = R dc_jᵀ,  R = Q M⁻¹ (3 x k, columns Σ_l Q_l M⁻¹_lk),  S = dc M⁻¹ dcᵀ,

    which is 2 BᵀB − 2 G M⁻¹ Gᵀ (module doc) expanded with G_k[i] = c_i Q_k + dc_ik q and
    Σ_kl Q_k M⁻¹_kl Q_lᵀ = I − P⊥ (projector onto span Q). Written this way no O(1/sin²θ)
    terms cancel for near-parallel lines: the caller passes P⊥ = n̂ n̂ᵀ and R from cross
    products. c: (m,), dc: (m, k), q: (3,), Pperp: (3, 3), R: (3, k), Minv: (k, k)."""
    m = len(c)
    k = dc.shape[1]
    A = np.zeros((m, 3))  # a_i = R dc_iᵀ
    S = np.zeros((m, m))  # S_ij = dc_i M⁻¹ dc_jᵀ
    for i in range(m):
        for kk in range(k):
            for a in range(3):
                A[i, a] += R[a, kk] * dc[i, kk]
    for i in range(m):
        for j in range(m):
            for kk in range(k):
                for ll in range(k):
                    S[i, j] += dc[i, kk] * Minv[kk, ll] * dc[j, ll]
    H = np.empty((3 * m, 3 * m))
    for i in range(m):
        for j in range(i, m):
            for a in range(3):
                for b in range(3):
                    H[3 * i + a, 3 * j + b] = 2.0 * (
                        c[i] * c[j] * Pperp[a, b]
                        - c[i] * A[j, a] * q[b]
                        - c[j] * q[a] * A[i, b]
                        - S[i, j] * q[a] * q[b]
                    )
    return symmetrize_from_upper(H)


@njit(cache=True, error_model="numpy")
def _normal_projector(n, N):
    # P⊥ = n nᵀ / |n|²
    P = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            P[a, b] = n[a] * n[b] / N
    return P


# =========================================================================================
# point-point:  d = |p − q|²
# =========================================================================================

@njit(cache=True, error_model="numpy")
def point_point_distance_sq(p, q):
    # d = |p − q|²
    return squared_norm3(sub3(p, q))


@njit(cache=True, error_model="numpy")
def point_point_distance_sq_gradient(p, q):
    # ∇d = [2(p − q), −2(p − q)]
    g = np.empty(6)
    for a in range(3):
        r = 2.0 * (p[a] - q[a])
        g[a] = r
        g[3 + a] = -r
    return g


@njit(cache=True, error_model="numpy")
def point_point_distance_sq_hessian(p, q):
    # ∇²d = 2 [[I, −I], [−I, I]]
    H = np.zeros((6, 6))
    for a in range(3):
        H[a, a] = 2.0
        H[3 + a, 3 + a] = 2.0
        H[a, 3 + a] = -2.0
        H[3 + a, a] = -2.0
    return H


# =========================================================================================
# point-line (infinite line through e0, e1):  d = |(e0 − p)×(e1 − p)|² / |e1 − e0|²
# =========================================================================================

@njit(cache=True, error_model="numpy")
def point_line_distance_sq(p, e0, e1):
    # d = |(e0 − p)×(e1 − p)|² / |e1 − e0|²
    return squared_norm3(cross3(sub3(e0, p), sub3(e1, p))) / squared_norm3(sub3(e1, e0))


@njit(cache=True, error_model="numpy")
def _point_line_closest(p, e0, e1):
    # e = e1 − e0, r = p − e0, t = r·e/|e|², q = p − (1−t)e0 − t e1 = (c × e)/|e|², c = e × r
    e = sub3(e1, e0)
    r = sub3(p, e0)
    L = squared_norm3(e)
    t = dot3(r, e) / L
    q = scale3(1.0 / L, cross3(cross3(e, r), e))
    c = (1.0, -(1.0 - t), -t)
    return q, c, e, L


@njit(cache=True, error_model="numpy")
def point_line_distance_sq_gradient(p, e0, e1):
    # ∇d = 2 [q, −(1−t) q, −t q]
    q, c, e, L = _point_line_closest(p, e0, e1)
    return _affine_gradient(c, q)


@njit(cache=True, error_model="numpy")
def point_line_distance_sq_hessian(p, e0, e1):
    # β = t: ∂c/∂t = (0, 1, −1); Q = ∂q/∂t = −e, M = |e|², R = Q M⁻¹ = −e/|e|², P⊥ = I − e eᵀ/|e|²
    q, c, e, L = _point_line_closest(p, e0, e1)
    dc = np.zeros((3, 1))
    dc[1, 0] = 1.0
    dc[2, 0] = -1.0
    R = np.empty((3, 1))
    Pperp = np.empty((3, 3))
    for a in range(3):
        R[a, 0] = -e[a] / L
        for b in range(3):
            Pperp[a, b] = (1.0 if a == b else 0.0) - e[a] * e[b] / L
    Minv = np.empty((1, 1))
    Minv[0, 0] = 1.0 / L
    return _affine_hessian(c, dc, q, Pperp, R, Minv)


# =========================================================================================
# point-plane (plane through t0, t1, t2):  d = ((p − t0)·n)² / |n|²,  n = (t1 − t0)×(t2 − t0)
# =========================================================================================

@njit(cache=True, error_model="numpy")
def point_plane_distance_sq(p, t0, t1, t2):
    # d = ((p − t0)·n)² / |n|²
    n = cross3(sub3(t1, t0), sub3(t2, t0))
    s = dot3(sub3(p, t0), n)
    return s * s / squared_norm3(n)


@njit(cache=True, error_model="numpy")
def _point_plane_closest(p, t0, t1, t2):
    # e1 = t1 − t0, e2 = t2 − t0, r = p − t0, N = |n|²
    # q = (r·n/N) n;  barycentric β1 = ((r×e2)·n)/N, β2 = ((e1×r)·n)/N
    e1 = sub3(t1, t0)
    e2 = sub3(t2, t0)
    r = sub3(p, t0)
    n = cross3(e1, e2)
    N = squared_norm3(n)
    q = scale3(dot3(r, n) / N, n)
    b1 = dot3(cross3(r, e2), n) / N
    b2 = dot3(cross3(e1, r), n) / N
    c = (1.0, -(1.0 - b1 - b2), -b1, -b2)
    return q, c, e1, e2, n, N


@njit(cache=True, error_model="numpy")
def point_plane_distance_sq_gradient(p, t0, t1, t2):
    # ∇d = 2 [q, −β0 q, −β1 q, −β2 q]
    q, c, e1, e2, n, N = _point_plane_closest(p, t0, t1, t2)
    return _affine_gradient(c, q)


@njit(cache=True, error_model="numpy")
def point_plane_distance_sq_hessian(p, t0, t1, t2):
    # β = (β1, β2): ∂c/∂β1 = (0, 1, −1, 0), ∂c/∂β2 = (0, 1, 0, −1); Q = (−e1, −e2)
    # M = Gram(e1, e2), M⁻¹ = [[e2·e2, −e1·e2], [−e1·e2, e1·e1]] / N   (det M = |n|² = N)
    # R = Q M⁻¹ = [−e2×n, e1×n] / N  (BAC-CAB),  P⊥ = n nᵀ / N
    q, c, e1, e2, n, N = _point_plane_closest(p, t0, t1, t2)
    dc = np.zeros((4, 2))
    dc[1, 0] = 1.0
    dc[2, 0] = -1.0
    dc[1, 1] = 1.0
    dc[3, 1] = -1.0
    r1 = cross3(e2, n)
    r2 = cross3(e1, n)
    R = np.empty((3, 2))
    for a in range(3):
        R[a, 0] = -r1[a] / N
        R[a, 1] = r2[a] / N
    Minv = np.empty((2, 2))
    Minv[0, 0] = dot3(e2, e2) / N
    Minv[1, 1] = dot3(e1, e1) / N
    Minv[0, 1] = -dot3(e1, e2) / N
    Minv[1, 0] = Minv[0, 1]
    return _affine_hessian(c, dc, q, _normal_projector(n, N), R, Minv)


# =========================================================================================
# line-line (infinite lines, non-parallel):  d = ((eb0 − ea0)·n)² / |n|²,  n = u×v
# =========================================================================================

@njit(cache=True, error_model="numpy", inline="always")
def edge_directions(ea0, ea1, eb0, eb1):
    """u = ea1 − ea0, v = eb1 − eb0 and the common normal n = u×v (the mollifier's c is
    |n|²)."""
    u = sub3(ea1, ea0)
    v = sub3(eb1, eb0)
    return u, v, cross3(u, v)


@njit(cache=True, error_model="numpy")
def line_line_distance_sq(ea0, ea1, eb0, eb1):
    # d = ((eb0 − ea0)·n)² / |n|²,  n = (ea1 − ea0)×(eb1 − eb0)
    _, _, n = edge_directions(ea0, ea1, eb0, eb1)
    s = dot3(sub3(eb0, ea0), n)
    return s * s / squared_norm3(n)


@njit(cache=True, error_model="numpy")
def _line_line_closest(ea0, ea1, eb0, eb1):
    # u = ea1 − ea0, v = eb1 − eb0, w = ea0 − eb0, n = u×v, N = |n|²
    # q = (ea0 + s u) − (eb0 + t v) = (w·n/N) n
    # s = −((w×v)·n)/N,  t = −((w×u)·n)/N      (from (q×v)·n = (q×u)·n = 0)
    u, v, n = edge_directions(ea0, ea1, eb0, eb1)
    w = sub3(ea0, eb0)
    N = squared_norm3(n)
    q = scale3(dot3(w, n) / N, n)
    s = -dot3(cross3(w, v), n) / N
    t = -dot3(cross3(w, u), n) / N
    c = (1.0 - s, s, -(1.0 - t), -t)
    return q, c, u, v, n, N


@njit(cache=True, error_model="numpy")
def line_line_distance_sq_gradient(ea0, ea1, eb0, eb1):
    # ∇d = 2 [(1−s) q, s q, −(1−t) q, −t q]
    q, c, u, v, n, N = _line_line_closest(ea0, ea1, eb0, eb1)
    return _affine_gradient(c, q)


@njit(cache=True, error_model="numpy")
def line_line_distance_sq_hessian(ea0, ea1, eb0, eb1):
    # β = (s, t): ∂c/∂s = (−1, 1, 0, 0), ∂c/∂t = (0, 0, 1, −1); Q = (u, −v)
    # M = [[u·u, −u·v], [−u·v, v·v]], M⁻¹ = [[v·v, u·v], [u·v, u·u]] / N   (det M = |u×v|²)
    # R = Q M⁻¹ = [v×n, u×n] / N  (BAC-CAB),  P⊥ = n nᵀ / N
    q, c, u, v, n, N = _line_line_closest(ea0, ea1, eb0, eb1)
    dc = np.zeros((4, 2))
    dc[0, 0] = -1.0
    dc[1, 0] = 1.0
    dc[2, 1] = 1.0
    dc[3, 1] = -1.0
    r1 = cross3(v, n)
    r2 = cross3(u, n)
    R = np.empty((3, 2))
    for a in range(3):
        R[a, 0] = r1[a] / N
        R[a, 1] = r2[a] / N
    Minv = np.empty((2, 2))
    Minv[0, 0] = dot3(v, v) / N
    Minv[1, 1] = dot3(u, u) / N
    Minv[0, 1] = dot3(u, v) / N
    Minv[1, 0] = Minv[0, 1]
    return _affine_hessian(c, dc, q, _normal_projector(n, N), R, Minv)


# =========================================================================================
# Closest-feature (distance type) selection, compatible with ipctk
# =========================================================================================

@njit(cache=True, error_model="numpy")
def point_edge_distance_type(p, e0, e1):
    # t = (p − e0)·e / |e|²:  t < 0 -> P_E0, t > 1 -> P_E1, else P_E (degenerate edge -> P_E0)
    e = sub3(e1, e0)
    L = squared_norm3(e)
    if L == 0.0:
        return PE_P_E0
    t = dot3(sub3(p, e0), e) / L
    if t < 0.0:
        return PE_P_E0
    if t > 1.0:
        return PE_P_E1
    return PE_P_E


@njit(cache=True, error_model="numpy")
def _edge_frame_coords(p, a, b, n):
    # coordinates of p − a in the orthogonal frame (e, e×n) of edge a->b, undivided:
    # (e·(p − a), |e|², (e×n)·(p − a)). The edge parameter is s = e·(p − a)/|e|², and
    # p is outside the edge when the last is ≥ 0. The type tests compare e·(p − a) with 0
    # and |e|² instead of s with 0 and 1: the same outcome in floating point (a/L < 1 iff
    # a < L for L > 0, barring underflow), without the divisions.
    e = sub3(b, a)
    r = sub3(p, a)
    return dot3(e, r), squared_norm3(e), dot3(cross3(e, n), r)


@njit(cache=True, error_model="numpy")
def degenerate_triangle_distance_type(p, t0, t1, t2):
    """Type for a triangle with collinear vertices (normal exactly 0, no plane): the closest
    of its three edges (t0t1, t1t2, t2t0) as segments, i.e. P_E{k} or a vertex P_T{k}
    (the first edge wins a tie)."""
    T = (t0, t1, t2)
    best = PT_P_T0
    d_best = np.inf
    for k in range(3):
        kb = (k + 1) % 3
        pe = point_edge_distance_type(p, T[k], T[kb])
        d = point_edge_distance_sq(p, T[k], T[kb], pe)
        if d < d_best:
            d_best = d
            best = PT_P_E0 + k if pe == PE_P_E else (PT_P_T0 + k if pe == PE_P_E0 else PT_P_T0 + kb)
    return best


@njit(cache=True, error_model="numpy")
def point_triangle_distance_type(p, t0, t1, t2):
    """P_E{k} when p projects inside edge k (t0t1, t1t2, t2t0) on its outer side; else a
    vertex when p is beyond both of its edges' ends; else the interior P_T. A degenerate
    triangle (collinear vertices) goes to degenerate_triangle_distance_type."""
    n = cross3(sub3(t1, t0), sub3(t2, t0))
    if n[0] == 0.0 and n[1] == 0.0 and n[2] == 0.0:
        return degenerate_triangle_distance_type(p, t0, t1, t2)
    # per edge k: a_k = e·(p − t_k), L_k = |e|² (s_k = a_k / L_k), h_k ≥ 0: outside
    a0, L0, h0 = _edge_frame_coords(p, t0, t1, n)
    if a0 > 0.0 and a0 < L0 and h0 >= 0.0:
        return PT_P_E0
    a1, L1, h1 = _edge_frame_coords(p, t1, t2, n)
    if a1 > 0.0 and a1 < L1 and h1 >= 0.0:
        return PT_P_E1
    a2, L2, h2 = _edge_frame_coords(p, t2, t0, n)
    if a2 > 0.0 and a2 < L2 and h2 >= 0.0:
        return PT_P_E2
    if a0 <= 0.0 and a2 >= L2:
        return PT_P_T0
    if a1 <= 0.0 and a0 >= L0:
        return PT_P_T1
    if a2 <= 0.0 and a1 >= L1:
        return PT_P_T2
    return PT_P_T


@njit(cache=True, error_model="numpy")
def edge_edge_parallel_distance_type(ea0, ea1, eb0, eb1):
    """Type for (near-)parallel edges: project eb0, eb1 on line a (alpha, beta in units of
    |ea|), then decide which endpoint of each edge is closest."""
    ea = sub3(ea1, ea0)
    L = squared_norm3(ea)
    alpha = dot3(sub3(eb0, ea0), ea) / L
    beta = dot3(sub3(eb1, ea0), ea) / L
    # feature of a: 0 = ea0, 1 = ea1, 2 = the whole line; same coding for b
    if alpha < 0.0:
        fa = 2 if (0.0 <= beta and beta <= 1.0) else 0
        fb = 0 if beta <= alpha else (1 if beta <= 1.0 else 2)
    elif alpha > 1.0:
        fa = 2 if (0.0 <= beta and beta <= 1.0) else 1
        fb = 0 if beta >= alpha else (1 if 0.0 <= beta else 2)
    else:
        fa = 2
        fb = 0
    if fb < 2:
        return 2 * fa + fb  # EA0_EB0, EA0_EB1, EA1_EB0, EA1_EB1, EA_EB0, EA_EB1
    return 6 + fa  # EA0_EB, EA1_EB


@njit(cache=True, error_model="numpy")
def edge_edge_distance_type(ea0, ea1, eb0, eb1):
    """Closest features of two segments, after the segment-segment algorithm of
    geomalgorithms.com (Sunday), made robust as in ipctk: line parameters
    sc = sN/sD, tc = tN/tD are clamped to the segments and the clamped case names
    the type; near-parallel edges go to edge_edge_parallel_distance_type."""
    u = sub3(ea1, ea0)
    v = sub3(eb1, eb0)
    w = sub3(ea0, eb0)
    a = dot3(u, u)
    b = dot3(u, v)
    c = dot3(v, v)
    d = dot3(u, w)
    e = dot3(v, w)
    D = a * c - b * b
    if a == 0.0 and c == 0.0:
        return EE_EA0_EB0
    if a == 0.0:
        return EE_EA0_EB
    if c == 0.0:
        return EE_EA_EB0
    if squared_norm3(cross3(u, v)) < EE_PARALLEL_THRESHOLD * a * c:
        return edge_edge_parallel_distance_type(ea0, ea1, eb0, eb1)

    # s on edge a: sc = sN / D;  t on edge b: tc = tN / tD
    default = EE_EA_EB
    sN = b * e - c * d
    if sN <= 0.0:  # sc ≤ 0: ea0 end
        tN = e
        tD = c
        default = EE_EA0_EB
    elif sN >= D:  # sc ≥ 1: ea1 end
        tN = e + b
        tD = c
        default = EE_EA1_EB
    else:
        tN = a * e - b * d
        tD = D

    if tN <= 0.0:  # tc ≤ 0: eb0 end; recompute s for eb0 against a
        if -d <= 0.0:
            return EE_EA0_EB0
        if -d >= a:
            return EE_EA1_EB0
        return EE_EA_EB0
    if tN >= tD:  # tc ≥ 1: eb1 end
        if -d + b <= 0.0:
            return EE_EA0_EB1
        if -d + b >= a:
            return EE_EA1_EB1
        return EE_EA_EB1
    return default


# =========================================================================================
# Stencil distances: type -> (sub-distance, vertex slots), then embed in the stencil
# =========================================================================================

POINT_POINT, POINT_LINE, POINT_PLANE, LINE_LINE = 0, 1, 2, 3  # sub-distance codes

# row = distance type: [sub-distance, slot0, slot1, slot2, slot3] (−1: slot unused);
# the sub-distance's arguments are the stencil vertices at those slots, in that order.
PT_FEATURES = np.array([
    [POINT_POINT, 0, 1, -1, -1],   # P_T0: (p, t0)
    [POINT_POINT, 0, 2, -1, -1],   # P_T1: (p, t1)
    [POINT_POINT, 0, 3, -1, -1],   # P_T2: (p, t2)
    [POINT_LINE, 0, 1, 2, -1],     # P_E0: (p, t0, t1)
    [POINT_LINE, 0, 2, 3, -1],     # P_E1: (p, t1, t2)
    [POINT_LINE, 0, 3, 1, -1],     # P_E2: (p, t2, t0)
    [POINT_PLANE, 0, 1, 2, 3],     # P_T:  (p, t0, t1, t2)
], dtype=np.int64)
EE_FEATURES = np.array([
    [POINT_POINT, 0, 2, -1, -1],   # EA0_EB0: (ea0, eb0)
    [POINT_POINT, 0, 3, -1, -1],   # EA0_EB1: (ea0, eb1)
    [POINT_POINT, 1, 2, -1, -1],   # EA1_EB0: (ea1, eb0)
    [POINT_POINT, 1, 3, -1, -1],   # EA1_EB1: (ea1, eb1)
    [POINT_LINE, 2, 0, 1, -1],     # EA_EB0:  eb0 vs line a
    [POINT_LINE, 3, 0, 1, -1],     # EA_EB1:  eb1 vs line a
    [POINT_LINE, 0, 2, 3, -1],     # EA0_EB:  ea0 vs line b
    [POINT_LINE, 1, 2, 3, -1],     # EA1_EB:  ea1 vs line b
    [LINE_LINE, 0, 1, 2, 3],       # EA_EB:   line a vs line b
], dtype=np.int64)
PE_FEATURES = np.array([
    [POINT_POINT, 0, 1, -1, -1],   # P_E0: (p, e0)
    [POINT_POINT, 0, 2, -1, -1],   # P_E1: (p, e1)
    [POINT_LINE, 0, 1, 2, -1],     # P_E:  (p, e0, e1)
], dtype=np.int64)


@njit(cache=True, error_model="numpy")
def feature_distance_sq(V, f):
    # V: tuple of the stencil's 3-vectors, f: a row of a *_FEATURES table
    if f[0] == POINT_POINT:
        return point_point_distance_sq(V[f[1]], V[f[2]])
    if f[0] == POINT_LINE:
        return point_line_distance_sq(V[f[1]], V[f[2]], V[f[3]])
    if f[0] == POINT_PLANE:
        return point_plane_distance_sq(V[f[1]], V[f[2]], V[f[3]], V[f[4]])
    return line_line_distance_sq(V[f[1]], V[f[2]], V[f[3]], V[f[4]])


@njit(cache=True, error_model="numpy")
def feature_distance_sq_gradient(V, f):
    # sub-distance gradient scattered to the stencil: g[slot k] = g_sub[k], 0 elsewhere
    if f[0] == POINT_POINT:
        gs = point_point_distance_sq_gradient(V[f[1]], V[f[2]])
    elif f[0] == POINT_LINE:
        gs = point_line_distance_sq_gradient(V[f[1]], V[f[2]], V[f[3]])
    elif f[0] == POINT_PLANE:
        gs = point_plane_distance_sq_gradient(V[f[1]], V[f[2]], V[f[3]], V[f[4]])
    else:
        gs = line_line_distance_sq_gradient(V[f[1]], V[f[2]], V[f[3]], V[f[4]])
    g = np.zeros(3 * len(V))
    for k in range(gs.shape[0] // 3):
        for a in range(3):
            g[3 * f[1 + k] + a] = gs[3 * k + a]
    return g


@njit(cache=True, error_model="numpy")
def feature_distance_sq_hessian(V, f):
    # sub-distance Hessian scattered to the stencil: H[slot k, slot l] = H_sub[k, l]
    if f[0] == POINT_POINT:
        Hs = point_point_distance_sq_hessian(V[f[1]], V[f[2]])
    elif f[0] == POINT_LINE:
        Hs = point_line_distance_sq_hessian(V[f[1]], V[f[2]], V[f[3]])
    elif f[0] == POINT_PLANE:
        Hs = point_plane_distance_sq_hessian(V[f[1]], V[f[2]], V[f[3]], V[f[4]])
    else:
        Hs = line_line_distance_sq_hessian(V[f[1]], V[f[2]], V[f[3]], V[f[4]])
    n = 3 * len(V)
    H = np.zeros((n, n))
    m = Hs.shape[0] // 3
    for k in range(m):
        for l in range(m):
            for a in range(3):
                for b in range(3):
                    H[3 * f[1 + k] + a, 3 * f[1 + l] + b] = Hs[3 * k + a, 3 * l + b]
    return H


# --- point-triangle (p, t0, t1, t2): vertex (point-point), edge (point-line), face (plane) --

@njit(cache=True, error_model="numpy")
def point_triangle_distance_sq(p, t0, t1, t2, dtype=PT_AUTO):
    if dtype == PT_AUTO:
        dtype = point_triangle_distance_type(p, t0, t1, t2)
    return feature_distance_sq((p, t0, t1, t2), PT_FEATURES[dtype])


@njit(cache=True, error_model="numpy")
def point_triangle_distance_sq_gradient(p, t0, t1, t2, dtype=PT_AUTO):
    if dtype == PT_AUTO:
        dtype = point_triangle_distance_type(p, t0, t1, t2)
    return feature_distance_sq_gradient((p, t0, t1, t2), PT_FEATURES[dtype])


@njit(cache=True, error_model="numpy")
def point_triangle_distance_sq_hessian(p, t0, t1, t2, dtype=PT_AUTO):
    if dtype == PT_AUTO:
        dtype = point_triangle_distance_type(p, t0, t1, t2)
    return feature_distance_sq_hessian((p, t0, t1, t2), PT_FEATURES[dtype])


# --- edge-edge (ea0, ea1, eb0, eb1): endpoints, endpoint vs line, or line-line ------------

@njit(cache=True, error_model="numpy")
def edge_edge_distance_sq(ea0, ea1, eb0, eb1, dtype=EE_AUTO):
    if dtype == EE_AUTO:
        dtype = edge_edge_distance_type(ea0, ea1, eb0, eb1)
    return feature_distance_sq((ea0, ea1, eb0, eb1), EE_FEATURES[dtype])


@njit(cache=True, error_model="numpy")
def edge_edge_distance_sq_gradient(ea0, ea1, eb0, eb1, dtype=EE_AUTO):
    if dtype == EE_AUTO:
        dtype = edge_edge_distance_type(ea0, ea1, eb0, eb1)
    return feature_distance_sq_gradient((ea0, ea1, eb0, eb1), EE_FEATURES[dtype])


@njit(cache=True, error_model="numpy")
def edge_edge_distance_sq_hessian(ea0, ea1, eb0, eb1, dtype=EE_AUTO):
    if dtype == EE_AUTO:
        dtype = edge_edge_distance_type(ea0, ea1, eb0, eb1)
    return feature_distance_sq_hessian((ea0, ea1, eb0, eb1), EE_FEATURES[dtype])


# --- point-edge (p, e0, e1): endpoint or point-line -----------------------------------------

@njit(cache=True, error_model="numpy")
def point_edge_distance_sq(p, e0, e1, dtype=PE_AUTO):
    if dtype == PE_AUTO:
        dtype = point_edge_distance_type(p, e0, e1)
    return feature_distance_sq((p, e0, e1), PE_FEATURES[dtype])


@njit(cache=True, error_model="numpy")
def point_edge_distance_sq_gradient(p, e0, e1, dtype=PE_AUTO):
    if dtype == PE_AUTO:
        dtype = point_edge_distance_type(p, e0, e1)
    return feature_distance_sq_gradient((p, e0, e1), PE_FEATURES[dtype])


@njit(cache=True, error_model="numpy")
def point_edge_distance_sq_hessian(p, e0, e1, dtype=PE_AUTO):
    if dtype == PE_AUTO:
        dtype = point_edge_distance_type(p, e0, e1)
    return feature_distance_sq_hessian((p, e0, e1), PE_FEATURES[dtype])
