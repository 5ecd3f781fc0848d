"""Scalar IPC barrier b(s, ŝ) and the edge-edge mollifier (kernels/contact/barrier.py, mollifier.py)."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.kernels.contact import barrier as B
from ipcsim.kernels.contact import mollifier as M


@pytest.fixture(scope="module")
def ipctk():
    return pytest.importorskip("ipctk")


S_HAT = 0.01
S_GRID = S_HAT * np.concatenate([np.logspace(-12, -1, 40), np.linspace(0.1, 0.999999, 40)])


# --- scalar barrier ------------------------------------------------------------------------

def _third_derivative(s, s_hat):
    # d³b/ds³ = −2/s − 4ŝ/s² + 2(s − ŝ)/s² − 2(s − ŝ)²/s³
    r = s - s_hat
    return -2 / s - 4 * s_hat / s**2 + 2 * r / s**2 - 2 * r**2 / s**3


def test_barrier_matches_ipctk(ipctk):
    """1e-12 relative, plus the rounding floor 8·eps·s·|f'(s)| of evaluating f at a rounded s
    (near s = ŝ the derivatives vanish faster than s·f', and that floor dominates)."""
    eps = np.finfo(float).eps
    for s_hat in (1e-6, S_HAT, 4.0):
        for s in S_GRID / S_HAT * s_hat:
            for mine, ref, nxt in (
                    (B.barrier, ipctk.barrier, B.barrier_first_derivative),
                    (B.barrier_first_derivative, ipctk.barrier_first_derivative,
                     B.barrier_second_derivative),
                    (B.barrier_second_derivative, ipctk.barrier_second_derivative,
                     _third_derivative)):
                r = ref(s, s_hat)
                tol = 1e-12 * abs(r) + 8 * eps * s * abs(nxt(s, s_hat))
                assert abs(mine(s, s_hat) - r) <= tol, (s, s_hat, mine)


def test_barrier_and_derivatives_at_the_ends():
    assert B.barrier_and_derivatives(S_HAT, S_HAT) == (0.0, 0.0, 0.0)
    assert B.barrier_and_derivatives(2 * S_HAT, S_HAT) == (0.0, 0.0, 0.0)
    assert B.barrier_and_derivatives(0.0, S_HAT)[0] == np.inf


def test_barrier_derivatives_finite_differences():
    for s in S_GRID[(S_GRID > 1e-9) & (S_GRID < 0.99 * S_HAT)]:
        h = 1e-6 * s
        fd1 = (B.barrier(s + h, S_HAT) - B.barrier(s - h, S_HAT)) / (2 * h)
        fd2 = (B.barrier_first_derivative(s + h, S_HAT)
               - B.barrier_first_derivative(s - h, S_HAT)) / (2 * h)
        assert fd1 == pytest.approx(B.barrier_first_derivative(s, S_HAT), rel=1e-6)
        assert fd2 == pytest.approx(B.barrier_second_derivative(s, S_HAT), rel=1e-6)


def test_barrier_is_c2_at_s_hat_and_positive_inside():
    s = S_HAT * (1 - 1e-7)
    assert B.barrier(s, S_HAT) < 1e-15 and abs(B.barrier_first_derivative(s, S_HAT)) < 1e-8
    assert abs(B.barrier_second_derivative(s, S_HAT)) < 1e-4
    inside = S_GRID[S_GRID < S_HAT]
    assert all(B.barrier(s, S_HAT) > 0 for s in inside)
    assert all(B.barrier_first_derivative(s, S_HAT) < 0 for s in inside)
    assert all(B.barrier_second_derivative(s, S_HAT) > 0 for s in inside)


# --- edge-edge mollifier ---------------------------------------------------------------------

def _near_parallel_edges(n, seed):
    """(n, 4, 3) edge pairs with sin²θ spread over [1e-8, 1e-1] (so c/eps_x spans both sides
    of 1) plus a few exactly parallel ones."""
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, 4, 3))
    u = X[:, 1] - X[:, 0]
    perp = np.cross(u, rng.standard_normal((n, 3)))
    perp /= np.linalg.norm(perp, axis=1, keepdims=True)
    sin = np.sqrt(10.0 ** rng.uniform(-8, -1, n))
    sin[: n // 20] = 0.0
    v = u * rng.uniform(0.3, 2.0, (n, 1)) + (sin * np.linalg.norm(u, axis=1))[:, None] * perp
    X[:, 3] = X[:, 2] + v
    return np.ascontiguousarray(X)


def test_mollifier_threshold_and_cross_match_ipctk(ipctk):
    X = _near_parallel_edges(400, seed=1)
    R = X + 0.1 * np.random.default_rng(2).standard_normal(X.shape)  # "rest" positions
    for x, r in zip(X, R):
        a = tuple(x)
        eps_ref = ipctk.edge_edge_mollifier_threshold(*tuple(r))
        assert M.edge_edge_mollifier_threshold(*tuple(r)) == pytest.approx(eps_ref, rel=1e-14)
        c_ref = ipctk.edge_edge_cross_squarednorm(*a)
        g_ref = np.asarray(ipctk.edge_edge_cross_squarednorm_gradient(*a))
        H_ref = np.asarray(ipctk.edge_edge_cross_squarednorm_hessian(*a))
        # c = |u×v|² cancels for near-parallel edges: floor eps·|u|²|v|² (its rounding error)
        scale = np.sum((x[1] - x[0]) ** 2) * np.sum((x[3] - x[2]) ** 2)
        assert abs(M.edge_edge_cross_sq(*a) - c_ref) <= 1e-10 * c_ref + 1e-14 * scale
        g = M.edge_edge_cross_sq_gradient(*a)
        assert np.abs(g - g_ref).max() <= 1e-10 * np.abs(g_ref).max() + 1e-14 * scale
        H = M.edge_edge_cross_sq_hessian(*a)
        assert np.abs(H - H_ref).max() <= 1e-12 * np.abs(H_ref).max()
    batch = M.edge_edge_mollifier_thresholds(R.reshape(-1, 3),
                                             np.arange(4 * len(R)).reshape(-1, 4))
    assert np.allclose(batch, [M.edge_edge_mollifier_threshold(*tuple(r)) for r in R],
                       rtol=1e-15, atol=0.0)


def test_mollifier_matches_ipctk(ipctk):
    X = _near_parallel_edges(2000, seed=3)
    n_moll = 0
    for x in X:
        a = tuple(x)
        eps_x = M.edge_edge_mollifier_threshold(*a)
        c = M.edge_edge_cross_sq(*a)
        n_moll += c < eps_x
        m_ref = ipctk.edge_edge_mollifier(*a, eps_x)
        g_ref = np.asarray(ipctk.edge_edge_mollifier_gradient(*a, eps_x))
        H_ref = np.asarray(ipctk.edge_edge_mollifier_hessian(*a, eps_x))
        # m, ∇m are smooth in c, whose rounding error is ~eps·|u|²|v|² = 1e3·eps·eps_x:
        # floors 1e-12 (m ≤ 1) and 1e-12·|∇c|max/eps_x for the gradient, with
        # |∇c|max = 2|u||v|·max(|u|, |v|) (its size for perpendicular edges)
        lu, lv = np.linalg.norm(x[1] - x[0]), np.linalg.norm(x[3] - x[2])
        gscale = 2 * lu * lv * max(lu, lv) / eps_x
        assert abs(M.edge_edge_mollifier(*a, eps_x) - m_ref) <= 1e-12
        assert np.abs(M.edge_edge_mollifier_gradient(*a, eps_x) - g_ref).max() <= (
            1e-10 * np.abs(g_ref).max() + 1e-12 * gscale)
        H = M.edge_edge_mollifier_hessian(*a, eps_x)
        assert np.abs(H - H_ref).max() <= 1e-10 * max(np.abs(H_ref).max(), 1e-300)
    # both sides of the threshold are exercised
    assert 200 < n_moll < len(X) - 200


def _fd(f, x, h):
    out = []
    for k in range(12):
        xp, xm = x.copy(), x.copy()
        xp.flat[k] += h
        xm.flat[k] -= h
        out.append((np.ravel(f(*xp)) - np.ravel(f(*xm))) / (2 * h))
    return np.array(out).T.squeeze()


def test_mollifier_derivatives_finite_differences():
    X = _near_parallel_edges(200, seed=4)
    checked = 0
    for x in X:
        eps_x = M.edge_edge_mollifier_threshold(*x)
        c = M.edge_edge_cross_sq(*x)
        if not 0.05 * eps_x < c < 0.95 * eps_x:  # stay away from the kink at c = eps_x
            continue
        checked += 1
        h = 1e-7 * np.abs(x).max()
        for f, g in ((M.edge_edge_cross_sq, M.edge_edge_cross_sq_gradient),
                     (lambda *v: M.edge_edge_mollifier(*v, eps_x),
                      lambda *v: M.edge_edge_mollifier_gradient(*v, eps_x))):
            assert np.allclose(_fd(f, x, h), g(*x), rtol=1e-5,
                               atol=1e-6 * np.abs(g(*x)).max())
        for g, H in ((M.edge_edge_cross_sq_gradient, M.edge_edge_cross_sq_hessian),
                     (lambda *v: M.edge_edge_mollifier_gradient(*v, eps_x),
                      lambda *v: M.edge_edge_mollifier_hessian(*v, eps_x))):
            Hx = H(*x)
            assert np.allclose(_fd(g, x, h), Hx, rtol=1e-5, atol=1e-6 * np.abs(Hx).max())
    assert checked >= 10


def test_mollifier_scalar():
    eps_x = 2.0
    assert M.mollifier_scalar(0.0, eps_x) == 0.0
    assert M.mollifier_scalar(eps_x, eps_x) == 1.0 and M.mollifier_scalar(5.0, eps_x) == 1.0
    assert M.mollifier_scalar(1.0, eps_x) == pytest.approx(0.75)  # (2 − ½)·½
    assert M.mollifier_scalar_first_derivative(eps_x * (1 - 1e-12), eps_x) < 1e-11  # C¹
    assert M.mollifier_scalar_second_derivative(1.0, eps_x) == -2.0 / eps_x**2


def test_lecture_barrier_derivatives_finite_differences_and_its_shape():
    r_hat = 0.01
    for r in np.linspace(0.05, 0.99, 12) * r_hat:
        b, db, d2b = B.lecture_barrier_and_derivatives(r, r_hat)
        h = 1e-7 * r
        fd1 = (B.lecture_barrier_and_derivatives(r + h, r_hat)[0]
               - B.lecture_barrier_and_derivatives(r - h, r_hat)[0]) / (2 * h)
        fd2 = (B.lecture_barrier_and_derivatives(r + h, r_hat)[1]
               - B.lecture_barrier_and_derivatives(r - h, r_hat)[1]) / (2 * h)
        assert fd1 == pytest.approx(db, rel=1e-6)
        assert fd2 == pytest.approx(d2b, rel=1e-6)
        assert b > 0.0 and db < 0.0 and d2b > 0.0
        assert B.barrier_of_form(B.BARRIER_LECTURE, r, r_hat) == (b, db, d2b)
        assert B.barrier_of_form(B.BARRIER_IPC, r, r_hat) == B.barrier_and_derivatives(r, r_hat)
    # C¹ at r̂ (value and slope vanish there), unbounded at 0
    below = B.lecture_barrier_and_derivatives(r_hat * (1 - 1e-9), r_hat)
    assert abs(below[0]) < 1e-17 and abs(below[1]) < 1e-6
    assert B.lecture_barrier_and_derivatives(r_hat, r_hat) == (0.0, 0.0, 0.0)
    assert B.lecture_barrier_and_derivatives(0.0, r_hat)[0] == np.inf
