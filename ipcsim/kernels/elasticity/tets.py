"""Hyperelastic energies of linear tetrahedra, their gradients and PSD-projected Hessians.

Per tet e with vertices (x0, x1, x2, x3):

    Ds = [x1 − x0, x2 − x0, x3 − x0]       (columns),  Dm likewise at rest
    F  = Ds Dm⁻¹,  J = det F,  F = U Σ Vᵀ   (rotation-variant SVD: det U = det V = +1,
                                            σ0 ≥ σ1 ≥ |σ2|, only σ2 may be negative)
    E_e = V_rest · Ψ(F)

Energy densities, as in the original IPC program (``model`` codes):

    0  neo-Hookean     Ψ = μ/2 (tr FᵀF − 3) − μ ln J + λ/2 (ln J)²,   +∞ for J ≤ 0
    1  fixed corotated Ψ = μ Σ (σᵢ − 1)² + λ/2 (J − 1)²             (Stomakhin et al. 2012)

Derivatives in the singular values (ψᵢ = ∂Ψ/∂σᵢ, P = ∂Ψ/∂F = U diag(ψ) Vᵀ):

    NH   ψᵢ = μ σᵢ − (μ − λ ln J)/σᵢ
    FCR  ψᵢ = 2μ(σᵢ − 1) + λ (J − 1) σⱼσₖ

Hessian and its PSD projection (Smith, de Goes, Kim 2019, "Analytic eigensystems for
isotropic distortion energies"): ∂²Ψ/∂F² has the nine orthonormal eigenmatrices

    scaling  Σᵢ wᵢₖ uᵢvᵢᵀ          eigenvalues = eigenvalues of A = ∂²Ψ/∂σ² (3×3), w its vectors
    twist    (uᵢvⱼᵀ − uⱼvᵢᵀ)/√2     λ = (ψᵢ + ψⱼ)/(σᵢ + σⱼ)
    flip     (uᵢvⱼᵀ + uⱼvᵢᵀ)/√2     λ = (ψᵢ − ψⱼ)/(σᵢ − σⱼ)

for each pair i < j. The two quotients are written in closed form below with the
σᵢ − σⱼ (and for NH the σᵢ + σⱼ) cancelled, so nothing blows up at σᵢ ≈ σⱼ. Projection
clamps every eigenvalue at 0. The element Hessian is V_rest Σₖ λₖ gₖgₖᵀ with
gₖ = (∂F/∂x)ᵀ vec(Qₖ) the 12-vector of mode Qₖ, the same map that turns P into the gradient.
The 3×3 block A is diagonalised (cyclic Jacobi) only when it has to be clamped: when A is
already positive definite (Sylvester's criterion), or without projection, its part is
Σᵢⱼ Aᵢⱼ gᵢgⱼᵀ with gᵢ the vector of uᵢvᵢᵀ.

Layout: x (n, 3), tets (m, 4) int64, Dm_inv (m, 3, 3), volumes (m,), lame (m, 2) = (μ, λ).
Gradients are flat (3n,) with DOF 3i + a. Hessians are COO triplets with exactly 144 entries
per tet at offset 144·e, row-major over the local DOFs 3·v + a (v = 0..3 the tet's vertices).
The NH gradient and Hessian are NaN for an element with J ≤ 0 (its energy is +∞; the line
search bound ``max_step_no_inversion`` keeps the solver away from there). FCR is finite for
inverted elements but not smooth where σ₁ + σ₂ = 0 (the rotation of F jumps there); its
twist eigenvalue −4μ/(σ₁ + σ₂) is evaluated with the sum floored at 1e-12.

Step bound (the original IPC's rule): ``max_step_no_inversion(x, p, tets, r)`` returns the
largest α ∈ [0, 1] with det Ds(x + t p) > r · det Ds(x) on [0, α) for every tet. The
determinant along the line is a cubic in t; its first crossing of r · det Ds(x) is found by
splitting [0, 1] at the critical points into monotone pieces and bisecting the first piece
whose end value is ≤ 0, which is immune to vanishing leading coefficients and returns a
point on the safe side of the root.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.algebra.linalg import (
    cofactor3,
    det3,
    edge_matrix,
    hypot,
    ordered_sum,
    symmetrize_from_upper,
)
from ipcsim.kernels.algebra.scatter import local_dof, scatter_local_gradients
from ipcsim.compiler.twin import kernel

NEO_HOOKEAN = 0
FIXED_COROTATED = 1

_CHUNK = 256  # tets per parallel work item; scratch arrays are allocated once per chunk
# Small helpers are inlined at the numba IR level (inline="always"): a call that passes
# arrays costs atomic reference-count updates per array, which dominated the cheap
# per-tet work. The SVD, the 3×3 eigensolver and the element Hessian stay real calls
# (inlining them too gained ~1.5× more but more than doubled the compile time).
_INV_SQRT2 = 1.0 / np.sqrt(2.0)
_MIN_PAIR_SUM = 1e-12  # FCR twist: σᵢ + σⱼ ≥ 0 for the rotation-variant SVD; floor it here


# --------------------------------------------------------------------------------------
# small dense helpers (write into caller-provided arrays; no allocation per element)
# --------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _pair(k):
    # pairs in the order (0,1), (0,2), (1,2); the third index is the one left out
    if k == 0:
        return 0, 1, 2
    if k == 1:
        return 0, 2, 1
    return 1, 2, 0


@njit(cache=True, inline="always")
def _deformation_gradient(x, tets, Dm_inv, e, Ds, F):
    # F = Ds Dm⁻¹
    edge_matrix(x, tets, e, Ds)
    for a in range(3):
        for b in range(3):
            F[a, b] = Ds[a, 0] * Dm_inv[e, 0, b] + Ds[a, 1] * Dm_inv[e, 1, b] + Ds[a, 2] * Dm_inv[e, 2, b]


@njit(cache=True, inline="always")
def _jacobi_rotation(zeta):
    """(c, s, t) of the Jacobi rotation for ζ = (a_qq − a_pp)/(2 a_pq) (of the matrix, or of
    the Gram matrix of two columns): t = sgn ζ / (|ζ| + √(1 + ζ²)), the smaller root of
    t² + 2ζt − 1 = 0 (t ≈ 1/(2ζ) once ζ² would overflow), c = 1/√(1 + t²), s = c t."""
    if abs(zeta) > 1e150:
        t = 0.5 / zeta
    else:
        t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + np.sqrt(1.0 + zeta * zeta))
    c = 1.0 / np.sqrt(1.0 + t * t)
    return c, c * t, t


@njit(cache=True, inline="always")
def _rotate_columns(X, p, q, c, s):
    # X ← X J for a 3 x 3 X, J the rotation by (c, s) in the (p, q) plane:
    # columns (x_p, x_q) ← (c x_p − s x_q, s x_p + c x_q)
    for a in range(3):
        xp = X[a, p]
        xq = X[a, q]
        X[a, p] = c * xp - s * xq
        X[a, q] = s * xp + c * xq


@njit(cache=True, inline="always")
def _jacobi_orthogonalize(B, V):
    # one-sided Jacobi (Hestenes): rotate column pairs of B (and V alike) until they are
    # orthogonal
    for _sweep in range(20):
        t_max = 0.0  # largest rotation this sweep; Jacobi converges quadratically, so once
        #              every |t| < 1e-9 the off-diagonal left is ~1e-18 and we stop
        for k in range(3):
            p, q, _r = _pair(k)
            alpha = B[0, p] * B[0, p] + B[1, p] * B[1, p] + B[2, p] * B[2, p]
            beta = B[0, q] * B[0, q] + B[1, q] * B[1, q] + B[2, q] * B[2, q]
            gamma = B[0, p] * B[0, q] + B[1, p] * B[1, q] + B[2, p] * B[2, q]
            if abs(gamma) <= 1e-15 * np.sqrt(alpha * beta):
                continue
            # the rotation zeroes γ' = cs(α−β) + (c²−s²)γ
            c, sn, t = _jacobi_rotation((beta - alpha) / (2.0 * gamma))
            t_max = max(t_max, abs(t))
            _rotate_columns(B, p, q, c, sn)
            _rotate_columns(V, p, q, c, sn)
        if t_max < 1e-9:
            break


@njit(cache=True, inline="always")
def _sort_columns(B, V):
    # columns of B (and V alike) by squared norm, descending (three compare-and-swaps);
    # then det V = +1 by negating the last column of both
    for k in range(3):
        p = 0 if k != 1 else 1
        q = p + 1
        np_ = B[0, p] * B[0, p] + B[1, p] * B[1, p] + B[2, p] * B[2, p]
        nq = B[0, q] * B[0, q] + B[1, q] * B[1, q] + B[2, q] * B[2, q]
        if nq > np_:
            for a in range(3):
                tmp = B[a, p]
                B[a, p] = B[a, q]
                B[a, q] = tmp
                tmp = V[a, p]
                V[a, p] = V[a, q]
                V[a, q] = tmp
    if det3(V) < 0.0:
        for a in range(3):
            V[a, 2] = -V[a, 2]
            B[a, 2] = -B[a, 2]


@njit(cache=True, inline="always")
def _givens_qr(B, U):
    # Givens QR: zero B[1,0], B[2,0], B[2,1]; U ← U Gᵀ keeps F V = U B
    for k in range(3):
        if k == 0:
            col, r0, r1 = 0, 0, 1
        elif k == 1:
            col, r0, r1 = 0, 0, 2
        else:
            col, r0, r1 = 1, 1, 2
        ga = B[r0, col]
        gb = B[r1, col]
        r = hypot(ga, gb)
        if r == 0.0:
            continue
        c = ga / r
        sn = gb / r
        for a in range(3):
            b0 = B[r0, a]
            b1 = B[r1, a]
            B[r0, a] = c * b0 + sn * b1
            B[r1, a] = -sn * b0 + c * b1
            u0 = U[a, r0]
            u1 = U[a, r1]
            U[a, r0] = c * u0 + sn * u1
            U[a, r1] = -sn * u0 + c * u1


@njit(cache=True)
def _svd3(F, U, s, V, B):
    """Rotation-variant SVD F = U diag(s) Vᵀ with det U = det V = +1, s0 ≥ s1 ≥ |s2|.

    1. one-sided Jacobi (Hestenes): rotate column pairs of B = F V until they are
       orthogonal (accurate also for small singular values, unlike eig(FᵀF));
    2. sort columns by norm, make det V = +1 by negating the last column;
    3. Givens QR of B = U R with U a product of rotations: R is diagonal up to round-off,
       s = diag(R), and s2 carries the sign of det F.
    B is scratch (3, 3). The three steps are inlined (inline="always"): one call.
    """
    for a in range(3):
        for b in range(3):
            B[a, b] = F[a, b]
            V[a, b] = 1.0 if a == b else 0.0
            U[a, b] = 1.0 if a == b else 0.0
    _jacobi_orthogonalize(B, V)
    _sort_columns(B, V)
    _givens_qr(B, U)
    s[0] = B[0, 0]
    s[1] = B[1, 1]
    s[2] = B[2, 2]


@njit(cache=True)
def _sym3_eig(A, w, Q, M):
    """Eigen-decomposition of the symmetric 3×3 A by cyclic Jacobi: A = Q diag(w) Qᵀ.
    M is scratch (3, 3); A is not modified."""
    for a in range(3):
        for b in range(3):
            M[a, b] = A[a, b]
            Q[a, b] = 1.0 if a == b else 0.0
    for _sweep in range(30):
        t_max = 0.0  # as in _svd3: stop once a sweep only made rotations below 1e-9
        for k in range(3):
            p, q, _r = _pair(k)
            apq = M[p, q]
            # negligible next to the diagonal (or exactly 0): skip
            if abs(apq) <= 1e-16 * (abs(M[p, p]) + abs(M[q, q])):
                continue
            # the rotation zeroes a_pq
            c, sn, t = _jacobi_rotation((M[q, q] - M[p, p]) / (2.0 * apq))
            t_max = max(t_max, abs(t))
            # M ← Jᵀ M J, Q ← Q J
            _rotate_columns(M, p, q, c, sn)
            _rotate_columns(M.T, p, q, c, sn)
            M[p, q] = 0.0  # zero by construction; drop the round-off residue
            M[q, p] = 0.0
            _rotate_columns(Q, p, q, c, sn)
        if t_max < 1e-9:
            break
    w[0] = M[0, 0]
    w[1] = M[1, 1]
    w[2] = M[2, 2]


# --------------------------------------------------------------------------------------
# energy densities and their derivatives in the singular values
# (the scalar formulas are public: triangles.py evaluates them in plane strain, at
# F₃ = diag(F, 1), σ₃ = 1)
# --------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def neo_hookean_density(trace_c, J, mu, lam):
    """Ψ = μ/2 (tr FᵀF − 3) − μ ln J + λ/2 (ln J)² from tr FᵀF and J; +∞ for J ≤ 0."""
    if J <= 0.0:
        return np.inf
    lnJ = np.log(J)
    return 0.5 * mu * (trace_c - 3.0) - mu * lnJ + 0.5 * lam * lnJ * lnJ


@njit(cache=True, inline="always")
def neo_hookean_cofactor_factor(J, mu, lam):
    """k of the NH stress P = μ F + k cof F, k = (λ ln J − μ)/J (cof F = J F⁻ᵀ), J > 0."""
    return (lam * np.log(J) - mu) / J


@njit(cache=True, inline="always")
def fixed_corotated_density(s0, s1, s2, J, mu, lam):
    """Ψ = μ Σ (σᵢ − 1)² + λ/2 (J − 1)²."""
    return mu * ((s0 - 1.0) ** 2 + (s1 - 1.0) ** 2 + (s2 - 1.0) ** 2) + 0.5 * lam * (J - 1.0) ** 2


@njit(cache=True, inline="always")
def fixed_corotated_stress(si, sj, sk, J, mu, lam):
    """ψᵢ = ∂Ψ/∂σᵢ = 2μ(σᵢ − 1) + λ (J − 1) σⱼσₖ of the fixed corotated Ψ."""
    return 2.0 * mu * (si - 1.0) + lam * (J - 1.0) * sj * sk


@njit(cache=True, inline="always")
def _psi_from_F(F, mu, lam, model, U, s, V, B):
    if model == NEO_HOOKEAN:
        # Ψ = μ/2 (tr FᵀF − 3) − μ ln J + λ/2 (ln J)²
        trc = 0.0
        for a in range(3):
            for b in range(3):
                trc += F[a, b] * F[a, b]
        return neo_hookean_density(trc, det3(F), mu, lam)
    # Ψ = μ Σ (σᵢ − 1)² + λ/2 (J − 1)²
    _svd3(F, U, s, V, B)
    return fixed_corotated_density(s[0], s[1], s[2], det3(F), mu, lam)


@njit(cache=True, inline="always")
def _first_piola(F, mu, lam, model, P, U, s, V, B):
    """P = ∂Ψ/∂F. Returns False (and leaves P undefined) for NH with J ≤ 0."""
    if model == NEO_HOOKEAN:
        # P = μ F + (λ ln J − μ) F⁻ᵀ,  F⁻ᵀ = cof(F)/J
        cofactor3(F, B)
        J = det3(F)
        if J <= 0.0:
            return False
        k = neo_hookean_cofactor_factor(J, mu, lam)
        for a in range(3):
            for b in range(3):
                P[a, b] = mu * F[a, b] + k * B[a, b]
        return True
    # P = U diag(ψ) Vᵀ,  ψᵢ = 2μ(σᵢ − 1) + λ (J − 1) σⱼσₖ
    _svd3(F, U, s, V, B)
    J = s[0] * s[1] * s[2]
    p0 = fixed_corotated_stress(s[0], s[1], s[2], J, mu, lam)
    p1 = fixed_corotated_stress(s[1], s[0], s[2], J, mu, lam)
    p2 = fixed_corotated_stress(s[2], s[0], s[1], J, mu, lam)
    for a in range(3):
        for b in range(3):
            P[a, b] = p0 * U[a, 0] * V[b, 0] + p1 * U[a, 1] * V[b, 1] + p2 * U[a, 2] * V[b, 2]
    return True


@njit(cache=True, inline="always")
def sigma_hessian(s, mu, lam, model, A, twist, flip):
    """A = ∂²Ψ/∂σ² (3×3), and per pair k = (i, j) in (0,1), (0,2), (1,2):
    twist[k] = (ψᵢ + ψⱼ)/(σᵢ + σⱼ), flip[k] = (ψᵢ − ψⱼ)/(σᵢ − σⱼ), in cancelled form."""
    J = s[0] * s[1] * s[2]
    if model == NEO_HOOKEAN:
        lnJ = np.log(J)
        m = mu - lam * lnJ
        for i in range(3):
            # ∂²Ψ/∂σᵢ² = μ + (μ − λ ln J + λ)/σᵢ²
            A[i, i] = mu + (m + lam) / (s[i] * s[i])
        for k in range(3):
            i, j, _l = _pair(k)
            # ∂²Ψ/∂σᵢ∂σⱼ = λ/(σᵢσⱼ)
            A[i, j] = lam / (s[i] * s[j])
            A[j, i] = A[i, j]
            # (ψᵢ ± ψⱼ)/(σᵢ ± σⱼ) = μ ∓ (μ − λ ln J)/(σᵢσⱼ)
            twist[k] = mu - m / (s[i] * s[j])
            flip[k] = mu + m / (s[i] * s[j])
        return
    for k in range(3):
        i, j, l = _pair(k)  # l: the index the pair (i, j) leaves out
        # ∂²Ψ/∂σₗ² = 2μ + λ (σᵢσⱼ)²
        A[l, l] = 2.0 * mu + lam * (s[i] * s[j]) ** 2
        # ∂²Ψ/∂σᵢ∂σⱼ = λ σₗ (2J − 1)
        A[i, j] = lam * s[l] * (2.0 * J - 1.0)
        A[j, i] = A[i, j]
        # (ψᵢ + ψⱼ)/(σᵢ + σⱼ) = 2μ − 4μ/(σᵢ + σⱼ) + λ (J − 1) σₗ
        twist[k] = 2.0 * mu - 4.0 * mu / max(s[i] + s[j], _MIN_PAIR_SUM) + lam * (J - 1.0) * s[l]
        # (ψᵢ − ψⱼ)/(σᵢ − σⱼ) = 2μ − λ (J − 1) σₗ
        flip[k] = 2.0 * mu - lam * (J - 1.0) * s[l]


@njit(cache=True, inline="always")
def _is_spd3(A):
    # Sylvester's criterion: every leading principal minor > 0
    if A[0, 0] <= 0.0:
        return False
    if A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0] <= 0.0:
        return False
    return det3(A) > 0.0


@njit(cache=True, inline="always")
def mode_vector(G, g, d):
    # g = (∂F/∂x)ᵀ vec(Q) with G = Q Dm⁻ᵀ (d x d, d = 3, or 2 for a triangle): vertex c+1
    # gets column c of G, vertex 0 minus their sum (F = Σ_c (x_{c+1} − x₀) ⊗ row c of
    # Dm⁻¹); a triangle's z entries 0. d is a literal at each call: loops of known length
    for a in range(d):
        total = G[a, 0]
        for c in range(1, d):
            total += G[a, c]
        g[a] = -total
        for c in range(d):
            g[3 * (c + 1) + a] = G[a, c]
    for a in range(d, 3):
        for v in range(d + 1):
            g[3 * v + a] = 0.0


@njit(cache=True, inline="always")
def add_mode(H, k, g, n):
    # H += k g gᵀ (upper triangle), n = 3 (d + 1) entries
    for r in range(n):
        kr = k * g[r]
        for c in range(r, n):
            H[r, c] += kr * g[c]


@njit(cache=True, inline="always")
def add_twist_flip(H, U, Wd, i, j, twist, flip, measure, project_psd, G, g, d):
    # the twist and flip modes of singular pair (i, j), Q = (uᵢvⱼᵀ ∓ uⱼvᵢᵀ)/√2 with
    # eigenvalues twist and flip (skipped where ≤ 0 when projecting); Wd[:, j] = Dm⁻¹ vⱼ
    for mode in range(2):
        lam_k = twist if mode == 0 else flip
        if project_psd and lam_k <= 0.0:
            continue
        sg = -_INV_SQRT2 if mode == 0 else _INV_SQRT2
        for a in range(d):
            for c in range(d):
                G[a, c] = _INV_SQRT2 * U[a, i] * Wd[c, j] + sg * U[a, j] * Wd[c, i]
        mode_vector(G, g, d)
        add_mode(H, measure * lam_k, g, 3 * (d + 1))


@njit(cache=True, inline="always")
def element_gradient(P, Dm_inv_e, measure, G, g, d):
    # g = measure (∂F/∂x)ᵀ vec P: G = measure P Dm⁻ᵀ, (P Dm⁻ᵀ)[a, c] = Σ_b P[a, b] Dm⁻¹[c, b]
    for a in range(d):
        for c in range(d):
            total = P[a, 0] * Dm_inv_e[c, 0]
            for b in range(1, d):
                total += P[a, b] * Dm_inv_e[c, b]
            G[a, c] = measure * total
    mode_vector(G, g, d)


@njit(cache=True)
def _tet_hessian(F, Dm_inv_e, vol, mu, lam, model, project_psd, H, S):
    """12×12 element Hessian V_rest (∂F/∂x)ᵀ ∂²Ψ/∂F² (∂F/∂x) into H, from the eigensystem
    in the module docstring, every eigenvalue clamped at 0 when project_psd.
    S: scratch (16, 3, 3). NaN for NH with J ≤ 0."""
    U = S[0]
    V = S[1]
    B = S[2]
    A = S[3]
    Wq = S[4]
    M = S[5]
    Wd = S[6]
    G = S[7]
    s = S[8, 0]
    twist = S[8, 1]
    flip = S[8, 2]
    w = S[9, 0]
    g = S[10:12].reshape(-1)[:12]
    gs = S[12:16].reshape(-1)[:36].reshape(3, 12)
    for r in range(12):
        for c in range(12):
            H[r, c] = 0.0
    _svd3(F, U, s, V, B)
    if model == NEO_HOOKEAN and (s[0] <= 0.0 or s[1] <= 0.0 or s[2] <= 0.0):
        for r in range(12):
            for c in range(12):
                H[r, c] = np.nan
        return
    sigma_hessian(s, mu, lam, model, A, twist, flip)
    # Wd[:, j] = Dm⁻¹ vⱼ so that uᵢvⱼᵀ Dm⁻ᵀ = uᵢ (Dm⁻¹vⱼ)ᵀ
    for a in range(3):
        for j in range(3):
            Wd[a, j] = Dm_inv_e[a, 0] * V[0, j] + Dm_inv_e[a, 1] * V[1, j] + Dm_inv_e[a, 2] * V[2, j]
    if project_psd and not _is_spd3(A):
        # scaling modes Q = Σᵢ Wq[i,k] uᵢvᵢᵀ, A = Wq diag(w) Wqᵀ, w clamped at 0
        _sym3_eig(A, w, Wq, M)
        for k in range(3):
            if w[k] <= 0.0:
                continue
            for a in range(3):
                for c in range(3):
                    G[a, c] = (
                        Wq[0, k] * U[a, 0] * Wd[c, 0] + Wq[1, k] * U[a, 1] * Wd[c, 1] + Wq[2, k] * U[a, 2] * Wd[c, 2]
                    )
            mode_vector(G, g, 3)
            add_mode(H, vol * w[k], g, 12)
    else:
        # A is already SPD (or no projection asked): Σᵢⱼ Aᵢⱼ gᵢgⱼᵀ with gᵢ the vector of uᵢvᵢᵀ
        for i in range(3):
            for a in range(3):
                for c in range(3):
                    G[a, c] = U[a, i] * Wd[c, i]
            mode_vector(G, gs[i], 3)
        for r in range(12):
            t0 = vol * (A[0, 0] * gs[0, r] + A[1, 0] * gs[1, r] + A[2, 0] * gs[2, r])
            t1 = vol * (A[0, 1] * gs[0, r] + A[1, 1] * gs[1, r] + A[2, 1] * gs[2, r])
            t2 = vol * (A[0, 2] * gs[0, r] + A[1, 2] * gs[1, r] + A[2, 2] * gs[2, r])
            for c in range(r, 12):
                H[r, c] += t0 * gs[0, c] + t1 * gs[1, c] + t2 * gs[2, c]
    for k in range(3):
        i, j, _l = _pair(k)
        add_twist_flip(H, U, Wd, i, j, twist[k], flip[k], vol, project_psd, G, g, 3)
    symmetrize_from_upper(H)


# --------------------------------------------------------------------------------------
# batched kernels over all tets
# --------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _chunk_scratch():
    # a chunk's scratch, allocated once per chunk and not per tet: Ds, F, U, V, B, P
    # (3 x 3) and s (3,)
    S = np.empty((7, 3, 3))
    return S[0], S[1], S[2], S[3], S[4], S[5], S[6, 0]


@kernel(parallel=True)
def elastic_energy_per_tet(x, tets, Dm_inv, volumes, lame, model):
    """E_e = V_rest Ψ(F_e) for every tet, (m,); +∞ for an NH tet with J ≤ 0."""
    m = tets.shape[0]
    out = np.empty(m)
    n_chunks = (m + _CHUNK - 1) // _CHUNK
    for ch in prange(n_chunks):
        Ds, F, U, V, B, _, s = _chunk_scratch()
        for e in range(ch * _CHUNK, min(m, (ch + 1) * _CHUNK)):
            _deformation_gradient(x, tets, Dm_inv, e, Ds, F)
            out[e] = volumes[e] * _psi_from_F(F, lame[e, 0], lame[e, 1], model, U, s, V, B)
    return out


@kernel()
def elastic_energy(x, tets, Dm_inv, volumes, lame, model):
    """Σₑ V_rest Ψ(Fₑ), summed serially in tet order (deterministic)."""
    return ordered_sum(elastic_energy_per_tet(x, tets, Dm_inv, volumes, lame, model))


@kernel(parallel=True)
def elastic_local_gradients(x, tets, Dm_inv, volumes, lame, model):
    """Per-tet gradients (m, 12), local DOF 3·v + a: ∂E/∂x_{c+1} = V_rest (P Dm⁻ᵀ)[:, c],
    ∂E/∂x₀ = −Σ_c of those."""
    m = tets.shape[0]
    out = np.empty((m, 12))
    n_chunks = (m + _CHUNK - 1) // _CHUNK
    for ch in prange(n_chunks):
        Ds, F, U, V, B, P, s = _chunk_scratch()
        for e in range(ch * _CHUNK, min(m, (ch + 1) * _CHUNK)):
            _deformation_gradient(x, tets, Dm_inv, e, Ds, F)
            if not _first_piola(F, lame[e, 0], lame[e, 1], model, P, U, s, V, B):
                for k in range(12):
                    out[e, k] = np.nan
                continue
            element_gradient(P, Dm_inv[e], volumes[e], Ds, out[e], 3)  # Ds: free scratch now
    return out


@kernel()
def elastic_gradient(x, tets, Dm_inv, volumes, lame, model):
    """∂E/∂x as a flat (3n,) vector, DOF 3i + a: per-tet gradients in parallel, then the
    shared serial scatter (``scatter.scatter_local_gradients``)."""
    local = elastic_local_gradients(x, tets, Dm_inv, volumes, lame, model)
    return scatter_local_gradients(local, tets, x.shape[0])


@kernel(parallel=True)
def tet_hessian_pattern(tets):
    """Rows and cols (int32, 144 m) of the element Hessians: entry 144e + 12r + c is
    (global DOF of local r, global DOF of local c), local DOF r = 3·v + a. int32 halves the
    largest arrays a run keeps (29 M entries each for 200 K tets); DOFs stay below 2³¹."""
    m = tets.shape[0]
    rows = np.empty(144 * m, dtype=np.int32)
    cols = np.empty(144 * m, dtype=np.int32)
    for e in prange(m):
        base = 144 * e
        for r in range(12):
            gr = local_dof(tets, e, r)
            for c in range(12):
                rows[base + 12 * r + c] = gr
                cols[base + 12 * r + c] = local_dof(tets, e, c)
    return rows, cols


@kernel(parallel=True)
def elastic_hessian_values(x, tets, Dm_inv, volumes, lame, model, project_psd):
    """Values (144 m,) of the element Hessians, in the order of ``tet_hessian_pattern``;
    each 12×12 block projected to PSD when project_psd."""
    m = tets.shape[0]
    vals = np.empty(144 * m)
    n_chunks = (m + _CHUNK - 1) // _CHUNK
    for ch in prange(n_chunks):
        S = np.empty((16, 3, 3))
        T = np.empty((2, 3, 3))
        H = np.empty((12, 12))
        Ds = T[0]
        F = T[1]
        for e in range(ch * _CHUNK, min(m, (ch + 1) * _CHUNK)):
            _deformation_gradient(x, tets, Dm_inv, e, Ds, F)
            _tet_hessian(F, Dm_inv[e], volumes[e], lame[e, 0], lame[e, 1], model, project_psd, H, S)
            base = 144 * e
            for r in range(12):
                for c in range(12):
                    vals[base + 12 * r + c] = H[r, c]
    return vals


@kernel()
def elastic_hessian(x, tets, Dm_inv, volumes, lame, model, project_psd):
    """COO triplets (rows, cols, vals) of ∂²E/∂x², 144 per tet at offset 144e."""
    rows, cols = tet_hessian_pattern(tets)
    vals = elastic_hessian_values(x, tets, Dm_inv, volumes, lame, model, project_psd)
    return rows, cols, vals


# --------------------------------------------------------------------------------------
# single-F entry points (tests, diagnostics); these allocate
# --------------------------------------------------------------------------------------


@njit(cache=True)
def svd_rv(F):
    """Rotation-variant SVD of one 3×3 F: (U, s, V) with F = U diag(s) Vᵀ, det U = det V = 1."""
    U = np.empty((3, 3))
    V = np.empty((3, 3))
    B = np.empty((3, 3))
    s = np.empty(3)
    _svd3(np.ascontiguousarray(F), U, s, V, B)
    return U, s, V


@njit(cache=True)
def energy_density(F, mu, lam, model):
    """Ψ(F)."""
    S = np.empty((4, 3, 3))
    return _psi_from_F(np.ascontiguousarray(F), mu, lam, model, S[0], S[1, 0], S[2], S[3])


@njit(cache=True)
def first_piola(F, mu, lam, model):
    """P = ∂Ψ/∂F (NaN for NH with J ≤ 0)."""
    S = np.empty((4, 3, 3))
    P = np.empty((3, 3))
    if not _first_piola(np.ascontiguousarray(F), mu, lam, model, P, S[0], S[1, 0], S[2], S[3]):
        P[:] = np.nan
    return P


@njit(cache=True)
def dpsi_dF2(F, mu, lam, model, project_psd):
    """∂²Ψ/∂F² as a 9×9 matrix on vec(F)[3a + b] = F[a, b], through the element path itself:
    with Dm⁻¹ = I and V_rest = 1, F = Ds and local DOF 3(b+1) + a of the 12×12 Hessian is
    F[a, b]."""
    S = np.empty((16, 3, 3))
    H = np.empty((12, 12))
    _tet_hessian(np.ascontiguousarray(F), np.eye(3), 1.0, mu, lam, model, project_psd, H, S)
    H9 = np.empty((9, 9))
    for a in range(3):
        for b in range(3):
            for c in range(3):
                for d in range(3):
                    H9[3 * a + b, 3 * c + d] = H[3 * (b + 1) + a, 3 * (d + 1) + c]
    return H9


@njit(cache=True)
def sigma_derivatives(F, mu, lam, model):
    """(σ, ∂²Ψ/∂σ², twist, flip) of one F: the rotation-variant singular values, the 3×3
    scaling block and the twist/flip eigenvalues for the pairs (0,1), (0,2), (1,2)."""
    S = np.empty((4, 3, 3))
    s = np.empty(3)
    A = np.empty((3, 3))
    twist = np.empty(3)
    flip = np.empty(3)
    _svd3(np.ascontiguousarray(F), S[0], s, S[1], S[2])
    sigma_hessian(s, mu, lam, model, A, twist, flip)
    return s, A, twist, flip


# --------------------------------------------------------------------------------------
# inversion-free step bound (the NH term's own line-search filter)
# --------------------------------------------------------------------------------------


@njit(cache=True)
def _cubic(a, b, c, d, t):
    # a t³ + b t² + c t + d by Horner
    return ((a * t + b) * t + c) * t + d


@njit(cache=True)
def first_nonpositive(a, b, c, d):
    """Largest α ∈ [0, 1] with f(t) = a t³ + b t² + c t + d > 0 on [0, α) (f(0) = d > 0
    assumed): 1 when f stays positive on [0, 1], else the first zero, from below.

    [0, 1] is split at the real roots of f' = 3a t² + 2b t + c (any of a, b, c may be 0)
    into intervals where f is monotone; f is positive on an interval iff it is at both
    ends, and the first interval whose right end has f ≤ 0 is bisected to full precision,
    returning the left bracket (f > 0 there)."""
    brk = np.empty(4)
    nb = 0
    # critical points in (0, 1), stable quadratic formula
    qa = 3.0 * a
    qb = 2.0 * b
    qc = c
    r1 = -1.0
    r2 = -1.0
    if qa == 0.0:
        if qb != 0.0:
            r1 = -qc / qb
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            qq = -0.5 * (qb + (np.sqrt(disc) if qb >= 0.0 else -np.sqrt(disc)))
            if qq != 0.0:
                r1 = qq / qa
                r2 = qc / qq
            else:  # qb = qc = 0: double critical point at 0
                r1 = 0.0
    if r2 < r1:
        r1, r2 = r2, r1
    if 0.0 < r1 < 1.0:
        brk[nb] = r1
        nb += 1
    if 0.0 < r2 < 1.0 and r2 != r1:
        brk[nb] = r2
        nb += 1
    brk[nb] = 1.0
    nb += 1
    lo = 0.0
    for k in range(nb):
        hi = brk[k]
        if _cubic(a, b, c, d, hi) > 0.0:
            lo = hi
            continue
        # f(lo) > 0 ≥ f(hi), f monotone on [lo, hi]: bisect
        for _it in range(200):
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            if _cubic(a, b, c, d, mid) > 0.0:
                lo = mid
            else:
                hi = mid
        return lo
    return 1.0


@kernel(parallel=True)
def max_step_per_tet(x, p, tets, min_volume_ratio):
    """Per-tet bound (m,): largest α ∈ [0, 1] with det Ds(x + t p) > r det Ds(x) on [0, α)
    (r = min_volume_ratio ∈ [0, 1)); 0 for a tet that is already inverted or flat."""
    m = tets.shape[0]
    out = np.empty(m)
    n_chunks = (m + _CHUNK - 1) // _CHUNK
    for ch in prange(n_chunks):
        S = np.empty((4, 3, 3))
        Ds = S[0]
        Dp = S[1]
        C = S[2]
        for e in range(ch * _CHUNK, min(m, (ch + 1) * _CHUNK)):
            edge_matrix(x, tets, e, Ds)
            edge_matrix(p, tets, e, Dp)
            # det(Ds + t Dp) = det Dp t³ + ⟨cof Dp, Ds⟩ t² + ⟨cof Ds, Dp⟩ t + det Ds
            d0 = det3(Ds)
            if d0 <= 0.0:
                out[e] = 0.0
                continue
            a = det3(Dp)
            cofactor3(Dp, C)
            b = 0.0
            for i in range(3):
                for j in range(3):
                    b += C[i, j] * Ds[i, j]
            cofactor3(Ds, C)
            c = 0.0
            for i in range(3):
                for j in range(3):
                    c += C[i, j] * Dp[i, j]
            # f(t) = det(Ds + t Dp) − r det Ds, f(0) = (1 − r) det Ds > 0
            out[e] = first_nonpositive(a, b, c, (1.0 - min_volume_ratio) * d0)
    return out


@kernel()
def max_step_no_inversion(x, p, tets, min_volume_ratio):
    """Largest α ∈ [0, 1] such that every tet keeps det Ds(x + t p) > r · det Ds(x) for all
    t ∈ [0, α) (r = min_volume_ratio; the original IPC uses r = 0.1, i.e. no tet loses more
    than 90 % of its current volume within one line search). With r > 0 the returned step
    stays strictly away from zero volume regardless of round-off in the cubic."""
    per = max_step_per_tet(x, p, tets, min_volume_ratio)
    alpha = 1.0
    for e in range(per.shape[0]):
        alpha = min(alpha, per[e])
    return alpha
