"""The sparse SPD solvers of ipcsim.solver.linear: accuracy, symbolic reuse, selection."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from ipcsim.errors import SolverError
from ipcsim.solver import linear
from ipcsim.solver.linear import (AUTO_ORDER, SOLVERS, available_solvers,
                                  group_nested_dissection, make_solver)

AVAILABLE = available_solvers()


def block_spd(n_vertices: int, seed: int, extra_pairs: int = 0, scale_seed: int | None = None):
    """Full symmetric CSC SPD matrix with 3×3 blocks: a random vertex graph (each vertex
    coupled to ~6 others, like a tet mesh's edges), random dense blocks, and a diagonal that
    makes it strictly diagonally dominant. ``extra_pairs`` adds couplings (a new pattern);
    ``scale_seed`` rescales values symmetrically (same pattern, new values)."""
    rng = np.random.default_rng(seed)
    i = np.repeat(np.arange(n_vertices), 3)
    j = (i + rng.integers(1, n_vertices, size=i.size)) % n_vertices  # never i itself
    if extra_pairs:
        extra = np.random.default_rng(seed + 1000)
        i = np.concatenate([i, extra.integers(0, n_vertices, extra_pairs)])
        j = np.concatenate([j, extra.integers(0, n_vertices, extra_pairs)])
        keep = i != j
        i, j = i[keep], j[keep]
    blocks = rng.standard_normal((i.size, 3, 3))
    a = np.arange(3)
    rows = (3 * i[:, None, None] + a[None, :, None]).repeat(3, axis=2).ravel()
    cols = (3 * j[:, None, None] + a[None, None, :]).repeat(3, axis=1).ravel()
    R = sp.csc_matrix((blocks.ravel(), (rows, cols)), shape=(3 * n_vertices,) * 2)
    A = R + R.T
    diag = np.abs(A).sum(axis=1).A.ravel() + 1.0
    A = (A + sp.diags(diag)).tocsc()
    if scale_seed is not None:
        d = 1.0 + np.random.default_rng(scale_seed).random(A.shape[0])
        A = sp.diags(d) @ A @ sp.diags(d)
    A = sp.csc_matrix(A)
    A.sort_indices()
    return A


def rel_residual(A, x, b):
    return np.linalg.norm(A @ x - b) / np.linalg.norm(b)


def require(name):
    if name not in AVAILABLE:
        pytest.skip(f"{name} backend not installed")


@pytest.mark.parametrize("name", sorted(SOLVERS))
@pytest.mark.parametrize("n_vertices", [100, 1000])
def test_backend_solves_block_spd(name, n_vertices):
    require(name)
    A = block_spd(n_vertices, seed=n_vertices)
    b = np.random.default_rng(1).standard_normal(A.shape[0])
    solver = make_solver(name)
    assert solver.name == name
    x = solver.solve(A, b)
    assert x.shape == b.shape
    assert rel_residual(A, x, b) < 1e-10
    # CSR of a symmetric matrix is read without conversion and gives the same answer
    assert rel_residual(A, make_solver(name).solve(A.tocsr(), b), b) < 1e-10


@pytest.mark.parametrize("name", sorted(SOLVERS))
def test_symbolic_reuse_same_pattern_then_new_pattern(name, monkeypatch):
    require(name)
    solver = make_solver(name)
    cls = type(solver)
    analyses = []
    if hasattr(cls, "_analyse"):
        original = cls._analyse
        monkeypatch.setattr(cls, "_analyse", lambda self: (analyses.append(1), original(self)))
    rng = np.random.default_rng(2)
    A1 = block_spd(300, seed=3)
    A2 = block_spd(300, seed=3, scale_seed=4)          # same pattern, new values
    A3 = block_spd(300, seed=3, extra_pairs=200)       # new pattern, same size
    A4 = block_spd(250, seed=5)                        # new size
    assert np.array_equal(A1.indices, A2.indices) and not np.allclose(A1.data, A2.data)
    assert A3.nnz > A1.nnz
    for k, (A, reanalysed) in enumerate([(A1, True), (A2, False), (A1, False), (A3, True),
                                         (A2, True), (A4, True), (A4, False)]):
        b = rng.standard_normal(A.shape[0])
        count = len(analyses)
        x = solver.solve(A, b)
        assert rel_residual(A, x, b) < 1e-10, f"call {k}"
        if hasattr(cls, "_analyse"):
            assert len(analyses) - count == int(reanalysed), f"call {k}"


@pytest.mark.parametrize("name", sorted(SOLVERS))
def test_input_not_mutated_and_non_canonical_input(name):
    require(name)
    A = block_spd(120, seed=6)
    b = np.random.default_rng(7).standard_normal(A.shape[0])
    data, b0 = A.data.copy(), b.copy()
    solver = make_solver(name)
    x = solver.solve(A, b)
    assert np.array_equal(A.data, data) and np.array_equal(b, b0)
    # COO with duplicate entries (summed), and CSC with unsorted indices
    C = A.tocoo()
    half = C.data / 2
    dup = sp.coo_matrix((np.concatenate([half, half]), (np.tile(C.row, 2), np.tile(C.col, 2))),
                        shape=A.shape)
    assert np.allclose(solver.solve(dup, b), x, rtol=1e-9, atol=1e-12)
    U = A.copy()
    for j in range(U.shape[1]):
        s, e = U.indptr[j], U.indptr[j + 1]
        U.indices[s:e] = U.indices[s:e][::-1]
        U.data[s:e] = U.data[s:e][::-1]
    U.has_sorted_indices = False
    assert np.allclose(solver.solve(U, b), x, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("name", sorted(SOLVERS))
def test_empty_system(name):
    require(name)
    assert make_solver(name).solve(sp.csc_matrix((0, 0)), np.zeros(0)).shape == (0,)


@pytest.mark.parametrize("name", ["cholmod", "pardiso"])
def test_indefinite_matrix_raises_solver_error(name):
    require(name)
    A = block_spd(50, seed=8)
    A = sp.csc_matrix(A - sp.diags(np.full(A.shape[0], 2.0 * A.diagonal().max())))
    with pytest.raises(SolverError):
        make_solver(name).solve(A, np.ones(A.shape[0]))


@pytest.mark.parametrize("name", ["cholmod", "pardiso"])
def test_missing_diagonal_raises_solver_error(name):
    require(name)
    A = block_spd(50, seed=12).tolil()
    A[7, 7] = 0.0
    A = A.tocsc()
    A.eliminate_zeros()
    assert A.nnz and A[7, 7] == 0
    with pytest.raises(SolverError):
        make_solver(name).solve(A, np.ones(A.shape[0]))


@pytest.mark.parametrize("ordering", ["amd", "metis"])
@pytest.mark.parametrize("supernodal", [True, False])
def test_cholmod_orderings_and_factor_kinds(ordering, supernodal):
    require("cholmod")
    if ordering == "metis":
        pytest.importorskip("pymetis")
    A = block_spd(400, seed=9)
    b = np.random.default_rng(10).standard_normal(A.shape[0])
    solver = linear.CholmodSolver(ordering=ordering, supernodal=supernodal)
    assert rel_residual(A, solver.solve(A, b), b) < 1e-10
    with pytest.raises(ValueError):
        linear.CholmodSolver(ordering="colamd")


def test_auto_ordering_is_amd_for_small_matrices_and_metis_from_its_threshold():
    """Small systems never import pymetis (25 ms of a tiny scene's start); large ones
    are ordered by METIS where it is installed, and both solve."""
    require("cholmod")
    pytest.importorskip("pymetis")
    solver = linear.CholmodSolver()
    assert solver.ordering == "auto"
    assert solver._ordering_for(linear.CholmodSolver.METIS_FROM - 1) == "amd"
    assert solver._ordering_for(linear.CholmodSolver.METIS_FROM) == "metis"
    code = ("import sys, numpy as np, scipy.sparse as sp; from ipcsim.solver import linear; "
            "A = sp.identity(300, format='csc') * 2.0; "
            "x = linear.CholmodSolver().solve(A, np.ones(300)); "
            "print(round(float(x[0]), 12), 'pymetis' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["0.5", "False"]
    A = block_spd(linear.CholmodSolver.METIS_FROM // 3 + 1, seed=4)
    b = np.random.default_rng(5).standard_normal(A.shape[0])
    assert rel_residual(A, solver.solve(A, b), b) < 1e-10


@pytest.mark.parametrize("n", [2, 3, 299, 300, 301])
def test_group_nested_dissection_is_a_permutation(n):
    pytest.importorskip("pymetis")
    A = block_spd(max(2, (n + 2) // 3), seed=n)[:n, :n].tocsc()
    perm = group_nested_dissection(A.indptr, A.indices, n)
    assert perm.dtype == np.int64
    assert np.array_equal(np.sort(perm), np.arange(n))
    if n % 3 == 0:  # a vertex's DOFs stay together, in order
        assert np.all(perm.reshape(-1, 3) - perm.reshape(-1, 3)[:, :1] == np.arange(3))


@pytest.mark.parametrize("n", [2, 3, 299, 300, 301])
def test_the_block_graph_is_the_groups_coupling_graph(n):
    """METIS's graph, built column by column, is the one defined entry by entry: every pair
    of DOF groups that share a stored entry, both ways, sorted, no self-loops."""
    from ipcsim.kernels.algebra.assembly import block_graph

    A = block_spd(max(2, (n + 2) // 3), seed=n, extra_pairs=n)[:n, :n].tocsc()
    xadj, adjncy = block_graph(A.indptr, A.indices, n, 3)
    groups = (n + 2) // 3
    col = np.repeat(np.arange(n), np.diff(A.indptr)) // 3
    row = A.indices // 3
    pairs = {(int(r), int(c)) for r, c in zip(row, col) if r != c}
    expected = [sorted(h for g2, h in pairs if g2 == g) for g in range(groups)]
    assert xadj.dtype == adjncy.dtype == np.int64
    assert len(xadj) == groups + 1 and xadj[0] == 0
    assert [list(adjncy[xadj[g]:xadj[g + 1]]) for g in range(groups)] == expected


def test_unknown_name_raises():
    with pytest.raises(ValueError, match="unknown linear solver"):
        make_solver("umfpack")


def test_aliases():
    assert make_solver("EIGEN").name == "scipy"
    assert make_solver("superlu").name == "scipy"
    assert make_solver("AMGCL").name == "scipy"
    if "cholmod" in AVAILABLE:
        assert make_solver("CHOLMOD").name == "cholmod"


def test_auto_picks_the_first_available():
    expected = next((n for n in AUTO_ORDER if n in AVAILABLE), "scipy")
    for name in (None, "auto", "AUTO"):
        solver = make_solver(name)
        assert solver.name == expected
        assert solver.name in AVAILABLE
    A = block_spd(100, seed=11)
    b = np.ones(A.shape[0])
    assert rel_residual(A, make_solver(None).solve(A, b), b) < 1e-10


def test_auto_falls_back_when_preferred_backends_are_missing(monkeypatch):
    def missing():
        raise ImportError("not installed")

    monkeypatch.setitem(linear.SOLVERS, "cholmod", missing)
    monkeypatch.setitem(linear.SOLVERS, "pardiso", missing)
    assert make_solver(None).name == "scipy"
    assert available_solvers() == ["scipy"]


@pytest.mark.parametrize("name", sorted(SOLVERS))
def test_solve_again_reuses_the_last_factor(name):
    """Newton's kinematic completion solves a second right-hand side with the factor of
    the first solve: the answer must be that of the same matrix."""
    require(name)
    A = block_spd(200, seed=7)
    solver = make_solver(name)
    rng = np.random.default_rng(3)
    solver.solve(A, rng.standard_normal(A.shape[0]))
    b = rng.standard_normal(A.shape[0])
    assert rel_residual(A, solver.solve_again(b), b) < 1e-10
    assert solver.solve_again(np.zeros(0)).shape == (0,)


@pytest.mark.parametrize("name", [n for n in ("cholmod", "pardiso") if n in AVAILABLE])
def test_the_newton_matrix_arrays_are_kept_and_other_matrices_copied(name):
    """A solver remembers a pattern by its index arrays: the Newton matrix's own
    (``CscMatrix``, never written once made) are kept as they are, a scipy matrix's are
    copied, since its owner may change them."""
    from ipcsim.solver.assembly import CscMatrix

    A = block_spd(30, seed=4)
    b = np.arange(A.shape[0], dtype=float)
    ours = CscMatrix(A.data.copy(), A.indices.copy(), A.indptr.copy(), A.shape)
    solver = make_solver(name)
    x = solver.solve(ours, b)
    assert solver._pattern.indices_full is ours.indices
    assert rel_residual(A, x, b) < 1e-10
    solver = make_solver(name)
    solver.solve(A, b)
    assert solver._pattern.indices_full is not A.indices
    np.testing.assert_array_equal(solver._pattern.indices_full, A.indices)


# --------------------------------------------------------------------------- dense (small)

@pytest.mark.parametrize("n_vertices", [2, 5, 16, 32])
def test_dense_solver_agrees_with_numpy(n_vertices):
    """The dense factor of a small system solves it as numpy's LAPACK solve does, from
    CSC, CSR and non-canonical input (duplicates, unsorted rows)."""
    A = block_spd(n_vertices, seed=20 + n_vertices, scale_seed=1)
    b = np.random.default_rng(n_vertices).standard_normal(A.shape[0])
    expected = np.linalg.solve(A.toarray(), b)
    solver = linear.DenseSolver()
    for M in (A, A.tocsr(), A.tocoo()):
        x = solver.solve(M, b)
        np.testing.assert_allclose(x, expected, rtol=1e-11, atol=1e-14)
    C = A.tocoo()
    dup = sp.coo_matrix((np.concatenate([C.data / 2, C.data / 2]),
                         (np.tile(C.row, 2), np.tile(C.col, 2))), shape=A.shape)
    np.testing.assert_allclose(solver.solve(dup, b), expected, rtol=1e-11, atol=1e-14)


def test_dense_solver_agrees_with_cholmod_on_the_newton_matrix():
    """On the Newton matrix as assembly makes it (``CscMatrix``, int32 indices) the dense
    factor and CHOLMOD give the same direction to round-off."""
    require("cholmod")
    from ipcsim.solver.assembly import CscMatrix

    A = block_spd(16, seed=31)
    ours = CscMatrix(A.data.copy(), A.indices.astype(np.int32), A.indptr.astype(np.int32),
                     A.shape)
    b = np.random.default_rng(5).standard_normal(A.shape[0])
    x = linear.DenseSolver().solve(ours, b)
    assert rel_residual(A, x, b) < 1e-13
    np.testing.assert_allclose(x, linear.CholmodSolver().solve(ours, b), rtol=1e-12,
                               atol=1e-15)


def test_dense_solver_solves_again_with_its_factor_and_sizes_follow_the_matrix():
    solver = linear.DenseSolver()
    rng = np.random.default_rng(8)
    for n_vertices in (10, 4, 10):  # a new size each time: the factor follows it
        A = block_spd(n_vertices, seed=n_vertices)
        solver.solve(A, rng.standard_normal(A.shape[0]))
        b = rng.standard_normal(A.shape[0])
        assert rel_residual(A, solver.solve_again(b), b) < 1e-12
    with pytest.raises(ValueError, match="right side"):
        solver.solve_again(np.ones(3))
    assert solver.solve(sp.csc_matrix((0, 0)), np.zeros(0)).shape == (0,)
    assert solver.solve_again(np.zeros(0)).shape == (0,)


@pytest.mark.parametrize("defect", ["indefinite", "zero diagonal", "nan"])
def test_dense_solver_refuses_what_is_not_positive_definite(defect):
    A = block_spd(12, seed=14).tolil()
    if defect == "indefinite":
        A = A - sp.diags(np.full(A.shape[0], 2.0 * A.diagonal().max()))
    elif defect == "zero diagonal":
        A[7, 7] = 0.0
    else:
        A[5, 5] = np.nan
    solver = linear.DenseSolver()
    with pytest.raises(SolverError, match="Cholesky"):
        solver.solve(sp.csc_matrix(A), np.ones(A.shape[0]))
    with pytest.raises(ValueError):  # no factor is left to solve again with
        solver.solve_again(np.ones(A.shape[0]))


def test_auto_factors_small_systems_dense_and_others_with_the_sparse_default():
    expected = next((n for n in AUTO_ORDER if n in AVAILABLE), "scipy")
    assert make_solver(None, linear.DENSE_UP_TO).name == "dense"
    assert make_solver("auto", 3).name == "dense"
    assert make_solver("auto", linear.DENSE_UP_TO + 1).name == expected
    assert make_solver("auto").name == expected  # size unknown
    assert make_solver("scipy", 3).name == "scipy"  # a named solver is what it names


def test_a_small_scene_runs_without_importing_kvxopt(tmp_path, repo_root):
    """A scene of one cube of 8 vertices factors dense: kvxopt, 9 ms of imports, stays
    out."""
    from generated import packages_a_run_imports, write_box_msh

    write_box_msh(tmp_path / "box.msh", cells=(1, 1, 1))
    scene = tmp_path / "box_drop.toml"
    scene.write_text((repo_root / "input" / "cube_drop.toml").read_text()
                     .replace('"meshes/cube.msh"', '"box.msh"'))
    status, packages = packages_a_run_imports(scene, tmp_path / "out", "--steps", "30")
    assert status == 0 and "kvxopt" not in packages and "numpy" in packages
    info = (tmp_path / "out" / "run.json").read_text()
    assert '"linear_solver": "dense"' in info


def test_dense_solver_factors_a_dense_array_in_place():
    """The dense matrix DenseAssembler makes is factored where it lies (its lower
    triangle becomes L) and solves as the sparse matrix does."""
    A = block_spd(12, seed=40)
    b = np.random.default_rng(41).standard_normal(A.shape[0])
    dense = np.ascontiguousarray(A.toarray())
    solver = linear.DenseSolver()
    x = solver.solve(dense, b)
    np.testing.assert_allclose(x, linear.DenseSolver().solve(A, b), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.tril(dense) @ np.tril(dense).T, A.toarray(), rtol=1e-12,
                               atol=1e-12)
    assert rel_residual(A, solver.solve_again(2 * b), 2 * b) < 1e-12
    with pytest.raises(ValueError, match="square"):
        solver.solve(np.ones((3, 4)), np.ones(3))
    with pytest.raises(ValueError, match="not C-contiguous"):
        solver.solve(np.asfortranarray(np.eye(3) + np.tri(3)), np.ones(3))
    indefinite = np.ascontiguousarray(A.toarray() - 2.0 * np.abs(A).max() * np.eye(A.shape[0]))
    with pytest.raises(SolverError, match="Cholesky"):
        solver.solve(indefinite, b)


def _cholesky_row_by_row(A):
    """The textbook Cholesky factor, one entry at a time in plain Python floats:
    L_ij = (A_ij − Σ_k<j L_ik L_jk) / L_jj with the sum in k order."""
    n = len(A)
    L = [[0.0] * n for _ in range(n)]
    for j in range(n):
        d = float(A[j][j])
        for k in range(j):
            d -= L[j][k] * L[j][k]
        L[j][j] = d ** 0.5
        for i in range(j + 1, n):
            s = float(A[i][j])
            for k in range(j):
                s -= L[i][k] * L[j][k]
            L[i][j] = s / L[j][j]
    return np.array(L)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6, 7, 9, 13, 30])
def test_dense_cholesky_kernel_rounds_as_the_textbook_formula(n):
    """``cholesky_in_place`` works on four rows at once; each entry is still the
    textbook sum in k order, so its factor equals the formula's bit for bit (every
    count of rows left over after the blocks of four occurs)."""
    from ipcsim.kernels.algebra.linalg import cholesky_in_place

    rng = np.random.default_rng(n)
    B = rng.standard_normal((n, n))
    A = B @ B.T + n * np.eye(n)
    L = A.copy()
    assert cholesky_in_place(L)
    np.testing.assert_array_equal(np.tril(L), _cholesky_row_by_row(A))
    np.testing.assert_array_equal(np.triu(L, 1), np.triu(A, 1))  # not read, nor written


@pytest.mark.parametrize("row", [1, 4, 8, 10])
def test_dense_cholesky_kernel_refuses_a_nan_below_the_diagonal(row):
    from ipcsim.kernels.algebra.linalg import cholesky_in_place

    A = block_spd(4, seed=3).toarray()
    A[row, 0] = np.nan
    assert not cholesky_in_place(A)
