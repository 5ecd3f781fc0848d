"""Elasticity kernels: SVD, energies, derivatives against finite differences, the analytic
PSD projection against a dense eigendecomposition, and the inversion-free step bound."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ipcsim.kernels.elasticity import tets as K

NH = K.NEO_HOOKEAN
FCR = K.FIXED_COROTATED


# --------------------------------------------------------------------------------------
# procedural meshes and deformations
# --------------------------------------------------------------------------------------


def box_mesh(nx, ny, nz, h=1.0):
    """Structured box of nx·ny·nz cubes, 6 tets each (Kuhn subdivision), positively oriented."""
    g = np.stack(np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij"), -1)
    X = h * g.reshape(-1, 3).astype(float)

    def vid(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k

    tets = []
    for i, j, k in itertools.product(range(nx), range(ny), range(nz)):
        for perm in itertools.permutations(range(3)):
            c = np.zeros(3, dtype=int)
            path = [vid(i, j, k)]
            for ax in perm:
                c[ax] += 1
                path.append(vid(i + c[0], j + c[1], k + c[2]))
            tets.append(path)
    tets = np.array(tets, dtype=np.int64)
    return X, orient(X, tets)


def orient(X, tets):
    D = edge_matrices(X, tets)
    neg = np.linalg.det(D) < 0
    tets = tets.copy()
    tets[neg, 1], tets[neg, 2] = tets[neg, 2].copy(), tets[neg, 1].copy()
    return tets


def edge_matrices(X, tets):
    return np.stack([X[tets[:, c + 1]] - X[tets[:, 0]] for c in range(3)], axis=-1)


def rest_data(X, tets):
    Dm = edge_matrices(X, tets)
    det = np.linalg.det(Dm)
    assert np.all(det > 0)
    return np.ascontiguousarray(np.linalg.inv(Dm)), det / 6.0


def random_rotation(rng):
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] = -Q[:, 0]
    return Q


def affine(rng, sigma):
    return random_rotation(rng) @ np.diag(sigma) @ random_rotation(rng)


class Mesh:
    """A jittered box mesh with per-tet Lamé parameters."""

    def __init__(self, rng, n=(2, 1, 1), jitter=0.12):
        X, tets = box_mesh(*n)
        X = X + jitter * rng.uniform(-1, 1, size=X.shape)
        self.X = np.ascontiguousarray(X)
        self.tets = orient(self.X, tets)
        self.Dm_inv, self.vol = rest_data(self.X, self.tets)
        m = len(self.tets)
        self.lame = np.ascontiguousarray(np.column_stack([rng.uniform(0.5, 1.5, m), rng.uniform(1.0, 5.0, m)]))

    def args(self):
        return self.tets, self.Dm_inv, self.vol, self.lame

    def energy(self, x, model):
        return K.elastic_energy(x, *self.args(), model)

    def gradient(self, x, model):
        return K.elastic_gradient(x, *self.args(), model)

    def hessian_dense(self, x, model, project):
        r, c, v = K.elastic_hessian(x, *self.args(), model, project)
        n = 3 * len(x)
        H = np.zeros((n, n))
        np.add.at(H, (r, c), v)
        return H

    def blocks(self, x, model, project):
        return K.elastic_hessian_values(x, *self.args(), model, project).reshape(-1, 12, 12)


DEFORMATIONS = {
    # name: (singular values of the affine part, vertex noise)
    "well_shaped": ((1.1, 0.95, 0.9), 0.08),
    "large_stretch": ((2.8, 1.9, 1.3), 0.05),
    "compress_J0.1": ((0.9, 0.6, 0.185), 0.0),
    "sigma1_eq_sigma2": ((1.3, 1.3 * (1 + 1e-9), 0.7), 0.0),
    "all_sigma_equal": ((0.8, 0.8, 0.8), 0.0),
    "inverted": ((1.2, 0.8, -0.4), 0.03),
}


def deformed(mesh, rng, name):
    sigma, noise = DEFORMATIONS[name]
    A = affine(rng, sigma)
    x = mesh.X @ A.T + rng.normal(size=3) + noise * rng.normal(size=mesh.X.shape)
    return np.ascontiguousarray(x)


def cases():
    for model in (NH, FCR):
        for name in DEFORMATIONS:
            if name == "inverted" and model == NH:
                continue
            yield pytest.param(model, name, id=f"{'NH' if model == NH else 'FCR'}-{name}")


def fd_gradient(f, x, h):
    x = x.copy()
    flat = x.reshape(-1)
    g = np.empty(flat.size)
    for i in range(flat.size):
        xi = flat[i]
        flat[i] = xi + h
        fp = f(x)
        flat[i] = xi - h
        fm = f(x)
        flat[i] = xi
        g[i] = (fp - fm) / (2 * h)
    return g


def fd_jacobian(f, x, h):
    x = x.copy()
    flat = x.reshape(-1)
    cols = []
    for i in range(flat.size):
        xi = flat[i]
        flat[i] = xi + h
        fp = f(x)
        flat[i] = xi - h
        fm = f(x)
        flat[i] = xi
        cols.append((fp - fm) / (2 * h))
    return np.column_stack(cols)


def rel_err(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


# --------------------------------------------------------------------------------------
# SVD
# --------------------------------------------------------------------------------------


def svd_matrices():
    rng = np.random.default_rng(1)
    Fs = [rng.normal(size=(3, 3)) for _ in range(20)]
    Fs += [affine(rng, s) for s in [(1.3, 1.3, 0.7), (1.3, 1.3 * (1 + 1e-12), 0.7), (2, 2, 2), (1, 1, -1),
                                     (1.5, 0.5, 0.5), (1, 0.6, -0.6), (1, 1, 0), (3, 0, 0), (1e3, 1, 1e-6),
                                     (1, 1e-9, -1e-9)]]
    Fs += [np.eye(3), -np.eye(3), np.zeros((3, 3)), np.diag([1.0, 2.0, 3.0]), random_rotation(rng)]
    return Fs


@pytest.mark.parametrize("F", svd_matrices())
def test_svd_is_rotation_variant_and_reconstructs(F):
    U, s, V = K.svd_rv(F)
    scale = max(np.abs(F).max(), 1e-300)
    assert np.abs(U @ np.diag(s) @ V.T - F).max() <= 1e-13 * scale
    assert np.abs(U.T @ U - np.eye(3)).max() < 1e-13
    assert np.abs(V.T @ V - np.eye(3)).max() < 1e-13
    assert np.linalg.det(U) == pytest.approx(1.0, abs=1e-13)
    assert np.linalg.det(V) == pytest.approx(1.0, abs=1e-13)
    assert s[0] >= s[1] - 1e-13 * scale and s[1] >= abs(s[2]) - 1e-13 * scale
    np.testing.assert_allclose(np.abs(s), np.linalg.svd(F, compute_uv=False), atol=1e-13 * scale)
    if abs(np.linalg.det(F)) > 1e-12 * scale**3:
        assert np.sign(s[2]) == np.sign(np.linalg.det(F))


# --------------------------------------------------------------------------------------
# energies and derivatives
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("model", [NH, FCR])
def test_rest_state_has_zero_energy_and_gradient(model):
    mesh = Mesh(np.random.default_rng(2))
    for x in (mesh.X, mesh.X @ random_rotation(np.random.default_rng(3)).T + 5.0):
        x = np.ascontiguousarray(x)
        assert abs(mesh.energy(x, model)) < 1e-13
        assert np.abs(K.elastic_energy_per_tet(x, *mesh.args(), model)).max() < 1e-14
        assert np.abs(mesh.gradient(x, model)).max() < 1e-13


def test_energy_densities_match_their_formulas():
    rng = np.random.default_rng(4)
    mu, lam = 0.7, 3.1
    for _ in range(10):
        F = affine(rng, rng.uniform(0.3, 2.0, 3))
        J = np.linalg.det(F)
        nh = 0.5 * mu * (np.sum(F * F) - 3) - mu * np.log(J) + 0.5 * lam * np.log(J) ** 2
        assert K.energy_density(F, mu, lam, NH) == pytest.approx(nh, rel=1e-12, abs=1e-14)
        # FCR via the polar decomposition F = R S, det R = +1: μ ‖F − R‖² + λ/2 (J − 1)²
        Fi = F @ np.diag([1.0, 1.0, -1.0]) if rng.uniform() < 0.5 else F
        W, sv, Zt = np.linalg.svd(Fi)
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(W @ Zt))])
        R = W @ D @ Zt
        fcr = mu * np.sum((Fi - R) ** 2) + 0.5 * lam * (np.linalg.det(Fi) - 1) ** 2
        assert K.energy_density(Fi, mu, lam, FCR) == pytest.approx(fcr, rel=1e-12, abs=1e-14)
    assert K.energy_density(np.diag([1.0, 1.0, -0.5]), mu, lam, NH) == np.inf
    assert K.energy_density(np.diag([1.0, 1.0, 0.0]), mu, lam, NH) == np.inf
    assert np.all(np.isnan(K.first_piola(np.diag([1.0, 1.0, -0.5]), mu, lam, NH)))


@pytest.mark.parametrize("model,name", list(cases()))
def test_gradient_matches_finite_differences(model, name):
    rng = np.random.default_rng(5)
    mesh = Mesh(rng)
    x = deformed(mesh, rng, name)
    g = mesh.gradient(x, model)
    assert np.all(np.isfinite(g))
    g_fd = fd_gradient(lambda y: mesh.energy(y, model), x, 1e-6)
    assert rel_err(g_fd, g) < 1e-7


@pytest.mark.parametrize("model,name", list(cases()))
def test_hessian_matches_finite_differences_of_gradient(model, name):
    rng = np.random.default_rng(6)
    mesh = Mesh(rng)
    x = deformed(mesh, rng, name)
    H = mesh.hessian_dense(x, model, False)
    assert np.abs(H - H.T).max() <= 1e-12 * np.abs(H).max()
    H_fd = fd_jacobian(lambda y: mesh.gradient(y, model), x, 1e-6)
    assert rel_err(H_fd, H) < 1e-7


@pytest.mark.parametrize("model", [NH, FCR])
def test_nh_inverted_tet_is_infinite_and_gradient_nan(model):
    mesh = Mesh(np.random.default_rng(7), n=(1, 1, 1))
    x = mesh.X.copy()
    x[:, 2] *= -1.0  # mirror: every tet inverted
    x = np.ascontiguousarray(x)
    if model == NH:
        assert mesh.energy(x, model) == np.inf
        assert np.all(np.isnan(mesh.gradient(x, model)))
        assert np.all(np.isnan(mesh.blocks(x, model, True)))
    else:
        assert np.isfinite(mesh.energy(x, model)) and mesh.energy(x, model) > 0
        assert np.all(np.isfinite(mesh.gradient(x, model)))
        assert np.all(np.isfinite(mesh.blocks(x, model, True)))


@pytest.mark.parametrize("model", [NH, FCR])
def test_rotation_invariance(model):
    rng = np.random.default_rng(8)
    mesh = Mesh(rng)
    x = deformed(mesh, rng, "large_stretch")
    R = random_rotation(rng)
    xr = np.ascontiguousarray(x @ R.T + rng.normal(size=3))
    e, er = (K.elastic_energy_per_tet(y, *mesh.args(), model) for y in (x, xr))
    np.testing.assert_allclose(er, e, rtol=1e-12)
    g, gr = mesh.gradient(x, model), mesh.gradient(xr, model)
    np.testing.assert_allclose(gr.reshape(-1, 3), g.reshape(-1, 3) @ R.T, atol=1e-12 * np.abs(g).max())
    Rn = np.kron(np.eye(len(x)), R)
    for project in (False, True):
        H, Hr = mesh.hessian_dense(x, model, project), mesh.hessian_dense(xr, model, project)
        np.testing.assert_allclose(Hr, Rn @ H @ Rn.T, atol=1e-11 * np.abs(H).max())


# --------------------------------------------------------------------------------------
# PSD projection
# --------------------------------------------------------------------------------------


def dF_dx(Dm_inv):
    """B (9×12): vec(F)[3a+b] = Σ_c (x_{c+1} − x_0)[a] Dm⁻¹[c, b]."""
    B = np.zeros((9, 12))
    for a, b in itertools.product(range(3), range(3)):
        for c in range(3):
            B[3 * a + b, 3 * (c + 1) + a] = Dm_inv[c, b]
        B[3 * a + b, a] = -Dm_inv[:, b].sum()
    return B


def dense_projected_tet_hessian(F, Dm_inv, vol, mu, lam, model):
    """Test oracle: clamp a dense eigendecomposition of the same 9×9 ∂²Ψ/∂F²."""
    H9 = K.dpsi_dF2(F, mu, lam, model, False)
    w, Q = np.linalg.eigh(H9)
    H9p = (Q * np.maximum(w, 0.0)) @ Q.T
    B = dF_dx(Dm_inv)
    return H9p, vol * B.T @ H9p @ B


def nh_dpsi_dF2_closed_form(F, mu, lam):
    """δP = μ δF + (μ − λ ln J) F⁻ᵀ δFᵀ F⁻ᵀ + λ tr(F⁻¹ δF) F⁻ᵀ (invariant form)."""
    Finv = np.linalg.inv(F)
    FinvT = Finv.T
    lnJ = np.log(np.linalg.det(F))
    H = np.zeros((9, 9))
    for a, b in itertools.product(range(3), range(3)):
        dF = np.zeros((3, 3))
        dF[a, b] = 1.0
        dP = mu * dF + (mu - lam * lnJ) * FinvT @ dF.T @ FinvT + lam * np.trace(Finv @ dF) * FinvT
        H[:, 3 * a + b] = dP.reshape(-1)
    return H


def sample_F(rng, model):
    sig = [rng.uniform(0.2, 3.0, 3), [1.3, 1.3 * (1 + 1e-10), 0.5], [0.7, 0.7, 0.7], [2.0, 0.3, 0.3],
           [1.0, 1.0, 0.1]]
    if model == FCR:
        sig += [[1.5, 0.6, -0.3], [1.0, 0.5, -0.5 + 1e-6], [2.0, 1.0, -1.0 + 1e-3]]
    return [affine(rng, s) for s in sig]


@pytest.mark.parametrize("model", [NH, FCR])
def test_dpsi_dF2_is_the_derivative_of_first_piola(model):
    rng = np.random.default_rng(9)
    mu, lam = 0.8, 2.5
    for F in sample_F(rng, model):
        H = K.dpsi_dF2(F, mu, lam, model, False)
        assert np.abs(H - H.T).max() <= 1e-12 * np.abs(H).max()
        if model == NH:
            np.testing.assert_allclose(H, nh_dpsi_dF2_closed_form(F, mu, lam), atol=1e-10 * np.abs(H).max())
        s = np.linalg.svd(F, compute_uv=False)
        # stay well inside the region where Ψ is smooth: σ > 0 (NH), σ₁ + σ₂ > 0 (FCR, inverted)
        smooth_radius = s[1] - s[2] if np.linalg.det(F) < 0 else s[2]
        h = 3e-4 * smooth_radius  # round-off in P grows like 1/smooth_radius near the FCR kink
        H_fd = fd_jacobian(lambda G: K.first_piola(G.reshape(3, 3), mu, lam, model).reshape(-1), F, h)
        assert rel_err(H_fd, H) < 1e-6


@pytest.mark.parametrize("model", [NH, FCR])
def test_sigma_derivatives_match_the_quotients_they_replace(model):
    """A = ∂²Ψ/∂σ², twist = (ψᵢ+ψⱼ)/(σᵢ+σⱼ), flip = (ψᵢ−ψⱼ)/(σᵢ−σⱼ), with ψᵢ = (UᵀPV)ᵢᵢ,
    checked on well-separated σ where the naive quotients are accurate."""
    rng = np.random.default_rng(16)
    mu, lam = 0.9, 4.0
    sigmas = [(2.1, 1.3, 0.6), (1.7, 0.9, 0.4)] + ([(1.5, 0.8, -0.3)] if model == FCR else [])
    for sig in sigmas:
        F = affine(rng, sig)
        s, A, twist, flip = K.sigma_derivatives(F, mu, lam, model)
        np.testing.assert_allclose(s, sig, rtol=1e-13)

        def psi(sv):
            U, _, V = K.svd_rv(F)
            return np.diag(U.T @ K.first_piola(U @ np.diag(sv) @ V.T, mu, lam, model) @ V)

        p = psi(s)
        for k, (i, j) in enumerate([(0, 1), (0, 2), (1, 2)]):
            assert twist[k] == pytest.approx((p[i] + p[j]) / (s[i] + s[j]), rel=1e-12)
            assert flip[k] == pytest.approx((p[i] - p[j]) / (s[i] - s[j]), rel=1e-12)
        A_fd = fd_jacobian(psi, s.copy(), 1e-6)
        np.testing.assert_allclose(A, A_fd, rtol=1e-7, atol=1e-8 * np.abs(A).max())


@pytest.mark.parametrize("model", [NH, FCR])
def test_analytic_projection_matches_dense_oracle(model):
    rng = np.random.default_rng(10)
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) + 0.15 * rng.uniform(-1, 1, (4, 3))
    tets = orient(X, np.array([[0, 1, 2, 3]], dtype=np.int64))
    Dm_inv, vol = rest_data(X, tets)
    mu, lam = 1.1, 7.0
    lame = np.array([[mu, lam]])
    n_clamped = n_scaling_clamped = 0
    Fs = sample_F(rng, model) + sample_F(rng, model)
    for A in Fs:
        x = np.ascontiguousarray(X @ A.T)
        F = edge_matrices(x, tets)[0] @ Dm_inv[0]
        H9p_oracle, H12_oracle = dense_projected_tet_hessian(F, Dm_inv[0], vol[0], mu, lam, model)
        H9p = K.dpsi_dF2(F, mu, lam, model, True)
        assert rel_err(H9p, H9p_oracle) < 1e-8
        H12 = K.elastic_hessian_values(x, tets, Dm_inv, vol, lame, model, True).reshape(12, 12)
        assert rel_err(H12, H12_oracle) < 1e-8
        n_clamped += np.linalg.eigvalsh(K.dpsi_dF2(F, mu, lam, model, False)).min() < 0
        n_scaling_clamped += np.linalg.eigvalsh(K.sigma_derivatives(F, mu, lam, model)[1]).min() < 0
    # the comparison exercised clamping, and both ways of treating the 3×3 scaling block
    assert n_clamped >= 3 and 1 <= n_scaling_clamped < len(Fs)


@pytest.mark.parametrize("model,name", [(NH, "compress_J0.1"), (NH, "large_stretch"), (FCR, "inverted"),
                                        (FCR, "compress_J0.1")])
def test_projected_hessian_is_psd(model, name):
    rng = np.random.default_rng(11)
    mesh = Mesh(rng)
    x = deformed(mesh, rng, name)
    raw = np.linalg.eigvalsh(mesh.blocks(x, model, False))
    assert raw.min() < -1e-3 * raw.max()  # indefinite before projection
    ev = np.linalg.eigvalsh(mesh.blocks(x, model, True))
    assert ev.min() >= -1e-12 * ev.max()
    H = mesh.hessian_dense(x, model, True)
    assert np.linalg.eigvalsh(H).min() >= -1e-12 * np.abs(H).max()


@pytest.mark.parametrize("model", [NH, FCR])
def test_projection_leaves_psd_hessians_unchanged(model):
    rng = np.random.default_rng(12)
    mesh = Mesh(rng)
    rest = np.ascontiguousarray(mesh.X)
    np.testing.assert_allclose(mesh.blocks(rest, model, True), mesh.blocks(rest, model, False), rtol=0,
                               atol=1e-12 * np.abs(mesh.blocks(rest, model, False)).max())
    # mild stretch: every eigenvalue of ∂²Ψ/∂F² is positive (larger ones make NH's flip
    # eigenvalues μ + (μ − λ ln J)/(σᵢσⱼ) negative)
    x = np.ascontiguousarray(mesh.X @ affine(rng, (1.03, 1.02, 1.01)).T)
    raw = mesh.blocks(x, model, False)
    for e in range(len(mesh.tets)):
        F = edge_matrices(x, mesh.tets[e:e + 1])[0] @ mesh.Dm_inv[e]
        assert np.linalg.eigvalsh(K.dpsi_dF2(F, *mesh.lame[e], model, False)).min() > 0
    np.testing.assert_allclose(mesh.blocks(x, model, True), raw, rtol=0, atol=1e-12 * np.abs(raw).max())


def test_hessian_layout_is_144_fixed_slots_per_tet():
    rng = np.random.default_rng(13)
    mesh = Mesh(rng)
    x = deformed(mesh, rng, "well_shaped")
    r, c, v = K.elastic_hessian(x, *mesh.args(), FCR, True)
    m = len(mesh.tets)
    assert r.dtype == np.int32 and c.dtype == np.int32 and len(r) == len(c) == len(v) == 144 * m
    dofs = (3 * mesh.tets[:, :, None] + np.arange(3)).reshape(m, 12)
    np.testing.assert_array_equal(r.reshape(m, 12, 12), np.broadcast_to(dofs[:, :, None], (m, 12, 12)))
    np.testing.assert_array_equal(c.reshape(m, 12, 12), np.broadcast_to(dofs[:, None, :], (m, 12, 12)))
    np.testing.assert_array_equal(v, K.elastic_hessian_values(x, *mesh.args(), FCR, True))
    # the parallel gradient equals the serial sum of per-tet gradients
    local = K.elastic_local_gradients(x, *mesh.args(), FCR)
    g = np.zeros(3 * len(x))
    np.add.at(g, dofs.reshape(-1), local.reshape(-1))
    np.testing.assert_allclose(mesh.gradient(x, FCR), g, rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("model", [NH, FCR])
def test_parallel_chunks_match_single_tet_evaluation(model):
    """A mesh spanning several parallel work chunks gives the same per-tet results as
    evaluating each tet on its own."""
    rng = np.random.default_rng(17)
    mesh = Mesh(rng, n=(5, 5, 4))
    m = len(mesh.tets)
    assert m > 2 * K._CHUNK
    x = deformed(mesh, rng, "well_shaped")
    F = edge_matrices(x, mesh.tets) @ mesh.Dm_inv
    per = K.elastic_energy_per_tet(x, *mesh.args(), model)
    expected = [mesh.vol[e] * K.energy_density(F[e], *mesh.lame[e], model) for e in range(m)]
    np.testing.assert_allclose(per, expected, rtol=1e-13)
    assert mesh.energy(x, model) == pytest.approx(sum(expected), rel=1e-13)
    local = K.elastic_local_gradients(x, *mesh.args(), model)
    blocks = mesh.blocks(x, model, True)
    for e in rng.choice(m, 12, replace=False):
        one = (mesh.tets[e:e + 1], mesh.Dm_inv[e:e + 1], mesh.vol[e:e + 1], mesh.lame[e:e + 1])
        np.testing.assert_array_equal(K.elastic_local_gradients(x, *one, model)[0], local[e])
        np.testing.assert_array_equal(K.elastic_hessian_values(x, *one, model, True).reshape(12, 12), blocks[e])


# --------------------------------------------------------------------------------------
# inversion-free step bound
# --------------------------------------------------------------------------------------

UNIT_TET = (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float), np.array([[0, 1, 2, 3]], np.int64))


def scaled_edges_step(k):
    """Unit tet, p moves vertex c+1 by −k_c along axis c: det(Ds + t Dp) = Π_c (1 − k_c t)."""
    p = np.zeros((4, 3))
    for c in range(3):
        p[c + 1, c] = -k[c]
    return p


def test_max_step_collapse_at_half():
    X, tets = UNIT_TET
    p = scaled_edges_step((0.0, 0.0, 2.0))  # apex reaches the base plane at t = 0.5
    assert K.max_step_no_inversion(X, p, tets, 0.0) == pytest.approx(0.5, abs=1e-14)
    # det(t)/det(0) = 1 − 2t = 0.1  ->  t = 0.45
    assert K.max_step_no_inversion(X, p, tets, 0.1) == pytest.approx(0.45, abs=1e-14)
    assert K.max_step_no_inversion(X, p, tets, 0.1) <= 0.45


@pytest.mark.parametrize("k", [(0.5, 3.0, 1.5), (2.0, 2.0, 2.0), (0.0, 4.0, 4.0), (-1.0, 1.5, 0.0), (1.2, -0.5, 3.0)])
@pytest.mark.parametrize("ratio", [0.0, 0.1, 0.5])
def test_max_step_matches_cubic_roots(k, ratio):
    X, tets = UNIT_TET
    p = scaled_edges_step(k)
    alpha = K.max_step_no_inversion(X, p, tets, ratio)

    def vol_ratio(t):  # Π_c (1 − k_c t), evaluated in product form: no cancellation
        return np.prod([1.0 - kc * np.asarray(t) for kc in k], axis=0)

    t = np.linspace(0.0, 1.0, 100001)
    below = np.nonzero(vol_ratio(t) <= ratio)[0]
    if len(below) == 0:
        assert alpha == 1.0
        return
    lo, hi = t[below[0] - 1], t[below[0]]  # bracket of the first crossing; refine
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if vol_ratio(mid) > ratio else (lo, mid)
    # a multiple root evaluated from cubic coefficients is only good to ~eps^(1/m)
    multiple = ratio == 0.0 and len(set(k)) < 3
    assert hi - (1e-5 if multiple else 1e-13) <= alpha <= hi + 1e-13
    assert np.all(vol_ratio(np.linspace(0.0, alpha, 2001)) >= ratio - 1e-13)


def test_max_step_is_one_when_nothing_inverts():
    X, tets = UNIT_TET
    rng = np.random.default_rng(14)
    assert K.max_step_no_inversion(X, np.tile(rng.normal(size=3), (4, 1)), tets, 0.1) == 1.0  # translation
    assert K.max_step_no_inversion(X, 0.7 * X, tets, 0.1) == 1.0  # growth
    assert K.max_step_no_inversion(X, np.zeros((4, 3)), tets, 0.1) == 1.0
    assert K.max_step_no_inversion(X, scaled_edges_step((0, 0, 0.8)), tets, 0.1) == 1.0  # root at 1.125
    assert K.max_step_no_inversion(-X, scaled_edges_step((0, 0, 1)), tets, 0.1) == 0.0  # already inverted


def test_max_step_random_batch_keeps_volume_and_is_tight():
    rng = np.random.default_rng(15)
    X, tets = box_mesh(3, 3, 3, h=1e-3)  # small scale: the bound is scale-free
    X = np.ascontiguousarray(X + 2e-4 * rng.uniform(-1, 1, X.shape))
    tets = orient(X, tets)
    r = 0.1
    det0 = np.linalg.det(edge_matrices(X, tets))
    for trial in range(5):
        p = np.ascontiguousarray(rng.normal(scale=2e-3 * (trial + 1) / 3, size=X.shape))
        alpha = K.max_step_no_inversion(X, p, tets, r)
        assert 0.0 < alpha <= 1.0
        per = K.max_step_per_tet(X, p, tets, r)
        assert alpha == per.min()
        for t in np.linspace(0.0, alpha, 400):
            d = np.linalg.det(edge_matrices(X + t * p, tets))
            assert np.all(d >= r * det0 * (1 - 1e-9))
        if alpha < 1.0:  # tight: the limiting tet reaches r·det0 at α
            e = per.argmin()
            d = np.linalg.det(edge_matrices(X + alpha * p, tets[e:e + 1]))[0]
            assert d == pytest.approx(r * det0[e], rel=1e-8)
        np.testing.assert_allclose(K.max_step_no_inversion(1e3 * X, 1e3 * p, tets, r), alpha, rtol=1e-12)
    assert alpha < 1.0
