"""Exact intersection predicates for checking a frame: segment-triangle and tet orientation;
in a 2D scene (the plane z = 0) segment-segment crossing and triangle orientation.

Every sign below is *exact* for finite float64 input: no tolerance, no epsilon. Each
orientation determinant is evaluated in up to three tiers:

1. a floating-point filter (Shewchuk's static bound A): the float determinant is trusted
   when |det| > errbound * permanent. Valid only where no intermediate underflows or
   overflows, so it runs only when every coordinate is 0 or in [2^-250, 2^250];
2. exact expansion arithmetic (error-free two-sum / two-product, Shewchuk-style
   expansions): the determinant written as a sum of products of the *input coordinates*
   (no rounded differences), every product an exact 2- or 4-term expansion, summed with
   Grow-Expansion. Exact on the same coordinate range (all partial products stay normal);
3. exact big-integer arithmetic for anything else (1e-300, subnormals, 1e+300): each
   coordinate is m * 2^e with an integer 53-bit m; the determinant is an integer sum
   over 30-bit limbs, shifted to a common exponent.

Conventions
-----------
``orient3d(a, b, c, d) = sign det[b - a, c - a, d - a]``: positive when d lies on the
side of the plane abc that (b - a) x (c - a) points to. A tet (a, b, c, d) has positive
volume exactly when orient3d > 0.

``segment_triangle_intersection(p, q, a, b, c)`` answers whether the *closed* segment pq
meets the *closed* triangle abc (distance exactly zero counts: IPC promises a positive
distance, so touching is a violation). It returns a kind:

- 0: disjoint;
- 1: transversal - pq is not contained in the triangle's plane and meets the triangle at
  one point (interior, edge, vertex, or a segment endpoint on the triangle);
- 2: coplanar - pq lies in the triangle's plane and overlaps the triangle (decided by
  exact 2D tests on an axis projection that is one-to-one on that plane), or the
  triangle is degenerate (collinear vertices) and pq meets it (then decided by exact
  segment-segment tests against its three edges).

The predicate is purely geometric: a segment and a triangle sharing a vertex (equal
coordinates) always meet. Callers that want mesh intersections skip pairs that share a
vertex *index* (see ``edge_triangle_candidates``); a fold of an edge over an adjacent
triangle is then not reported, as in ipctk's ``has_intersections``.

Non-finite coordinates give an unspecified answer; callers check ``np.isfinite`` first.

2D scenes
---------
A 2D scene lies in the plane z = 0; its bodies are triangles and their boundaries are
edges. ``segments_cross_2d(p, q, r, s)`` answers whether the closed segments pq and rs
share a point of the plane (the exact ``orient2d`` signs with z dropped: a proper
crossing, an endpoint on the other segment, or collinear overlap); a triangle (a, b, c)
is inverted or flat exactly when ``orient2d(a, b, c, 2) <= 0``. Boundary edges that share
a vertex index are not tested against each other, as in 3D.

Broad phase
-----------
``edge_triangle_candidates`` is the package's broad phase (``kernels/contact/broad_phase.py``, the
BVH the simulation uses), run on exact boxes: no inflation, and the overlap test is
inclusive (closed intervals), so a pair whose closed segment and closed triangle share a
point always has overlapping boxes and is a candidate. The exactness of the check rests
on the predicates below; the broad phase only has to be complete, which a box test is.
``classify_edge_triangle_pairs`` runs sequentially (see the note there).
"""

from __future__ import annotations

import math
from itertools import permutations

import numpy as np
from ipcsim.compiler.jit import njit

from ipcsim.kernels.contact.broad_phase import build_bvh, primitive_boxes, query_bvh
from ipcsim.kernels.algebra.linalg import point3, tet_signed_volumes, triangle_signed_areas
from ipcsim.compiler.twin import kernel

_EPS = 2.0**-53
_O3D_ERRBOUND = (7.0 + 56.0 * _EPS) * _EPS  # Shewchuk o3derrboundA
_O2D_ERRBOUND = (3.0 + 16.0 * _EPS) * _EPS  # Shewchuk ccwerrboundA
_SPLITTER = 134217729.0  # 2^27 + 1, Dekker's split
_LO = 2.0**-250  # coordinates 0 or in [_LO, _HI]: filter and expansions are exact
_HI = 2.0**250
_LIMB_BITS = 30
_LIMB_MASK = (1 << 30) - 1
_TWO53 = 9007199254740992.0


def _det_terms(n: int):
    """det of the (n+1)x(n+1) matrix with rows (1, p_i) as a signed sum of products.

    det[[1, p0], [1, p1], ...] = det[p1 - p0, p2 - p0, ...] (subtract row 0, expand on
    the column of ones). Factor index i*n + axis refers to coordinate axis of point i.
    """
    terms, signs = [], []
    for perm in permutations(range(n + 1)):
        inversions = sum(perm[i] > perm[j] for i in range(n + 1) for j in range(i + 1, n + 1))
        terms.append([row * n + col - 1 for row, col in enumerate(perm) if col != 0])
        signs.append(-1 if inversions % 2 else 1)
    return np.array(terms, dtype=np.int64), np.array(signs, dtype=np.int64)


ORIENT3D_TERMS, ORIENT3D_SIGNS = _det_terms(3)  # (24, 3), (24,)
ORIENT2D_TERMS, ORIENT2D_SIGNS = _det_terms(2)  # (6, 2), (6,)


# ---------------------------------------------------------------- error-free transforms


@njit(cache=True)
def _two_sum(a, b):
    # a + b = x + y exactly (Knuth)
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


@njit(cache=True)
def _split(a):
    # a = hi + lo, each with <= 26 significant bits (Dekker)
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


@njit(cache=True)
def _two_product(a, b):
    # a * b = x + y exactly (Dekker / Shewchuk Two-Product)
    x = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    err = ((x - ah * bh) - al * bh) - ah * bl
    return x, al * bl - err


@njit(cache=True)
def _grow(e, n, b):
    # e[:n] nonoverlapping, increasing magnitude; e += b in place, zero components dropped
    q = b
    m = 0
    for i in range(n):
        q, h = _two_sum(q, e[i])
        if h != 0.0:
            e[m] = h
            m += 1
    if q != 0.0:
        e[m] = q
        m += 1
    return m


@njit(cache=True)
def expansion_sign(vals, terms, signs):
    """Exact sign of sum_t signs[t] * prod_f vals[terms[t, f]] by expansion arithmetic.

    Exact when every nonzero |vals| lies in [2^-250, 2^250] and each term has at most
    3 factors (every partial product is then a normal number).
    """
    nt, deg = terms.shape
    e = np.empty(nt * (1 << (deg - 1)) + 1)
    part = np.empty(1 << deg)
    tmp = np.empty(1 << deg)
    n = 0
    for t in range(nt):
        part[0] = signs[t] * vals[terms[t, 0]]  # exact: sign flip
        np_ = 1
        for f in range(1, deg):
            v = vals[terms[t, f]]
            for k in range(np_):
                hi, lo = _two_product(part[k], v)
                tmp[2 * k] = hi
                tmp[2 * k + 1] = lo
            np_ *= 2
            part[:np_] = tmp[:np_]
        for k in range(np_):
            if part[k] != 0.0:
                n = _grow(e, n, part[k])
    if n == 0:
        return 0
    # the largest (last) component of a nonoverlapping expansion carries the sign
    return 1 if e[n - 1] > 0.0 else -1


@njit(cache=True)
def _normalize_limbs(acc):
    carry = 0
    for k in range(acc.size):
        v = acc[k] + carry
        acc[k] = v & _LIMB_MASK
        carry = v >> _LIMB_BITS


@njit(cache=True)
def bigint_sign(vals, terms, signs):
    """Exact sign of the same homogeneous sum of products for any finite float64 input.

    vals[i] = m_i 2^(e_i) with integer |m_i| < 2^53. With E = min e_i every term is the
    integer prod m * 2^(sum e - deg E) times 2^(deg E), so the sign is that of an integer
    sum, kept as two nonnegative accumulators (positive and negative terms) in 30-bit limbs.
    Returns 0 for non-finite input.
    """
    nv = vals.size
    nt, deg = terms.shape
    mant = np.zeros(nv, np.int64)
    expo = np.zeros(nv, np.int64)
    emin = 1 << 20
    emax = -(1 << 20)
    for i in range(nv):
        v = vals[i]
        if not np.isfinite(v):
            return 0
        if v != 0.0:
            f, ex = math.frexp(v)  # v = f 2^ex, 1/2 <= |f| < 1
            mant[i] = np.int64(f * _TWO53)  # exact integer, |m| < 2^53
            expo[i] = ex - 53
            emin = min(emin, expo[i])
            emax = max(emax, expo[i])
    if emin > emax:
        return 0
    plen_max = 2 * deg + 1
    nl = (deg * (emax - emin)) // _LIMB_BITS + plen_max + 4
    pos = np.zeros(nl, np.int64)
    neg = np.zeros(nl, np.int64)
    prod = np.zeros(plen_max + 1, np.int64)
    tmp = np.zeros(plen_max + 1, np.int64)
    for t in range(nt):
        s = signs[t]
        shift = 0
        prod[:] = 0
        prod[0] = 1
        plen = 1
        zero = False
        for f in range(deg):
            i = terms[t, f]
            m = mant[i]
            if m == 0:
                zero = True
                break
            if m < 0:
                s = -s
                m = -m
            shift += expo[i] - emin
            lo = m & _LIMB_MASK
            hi = m >> _LIMB_BITS  # < 2^23
            tmp[: plen + 2] = 0
            for k in range(plen):
                tmp[k] += prod[k] * lo  # < 2^60
                tmp[k + 1] += prod[k] * hi  # < 2^53
            carry = 0
            for k in range(plen + 2):
                v = tmp[k] + carry
                prod[k] = v & _LIMB_MASK
                carry = v >> _LIMB_BITS
            plen += 2
        if zero:
            continue
        acc = pos if s > 0 else neg
        q = shift // _LIMB_BITS
        r = shift - q * _LIMB_BITS
        for k in range(plen):
            v = prod[k] << r  # < 2^60; limbs grow by < 2^31 per term, normalised at the end
            acc[q + k] += v & _LIMB_MASK
            acc[q + k + 1] += v >> _LIMB_BITS
    _normalize_limbs(pos)
    _normalize_limbs(neg)
    for k in range(nl - 1, -1, -1):
        if pos[k] != neg[k]:
            return 1 if pos[k] > neg[k] else -1
    return 0


@njit(cache=True)
def _fits(v):
    av = abs(v)
    return av == 0.0 or (av >= _LO and av <= _HI)


@njit(cache=True)
def _exact_sign(vals, terms, signs):
    for i in range(vals.size):
        if not _fits(vals[i]):
            return bigint_sign(vals, terms, signs)
    return expansion_sign(vals, terms, signs)


# ---------------------------------------------------------------- orientation predicates


@njit(cache=True)
def _points_fit(a, b, c, d):
    for k in range(3):
        if not (_fits(a[k]) and _fits(b[k]) and _fits(c[k]) and _fits(d[k])):
            return False
    return True


@njit(cache=True)
def orient3d_exact(a, b, c, d):
    """sign det[b - a, c - a, d - a] without the float filter (tiers 2 and 3)."""
    vals = np.empty(12)
    for k in range(3):
        vals[k] = a[k]
        vals[3 + k] = b[k]
        vals[6 + k] = c[k]
        vals[9 + k] = d[k]
    return _exact_sign(vals, ORIENT3D_TERMS, ORIENT3D_SIGNS)


@njit(cache=True)
def orient3d(a, b, c, d):
    """Exact sign (-1, 0, 1) of det[b - a, c - a, d - a] for points given as (3,) arrays."""
    if _points_fit(a, b, c, d):
        ux = b[0] - a[0]
        uy = b[1] - a[1]
        uz = b[2] - a[2]
        vx = c[0] - a[0]
        vy = c[1] - a[1]
        vz = c[2] - a[2]
        wx = d[0] - a[0]
        wy = d[1] - a[1]
        wz = d[2] - a[2]
        # det = u . (v x w)
        m1a = vy * wz
        m1b = vz * wy
        m2a = vz * wx
        m2b = vx * wz
        m3a = vx * wy
        m3b = vy * wx
        det = ux * (m1a - m1b) + uy * (m2a - m2b) + uz * (m3a - m3b)
        perm = (
            abs(ux) * (abs(m1a) + abs(m1b))
            + abs(uy) * (abs(m2a) + abs(m2b))
            + abs(uz) * (abs(m3a) + abs(m3b))
        )
        bound = _O3D_ERRBOUND * perm
        if det > bound:
            return 1
        if -det > bound:
            return -1
        if perm == 0.0:
            return 0  # every product is exactly zero
    return orient3d_exact(a, b, c, d)


@njit(cache=True)
def orient2d_exact(a, b, c, k):
    """orient2d of the projection that drops axis k, without the float filter."""
    i = (k + 1) % 3
    j = (k + 2) % 3
    vals = np.empty(6)
    vals[0] = a[i]
    vals[1] = a[j]
    vals[2] = b[i]
    vals[3] = b[j]
    vals[4] = c[i]
    vals[5] = c[j]
    return _exact_sign(vals, ORIENT2D_TERMS, ORIENT2D_SIGNS)


@njit(cache=True)
def orient2d(a, b, c, k):
    """Exact sign of det[b' - a', c' - a'] where ' drops axis k: (x, y) = axes (k+1, k+2) mod 3."""
    i = (k + 1) % 3
    j = (k + 2) % 3
    if (
        _fits(a[i]) and _fits(a[j]) and _fits(b[i]) and _fits(b[j])
        and _fits(c[i]) and _fits(c[j])
    ):
        left = (b[i] - a[i]) * (c[j] - a[j])
        right = (b[j] - a[j]) * (c[i] - a[i])
        det = left - right
        bound = _O2D_ERRBOUND * (abs(left) + abs(right))
        if det > bound:
            return 1
        if -det > bound:
            return -1
        if left == 0.0 and right == 0.0:
            return 0
    return orient2d_exact(a, b, c, k)


# ---------------------------------------------------------------- 2D and 3D segment tests


@njit(cache=True)
def _in_box_2d(p, q, r, k):
    # r (collinear with p, q in projection k) lies on the closed segment pq
    i = (k + 1) % 3
    j = (k + 2) % 3
    return (
        min(p[i], q[i]) <= r[i] <= max(p[i], q[i])
        and min(p[j], q[j]) <= r[j] <= max(p[j], q[j])
    )


@njit(cache=True)
def _segments_meet_2d(p, q, r, s, k):
    # closed segments pq and rs in the projection dropping axis k
    o1 = orient2d(p, q, r, k)
    o2 = orient2d(p, q, s, k)
    o3 = orient2d(r, s, p, k)
    o4 = orient2d(r, s, q, k)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return (
        (o1 == 0 and _in_box_2d(p, q, r, k))
        or (o2 == 0 and _in_box_2d(p, q, s, k))
        or (o3 == 0 and _in_box_2d(r, s, p, k))
        or (o4 == 0 and _in_box_2d(r, s, q, k))
    )


@njit(cache=True)
def _point_in_triangle_2d(x, a, b, c, k):
    # closed triangle, nondegenerate in projection k: the three signs do not disagree
    o1 = orient2d(a, b, x, k)
    o2 = orient2d(b, c, x, k)
    o3 = orient2d(c, a, x, k)
    return not ((o1 > 0 or o2 > 0 or o3 > 0) and (o1 < 0 or o2 < 0 or o3 < 0))


@njit(cache=True)
def segments_intersect_3d(p, q, r, s):
    """Exact: do the closed 3D segments pq and rs share a point?"""
    if orient3d(p, q, r, s) != 0:
        return False  # not coplanar
    # coplanar: a projection with a nonzero triangle area is one-to-one on the plane
    for k in range(3):
        if (
            orient2d(p, q, r, k) != 0 or orient2d(p, q, s, k) != 0
            or orient2d(r, s, p, k) != 0 or orient2d(r, s, q, k) != 0
        ):
            return _segments_meet_2d(p, q, r, s, k)
    # collinear: a projection in which the points are not all equal is one-to-one on the line
    for k in range(3):
        i = (k + 1) % 3
        j = (k + 2) % 3
        if not (
            p[i] == q[i] == r[i] == s[i] and p[j] == q[j] == r[j] == s[j]
        ):
            return _segments_meet_2d(p, q, r, s, k)
    return True  # all four points coincide


@njit(cache=True)
def segment_triangle_intersection(p, q, a, b, c):
    """Exact kind of contact of closed segment pq and closed triangle abc: 0 none,
    1 transversal, 2 coplanar or degenerate triangle (see the module docstring)."""
    sp = orient3d(a, b, c, p)
    sq = orient3d(a, b, c, q)
    if sp * sq > 0:
        return 0  # both endpoints strictly on one side
    if sp != 0 or sq != 0:
        # pq meets the plane at one point; it is in the closed triangle iff the line pq
        # sees the three edges with no two opposite orientations
        s1 = orient3d(p, q, a, b)
        s2 = orient3d(p, q, b, c)
        s3 = orient3d(p, q, c, a)
        if (s1 > 0 or s2 > 0 or s3 > 0) and (s1 < 0 or s2 < 0 or s3 < 0):
            return 0
        return 1
    for k in range(3):
        if orient2d(a, b, c, k) != 0:
            # pq lies in the triangle's plane; projection k is one-to-one on it
            if (
                _point_in_triangle_2d(p, a, b, c, k)
                or _point_in_triangle_2d(q, a, b, c, k)
                or _segments_meet_2d(p, q, a, b, k)
                or _segments_meet_2d(p, q, b, c, k)
                or _segments_meet_2d(p, q, c, a, k)
            ):
                return 2
            return 0
    # degenerate triangle (collinear or coincident vertices): the union of its edges
    if (
        segments_intersect_3d(p, q, a, b)
        or segments_intersect_3d(p, q, b, c)
        or segments_intersect_3d(p, q, c, a)
    ):
        return 2
    return 0


# ---------------------------------------------------------------- mesh-level kernels


@njit(cache=True)
def tet_orientations(x, tets, signs, volumes):
    """signs[t] = exact orient3d of tet t (int8); volumes[t] = its floating-point signed
    volume det[b-a, c-a, d-a] / 6 (``linalg.tet_signed_volumes``, not exact)."""
    for t in range(tets.shape[0]):
        signs[t] = orient3d(point3(x, tets[t, 0]), point3(x, tets[t, 1]),
                            point3(x, tets[t, 2]), point3(x, tets[t, 3]))
    volumes[:] = tet_signed_volumes(x, tets)


@njit(cache=True)
def _body_tags(n, body):
    # broad-phase tags [body id, kinematic = 0]; body 0 for all without body ids
    tags = np.zeros((n, 2), np.int64)
    if body.size > 0:
        tags[:, 0] = body
    return tags


@kernel()
def edge_triangle_candidates(x, edges, triangles, edge_body, triangle_body):
    """Pairs (edge, triangle) whose closed bounding boxes overlap and that share no vertex
    index, as an (m, 2) array. With nonempty body arrays, pairs whose edge and triangle
    have the same body are skipped.

    The package's broad phase (``broad_phase``: BVH over the triangles' boxes, queried with
    every edge's box), with exact boxes (no inflation: the min and max of the vertex
    coordinates) and its inclusive overlap test, so every pair whose closed segment and
    closed triangle share a point is a candidate. Rows come in the BVH's query order."""
    if edges.shape[0] == 0 or triangles.shape[0] == 0:
        return np.empty((0, 2), np.int64)
    edge_boxes = primitive_boxes(x, x, edges, 0.0)
    tri_boxes = primitive_boxes(x, x, triangles, 0.0)
    nodes, leaf_boxes, order, last_slot = build_bvh(tri_boxes)
    tree = (nodes, leaf_boxes, order, last_slot, triangles,
            _body_tags(triangles.shape[0], triangle_body))
    query = (edge_boxes, edges, _body_tags(edges.shape[0], edge_body))
    # self_collision off drops the pairs with equal body tags; without body ids keep all
    return query_bvh(query, tree, False, edge_body.size == 0)


@njit(cache=True)
def classify_edge_triangle_pairs(x, edges, triangles, pairs):
    """kinds[i] = segment_triangle_intersection of pair i (0 none, 1 transversal, 2 coplanar).

    The points go in as tuples (``linalg.point3``), not as row views of x: a view per
    point, with its reference count, cost more than the predicates themselves."""
    kinds = np.zeros(pairs.shape[0], np.int8)
    for i in range(pairs.shape[0]):
        e = pairs[i, 0]
        t = pairs[i, 1]
        kinds[i] = segment_triangle_intersection(
            point3(x, edges[e, 0]), point3(x, edges[e, 1]),
            point3(x, triangles[t, 0]), point3(x, triangles[t, 1]),
            point3(x, triangles[t, 2]),
        )
    return kinds


# ---------------------------------------------------------------- 2D scenes (z = 0)


@njit(cache=True)
def segments_cross_2d(p, q, r, s):
    """Exact: do the closed segments pq and rs of the plane z = 0 share a point?"""
    return _segments_meet_2d(p, q, r, s, 2)


@njit(cache=True)
def triangle_orientations(x, triangles, signs, areas):
    """signs[t] = exact orient2d of triangle t in the plane z = 0 (int8: 1 counter-
    clockwise, 0 flat, −1 inverted); areas[t] = its floating-point signed area
    (``linalg.triangle_signed_areas``, not exact)."""
    for t in range(triangles.shape[0]):
        signs[t] = orient2d(point3(x, triangles[t, 0]), point3(x, triangles[t, 1]),
                            point3(x, triangles[t, 2]), 2)
    areas[:] = triangle_signed_areas(x, triangles)


@kernel()
def edge_edge_candidates_2d(x, edges):
    """Pairs (i, j), i < j, of edges whose closed bounding boxes overlap and that share
    no vertex index, as an (m, 2) array: the package's broad phase (``broad_phase``'s
    BVH of the edges, queried by the edges themselves) on exact boxes with its inclusive
    overlap test, so every pair of closed segments that share a point is a candidate."""
    if edges.shape[0] < 2:
        return np.empty((0, 2), np.int64)
    boxes = primitive_boxes(x, x, edges, 0.0)
    nodes, leaf_boxes, order, last_slot = build_bvh(boxes)
    tags = _body_tags(edges.shape[0], np.empty(0, np.int64))
    return query_bvh((boxes, edges, tags), (nodes, leaf_boxes, order, last_slot, edges, tags),
                     True, True)


@njit(cache=True)
def crossing_edge_pairs_2d(x, edges, pairs):
    """crossing[i] = segments_cross_2d of the two edges of pairs[i] (bool)."""
    crossing = np.zeros(pairs.shape[0], np.bool_)
    for i in range(pairs.shape[0]):
        a = pairs[i, 0]
        b = pairs[i, 1]
        crossing[i] = segments_cross_2d(point3(x, edges[a, 0]), point3(x, edges[a, 1]),
                                        point3(x, edges[b, 0]), point3(x, edges[b, 1]))
    return crossing


# ---------------------------------------------------------------- containment


@njit(cache=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]  # path halving
        i = parent[i]
    return i


@njit(cache=True)
def _join_rows(parent, cells):
    for r in range(cells.shape[0]):
        a = _root(parent, cells[r, 0])
        for j in range(1, cells.shape[1]):
            b = _root(parent, cells[r, j])
            if a != b:
                parent[max(a, b)] = min(a, b)
                a = min(a, b)


@njit(cache=True)
def component_labels(n, tets, triangles):
    """labels[v] = the connected component of vertex v over the tets and triangles
    (vertices sharing a cell are connected), numbered 0, 1, ... in the order of their
    lowest vertex; -1 for a vertex in no cell. Union-find with path halving."""
    parent = np.arange(n)
    _join_rows(parent, tets)
    _join_rows(parent, triangles)
    used = np.zeros(n, np.bool_)
    for cells in (tets, triangles):
        for r in range(cells.shape[0]):
            for j in range(cells.shape[1]):
                used[cells[r, j]] = True
    labels = np.full(n, -1, np.int64)
    count = 0
    for v in range(n):  # a root is its component's lowest vertex: it comes first
        if used[v]:
            r = _root(parent, v)
            if r == v:
                labels[v] = count
                count += 1
            else:
                labels[v] = labels[r]
    return labels


@njit(cache=True)
def solid_angle(p, a, b, c):
    """The signed solid angle of triangle abc seen from p (Van Oosterom and Strackee),
    positive where abc turns counter-clockwise seen from p: on a closed surface with
    outward normals they sum to 4 pi at a point inside and to 0 outside. The sign of
    the triple product is the exact orient3d's (zero: p in the triangle's plane, where
    the angle is 0 unless p lies on the triangle, which is contact, not containment)."""
    side = orient3d(p, a, b, c)
    if side == 0:
        return 0.0
    ax, ay, az = a[0] - p[0], a[1] - p[1], a[2] - p[2]
    bx, by, bz = b[0] - p[0], b[1] - p[1], b[2] - p[2]
    cx, cy, cz = c[0] - p[0], c[1] - p[1], c[2] - p[2]
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc
           + (ax * cx + ay * cy + az * cz) * lb + (bx * cx + by * cy + bz * cz) * la)
    return 2.0 * math.atan2(side * abs(det), den)


@njit(cache=True)
def _component_triangles(triangle_component, k):
    """(start, order): the triangles of component c are order[start[c]:start[c + 1]]."""
    start = np.zeros(k + 1, np.int64)
    for t in range(triangle_component.shape[0]):
        start[triangle_component[t] + 1] += 1
    for c in range(k):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(triangle_component.shape[0], np.int64)
    for t in range(triangle_component.shape[0]):
        c = triangle_component[t]
        order[fill[c]] = t
        fill[c] += 1
    return start, order


@njit(cache=True)
def _component_boxes(x, triangles, start, order):
    k = start.shape[0] - 1
    boxes = np.empty((k, 6))
    for c in range(k):
        boxes[c, :3] = np.inf
        boxes[c, 3:] = -np.inf
        for s in range(start[c], start[c + 1]):
            for j in range(3):
                for a in range(3):
                    value = x[triangles[order[s], j], a]
                    boxes[c, a] = min(boxes[c, a], value)
                    boxes[c, 3 + a] = max(boxes[c, 3 + a], value)
    return boxes


@njit(cache=True)
def containments(x, representatives, triangles, triangle_component, container):
    """Pairs (q, c) of components such that component q's representative vertex lies
    inside the closed surface of component c (``container[c]``: its triangles form a
    closed, consistently oriented surface), as an (m, 2) int64 array: the winding number
    of c's triangles about the point (their solid angles over 4 pi) rounds to 1 or more.
    Only containers whose bounding box holds the point are summed over."""
    k = representatives.shape[0]
    start, order = _component_triangles(triangle_component, k)
    boxes = _component_boxes(x, triangles, start, order)
    pairs = np.empty((max(k, 1), 2), np.int64)
    m = 0
    for q in range(k):
        p = point3(x, representatives[q])
        for c in range(k):
            if c == q or not container[c] or not (
                    boxes[c, 0] <= p[0] <= boxes[c, 3] and boxes[c, 1] <= p[1] <= boxes[c, 4]
                    and boxes[c, 2] <= p[2] <= boxes[c, 5]):
                continue
            total = 0.0
            for s in range(start[c], start[c + 1]):
                t = order[s]
                total += solid_angle(p, point3(x, triangles[t, 0]), point3(x, triangles[t, 1]),
                                     point3(x, triangles[t, 2]))
            if total > 2.0 * math.pi:  # winding number above 1/2
                if m == pairs.shape[0]:
                    grown = np.empty((2 * m, 2), np.int64)
                    grown[:m] = pairs
                    pairs = grown
                pairs[m, 0] = q
                pairs[m, 1] = c
                m += 1
    return pairs[:m].copy()
