"""The Elasticity term as the solver sees it: value/gradient/hessian/max_step on a mesh."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ipcsim.potentials.base import ElementHessian, Triplets
from ipcsim.potentials.elasticity import Elasticity
from ipcsim.solver.assembly import Assembler


def box(n=2, jitter=0.1, seed=0):
    """n³ cubes of a unit grid, 6 positively oriented tets each, vertices jittered."""
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
    X = g + jitter * rng.uniform(-1, 1, g.shape)
    vid = {tuple(p): i for i, p in enumerate(g.astype(int))}
    tets = []
    for cell in itertools.product(range(n), repeat=3):
        for perm in itertools.permutations(range(3)):
            c = np.array(cell)
            path = [vid[tuple(c)]]
            for ax in perm:
                c[ax] += 1
                path.append(vid[tuple(c)])
            tets.append(path)
    tets = np.array(tets, dtype=np.int64)
    Dm = np.stack([X[tets[:, k + 1]] - X[tets[:, 0]] for k in range(3)], -1)
    neg = np.linalg.det(Dm) < 0
    tets[neg, 1], tets[neg, 2] = tets[neg, 2].copy(), tets[neg, 1].copy()
    Dm = np.stack([X[tets[:, k + 1]] - X[tets[:, 0]] for k in range(3)], -1)
    return X, tets, np.linalg.inv(Dm), np.linalg.det(Dm) / 6.0


def volumes6(x, tets):
    return np.linalg.det(np.stack([x[tets[:, k + 1]] - x[tets[:, 0]] for k in range(3)], -1))


def make(energy, seed=0, lame=(0.8, 3.0)):
    X, tets, Dm_inv, vol = box(seed=seed)
    return X, Elasticity(tets, Dm_inv, vol, lame, energy, len(X))


def squash(X, rng, sigma, noise=0.05):
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return X @ (Q @ np.diag(sigma) @ Q.T).T + noise * rng.normal(size=X.shape)


def test_energy_names():
    X, tets, Dm_inv, vol = box(n=1)
    assert Elasticity(tets, Dm_inv, vol, (1, 1), "nh", len(X)).energy == "NH"
    assert Elasticity(tets, Dm_inv, vol, (1, 1), "FCR", len(X)).energy == "FCR"
    with pytest.raises(ValueError, match="unknown elastic energy"):
        Elasticity(tets, Dm_inv, vol, (1, 1), "StVK", len(X))
    with pytest.raises(ValueError):
        Elasticity(tets, Dm_inv, vol, (1, 1), "NH", 3)  # indices beyond n_vertices


@pytest.mark.parametrize("energy", ["NH", "FCR"])
def test_value_gradient_hessian_agree(energy):
    X, el = make(energy)
    rng = np.random.default_rng(1)
    x = squash(X, rng, (1.4, 0.7, 0.5))
    assert el.value(x) == pytest.approx(el.per_tet_energy(x).sum(), rel=1e-14)
    assert el.value(x) > 0
    # the solver passes flat vectors
    assert el.value(x.reshape(-1)) == el.value(x)
    g = el.gradient(x)
    assert g.shape == (x.size,)
    np.testing.assert_array_equal(el.gradient(x.reshape(-1)), g)
    h = 1e-6
    for _ in range(3):
        d = rng.normal(size=x.shape)
        slope = (el.value(x + h * d) - el.value(x - h * d)) / (2 * h)
        assert slope == pytest.approx(g @ d.reshape(-1), rel=1e-7)
        Hd = el.hessian(x, project_psd=False).tocsr(x.size) @ d.reshape(-1)
        Hd_fd = (el.gradient(x + h * d) - el.gradient(x - h * d)) / (2 * h)
        assert np.linalg.norm(Hd - Hd_fd) < 1e-7 * np.linalg.norm(Hd)


@pytest.mark.parametrize("energy", ["NH", "FCR"])
def test_hessian_is_psd_triplets(energy):
    X, el = make(energy)
    x = squash(X, np.random.default_rng(2), (1.8, 0.6, 0.3))
    H = el.hessian(x)
    assert isinstance(H, ElementHessian) and H.block == 144 and H.n_elements == len(el.tets)
    assert H.rows.dtype == np.int32 and len(H.vals) == 144 * len(el.tets)  # compact pattern
    A = H.tocsr(x.size).toarray()
    assert np.abs(A - A.T).max() <= 1e-12 * np.abs(A).max()
    assert np.linalg.eigvalsh(A).min() >= -1e-12 * np.abs(A).max()
    A_raw = el.hessian(x, project_psd=False).tocsr(x.size).toarray()
    assert np.linalg.eigvalsh(A_raw).min() < -1e-3 * np.abs(A_raw).max()  # projection mattered
    # a second call reuses the sparsity pattern
    assert el.hessian(x).pattern_key is H.pattern_key


def test_lame_per_tet_scales_energy():
    X, tets, Dm_inv, vol = box(n=1)
    x = squash(X, np.random.default_rng(3), (1.2, 0.9, 0.8))
    one = Elasticity(tets, Dm_inv, vol, (1.0, 2.0), "NH", len(X))
    per = np.tile([1.0, 2.0], (len(tets), 1))
    per[0] *= 3.0
    three = Elasticity(tets, Dm_inv, vol, per, "NH", len(X))
    e1, e3 = one.per_tet_energy(x), three.per_tet_energy(x)
    assert e3[0] == pytest.approx(3 * e1[0], rel=1e-13)
    np.testing.assert_array_equal(e3[1:], e1[1:])


def test_max_step_bounds_nh_and_not_fcr():
    X, nh = make("NH")
    _, fcr = make("FCR")
    rng = np.random.default_rng(4)
    x = X + 0.02 * rng.normal(size=X.shape)
    p = -1.5 * (x - x.mean(0))  # shrink through a point: everything collapses at t = 2/3
    alpha = nh.max_step(x, p.reshape(-1))
    # det scales by (1 − 1.5 t)³ = 0.1 at t = (1 − 0.1^(1/3))/1.5
    assert alpha == pytest.approx((1 - 0.1 ** (1 / 3)) / 1.5, rel=1e-9)
    assert fcr.max_step(x, p.reshape(-1)) == 1.0
    det0 = volumes6(x, nh.tets)
    for t in np.linspace(0, alpha, 50):
        assert np.all(volumes6(x + t * p, nh.tets) >= 0.1 * det0 * (1 - 1e-12))
    assert np.isfinite(nh.value(x + alpha * p))
    assert nh.max_step(x, 0.1 * (x - x.mean(0))) == 1.0  # growth never inverts


@pytest.mark.parametrize("energy", ["NH", "FCR"])
def test_projected_newton_returns_to_rest(energy):
    """Projected Newton on the elastic energy alone, with the term's own step bound: energy
    decreases monotonically, NH stays finite, and the mesh ends at a rigid motion of rest."""
    X, el = make(energy, seed=5)
    rng = np.random.default_rng(6)
    x = squash(X, rng, (1.6, 0.8, 0.35), noise=0.03)
    e = el.value(x)
    e0 = e
    n = x.size
    for _ in range(40):
        g = el.gradient(x)
        if np.linalg.norm(g) < 1e-10:
            break
        H = el.hessian(x).tocsr(n)
        # rigid motions are a null space of H: a tiny shift keeps the system solvable
        K = H + 1e-8 * abs(H).max() * sp.identity(n)
        p = -spla.spsolve(K.tocsc(), g).reshape(-1, 3)
        assert g @ p.reshape(-1) < 0
        alpha = el.max_step(x, p.reshape(-1))
        while el.value(x + alpha * p) > e + 1e-4 * alpha * (g @ p.reshape(-1)):
            alpha *= 0.5
            assert alpha > 1e-12
        x = x + alpha * p
        e_new = el.value(x)
        assert np.isfinite(e_new) and e_new <= e
        e = e_new
    assert e < 1e-12 * e0
    # a rigid motion of rest: every edge length restored
    edges = np.array([(a, b) for t in el.tets for a, b in itertools.combinations(t, 2)])
    np.testing.assert_allclose(np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1),
                               np.linalg.norm(X[edges[:, 0]] - X[edges[:, 1]], axis=1), rtol=1e-5)


def test_read_only_model_arrays_are_accepted():
    """The Model hands over read-only arrays; results equal those from writeable ones."""
    X, tets, Dm_inv, vol = box(n=1)
    x = squash(X, np.random.default_rng(7), (1.2, 0.9, 0.8))
    arrays = [tets.copy(), Dm_inv.copy(), vol.copy(), np.tile([1.0, 2.0], (len(tets), 1)), x.copy()]
    for a in arrays:
        a.flags.writeable = False
    ro = Elasticity(*arrays[:4], "NH", len(X))
    rw = Elasticity(tets, Dm_inv, vol, (1.0, 2.0), "NH", len(X))
    assert ro.value(arrays[4]) == rw.value(x)
    np.testing.assert_array_equal(ro.gradient(arrays[4]), rw.gradient(x))
    np.testing.assert_array_equal(ro.hessian(arrays[4]).vals, rw.hessian(x).vals)
    assert ro.max_step(arrays[4], -x) == rw.max_step(x, -x)
    from ipcsim.kernels.elasticity import tets as kern

    for f in (kern.elastic_energy, kern.elastic_gradient, kern.elastic_hessian_values, kern.max_step_no_inversion):
        # no read-only specialisation was compiled
        assert all(arg.mutable for sig in f.signatures for arg in sig if hasattr(arg, "ndim"))


def test_element_hessian_assembles_chunk_by_chunk_as_its_values_do(monkeypatch):
    """An ElementHessian (elasticity's) added into the matrix a few elements at a time,
    with kinematic DOFs and a scale, equals the same values assembled as plain triplets."""
    X, el = make("NH")
    rng = np.random.default_rng(5)
    x = squash(X, rng, (1.3, 0.8, 0.9))
    H = el.hessian(x).scaled(2.5)
    assert isinstance(H, ElementHessian) and H.n_elements > 7
    monkeypatch.setattr(ElementHessian, "CHUNK", 7)  # several chunks and a ragged last one
    n_dofs = x.size
    kinematic = np.repeat(np.isin(np.arange(len(x)), rng.choice(len(x), 3, replace=False)), 3)
    free_index = np.full(n_dofs, -1)
    free_index[~kinematic] = np.arange((~kinematic).sum())
    p = rng.normal(size=n_dofs)
    n_free = int((~kinematic).sum())
    A, coupling = Assembler().assemble([H], [], free_index, n_free, p)
    plain = Triplets(H.rows, H.cols, H.vals, H.scale)
    A_ref, c_ref = Assembler().assemble([plain], [], free_index, n_free, p)
    np.testing.assert_allclose(A.toarray(), A_ref.toarray(), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(coupling, c_ref, rtol=1e-13, atol=1e-13)
    free = ~kinematic
    H_ref = plain.tocsr(n_dofs).toarray()
    np.testing.assert_allclose(A.toarray(), H_ref[np.ix_(free, free)], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(coupling, H_ref[np.ix_(free, kinematic)] @ p[kinematic],
                               rtol=1e-12, atol=1e-9)
    # its slots come per row vertex: a mask that splits a vertex's DOFs is refused
    kinematic[np.flatnonzero(kinematic)[1]] = False  # the middle DOF of a vertex
    free_index = np.full(n_dofs, -1)
    free_index[~kinematic] = np.arange((~kinematic).sum())
    with pytest.raises(ValueError, match="three DOFs"):
        Assembler().assemble([H], [], free_index, int((~kinematic).sum()), p)
