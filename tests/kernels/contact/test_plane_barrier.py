"""Vertex–plane barrier: finite differences, PSD Hessian, exact CCD."""

import numpy as np
import pytest

from ipcsim.kernels.contact import barrier as b
from ipcsim.kernels.contact import plane_barrier as pc
from ipcsim.potentials.base import Triplets

RNG = np.random.default_rng(7)


def _setup(n=6, dhat=0.1):
    normals = np.array([[0.0, 1.0, 0.0], [1.0, 2.0, 0.5]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    origins = np.array([[0.0, 0.0, 0.0], [-0.3, 0.0, 0.2]])
    # vertices on the positive side of both planes, some within dhat of them
    x = np.zeros((n, 3))
    for i in range(n):
        while True:
            p = RNG.uniform(-0.1, 0.2, 3)
            d = (p - origins) @ normals.T
            d = np.einsum("ij,ij->i", p - origins, normals)
            if np.all(d > 0.01):
                break
        x[i] = p
    return x, np.arange(n, dtype=np.int64), origins, normals, dhat * dhat


def test_scalar_barrier_derivatives_match_finite_differences():
    s_hat = 0.01
    for s in [1e-4, 3e-3, 7e-3, 0.0099]:
        eps = 1e-7 * s
        fd1 = (b.barrier(s + eps, s_hat) - b.barrier(s - eps, s_hat)) / (2 * eps)
        fd2 = (b.barrier_first_derivative(s + eps, s_hat)
               - b.barrier_first_derivative(s - eps, s_hat)) / (2 * eps)
        assert fd1 == pytest.approx(b.barrier_first_derivative(s, s_hat), rel=1e-6)
        assert fd2 == pytest.approx(b.barrier_second_derivative(s, s_hat), rel=1e-6)
    assert b.barrier(s_hat, s_hat) == 0.0 and b.barrier(0.0, s_hat) == np.inf


def test_gradient_and_hessian_match_finite_differences():
    x, verts, o, n, s_hat = _setup()
    kappa = 3.0
    g = pc.plane_barrier_gradient(x, verts, o, n, s_hat, kappa)
    assert np.abs(g).max() > 0  # some pair is active
    eps = 1e-7
    fd = np.zeros(x.size)
    for i in range(x.size):
        xp, xm = x.copy().reshape(-1), x.copy().reshape(-1)
        xp[i] += eps
        xm[i] -= eps
        fd[i] = (pc.plane_barrier_value(xp.reshape(-1, 3), verts, o, n, s_hat, kappa)
                 - pc.plane_barrier_value(xm.reshape(-1, 3), verts, o, n, s_hat, kappa)) / (2 * eps)
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6 * np.abs(g).max())


def test_hessian_is_psd_and_equals_exact_where_convex():
    x, verts, o, n, s_hat = _setup()
    H = Triplets(*pc.plane_barrier_hessian(x, verts, o, n, s_hat, 1.0)).tocsr(x.size).toarray()
    assert np.linalg.eigvalsh(H).min() > -1e-9 * np.abs(H).max()
    # one vertex, one plane: compare against d/dx of the gradient by finite differences
    x1 = np.array([[0.0, 0.03, 0.0]])
    v1 = np.array([0], dtype=np.int64)
    o1, n1 = np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]])
    H1 = Triplets(*pc.plane_barrier_hessian(x1, v1, o1, n1, s_hat, 1.0)).tocsr(3).toarray()
    eps = 1e-8
    fd = np.zeros((3, 3))
    for i in range(3):
        xp, xm = x1.copy(), x1.copy()
        xp[0, i] += eps
        xm[0, i] -= eps
        fd[:, i] = (pc.plane_barrier_gradient(xp, v1, o1, n1, s_hat, 1.0)
                    - pc.plane_barrier_gradient(xm, v1, o1, n1, s_hat, 1.0)) / (2 * eps)
    np.testing.assert_allclose(H1, fd, rtol=1e-5, atol=1e-8 * np.abs(fd).max())


def test_ccd_stops_before_the_exact_time_of_impact():
    x = np.array([[0.0, 0.5, 0.0], [1.0, 2.0, 0.0]])
    verts = np.array([0, 1], dtype=np.int64)
    o, n = np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]])
    p = np.array([0.0, -1.0, 0.0, 0.0, 1.0, 0.0])  # vertex 0 would hit y=0 at α=0.5
    alpha = pc.plane_ccd_max_step(x, p, verts, o, n, 0.1)
    assert alpha == pytest.approx(0.45)
    assert alpha < 0.5
    # moving away or parallel: the full step is free
    assert pc.plane_ccd_max_step(x, -p, verts, o, n, 0.1) == 1.0
    # random steps: the configuration at α keeps every vertex strictly above the plane
    for _ in range(200):
        xr = np.column_stack([RNG.uniform(-1, 1, 5), RNG.uniform(1e-6, 1, 5), RNG.uniform(-1, 1, 5)])
        pr = RNG.normal(size=15) * RNG.choice([1e-3, 1.0, 1e3])
        a = pc.plane_ccd_max_step(xr, pr, np.arange(5, dtype=np.int64), o, n, 0.1)
        assert 0.0 < a <= 1.0
        assert np.all((xr + a * pr.reshape(-1, 3))[:, 1] > 0.0)
