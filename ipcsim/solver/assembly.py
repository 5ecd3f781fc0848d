"""Assembly of the Newton system over free DOFs from COO triplets.

Kinematic DOFs are eliminated by mapping triplet indices to free-DOF numbers; nothing
edits a CSR matrix in place. Terms whose sparsity pattern never changes (inertia,
elasticity, damping: ``constant_pattern = True``) return the same index arrays on every
call, so the map from each of their triplets to a slot of the CSC matrix is computed once
per kinematic mask, and each iteration only scatter-adds values (a linear pass instead of
a sort of millions of triplets). Triplets of terms whose pattern changes (contact,
friction) are merged into that matrix by one kernel (``kernels/assembly.py``).

``assemble`` also returns the coupling H_fk p_k, the free rows' product with the
prescribed motion of kinematic DOFs, which the Newton step subtracts from its right side.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..kernels.assembly import add_triplets
from ..kernels.scatter import scatter_add


class _StaticPattern:
    """CSC structure of the constant-pattern terms and each triplet's slot in it."""

    def __init__(self, parts, free_index, n_free):
        self.refs = [(p.rows, p.cols) for p in parts]
        self.free_index = free_index
        keeps, rows, cols = [], [], []
        self.coupling = []  # per part: (kept triplets, free row, kinematic column DOF)
        for p in parts:
            rf, cf = free_index[p.rows], free_index[p.cols]
            ff = np.flatnonzero((rf >= 0) & (cf >= 0))
            keeps.append(ff)
            rows.append(rf[ff])
            cols.append(cf[ff])
            fk = np.flatnonzero((rf >= 0) & (cf < 0))
            self.coupling.append((fk, rf[fk], p.cols[fk]))
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        key = cols * np.int64(n_free) + rows  # column-major order = CSC order
        unique, slots = np.unique(key, return_inverse=True)
        self.indices = (unique % n_free).astype(np.int32)
        self.indptr = np.searchsorted(unique // n_free, np.arange(n_free + 1)).astype(np.int32)
        bounds = np.cumsum([0] + [len(k) for k in keeps])
        self.parts = [(keeps[i], slots[bounds[i]:bounds[i + 1]].astype(np.int64))
                      for i in range(len(parts))]
        self.n_free = n_free

    def matches(self, parts, free_index) -> bool:
        return (free_index is self.free_index and len(parts) == len(self.refs)
                and all(p.rows is r and p.cols is c for p, (r, c) in zip(parts, self.refs)))


class Assembler:
    def __init__(self):
        self._pattern: _StaticPattern | None = None

    def assemble(self, static_parts, dynamic_parts, free_index, n_free, p):
        """(A over free DOFs as CSC, coupling H_fk p_k over free DOFs)."""
        if self._pattern is None or not self._pattern.matches(static_parts, free_index):
            self._pattern = _StaticPattern(static_parts, free_index, n_free)
        pat = self._pattern
        data = np.zeros(len(pat.indices))
        coupling = np.zeros(n_free)
        for part, (keep, slots), (fk, fk_rows, fk_cols) in zip(static_parts, pat.parts,
                                                               pat.coupling):
            scatter_add(data, slots, part.vals, keep)
            if len(fk):
                coupling += np.bincount(fk_rows, weights=part.vals[fk] * p[fk_cols],
                                        minlength=n_free)
        if dynamic_parts:
            rows = np.concatenate([d.rows for d in dynamic_parts])
            cols = np.concatenate([d.cols for d in dynamic_parts])
            vals = np.concatenate([d.vals for d in dynamic_parts])
            indptr, indices, data = add_triplets(pat.indptr, pat.indices, data, rows, cols,
                                                 vals, free_index, p, coupling)
        else:
            indptr, indices = pat.indptr, pat.indices
        return sp.csc_matrix((data, indices, indptr), shape=(n_free, n_free)), coupling
