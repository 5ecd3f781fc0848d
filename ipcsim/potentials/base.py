"""What every term of the incremental potential looks like to the solver.

A potential has ``value(x)``, ``gradient(x)`` -> (3n,) and ``hessian(x)`` -> ``Triplets``
with every local block already projected to positive semi-definite. ``x`` is the (n, 3)
array of all vertex positions; DOF 3i+a is vertex i, axis a.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class Triplets:
    """A sparse matrix as COO triplets; duplicates are summed by ``tocsr``."""

    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray

    @staticmethod
    def empty() -> "Triplets":
        z = np.zeros(0, dtype=np.int64)
        return Triplets(z, z, np.zeros(0))

    @staticmethod
    def concat(parts: list["Triplets"]) -> "Triplets":
        parts = [p for p in parts if len(p.vals)]
        if not parts:
            return Triplets.empty()
        return Triplets(
            np.concatenate([p.rows for p in parts]),
            np.concatenate([p.cols for p in parts]),
            np.concatenate([p.vals for p in parts]),
        )

    def __add__(self, other: "Triplets") -> "Triplets":
        return Triplets.concat([self, other])

    def tocsr(self, n_dofs: int) -> sp.csr_matrix:
        return sp.csr_matrix((self.vals, (self.rows, self.cols)), shape=(n_dofs, n_dofs))
