"""Assembly of the Newton system over free DOFs from COO triplets.

Kinematic DOFs are eliminated by mapping triplet indices to free-DOF numbers; nothing
edits a CSR matrix in place. Terms whose sparsity pattern never changes (inertia,
elasticity, damping: ``constant_pattern = True``) return the same index arrays on every
call, so the map from each of their triplets to a slot of the CSC matrix is computed once
per kinematic mask, and each iteration only scatter-adds values, times the term's weight
(a linear pass instead of a sort of millions of triplets). Triplets of terms whose pattern
changes (contact, friction) are bucketed by column and merged into that matrix
(``kernels/algebra/assembly.py``).

``assemble`` also returns the coupling H_fk p_k, the free rows' product with the
prescribed motion of kinematic DOFs, which the Newton step subtracts from its right side.
The matrix is a plain ``CscMatrix``: a run needs no scipy.sparse (whose import, with
the numpy modules scipy pulls in, is 0.08 s and 17 MB of every start here).
"""

from __future__ import annotations

from typing import ClassVar

from msgspec import Struct
import numpy as np

from ..kernels.algebra import assembly as ka


class CscMatrix(Struct, frozen=True, eq=False):
    """A sparse matrix in compressed sparse columns, with sorted row indices and no
    duplicates in each column (as the linear solvers read it)."""

    data: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    shape: tuple[int, int]
    format: ClassVar[str] = "csc"
    has_canonical_format: ClassVar[bool] = True
    # nothing writes its arrays once it is made: a solver keeps them rather than copies
    # (the index arrays of a heavy-contact matrix are 9 MB on mat100x100)
    fixed_arrays: ClassVar[bool] = True

    def to_scipy(self):
        """The same matrix as a ``scipy.sparse.csc_matrix`` (sharing the arrays)."""
        import scipy.sparse as sp

        return sp.csc_matrix((self.data, self.indices, self.indptr), shape=self.shape)

    def toarray(self) -> np.ndarray:
        return self.to_scipy().toarray()


class _StaticPattern:
    """CSC structure of the constant-pattern terms and each triplet's slot in it.

    Built without sorting all triplets: the free rows of each free column are bucketed,
    sorted and made unique column by column, and each part finds its slots by bisection
    (``slots_in``): what is kept is one int32 slot per triplet (−1 for kinematic rows or
    columns), or per element block's row vertex and column."""

    def __init__(self, parts, free_index, n_free):
        self.keys = [p.pattern_key for p in parts]
        self.free_index = free_index
        counts = np.zeros(n_free + 1, dtype=np.int64)
        for p in parts:
            for rows, cols in p.pattern_chunks():
                ka.count_free_columns(rows, cols, free_index, counts)
        start = np.cumsum(counts)
        bucket = np.empty(int(start[-1]), dtype=np.int32)
        fill = start[:-1].copy()
        for p in parts:
            for rows, cols in p.pattern_chunks():
                ka.bucket_rows(rows, cols, free_index, fill, bucket)
        self.indptr, self.indices = ka.unique_column_rows(start, bucket)
        del bucket
        self.slots = [p.slots_in(free_index, self.indptr, self.indices) for p in parts]
        self.n_free = n_free

    def matches(self, parts, free_index) -> bool:
        return (free_index is self.free_index and len(parts) == len(self.keys)
                and all(p.pattern_key is k for p, k in zip(parts, self.keys)))


class Assembler:
    """Keeps the static pattern of the last two kinematic masks: a step whose first
    iteration leaves the prescribed motion unfinished pulls those vertices as free DOFs
    for the rest of it, then the next step starts with them prescribed again; building
    a pattern costs a quarter of a second on a 60K-tet mesh, twice a step."""

    KEPT = 2

    def __init__(self):
        self._patterns: list[_StaticPattern] = []  # the most recently used first

    def assemble(self, static_parts, dynamic_parts: list, free_index, n_free, p):
        """(A over free DOFs as CSC, coupling H_fk p_k over free DOFs). The list
        ``dynamic_parts`` is emptied: each term's triplets are let go once bucketed, before
        the merged matrix is built (in heavy contact they are the largest arrays here)."""
        pat = self._pattern_for(static_parts, free_index, n_free)
        data = np.zeros(len(pat.indices))
        coupling = np.zeros(n_free)
        for part, slots in zip(static_parts, pat.slots):
            part.scatter_into(data, slots, free_index, p, coupling)
        parts = [d for d in dynamic_parts if d.size]  # no contact: no merge
        dynamic_parts.clear()
        if parts:
            indptr, indices, data = _merge(pat, data, parts, free_index, p, coupling)
        else:
            indptr, indices = pat.indptr, pat.indices
        return CscMatrix(data, indices, indptr, (n_free, n_free)), coupling


    def _pattern_for(self, static_parts, free_index, n_free) -> _StaticPattern:
        kept = [p for p in self._patterns if p.matches(static_parts, free_index)]
        if kept:
            pat = kept[0]
        else:
            # let the oldest go before the new one is built
            self._patterns = self._patterns[:self.KEPT - 1]
            pat = _StaticPattern(static_parts, free_index, n_free)
        self._patterns = [pat, *(p for p in self._patterns if p is not pat)]
        return pat


class DenseAssembler:
    """The Newton matrix of a small system as a dense (n_free, n_free) array, for
    ``linear.DenseSolver``: every part adds its entries where they fall
    (``add_dense``), so there is no pattern to build and no merge (on two tutorial cubes,
    48 DOFs, the sparse assembly is about 90 µs of a 470 µs Newton iteration)."""

    def assemble(self, static_parts, dynamic_parts: list, free_index, n_free, p):
        """(A over free DOFs, dense; coupling H_fk p_k over free DOFs), as
        ``Assembler.assemble``; ``dynamic_parts`` is emptied as there."""
        A = np.zeros((n_free, n_free))
        coupling = np.zeros(n_free)
        for part in static_parts:
            part.add_dense(A, free_index, p, coupling)
        while dynamic_parts:
            part = dynamic_parts.pop(0)
            if part.size:  # no contact: nothing to add
                part.add_dense(A, free_index, p, coupling)
        return A, coupling


def _merge(pat, data, parts: list, free_index, p, coupling):
    """The static matrix (pat's pattern, data) plus the triplets of ``parts``: counted
    and bucketed by free column term after term (no concatenated copy; ``parts`` is
    emptied as they are bucketed), then merged."""
    n = len(pat.indptr) - 1
    start = np.zeros(n + 1, dtype=np.int64)
    for d in parts:
        d.count_into(free_index, p, coupling, start)
    del d  # the loop variable would keep the last term's triplets alive
    np.cumsum(start, out=start)
    bucket_rows = np.empty(int(start[-1]), dtype=np.int32)
    bucket_vals = np.empty(int(start[-1]))
    fill = start[:-1].copy()
    while parts:
        parts.pop(0).bucket_into(free_index, fill, bucket_rows, bucket_vals)
    return ka.merge_columns(pat.indptr, pat.indices, data, start, bucket_rows, bucket_vals)
