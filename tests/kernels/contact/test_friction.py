"""Lagged friction (kernels/contact/friction.py, potentials/friction.py).

* finite differences of the gradient and the (unprojected) Hessian on random lagged data
  with |Pᵀr| below, above and exactly at ε;
* the projected Hessian is PSD and equals the unprojected one where that is PSD;
* ipctk oracle: two tetrahedralised cubes a small gap apart; NormalCollisions and
  TangentialCollisions built at X_lag, FrictionPotential(ε) evaluated at V = u = X − X_lag,
  against ipcsim's friction over the brute-force PT/EE candidate pairs;
* linear momentum: mesh–mesh friction forces sum to zero;
* vertex–plane friction against a hand computation.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from ipcsim.kernels.contact import barrier as KB
from ipcsim.kernels.contact.pair_barrier import classify_and_distance
from ipcsim.kernels.contact import friction as KF
from ipcsim.kernels.contact import mollifier as M
from ipcsim.contact.collisions import Collisions
from ipcsim.contact.friction_lag import lag_friction
from ipcsim.contact.planes import Planes
from ipcsim.potentials.base import StepContext
from ipcsim.potentials.friction import Friction as FrictionTerm


class Friction:
    """The friction term with its lagged data, as one Newton solve sees it: ``lag``
    freezes the data (``contact.friction_lag``), value/gradient/hessian evaluate the term
    in a step context that holds it."""

    def __init__(self, eps):
        self.term = FrictionTerm(eps)
        self.constant_pattern = self.term.constant_pattern
        self.ctx = StepContext()

    def lag(self, x_lag, pt, ee, eps_x, plane_vertices, origins, normals, plane_mu, mu_mesh,
            kappa, dhat):
        planes = Planes(plane_vertices, origins, normals, plane_mu)
        self.ctx = StepContext(friction=lag_friction(
            x_lag, x_lag, Collisions(pt, ee, np.asarray(eps_x, float)), planes, mu_mesh, kappa,
            dhat))

    def __getattr__(self, name):  # count, verts, coeffs, basis of the lagged data
        return getattr(self.ctx.friction, name)

    @property
    def count(self):
        return 0 if self.ctx.friction is None else self.ctx.friction.count

    def value(self, x):
        return self.term.value(x, self.ctx)

    def gradient(self, x):
        return self.term.gradient(x, self.ctx)

    def hessian(self, x):
        return self.term.hessian(x, self.ctx)
from two_bodies import SCENES, boundary_faces, ipctk_scene, two_cubes


# =========================================================================================
# Helpers
# =========================================================================================

def assemble(rows, cols, vals, n):
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n)).toarray()


def random_lagged(rng, n_vertices, n_pairs):
    """Random lagged data: stencils of 1–4 distinct vertices, c_0 = 1 and the rest summing
    to −1 (a relative displacement), random orthonormal P, positive weights."""
    verts = np.full((n_pairs, 4), -1, dtype=np.int64)
    coeffs = np.zeros((n_pairs, 4))
    basis = np.empty((n_pairs, 3, 2))
    for k in range(n_pairs):
        nv = 1 + k % 4
        verts[k, :nv] = rng.choice(n_vertices, nv, replace=False)
        coeffs[k, 0] = 1.0
        if nv > 1:
            b = rng.random(nv - 1)
            coeffs[k, 1:nv] = -b / b.sum()
        Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        basis[k] = Q[:, :2]
    weight = rng.uniform(0.5, 2.0, n_pairs)
    return verts, coeffs, basis, weight


def tangential_norms(u, verts, coeffs, basis):
    r = np.einsum("kv,kva->ka", coeffs, np.where(verts[..., None] >= 0, u[verts], 0.0))
    return np.linalg.norm(np.einsum("kap,ka->kp", basis, r), axis=1)


def fd_check(u, data, eps, h=1e-7):
    """Max relative errors of the gradient vs FD of the value, and of the unprojected
    Hessian vs FD of the gradient."""
    verts, coeffs, basis, weight = data
    u0 = u.ravel().copy()

    def val(z):
        return KF.friction_value(z.reshape(-1, 3), verts, coeffs, basis, weight, eps)

    def grad(z):
        return KF.friction_gradient(z.reshape(-1, 3), verts, coeffs, basis, weight, eps)

    g = grad(u0)
    off = KF.triplet_offsets(verts)
    H = assemble(*KF.friction_hessian_triplets(u, verts, coeffs, basis, weight, eps,
                                               False, off), u0.size)
    gfd = np.empty_like(u0)
    Hfd = np.empty((u0.size, u0.size))
    for i in range(u0.size):
        zp = u0.copy()
        zm = u0.copy()
        zp[i] += h
        zm[i] -= h
        gfd[i] = (val(zp) - val(zm)) / (2 * h)
        Hfd[:, i] = (grad(zp) - grad(zm)) / (2 * h)
    return (np.abs(g - gfd).max() / np.abs(g).max(),
            np.abs(H - Hfd).max() / np.abs(H).max(), H)


# =========================================================================================
# f0 and its derivatives
# =========================================================================================

def test_f0_smoothing_is_c2_at_eps():
    eps = 0.3
    for y in (0.0, 0.1, 0.29, 0.3, 0.5):
        f = KF.f0(y, eps)
        expect = (-y ** 3 / (3 * eps ** 2) + y ** 2 / eps + eps / 3) if y < eps else y
        assert f == pytest.approx(expect, rel=1e-14)
    assert KF.f0(0.0, eps) == pytest.approx(eps / 3)
    # f1 (= y f1/y) and f1' continuous across ε
    lo, hi = np.nextafter(eps, 0.0), eps
    assert lo * KF.f1_over_y(lo, eps) == pytest.approx(hi * KF.f1_over_y(hi, eps), rel=1e-12)
    assert KF.f1_prime(lo, eps) == pytest.approx(0.0, abs=1e-12)
    assert KF.f1_over_y(0.0, eps) == pytest.approx(2.0 / eps)
    # f1 = f0' by finite differences on both sides
    for y in (0.05, 0.2, 0.45):
        h = 1e-6
        assert y * KF.f1_over_y(y, eps) == pytest.approx(
            (KF.f0(y + h, eps) - KF.f0(y - h, eps)) / (2 * h), rel=1e-8)


# =========================================================================================
# Finite differences and PSD on random lagged data
# =========================================================================================

@pytest.mark.parametrize("scale", [0.2, 1.0, 5.0])
def test_gradient_and_hessian_match_finite_differences(scale):
    rng = np.random.default_rng(7)
    n, m, eps = 9, 16, 0.1
    data = random_lagged(rng, n, m)
    u = scale * eps * rng.standard_normal((n, 3))
    y = tangential_norms(u, *data[:3])
    if scale == 1.0:  # both regimes present
        assert np.any(y < eps) and np.any(y > eps)
    eg, eh, _ = fd_check(u, data, eps)
    assert eg < 1e-6
    assert eh < 1e-6


def test_finite_differences_exactly_at_eps_and_at_zero():
    eps = 0.05
    # one vertex–plane-like stencil with P = (e_x, e_y): τ = (u_x, u_y)
    verts = np.array([[0, -1, -1, -1], [1, 2, -1, -1]], dtype=np.int64)
    coeffs = np.array([[1.0, 0, 0, 0], [1.0, -1.0, 0, 0]])
    basis = np.zeros((2, 3, 2))
    basis[:, 0, 0] = 1.0
    basis[:, 1, 1] = 1.0
    weight = np.array([1.3, 0.7])
    u = np.zeros((3, 3))
    u[0] = [eps, 0.0, 0.4]            # y = ε exactly
    u[1] = [0.6 * eps, 0.8 * eps, 0.0]
    u[2] = [0.0, 0.0, 0.0]            # y = |(0.6, 0.8) ε| = ε (up to rounding)
    data = (verts, coeffs, basis, weight)
    y = tangential_norms(u, verts, coeffs, basis)
    assert y[0] == eps and y[1] == pytest.approx(eps, rel=1e-15)
    eg, eh, _ = fd_check(u, data, eps, h=1e-8)
    assert eg < 1e-6 and eh < 1e-5
    # y = 0: zero force, Hessian (2/ε) w c_i c_j P Pᵀ
    z = np.zeros((3, 3))
    assert np.all(KF.friction_gradient(z, *data, eps) == 0.0)
    H = assemble(*KF.friction_hessian_triplets(z, *data, eps, True,
                                               KF.triplet_offsets(verts)), 9)
    assert H[0, 0] == pytest.approx(2.0 / eps * 1.3) and H[2, 2] == 0.0
    assert np.isfinite(H).all()


def test_projected_hessian_is_psd_and_agrees():
    rng = np.random.default_rng(3)
    n, m, eps = 12, 40, 0.1
    data = random_lagged(rng, n, m)
    off = KF.triplet_offsets(data[0])
    for scale in (0.05, 0.5, 1.0, 3.0):
        u = scale * eps * rng.standard_normal((n, 3))
        Hp = assemble(*KF.friction_hessian_triplets(u, *data, eps, True, off), 3 * n)
        Hr = assemble(*KF.friction_hessian_triplets(u, *data, eps, False, off), 3 * n)
        assert np.abs(Hp - Hp.T).max() <= 1e-12 * np.abs(Hp).max()
        assert np.linalg.eigvalsh(Hp).min() >= -1e-12 * np.abs(Hp).max()
        # analytically M is PSD already (eigenvalues f1/y ≥ 0, f1' ≥ 0): the same matrix
        assert np.abs(Hp - Hr).max() <= 1e-10 * np.abs(Hr).max()


# =========================================================================================
# Two bodies: ipctk oracle and momentum
# =========================================================================================







def brute_force_pairs(X, E, F, dhat):
    """All surface vertex–triangle and edge–edge pairs sharing no vertex (the distance
    filter d² < d̂² is the lagging kernel's)."""
    verts = np.unique(F)
    vi, fi = np.meshgrid(np.arange(len(verts)), np.arange(len(F)), indexing="ij")
    vi, fi = vi.ravel(), fi.ravel()
    keep = np.all(F[fi] != verts[vi, None], axis=1)
    pt = np.column_stack([verts[vi[keep]], F[fi[keep]]])
    ea, eb = np.triu_indices(len(E), 1)
    keep = ~np.any(E[ea][:, :, None] == E[eb][:, None, :], axis=(1, 2))
    ee = np.column_stack([E[ea[keep]], E[eb[keep]]])
    # cheap prefilter (AABB within d̂) so the kernels see a few thousand pairs
    def close(a, b):
        lo_a, hi_a = X[a].min(1), X[a].max(1)
        lo_b, hi_b = X[b].min(1), X[b].max(1)
        return np.all((lo_a <= hi_b + dhat) & (lo_b <= hi_a + dhat), axis=1)
    pt = pt[close(pt[:, :1], pt[:, 1:])]
    ee = ee[close(ee[:, :2], ee[:, 2:])]
    return np.ascontiguousarray(pt, np.int64), np.ascontiguousarray(ee, np.int64)


def scene(ipctk, name):
    mesh, X, p = ipctk_scene(ipctk, name)
    pt, ee = brute_force_pairs(X, np.asarray(mesh.edges, np.int64),
                               np.asarray(mesh.faces, np.int64), p["dhat"])
    eps_x = M.edge_edge_mollifier_thresholds(np.ascontiguousarray(mesh.rest_positions), ee)
    return mesh, X, pt, ee, eps_x, p["dhat"], p["kappa"]


def sliding_displacement(rng, X, eps):
    """Top cube slides in x, bottom cube a little the other way, plus noise: pairs land
    on both sides of ε."""
    u = np.zeros_like(X)
    top = X[:, 2] > 1.0
    u[top, 0] = 0.8 * eps
    u[top, 1] = 0.3 * eps
    u[~top, 0] = -0.4 * eps
    return u + 0.7 * eps * rng.standard_normal(X.shape)


@pytest.fixture(scope="module")
def ipctk():
    return pytest.importorskip("ipctk")


@pytest.mark.parametrize("name", list(SCENES))
def test_two_body_friction_matches_ipctk(ipctk, name):
    mesh, X, pt, ee, eps_x, dhat, kappa = scene(ipctk, name)
    mu, eps = 0.35, 2e-3
    rng = np.random.default_rng(11)
    u = sliding_displacement(rng, X, eps)

    # ipctk: normal collisions and lagged tangential collisions at X_lag, evaluated at V = u
    Xf = np.asfortranarray(X)
    C = ipctk.NormalCollisions()
    C.use_area_weighting = False
    C.collision_set_type = ipctk.NormalCollisions.CollisionSetType.IPC
    C.build(mesh, Xf, dhat)
    TC = ipctk.TangentialCollisions()
    TC.build(mesh, Xf, C, ipctk.BarrierPotential(dhat, kappa), mu)
    Dp = ipctk.FrictionPotential(eps)
    Uf = np.asfortranarray(u)
    ref_val = Dp(TC, mesh, Uf)
    ref_grad = np.asarray(Dp.gradient(TC, mesh, Uf)).ravel()
    ref_hess = Dp.hessian(TC, mesh, Uf, ipctk.PSDProjectionMethod.CLAMP).toarray()

    fr = Friction(eps)
    fr.lag(X, pt, ee, eps_x, np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)),
           np.zeros(0), mu, kappa, dhat)
    x = X + u
    val, grad = fr.value(x), fr.gradient(x)
    H = fr.hessian(x).tocsr(X.size).toarray()

    weights = sum(c.weight for lst in (TC.vv_collisions, TC.ev_collisions, TC.ee_collisions,
                                       TC.fv_collisions) for c in lst)
    assert fr.count == round(weights) and fr.count > 50
    y = tangential_norms(u, fr.verts, fr.coeffs, fr.basis)
    assert np.any(y < eps) and np.any(y > eps)

    def rel(a, b):
        return np.abs(a - b).max() / np.abs(b).max()

    print(f"  {name}: {fr.count} frictional pairs, relative errors: value "
          f"{abs(val - ref_val) / ref_val:.1e}, gradient {rel(grad, ref_grad):.1e}, "
          f"Hessian (clamped) {rel(H, ref_hess):.1e}")
    assert val == pytest.approx(ref_val, rel=1e-9, abs=0.0)
    assert rel(grad, ref_grad) <= 1e-9
    assert rel(H, ref_hess) <= 1e-9
    assert np.linalg.eigvalsh(H).min() >= -1e-12 * np.abs(H).max()

    # free two-body system: friction forces are internal, total linear momentum unchanged
    g3 = grad.reshape(-1, 3)
    assert np.abs(g3.sum(0)).max() <= 1e-12 * np.abs(g3).sum()
    top = X[:, 2] > 1.0
    assert np.abs(g3[top].sum(0)).max() > 1e-3 * np.abs(g3).sum()  # net force on a body


def test_two_body_linear_momentum_without_oracle():
    """Free two-body check with numpy-only meshing: Σ over vertices of the mesh friction
    gradient is 0 (every relative-displacement stencil has Σ c_i = 0)."""
    p = SCENES["rotated"]
    X, T = two_cubes(p["n"], p["gap"], p["shift"], p["angle_deg"])
    F = boundary_faces(T)
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), 1),
                  axis=0)
    pt, ee = brute_force_pairs(X, E, F, p["dhat"])
    eps_x = M.edge_edge_mollifier_thresholds(X, ee)
    fr = Friction(1e-3)
    fr.lag(X, pt, ee, eps_x, np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)),
           np.zeros(0), 0.5, p["kappa"], p["dhat"])
    assert fr.count > 50
    np.testing.assert_allclose(fr.coeffs.sum(1), 0.0, atol=1e-12)
    u = sliding_displacement(np.random.default_rng(5), X, 1e-3)
    g3 = fr.gradient(X + u).reshape(-1, 3)
    assert np.abs(g3.sum(0)).max() <= 1e-12 * np.abs(g3).sum()
    top = X[:, 2] > 1.0
    assert np.abs(g3[top].sum(0)).max() > 1e-3 * np.abs(g3).sum()


def test_mollified_edge_pairs_get_no_friction(ipctk):
    mesh, X, pt, ee, eps_x, dhat, kappa = scene(ipctk, "aligned")
    keep, *_ = KF.lag_mesh_pairs(X, np.zeros((0, 4), np.int64), ee, eps_x, dhat ** 2, kappa)
    _, _, _, d2 = classify_and_distance(X, np.zeros((0, 4), np.int64), ee)
    c = np.array([M.edge_edge_cross_sq(*X[p]) for p in ee])
    active = d2 < dhat ** 2
    mollified = active & (c < eps_x)
    assert mollified.sum() > 10
    assert np.array_equal(keep, active & ~mollified)


# =========================================================================================
# Vertex–plane friction and the Friction potential's bookkeeping
# =========================================================================================

def test_plane_friction_by_hand():
    dhat, kappa, eps, mu = 0.1, 50.0, 1e-2, 0.4
    x_lag = np.array([[0.3, 0.04, 0.1],    # 0.04 above the ground: active
                      [0.0, 0.5, 0.0],     # far: inactive
                      [1.0, 0.07, 0.2]])   # 0.07 above: active
    origins = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    normals = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # second plane: x ≤ 5
    verts = np.arange(3, dtype=np.int64)
    u = np.array([[0.003, 0.001, -0.004],  # tangential |(3, −4)| 1e-3 = 5e-3 < ε
                  [0.5, 0.0, 0.0],
                  [0.02, -0.002, 0.0]])    # tangential 0.02 > ε
    fr = Friction(eps)
    empty = np.zeros((0, 4), np.int64)
    fr.lag(x_lag, empty, empty, np.zeros(0), verts, origins, normals,
           np.array([mu, 0.0]), 0.0, kappa, dhat)
    assert fr.count == 2  # μ = 0 plane built not at all; far vertex dropped

    def lam(d):
        return -kappa * KB.barrier_first_derivative(d * d, dhat * dhat) * 2 * d

    def f0(y):
        return -y ** 3 / (3 * eps ** 2) + y ** 2 / eps + eps / 3 if y < eps else y

    expect = mu * lam(0.04) * f0(5e-3) + mu * lam(0.07) * f0(0.02)
    x = x_lag + u
    assert fr.value(x) == pytest.approx(expect, rel=1e-13)
    g = fr.gradient(x).reshape(-1, 3)
    # force opposes the tangential slip; no normal component, nothing on vertex 1
    assert g[2] == pytest.approx(mu * lam(0.07) * np.array([1.0, 0.0, 0.0]), rel=1e-13)
    assert g[0, 1] == 0.0 and np.all(g[1] == 0.0)
    assert g[0] == pytest.approx(mu * lam(0.04) * (2 / eps - 5e-3 / eps ** 2)
                                 * np.array([0.003, 0.0, -0.004]), rel=1e-12)
    # with μ > 0 on the second plane (x ≤ 5), a vertex 0.05 from it joins; its
    # displacement (0.5, 0, 0) is along that plane's normal: no slip, f0(0) = ε/3
    x_lag2 = x_lag.copy()
    x_lag2[1] = [4.95, 0.5, 0.0]
    fr.lag(x_lag2, empty, empty, np.zeros(0), verts, origins, normals,
           np.array([mu, 0.2]), 0.0, kappa, dhat)
    assert fr.count == 3
    x2 = x_lag2 + u
    assert fr.value(x2) == pytest.approx(expect + 0.2 * lam(0.05) * f0(0.0), rel=1e-13)
    H = fr.hessian(x2)
    assert np.linalg.eigvalsh(H.tocsr(9).toarray()).min() >= -1e-12


def test_friction_potential_empty_and_mu_zero():
    fr = Friction(1e-3)
    x = np.random.default_rng(0).standard_normal((4, 3))
    assert fr.count == 0 and fr.value(x) == 0.0
    assert fr.gradient(x).shape == (12,) and len(fr.hessian(x).vals) == 0
    assert fr.constant_pattern is False
    pt = np.array([[0, 1, 2, 3]], np.int64)
    X = np.array([[0.2, 0.2, 0.01], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    fr.lag(X, pt, np.zeros((0, 4), np.int64), np.zeros(0), np.zeros(0, np.int64),
           np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), 0.0, 1.0, 0.1)
    assert fr.count == 0
    fr.lag(X, pt, np.zeros((0, 4), np.int64), np.zeros(0), np.zeros(0, np.int64),
           np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), 0.5, 1.0, 0.1)
    assert fr.count == 1
    # point–triangle interior: r = u_p − Σ β u_t, β = (0.6, 0.2, 0.2); P spans the xy-plane
    u = np.zeros((4, 3))
    u[0] = [0.002, 0.0, 0.5]
    lam = -1.0 * KB.barrier_first_derivative(1e-4, 1e-2) * 2 * 0.01
    assert fr.value(X + u) == pytest.approx(0.5 * lam * 0.002, rel=1e-12)
    u[:] = [0.3, -0.2, 0.1]  # rigid translation: no slip
    assert fr.value(X + u) == pytest.approx(0.5 * lam * 1e-3 / 3, rel=1e-10)


def _ground_pairs(eps, heights):
    """Friction lagged for vertices at the given heights above the ground y = 0."""
    fr = Friction(eps)
    x_lag = np.array([[float(i), h, 0.0] for i, h in enumerate(heights)])
    n = len(heights)
    fr.lag(x_lag, np.zeros((0, 4), np.int64), np.zeros((0, 4), np.int64), np.zeros(0),
           np.arange(n), np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]), np.array([0.5]),
           0.0, 10.0, 0.1)
    assert fr.count == n
    return fr, x_lag


def test_ramp_pairs_that_must_slide_are_resolved_before_newton_stops():
    """Friction.resolved: a pair in the static ramp (slip y < ε) whose linearised friction
    force along p reaches μλ (ρ = f1(y) + f1'(y)·Δy ≥ 1 along τ) blocks convergence while
    p changes its slip by ≥ ramp_resolution·ε; a sticking pair (ρ < 1), a sliding pair,
    a normal motion and a small tangential change do not."""
    eps = 1e-3
    fr, x_lag = _ground_pairs(eps, [0.05])

    def resolved(slip, step, term=fr.term):
        x = x_lag + np.array([[slip, 0.0, 0.0]])
        return term.resolved(x, np.array([step]).reshape(-1), fr.ctx)

    # at y = ε/2: f1 = 3/4, f1' = 1/ε, so ρ = 3/4 + Δy/ε
    assert not resolved(0.5 * eps, [0.3 * eps, 0.0, 0.0])  # ρ = 1.05: must slide
    assert resolved(0.5 * eps, [0.2 * eps, 0.0, 0.0])  # ρ = 0.95: sticks
    assert resolved(0.5 * eps, [-0.3 * eps, 0.0, 0.0])  # ρ = 0.45: held back
    # from rest ρ = 2|Δ|/ε, in any tangential direction
    assert not resolved(0.0, [0.0, 0.0, 0.6 * eps])
    assert resolved(0.0, [0.0, 0.0, 0.4 * eps])
    assert resolved(0.5 * eps, [0.0, 0.3, 0.0])  # along the normal only
    assert resolved(2.0 * eps, [0.5 * eps, 0.0, 0.0])  # sliding: the plain test decides
    # ρ ≥ 1 but the slip changes by less than ramp_resolution·ε
    assert resolved(0.5 * eps, [0.3 * eps, 0.0, 0.0], FrictionTerm(eps, ramp_resolution=0.5))


def test_ramp_resolution_is_a_force_against_the_bodys_friction_capacity():
    """Two equally loaded ground pairs, one of them at y = 0.9 ε pushed on by Δy = 0.15 ε
    (ρ = 0.99 + 0.2·0.15 ≥ 1), the other still: on one body the change is 0.15 of the
    capacity 2μλ·ε, below 0.1·2 = 0.2; if the pairs are two bodies it is 0.15 of its own
    body's μλ·ε, above 0.1."""
    eps = 1e-3
    fr, x_lag = _ground_pairs(eps, [0.05, 0.05])
    x = x_lag + np.array([[0.9 * eps, 0.0, 0.0], [0.0, 0.0, 0.0]])
    p = np.array([0.15 * eps, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert FrictionTerm(eps, body=np.array([0, 0])).resolved(x, p, fr.ctx)
    assert not FrictionTerm(eps, body=np.array([0, 1])).resolved(x, p, fr.ctx)
    assert not FrictionTerm(eps, body=np.array([0, 0])).resolved(x, 2.0 * p, fr.ctx)
