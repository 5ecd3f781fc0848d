"""Adding COO triplets to a CSC matrix over free DOFs, without going through scipy.

The Newton matrix is a fixed-pattern part (inertia, elasticity, damping; see
``solver/assembly.py``) plus the triplets of contact and friction, whose pattern changes
with the contact set. ``add_triplets`` maps the triplets to free-DOF numbers, drops
those of kinematic rows, sums duplicates and merges them into the fixed part column by
column; triplets of a free row and a kinematic column go into the coupling H_fk p_k.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def add_triplets(indptr, indices, data, rows, cols, vals, free_index, p, coupling):
    """(indptr, indices, data) of A + T over free DOFs, with A the CSC matrix
    (indptr, indices, data) with sorted indices and T the triplets (rows, cols, vals) in
    DOF numbers; zero triplets add no entry. ``coupling`` (free DOFs) gets T_fk p_k
    added in place."""
    n = indptr.shape[0] - 1
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
        keys[k] = np.int64(c) * n + r  # column-major: CSC order
        kept[k] = vals[t]
        k += 1
    order = np.argsort(keys[:k], kind="mergesort")  # stable: duplicates summed in order
    out_ptr = np.zeros(n + 1, dtype=np.int32)  # int32 as scipy keeps it (sizes < 2³¹)
    out_idx = np.empty(indices.shape[0] + k, dtype=np.int32)
    out_val = np.empty(indices.shape[0] + k, dtype=np.float64)
    o = 0
    j = 0  # next sorted triplet
    for col in range(n):
        a, end = indptr[col], indptr[col + 1]
        while True:
            has_a = a < end
            has_t = j < k and keys[order[j]] // n == col
            if not has_a and not has_t:
                break
            if has_a and (not has_t or indices[a] <= keys[order[j]] % n):
                row, value = indices[a], data[a]
                a += 1
            else:
                row, value = keys[order[j]] % n, 0.0
            while j < k and keys[order[j]] == col * n + row:
                value += kept[order[j]]
                j += 1
            out_idx[o] = row
            out_val[o] = value
            o += 1
        out_ptr[col + 1] = o
    return out_ptr, out_idx[:o], out_val[:o]
