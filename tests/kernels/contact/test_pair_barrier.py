"""Batched contact barrier (kernels/contact/pair_barrier.py) and project_psd (kernels/algebra/linalg.py).

The two-body test builds two tetrahedralised unit cubes a small gap apart (the top one
shifted and rotated about z), takes ipctk's collision mesh of their boundary, builds the
candidate pairs by brute force (every surface vertex-triangle and edge-edge pair that
shares no vertex, kept when their bounding boxes inflated by d̂/2 overlap), and compares
ipcsim's value, gradient and PSD-clamped Hessian with ipctk's BarrierPotential on
NormalCollisions built at the same positions (default IPC set, no area weighting).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp

from ipcsim.kernels.contact import pair_barrier as CB
from ipcsim.kernels.contact import distance as D
from ipcsim.kernels.algebra import linalg as LA
from ipcsim.kernels.contact import mollifier as M
from ipcsim.kernels.contact.barrier import BARRIER_IPC as IPC
from two_bodies import SCENES, boundary_faces, ipctk_scene, surface_edges, two_cubes


@pytest.fixture(scope="module")
def ipctk():
    return pytest.importorskip("ipctk")


# =========================================================================================
# Meshes and brute-force candidates (numpy)
# =========================================================================================









def brute_force_candidates(X, E, F, inflation):
    """PT pairs (v, f0, f1, f2) and EE pairs (ea0, ea1, eb0, eb1) whose AABBs, inflated by
    ``inflation``, overlap; pairs sharing a vertex are excluded. Also returns the EE pairs'
    edge indices (for comparing with ipctk's candidates)."""
    verts = np.unique(F)

    def boxes(idx):
        P = X[idx]
        return P.min(1) - inflation, P.max(1) + inflation

    def overlap(lo1, hi1, lo2, hi2):
        return np.all((lo1[:, None] <= hi2[None]) & (lo2[None] <= hi1[:, None]), axis=2)

    vlo, vhi = boxes(verts[:, None])
    flo, fhi = boxes(F)
    vi, fi = np.nonzero(overlap(vlo, vhi, flo, fhi))
    keep = np.all(F[fi] != verts[vi, None], axis=1)
    pt = np.column_stack([verts[vi[keep]], F[fi[keep]]])

    elo, ehi = boxes(E)
    ea, eb = np.nonzero(np.triu(overlap(elo, ehi, elo, ehi), 1))
    keep = ~np.any(E[ea][:, :, None] == E[eb][:, None, :], axis=(1, 2))
    ea, eb = ea[keep], eb[keep]
    ee = np.column_stack([E[ea], E[eb]])
    return (np.ascontiguousarray(pt, dtype=np.int64), np.ascontiguousarray(ee, dtype=np.int64),
            np.column_stack([ea, eb]))


def scene(ipctk, name):
    mesh, X, p = ipctk_scene(ipctk, name)
    Ec = np.asarray(mesh.edges, dtype=np.int64)
    Fc = np.asarray(mesh.faces, dtype=np.int64)
    pt, ee, ee_edges = brute_force_candidates(X, Ec, Fc, 0.5 * p["dhat"])
    eps_x = M.edge_edge_mollifier_thresholds(np.ascontiguousarray(mesh.rest_positions), ee)
    return mesh, X, pt, ee, ee_edges, eps_x, p["dhat"], p["kappa"]


def ipctk_barrier(ipctk, mesh, X, dhat, kappa):
    C = ipctk.NormalCollisions()
    C.use_area_weighting = False
    C.collision_set_type = ipctk.NormalCollisions.CollisionSetType.IPC
    Xf = np.asfortranarray(X)
    C.build(mesh, Xf, dhat)
    Bp = ipctk.BarrierPotential(dhat, kappa)
    return dict(
        collisions=C,
        value=Bp(C, mesh, Xf),
        grad=np.asarray(Bp.gradient(C, mesh, Xf)).ravel(),
        hess_clamp=Bp.hessian(C, mesh, Xf, ipctk.PSDProjectionMethod.CLAMP).toarray(),
        hess=Bp.hessian(C, mesh, Xf, ipctk.PSDProjectionMethod.NONE).toarray(),
    )


def assemble(rows, cols, vals, n):
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n)).toarray()


# =========================================================================================
# Two bodies against ipctk
# =========================================================================================

@pytest.mark.parametrize("name", list(SCENES))
def test_two_body_barrier_matches_ipctk(ipctk, name):
    mesh, X, pt, ee, ee_edges, eps_x, dhat, kappa = scene(ipctk, name)
    s_hat = dhat * dhat
    ref = ipctk_barrier(ipctk, mesh, X, dhat, kappa)
    C = ref["collisions"]

    # active pairs: count = Σ ipctk weights (its merged set counts each candidate once)
    pt_t, pt_d2, ee_t, ee_d2 = CB.classify_and_distance(X, pt, ee)
    n_active = int((pt_d2 < s_hat).sum() + (ee_d2 < s_hat).sum())
    weights = sum(c.weight for lst in (C.vv_collisions, C.ev_collisions, C.ee_collisions,
                                       C.fv_collisions) for c in lst)
    assert n_active == round(weights) and n_active > 50
    # ... and the very same pairs as ipctk's broad-phase candidates filtered by distance
    cands = ipctk.Candidates()
    cands.build(mesh, np.asfortranarray(X), 0.5 * dhat)
    E, F = mesh.edges, mesh.faces
    ref_pt = {tuple(int(v) for v in c.vertex_ids(E, F)) for c in cands.fv_candidates
              if ipctk.point_triangle_distance(*X[list(c.vertex_ids(E, F))]) < s_hat}
    ref_ee = {tuple(sorted((c.edge0_id, c.edge1_id))) for c in cands.ee_candidates
              if ipctk.edge_edge_distance(*X[list(c.vertex_ids(E, F))]) < s_hat}
    assert {tuple(p) for p in pt[pt_d2 < s_hat]} == ref_pt
    assert {tuple(sorted(e)) for e in ee_edges[ee_d2 < s_hat]} == ref_ee
    if name == "aligned":  # the scene is there to exercise the mollifier
        c = np.array([M.edge_edge_cross_sq(*X[p]) for p in ee[ee_d2 < s_hat]])
        assert np.sum(c < eps_x[ee_d2 < s_hat]) > 20

    value = CB.barrier_value(X, pt, ee, eps_x, s_hat, kappa)
    grad = CB.barrier_gradient(X, pt, ee, eps_x, s_hat, kappa)
    n = X.size
    H = assemble(*CB.barrier_hessian_triplets(X, pt, ee, eps_x, s_hat, kappa, True), n)
    H_raw = assemble(*CB.barrier_hessian_triplets(X, pt, ee, eps_x, s_hat, kappa, False), n)

    def rel(a, b):
        return np.abs(a - b).max() / np.abs(b).max()

    print(f"  {name}: {n_active} active pairs, relative errors: value "
          f"{abs(value - ref['value']) / ref['value']:.1e}, gradient {rel(grad, ref['grad']):.1e},"
          f" Hessian (clamped) {rel(H, ref['hess_clamp']):.1e}, raw {rel(H_raw, ref['hess']):.1e}")
    assert value == pytest.approx(ref["value"], rel=1e-9, abs=0.0)
    assert rel(grad, ref["grad"]) <= 1e-9
    assert rel(H, ref["hess_clamp"]) <= 1e-9
    assert rel(H_raw, ref["hess"]) <= 1e-9
    assert np.linalg.eigvalsh(H).min() >= -1e-9 * np.abs(H).max()
    assert np.linalg.eigvalsh(H_raw).min() < -1e-6 * np.abs(H_raw).max()  # clamp did work


def test_classification_matches_ipctk_types(ipctk):
    """Types agree with ipctk's, except on exact ties, where both types give the same
    distance. (The mesh has exactly parallel edges; ipctk's binary rounds the parallel
    rule's projections differently, apparently with fused multiply-adds.)"""
    mesh, X, pt, ee, _, _, dhat, _ = scene(ipctk, "rotated")
    pt_t, pt_d2, ee_t, ee_d2 = CB.classify_and_distance(X, pt, ee)
    ties = 0
    for k in range(len(pt)):
        a = X[pt[k]]
        assert pt_d2[k] == pytest.approx(ipctk.point_triangle_distance(*a), rel=1e-12)
        t_ref = int(ipctk.point_triangle_distance_type(*a))
        if pt_t[k] != t_ref:
            ties += 1
            assert pt_d2[k] == pytest.approx(D.point_triangle_distance_sq(*a, t_ref), rel=1e-12)
    for k in range(len(ee)):
        a = X[ee[k]]
        assert ee_d2[k] == pytest.approx(ipctk.edge_edge_distance(*a), rel=1e-12)
        t_ref = int(ipctk.edge_edge_distance_type(*a))
        if ee_t[k] != t_ref:
            ties += 1
            assert ee_d2[k] == pytest.approx(D.edge_edge_distance_sq(*a, t_ref), rel=1e-12)
    assert ties <= 0.02 * (len(pt) + len(ee)), ties


# =========================================================================================
# Without ipctk: finite differences, layout, per-pair functions
# =========================================================================================

def numpy_scene(name, jitter=1e-3, seed=0):
    """The same two-body scene without ipctk (full-mesh indices), jittered off exact ties."""
    p = SCENES[name]
    V, T = two_cubes(p["n"], p["gap"], p["shift"], p["angle_deg"])
    F = boundary_faces(T).astype(np.int64)
    E = surface_edges(F)
    X = V + jitter * np.random.default_rng(seed).standard_normal(V.shape)
    pt, ee, _ = brute_force_candidates(X, E, F, 0.5 * p["dhat"])
    eps_x = M.edge_edge_mollifier_thresholds(V, ee)  # rest = unjittered
    return np.ascontiguousarray(X), pt, ee, eps_x, p["dhat"] ** 2, p["kappa"]


@pytest.mark.parametrize("name", list(SCENES))
def test_batched_derivatives_finite_differences(name):
    X, pt, ee, eps_x, s_hat, kappa = numpy_scene(name)
    g = CB.barrier_gradient(X, pt, ee, eps_x, s_hat, kappa)
    H = assemble(*CB.barrier_hessian_triplets(X, pt, ee, eps_x, s_hat, kappa, False), X.size)
    rng = np.random.default_rng(1)
    dofs = rng.choice(np.flatnonzero(g), 12, replace=False)
    h = 1e-7
    for k in dofs:
        Xp, Xm = X.copy(), X.copy()
        Xp.flat[k] += h
        Xm.flat[k] -= h
        fd = (CB.barrier_value(Xp, pt, ee, eps_x, s_hat, kappa)
              - CB.barrier_value(Xm, pt, ee, eps_x, s_hat, kappa)) / (2 * h)
        assert fd == pytest.approx(g[k], rel=1e-5, abs=1e-6 * np.abs(g).max())
        col = (CB.barrier_gradient(Xp, pt, ee, eps_x, s_hat, kappa)
               - CB.barrier_gradient(Xm, pt, ee, eps_x, s_hat, kappa)) / (2 * h)
        assert np.abs(col - H[:, k]).max() <= 1e-5 * np.abs(H[:, k]).max()


def _pair_fd(f, g, V, h=1e-7):
    out = np.empty((12,) + np.shape(g(V)))
    for k in range(12):
        Vp, Vm = V.copy(), V.copy()
        Vp.flat[k] += h
        Vm.flat[k] -= h
        out[k] = (f(Vp) - f(Vm)) / (2 * h)
    return out


def test_pair_barrier_product_rule_finite_differences():
    """Per-pair κ b and κ m b with the full mollifier product rule, every distance type."""
    rng = np.random.default_rng(2)
    s_hat, kappa = 0.04, 10.0
    seen_pt, seen_ee, seen_moll = set(), set(), 0
    for _ in range(4000):
        V = rng.standard_normal((4, 3)) * 0.1
        if rng.random() < 0.5:  # nearly parallel edges, often mollified
            u = V[1] - V[0]
            V[3] = V[2] + u * rng.uniform(0.5, 1.5) + 0.02 * np.linalg.norm(
                u) * rng.standard_normal(3)
        t = int(D.point_triangle_distance_type(*V))
        d = D.point_triangle_distance_sq(*V, t)
        if 0.2 * s_hat < d < 0.9 * s_hat and len(seen_pt) < 7 and t not in seen_pt:
            seen_pt.add(t)
            f = lambda W: CB.stencil_barrier(W, D.PT_FEATURES[t], s_hat, kappa, IPC)
            g = lambda W: CB.stencil_barrier_gradient(W, D.PT_FEATURES[t], s_hat, kappa, IPC)
            Hf = lambda W: CB.stencil_barrier_hessian(W, D.PT_FEATURES[t], s_hat, kappa, IPC)
            assert np.allclose(_pair_fd(f, lambda W: 0.0, V), g(V), rtol=1e-5,
                               atol=1e-6 * np.abs(g(V)).max())
            assert np.allclose(_pair_fd(g, g, V), Hf(V), rtol=1e-5,
                               atol=1e-6 * np.abs(Hf(V)).max())
        t = int(D.edge_edge_distance_type(*V))
        d = D.edge_edge_distance_sq(*V, t)
        eps_x = M.edge_edge_mollifier_threshold(*V)
        c = M.edge_edge_cross_sq(*V)
        moll = 0.05 * eps_x < c < 0.95 * eps_x
        if 0.2 * s_hat < d < 0.9 * s_hat and (
                (moll and seen_moll < 10) or (c > 1.05 * eps_x and t not in seen_ee)):
            seen_ee.add(t)
            seen_moll += moll
            f = lambda W: CB.edge_edge_barrier(W, t, eps_x, s_hat, kappa)
            g = lambda W: CB.edge_edge_barrier_gradient(W, t, eps_x, s_hat, kappa)
            Hf = lambda W: CB.edge_edge_barrier_hessian(W, t, eps_x, s_hat, kappa)
            assert np.allclose(_pair_fd(f, lambda W: 0.0, V), g(V), rtol=1e-5,
                               atol=1e-6 * np.abs(g(V)).max())
            assert np.allclose(_pair_fd(g, g, V), Hf(V), rtol=1e-5,
                               atol=1e-6 * np.abs(Hf(V)).max())
        if len(seen_pt) == 7 and seen_moll >= 10 and len(seen_ee) >= 6:
            break
    assert len(seen_pt) == 7 and seen_moll >= 10 and len(seen_ee) >= 6, (
        seen_pt, seen_ee, seen_moll)


def test_hessian_triplet_layout_and_inactive_pairs():
    X, pt, ee, eps_x, s_hat, kappa = numpy_scene("rotated")
    _, pt_d2, _, ee_d2 = CB.classify_and_distance(X, pt, ee)
    pt_act, ee_act = np.flatnonzero(pt_d2 < s_hat), np.flatnonzero(ee_d2 < s_hat)
    assert len(pt_act) < len(pt) and len(ee_act) < len(ee)  # inactive pairs exist
    rows, cols, vals = CB.barrier_hessian_triplets(X, pt, ee, eps_x, s_hat, kappa, True)
    assert rows.dtype == np.int32 and cols.dtype == np.int32  # 16 bytes a triplet
    assert len(vals) == 144 * (len(pt_act) + len(ee_act))
    pairs = np.concatenate([pt[pt_act], ee[ee_act]])
    for a in (0, len(pt_act) - 1, len(pt_act), len(pairs) - 1):
        sl = slice(144 * a, 144 * (a + 1))
        dof = (3 * pairs[a][:, None] + np.arange(3)).ravel()
        assert np.array_equal(rows[sl], np.repeat(dof, 12))
        assert np.array_equal(cols[sl], np.tile(dof, 12))
        V = np.ascontiguousarray(X[pairs[a]])
        if a < len(pt_act):
            Hl = CB.stencil_barrier_hessian(V, D.PT_FEATURES[D.point_triangle_distance_type(*V)],
                                            s_hat, kappa, IPC)
        else:
            Hl = CB.edge_edge_barrier_hessian(V, D.edge_edge_distance_type(*V),
                                              eps_x[ee_act[a - len(pt_act)]], s_hat, kappa)
        assert np.allclose(vals[sl].reshape(12, 12), LA.project_psd(Hl), rtol=0,
                           atol=1e-12 * np.abs(Hl).max())
    # value and gradient are sums over the active pairs only
    v_act = CB.barrier_value(X, pt[pt_act], ee[ee_act], eps_x[ee_act], s_hat, kappa)
    assert CB.barrier_value(X, pt, ee, eps_x, s_hat, kappa) == pytest.approx(v_act, rel=1e-13)
    assert np.allclose(CB.barrier_gradient(X, pt, ee, eps_x, s_hat, kappa),
                       CB.barrier_gradient(X, pt[pt_act], ee[ee_act], eps_x[ee_act], s_hat,
                                           kappa), rtol=1e-13, atol=0)


def test_empty_candidate_lists():
    X = np.random.default_rng(0).standard_normal((5, 3))
    none = np.zeros((0, 4), dtype=np.int64)
    eps = np.zeros(0)
    t1, d1, t2, d2 = CB.classify_and_distance(X, none, none)
    assert len(t1) == len(d1) == len(t2) == len(d2) == 0
    assert CB.barrier_value(X, none, none, eps, 1.0, 1.0) == 0.0
    assert np.array_equal(CB.barrier_gradient(X, none, none, eps, 1.0, 1.0), np.zeros(15))
    r, c, v = CB.barrier_hessian_triplets(X, none, none, eps, 1.0, 1.0, True)
    assert len(r) == len(c) == len(v) == 0


def test_contact_and_degenerate_pairs_give_ieee_values_not_exceptions():
    # a vertex exactly on a triangle (d² = 0): the barrier is +inf, as b(0) is
    X = np.array([[0.2, 0.2, 0.0], [0, 0, 0], [1, 0, 0], [0, 1, 0],
                  [5, 6, 5], [5, 6, 5], [6, 5, 5], [7, 5, 5]], dtype=float)
    pt = np.array([[0, 1, 2, 3]], dtype=np.int64)
    none = np.zeros((0, 4), dtype=np.int64)
    assert CB.barrier_value(X, pt, none, np.zeros(0), 0.01, 1.0) == np.inf
    assert not np.all(np.isfinite(CB.barrier_gradient(X, pt, none, np.zeros(0), 0.01, 1.0)))
    # a zero-area triangle (three coincident vertices) and a zero-length edge: no exception
    pt = np.array([[6, 4, 5, 4]], dtype=np.int64)
    ee = np.array([[4, 5, 6, 7]], dtype=np.int64)
    t1, d1, t2, d2 = CB.classify_and_distance(X, pt, ee)
    assert d2[0] == pytest.approx(1.0)  # ea0 = ea1: EA0_EB, the point vs line b (ipctk)
    assert t2[0] == D.EE_EA0_EB
    CB.barrier_gradient(X, pt, ee, np.ones(1), 2.0, 1.0)


# =========================================================================================
# project_psd
# =========================================================================================

def test_project_psd():
    rng = np.random.default_rng(3)
    for n in (6, 9, 12):
        for _ in range(20):
            A = rng.standard_normal((n, n))
            A = A + A.T
            P = LA.project_psd(A)
            w, Q = np.linalg.eigh(A)
            assert np.allclose(P, (Q * np.maximum(w, 0.0)) @ Q.T, atol=1e-12 * np.abs(A).max())
            assert np.array_equal(P, P.T)
            assert np.linalg.eigvalsh(P).min() >= -1e-12 * np.abs(A).max()
            assert np.allclose(LA.project_psd(P), P, atol=1e-12 * np.abs(A).max())
            S = A @ A.T  # already PSD: returned unchanged
            assert np.array_equal(LA.project_psd(S), S)


def _symmetric_test_matrices(rng):
    yield np.zeros((12, 12))
    yield np.eye(12)
    yield np.diag(np.arange(12.0) - 5.0)
    yield -2.0 * np.ones((1, 1))
    for n in (2, 3, 6, 9, 12):
        for _ in range(30):
            A = rng.standard_normal((n, n))
            yield A + A.T
            L = rng.standard_normal((n, 2))
            yield L @ np.diag([3.0, -1.0]) @ L.T  # rank 2, indefinite
            g = rng.standard_normal(n)
            yield 1e8 * np.outer(g, g) + 1e-3 * (A + A.T)  # a barrier's stiff rank one
            B = np.zeros((n, n))
            B[: n // 2, : n // 2] = (A + A.T)[: n // 2, : n // 2]
            yield B  # a block of zeros, as a feature's stencil leaves
            Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
            yield (Q * rng.choice([1.0, 2.0, -1.0], n)) @ Q.T  # repeated eigenvalues


def test_symmetric_eigen_decomposes_to_round_off():
    """A = V diag(w) Vᵀ with orthonormal V, and the eigenvalues LAPACK finds, on random,
    low-rank, stiff, block-zero and repeated-eigenvalue matrices."""
    rng = np.random.default_rng(11)
    for A in _symmetric_test_matrices(rng):
        n = A.shape[0]
        w, V = np.empty(n), np.empty((n, n))
        LA.symmetric_eigen(A, w, V)
        scale = max(np.abs(A).max(), 1.0)
        assert np.abs((V * w) @ V.T - A).max() <= 1e-13 * scale
        assert np.abs(V.T @ V - np.eye(n)).max() <= 1e-13
        assert np.abs(np.sort(w) - np.linalg.eigvalsh(A)).max() <= 1e-13 * scale


def test_hypot_within_two_ulps_of_libm():
    rng = np.random.default_rng(13)
    exponents = rng.uniform(-320, 308, (2000, 2))
    signs = rng.choice([-1.0, 1.0], (2000, 2))
    pairs = [tuple(v) for v in signs * 10.0 ** exponents]
    pairs += [(0.0, 0.0), (0.0, -3.0), (3.0, 4.0), (1e308, 1e308), (5e-324, 5e-324),
              (1e-160, 1e-160), (1e160, 1.0)]
    for a, b in pairs:
        exact = math.hypot(a, b)
        assert abs(LA.hypot(a, b) - exact) <= 2 * math.ulp(exact), (a, b)
    assert LA.hypot(np.inf, 1.0) == LA.hypot(1.0, -np.inf) == np.inf
    assert np.isnan(LA.hypot(np.nan, 1.0))


def test_symmetric_eigen_ends_on_a_nan():
    A = np.eye(12)
    A[3, 5] = A[5, 3] = np.nan
    w, V = np.empty(12), np.empty((12, 12))
    LA.symmetric_eigen(A, w, V)
    assert np.isnan(w).any()
