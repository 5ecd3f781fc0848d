"""Sparse symmetric positive definite solves behind one small interface.

The Newton step solves H p = -g with H the projected (PSD) Hessian of the incremental
potential restricted to free DOFs; the mass term makes it positive definite. The solve is
the floor of a Newton iteration, so the fastest installed factorisation is the default
(measurements and the reasons for the order: ``docs/linear-solvers.md``,
``python -m benchmarks.linear_solvers``):

* ``cholmod``: CHOLMOD's supernodal Cholesky from the kvxopt wheel (no system library).
  With pymetis installed (a 0.3 MB wheel) the fill-reducing ordering is METIS nested
  dissection of the vertex graph (each 3×3 DOF block one node), which on tet meshes
  leaves 23–28% less fill than CHOLMOD's built-in AMD (this kvxopt has no METIS) and
  factors 1.6× faster; without pymetis, and below 3,000 DOFs, it is AMD.
* ``pardiso``: MKL PARDISO (real SPD, METIS ordering, MKL's threads), called through
  ctypes when the ``mkl`` wheel's ``libmkl_rt`` can be found; by name only. With
  MKL_NUM_THREADS=1 it factors 10–14% faster than cholmod + METIS, with MKL's default
  two threads on the shared 2-core machine no faster (slower at 90k DOFs), and MKL is
  ~315 MB of wheels (~940 MB installed): not a dependency, not picked by "auto".
* ``scipy``: SuperLU through scipy (symmetric-mode ordering and pivots), the fallback
  that needs nothing beyond scipy; about 10× slower than cholmod at 30k DOFs.

``AUTO_ORDER`` is what ``None``/``"auto"`` tries: cholmod, then scipy. Systems of at most
``DENSE_UP_TO`` DOFs (the tutorial scenes' two cubes: 48) get ``DenseSolver`` instead: a
dense Cholesky factor (a compiled kernel), 1.5× faster there than CHOLMOD's call, whose
setup outweighs the arithmetic at that size (and kvxopt is then never imported). Where
the terms' Hessians are added into the dense matrix in one call (every scene but the
baselines' and warm start 5's), up to ``DENSE_HESSIAN_UP_TO`` DOFs.

Every backend accepts the full symmetric matrix as CSC or CSR (for a symmetric matrix the
two share their arrays) and reads only its lower triangle (= upper triangle in CSR, which
PARDISO wants). The conversion keeps what depends only on the sparsity pattern, so a call
whose pattern (``indptr``, ``indices``) equals the previous call's copies the values only
and reuses the symbolic analysis (ordering + elimination tree); a new pattern, e.g. after
the contact set changed, is analysed afresh.

``make_solver(name, n_dofs)`` picks one; ``None`` or ``"auto"`` means the fastest available
for systems of up to ``n_dofs`` DOFs.
"""

from __future__ import annotations

import ctypes
import glob
import os
import site
import sys

import numpy as np

from ..errors import SolverError
from ..kernels.algebra.assembly import block_graph
from ..kernels.algebra.linalg import cholesky_in_place, cholesky_solve, dense_cholesky

BLOCK = 3  # DOFs per vertex: the ordering works on the graph of these blocks


# --------------------------------------------------------------------------- patterns

def _symmetric_csc_arrays(A):
    """(indptr, indices, data) of a full symmetric sparse matrix, as CSC with sorted,
    unique indices. CSR input is used as is: for a symmetric matrix it is the CSC of Aᵀ = A.
    The Newton matrix (``assembly.CscMatrix``) is used as it is; other scipy matrices
    are converted."""
    if A.shape[0] != A.shape[1]:
        raise ValueError(f"expected a square matrix, got shape {A.shape}")
    if A.format not in ("csc", "csr"):
        import scipy.sparse as sp

        A = sp.csc_matrix(A)
    if not A.has_canonical_format:  # sorted indices, no duplicates
        A = A.copy()
        A.sum_duplicates()
    return A.indptr, A.indices, A.data


class _LowerPattern:
    """The lower triangle of a symmetric CSC pattern: which stored entries it keeps
    (``mask``) and where each column's part starts (``indptr``). Built once per pattern;
    ``values(data)`` is a single gather. The row and column of each kept entry (16 bytes
    an entry) are made when a backend builds its matrix (``rows_and_columns``), not kept."""

    def __init__(self, indptr, indices, n, keep: bool = False):
        """``keep``: the arrays are never written after this (the Newton matrix's, see
        ``assembly.CscMatrix``): kept as they are rather than copied."""
        self.indptr_full = indptr if keep else np.array(indptr, copy=True)
        self.indices_full = indices if keep else np.array(indices, copy=True)
        self.n = n
        col = np.repeat(np.arange(n, dtype=np.int64), np.diff(self.indptr_full))
        self.mask = self.indices_full >= col
        self.indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(col[self.mask], minlength=n), out=self.indptr[1:])

    def rows_and_columns(self) -> tuple[np.ndarray, np.ndarray]:
        """(row, column), int64, of each kept entry, in column order."""
        return (self.indices_full[self.mask].astype(np.int64),
                np.repeat(np.arange(self.n, dtype=np.int64), np.diff(self.indptr)))

    def has_diagonal(self, rows) -> bool:
        """Whether every diagonal entry is stored, given the kept entries' ``rows``: with
        sorted indices a column's lower part starts at its diagonal when that is stored."""
        starts = self.indptr[:-1]
        return bool(np.all(starts < self.indptr[1:])
                    and np.array_equal(rows[starts], np.arange(self.n)))

    def same(self, indptr, indices) -> bool:
        return (len(indices) == len(self.indices_full)
                and np.array_equal(indptr, self.indptr_full)
                and np.array_equal(indices, self.indices_full))

    def values(self, data) -> np.ndarray:
        return np.ascontiguousarray(data[self.mask], dtype=np.float64)


def group_nested_dissection(indptr, indices, n: int, block: int = BLOCK):
    """Fill-reducing permutation of the DOFs (int64, new position -> old DOF) from METIS
    nested dissection of the graph whose nodes are the DOF groups {block·k, ..., block·k +
    block − 1} (a vertex's DOFs) and whose edges are the groups' couplings; each group's DOFs
    stay consecutive. The pattern must be symmetric (every backend's input is: the full
    symmetric matrix); any such pattern gives a valid permutation, a good one when DOFs
    come in blocks, as they do here. None when pymetis is not installed."""
    try:
        import pymetis
    except ImportError:
        return None
    groups = (n + block - 1) // block
    if groups <= 1:
        return np.arange(n, dtype=np.int64)
    # built column by column into the graph's own arrays: the int64 keys of every entry
    # that np.unique made of it were a 33 MB peak on 13_dolphinFunnel (24K DOFs)
    xadj, adjncy = block_graph(np.ascontiguousarray(indptr, dtype=np.int32),
                               np.ascontiguousarray(indices, dtype=np.int32), n, block)
    if hasattr(pymetis, "CSRAdjacency"):  # newer pymetis; older ones take xadj/adjncy
        order, _ = pymetis.nested_dissection(adjacency=pymetis.CSRAdjacency(xadj, adjncy))
    else:
        order, _ = pymetis.nested_dissection(xadj=xadj, adjncy=adjncy)
    order = np.asarray(order).astype(np.int64)  # pymetis gives 'q' buffers; kvxopt reads 'l'
    perm = (block * order[:, None] + np.arange(block, dtype=np.int64)).ravel()
    return perm[perm < n] if n % block else perm


def _check(x: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(x)):
        raise SolverError("linear solve produced non-finite values (singular Hessian?)")
    return x


# --------------------------------------------------------------------------- backends

class ScipySolver:
    """SuperLU (scipy) with the settings for symmetric positive definite matrices: the
    symmetric minimum-degree ordering of A + Aᵀ and diagonal pivots. There is no separate
    symbolic phase to reuse."""

    name = "scipy"

    def solve(self, A, b: np.ndarray) -> np.ndarray:
        indptr, indices, data = _symmetric_csc_arrays(A)
        n = len(indptr) - 1
        if n == 0:
            return np.zeros(0)
        import scipy.sparse as sp  # the fallback only: 0.2 s to import both
        import scipy.sparse.linalg as spla

        M = sp.csc_matrix((data, indices, indptr), shape=(n, n))
        try:
            lu = spla.splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(f"LU factorisation failed: {exc}") from None
        self._lu = lu
        return _check(lu.solve(np.asarray(b, dtype=np.float64)))

    def solve_again(self, b: np.ndarray) -> np.ndarray:
        """A x = b for the matrix of the last ``solve``, with its factor."""
        return _check(self._lu.solve(np.asarray(b, dtype=np.float64))) if len(b) \
            else np.zeros(0)


class DenseSolver:
    """Dense Cholesky L Lᵀ = A (``kernels/algebra/linalg.py``) for small systems only: n² memory
    and n³/3 operations. At 48 DOFs a solve takes 14 µs against CHOLMOD's 22 µs (its
    per-call setup); at about 70 DOFs the two are even (``benchmarks/small_solves.py``,
    docs/linear-solvers.md). ``A`` is a sparse matrix, or the dense (n, n) array that
    ``assembly.DenseAssembler`` makes (``dense`` says Newton may hand it one), which is
    factored in place: its lower triangle becomes L."""

    name = "dense"
    dense = True

    def __init__(self):
        self._L = np.zeros((0, 0))

    def solve(self, A, b: np.ndarray) -> np.ndarray:
        if isinstance(A, np.ndarray):
            if A.ndim != 2 or A.shape[0] != A.shape[1] or A.dtype != np.float64 \
                    or not A.flags.c_contiguous:
                order = "C-contiguous" if A.flags.c_contiguous else "not C-contiguous"
                raise ValueError(f"expected a square C-contiguous float64 array, got a "
                                 f"{A.shape} {A.dtype} array, {order}")
            self._L = A
            factored = cholesky_in_place(A)
        else:
            indptr, indices, data = _symmetric_csc_arrays(A)
            n = len(indptr) - 1
            if self._L.shape[0] != n:
                self._L = np.empty((n, n))
            # int32 indices and float64 values: the kernel's compiled variant
            factored = dense_cholesky(np.asarray(indptr, dtype=np.int32),
                                      np.asarray(indices, dtype=np.int32),
                                      np.asarray(data, dtype=np.float64), self._L)
        if not factored:
            self._L = np.zeros((0, 0))  # no factor to solve again with
            raise SolverError("Cholesky factorisation failed (matrix not positive definite "
                              "or not finite)")
        return self.solve_again(b)

    def solve_again(self, b: np.ndarray) -> np.ndarray:
        """A x = b for the matrix of the last ``solve``, with its factor."""
        b = np.ascontiguousarray(b, dtype=np.float64).reshape(-1)
        if len(b) != self._L.shape[0]:
            raise ValueError(f"right side of {len(b)} entries for a {self._L.shape[0]}-DOF factor")
        x = np.empty(len(b))
        if len(b):
            cholesky_solve(self._L, b, x)
        return _check(x)


class _Factorising:
    """A direct solver in four phases, separate so that the benchmark can time each one:
    ``_load`` takes A's values (and its pattern when new; True then), ``_analyse`` the
    symbolic analysis (ordering, elimination tree), ``_factorise`` the numeric factor,
    ``_backsolve`` the triangular solves. The analysis is kept while the pattern is."""

    _analysed = False

    def solve(self, A, b: np.ndarray) -> np.ndarray:
        if A.shape[0] == 0:
            return np.zeros(0)
        if self._load(A) or not self._analysed:
            self._analyse()
        self._factorise()
        return self._backsolve(b)

    def solve_again(self, b: np.ndarray) -> np.ndarray:
        """A x = b for the matrix of the last ``solve``, with its factor."""
        return self._backsolve(b) if len(b) else np.zeros(0)


class CholmodSolver(_Factorising):
    """CHOLMOD (kvxopt) Cholesky with the symbolic analysis kept per sparsity pattern.

    ``ordering``: "metis" (pymetis on the vertex graph), "amd" (CHOLMOD's own), or "auto"
    (metis from ``METIS_FROM`` DOFs up when pymetis is installed, else amd: below, both
    order in microseconds and leave the same fill, and importing pymetis costs 25 ms,
    4 % of a tiny scene's run). ``supernodal``: True for the supernodal LLᵀ
    (BLAS-3, the fast one), False for the simplicial LDLᵀ (kept for measurements).
    """

    name = "cholmod"
    METIS_FROM = 3000  # DOFs

    def __init__(self, ordering: str = "auto", supernodal: bool = True):
        import importlib.util

        from kvxopt import cholmod  # ImportError: not available

        if ordering not in ("auto", "metis", "amd"):
            raise ValueError(f"unknown ordering {ordering!r}; choose auto, metis or amd")
        if ordering == "auto" and importlib.util.find_spec("pymetis") is None:
            ordering = "amd"
        elif ordering == "metis":
            import pymetis  # noqa: F401  (ImportError: not available)
        self._cholmod = cholmod
        self.ordering = ordering
        self.supernodal = bool(supernodal)
        self._pattern: _LowerPattern | None = None
        self._K = None  # kvxopt spmatrix of the lower triangle, values updated in place
        self._factor = None  # symbolic factor of the current pattern (numeric after _factorise)
        self._analysed = False

    def _load(self, A) -> bool:
        """Take A's values (and its pattern when new); True when the pattern is new."""
        from kvxopt import matrix, spmatrix

        indptr, indices, data = _symmetric_csc_arrays(A)
        n = len(indptr) - 1
        if self._pattern is not None and self._pattern.n == n and self._pattern.same(indptr, indices):
            self._K.V = matrix(self._pattern.values(data))
            return False
        # a new pattern: let the old matrix and factor go before the new ones are built
        self._pattern = self._K = self._factor = None
        pat = _LowerPattern(indptr, indices, n, keep=getattr(A, "fixed_arrays", False))
        self._K = spmatrix(pat.values(data), *pat.rows_and_columns(), size=(n, n))
        self._pattern = pat
        self._analysed = False
        return True

    def _analyse(self) -> None:
        from kvxopt import matrix

        opts = self._cholmod.options  # module-wide: set what we rely on before every call
        opts["supernodal"] = 2 if self.supernodal else 0
        perm = None
        if self._ordering_for(self._pattern.n) == "metis":
            pat = self._pattern
            # None where pymetis is found but does not import: AMD then
            perm = group_nested_dissection(pat.indptr_full, pat.indices_full, pat.n)
        if perm is not None:
            opts["nmethods"] = 1  # use the given ordering, do not also try AMD
            self._factor = self._cholmod.symbolic(self._K, p=matrix(perm))
        else:
            opts["nmethods"] = 0  # CHOLMOD's default: AMD (this build has no METIS)
            self._factor = self._cholmod.symbolic(self._K)
        self._analysed = True

    def _ordering_for(self, n: int) -> str:
        """The ordering of an n × n matrix: "metis" or "amd"."""
        if self.ordering == "auto":
            return "metis" if n >= self.METIS_FROM else "amd"
        return self.ordering

    def _factorise(self) -> None:
        try:
            self._cholmod.numeric(self._K, self._factor)
        except ArithmeticError as exc:
            raise SolverError(f"Cholesky factorisation failed: {exc}") from None

    def _backsolve(self, b: np.ndarray) -> np.ndarray:
        from kvxopt import matrix

        x = matrix(np.array(b, dtype=np.float64).reshape(-1))
        try:
            self._cholmod.solve(self._factor, x)
        except ArithmeticError as exc:  # a supernodal factor that stopped at a non-positive pivot
            raise SolverError(f"Cholesky factorisation failed (matrix not positive definite): {exc}") from None
        return _check(np.array(x).reshape(-1))


# --------------------------------------------------------------------------- MKL PARDISO

_MKL_RT: str | None | bool = False  # False: not looked for yet


def find_mkl_rt() -> str | None:
    """Path of MKL's single dynamic library libmkl_rt (the ``mkl`` wheel installs it into
    the environment's lib/), or None. IPCSIM_MKL_RT overrides the search."""
    global _MKL_RT
    if _MKL_RT is not False:
        return _MKL_RT
    import ctypes.util  # here: 2 ms of imports that only the search for MKL needs

    found = os.environ.get("IPCSIM_MKL_RT") or ctypes.util.find_library("mkl_rt")
    if not found:
        names = ("libmkl_rt.so*", "libmkl_rt*.dylib", "mkl_rt*.dll")
        bases = [sys.prefix, sys.base_prefix, getattr(site, "USER_BASE", None) or ""]
        cands = [p for base in dict.fromkeys(bases) if base
                 for sub in ("lib", "Library/bin") for name in names
                 for p in glob.glob(os.path.join(base, sub, name))]
        found = min(cands, key=len) if cands else None
    _MKL_RT = found
    return found


_P32 = ctypes.POINTER(ctypes.c_int32)


def _load_pardiso():
    path = find_mkl_rt()
    if path is None:
        raise ImportError("MKL (libmkl_rt) not found; pip install mkl")
    try:
        lib = ctypes.CDLL(path)
    except OSError as exc:
        raise ImportError(f"cannot load {path}: {exc}") from None
    fn = lib.pardiso
    fn.argtypes = [ctypes.POINTER(ctypes.c_int64), _P32, _P32, _P32, _P32, _P32,
                   ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                   _P32, ctypes.c_void_p, _P32, ctypes.c_void_p, ctypes.c_void_p, _P32]
    fn.restype = None
    return fn


_PARDISO_ERRORS = {
    -1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
    -4: "zero pivot (matrix not positive definite?)", -5: "unclassified internal error",
    -6: "reordering failed", -7: "diagonal matrix is singular", -8: "32-bit integer overflow",
    -9: "not enough memory for out-of-core", -10: "error opening out-of-core files",
    -11: "read/write error with out-of-core files", -12: "wrong pardiso_64 call",
    -13: "interrupted", -15: "internal error",
}


class PardisoSolver(_Factorising):
    """MKL PARDISO for real symmetric positive definite matrices (mtype 2), zero-based upper
    CSR, ordering ``iparm[1]``: 2 = METIS (default), 0 = minimum degree, 3 = parallel METIS.
    Phases: 11 analysis (kept per pattern), 22 numeric factorisation, 33 solve."""

    name = "pardiso"
    MTYPE = 2  # real SPD

    def __init__(self, ordering: int = 2):
        self._pardiso = _load_pardiso()  # ImportError: not available
        self._pt = np.zeros(64, dtype=np.int64)  # PARDISO's opaque handle; zero = none yet
        self._iparm = np.zeros(64, dtype=np.int32)
        ip = self._iparm
        ip[0] = 1            # use the values below, no defaults
        ip[1] = int(ordering)
        ip[9] = 8            # pivot perturbation 1e-8 (only if a pivot is tiny)
        ip[17] = -1          # report nnz(L) in iparm[17]
        ip[34] = 1           # zero-based indices
        self._pattern: _LowerPattern | None = None
        self._ia = self._ja = self._a = None
        self._analysed = False
        self._n = 0

    def _call(self, phase: int, b: np.ndarray, x: np.ndarray) -> None:
        err = ctypes.c_int32(0)
        one = ctypes.c_int32(1)
        self._pardiso(self._pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                      ctypes.byref(one), ctypes.byref(ctypes.c_int32(1)),
                      ctypes.byref(ctypes.c_int32(self.MTYPE)), ctypes.byref(ctypes.c_int32(phase)),
                      ctypes.byref(ctypes.c_int32(self._n)),
                      self._a.ctypes.data if self._a is not None else None,
                      self._ia.ctypes.data if self._ia is not None else None,
                      self._ja.ctypes.data if self._ja is not None else None,
                      None, ctypes.byref(ctypes.c_int32(1)), self._iparm.ctypes.data,
                      ctypes.byref(ctypes.c_int32(0)), b.ctypes.data, x.ctypes.data,
                      ctypes.byref(err))
        if err.value != 0:
            raise SolverError(f"PARDISO phase {phase} failed: error {err.value} "
                              f"({_PARDISO_ERRORS.get(err.value, 'unknown')})")

    def _release(self) -> None:
        if self._pt.any():
            dummy = np.zeros(1)
            try:
                self._call(-1, dummy, dummy)
            except SolverError:
                pass
            self._pt[:] = 0
        self._analysed = False

    def __del__(self):
        try:
            self._release()
        except Exception:
            pass

    def _load(self, A) -> bool:
        indptr, indices, data = _symmetric_csc_arrays(A)
        n = len(indptr) - 1
        if self._pattern is not None and self._pattern.n == n and self._pattern.same(indptr, indices):
            self._a = self._pattern.values(data)
            return False
        if n >= 2**31 or len(indices) >= 2**31:
            raise SolverError("matrix too large for 32-bit PARDISO indices")
        pat = _LowerPattern(indptr, indices, n, keep=getattr(A, "fixed_arrays", False))
        rows, _ = pat.rows_and_columns()
        if not pat.has_diagonal(rows):  # PARDISO needs every diagonal entry; SPD needs it > 0
            raise SolverError("matrix has a structurally zero diagonal entry (not positive definite)")
        self._release()
        self._pattern, self._n = pat, n
        # lower CSC of a symmetric matrix = upper CSR, the layout PARDISO reads
        self._ia = pat.indptr.astype(np.int32)
        self._ja = rows.astype(np.int32)
        self._a = pat.values(data)
        return True

    def _analyse(self) -> None:
        dummy = np.zeros(1)
        self._call(11, dummy, dummy)
        self._analysed = True

    def _factorise(self) -> None:
        dummy = np.zeros(1)
        self._call(22, dummy, dummy)

    def _backsolve(self, b: np.ndarray) -> np.ndarray:
        b = np.array(b, dtype=np.float64).reshape(-1)
        x = np.zeros_like(b)
        self._call(33, b, x)
        return _check(x)


# --------------------------------------------------------------------------- selection

SOLVERS = {"cholmod": CholmodSolver, "pardiso": PardisoSolver, "scipy": ScipySolver}
# what "auto" tries, fastest first (docs/linear-solvers.md)
AUTO_ORDER = ("cholmod", "scipy")
# "auto" factors systems of at most this many DOFs dense (DenseSolver)
DENSE_UP_TO = 60
# ... and of at most this many where the terms' Hessians go into the dense matrix in one
# call: the Python that saves outweighs the dense factor's n³ (docs/linear-solvers.md)
DENSE_HESSIAN_UP_TO = 240
# the original's names and other spellings
ALIASES = {"eigen": "scipy", "amgcl": "scipy", "superlu": "scipy", "mkl": "pardiso"}


def available_solvers() -> list[str]:
    names = []
    for name, cls in SOLVERS.items():
        try:
            cls()
        except ImportError:
            continue
        names.append(name)
    return names


def make_solver(name: str | None = None, n_dofs: int | None = None,
                dense_up_to: int = DENSE_UP_TO):
    """The named solver, or the fastest one installed for ``None``/``"auto"``: for
    systems of at most ``n_dofs`` DOFs (when known) up to ``dense_up_to``, ``DenseSolver``.

    The original's names map onto ours: CHOLMOD -> cholmod, EIGEN/AMGCL -> scipy.
    Unknown names raise ValueError; a known backend that is not installed raises
    ImportError.
    """
    key = (name or "auto").lower()
    key = ALIASES.get(key, key)
    if key == "auto":
        if n_dofs is not None and n_dofs <= dense_up_to:
            return DenseSolver()
        for candidate in AUTO_ORDER:
            try:
                return SOLVERS[candidate]()
            except ImportError:
                continue
        return ScipySolver()
    if key not in SOLVERS:
        raise ValueError(f"unknown linear solver {name!r}; choose from {sorted(SOLVERS)}")
    return SOLVERS[key]()
