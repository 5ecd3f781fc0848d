"""Hyperelastic energies of linear triangles in plane strain (2D scenes, the plane z = 0),
their gradients and PSD-projected Hessians, and the inversion-free step bound.

Per triangle e with vertices (x0, x1, x2) (their x, y parts):

    Ds = [x1 − x0, x2 − x0]   (2 x 2, columns),  Dm likewise at rest
    F  = Ds Dm⁻¹,  J = det F,  F = U Σ Vᵀ   (rotation-variant: det U = det V = +1,
                                            σ0 ≥ |σ1|, σ1 < 0 for an inverted triangle)
    E_e = A_rest · Ψ(F₃),   F₃ = diag(F, 1)  (plane strain: no stretch across the plane)

with the densities of ``tets.py``, evaluated at F₃ (its third singular value is 1):

    0  neo-Hookean     Ψ = μ/2 (tr FᵀF + 1 − 3) − μ ln J + λ/2 (ln J)²,   +∞ for J ≤ 0
    1  fixed corotated Ψ = μ Σᵢ₌₀,₁ (σᵢ − 1)² + λ/2 (J − 1)²

so ψᵢ = ∂Ψ/∂σᵢ, ∂²Ψ/∂σ² and the twist and flip eigenvalues of the pair (0, 1) are the 3D
ones at σ = (σ0, σ1, 1) (``tets.sigma_hessian``). The rotations U, V are those of the
plane: an inverted triangle's reflection stays in the plane (σ1 < 0), where the 3D SVD of
diag(F, 1) would put it on its smallest singular value, the 1 along z when |σ1| > 1 (so
the fixed corotated energy of such a triangle is not the 3D one of diag(F, 1)).
∂²Ψ/∂F² (4 x 4) has the eigenmatrices

    scaling  Σᵢ wᵢₖ uᵢvᵢᵀ         eigenvalues of the 2 x 2 block ∂²Ψ/∂σ², w its vectors
    twist    (u0v1ᵀ − u1v0ᵀ)/√2   λ = (ψ0 + ψ1)/(σ0 + σ1)
    flip     (u0v1ᵀ + u1v0ᵀ)/√2   λ = (ψ0 − ψ1)/(σ0 − σ1)

(Smith, de Goes, Kim 2019), each clamped at 0 for the projection; the element Hessian
is A_rest Σₖ λₖ gₖgₖᵀ with gₖ = (∂F/∂x)ᵀ vec(Qₖ). The lecture's NeoHookeanEnergy (its
lesson 6) projects the same eigenvalues.

The 2 x 2 rotation-variant SVD is in closed form: with E = (F00 + F11)/2, D = (F00 − F11)/2,
G = (F10 + F01)/2, H = (F10 − F01)/2, F = Q rot(a2) + R refl(a1) where Q = |(E, H)|,
R = |(D, G)|, a2 = atan2(H, E), a1 = atan2(G, D); so σ0 = Q + R, σ1 = Q − R,
U = rot((a1 + a2)/2), V = rot((a1 − a2)/2).

Layout: x (n, 3), triangles (m, 3) int64, Dm_inv (m, 2, 2), areas (m,), lame (m, 2) =
(μ, λ), model as in ``tets.py``. Gradients are flat (3n,) with DOF 3i + a, their z parts 0.
Hessians are COO triplets, 81 per triangle at offset 81·e, row-major over the local DOFs
3·v + a (v = 0..2 the triangle's vertices, a = 0..2): the same per-vertex layout as the
tets' and the contact stencils', with the z rows and columns exactly 0 (nothing acts
along z). The NH gradient and Hessian are NaN for a triangle with J ≤ 0 (its energy is
+∞; ``max_step_no_inversion`` keeps the solver away from there).

Step bound: ``max_step_no_inversion(x, p, triangles, r)``, the largest α ∈ [0, 1] with
det Ds(x + t p) > r · det Ds(x) on [0, α) for every triangle, det Ds(x + t p) being a
quadratic in t (``tets.first_nonpositive`` finds its first crossing).
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.algebra.linalg import edge_matrix, ordered_sum, symmetrize_from_upper
from ipcsim.kernels.algebra.scatter import scatter_local_gradients
from ipcsim.kernels.elasticity.tets import (
    NEO_HOOKEAN,
    add_mode,
    add_twist_flip,
    element_gradient,
    first_nonpositive,
    fixed_corotated_density,
    fixed_corotated_stress,
    mode_vector,
    neo_hookean_cofactor_factor,
    neo_hookean_density,
    sigma_hessian,
)
from ipcsim.compiler.twin import kernel

_CHUNK = 256  # triangles per parallel work item; scratch allocated once per chunk


# --------------------------------------------------------------------------------------
# one triangle (scratch arrays from the caller: no allocation per element)
# --------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _deformation_gradient(x, triangles, Dm_inv, e, Ds, F):
    # F = Ds Dm⁻¹
    edge_matrix(x, triangles, e, Ds)
    for a in range(2):
        for b in range(2):
            F[a, b] = Ds[a, 0] * Dm_inv[e, 0, b] + Ds[a, 1] * Dm_inv[e, 1, b]


@njit(cache=True, inline="always")
def _det2(F):
    return F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]


@njit(cache=True)
def _svd2(F, U, s, V):
    """Rotation-variant SVD F = U diag(s) Vᵀ of a 2 x 2 F (module docstring)."""
    E = 0.5 * (F[0, 0] + F[1, 1])
    D = 0.5 * (F[0, 0] - F[1, 1])
    G = 0.5 * (F[1, 0] + F[0, 1])
    H = 0.5 * (F[1, 0] - F[0, 1])
    Q = np.sqrt(E * E + H * H)
    R = np.sqrt(D * D + G * G)
    s[0] = Q + R
    s[1] = Q - R
    a1 = np.arctan2(G, D)
    a2 = np.arctan2(H, E)
    phi = 0.5 * (a1 + a2)
    theta = 0.5 * (a1 - a2)
    U[0, 0] = np.cos(phi)
    U[1, 0] = np.sin(phi)
    U[0, 1] = -U[1, 0]
    U[1, 1] = U[0, 0]
    V[0, 0] = np.cos(theta)
    V[1, 0] = np.sin(theta)
    V[0, 1] = -V[1, 0]
    V[1, 1] = V[0, 0]


@njit(cache=True, inline="always")
def _psi(F, mu, lam, model, U, s, V):
    # Ψ(diag(F, 1)): NH from tr FᵀF + 1 and J; FCR from (σ0, σ1, 1)
    J = _det2(F)
    if model == NEO_HOOKEAN:
        trc = F[0, 0] ** 2 + F[0, 1] ** 2 + F[1, 0] ** 2 + F[1, 1] ** 2 + 1.0
        return neo_hookean_density(trc, J, mu, lam)
    _svd2(F, U, s, V)
    return fixed_corotated_density(s[0], s[1], 1.0, J, mu, lam)


@njit(cache=True, inline="always")
def _first_piola(F, mu, lam, model, P, U, s, V):
    """P = ∂Ψ/∂F (2 x 2). False (P undefined) for NH with J ≤ 0."""
    J = _det2(F)
    if model == NEO_HOOKEAN:
        if J <= 0.0:
            return False
        # P = μ F + k cof F,  cof F = [[F11, −F10], [−F01, F00]]
        k = neo_hookean_cofactor_factor(J, mu, lam)
        P[0, 0] = mu * F[0, 0] + k * F[1, 1]
        P[0, 1] = mu * F[0, 1] - k * F[1, 0]
        P[1, 0] = mu * F[1, 0] - k * F[0, 1]
        P[1, 1] = mu * F[1, 1] + k * F[0, 0]
        return True
    # P = U diag(ψ0, ψ1) Vᵀ,  ψᵢ = 2μ(σᵢ − 1) + λ (J − 1) σⱼ · 1
    _svd2(F, U, s, V)
    J = s[0] * s[1]
    p0 = fixed_corotated_stress(s[0], s[1], 1.0, J, mu, lam)
    p1 = fixed_corotated_stress(s[1], s[0], 1.0, J, mu, lam)
    for a in range(2):
        for b in range(2):
            P[a, b] = p0 * U[a, 0] * V[b, 0] + p1 * U[a, 1] * V[b, 1]
    return True


@njit(cache=True, inline="always")
def _sym2_eig(A, w, W):
    # A (2 x 2 symmetric) = W diag(w) Wᵀ, by the rotation that zeroes A01
    theta = 0.5 * np.arctan2(2.0 * A[0, 1], A[0, 0] - A[1, 1])
    c = np.cos(theta)
    sn = np.sin(theta)
    W[0, 0], W[1, 0], W[0, 1], W[1, 1] = c, sn, -sn, c
    w[0] = c * c * A[0, 0] + 2.0 * c * sn * A[0, 1] + sn * sn * A[1, 1]
    w[1] = sn * sn * A[0, 0] - 2.0 * c * sn * A[0, 1] + c * c * A[1, 1]


@njit(cache=True)
def _scaling_modes(A, U, Wd, area, project_psd, H, S):
    """Adds the scaling part Σᵢⱼ Aᵢⱼ gᵢgⱼᵀ (gᵢ the vector of uᵢvᵢᵀ), or with the
    projection, where A (2 x 2 of ∂²Ψ/∂σ²) is not positive definite, its eigenvectors'
    modes with the eigenvalues clamped at 0. Uses rows 0-4 of the scratch S."""
    G = S[0, :4].reshape(2, 2)
    if project_psd and not (A[0, 0] > 0.0 and A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0] > 0.0):
        w = S[1, :2]
        W = S[1, 2:6].reshape(2, 2)
        g = S[2]
        _sym2_eig(A, w, W)
        for k in range(2):
            if w[k] <= 0.0:
                continue
            for a in range(2):
                for c in range(2):
                    G[a, c] = W[0, k] * U[a, 0] * Wd[c, 0] + W[1, k] * U[a, 1] * Wd[c, 1]
            mode_vector(G, g, 2)
            add_mode(H, area * w[k], g, 9)
        return
    for i in range(2):
        for a in range(2):
            for c in range(2):
                G[a, c] = U[a, i] * Wd[c, i]
        mode_vector(G, S[3 + i], 2)
    for r in range(9):
        t0 = area * (A[0, 0] * S[3, r] + A[1, 0] * S[4, r])
        t1 = area * (A[0, 1] * S[3, r] + A[1, 1] * S[4, r])
        for c in range(r, 9):
            H[r, c] += t0 * S[3, c] + t1 * S[4, c]


@njit(cache=True)
def _triangle_hessian(F, Dm_inv_e, area, mu, lam, model, project_psd, H, S):
    """9 x 9 element Hessian A_rest (∂F/∂x)ᵀ ∂²Ψ/∂F² (∂F/∂x) into H (module docstring),
    every eigenvalue clamped at 0 when project_psd. S: scratch (9, 9) (rows 0-4 the modes',
    5-8 the SVD's and the σ-derivatives'). NaN for NH with J ≤ 0."""
    for r in range(9):
        for c in range(9):
            H[r, c] = 0.0
    U, V = S[5, :4].reshape(2, 2), S[5, 4:8].reshape(2, 2)
    A, Wd = S[6].reshape(3, 3), S[8, :4].reshape(2, 2)
    s, twist, flip = S[7, :3], S[7, 3:6], S[7, 6:9]
    s[2] = 1.0  # (σ0, σ1, 1): plane strain
    _svd2(F, U, s, V)
    if model == NEO_HOOKEAN and (s[0] <= 0.0 or s[1] <= 0.0):
        H[:, :] = np.nan
        return
    sigma_hessian(s, mu, lam, model, A, twist, flip)
    # Wd[:, j] = Dm⁻¹ vⱼ so that uᵢvⱼᵀ Dm⁻ᵀ = uᵢ (Dm⁻¹vⱼ)ᵀ
    for a in range(2):
        for j in range(2):
            Wd[a, j] = Dm_inv_e[a, 0] * V[0, j] + Dm_inv_e[a, 1] * V[1, j]
    _scaling_modes(A[:2, :2], U, Wd, area, project_psd, H, S)
    G = S[0, :4].reshape(2, 2)
    g = S[2]
    # the one singular pair (0, 1) is k = 0 of sigma_hessian's twist and flip
    add_twist_flip(H, U, Wd, 0, 1, twist[0], flip[0], area, project_psd, G, g, 2)
    symmetrize_from_upper(H)


# --------------------------------------------------------------------------------------
# batched kernels over all triangles
# --------------------------------------------------------------------------------------


@kernel(parallel=True)
def triangle_energy_per_element(x, triangles, Dm_inv, areas, lame, model):
    """E_e = A_rest Ψ(F_e) for every triangle, (m,); +∞ for an NH triangle with J ≤ 0."""
    m = triangles.shape[0]
    out = np.empty(m)
    for ch in prange((m + _CHUNK - 1) // _CHUNK):
        S = np.empty((5, 2, 2))
        s = np.empty(2)
        for e in range(ch * _CHUNK, min(m, (ch + 1) * _CHUNK)):
            _deformation_gradient(x, triangles, Dm_inv, e, S[0], S[1])
            out[e] = areas[e] * _psi(S[1], lame[e, 0], lame[e, 1], model, S[2], s, S[3])
    return out


@kernel()
def triangle_energy(x, triangles, Dm_inv, areas, lame, model):
    """Σₑ A_rest Ψ(Fₑ), summed serially in triangle order (deterministic)."""
    return ordered_sum(triangle_energy_per_element(x, triangles, Dm_inv, areas, lame, model))


@kernel(parallel=True)
def triangle_local_gradients(x, triangles, Dm_inv, areas, lame, model):
    """Per-triangle gradients (m, 9), local DOF 3·v + a: ∂E/∂x_{c+1} = A_rest (P Dm⁻ᵀ)[:, c],
    ∂E/∂x₀ = −Σ_c of those; z entries 0."""
    m = triangles.shape[0]
    out = np.zeros((m, 9))
    for ch in prange((m + _CHUNK - 1) // _CHUNK):
        S = np.empty((5, 2, 2))
        s = np.empty(2)
        for e in range(ch * _CHUNK, min(m, (ch + 1) * _CHUNK)):
            _deformation_gradient(x, triangles, Dm_inv, e, S[0], S[1])
            P = S[4]
            if not _first_piola(S[1], lame[e, 0], lame[e, 1], model, P, S[2], s, S[3]):
                out[e, :] = np.nan
                continue
            element_gradient(P, Dm_inv[e], areas[e], S[0], out[e], 2)  # S[0]: free scratch now
    return out


@kernel()
def triangle_gradient(x, triangles, Dm_inv, areas, lame, model):
    """∂E/∂x as a flat (3n,) vector: per-triangle gradients in parallel, then the shared
    serial scatter (``scatter.scatter_local_gradients``)."""
    local = triangle_local_gradients(x, triangles, Dm_inv, areas, lame, model)
    return scatter_local_gradients(local, triangles, x.shape[0])


@kernel(parallel=True)
def triangle_hessian_values(x, triangles, Dm_inv, areas, lame, model, project_psd):
    """Values (81 m,) of the element Hessians, block e at [81 e, 81 (e + 1)), row-major over
    the local DOFs (``assembly.block_triplet_indices(triangles)`` gives their rows and
    columns); each 9 x 9 block projected to PSD when project_psd."""
    m = triangles.shape[0]
    vals = np.empty(81 * m)
    for ch in prange((m + _CHUNK - 1) // _CHUNK):
        T = np.empty((2, 2, 2))
        S = np.empty((9, 9))
        H = np.empty((9, 9))
        for e in range(ch * _CHUNK, min(m, (ch + 1) * _CHUNK)):
            _deformation_gradient(x, triangles, Dm_inv, e, T[0], T[1])
            _triangle_hessian(T[1], Dm_inv[e], areas[e], lame[e, 0], lame[e, 1], model,
                              project_psd, H, S)
            for r in range(9):
                for c in range(9):
                    vals[81 * e + 9 * r + c] = H[r, c]
    return vals


# --------------------------------------------------------------------------------------
# single-F entry points (tests, diagnostics); these allocate
# --------------------------------------------------------------------------------------


@njit(cache=True)
def svd2(F):
    """Rotation-variant SVD of one 2 x 2 F: (U, s, V), F = U diag(s) Vᵀ, det U = det V = 1."""
    U = np.empty((2, 2))
    V = np.empty((2, 2))
    s = np.empty(2)
    _svd2(np.ascontiguousarray(F), U, s, V)
    return U, s, V


@njit(cache=True)
def energy_density_2d(F, mu, lam, model):
    """Ψ(diag(F, 1)) of one 2 x 2 F."""
    S = np.empty((2, 2, 2))
    return _psi(np.ascontiguousarray(F), mu, lam, model, S[0], np.empty(2), S[1])


@njit(cache=True)
def first_piola_2d(F, mu, lam, model):
    """P = ∂Ψ/∂F (2 x 2; NaN for NH with J ≤ 0)."""
    S = np.empty((2, 2, 2))
    P = np.empty((2, 2))
    if not _first_piola(np.ascontiguousarray(F), mu, lam, model, P, S[0], np.empty(2), S[1]):
        P[:] = np.nan
    return P


@njit(cache=True)
def dpsi_dF2_2d(F, mu, lam, model, project_psd):
    """∂²Ψ/∂F² as a 4 x 4 matrix on vec(F)[2a + b] = F[a, b], through the element path:
    with Dm⁻¹ = I and A_rest = 1, local DOF 3(b + 1) + a of the 9 x 9 Hessian is F[a, b]."""
    H = np.empty((9, 9))
    _triangle_hessian(np.ascontiguousarray(F), np.eye(2), 1.0, mu, lam, model, project_psd,
                      H, np.empty((9, 9)))
    H4 = np.empty((4, 4))
    for a in range(2):
        for b in range(2):
            for c in range(2):
                for d in range(2):
                    H4[2 * a + b, 2 * c + d] = H[3 * (b + 1) + a, 3 * (d + 1) + c]
    return H4


# --------------------------------------------------------------------------------------
# inversion-free step bound
# --------------------------------------------------------------------------------------


@kernel(parallel=True)
def max_step_per_triangle(x, p, triangles, min_area_ratio):
    """Per-triangle bound (m,): largest α ∈ [0, 1] with det Ds(x + t p) > r det Ds(x) on
    [0, α) (r = min_area_ratio ∈ [0, 1)); 0 for a triangle already inverted or flat."""
    m = triangles.shape[0]
    out = np.empty(m)
    for ch in prange((m + _CHUNK - 1) // _CHUNK):
        S = np.empty((2, 2, 2))
        Ds = S[0]
        Dp = S[1]
        for e in range(ch * _CHUNK, min(m, (ch + 1) * _CHUNK)):
            edge_matrix(x, triangles, e, Ds)
            edge_matrix(p, triangles, e, Dp)
            d0 = _det2(Ds)
            if d0 <= 0.0:
                out[e] = 0.0
                continue
            # det(Ds + t Dp) = det Dp t² + ⟨cof Ds, Dp⟩ t + det Ds
            b = (Ds[0, 0] * Dp[1, 1] + Dp[0, 0] * Ds[1, 1]
                 - Ds[0, 1] * Dp[1, 0] - Dp[0, 1] * Ds[1, 0])
            out[e] = first_nonpositive(0.0, _det2(Dp), b, (1.0 - min_area_ratio) * d0)
    return out


@kernel()
def max_step_no_inversion_2d(x, p, triangles, min_area_ratio):
    """Largest α ∈ [0, 1] such that every triangle keeps det Ds(x + t p) > r · det Ds(x)
    for all t ∈ [0, α) (r = min_area_ratio; the lecture's filter uses r = 0.1)."""
    per = max_step_per_triangle(x, p, triangles, min_area_ratio)
    alpha = 1.0
    for e in range(per.shape[0]):
        alpha = min(alpha, per[e])
    return alpha
