"""Adding COO triplets to a CSC matrix over free DOFs, without going through scipy.

The Newton matrix is a fixed-pattern part (inertia, elasticity, damping; see
``solver/assembly.py``) plus the triplets of contact and friction, whose pattern changes
with the contact set. ``add_triplets`` maps the triplets to free-DOF numbers, drops
those of kinematic rows, sums duplicates and merges them into the fixed part column by
column; triplets of a free row and a kinematic column go into the coupling H_fk p_k.
"""

from __future__ import annotations

import numpy as np
from ipcsim.kernels.jit import njit


@njit(cache=True)
def add_triplets(indptr, indices, data, rows, cols, vals, free_index, p, coupling):
    """(indptr, indices, data) of A + T over free DOFs, with A the CSC matrix
    (indptr, indices, data) with sorted indices and T the triplets (rows, cols, vals) in
    DOF numbers; zero triplets add no entry. ``coupling`` (free DOFs) gets T_fk p_k
    added in place."""
    n = indptr.shape[0] - 1
    keys, kept = _free_keys(rows, cols, vals, free_index, p, coupling, n)
    keys, kept = _stable_sort_by_key(keys, kept, n)  # duplicates are summed in order
    t_col, t_row, t_val = _summed(keys, kept, n)
    out_ptr = np.zeros(n + 1, dtype=np.int32)  # int32 as scipy keeps it (sizes < 2³¹)
    out_idx = np.empty(indices.shape[0] + t_col.shape[0], dtype=np.int32)
    out_val = np.empty(indices.shape[0] + t_col.shape[0], dtype=np.float64)
    o = 0
    j = 0  # next summed triplet, by column then row
    m = t_col.shape[0]
    for col in range(n):
        a, end = indptr[col], indptr[col + 1]
        while a < end or (j < m and t_col[j] == col):
            if j < m and t_col[j] == col and (a == end or t_row[j] <= indices[a]):
                row, value = t_row[j], t_val[j]
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


@njit(cache=True)
def _free_keys(rows, cols, vals, free_index, p, coupling, n):
    """Column-major keys col·n + row and values of the free-free triplets; free-kinematic
    ones go into the coupling."""
    m = rows.shape[0]
    keys = np.empty(m, dtype=np.int64)
    kept = np.empty(m, dtype=np.float64)
    k = 0
    for t in range(m):
        r = free_index[rows[t]]
        if r < 0 or vals[t] == 0.0:
            continue
        c = free_index[cols[t]]
        if c < 0:
            coupling[r] += vals[t] * p[cols[t]]
            continue
        keys[k] = np.int64(c) * n + r
        kept[k] = vals[t]
        k += 1
    return keys[:k], kept[:k]


@njit(cache=True)
def _stable_sort_by_key(keys, vals, n):
    """keys (col·n + row) and vals in the order of a stable sort by key: a counting sort
    by column, then a stable sort of each column's rows. The same order as one stable
    sort of all keys, without sorting millions of keys at once (contact triplets)."""
    m = keys.shape[0]
    start = np.zeros(n + 1, dtype=np.int64)
    for t in range(m):
        start[keys[t] // n + 1] += 1
    for c in range(n):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    sorted_keys = np.empty(m, dtype=np.int64)
    sorted_vals = np.empty(m, dtype=np.float64)
    for t in range(m):
        c = keys[t] // n
        sorted_keys[fill[c]] = keys[t]
        sorted_vals[fill[c]] = vals[t]
        fill[c] += 1
    for c in range(n):
        lo, hi = start[c], start[c + 1]
        if hi - lo > 1:
            order = np.argsort(sorted_keys[lo:hi], kind="mergesort")
            sorted_keys[lo:hi] = sorted_keys[lo:hi][order]
            sorted_vals[lo:hi] = sorted_vals[lo:hi][order]
    return sorted_keys, sorted_vals


@njit(cache=True)
def _summed(keys, vals, n):
    """(columns, rows, sums) of the distinct sorted keys, duplicates summed in order."""
    m = keys.shape[0]
    col = np.empty(m, dtype=np.int64)
    row = np.empty(m, dtype=np.int64)
    val = np.empty(m, dtype=np.float64)
    u = -1
    for t in range(m):
        if u < 0 or keys[t] != keys[t - 1]:
            u += 1
            col[u] = keys[t] // n
            row[u] = keys[t] - col[u] * n
            val[u] = vals[t]
        else:
            val[u] += vals[t]
    return col[:u + 1], row[:u + 1], val[:u + 1]


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
        lo, hi = indptr[c], indptr[c + 1]
        while lo < hi:
            mid = (lo + hi) // 2
            if indices[mid] < r:
                lo = mid + 1
            else:
                hi = mid
        slots[t] = lo
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
def scatter_element_blocks(data, slots, vals, scale, elements, free_index, p, coupling):
    """scatter_into_pattern for per-element blocks: entry e·B + 3nv·i + j of vals (B =
    (3nv)², nv = elements.shape[1]) couples DOF 3·elements[e, i // 3] + i % 3 with DOF
    3·elements[e, j // 3] + j % 3; its row and column are only worked out for the entries
    of kinematic columns (slot −1), whose product with p goes into the coupling."""
    nd = 3 * elements.shape[1]
    t = 0
    for e in range(elements.shape[0]):
        for i in range(nd):
            r = -1  # the free row of local DOF i, found when a kinematic column needs it
            for j in range(nd):
                v = scale * vals[t]
                s = slots[t]
                t += 1
                if s >= 0:
                    data[s] += v
                    continue
                if r == -1:
                    r = free_index[3 * elements[e, i // 3] + i % 3]
                    if r < 0:
                        r = -2  # a kinematic row: its entries are dropped
                if r >= 0:
                    coupling[r] += v * p[3 * elements[e, j // 3] + j % 3]


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
