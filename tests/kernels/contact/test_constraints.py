"""Collision constraints of the SQP / QP baselines (ipcsim.kernels.contact.constraints): values by
their formulas, gradients against central finite differences, signs and switched-off
pairs."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.kernels.contact import constraints as K

RNG = np.random.default_rng(7)
H = 1e-6


def _eval(x, pair, is_ee, kind, weights=None):
    w = np.zeros((1, 4)) if weights is None else np.asarray(weights, float).reshape(1, 4)
    c, g = K.constraint_values_and_gradients(x, np.array([pair], np.int64), is_ee, kind, w)
    return c[0], g[0]


def _fd_gradient(x, pair, is_ee, kind):
    g = np.zeros((4, 3))
    for i, v in enumerate(pair):
        for a in range(3):
            xp, xm = x.copy(), x.copy()
            xp[v, a] += H
            xm[v, a] -= H
            g[i, a] = (_eval(xp, pair, is_ee, kind)[0] - _eval(xm, pair, is_ee, kind)[0]) / (2 * H)
    return g


def _configs(is_ee, n=40):
    """Random well-shaped stencils: for EE, edges whose closest points are inside both."""
    out = []
    while len(out) < n:
        x = RNG.normal(size=(4, 3))
        if is_ee:
            x[1] = x[0] + RNG.normal(size=3)
            x[2] = x[0] + 0.5 * (x[1] - x[0]) + RNG.normal(size=3) * 0.5
            x[3] = x[2] + RNG.normal(size=3)
            da, db = x[1] - x[0], x[3] - x[2]
            if np.linalg.norm(np.cross(da, db)) < 0.3 * np.linalg.norm(da) * np.linalg.norm(db):
                continue
        out.append(x)
    return out


@pytest.mark.parametrize("is_ee", [False, True], ids=["PT", "EE"])
@pytest.mark.parametrize("kind", [K.VOLUME, K.GAP], ids=["volume", "gap"])
def test_gradients_match_finite_differences(is_ee, kind):
    pair = [0, 1, 2, 3]
    for x in _configs(is_ee):
        c, g = _eval(x, pair, is_ee, kind)
        fd = _fd_gradient(x, pair, is_ee, kind)
        assert np.allclose(g, fd, rtol=1e-6, atol=1e-7 * max(1.0, np.abs(fd).max())), (x, g, fd)


def test_point_triangle_values_and_their_sign():
    """PT: positive on the side the normal (t1 − t0) × (t2 − t0) points to."""
    x = np.array([[0.2, 0.3, 0.5], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    pair = [0, 1, 2, 3]
    vol, _ = _eval(x, pair, False, K.VOLUME)
    gap, g = _eval(x, pair, False, K.GAP)
    assert vol == pytest.approx(0.5)  # |n| · height = 1 · 0.5
    assert gap == pytest.approx(0.5)
    # the gradient is the normal on the point and −α n on the triangle (α = (0.5, 0.2, 0.3))
    assert np.allclose(g, [[0, 0, 1], [0, 0, -0.5], [0, 0, -0.2], [0, 0, -0.3]])
    x[0, 2] = -0.5
    assert _eval(x, pair, False, K.VOLUME)[0] < 0 and _eval(x, pair, False, K.GAP)[0] < 0


def test_edge_edge_gap_is_the_signed_distance_of_the_lines():
    x = np.array([[0, 0, 0], [2, 0, 0], [1, -1, 0.25], [1, 1, 0.25]], float)
    gap, g = _eval(x, [0, 1, 2, 3], True, K.GAP)
    # n = db × da = (0, 2, 0) × (2, 0, 0) = (0, 0, −4): unit −z, c = n̂·(eb0 − ea0)
    assert gap == pytest.approx(-0.25)
    # closest points at s = t = 1/2: weights (−1/2, −1/2, 1/2, 1/2) times n̂
    assert np.allclose(g, 0.5 * np.array([[0, 0, 1], [0, 0, 1], [0, 0, -1], [0, 0, -1]]))
    vol, _ = _eval(x, [0, 1, 2, 3], True, K.VOLUME)
    assert vol == pytest.approx(-0.25 * 4)  # the same sign: |db × da| times the gap


def test_verschoor_is_the_gap_with_given_contact_weights():
    """The same value as the gap; the gradient is w_i n̂ with the contact point's weights,
    which equals the gap's gradient when they are the projection's."""
    for is_ee in (False, True):
        for x in _configs(is_ee, 10):
            c, g = _eval(x, [0, 1, 2, 3], is_ee, K.GAP)
            n = np.cross(x[3] - x[2], x[1] - x[0]) if is_ee else np.cross(x[2] - x[1],
                                                                         x[3] - x[1])
            n /= np.linalg.norm(n)
            w = g @ n  # the projection's weights
            cv, gv = _eval(x, [0, 1, 2, 3], is_ee, K.VERSCHOOR, w)
            assert cv == pytest.approx(c) and np.allclose(gv, g)
            other = np.array([1.0, -0.2, -0.3, -0.5]) if not is_ee else np.array(
                [-0.7, -0.3, 0.4, 0.6])
            cv, gv = _eval(x, [0, 1, 2, 3], is_ee, K.VERSCHOOR, other)
            assert cv == pytest.approx(c) and np.allclose(gv, other[:, None] * n)


def test_contact_weights_at_the_time_of_impact():
    """A point falling onto a triangle: its weights are 1 and minus the barycentric
    coordinates of where it lands; edges: the clamped closest-point parameters."""
    x0 = np.array([[0.2, 0.3, 1.0], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    x1 = x0.copy()
    x1[0] = [0.4, 0.1, -1.0]  # at toi = 0.5 it is at (0.3, 0.2, 0)
    w = K.contact_weights(x0, x1, np.array([[0, 1, 2, 3]]), False, np.array([0.5]))
    assert np.allclose(w, [[1, -0.5, -0.3, -0.2]])
    e0 = np.array([[0, 0, 1], [1, 0, 1], [3, -1, 0], [3, 1, 0]], float)  # s = 3 clamps to 1
    w = K.contact_weights(e0, e0, np.array([[0, 1, 2, 3]]), True, np.array([0.0]))
    assert np.allclose(w, [[0, -1, 0.5, 0.5]])


def test_degenerate_and_switched_off_pairs_are_inactive():
    flat = np.array([[0, 0, 1], [0, 0, 0], [1, 0, 0], [2, 0, 0]], float)  # collinear triangle
    c, g = _eval(flat, [0, 1, 2, 3], False, K.GAP)
    assert c == K.INACTIVE and not g.any()
    parallel = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 1, 0]], float)
    assert _eval(parallel, [0, 1, 2, 3], True, K.GAP)[0] == K.INACTIVE
    x = _configs(False, 1)[0]
    c, g = _eval(x, [0, 1, 2, 3], False, K.VERSCHOOR, [np.nan] * 4)
    assert c == K.INACTIVE and not g.any()
