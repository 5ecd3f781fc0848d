"""The one scatter of per-stencil gradients (kernels/algebra/scatter.py) and its users."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.kernels.elasticity import tets as KE
from ipcsim.kernels.contact import friction as KF
from ipcsim.kernels.algebra import scatter as S


def _serial_reference(local, stencils, n):
    # the documented order: rows in order, a row's vertices in order, axes in order
    g = np.zeros(3 * n)
    for i in range(stencils.shape[0]):
        for j in range(stencils.shape[1]):
            v = stencils[i, j]
            if v < 0:
                continue
            for a in range(3):
                g[3 * v + a] += local[i, 3 * j + a]
    return g


@pytest.mark.parametrize("width", [1, 2, 3, 4])
def test_scatter_matches_numpy_and_the_serial_order(width):
    rng = np.random.default_rng(width)
    n, k = 37, 500
    stencils = rng.integers(0, n, (k, width))
    stencils[rng.random((k, width)) < 0.2] = -1  # unused slots are skipped
    local = rng.normal(size=(k, 3 * width))
    got = S.scatter_local_gradients(local, stencils, n)
    want = np.zeros((n, 3))
    used = stencils >= 0
    np.add.at(want, stencils[used], local.reshape(k, width, 3)[used])
    np.testing.assert_allclose(got, want.ravel(), rtol=1e-13, atol=1e-13)
    # bit for bit the serial order (so results do not depend on threads)
    assert got.tobytes() == _serial_reference(local, stencils, n).tobytes()


def test_add_local_gradients_accumulates_in_place():
    rng = np.random.default_rng(0)
    stencils = rng.integers(0, 10, (40, 4))
    local = rng.normal(size=(40, 12))
    grad = rng.normal(size=30)
    want = grad + S.scatter_local_gradients(local, stencils, 10)
    S.add_local_gradients(grad, local, stencils)
    np.testing.assert_allclose(grad, want, rtol=1e-13, atol=1e-13)


def test_empty_stencils_give_zeros():
    g = S.scatter_local_gradients(np.zeros((0, 12)), np.zeros((0, 4), np.int64), 5)
    assert g.shape == (15,) and not g.any()


def test_stencil_pairs_scatter_is_the_general_scatter_on_stacked_rows():
    rng = np.random.default_rng(1)
    pt = rng.integers(0, 50, (120, 4))
    ee = rng.integers(0, 50, (90, 4))
    G = rng.normal(size=(210, 12))
    got = S.scatter_stencil_gradients(G, pt, ee, 50)
    want = S.scatter_local_gradients(G, np.concatenate([pt, ee]), 50)
    assert got.tobytes() == want.tobytes()


def test_elasticity_and_friction_use_the_shared_scatter():
    assert KE.scatter_local_gradients is S.scatter_local_gradients
    # friction: pair k contributes c_i · f_k on its stencil vertex i (f_k = w (f1/y) P τ)
    rng = np.random.default_rng(2)
    n, m = 12, 30
    verts = rng.integers(0, n, (m, 4))
    nv = rng.integers(1, 5, m)
    coeffs = rng.normal(size=(m, 4))
    for k in range(m):
        verts[k, nv[k]:] = -1
        coeffs[k, nv[k]:] = 0.0
    basis = np.linalg.qr(rng.normal(size=(m, 3, 3)))[0][:, :, :2].copy()
    weight = rng.uniform(0.5, 2.0, m)
    u = rng.normal(scale=1e-3, size=(n, 3))
    eps = 1e-3
    got = KF.friction_gradient(u, verts, coeffs, basis, weight, eps)
    want = np.zeros(3 * n)
    for k in range(m):
        r = sum(coeffs[k, i] * u[verts[k, i]] for i in range(nv[k]))
        tau = basis[k].T @ r
        force = weight[k] * KF.f1_over_y(np.linalg.norm(tau), eps) * (basis[k] @ tau)
        for i in range(nv[k]):
            want[3 * verts[k, i]:3 * verts[k, i] + 3] += coeffs[k, i] * force
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
