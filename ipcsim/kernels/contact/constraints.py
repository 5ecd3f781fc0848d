"""Collision constraint functions of the SQP and QP baselines, per pair: value and gradient.

The baselines keep c(x) ≥ offset for every point–triangle (PT) stencil (p, t0, t1, t2) and
edge–edge (EE) stencil (ea0, ea1, eb0, eb1) in their active set, linearised at each iterate.
The original program offers several c; these are the ones its example scripts use:

* **volume** (six times a signed tet volume): PT c = (t1 − p)·((t0 − p) × (t2 − p)),
  positive when p is on the side the triangle's normal (t1 − t0) × (t2 − t0) points to;
  EE c = (eb1 − ea0)·((ea1 − ea0) × (eb0 − ea0)). The gradient is exact.
* **gap** (the original's ``graphics`` / ``gapFunction``, after Harmon et al. 2008): the
  signed distance to the triangle's plane, c = n̂·(p − t0), n̂ the unit normal above; for
  EE the signed distance between the edges' lines, c = n̂·(eb0 − ea0), n̂ the unit
  (eb1 − eb0) × (ea1 − ea0). Gradient: w_i n̂ for vertex i, w = (1, −α0, −α1, −α2) with α
  the barycentric coordinates of p's projection onto the plane (PT), w = (−(1 − s), −s,
  1 − t, t) with s, t the parameters of the lines' closest points (EE). That is the exact
  gradient: the variation of n̂ is orthogonal to n̂, and p − Σαt (resp. the vector between
  the closest points) is parallel to n̂. (The original clamps s, t to the edges in the
  gradient; they agree whenever the closest points lie on both edges.)
* **Verschoor** (Verschoor and Jalba 2019): the same value, linearised with the weights w
  of the contact point at the time of impact instead (given per pair, from CCD): the
  gradient with n̂ held fixed, as the original computes it. NaN weights switch a pair off
  (``INACTIVE``): the original drops a Verschoor pair whose motion no longer collides.

The sign convention of a pair (which side is "outside") is applied by the caller. A
degenerate pair (zero-area triangle, parallel edges) gets c = ``INACTIVE`` and a zero
gradient: a constraint that always holds.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

VOLUME, GAP, VERSCHOOR = 0, 1, 2
INACTIVE = 1e28  # the value of a constraint that cannot be formed (as the original)
# sin² of the angle between the edges (or the triangle's sides) below this: degenerate;
# the original skips edges with |cos| > 1 − 1e-12, i.e. sin² < 2e-12
_PARALLEL_TOL = 2e-12


@njit(cache=True)
def _sub(x, i, j):
    return x[i] - x[j]


@njit(cache=True)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def _volume(v0, v1, v2, v3, g):
    """c = (v3 − v0)·((v1 − v0) × (v2 − v0)); g (4, 3) its gradient w.r.t. v0..v3."""
    a, b, d = v1 - v0, v2 - v0, v3 - v0
    g[1] = _cross(b, d)
    g[2] = _cross(d, a)
    g[3] = _cross(a, b)
    g[0] = -(g[1] + g[2] + g[3])
    return np.dot(d, g[3])


@njit(cache=True)
def _pt_volume(q, g):
    # (p, t0, t1, t2) -> v0 = p, v1 = t0, v2 = t2, v3 = t1
    h = np.empty((4, 3))
    c = _volume(q[0], q[1], q[3], q[2], h)
    g[0], g[1], g[2], g[3] = h[0], h[1], h[3], h[2]
    return c


@njit(cache=True)
def _pt_plane(q):
    """(c, n̂, α0, α1, α2, ok): signed distance of q[0] to the plane of q[1..3] and the
    barycentric coordinates of its projection."""
    e1, e2 = q[2] - q[1], q[3] - q[1]
    n = _cross(e1, e2)
    nn = np.dot(n, n)
    if not nn > _PARALLEL_TOL * np.dot(e1, e1) * np.dot(e2, e2):
        return 0.0, n, 0.0, 0.0, 0.0, False
    n = n / np.sqrt(nn)
    r = q[0] - q[1]
    c = np.dot(n, r)
    r = r - c * n  # the projection, relative to t0
    d00, d01, d11 = np.dot(e1, e1), np.dot(e1, e2), np.dot(e2, e2)
    d20, d21 = np.dot(r, e1), np.dot(r, e2)
    den = nn  # = d00 d11 − d01², without its cancellation
    b1 = (d11 * d20 - d01 * d21) / den
    b2 = (d00 * d21 - d01 * d20) / den
    return c, n, 1.0 - b1 - b2, b1, b2, True


@njit(cache=True)
def _ee_line(q):
    """(c, n̂, s, t, ok): signed distance between the lines of edges q[0]q[1] and q[2]q[3]
    along n̂ = (db × da)/|db × da| and the parameters of their closest points."""
    da, db = q[1] - q[0], q[3] - q[2]
    n = _cross(db, da)
    nn = np.dot(n, n)
    aa, bb = np.dot(da, da), np.dot(db, db)
    if not nn > _PARALLEL_TOL * aa * bb:
        return 0.0, n, 0.0, 0.0, False
    n = n / np.sqrt(nn)
    r = q[0] - q[2]
    ab, d, e = np.dot(da, db), np.dot(da, r), np.dot(db, r)
    den = nn  # = aa bb − ab², without its cancellation
    s = (ab * e - bb * d) / den
    t = (aa * e - ab * d) / den
    return np.dot(n, q[2] - q[0]), n, s, t, True


@njit(cache=True)
def _gap(q, is_ee, w_given, use_given, g):
    """Gap value; writes g = w_i n̂ and returns (c, ok)."""
    w = np.empty(4)
    if is_ee:
        c, n, s, t, ok = _ee_line(q)
        w[0], w[1], w[2], w[3] = -(1.0 - s), -s, 1.0 - t, t
    else:
        c, n, a0, a1, a2, ok = _pt_plane(q)
        w[0], w[1], w[2], w[3] = 1.0, -a0, -a1, -a2
    if not ok or (use_given and not w_given[0] == w_given[0]):  # NaN weights: switched off
        return INACTIVE, False
    if use_given:
        w[:] = w_given
    for i in range(4):
        g[i] = w[i] * n
    return c, True


@njit(cache=True, parallel=True)
def constraint_values_and_gradients(x, pairs, is_ee, kind, weights):
    """c (k,) and ∇c (k, 4, 3) of every stencil of ``pairs`` (k, 4) at x (n, 3), all PT
    (``is_ee`` False) or all EE; ``kind`` VOLUME, GAP or VERSCHOOR (``weights`` (k, 4): the
    contact weights w; ignored otherwise)."""
    k = pairs.shape[0]
    c = np.empty(k)
    grad = np.zeros((k, 4, 3))
    for i in prange(k):
        q = np.empty((4, 3))
        for j in range(4):
            q[j] = x[pairs[i, j]]
        g = np.zeros((4, 3))
        if kind == VOLUME:
            if is_ee:
                c[i] = _volume(q[0], q[1], q[2], q[3], g)
            else:
                c[i] = _pt_volume(q, g)
        else:
            c[i], ok = _gap(q, is_ee, weights[i], kind == VERSCHOOR, g)
        grad[i] = g
    return c, grad


@njit(cache=True, parallel=True)
def contact_weights(x0, x1, pairs, is_ee, toi):
    """(k, 4) weights w of the contact point of each stencil at its time of impact toi
    (positions x0 + toi (x1 − x0)): PT (1, −α) with α the barycentric coordinates of the
    point's projection onto the triangle; EE (−(1 − s), −s, 1 − t, t) with s, t the
    closest points' parameters clamped to the edges. Degenerate stencils get zeros."""
    k = pairs.shape[0]
    w = np.zeros((k, 4))
    for i in prange(k):
        q = np.empty((4, 3))
        for j in range(4):
            v = pairs[i, j]
            q[j] = x0[v] + toi[i] * (x1[v] - x0[v])
        if is_ee:
            c, n, s, t, ok = _ee_line(q)
            if ok:
                s, t = min(max(s, 0.0), 1.0), min(max(t, 0.0), 1.0)
                w[i, 0], w[i, 1], w[i, 2], w[i, 3] = -(1.0 - s), -s, 1.0 - t, t
        else:
            c, n, a0, a1, a2, ok = _pt_plane(q)
            if ok:
                w[i, 0], w[i, 1], w[i, 2], w[i, 3] = 1.0, -a0, -a1, -a2
    return w
