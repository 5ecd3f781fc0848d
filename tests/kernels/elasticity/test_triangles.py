"""Plane-strain triangle kernels (kernels/elasticity/triangles.py): the 2 x 2 SVD, the
densities against the 3D ones at diag(F, 1), derivatives against finite differences, the
analytic PSD projection against a dense eigendecomposition, the inversion-free step
bound, and the lecture's own neo-Hookean triangles (its lesson 6) where
../shared/solid-sim-tutorial is there."""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from ipcsim.kernels.algebra.assembly import block_triplet_indices
from ipcsim.kernels.elasticity import tets as K3
from ipcsim.kernels.elasticity import triangles as K
from ipcsim.model.generate import rectangle_mesh

NH = K3.NEO_HOOKEAN
FCR = K3.FIXED_COROTATED
MU, LAM = 3.0e4, 8.0e4


def random_F(rng, inverted=False):
    F = np.eye(2) + 0.4 * rng.standard_normal((2, 2))
    if (np.linalg.det(F) < 0) != inverted:
        F[:, 0] *= -1.0
    return F


def as_3d(F):
    F3 = np.eye(3)
    F3[:2, :2] = F
    return F3


def rest_data(P, T):
    Dm = np.stack([P[T[:, 1], :2] - P[T[:, 0], :2], P[T[:, 2], :2] - P[T[:, 0], :2]], axis=-1)
    return np.ascontiguousarray(np.linalg.inv(Dm)), 0.5 * np.linalg.det(Dm)


def deformed_square(rng, n=3, amount=0.06):
    """A square of n x n cells, its nodes moved at random, no triangle inverted."""
    P, T = rectangle_mesh(n, n)
    Dm_inv, areas = rest_data(P, T)
    while True:
        x = P.copy()
        x[:, :2] += amount * rng.standard_normal((len(P), 2))
        if np.all(rest_data(x, T)[1] > 0.0):
            break
    lame = np.column_stack([np.full(len(T), MU), np.full(len(T), LAM)])
    return x, T, Dm_inv, areas, lame


def test_svd2_is_rotation_variant_and_reconstructs():
    rng = np.random.default_rng(0)
    for k in range(200):
        F = random_F(rng, inverted=k % 3 == 0)
        U, s, V = K.svd2(F)
        np.testing.assert_allclose(U @ np.diag(s) @ V.T, F, atol=1e-14)
        assert np.linalg.det(U) == pytest.approx(1.0) and np.linalg.det(V) == pytest.approx(1.0)
        assert s[0] >= abs(s[1]) and np.sign(s[1]) == np.sign(np.linalg.det(F))
        np.testing.assert_allclose(sorted(np.abs(s)), sorted(np.linalg.svd(F)[1]), rtol=1e-12)


@pytest.mark.parametrize("model", [NH, FCR])
def test_densities_and_stresses_are_the_3d_ones_at_diag_F_1(model):
    rng = np.random.default_rng(1)
    assert K.energy_density_2d(np.eye(2), MU, LAM, model) == 0.0
    for k in range(100):
        F = random_F(rng, inverted=(model == FCR and k % 4 == 0))
        psi = K.energy_density_2d(F, MU, LAM, model)
        P = K.first_piola_2d(F, MU, LAM, model)
        # an inverted triangle keeps its reflection in the plane; the 3D SVD of diag(F, 1)
        # puts it on the smallest singular value, which is 1 (along z) where |σ1| > 1
        if np.linalg.det(F) > 0 or np.linalg.svd(F)[1].min() < 1.0:
            assert psi == pytest.approx(K3.energy_density(as_3d(F), MU, LAM, model), rel=1e-12)
            np.testing.assert_allclose(P, K3.first_piola(as_3d(F), MU, LAM, model)[:2, :2],
                                       rtol=1e-10, atol=1e-10 * np.abs(P).max())
        # P against central differences of Ψ
        h = 1e-7
        fd = np.empty((2, 2))
        for a in range(2):
            for b in range(2):
                Fp, Fm = F.copy(), F.copy()
                Fp[a, b] += h
                Fm[a, b] -= h
                fd[a, b] = (K.energy_density_2d(Fp, MU, LAM, model)
                            - K.energy_density_2d(Fm, MU, LAM, model)) / (2 * h)
        np.testing.assert_allclose(fd, P, rtol=1e-5, atol=1e-6 * np.abs(P).max())
    F = random_F(rng, inverted=True)
    if model == NH:
        assert K.energy_density_2d(F, MU, LAM, NH) == np.inf
        assert np.isnan(K.first_piola_2d(F, MU, LAM, NH)).all()


@pytest.mark.parametrize("model", [NH, FCR])
def test_stress_derivative_and_its_projection(model):
    rng = np.random.default_rng(2)
    clamped = 0
    for k in range(100):
        F = random_F(rng, inverted=(model == FCR and k % 4 == 0))
        if k % 5 == 0:  # compressed: negative eigenvalues to clamp
            F = 0.3 * F
        H = K.dpsi_dF2_2d(F, MU, LAM, model, False)
        h = 1e-7 * max(1.0, np.abs(F).max())
        fd = np.empty((4, 4))
        for j in range(4):
            Fp, Fm = F.copy(), F.copy()
            Fp.flat[j] += h
            Fm.flat[j] -= h
            fd[:, j] = (K.first_piola_2d(Fp, MU, LAM, model)
                        - K.first_piola_2d(Fm, MU, LAM, model)).ravel() / (2 * h)
        np.testing.assert_allclose(fd, H, rtol=1e-5, atol=1e-5 * np.abs(H).max())
        # the analytic projection is the nearest PSD matrix: eigenvalues clamped at 0
        w, Q = np.linalg.eigh(H)
        clamped += w.min() < 0
        ref = (Q * np.maximum(w, 0.0)) @ Q.T
        Hp = K.dpsi_dF2_2d(F, MU, LAM, model, True)
        np.testing.assert_allclose(Hp, ref, atol=1e-9 * np.abs(H).max())
    assert clamped >= 10


@pytest.mark.parametrize("model", [NH, FCR])
def test_batched_derivatives_finite_differences(model):
    rng = np.random.default_rng(3)
    x, T, Dm_inv, areas, lame = deformed_square(rng)
    E = K.triangle_energy(x, T, Dm_inv, areas, lame, model)
    assert E == pytest.approx(K.triangle_energy_per_element(x, T, Dm_inv, areas, lame,
                                                            model).sum(), rel=1e-14)
    g = K.triangle_gradient(x, T, Dm_inv, areas, lame, model)
    rows, cols = block_triplet_indices(T)
    vals = K.triangle_hessian_values(x, T, Dm_inv, areas, lame, model, False)
    H = sp.csr_matrix((vals, (rows, cols)), shape=(x.size, x.size)).toarray()
    h = 1e-7
    for k in range(x.size):
        xp, xm = x.copy(), x.copy()
        xp.flat[k] += h
        xm.flat[k] -= h
        fd = (K.triangle_energy(xp, T, Dm_inv, areas, lame, model)
              - K.triangle_energy(xm, T, Dm_inv, areas, lame, model)) / (2 * h)
        assert fd == pytest.approx(g[k], rel=1e-5, abs=1e-6 * np.abs(g).max())
        if k % 3 != 2:
            col = (K.triangle_gradient(xp, T, Dm_inv, areas, lame, model)
                   - K.triangle_gradient(xm, T, Dm_inv, areas, lame, model)) / (2 * h)
            assert np.abs(col - H[:, k]).max() <= 1e-5 * np.abs(H).max()
    z = 3 * np.arange(len(x)) + 2
    assert np.all(g[z] == 0.0) and np.all(H[z] == 0.0) and np.all(H[:, z] == 0.0)
    Hp = sp.csr_matrix((K.triangle_hessian_values(x, T, Dm_inv, areas, lame, model, True),
                        (rows, cols)), shape=(x.size, x.size)).toarray()
    assert np.linalg.eigvalsh(Hp).min() >= -1e-9 * np.abs(Hp).max()
    # rest shape: no energy, no force
    P, _ = rectangle_mesh(3, 3)
    assert K.triangle_energy(P, T, Dm_inv, areas, lame, model) == pytest.approx(0.0, abs=1e-9)
    assert np.abs(K.triangle_gradient(P, T, Dm_inv, areas, lame, model)).max() < 1e-9


def test_step_bound_keeps_every_triangle_above_its_area_ratio():
    rng = np.random.default_rng(4)
    x, T, Dm_inv, _, _ = deformed_square(rng, amount=0.02)
    r = 0.1

    def dets(y):
        D = np.stack([y[T[:, 1], :2] - y[T[:, 0], :2], y[T[:, 2], :2] - y[T[:, 0], :2]], -1)
        return np.linalg.det(D)

    d0 = dets(x)
    bounded = 0
    for _ in range(50):
        p = np.zeros_like(x)
        p[:, :2] = rng.uniform(0.1, 2.0) * rng.standard_normal((len(x), 2))
        alpha = K.max_step_no_inversion_2d(x, p, T, r)
        per = K.max_step_per_triangle(x, p, T, r)
        assert alpha == per.min() or (alpha == 1.0 and per.min() >= 1.0)
        for t in np.linspace(0.0, alpha, 50, endpoint=False):
            assert np.all(dets(x + t * p) > r * d0)
        if alpha < 1.0:
            bounded += 1
            beyond = dets(x + min(1.0, alpha * (1 + 1e-9) + 1e-12) * p)
            assert np.any(beyond <= r * d0 * (1 + 1e-6))
    assert bounded >= 20
    flat = x.copy()
    flat[T[0, 2], :2] = 0.5 * (flat[T[0, 0], :2] + flat[T[0, 1], :2])
    assert K.max_step_per_triangle(flat, p, T, r)[0] == 0.0


def test_neo_hookean_triangles_are_the_lectures(repo_root):
    folder = repo_root.parent / "shared" / "solid-sim-tutorial" / "6_inv_free"
    if not (folder / "NeoHookeanEnergy.py").is_file():
        pytest.skip("../shared/solid-sim-tutorial is not present")
    sys.path.insert(0, str(folder))
    try:
        sys.modules.pop("NeoHookeanEnergy", None)
        sys.modules.pop("utils", None)
        NHE = importlib.import_module("NeoHookeanEnergy")
        rng = np.random.default_rng(5)
        x, T, Dm_inv, areas, lame = deformed_square(rng, amount=0.1)
        x2 = x[:, :2].copy()
        IB = [Dm_inv[e] for e in range(len(T))]
        mu, lam = list(lame[:, 0]), list(lame[:, 1])
        ref_val = NHE.val(x2, T, list(areas), IB, mu, lam)
        ref_grad = NHE.grad(x2, T, list(areas), IB, mu, lam)
        I, J, V = NHE.hess(x2, T, list(areas), IB, mu, lam)
        ref_H = sp.csr_matrix((V, (I, J)), shape=(x2.size, x2.size)).toarray()
    finally:
        sys.path.remove(str(folder))
        for name in [n for n, m in sys.modules.items()
                     if str(folder) in (getattr(m, "__file__", None) or "")]:
            del sys.modules[name]
    E = K.triangle_energy(x, T, Dm_inv, areas, lame, NH)
    g = K.triangle_gradient(x, T, Dm_inv, areas, lame, NH)
    rows, cols = block_triplet_indices(T)
    H = sp.csr_matrix((K.triangle_hessian_values(x, T, Dm_inv, areas, lame, NH, True),
                       (rows, cols)), shape=(x.size, x.size)).toarray()
    xy = np.stack([3 * np.arange(len(x)), 3 * np.arange(len(x)) + 1], axis=1).ravel()
    assert E == pytest.approx(ref_val, rel=1e-12)
    np.testing.assert_allclose(g.reshape(-1, 3)[:, :2], ref_grad, rtol=1e-10,
                               atol=1e-10 * np.abs(ref_grad).max())
    # the lecture holds ∂P/∂F in an integer array (its entries truncated before they are
    # scaled by the area): its Hessian agrees to that truncation only
    err = np.abs(H[np.ix_(xy, xy)] - ref_H).max()
    assert err <= 2e-5 * np.abs(ref_H).max()
