"""Additive CCD on point–edge stencils (kernels/contact/ccd.py, the 2D scenes' kind) and
the point–edge broad phase (kernels/contact/broad_phase.py).

For every query (random and adversarial, in the plane z = 0) the step α must

* come before the first impact on the linear trajectory (reference below), or be 0 when
  the point touches the edge at the start;
* leave a positive distance, at least min_gap_fraction · d0 (to the CCD's own 1e-3);
* be collision free according to ipctk's 2D ``is_step_collision_free``.

Reference. In the plane the point p(t) meets the segment e(t) only where p, e0, e1 are
collinear: a root of the quadratic cross(e0(t) − p(t), e1(t) − p(t)) in [0, 1], at which
p lies between e0 and e1. Its roots are taken with 60 digits (mpmath), and a root counts
as an impact when p's parameter along the edge is within [−1e-30, 1 + 1e-30] (erring
towards impact, which only makes the test stricter). Queries that stay collinear all
along (the quadratic vanishes) are left to the other two checks.

On a scene of two squares, the step is compared with ipctk's
``compute_collision_free_stepsize``: ours never goes past a collision-free step, and the
two differ by the rule each stops at (ours at a tenth of the start gap, ipctk's at
min(0.2 d0, 1e-4)).
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from ipcsim.kernels.contact import ccd
from ipcsim.kernels.contact.broad_phase import point_edge_candidate_pairs, primitive_tags
from ipcsim.kernels.contact.distance import point_edge_distance_sq
from two_squares import ipctk_mesh, scene

GAP = ccd.DEFAULT_MIN_GAP_FRACTION
mpmath.mp.dps = 60


@pytest.fixture(scope="module")
def ipctk():
    return pytest.importorskip("ipctk")


def _first_impact(q0, q1):
    """The first time in [0, 1] at which p meets the closed segment (60 digits), or None."""
    P = [[mpmath.mpf(float(v)) for v in row[:2]] for row in q0]
    D = [[mpmath.mpf(float(q1[i, a])) - P[i][a] for a in range(2)] for i in range(3)]

    def rel(i, t):  # position of vertex i relative to p at time t
        return [P[i][a] + t * D[i][a] - P[0][a] - t * D[0][a] for a in range(2)]

    # cross(u + t du, w + t dw) = c0 + c1 t + c2 t²
    u = rel(1, 0)
    w = rel(2, 0)
    du = [D[1][a] - D[0][a] for a in range(2)]
    dw = [D[2][a] - D[0][a] for a in range(2)]
    c0 = u[0] * w[1] - u[1] * w[0]
    c1 = u[0] * dw[1] - u[1] * dw[0] + du[0] * w[1] - du[1] * w[0]
    c2 = du[0] * dw[1] - du[1] * dw[0]
    if c2 == 0 and c1 == 0:
        return None if c0 != 0 else "collinear"
    roots = [-c0 / c1] if c2 == 0 else []
    if c2 != 0:
        disc = c1 * c1 - 4 * c2 * c0
        if disc >= 0:
            s = mpmath.sqrt(disc)
            roots = [(-c1 - s) / (2 * c2), (-c1 + s) / (2 * c2)]
    for t in sorted(roots):
        if not 0 <= t <= 1:
            continue
        a, b = rel(1, t), rel(2, t)  # p on [e0, e1] iff p − e0 = λ (e1 − e0), λ ∈ [0, 1]
        e = [b[k] - a[k] for k in range(2)]
        L = e[0] ** 2 + e[1] ** 2
        lam = (-a[0] * e[0] - a[1] * e[1]) / L if L > 0 else mpmath.mpf(0)
        if -1e-30 <= lam <= 1 + 1e-30:
            return float(t)
    return None


def _queries(n, seed):
    """Random point-edge trajectories at z = 0: (x0 (3n, 3), x1, stencils (n, 3)), with
    sliding, head-on and turning edges mixed in."""
    rng = np.random.default_rng(seed)
    x0 = np.zeros((3 * n, 3))
    x1 = np.zeros((3 * n, 3))
    for k in range(n):
        e0 = rng.uniform(-1, 1, 2)
        e1 = e0 + rng.uniform(0.1, 1.0) * np.array([np.cos(a := rng.uniform(0, 6.3)), np.sin(a)])
        t = rng.uniform(-0.3, 1.3)
        normal = np.array([-(e1 - e0)[1], (e1 - e0)[0]]) / np.linalg.norm(e1 - e0)
        gap = 10.0 ** rng.uniform(-5, -0.5)
        p = e0 + t * (e1 - e0) + gap * normal
        kind = k % 4
        if kind == 0:  # anything
            moves = rng.uniform(-1, 1, (3, 2))
        elif kind == 1:  # the point slides along the edge, dipping towards it
            moves = np.zeros((3, 2))
            moves[0] = rng.uniform(-1, 1) * (e1 - e0) - rng.uniform(0, 3) * gap * normal
        elif kind == 2:  # head-on
            moves = np.zeros((3, 2))
            moves[0] = -rng.uniform(0.5, 3) * gap * normal
        else:  # the edge turns about its middle while the point waits
            c = 0.5 * (e0 + e1)
            th = rng.uniform(-1, 1)
            R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
            moves = np.array([np.zeros(2), (e0 - c) @ R.T + c - e0, (e1 - c) @ R.T + c - e1])
        x0[3 * k:3 * k + 3, :2] = [p, e0, e1]
        x1[3 * k:3 * k + 3, :2] = np.array([p, e0, e1]) + moves
    return x0, x1, np.arange(3 * n, dtype=np.int64).reshape(n, 3)


def test_steps_come_before_the_first_impact_and_keep_their_gap():
    x0, x1, pe = _queries(1200, seed=7)
    steps, iters = ccd.point_edge_query_steps(x0, x1, pe)
    impacts = 0
    for k, (a, b, c) in enumerate(pe):
        alpha = steps[k]
        q0, q1 = x0[[a, b, c]], x1[[a, b, c]]
        d0 = np.sqrt(point_edge_distance_sq(*q0))
        toi = _first_impact(q0, q1)
        if isinstance(toi, float):
            impacts += 1
            assert alpha < toi, (k, alpha, toi)
        q = q0 + alpha * (q1 - q0)
        assert np.sqrt(point_edge_distance_sq(*q)) >= GAP * d0 * (1 - 2e-3), k
        assert 0.0 <= alpha <= 1.0
        if k % 4 == 2 and isinstance(toi, float):  # head-on: 0.9 of the way, to 1e-3
            assert alpha >= 0.899 * toi, (k, alpha, toi)
    assert impacts > 300  # the test meets many impacts


def test_the_step_is_collision_free_for_ipctk(ipctk):
    """Each query scaled by a power of two (exactly) to a start gap of about 1, so that
    Tight-Inclusion's absolute tolerances (1e-6) are small against it, as in test_ccd."""
    x0, x1, pe = _queries(300, seed=8)
    steps, _ = ccd.point_edge_query_steps(x0, x1, pe)
    mesh = ipctk.CollisionMesh(np.zeros((3, 2)), np.array([[1, 2]], dtype=np.int32))
    for k, row in enumerate(pe):
        scale = 2.0 ** -np.floor(np.log2(np.sqrt(point_edge_distance_sq(*x0[row]))))
        q0 = np.asfortranarray(scale * x0[row, :2])
        q = np.asfortranarray(q0 + steps[k] * (scale * x1[row, :2] - q0))
        assert ipctk.is_step_collision_free(mesh, q0, q), k


def test_max_step_is_the_smallest_query_step_and_a_touching_start_gives_zero():
    x0, x1, pe = _queries(200, seed=9)
    steps, _ = ccd.point_edge_query_steps(x0, x1, pe)
    assert ccd.point_edge_max_step(x0, x1, pe) == pytest.approx(steps.min(), rel=1e-12)
    x0[0, :2] = 0.5 * (x0[1, :2] + x0[2, :2])  # the first point on its edge
    assert ccd.point_edge_max_step(x0, x1, pe) == 0.0
    assert ccd.point_edge_max_step(x0, x0, pe[1:]) == 1.0  # nothing moves
    with pytest.raises(ValueError, match="out of range"):
        ccd.point_edge_max_step(x0, x1, pe + len(x0))


def _candidates(V, V1, E):
    points = np.unique(E).reshape(-1, 1)
    none = np.zeros(len(V), dtype=np.int64)
    tags = (primitive_tags(points, none, none.astype(np.bool_)),
            primitive_tags(E, none, none.astype(np.bool_)))
    return point_edge_candidate_pairs(V, V1, points, E, tags, 0.0, True)[0]


def test_a_step_of_two_squares_is_within_ipctks_collision_free_step(ipctk):
    """ipctk's Tight-Inclusion step goes to within min(0.2 d0, 1e-4) of contact, ours to a
    tenth of the start gap: ours is never past it, and at least 0.95 of ipctk's additive
    CCD, which stops at the same tenth."""
    V, _, E, p = scene("corner")
    rng = np.random.default_rng(3)
    mesh, X = ipctk_mesh(ipctk, V, E)
    X = np.asfortranarray(X)
    upper = np.arange(len(V)) >= len(V) // 2
    limited = 0
    for trial in range(20):
        V1 = V.copy()
        V1[upper, 1] -= rng.uniform(0.02, 0.3)  # the upper square comes down, turning
        V1[upper, 0] += rng.uniform(-0.1, 0.1) + rng.uniform(-0.05, 0.05) * (V[upper, 1] - 1)
        ours = ccd.point_edge_max_step(V, V1, _candidates(V, V1, E))
        X1 = np.asfortranarray(mesh.vertices(np.asfortranarray(V1[:, :2])))
        ref = ipctk.compute_collision_free_stepsize(mesh, X, X1)
        accd = ipctk.compute_collision_free_stepsize(mesh, X, X1, 0.0, ipctk.LBVH(),
                                                     ipctk.AdditiveCCD())
        mid = np.asfortranarray(X + ours * (X1 - X))
        assert ipctk.is_step_collision_free(mesh, X, mid)
        assert ipctk.compute_collision_free_stepsize(mesh, X, mid) == 1.0
        if ref < 1.0:
            limited += 1
            print(f"  trial {trial}: ours {ours:.4f}, ipctk {ref:.4f}, ipctk ACCD {accd:.4f}")
            assert ours < ref and ours >= 0.95 * accd
    assert limited >= 10


def test_point_edge_candidates_are_the_brute_force_ones():
    V, _, E, p = scene("aligned")
    rng = np.random.default_rng(2)
    V1 = V + 0.06 * rng.standard_normal(V.shape) * [1, 1, 0]
    points = np.unique(E).reshape(-1, 1)
    body = (np.arange(len(V)) >= len(V) // 2).astype(np.int64)
    kinematic = np.zeros(len(V), dtype=np.bool_)
    tags = (primitive_tags(points, body, kinematic), primitive_tags(E, body, kinematic))
    for inflation, self_collision in ((p["dhat"], True), (0.0, True), (p["dhat"], False)):
        rows, index = point_edge_candidate_pairs(V, V1, points, E, tags, inflation,
                                                 self_collision)
        assert np.array_equal(rows, np.column_stack([points[index[:, 0], 0], E[index[:, 1]]]))
        found = [tuple(r) for r in rows.tolist()]
        expect = {t for t in _swept_pairs(V, V1, E, 0.5 * inflation)
                  if self_collision or body[t[0]] != body[t[1]]}
        assert len(found) == len(set(found)) and set(found) == expect and len(found) >= 8


def _swept_pairs(V, V1, E, grow):
    # every (p, e0, e1) whose boxes over both positions, grown by ``grow``, overlap
    lo = np.minimum(V, V1) - grow
    hi = np.maximum(V, V1) + grow
    out = set()
    for p in np.unique(E):
        for e in E:
            if p in e:
                continue
            elo = np.minimum(lo[e[0]], lo[e[1]])
            ehi = np.maximum(hi[e[0]], hi[e[1]])
            if np.all(lo[p] <= ehi) and np.all(elo <= hi[p]):
                out.add((int(p), int(e[0]), int(e[1])))
    return out
