"""Batched point–edge barrier (kernels/contact/point_edge_barrier.py): the contact of 2D
scenes, at z = 0.

Against ipctk's 2D BarrierPotential on NormalCollisions of the boundary edges of two
triangulated squares (tests/two_squares.py), with the candidates found by brute force;
derivatives against finite differences; the lecture's form against the lecture's own
BarrierEnergy (lesson 7) where ../shared/solid-sim-tutorial is there.
"""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from ipcsim.kernels.contact import distance as D
from ipcsim.kernels.contact import point_edge_barrier as PE
from ipcsim.kernels.contact.barrier import BARRIER_IPC, BARRIER_LECTURE
from two_squares import SCENES, brute_force_point_edge_pairs, ipctk_mesh, scene

FORMS = (BARRIER_IPC, BARRIER_LECTURE)


@pytest.fixture(scope="module")
def ipctk():
    return pytest.importorskip("ipctk")


def assemble(rows, cols, vals, n):
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n)).toarray()


def xy_dofs(n):
    """The x and y DOFs of n vertices in the (3n,) layout, in ipctk's 2D order."""
    return np.stack([3 * np.arange(n), 3 * np.arange(n) + 1], axis=1).ravel()


def rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


# =========================================================================================
# Against ipctk's 2D barrier
# =========================================================================================

@pytest.mark.parametrize("name", list(SCENES))
def test_two_squares_barrier_matches_ipctk(ipctk, name):
    V, _, E, p = scene(name)
    dhat, kappa = p["dhat"], p["kappa"]
    s_hat = dhat * dhat
    mesh, X = ipctk_mesh(ipctk, V, E)
    C = ipctk.NormalCollisions()
    C.build(mesh, np.asfortranarray(X), dhat)
    B = ipctk.BarrierPotential(dhat, kappa)
    Xf = np.asfortranarray(X)
    ref_value = B(C, mesh, Xf)
    ref_grad = np.asarray(mesh.to_full_dof(np.asarray(B.gradient(C, mesh, Xf)))).ravel()
    ref_H = mesh.to_full_dof(B.hessian(C, mesh, Xf, ipctk.PSDProjectionMethod.CLAMP)).toarray()
    ref_H_raw = mesh.to_full_dof(B.hessian(C, mesh, Xf, ipctk.PSDProjectionMethod.NONE)).toarray()

    pe = brute_force_point_edge_pairs(V, E, 0.5 * dhat)
    w = np.ones(len(pe))
    types, d2 = PE.pe_classify_and_distance(V, pe)
    n_active = int((d2 < s_hat).sum())
    weights = sum(c.weight for lst in (C.vv_collisions, C.ev_collisions) for c in lst)
    assert n_active == round(weights) and n_active >= 3
    assert len(C.ee_collisions) == len(C.fv_collisions) == 0
    if name == "corner":  # the corner is closest to an endpoint: point-point stencils too
        found = {int(t) for t in types[d2 < s_hat]}
        assert D.PE_P_E in found and found & {D.PE_P_E0, D.PE_P_E1}

    value = PE.pe_barrier_value(V, pe, w, s_hat, kappa, BARRIER_IPC)
    grad = PE.pe_barrier_gradient(V, pe, w, s_hat, kappa, BARRIER_IPC)
    n = V.size
    H = assemble(*PE.pe_barrier_hessian_triplets(V, pe, w, s_hat, kappa, BARRIER_IPC, True), n)
    H_raw = assemble(*PE.pe_barrier_hessian_triplets(V, pe, w, s_hat, kappa, BARRIER_IPC,
                                                     False), n)
    xy = xy_dofs(len(V))
    z = 3 * np.arange(len(V)) + 2
    print(f"  {name}: {n_active} active pairs, relative differences: value "
          f"{abs(value - ref_value) / ref_value:.1e}, gradient {rel(grad[xy], ref_grad):.1e}, "
          f"Hessian (clamped) {rel(H[np.ix_(xy, xy)], ref_H):.1e}, "
          f"raw {rel(H_raw[np.ix_(xy, xy)], ref_H_raw):.1e}")
    assert value == pytest.approx(ref_value, rel=1e-10, abs=0.0)
    assert rel(grad[xy], ref_grad) <= 1e-10
    assert rel(H[np.ix_(xy, xy)], ref_H) <= 1e-10
    assert rel(H_raw[np.ix_(xy, xy)], ref_H_raw) <= 1e-10
    # nothing acts along z: no force, and the projected blocks have no z rows
    assert np.all(grad[z] == 0.0)
    assert np.all(H[z] == 0.0) and np.all(H[:, z] == 0.0)
    assert np.linalg.eigvalsh(H).min() >= -1e-10 * np.abs(H).max()


def test_classification_and_distances_match_ipctk(ipctk):
    V, _, E, p = scene("corner")
    pe = brute_force_point_edge_pairs(V, E, 0.3)
    types, d2 = PE.pe_classify_and_distance(V, pe)
    assert len(pe) > 40 and len(set(types.tolist())) == 3
    for k in range(len(pe)):
        a = V[pe[k], :2]
        assert d2[k] == pytest.approx(ipctk.point_edge_distance(*a), rel=1e-13)
        assert int(types[k]) == int(ipctk.point_edge_distance_type(*a))


# =========================================================================================
# Finite differences, both forms
# =========================================================================================

def _stencils(seed):
    """Random stencils at z = 0 of each closest-feature type: P_E0, P_E1, P_E (the point
    0.03 before e0, 0.02 beyond e1, over the edge; off its line by 0.04, 0.035, 0.06)."""
    rng = np.random.default_rng(seed)
    out = []
    for kind, off in enumerate((0.04, 0.035, 0.06)):
        e0 = rng.uniform(-1, 1, 2)
        length = rng.uniform(0.5, 1.0)
        a = rng.uniform(0, 2 * np.pi)
        tangent = np.array([np.cos(a), np.sin(a)])
        normal = np.array([-tangent[1], tangent[0]])
        along = (-0.03, length + 0.02, 0.45 * length)[kind]
        V = np.zeros((3, 3))
        V[:, :2] = [e0 + along * tangent + off * normal, e0, e0 + length * tangent]
        out.append(V)
    return out


@pytest.mark.parametrize("form", FORMS)
def test_batched_derivatives_finite_differences(form):
    V = np.vstack(_stencils(3))
    pe = np.arange(9, dtype=np.int64).reshape(3, 3)
    w = np.array([1.0, 0.7, 2.5])
    s_hat, kappa = 0.08 ** 2, 10.0
    assert np.all(PE.pe_classify_and_distance(V, pe)[1] < s_hat)
    g = PE.pe_barrier_gradient(V, pe, w, s_hat, kappa, form)
    H = assemble(*PE.pe_barrier_hessian_triplets(V, pe, w, s_hat, kappa, form, False), V.size)
    h = 1e-8
    for k in range(V.size):
        Vp, Vm = V.copy(), V.copy()
        Vp.flat[k] += h
        Vm.flat[k] -= h
        fd = (PE.pe_barrier_value(Vp, pe, w, s_hat, kappa, form)
              - PE.pe_barrier_value(Vm, pe, w, s_hat, kappa, form)) / (2 * h)
        assert fd == pytest.approx(g[k], rel=1e-5, abs=1e-6 * np.abs(g).max())
        col = (PE.pe_barrier_gradient(Vp, pe, w, s_hat, kappa, form)
               - PE.pe_barrier_gradient(Vm, pe, w, s_hat, kappa, form)) / (2 * h)
        assert np.abs(col - H[:, k]).max() <= 1e-5 * np.abs(H).max()


def test_inactive_pairs_add_nothing_and_blocks_come_only_for_active_ones():
    V = np.vstack(_stencils(4))
    pe = np.arange(9, dtype=np.int64).reshape(3, 3)
    w = np.ones(3)
    d2 = PE.pe_classify_and_distance(V, pe)[1]
    s_hat = float(np.sort(d2)[1]) * 1.0001  # two of three active
    stencils, vals = PE.pe_barrier_hessian_blocks(V, pe, w, s_hat, 1.0, BARRIER_IPC, True)
    assert stencils.tolist() == pe[d2 < s_hat].tolist() and vals.shape == (81 * 2,)
    value = PE.pe_barrier_value(V, pe, w, s_hat, 1.0, BARRIER_IPC)
    assert value == pytest.approx(PE.pe_barrier_value(V, pe[d2 < s_hat], w[:2], s_hat, 1.0,
                                                      BARRIER_IPC), rel=1e-15)
    near = PE.pe_near_pairs(V, pe, w, np.arange(3), 10.0)
    assert near[0].tolist() == pe.tolist() and near[3].tolist() == \
        PE.pe_classify_and_distance(V, pe)[0].tolist()


# =========================================================================================
# The lecture's form against the lecture's own code (lesson 7's self-contact term)
# =========================================================================================

def _lesson7_barrier(folder):
    sys.path.insert(0, str(folder))
    try:
        names = ("BarrierEnergy", "utils", "distance", "distance.PointEdgeDistance",
                 "distance.PointLineDistance", "distance.PointPointDistance", "distance.CCD")
        for name in names:
            sys.modules.pop(name, None)
        return importlib.import_module("BarrierEnergy")
    finally:
        sys.path.remove(str(folder))


def test_the_lecture_form_is_the_lectures_point_edge_barrier(repo_root):
    folder = repo_root.parent / "shared" / "solid-sim-tutorial" / "7_self_contact"
    if not (folder / "BarrierEnergy.py").is_file():
        pytest.skip("../shared/solid-sim-tutorial is not present")
    BE = _lesson7_barrier(folder)
    try:
        V, _, E, _ = scene("corner")
        dhat, kappa = BE.dhat, BE.kappa
        X2 = V[:, :2] * 0.1 + [0.0, 3.0]  # well above the lesson's ground (y = -1)
        X2 = np.vstack([X2, [0.0, 100.0]])  # its ceiling, far above
        contact_length = np.linspace(0.1, 0.3, len(X2))
        bp = sorted(set(E.ravel().tolist()))
        ref_value = BE.val(X2, np.array([0.0, 1.0]), np.array([0.0, -1.0]), bp, E.tolist(),
                           contact_length)
        ref_grad = BE.grad(X2, np.array([0.0, 1.0]), np.array([0.0, -1.0]), bp, E.tolist(),
                           contact_length)
    finally:
        for name in [n for n, m in sys.modules.items()
                     if str(folder) in (getattr(m, "__file__", None) or "")]:
            del sys.modules[name]
    X = np.zeros((len(X2), 3))
    X[:, :2] = X2
    pe = brute_force_point_edge_pairs(X, E, dhat)
    w = contact_length[pe[:, 0]] * dhat / 16.0  # ½ A d̂ κ / 8 of the lecture, κ apart
    d2 = PE.pe_classify_and_distance(X, pe)[1]
    assert (d2 < dhat * dhat).sum() >= 3 and ref_value > 0.0
    value = PE.pe_barrier_value(X, pe, w, dhat * dhat, kappa, BARRIER_LECTURE)
    grad = PE.pe_barrier_gradient(X, pe, w, dhat * dhat, kappa, BARRIER_LECTURE)
    assert value == pytest.approx(ref_value, rel=1e-12)
    assert rel(grad.reshape(-1, 3)[:, :2], np.asarray(ref_grad)) <= 1e-10
