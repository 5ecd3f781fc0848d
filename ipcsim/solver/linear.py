"""Sparse symmetric positive (semi-)definite solves behind one small interface.

The Newton step solves H p = -g with H the projected (PSD) Hessian of the incremental
potential restricted to free DOFs; the mass term makes it positive definite. The solve is
the floor of a Newton iteration, so the fastest installed factorisation is the default:

* ``cholmod``: CHOLMOD's supernodal Cholesky from the kvxopt wheel (no system library).
  The symbolic analysis (fill-reducing ordering) is reused while the sparsity pattern
  stays the same, which it does between Newton iterations of a contact-free step.
* ``scipy``: SuperLU through scipy, the pure-scipy fallback.

``make_solver(name)`` picks one; ``None`` or ``"auto"`` means the fastest available.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import SolverError


class ScipySolver:
    name = "scipy"

    def solve(self, A: sp.spmatrix, b: np.ndarray) -> np.ndarray:
        x = spla.spsolve(sp.csc_matrix(A), b)
        if not np.all(np.isfinite(x)):
            raise SolverError("linear solve produced non-finite values (singular Hessian?)")
        return x


class CholmodSolver:
    name = "cholmod"

    def __init__(self):
        from kvxopt import cholmod

        self._cholmod = cholmod
        self._cholmod.options["supernodal"] = 2
        self._pattern = None  # (indptr, indices) of the analysed matrix
        self._symbolic = None

    def solve(self, A: sp.spmatrix, b: np.ndarray) -> np.ndarray:
        from kvxopt import matrix, spmatrix

        # CHOLMOD reads the lower triangle of a symmetric matrix in CSC form.
        L = sp.tril(A, format="csc")
        L.sort_indices()
        pattern = (L.indptr, L.indices)
        K = spmatrix(L.data, L.indices.astype(np.int64), _col_of(L), size=L.shape)
        same = self._pattern is not None and all(
            np.array_equal(p, q) for p, q in zip(pattern, self._pattern))
        if not same:
            self._symbolic = self._cholmod.symbolic(K)
            self._pattern = pattern
        F = self._symbolic
        try:
            self._cholmod.numeric(K, F)
        except ArithmeticError as exc:
            raise SolverError(f"Cholesky factorisation failed: {exc}") from None
        x = matrix(np.ascontiguousarray(b, dtype=float))
        self._cholmod.solve(F, x)
        return np.array(x).reshape(-1)


def _col_of(csc: sp.csc_matrix) -> np.ndarray:
    return np.repeat(np.arange(csc.shape[1], dtype=np.int64), np.diff(csc.indptr))


SOLVERS = {"cholmod": CholmodSolver, "scipy": ScipySolver}


def available_solvers() -> list[str]:
    names = []
    for name, cls in SOLVERS.items():
        try:
            cls()
        except ImportError:
            continue
        names.append(name)
    return names


def make_solver(name: str | None = None):
    """The named solver, or the fastest one installed for ``None``/``"auto"``.

    The original's names map onto ours: CHOLMOD -> cholmod, EIGEN/AMGCL -> scipy.
    """
    key = (name or "auto").lower()
    key = {"eigen": "scipy", "amgcl": "scipy", "superlu": "scipy"}.get(key, key)
    if key == "auto":
        for candidate in ("cholmod", "scipy"):
            try:
                return SOLVERS[candidate]()
            except ImportError:
                continue
    if key not in SOLVERS:
        raise ValueError(f"unknown linear solver {name!r}; choose from {sorted(SOLVERS)}")
    return SOLVERS[key]()
