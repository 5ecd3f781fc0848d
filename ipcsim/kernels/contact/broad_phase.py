"""Broad phase: axis-aligned boxes and a bounding volume hierarchy (BVH).

Candidates are pairs of primitives whose boxes overlap (closed intervals on every axis):

    overlap(A, B)  <=>  A.lo[a] <= B.hi[a]  and  B.lo[a] <= A.hi[a]   for a = x, y, z

A box is built over one or two positions of the primitive's vertices (x0, or x0 and x1 for a
swept box of a linear trajectory) and grown by ``inflation / 2`` on every side, so two boxes
overlap iff their un-inflated boxes are at most ``inflation`` apart on every axis.

The BVH sorts primitives by the Morton code of their box centre and groups them into leaves of
``LEAF_SIZE`` consecutive primitives; the leaves are the bottom of a complete binary tree stored
in heap order (node i has children 2i+1 and 2i+2, the ``n_leaf_slots`` leaves are the last
nodes). Padding leaves hold an empty box (lo = +inf, hi = -inf) that overlaps nothing. The tree
is built in O(n log n) (the sort) and queried in parallel, by groups of primitives next in
Morton order: one walk with the group's union box finds the leaves, then each query tests
those leaves' boxes. A first pass counts each query's hits and keeps up to ``_BUFFER`` of
them in the query's own row; the output is filled at prefix-sum offsets (queries with more
hits walk the tree again), so every query writes only its own slots and the output is the
same for any number of threads. Within one
primitive set (EE) a query only visits leaf slots after its own, so each pair is found once.

Why a BVH: sort-and-sweep along one axis degenerates on flat, axis-aligned faces (every
primitive of a face perpendicular to the sweep axis overlaps every other there: the two-cube
benchmark makes tens of millions of box tests), and a uniform grid suits only boxes of similar
size (swept boxes of fast vertices, long thin triangles). The BVH costs about the same as the
grid on uniform meshes and does not depend on box sizes.

Per-primitive tags ``(m, 2) int64`` hold ``[body id, kinematic flag]``. A pair is dropped when
the primitives share a vertex, when ``self_collision`` is off and both have the same body, or
when both are kinematic.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit, prange

from ipcsim.compiler.twin import kernel

LEAF_SIZE = 4
_STACK = 64  # depth of a complete tree over < 2**62 leaves, plus slack
_MORTON_BITS = 21  # bits per axis: 3 * 21 = 63 bits fit in an int64


@kernel(parallel=True)
def primitive_boxes(x0, x1, prims, inflation):
    """Boxes ``(m, 6) = [lo_x, lo_y, lo_z, hi_x, hi_y, hi_z]`` of ``prims (m, k)`` over the
    positions ``x0`` and ``x1`` (pass ``x1 = x0`` for a static box), grown by inflation/2."""
    m = prims.shape[0]
    k = prims.shape[1]
    r = 0.5 * inflation
    boxes = np.empty((m, 6))
    for i in prange(m):
        for a in range(3):
            lo = np.inf
            hi = -np.inf
            for j in range(k):
                v = prims[i, j]
                lo = min(lo, x0[v, a], x1[v, a])
                hi = max(hi, x0[v, a], x1[v, a])
            boxes[i, a] = lo - r
            boxes[i, 3 + a] = hi + r
    return boxes


@njit(cache=True)
def _spread_bits(v):
    # interleave: bit b of v moves to bit 3b (21 input bits -> 63 output bits)
    v &= 0x1FFFFF
    v = (v | (v << 32)) & 0x1F00000000FFFF
    v = (v | (v << 16)) & 0x1F0000FF0000FF
    v = (v | (v << 8)) & 0x100F00F00F00F00F
    v = (v | (v << 4)) & 0x10C30C30C30C30C3
    v = (v | (v << 2)) & 0x1249249249249249
    return v


@njit(cache=True)
def _morton_codes(boxes):
    # centre c quantised on the bounding box of all centres: q = floor((c - lo) / ext * (2^21 - 1))
    m = boxes.shape[0]
    cen = np.empty((m, 3))
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(m):
        for a in range(3):
            c = 0.5 * (boxes[i, a] + boxes[i, 3 + a])
            if not np.isfinite(c):
                c = 0.0
            cen[i, a] = c
            lo[a] = min(lo[a], c)
            hi[a] = max(hi[a], c)
    scale = np.empty(3)
    top = float((1 << _MORTON_BITS) - 1)
    for a in range(3):
        ext = hi[a] - lo[a]
        scale[a] = top / ext if ext > 0.0 else 0.0
    codes = np.empty(m, np.int64)
    for i in range(m):
        code = 0
        for a in range(3):
            q = int((cen[i, a] - lo[a]) * scale[a])
            q = min(max(q, 0), (1 << _MORTON_BITS) - 1)
            code |= _spread_bits(q) << a
        codes[i] = code
    return codes


@njit(cache=True)
def build_bvh(boxes):
    """BVH over ``boxes (m, 6)``. Returns ``(nodes, leaf_boxes, order, last_slot)``: node boxes
    in heap order, the primitive boxes in leaf-slot order, the primitive index of each slot,
    and the last slot under each node (-1 under a padding leaf)."""
    m = boxes.shape[0]
    order = np.argsort(_morton_codes(boxes), kind="mergesort")
    n_leaves = max(1, (m + LEAF_SIZE - 1) // LEAF_SIZE)
    n_slots = 1
    while n_slots < n_leaves:
        n_slots *= 2
    n_nodes = 2 * n_slots - 1
    first_leaf = n_slots - 1
    leaf_boxes = np.empty((m, 6))
    for s in range(m):
        for c in range(6):
            leaf_boxes[s, c] = boxes[order[s], c]
    nodes = np.empty((n_nodes, 6))
    last_slot = np.empty(n_nodes, np.int64)
    for lf in range(n_slots):
        nd = first_leaf + lf
        for a in range(3):
            nodes[nd, a] = np.inf
            nodes[nd, 3 + a] = -np.inf
        end = min((lf + 1) * LEAF_SIZE, m)
        last_slot[nd] = end - 1 if end > lf * LEAF_SIZE else -1
        for s in range(lf * LEAF_SIZE, end):
            for a in range(3):
                nodes[nd, a] = min(nodes[nd, a], leaf_boxes[s, a])
                nodes[nd, 3 + a] = max(nodes[nd, 3 + a], leaf_boxes[s, 3 + a])
    for nd in range(first_leaf - 1, -1, -1):
        c0 = 2 * nd + 1
        c1 = c0 + 1
        last_slot[nd] = max(last_slot[c0], last_slot[c1])
        for a in range(3):
            nodes[nd, a] = min(nodes[c0, a], nodes[c1, a])
            nodes[nd, 3 + a] = max(nodes[c0, 3 + a], nodes[c1, 3 + a])
    return nodes, leaf_boxes, order, last_slot


@njit(cache=True)
def _overlaps(b, i, q0, q1, q2, q3, q4, q5):
    return (b[i, 0] <= q3 and q0 <= b[i, 3] and b[i, 1] <= q4 and q1 <= b[i, 4]
            and b[i, 2] <= q5 and q2 <= b[i, 5])


@njit(cache=True)
def _leaves_met(box, min_slot, tree, leaves, stack):
    # depth-first walk with box = (lo_x, lo_y, lo_z, hi_x, hi_y, hi_z) over the slots
    # > min_slot: the leaves (heap node numbers, in slot order) whose boxes overlap it; the
    # first len(leaves) go to leaves; returns how many there are
    nodes, last_slot = tree[0], tree[3]
    q0, q1, q2, q3, q4, q5 = box
    first_leaf = (nodes.shape[0] + 1) // 2 - 1
    cap = leaves.shape[0]
    stack[0] = 0
    sp = 1
    count = 0
    while sp > 0:
        sp -= 1
        nd = stack[sp]
        if last_slot[nd] <= min_slot or not _overlaps(nodes, nd, q0, q1, q2, q3, q4, q5):
            continue
        if nd >= first_leaf:
            if count < cap:
                leaves[count] = nd
            count += 1
        else:
            stack[sp] = 2 * nd + 2
            stack[sp + 1] = 2 * nd + 1
            sp += 2
    return count


@njit(cache=True)
def _union_box(qboxes, qorder, g0, g1):
    # the box of the queries qorder[g0:g1]; a NaN box overlaps nothing, so it is skipped
    u0 = u1 = u2 = np.inf
    u3 = u4 = u5 = -np.inf
    for s in range(g0, g1):
        qi = qorder[s]
        if qboxes[qi, 0] < u0:
            u0 = qboxes[qi, 0]
        if qboxes[qi, 1] < u1:
            u1 = qboxes[qi, 1]
        if qboxes[qi, 2] < u2:
            u2 = qboxes[qi, 2]
        if qboxes[qi, 3] > u3:
            u3 = qboxes[qi, 3]
        if qboxes[qi, 4] > u4:
            u4 = qboxes[qi, 4]
        if qboxes[qi, 5] > u5:
            u5 = qboxes[qi, 5]
    return u0, u1, u2, u3, u4, u5


@njit(cache=True)
def _scan_leaves(qi, min_slot, leaves, n_leaves, query, tree, self_collision, dst):
    # the kept pairs of query qi among the slots > min_slot of the given leaves (in slot
    # order): the first len(dst) tree primitive indices go to dst; returns their number.
    # The pair filter is written out here: as a call taking the arrays it cost twice
    # the whole scan (reference counts), and most overlapping boxes share a vertex
    qboxes, qprims, qtags = query
    nodes, leaf_boxes, order, last_slot, tprims, ttags = tree
    q0, q1, q2 = qboxes[qi, 0], qboxes[qi, 1], qboxes[qi, 2]
    q3, q4, q5 = qboxes[qi, 3], qboxes[qi, 4], qboxes[qi, 5]
    qa = qprims[qi, 0]  # a query primitive is a point or an edge: its first and last
    qb = qprims[qi, qprims.shape[1] - 1]  # vertex are all of them
    qbody = qtags[qi, 0]
    qkinematic = qtags[qi, 1] != 0
    kt = tprims.shape[1]
    m = leaf_boxes.shape[0]
    first_leaf = (nodes.shape[0] + 1) // 2 - 1
    cap = dst.shape[0]
    count = 0
    for k in range(n_leaves):
        nd = leaves[k]
        if not _overlaps(nodes, nd, q0, q1, q2, q3, q4, q5):
            continue
        lf = nd - first_leaf
        for s in range(max(lf * LEAF_SIZE, min_slot + 1), min((lf + 1) * LEAF_SIZE, m)):
            if not _overlaps(leaf_boxes, s, q0, q1, q2, q3, q4, q5):
                continue
            j = order[s]
            # dropped: same body without self collision, both kinematic, a shared vertex
            keep = self_collision or qbody != ttags[j, 0]
            if keep and qkinematic and ttags[j, 1] != 0:
                keep = False
            for b in range(kt):
                v = tprims[j, b]
                if v == qa or v == qb:
                    keep = False
            if keep:
                if count < cap:
                    dst[count] = j
                count += 1
    return count


@njit(cache=True)
def _pairs_of_one(qi, min_slot, query, tree, self_collision, dst, stack):
    # every kept pair of query qi walked alone (a query whose hits overflowed its buffer)
    box = _union_box(query[0], np.array([qi]), 0, 1)
    n = _leaves_met(box, min_slot, tree, np.empty(0, np.int64), stack)
    leaves = np.empty(n, np.int64)
    _leaves_met(box, min_slot, tree, leaves, stack)
    return _scan_leaves(qi, min_slot, leaves, n, query, tree, self_collision, dst)


_BUFFER = 16  # hits kept per query in the first pass; queries with more are walked again
_CHUNK = 256  # queries per parallel task
_GROUP = 8  # consecutive (Morton-ordered) queries that walk the tree together
_GROUP_LEAVES = 256  # leaves a group's walk keeps; a group that meets more walks again


@kernel(parallel=True)
def query_bvh(query, tree, same_set, self_collision):
    """All kept pairs ``(k, 2) = [query primitive, tree primitive]`` whose boxes overlap.

    ``query = (boxes, prims, tags)`` of the query primitives (points or edges); ``tree =
    (nodes, leaf_boxes, order, last_slot, prims, tags)``: :func:`build_bvh` of the tree
    primitives' boxes, their vertex indices and their tags. ``same_set``: query and tree
    are the same primitives (with the same boxes); each pair is reported once, as (i, j)
    with i < j. Rows come in a fixed order (by the Morton order of the query boxes, then
    by leaf slot).

    Queries walk the tree in groups of ``_GROUP`` consecutive ones in Morton order (close
    together in space): one walk with the union of their boxes finds the leaves any of
    them may meet, and each query then tests those leaves alone."""
    if query[1].shape[1] > 2:
        raise ValueError("a query primitive is a point or an edge")
    if same_set:
        qorder = tree[2]
        nq = qorder.shape[0]
    else:
        nq = query[0].shape[0]
        qorder = np.argsort(_morton_codes(query[0]), kind="mergesort")
    n_chunks = (nq + _CHUNK - 1) // _CHUNK
    counts = np.zeros(nq + 1, np.int64)
    buf = np.empty((nq, _BUFFER), np.int64)
    for c in prange(n_chunks):
        stack = np.empty(_STACK, np.int64)
        kept = np.empty(_GROUP_LEAVES, np.int64)
        for g0 in range(c * _CHUNK, min((c + 1) * _CHUNK, nq), _GROUP):
            g1 = min(g0 + _GROUP, (c + 1) * _CHUNK, nq)
            group_min_slot = g0 if same_set else -1
            box = _union_box(query[0], qorder, g0, g1)
            n_leaves = _leaves_met(box, group_min_slot, tree, kept, stack)
            leaves = kept
            if n_leaves > kept.shape[0]:
                leaves = np.empty(n_leaves, np.int64)
                _leaves_met(box, group_min_slot, tree, leaves, stack)
            for s in range(g0, g1):
                counts[s + 1] = _scan_leaves(qorder[s], s if same_set else -1, leaves,
                                             n_leaves, query, tree, self_collision, buf[s])
    offsets = np.cumsum(counts)
    out = np.empty((offsets[nq], 2), np.int64)
    for c in prange(n_chunks):
        stack = np.empty(_STACK, np.int64)
        for s in range(c * _CHUNK, min((c + 1) * _CHUNK, nq)):
            qi = qorder[s]
            k = counts[s + 1]
            o = offsets[s]
            if k > _BUFFER:  # overflow: walk again into a buffer of the exact size
                full = np.empty(k, np.int64)
                _pairs_of_one(qi, s if same_set else -1, query, tree, self_collision, full,
                              stack)
                for r in range(k):
                    out[o + r, 0] = qi
                    out[o + r, 1] = full[r]
            else:
                for r in range(k):
                    out[o + r, 0] = qi
                    out[o + r, 1] = buf[s, r]
            if same_set:  # report (min, max)
                for r in range(k):
                    if out[o + r, 1] < qi:
                        out[o + r, 0] = out[o + r, 1]
                        out[o + r, 1] = qi
    return out


@kernel()
def _overlapping(queries, held, same_kind, self_collision):
    """The (query, held) index pairs of ``query_bvh`` with a tree built over the held
    primitives; each side is (boxes, primitives, tags)."""
    boxes, prims, tags = held
    nodes, leaf_boxes, order, last_slot = build_bvh(boxes)
    return query_bvh(queries, (nodes, leaf_boxes, order, last_slot, prims, tags),
                     same_kind, self_collision)


@kernel()
def candidate_pairs(x0, x1, points, edges, triangles, tags, inflation, self_collision):
    """Every kept point-triangle and edge-edge pair of one mesh whose boxes over ``x0``
    and ``x1``, grown by ``inflation / 2``, overlap: ``(pt_rows, ee_rows, pt_index,
    ee_index)``, stencil rows (p, t0, t1, t2) and (ea0, ea1, eb0, eb1) with the
    (point, triangle) and (edge a, edge b) index pairs they come from. ``points (n, 1)``,
    ``tags = (point, edge, triangle tags)``. One call from Python for the boxes, both
    trees, both queries and the rows (nine calls apart: most of a small mesh's time)."""
    point_tags, edge_tags, tri_tags = tags
    point_boxes = primitive_boxes(x0, x1, points, inflation)
    edge_boxes = primitive_boxes(x0, x1, edges, inflation)
    tri_boxes = primitive_boxes(x0, x1, triangles, inflation)
    pt_index = _overlapping((point_boxes, points, point_tags),
                            (tri_boxes, triangles, tri_tags), False, self_collision)
    ee_index = _overlapping((edge_boxes, edges, edge_tags),
                            (edge_boxes, edges, edge_tags), True, self_collision)
    return (gather_rows(points, triangles, pt_index), gather_rows(edges, edges, ee_index),
            pt_index, ee_index)


@kernel()
def point_edge_candidate_pairs(x0, x1, points, edges, tags, inflation, self_collision):
    """Every kept point-edge pair of a 2D mesh (its boundary vertices ``points (n, 1)``
    against its boundary edges) whose boxes over ``x0`` and ``x1``, grown by
    ``inflation / 2``, overlap: ``(pe_rows, pe_index)``, stencil rows (p, e0, e1) and the
    (point, edge) index pairs they come from; ``tags = (point tags, edge tags)``. The
    tree holds the edges and the points query it, so a point meets no edge it is an
    endpoint of (``query_bvh``'s shared-vertex rule)."""
    point_tags, edge_tags = tags
    point_boxes = primitive_boxes(x0, x1, points, inflation)
    edge_boxes = primitive_boxes(x0, x1, edges, inflation)
    pe_index = _overlapping((point_boxes, points, point_tags),
                            (edge_boxes, edges, edge_tags), False, self_collision)
    return gather_rows(points, edges, pe_index), pe_index


@njit(cache=True)
def primitive_tags(prims, body_of_vertex, kinematic_vertex):
    """Tags ``(m, 2) = [body id, kinematic]`` of ``prims (m, k)``: the body of the first vertex,
    and kinematic = 1 when every vertex of the primitive is kinematic."""
    m = prims.shape[0]
    tags = np.empty((m, 2), np.int64)
    for i in range(m):
        tags[i, 0] = body_of_vertex[prims[i, 0]]
        kin = 1
        for j in range(prims.shape[1]):
            if not kinematic_vertex[prims[i, j]]:
                kin = 0
        tags[i, 1] = kin
    return tags


@njit(cache=True)
def gather_rows(first, second, pairs):
    """Stencil rows ``(k, kf + ks)``: ``first[pairs[:, 0]]`` followed by ``second[pairs[:, 1]]``
    (PT rows (p, t0, t1, t2) and EE rows (ea0, ea1, eb0, eb1) in global vertex numbers)."""
    k = pairs.shape[0]
    kf = first.shape[1]
    ks = second.shape[1]
    rows = np.empty((k, kf + ks), np.int64)
    for r in range(k):
        for c in range(kf):
            rows[r, c] = first[pairs[r, 0], c]
        for c in range(ks):
            rows[r, kf + c] = second[pairs[r, 1], c]
    return rows


@kernel(parallel=True)
def swept_pairs_within(x0, x1, pairs, split, inflation):
    """Mask of the pairs (rows of 4 vertices, or of 3 for point-edge pairs: the first
    ``split`` form one primitive, the rest the other) whose boxes over the motion
    x0 -> x1, grown by inflation/2, overlap:
    the same test as the broad phase, applied to a known list of pairs (cheaper than a new
    query when the list is a superset, as for a shorter part of an already swept step)."""
    m = pairs.shape[0]
    keep = np.empty(m, dtype=np.bool_)
    r = 0.5 * inflation
    for i in prange(m):
        ok = True
        for a in range(3):
            lo0 = np.inf
            hi0 = -np.inf
            lo1 = np.inf
            hi1 = -np.inf
            for j in range(pairs.shape[1]):
                v = pairs[i, j]
                lo = min(x0[v, a], x1[v, a])
                hi = max(x0[v, a], x1[v, a])
                if j < split:
                    lo0 = min(lo0, lo)
                    hi0 = max(hi0, hi)
                else:
                    lo1 = min(lo1, lo)
                    hi1 = max(hi1, hi)
            if not (lo0 - r <= hi1 + r and lo1 - r <= hi0 + r):
                ok = False
                break
        keep[i] = ok
    return keep
