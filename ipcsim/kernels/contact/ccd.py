"""Continuous collision detection for linear trajectories: additive CCD (ACCD).

After Li, Kaufman and Jiang 2021 ("Codimensional Incremental Potential Contact"), section 4.
Every vertex moves on q(t) = q0 + t·dq, t in [0, 1]. For a point-triangle (PT) stencil
(p, t0, t1, t2), an edge-edge (EE) stencil (a0, a1, b0, b1) or, in a 2D scene, a point-edge
(PE) stencil (p, e0, e1), the unsquared distance d(t) is 1-Lipschitz in the relative
position of any point pair, so

    |d'(t)| <= l_p,   l_p = max_i |dt_i - dp|             (PT)
                      l_p = max_{i,j} |da_i - db_j|       (EE)
                      l_p = max_i |de_i - dp|             (PE)

(the relative motion of p against any convex combination of t0, t1, t2, of any point of
edge a against any point of edge b, or of p against any point of edge e). From a time t
with distance d, advancing by

    δ = s·d / l_p,   s = (1 - f)·(1 - 1e-3)

keeps d ≥ (1 - s)·d > 0 on all of [t, t + δ]. ACCD repeats such steps until one would end
with d < f·d0 (f = ``min_gap_fraction``, 0.1 in the paper). It then takes one last step of
(d - f·d0)/l_p, over which d ≥ f·d0 is guaranteed, and stops. So the time returned is never past
the time of impact, the distance stays positive on the whole interval, and it is at least f·d0
at the returned time. (The paper stops without the last step, which in oblique approaches can
leave α well short of the time of impact.) The (1 - 1e-3) keeps the first step of a head-on
approach (where the bound is exact and d lands on f·d0 exactly) clear of the stop test under
rounding.

Cost: a head-on approach takes 2 steps; an approach at normal speed v_n takes about
2.6·l_p / v_n steps. Sliding at a small gap d takes about l_p / (0.9·d) steps: that is the only
tail, and ``max_iterations`` cuts it (the query then keeps the safe time it has reached, which
is conservative). ``ccd_max_step`` runs the queries in rounds of growing iteration budget and
drops every query whose safe time already reaches the smallest finished result, so long queries
only run while they could still lower the step.

Distances are those of ``kernels/contact/distance.py`` (closest feature chosen as ipctk does, then
that feature's distance), the ones the barriers use (point-edge: ``point_edge_distance_sq``);
``point_triangle_distance_sq(q)`` and ``edge_edge_distance_sq(q)`` here only take the
stencil as one (4, 3) array. They are not
lower bounds, and need not be. A computed distance d_c = (1 + e)·d (d the exact one)
advances by δ = s·d_c/l_p, over which the exact distance stays at least
d − l_p·δ = (1 − s·(1 + e))·d. With s = (1 − f)(1 − 1e-3) that is at least f·d (the step
keeps its gap fraction) while e ≤ 1e-3/(1 − 1e-3), and positive while e < 1/s − 1 (0.11 for
f = 0.1). The stop test compares computed distances, so the gap at the returned time is
f·d0 up to the same relative error.

The rounding error is a few ulps of the coordinate scale, |d_c − d| ≤ c·ε·scale (scale =
largest coordinate magnitude of the stencil over the step), c of order one for well-shaped
primitives (measured against 60-digit references at distances from 1e-12 to 1e-1 of the
scale, up to 1e3 away from the origin: c < 2 for triangles without angles under 10° and
edges crossing at 3° or more; tests/kernels/test_ccd_distances.py asserts c ≤ 4). Queries
closer than ``1e-12·scale`` count as touching (they return 0: float64 cannot resolve them),
so e ≤ c·ε·scale/d ≤ c·2.2e-4 < 1e-3 down to that threshold, and e ≤ c·2.2e-6 from
1e-10·scale on: the relative rounding is covered by the 1e-3 margin, and positivity by a
hundred times more. c grows with ill-conditioning: as 1/sin of the smallest angle of a
sliver triangle (its plane is known only that well; c ≈ 700 was seen for an angle of
7e-6 rad), and for edges within sin θ ≲ 1e-7 of parallel, whose closest features are then
uncertain, the error reaches the smaller of ε·L/sin θ and L·sin θ, at most about 1e-8·L
(L the edge length; below sin²θ = 2.5e-16, distance.EE_PARALLEL_THRESHOLD, they are
treated as parallel), which is more than 11 % of d only for d below ~1e-7·L.
Degenerate triangles (collinear vertices) are measured by their three edges.

Stencils come as one (k, 4) array, PT rows first (``n_pt`` of them), then EE rows; or, for
a 2D scene, as one (k, 3) array of PE rows (``n_pt`` = 0): the kind of a query follows
from its row and the array's width (``query_kind``). A point-edge distance is as well
conditioned as a point-line one (c of order one).
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.kernels.contact.distance import edge_edge_distance_sq as ee_distance_sq_of_points
from ipcsim.kernels.contact.distance import point_edge_distance_sq as pe_distance_sq_of_points
from ipcsim.kernels.contact.distance import point_triangle_distance_sq as pt_distance_sq_of_points
from ipcsim.compiler.twin import kernel

DEFAULT_MIN_GAP_FRACTION = 0.1
DEFAULT_MAX_ITERATIONS = 10_000
_STEP_SAFETY = 1.0 - 1e-3
_TINY_REL = 1e-12  # distances below this times the coordinate scale count as touching
_CHUNK = 64  # queries per parallel task
_SERIAL_BELOW = 256  # fewer queries than this run in one thread's loop

# query state columns
_T, _D0, _LP, _DONE, _ITERS = 0, 1, 2, 3, 4
# stencil kinds
STENCIL_PT, STENCIL_EE, STENCIL_PE = 0, 1, 2


@njit(cache=True, inline="always")
def query_kind(stencils, k, n_pt):
    """The kind of query k: PE in a (k, 3) array of point-edge rows, else PT for the
    first n_pt rows and EE for the rest."""
    if stencils.shape[1] == 3:
        return STENCIL_PE
    return STENCIL_PT if k < n_pt else STENCIL_EE


@njit(cache=True)
def _rows(q):
    # the four rows of a (4, 3) stencil as tuples (registers: no array views, no refcounts)
    return ((q[0, 0], q[0, 1], q[0, 2]), (q[1, 0], q[1, 1], q[1, 2]),
            (q[2, 0], q[2, 1], q[2, 2]), (q[3, 0], q[3, 1], q[3, 2]))


@njit(cache=True)
def point_triangle_distance_sq(q):
    """``distance.point_triangle_distance_sq`` (closest feature chosen automatically) of
    the stencil q = (p, t0, t1, t2) given as one (4, 3) array."""
    p, t0, t1, t2 = _rows(q)
    return pt_distance_sq_of_points(p, t0, t1, t2)


@njit(cache=True)
def edge_edge_distance_sq(q):
    """``distance.edge_edge_distance_sq`` (closest feature chosen automatically) of the
    stencil q = (ea0, ea1, eb0, eb1) given as one (4, 3) array."""
    a0, a1, b0, b1 = _rows(q)
    return ee_distance_sq_of_points(a0, a1, b0, b1)


@njit(cache=True)
def _distance(q, kind):
    # the distance of a stencil given as a tuple of four points (a PE stencil: three, and
    # its last one again)
    if kind == STENCIL_PT:
        return np.sqrt(pt_distance_sq_of_points(q[0], q[1], q[2], q[3]))
    if kind == STENCIL_EE:
        return np.sqrt(ee_distance_sq_of_points(q[0], q[1], q[2], q[3]))
    return np.sqrt(pe_distance_sq_of_points(q[0], q[1], q[2]))


# The per-query helpers read a stencil's points into tuples (registers) and are inlined at
# the numba IR level: a call that takes arrays, or views of them, costs atomic reference
# counts per array, which was most of a query's cost.

@njit(cache=True, inline="always")
def _stencil(x0, x1, stencils, k):
    # (q0, dq): the four points of stencil k at t = 0 and their motions x1 - x0 (a
    # point-edge row's three points, its last one twice)
    a, b, c = stencils[k, 0], stencils[k, 1], stencils[k, 2]
    d = stencils[k, stencils.shape[1] - 1]
    q0 = ((x0[a, 0], x0[a, 1], x0[a, 2]), (x0[b, 0], x0[b, 1], x0[b, 2]),
          (x0[c, 0], x0[c, 1], x0[c, 2]), (x0[d, 0], x0[d, 1], x0[d, 2]))
    dq = ((x1[a, 0] - x0[a, 0], x1[a, 1] - x0[a, 1], x1[a, 2] - x0[a, 2]),
          (x1[b, 0] - x0[b, 0], x1[b, 1] - x0[b, 1], x1[b, 2] - x0[b, 2]),
          (x1[c, 0] - x0[c, 0], x1[c, 1] - x0[c, 1], x1[c, 2] - x0[c, 2]),
          (x1[d, 0] - x0[d, 0], x1[d, 1] - x0[d, 1], x1[d, 2] - x0[d, 2]))
    return q0, dq


@njit(cache=True, inline="always")
def _point_at(p, dp, t):
    # p + t·dp
    return (p[0] + t * dp[0], p[1] + t * dp[1], p[2] + t * dp[2])


@njit(cache=True)
def _distance_at(q0, dq, t, kind):
    # _distance of q(t) = q0 + t·dq
    q = (_point_at(q0[0], dq[0], t), _point_at(q0[1], dq[1], t),
         _point_at(q0[2], dq[2], t), _point_at(q0[3], dq[3], t))
    return _distance(q, kind)


@njit(cache=True, inline="always")
def _relative_motion(u, v):
    dx = u[0] - v[0]
    dy = u[1] - v[1]
    dz = u[2] - v[2]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True)
def _motion_bound(dq, kind):
    # l_p: PT max_i |dt_i - dp|; EE max_{i in a, j in b} |da_i - db_j|; PE max_i |de_i - dp|
    if kind != STENCIL_EE:  # a PE stencil's last point is its e1 again
        lp = max(0.0, _relative_motion(dq[0], dq[1]))
        lp = max(lp, _relative_motion(dq[0], dq[2]))
        return max(lp, _relative_motion(dq[0], dq[3]))
    lp = max(0.0, _relative_motion(dq[0], dq[2]))
    lp = max(lp, _relative_motion(dq[0], dq[3]))
    lp = max(lp, _relative_motion(dq[1], dq[2]))
    return max(lp, _relative_motion(dq[1], dq[3]))


@njit(cache=True)
def _scale(q0, dq):
    # the largest coordinate magnitude of the stencil at t = 0 and t = 1
    scale = 0.0
    for r in range(4):
        p = q0[r]
        dp = dq[r]
        for a in range(3):
            scale = max(scale, abs(p[a]), abs(p[a] + dp[a]))
    return scale


@njit(cache=True, inline="always")
def _init_query(x0, x1, stencils, k, kind, state):
    # state[k] = [t, d0, l_p, done, iterations]
    q0, dq = _stencil(x0, x1, stencils, k)
    scale = _scale(q0, dq)
    d0 = _distance(q0, kind)
    lp = _motion_bound(dq, kind)
    state[k, _T] = 0.0
    state[k, _D0] = d0
    state[k, _LP] = lp
    state[k, _ITERS] = 0.0
    state[k, _DONE] = 0.0
    if not d0 > _TINY_REL * scale:  # touching (or NaN): no step
        state[k, _DONE] = 1.0
    elif lp == 0.0:  # no relative motion: the distance never changes
        state[k, _T] = 1.0
        state[k, _DONE] = 1.0


@njit(cache=True, inline="always")
def _advance_query(x0, x1, stencils, k, kind, state, tmax, n_iter, f):
    # at most n_iter ACCD steps from the safe time state[k, _T], never past tmax
    q0, dq = _stencil(x0, x1, stencils, k)
    t = state[k, _T]
    lp = state[k, _LP]
    gap = f * state[k, _D0]
    s = (1.0 - f) * _STEP_SAFETY
    d = _distance_at(q0, dq, t, kind)
    iters = state[k, _ITERS]
    for _ in range(n_iter):
        iters += 1.0
        t_next = min(t + s * d / lp, tmax)  # d >= (1 - s)·d > 0 on [t, t_next]
        d_next = _distance_at(q0, dq, t_next, kind)
        if not d_next >= gap:  # the gap would fall under f·d0: one last, shorter step,
            # d >= d - l_p·τ >= f·d0 on [t, t + (d - f·d0) / l_p], then stop
            t_last = min(t + _STEP_SAFETY * (d - gap) / lp, tmax)
            if t_last > t:
                if _distance_at(q0, dq, t_last, kind) >= gap:
                    t = t_last
            state[k, _T] = t
            state[k, _DONE] = 1.0
            state[k, _ITERS] = iters
            return
        t = t_next
        d = d_next
        if t >= tmax:
            state[k, _T] = tmax
            state[k, _DONE] = 1.0
            state[k, _ITERS] = iters
            return
    state[k, _T] = t
    state[k, _ITERS] = iters


@njit(cache=True)
def _init_chunk(x0, x1, stencils, n_pt, state, c):
    for k in range(c * _CHUNK, min((c + 1) * _CHUNK, stencils.shape[0])):
        _init_query(x0, x1, stencils, k, query_kind(stencils, k, n_pt), state)


@kernel(parallel=True)
def init_queries(x0, x1, stencils, n_pt, state):
    """Every query's state at t = 0 (in parallel chunks when there are many: a parallel
    launch costs more than a few queries do)."""
    n_chunks = (stencils.shape[0] + _CHUNK - 1) // _CHUNK
    if stencils.shape[0] < _SERIAL_BELOW:
        for c in range(n_chunks):
            _init_chunk(x0, x1, stencils, n_pt, state, c)
    else:
        for c in prange(n_chunks):
            _init_chunk(x0, x1, stencils, n_pt, state, c)


@njit(cache=True)
def _advance_chunk(x0, x1, stencils, n_pt, state, active, tmax, n_iter, f, c):
    # every query writes only its own state row
    for i in range(c * _CHUNK, min((c + 1) * _CHUNK, active.shape[0])):
        k = active[i]
        _advance_query(x0, x1, stencils, k, query_kind(stencils, k, n_pt), state, tmax,
                       n_iter, f)


@kernel(parallel=True)
def advance_queries(x0, x1, stencils, n_pt, state, active, tmax, n_iter, f):
    """At most ``n_iter`` ACCD steps of each ``active`` query, never past ``tmax`` (in
    parallel chunks when there are many)."""
    n_chunks = (active.shape[0] + _CHUNK - 1) // _CHUNK
    if active.shape[0] < _SERIAL_BELOW:
        for c in range(n_chunks):
            _advance_chunk(x0, x1, stencils, n_pt, state, active, tmax, n_iter, f, c)
    else:
        for c in prange(n_chunks):
            _advance_chunk(x0, x1, stencils, n_pt, state, active, tmax, n_iter, f, c)


@kernel()
def max_step(x0, x1, stencils, n_pt, f, max_iterations):
    """The largest safe α of all queries (``ccd_max_step``): rounds of growing iteration
    budget, each over the queries whose safe time is still below the smallest finished
    one, so long queries only run while they could still lower the step."""
    n = stencils.shape[0]
    state = np.empty((n, 5))
    init_queries(x0, x1, stencils, n_pt, state)
    active = np.empty(n, dtype=np.int64)
    alpha = 1.0
    budget = 8
    spent = 0
    while True:
        for k in range(n):
            if state[k, _DONE] != 0.0 and state[k, _T] < alpha:
                alpha = state[k, _T]
        m = 0
        for k in range(n):
            if state[k, _DONE] == 0.0 and state[k, _T] < alpha:
                active[m] = k
                m += 1
        if m == 0 or spent >= max_iterations:
            break
        n_iter = min(budget, max_iterations - spent)
        advance_queries(x0, x1, stencils, n_pt, state, active[:m], alpha, n_iter, f)
        spent += n_iter
        budget *= 4
    for k in range(n):  # iteration budget spent: keep the safe time reached
        if state[k, _DONE] == 0.0 and state[k, _T] < alpha:
            alpha = state[k, _T]
    return alpha


def _stack_stencils(pt_pairs, ee_pairs, n_vertices):
    pt = np.ascontiguousarray(pt_pairs, dtype=np.int64).reshape(-1, 4)
    ee = np.ascontiguousarray(ee_pairs, dtype=np.int64).reshape(-1, 4)
    stencils = np.ascontiguousarray(np.concatenate([pt, ee]))
    if stencils.size and (stencils.min() < 0 or stencils.max() >= n_vertices):
        raise ValueError("stencil vertex index out of range")
    return stencils, pt.shape[0]


def _check(x0, x1, min_gap_fraction, max_iterations):
    x0 = np.ascontiguousarray(x0, dtype=np.float64)
    x1 = np.ascontiguousarray(x1, dtype=np.float64)
    if x0.shape != x1.shape or x0.ndim != 2 or x0.shape[1] != 3:
        raise ValueError("x0 and x1 must both be (n, 3) arrays")
    if not 0.0 < min_gap_fraction < 1.0:
        raise ValueError("min_gap_fraction must lie in (0, 1)")
    if max_iterations < 1:
        raise ValueError("max_iterations must be at least 1")
    return x0, x1


def _point_edge_stencils(pe_pairs, n_vertices):
    pe = np.ascontiguousarray(pe_pairs, dtype=np.int64).reshape(-1, 3)
    if pe.size and (pe.min() < 0 or pe.max() >= n_vertices):
        raise ValueError("stencil vertex index out of range")
    return pe


def _query_steps(x0, x1, stencils, n_pt, min_gap_fraction, max_iterations):
    state = np.empty((stencils.shape[0], 5))
    init_queries(x0, x1, stencils, n_pt, state)
    active = np.flatnonzero(state[:, _DONE] == 0.0)
    if active.size:
        advance_queries(x0, x1, stencils, n_pt, state, active, 1.0, int(max_iterations),
                        float(min_gap_fraction))
    return state[:, _T].copy(), state[:, _ITERS].copy()


def ccd_query_steps(x0, x1, pt_pairs, ee_pairs, min_gap_fraction=DEFAULT_MIN_GAP_FRACTION,
                    max_iterations=DEFAULT_MAX_ITERATIONS):
    """Safe step of every query, each run on its own over [0, 1] (no pruning).

    Returns ``(steps, iterations)``: PT queries first, then EE, each a float array."""
    x0, x1 = _check(x0, x1, min_gap_fraction, max_iterations)
    stencils, n_pt = _stack_stencils(pt_pairs, ee_pairs, x0.shape[0])
    return _query_steps(x0, x1, stencils, n_pt, min_gap_fraction, max_iterations)


def point_edge_query_steps(x0, x1, pe_pairs, min_gap_fraction=DEFAULT_MIN_GAP_FRACTION,
                           max_iterations=DEFAULT_MAX_ITERATIONS):
    """``ccd_query_steps`` for the point-edge stencils ``(p, e0, e1)`` of a 2D scene."""
    x0, x1 = _check(x0, x1, min_gap_fraction, max_iterations)
    stencils = _point_edge_stencils(pe_pairs, x0.shape[0])
    return _query_steps(x0, x1, stencils, 0, min_gap_fraction, max_iterations)


def _max_step(x0, x1, stencils, n_pt, min_gap_fraction, max_iterations):
    if stencils.shape[0] == 0:
        return 1.0
    return max_step(x0, x1, stencils, n_pt, float(min_gap_fraction), int(max_iterations))


def ccd_max_step(x0, x1, pt_pairs, ee_pairs, min_gap_fraction=DEFAULT_MIN_GAP_FRACTION,
                 max_iterations=DEFAULT_MAX_ITERATIONS):
    """Largest step α in [0, 1] such that moving every vertex from x0 towards x1 by α keeps
    every PT stencil ``(p, t0, t1, t2)`` and EE stencil ``(ea0, ea1, eb0, eb1)`` apart, with a
    gap of at least ``min_gap_fraction`` times its initial distance at α (ACCD)."""
    x0, x1 = _check(x0, x1, min_gap_fraction, max_iterations)
    stencils, n_pt = _stack_stencils(pt_pairs, ee_pairs, x0.shape[0])
    return _max_step(x0, x1, stencils, n_pt, min_gap_fraction, max_iterations)


def point_edge_max_step(x0, x1, pe_pairs, min_gap_fraction=DEFAULT_MIN_GAP_FRACTION,
                        max_iterations=DEFAULT_MAX_ITERATIONS):
    """``ccd_max_step`` for the point-edge stencils ``(p, e0, e1)`` of a 2D scene: the
    largest α in [0, 1] keeping each point and edge apart, with a gap of at least
    ``min_gap_fraction`` times its initial distance at α."""
    x0, x1 = _check(x0, x1, min_gap_fraction, max_iterations)
    stencils = _point_edge_stencils(pe_pairs, x0.shape[0])
    return _max_step(x0, x1, stencils, 0, min_gap_fraction, max_iterations)
