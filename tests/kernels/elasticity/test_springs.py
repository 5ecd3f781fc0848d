"""Mass-spring edges (kernels/elasticity/springs.py): derivatives against finite
differences, the projection against a dense eigendecomposition, and the lecture's own
MassSpringEnergy (its lesson 1) where ../shared/solid-sim-tutorial is there."""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from ipcsim.kernels.algebra.assembly import block_triplet_indices
from ipcsim.kernels.elasticity import springs as K
from ipcsim.model.generate import rectangle_mesh, rectangle_springs


def network(rng, n=3, amount=0.1, stretch=1.3):
    """The lecture's mass-spring square, stretched along x and shaken: some springs
    compressed, some stretched."""
    P, _ = rectangle_mesh(n, n)
    S = rectangle_springs(n, n)
    l2 = np.sum((P[S[:, 0]] - P[S[:, 1]]) ** 2, axis=1)
    k = rng.uniform(1e3, 2e4, len(S))
    x = P.copy()
    x[:, 0] *= stretch
    x[:, :2] += amount * rng.standard_normal((len(P), 2))
    return x, S, l2, k


def hessian(x, S, l2, k, project):
    rows, cols = block_triplet_indices(S)
    vals = K.spring_hessian_values(x, S, l2, k, project)
    return sp.csr_matrix((vals, (rows, cols)), shape=(x.size, x.size)).toarray()


def test_derivatives_finite_differences_and_nothing_along_z():
    rng = np.random.default_rng(0)
    x, S, l2, k = network(rng)
    g = K.spring_gradient(x, S, l2, k)
    H = hessian(x, S, l2, k, False)
    h = 1e-7
    for j in range(x.size):
        xp, xm = x.copy(), x.copy()
        xp.flat[j] += h
        xm.flat[j] -= h
        fd = (K.spring_energy(xp, S, l2, k) - K.spring_energy(xm, S, l2, k)) / (2 * h)
        assert fd == pytest.approx(g[j], rel=1e-5, abs=1e-6 * np.abs(g).max())
        col = (K.spring_gradient(xp, S, l2, k) - K.spring_gradient(xm, S, l2, k)) / (2 * h)
        assert np.abs(col - H[:, j]).max() <= 1e-5 * np.abs(H).max()
    z = 3 * np.arange(len(x)) + 2
    xy = np.setdiff1d(np.arange(x.size), z)
    assert np.all(g[z] == 0.0) and np.all(H[np.ix_(z, xy)] == 0.0)
    P, _ = rectangle_mesh(3, 3)  # at rest: no energy, no force
    assert K.spring_energy(P, S, l2, k) == 0.0
    assert np.all(K.spring_gradient(P, S, l2, k) == 0.0)


def test_projection_clamps_each_springs_eigenvalues():
    rng = np.random.default_rng(1)
    x, S, l2, k = network(rng, amount=0.15, stretch=0.8)
    x[S[0, 1]] = x[S[0, 0]]  # one spring of zero length
    clamped = 0
    for e in range(len(S)):
        one = slice(e, e + 1)
        Hr = hessian(x, S[one], l2[one], k[one], False)
        Hp = hessian(x, S[one], l2[one], k[one], True)
        w, Q = np.linalg.eigh(Hr)
        clamped += w.min() < -1e-9 * np.abs(w).max()
        np.testing.assert_allclose(Hp, (Q * np.maximum(w, 0.0)) @ Q.T,
                                   atol=1e-9 * max(np.abs(Hr).max(), 1.0))
    assert clamped > len(S) // 4


def test_springs_are_the_lectures(repo_root):
    folder = repo_root.parent / "shared" / "solid-sim-tutorial" / "1_mass_spring"
    if not (folder / "MassSpringEnergy.py").is_file():
        pytest.skip("../shared/solid-sim-tutorial is not present")
    rng = np.random.default_rng(2)
    x, S, l2, k = network(rng, amount=0.05)
    sys.path.insert(0, str(folder))
    try:
        for name in ("MassSpringEnergy", "utils"):
            sys.modules.pop(name, None)
        MS = importlib.import_module("MassSpringEnergy")
        x2 = x[:, :2].copy()
        ref_val = MS.val(x2, S, l2, k)
        ref_grad = MS.grad(x2, S, l2, k)
        I, J, V = MS.hess(x2, S, l2, k)
        ref_H = sp.csr_matrix((V, (I, J)), shape=(x2.size, x2.size)).toarray()
    finally:
        sys.path.remove(str(folder))
        for name in [n for n, m in sys.modules.items()
                     if str(folder) in (getattr(m, "__file__", None) or "")]:
            del sys.modules[name]
    xy = np.stack([3 * np.arange(len(x)), 3 * np.arange(len(x)) + 1], axis=1).ravel()
    assert K.spring_energy(x, S, l2, k) == pytest.approx(ref_val, rel=1e-12)
    np.testing.assert_allclose(K.spring_gradient(x, S, l2, k).reshape(-1, 3)[:, :2], ref_grad,
                               rtol=1e-12, atol=1e-12 * np.abs(ref_grad).max())
    np.testing.assert_allclose(hessian(x, S, l2, k, True)[np.ix_(xy, xy)], ref_H,
                               atol=1e-9 * np.abs(ref_H).max())
