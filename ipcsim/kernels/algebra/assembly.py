"""Adding COO triplets to a CSC matrix over free DOFs, without going through scipy.

The Newton matrix is a fixed-pattern part (inertia, elasticity, damping; see
``solver/assembly.py``) plus the triplets of contact and friction, whose pattern changes
with the contact set. Those are counted per free column (``count_kept_columns``), put
in column buckets as (free row, value) (``bucket_kept``, term after term), and each
column is sorted, summed and merged into the fixed part (``merge_columns``): 12 bytes a
triplet besides the triplets themselves. Triplets of kinematic rows are dropped; those
of a free row and a kinematic column go into the coupling H_fk p_k.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit

from ipcsim.kernels.algebra.scatter import gather_dofs, local_dof


@njit(cache=True, inline="always")
def _kept_entry(t, rows, cols, vals, scale, free_index):
    """(free row, free column, value) of triplet t, the row −1 where it is not kept (a
    kinematic row or a zero value); the column is −1 for a kinematic one."""
    v = scale * vals[t]
    r = free_index[rows[t]]
    if r < 0 or v == 0.0:
        return -1, -1, v
    return r, free_index[cols[t]], v


@njit(cache=True)
def count_kept_columns(rows, cols, vals, scale, free_index, p, coupling, counts):
    """counts[c + 1] += the triplets (rows, cols, scale·vals) in DOF numbers that
    ``merge_columns`` keeps in free column c: a free row and a nonzero value; those of a
    free row and a kinematic column add scale·v·p[col] to coupling[row] instead."""
    for t in range(rows.shape[0]):
        r, c, v = _kept_entry(t, rows, cols, vals, scale, free_index)
        if r < 0:
            continue
        if c < 0:
            coupling[r] += v * p[cols[t]]
        else:
            counts[c + 1] += 1


@njit(cache=True)
def bucket_kept(rows, cols, vals, scale, free_index, fill, bucket_rows, bucket_vals):
    """The kept triplets of ``count_kept_columns`` into column buckets, in triplet order:
    (free row, value) at fill[c], fill[c] advancing."""
    for t in range(rows.shape[0]):
        r, c, v = _kept_entry(t, rows, cols, vals, scale, free_index)
        if r >= 0 and c >= 0:
            bucket_rows[fill[c]] = r
            bucket_vals[fill[c]] = v
            fill[c] += 1


@njit(cache=True)
def block_triplet_indices(stencils):
    """(rows, cols), int32, of the B = (3w)² entries of each stencil's 3w x 3w block (w =
    stencils.shape[1] vertices: 4 for point-triangle and edge-edge, 12 x 12 blocks; 3 for
    point-edge, 9 x 9), in the blocks' order, row-major: entry B k + 3w r + c couples DOF
    3 s[r//3] + r%3 with DOF 3 s[c//3] + c%3, s = stencils[k] (global vertex ids)."""
    k = stencils.shape[0]
    nd = 3 * stencils.shape[1]
    size = nd * nd
    rows = np.empty(size * k, dtype=np.int32)
    cols = np.empty(size * k, dtype=np.int32)
    for a in range(k):
        for r in range(nd):
            gr = local_dof(stencils, a, r)
            for c in range(nd):
                o = size * a + nd * r + c
                rows[o] = gr
                cols[o] = local_dof(stencils, a, c)
    return rows, cols


_INSERTION_BELOW = 32  # a column's distinct rows sorted by insertion up to this many


@njit(cache=True, inline="always")
def _sum_column(rows, vals, lo, hi, column, total, seen):
    """Sum the triplets rows[lo:hi] (vals along) by row and compact them to the front,
    rows sorted: returns the number of distinct rows. Each row's values are summed in
    triplet order (the sums of one stable sort by row), in a dense accumulator
    ``total`` (n,) marked per column in ``seen`` (n,): only the distinct rows are sorted
    (a contact vertex's column holds each of its few dozen rows many times over)."""
    u = lo
    for t in range(lo, hi):
        r = rows[t]
        if seen[r] != column:
            seen[r] = column
            total[r] = vals[t]
            rows[u] = r  # u ≤ t: a distinct row never overwrites one still to be read
            u += 1
        else:
            total[r] += vals[t]
    if u - lo <= _INSERTION_BELOW:
        for i in range(lo + 1, u):
            r = rows[i]
            k = i - 1
            while k >= lo and rows[k] > r:
                rows[k + 1] = rows[k]
                k -= 1
            rows[k + 1] = r
    else:
        rows[lo:u].sort()
    for t in range(lo, u):
        vals[t] = total[rows[t]]
    return u - lo


@njit(cache=True)
def merge_columns(indptr, indices, data, start, bucket_rows, bucket_vals):
    """(indptr, indices, data) of A + T over free DOFs: A the CSC matrix (indptr,
    indices, data) with sorted indices, T the triplets bucketed by column (column c's
    rows and values at [start[c], start[c + 1]) of the buckets, in triplet order).
    Each column's triplets are sorted by row and duplicates summed in order (the order
    of one stable sort of every (column, row) key), then added to A's entries."""
    n = indptr.shape[0] - 1
    distinct = np.empty(n, dtype=np.int64)
    total = np.empty(n)
    seen = np.full(n, -1, dtype=np.int64)
    for c in range(n):
        distinct[c] = _sum_column(bucket_rows, bucket_vals, start[c], start[c + 1], c,
                                  total, seen)
    size = distinct.sum()
    out_ptr = np.zeros(n + 1, dtype=np.int32)  # int32 as scipy keeps it (sizes < 2³¹)
    out_idx = np.empty(indices.shape[0] + size, dtype=np.int32)
    out_val = np.empty(indices.shape[0] + size, dtype=np.float64)
    o = 0
    for col in range(n):
        a, end = indptr[col], indptr[col + 1]
        j = start[col]
        j_end = j + distinct[col]
        while a < end or j < j_end:
            if j < j_end and (a == end or bucket_rows[j] <= indices[a]):
                row, value = bucket_rows[j], bucket_vals[j]
                if a < end and indices[a] == row:  # an entry of A gets the triplets' sum
                    value += data[a]
                    a += 1
                j += 1
            else:
                row, value = indices[a], data[a]
                a += 1
            out_idx[o] = row
            out_val[o] = value
            o += 1
        out_ptr[col + 1] = o
    return out_ptr, out_idx[:o], out_val[:o]


# --- a small system's matrix, dense ----------------------------------------------------
# Below DenseSolver's size (solver/linear.py) every entry is added where it falls in the
# (n_free, n_free) array: no pattern to build, no buckets, no merge.

@njit(cache=True)
def add_triplets_dense(A, rows, cols, vals, scale, free_index, p, coupling):
    """A[r, c] += scale·v for each triplet of a free row r and free column c (in DOF
    numbers, mapped by free_index); one of a free row and a kinematic column adds
    scale·v·p[col] to coupling[r] instead, one of a kinematic row is dropped."""
    for t in range(rows.shape[0]):
        r = free_index[rows[t]]
        if r < 0:
            continue
        v = scale * vals[t]
        c = free_index[cols[t]]
        if c >= 0:
            A[r, c] += v
        else:
            coupling[r] += v * p[cols[t]]


@njit(cache=True)
def add_blocks_dense(A, vals, scale, stencils, free_index, p, coupling):
    """``add_triplets_dense`` for per-stencil blocks: entry k·B + nd·i + j of vals
    (nd = 3·nv, B = nd², nv = stencils.shape[1]) couples DOF 3·s[i // 3] + i % 3 with
    DOF 3·s[j // 3] + j % 3, s = stencils[k] (tets, contact stencils)."""
    nd = 3 * stencils.shape[1]
    dofs = np.empty(nd, np.int64)  # the stencil's DOFs, and their free numbers
    free = np.empty(nd, np.int64)
    t = 0
    for k in range(stencils.shape[0]):
        gather_dofs(stencils, k, free_index, dofs, free)
        for i in range(nd):
            r = free[i]
            if r < 0:
                t += nd
                continue
            for j in range(nd):
                v = scale * vals[t]
                t += 1
                c = free[j]
                if c >= 0:
                    A[r, c] += v
                else:
                    coupling[r] += v * p[dofs[j]]


# --- the fixed pattern of inertia, elasticity and damping -------------------------------

@njit(cache=True)
def count_free_columns(rows, cols, free_index, counts):
    """counts[c + 1] += the triplets of free column c whose row is free too."""
    for t in range(rows.shape[0]):
        r = free_index[rows[t]]
        c = free_index[cols[t]]
        if r >= 0 and c >= 0:
            counts[c + 1] += 1


@njit(cache=True)
def bucket_rows(rows, cols, free_index, fill, bucket):
    """bucket[fill[c]] = r for every free-free triplet (r, c), fill[c] advancing."""
    for t in range(rows.shape[0]):
        r = free_index[rows[t]]
        c = free_index[cols[t]]
        if r >= 0 and c >= 0:
            bucket[fill[c]] = r
            fill[c] += 1


@njit(cache=True)
def unique_column_rows(start, bucket):
    """CSC (indptr, indices) int32 of the distinct rows of each column's bucket
    bucket[start[c]:start[c + 1]], sorted. ``bucket`` is scratch: each column's distinct
    rows are moved to the front (they never overtake what is still to be read) and
    sorted there, found with one mark per row, so only the distinct rows are sorted (a
    tet mesh's column holds its 40-odd distinct rows several times over)."""
    n = start.shape[0] - 1
    indptr = np.zeros(n + 1, dtype=np.int32)
    last_column = np.full(n, -1, dtype=np.int64)  # the last column each row was seen in
    o = 0
    for c in range(n):
        first = o
        for k in range(start[c], start[c + 1]):
            r = bucket[k]
            if last_column[r] != c:
                last_column[r] = c
                bucket[o] = r
                o += 1
        bucket[first:o].sort()
        indptr[c + 1] = o
    return indptr, bucket[:o].copy()


@njit(cache=True, inline="always")
def _slot_in_column(indptr, indices, c, r):
    # the position of row r among column c's sorted rows (bisection)
    lo, hi = indptr[c], indptr[c + 1]
    while lo < hi:
        mid = (lo + hi) // 2
        if indices[mid] < r:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True)
def csc_slots(rows, cols, free_index, indptr, indices):
    """The slot of every triplet in the CSC pattern (int32; −1 when its row or column is
    kinematic), found by bisection in its column."""
    slots = np.full(rows.shape[0], -1, dtype=np.int32)
    for t in range(rows.shape[0]):
        r = free_index[rows[t]]
        c = free_index[cols[t]]
        if r < 0 or c < 0:
            continue
        slots[t] = _slot_in_column(indptr, indices, c, r)
    return slots


@njit(cache=True)
def scatter_into_pattern(data, slots, vals, scale, rows, cols, free_index, p, coupling):
    """data[slots[t]] += scale·vals[t]; a triplet of a free row and a kinematic column
    adds scale·vals[t]·p[col] to the coupling of its row instead."""
    for t in range(vals.shape[0]):
        v = scale * vals[t]
        s = slots[t]
        if s >= 0:
            data[s] += v
            continue
        r = free_index[rows[t]]
        if r >= 0:
            coupling[r] += v * p[cols[t]]


@njit(cache=True)
def element_block_slots(elements, free_index, indptr, indices):
    """The slots of per-element blocks in the CSC pattern, one per (element, row vertex,
    local column), int32: entry (3k + a, j) of element e's block sits at slot
    s[e, k, j] + a. A vertex's three DOFs are free or kinematic together and number
    consecutively, so its three rows are adjacent in every column (a third of the slots
    of one per entry: 48 rather than 144 per tet). −1 where the row vertex or the
    column is kinematic."""
    m, nv = elements.shape
    nd = 3 * nv
    slots = np.full(m * nv * nd, -1, dtype=np.int32)
    for e in range(m):
        for j in range(nd):
            c = free_index[local_dof(elements, e, j)]
            if c < 0:
                continue
            for k in range(nv):
                r = free_index[3 * elements[e, k]]
                if r < 0:
                    continue
                slots[(e * nv + k) * nd + j] = _slot_in_column(indptr, indices, c, r)
    return slots


@njit(cache=True)
def scatter_element_blocks(data, slots, vals, scale, elements, free_index, p, coupling):
    """scatter_into_pattern for per-element blocks: entry e·B + 3nv·i + j of vals (B =
    (3nv)², nv = elements.shape[1]) couples DOF 3·elements[e, i // 3] + i % 3 with DOF
    3·elements[e, j // 3] + j % 3 and goes to slot s + i % 3, s the slot of its row
    vertex and column (``element_block_slots``); its row and column are only worked out
    for entries of kinematic columns (slot −1), whose product with p goes into the
    coupling."""
    nv = elements.shape[1]
    nd = 3 * nv
    t = 0
    for e in range(elements.shape[0]):
        for i in range(nd):
            row_slots = (e * nv + i // 3) * nd
            a = i % 3
            r = -1  # the free row of local DOF i, found when a kinematic column needs it
            for j in range(nd):
                v = scale * vals[t]
                s = slots[row_slots + j]
                t += 1
                if s >= 0:
                    data[s + a] += v
                    continue
                if r == -1:
                    r = free_index[3 * elements[e, i // 3] + a]
                    if r < 0:
                        r = -2  # a kinematic row: its entries are dropped
                if r >= 0:
                    coupling[r] += v * p[local_dof(elements, e, j)]


@njit(cache=True)
def block_graph(indptr, indices, n, block):
    """The graph METIS orders, from a symmetric CSC pattern (indptr, indices) of n DOFs:
    one node per group of ``block`` consecutive DOFs (a vertex's), an edge between two
    groups that share an entry. As METIS reads it: (xadj, adjncy) int64, each node's
    neighbours sorted, no self-loops. A symmetric pattern gives a symmetric graph; it is
    built from the columns alone, with one mark per group (no array per entry)."""
    groups = (n + block - 1) // block
    mark = np.full(groups, -1, dtype=np.int64)
    xadj = np.zeros(groups + 1, dtype=np.int64)
    for g in range(groups):  # count each group's distinct neighbours
        for c in range(g * block, min((g + 1) * block, n)):
            for k in range(indptr[c], indptr[c + 1]):
                h = indices[k] // block
                if h != g and mark[h] != g:
                    mark[h] = g
                    xadj[g + 1] += 1
    for g in range(groups):
        xadj[g + 1] += xadj[g]
    adjncy = np.empty(xadj[groups], dtype=np.int64)
    mark[:] = -1
    for g in range(groups):  # fill them in, then sort each node's list
        o = xadj[g]
        for c in range(g * block, min((g + 1) * block, n)):
            for k in range(indptr[c], indptr[c + 1]):
                h = indices[k] // block
                if h != g and mark[h] != g:
                    mark[h] = g
                    adjncy[o] = h
                    o += 1
        adjncy[xadj[g]:o].sort()
    return xadj, adjncy
