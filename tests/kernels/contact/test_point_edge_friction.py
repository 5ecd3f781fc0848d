"""Lagged friction of point–edge pairs (kernels/contact/friction.py's
``lag_point_edge_pairs``): the 2D scenes' friction, evaluated by the 3D friction kernels.

* ipctk oracle: two triangulated squares (tests/two_squares.py); NormalCollisions and
  TangentialCollisions built at X_lag, FrictionPotential(ε) at V = u = X − X_lag, against
  ipcsim's friction over the brute-force point–edge candidates (value, gradient, PSD
  Hessian, in the plane);
* in the plane: no force along z, no coupling of z with x or y;
* the lecture's form: its normal forces and its friction value against lesson 8's own
  code (where ../shared/solid-sim-tutorial is there).
"""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from ipcsim.kernels.contact import friction as KF
from ipcsim.kernels.contact.barrier import BARRIER_IPC, BARRIER_LECTURE, barrier_of_form
from ipcsim.kernels.contact.distance import PE_P_E
from ipcsim.kernels.contact.point_edge_barrier import pe_classify_and_distance
from two_squares import SCENES, brute_force_point_edge_pairs, ipctk_mesh, scene


@pytest.fixture(scope="module")
def ipctk():
    return pytest.importorskip("ipctk")


def assemble(rows, cols, vals, n):
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n)).toarray()


def rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def lagged(V, pe, weights, s_hat, kappa, form, mu):
    keep, verts, coeffs, basis, lam = KF.lag_point_edge_pairs(V, pe, weights, s_hat, kappa,
                                                              form)
    return verts[keep], coeffs[keep], basis[keep], mu * lam[keep]


def sliding(rng, V, eps):
    """The upper square slides along x, the lower one a little the other way, plus noise
    in the plane: pairs on both sides of ε."""
    u = np.zeros_like(V)
    top = np.arange(len(V)) >= len(V) // 2
    u[top, 0] = 0.8 * eps
    u[~top, 0] = -0.4 * eps
    u[:, :2] += 0.7 * eps * rng.standard_normal((len(V), 2))
    return u


@pytest.mark.parametrize("name", list(SCENES))
def test_two_squares_friction_matches_ipctk(ipctk, name):
    V, _, E, p = scene(name)
    dhat, kappa, mu, eps = p["dhat"], p["kappa"], 0.35, 2e-3
    u = sliding(np.random.default_rng(5), V, eps)
    mesh, X = ipctk_mesh(ipctk, V, E)
    Xf = np.asfortranarray(X)
    C = ipctk.NormalCollisions()
    C.build(mesh, Xf, dhat)
    TC = ipctk.TangentialCollisions()
    TC.build(mesh, Xf, C, ipctk.BarrierPotential(dhat, kappa), mu)
    D = ipctk.FrictionPotential(eps)
    U = np.asfortranarray(mesh.vertices(np.asfortranarray(u[:, :2])))
    ref_value = D(TC, mesh, U)
    ref_grad = np.asarray(mesh.to_full_dof(np.asarray(D.gradient(TC, mesh, U)))).ravel()
    ref_H = mesh.to_full_dof(D.hessian(TC, mesh, U, ipctk.PSDProjectionMethod.CLAMP)).toarray()

    pe = brute_force_point_edge_pairs(V, E, 0.5 * dhat)
    verts, coeffs, basis, weight = lagged(V, pe, np.ones(len(pe)), dhat * dhat, kappa,
                                          BARRIER_IPC, mu)
    assert len(verts) == round(sum(c.weight for lst in (TC.vv_collisions, TC.ev_collisions)
                                   for c in lst)) and len(verts) >= 3
    value = KF.friction_value(u, verts, coeffs, basis, weight, eps)
    grad = KF.friction_gradient(u, verts, coeffs, basis, weight, eps)
    H = assemble(*KF.friction_hessian_triplets(u, verts, coeffs, basis, weight, eps, True,
                                               KF.triplet_offsets(verts)), u.size)
    n = len(V)
    xy = np.stack([3 * np.arange(n), 3 * np.arange(n) + 1], axis=1).ravel()
    z = 3 * np.arange(n) + 2
    print(f"  {name}: {len(verts)} frictional pairs, relative differences: value "
          f"{abs(value - ref_value) / ref_value:.1e}, gradient {rel(grad[xy], ref_grad):.1e}, "
          f"Hessian (clamped) {rel(H[np.ix_(xy, xy)], ref_H):.1e}")
    assert value == pytest.approx(ref_value, rel=1e-10)
    assert rel(grad[xy], ref_grad) <= 1e-10
    assert rel(H[np.ix_(xy, xy)], ref_H) <= 1e-10
    assert np.all(grad[z] == 0.0) and np.all(H[np.ix_(z, xy)] == 0.0)
    assert np.linalg.eigvalsh(H).min() >= -1e-12 * np.abs(H).max()
    # one column of each basis is ±e_z (up to rounding in z), the other lies in the plane
    along_z = np.argmax(np.abs(basis[:, 2, :]), axis=1)
    k = np.arange(len(basis))
    assert np.all(basis[k, :2, along_z] == 0.0) and np.all(basis[k, 2, 1 - along_z] == 0.0)
    np.testing.assert_allclose(np.abs(basis[k, 2, along_z]), 1.0, rtol=1e-15)


def test_inactive_pairs_are_dropped_and_forces_follow_the_barrier():
    V, _, E, p = scene("corner")
    pe = brute_force_point_edge_pairs(V, E, 0.3)
    s_hat, kappa = p["dhat"] ** 2, p["kappa"]
    w = np.linspace(0.5, 2.0, len(pe))
    _, d2 = pe_classify_and_distance(V, pe)
    for form in (BARRIER_IPC, BARRIER_LECTURE):
        keep, verts, _, _, lam = KF.lag_point_edge_pairs(V, pe, w, s_hat, kappa, form)
        assert np.array_equal(keep, d2 < s_hat) and 0 < keep.sum() < len(pe)
        assert np.all(lam[keep] > 0.0)
        # λ = −∂(w κ b)/∂d: the barrier's derivative along the distance, by differences
        for i in np.flatnonzero(keep):
            d, h = np.sqrt(d2[i]), 1e-7 * np.sqrt(d2[i])
            b = [w[i] * kappa * barrier_of_form(form, (d + s) ** 2, s_hat)[0] for s in (h, -h)]
            assert lam[i] == pytest.approx(-(b[0] - b[1]) / (2 * h), rel=1e-6)
        assert np.all(verts[keep, 0] == pe[keep, 0])


def _lesson8(folder):
    sys.path.insert(0, str(folder))
    try:
        for name in [n for n in sys.modules if n in ("BarrierEnergy", "FrictionEnergy", "utils")
                     or n == "distance" or n.startswith("distance.")]:
            del sys.modules[name]
        return importlib.import_module("BarrierEnergy"), importlib.import_module("FrictionEnergy")
    finally:
        sys.path.remove(str(folder))


def test_the_lecture_form_gives_the_lectures_self_friction(repo_root):
    folder = repo_root.parent / "shared" / "solid-sim-tutorial" / "8_self_friction"
    if not (folder / "FrictionEnergy.py").is_file():
        pytest.skip("../shared/solid-sim-tutorial is not present")
    try:
        BE, FE = _lesson8(folder)
        V, _, E, _ = scene("corner")
        dhat, kappa, mu, h = BE.dhat, BE.kappa, 0.4, 0.01
        X2 = V[:, :2] * 0.1 + [0.0, 3.0]  # well above the lesson's ground (y = -1)
        A = np.linspace(0.1, 0.3, len(X2))
        bp = sorted(set(E.ravel().tolist()))
        _, self_pairs = BE.compute_mu_lambda(X2, np.array([0.0, 1.0]), np.array([0.0, -1.0]),
                                             bp, E.tolist(), A, mu)
        u2 = 1e-5 * np.random.default_rng(2).standard_normal(X2.shape)
        ref = {(a, b, c): (ml, FE.val(u2 / h, np.zeros(len(X2)), [[a, b, c, ml, n, r]], h,
                                         np.array([0.0, 1.0])))
               for a, b, c, ml, n, r in self_pairs}
    finally:
        for name in [n for n, m in sys.modules.items()
                     if str(folder) in (getattr(m, "__file__", None) or "")]:
            del sys.modules[name]
    X = np.zeros((len(X2), 3))
    X[:, :2] = X2
    u = np.zeros_like(X)
    u[:, :2] = u2
    pe = brute_force_point_edge_pairs(X, E, dhat)
    types, _ = pe_classify_and_distance(X, pe)
    keep, verts, coeffs, basis, lam = KF.lag_point_edge_pairs(X, pe, A[pe[:, 0]] * dhat / 16.0,
                                                              dhat * dhat, kappa, BARRIER_LECTURE)
    assert keep.sum() == len(ref) >= 3
    eps = FE.epsv * h
    assert np.sum(keep & (types == PE_P_E)) >= 2
    for i in np.flatnonzero(keep):
        ml, value = ref[tuple(int(v) for v in pe[i])]
        assert mu * lam[i] == pytest.approx(ml, rel=1e-12)
        if types[i] == PE_P_E:  # the lecture's closest point is ours over the edge's inside
            ours = KF.friction_value(u, verts[i:i + 1], coeffs[i:i + 1], basis[i:i + 1],
                                     np.array([mu * lam[i]]), eps)
            assert ours == pytest.approx(value, rel=1e-10)
