"""The cached-pattern assembler equals plain COO assembly with kinematic elimination."""

import numpy as np
import pytest
import scipy.sparse as sp

from ipcsim.potentials.base import Triplets
from ipcsim.solver.assembly import Assembler, CscMatrix

RNG = np.random.default_rng(11)


def _random_triplets(n_dofs, k):
    return Triplets(RNG.integers(0, n_dofs, k), RNG.integers(0, n_dofs, k), RNG.normal(size=k))


def _reference(parts, kinematic_dofs, p):
    H = Triplets.concat(parts).tocsr(len(kinematic_dofs)).toarray()
    free = ~kinematic_dofs
    return H[np.ix_(free, free)], H[np.ix_(free, kinematic_dofs)] @ p[kinematic_dofs]


def _assert_canonical(A):
    """What CscMatrix promises the solvers: each column's rows sorted and unique."""
    assert A.indptr[0] == 0 and A.indptr[-1] == len(A.indices) == len(A.data)
    for j in range(A.shape[1]):
        rows = A.indices[A.indptr[j]:A.indptr[j + 1]]
        assert np.all(np.diff(rows) > 0)
    assert sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape).has_canonical_format


def test_assembly_matches_reference_and_reuses_the_pattern():
    n_dofs = 60
    static = [_random_triplets(n_dofs, 400), _random_triplets(n_dofs, 200)]
    assembler = Assembler()
    for step in range(3):
        kinematic = np.zeros(n_dofs, dtype=bool)
        kinematic[RNG.choice(n_dofs, 6 * step, replace=False)] = True
        free_index = np.full(n_dofs, -1)
        free_index[~kinematic] = np.arange((~kinematic).sum())
        for _ in range(2):  # new values, same pattern objects
            static = [Triplets(s.rows, s.cols, RNG.normal(size=len(s.vals))) for s in static]
            # a contact term without contacts gives empty triplets: nothing to merge
            dynamic = ([_random_triplets(n_dofs, 30), Triplets.empty()] if step
                       else [Triplets.empty()])
            p = RNG.normal(size=n_dofs)
            ref_A, ref_c = _reference(static + dynamic, kinematic, p)
            given = list(dynamic)
            A, coupling = assembler.assemble(static, given, free_index, int((~kinematic).sum()), p)
            assert given == []  # the contact triplets were taken over and let go
            assert isinstance(A, CscMatrix)
            _assert_canonical(A)
            np.testing.assert_allclose(A.toarray(), ref_A, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(coupling, ref_c, rtol=1e-12, atol=1e-12)
            if not step:  # only empty dynamic parts: the static pattern itself, no copy
                assert A.indices is assembler._patterns[0].indices



def test_a_pull_going_back_and_forth_between_two_masks_builds_two_patterns(monkeypatch):
    """A step that pulls its prescribed vertices alternates between two kinematic masks
    (the free-index array of each is kept by Newton): the assembler builds each mask's
    pattern once, and a third mask lets the least recently used one go."""
    import ipcsim.solver.assembly as assembly

    built = []
    real = assembly._StaticPattern

    def counting(parts, free_index, n_free):
        built.append(n_free)
        return real(parts, free_index, n_free)

    monkeypatch.setattr(assembly, "_StaticPattern", counting)
    n_dofs = 30
    static = [_random_triplets(n_dofs, 300)]
    masks = [np.zeros(n_dofs, dtype=bool) for _ in range(3)]
    masks[0][:6] = True
    masks[2][-3:] = True
    free_indices = []
    for kinematic in masks:
        free_index = np.full(n_dofs, -1)
        free_index[~kinematic] = np.arange((~kinematic).sum())
        free_indices.append(free_index)
    assembler = Assembler()
    for which in (0, 1, 0, 1, 0, 2, 0, 1):
        kinematic, free_index = masks[which], free_indices[which]
        p = RNG.normal(size=n_dofs)
        A, coupling = assembler.assemble(static, [], free_index, int((~kinematic).sum()), p)
        ref_A, ref_c = _reference(static, kinematic, p)
        np.testing.assert_allclose(A.toarray(), ref_A, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(coupling, ref_c, rtol=1e-12, atol=1e-12)
    # masks 0 and 1 once each; 2 evicts 1 (0 was used last); 1 again after 0
    assert built == [24, 30, 27, 30]

def test_contact_triplets_merge_in_the_order_of_one_stable_sort():
    """The contact triplets are bucketed by column and each column sorted and summed; the
    merged matrix is bit for bit the one a single stable sort of all (col, row) keys
    gives, duplicates summed in order and then added to the fixed part's entry."""
    from ipcsim.kernels.algebra import assembly as ka

    n = 50
    fixed = sp.random(n, n, density=0.1, random_state=3, format="csc")
    fixed.sort_indices()
    rows = RNG.integers(0, n, 20000)
    cols = np.concatenate([RNG.integers(0, n, 19000), np.full(1000, 7)])  # a long column
    vals = RNG.normal(size=rows.size)
    vals[::17] = 0.0  # zero triplets add no entry
    free_index = np.arange(n)
    start = np.zeros(n + 1, dtype=np.int64)
    coupling = np.zeros(n)
    ka.count_kept_columns(rows, cols, vals, 0.5, free_index, np.zeros(n), coupling, start)
    np.cumsum(start, out=start)
    bucket_rows = np.empty(int(start[-1]), dtype=np.int32)
    bucket_vals = np.empty(int(start[-1]))
    ka.bucket_kept(rows, cols, vals, 0.5, free_index, start[:-1].copy(), bucket_rows,
                   bucket_vals)
    indptr, indices, data = ka.merge_columns(fixed.indptr.astype(np.int32),
                                             fixed.indices.astype(np.int32), fixed.data,
                                             start, bucket_rows, bucket_vals)
    # the reference: one stable sort of the keys, sums in order, then the fixed entry
    keep = vals != 0.0
    keys = (cols * n + rows)[keep]
    scaled = (0.5 * vals)[keep]
    order = np.argsort(keys, kind="stable")
    sums = {}
    for key, v in zip(keys[order].tolist(), scaled[order].tolist()):
        sums[key] = sums[key] + v if key in sums else v
    coo = fixed.tocoo()
    for r, c, v in zip(coo.row.tolist(), coo.col.tolist(), coo.data.tolist()):
        key = c * n + r
        sums[key] = sums[key] + v if key in sums else v
    want = sorted(sums)
    got_cols = np.repeat(np.arange(n), np.diff(indptr))
    assert (got_cols * n + indices).tolist() == want
    assert data.tolist() == [sums[k] for k in want]  # bit for bit


@pytest.mark.parametrize("chunk", [8192, 7])  # one piece, and pieces of 7 blocks
def test_contact_blocks_merge_as_their_triplets_do(chunk, monkeypatch):
    """A BlockHessian (12 × 12 blocks over 4-vertex stencils, no row or column stored)
    gives the same matrix and coupling, bit for bit, as the triplets it stands for."""
    from ipcsim.potentials.base import BlockHessian

    monkeypatch.setattr(BlockHessian, "CHUNK", chunk)

    n_vertices = 20
    n_dofs = 3 * n_vertices
    stencils = np.array([RNG.choice(n_vertices, 4, replace=False) for _ in range(40)])
    vals = RNG.normal(size=144 * len(stencils))
    vals[RNG.random(vals.size) < 0.3] = 0.0  # uninvolved vertices' rows and columns
    blocks = BlockHessian(stencils, vals).scaled(2.5)
    triplets = Triplets(blocks.rows, blocks.cols, vals, 2.5)
    assert blocks.rows.dtype == np.int32 and blocks.size == 144 * len(stencils)
    np.testing.assert_array_equal(blocks.tocsr(n_dofs).toarray(),
                                  triplets.tocsr(n_dofs).toarray())
    static = [_random_triplets(n_dofs, 300)]
    kinematic = np.zeros(n_dofs, dtype=bool)
    kinematic[:9] = True  # three vertices prescribed: their columns go to the coupling
    free_index = np.full(n_dofs, -1)
    free_index[~kinematic] = np.arange((~kinematic).sum())
    p = RNG.normal(size=n_dofs)
    got = Assembler().assemble(static, [blocks], free_index, int((~kinematic).sum()), p)
    want = Assembler().assemble(static, [triplets], free_index, int((~kinematic).sum()), p)
    for a, b in zip((got[0].indptr, got[0].indices, got[0].data, got[1]),
                    (want[0].indptr, want[0].indices, want[0].data, want[1])):
        np.testing.assert_array_equal(a, b)
    ref_A, ref_c = _reference(static + [triplets], kinematic, p)
    np.testing.assert_allclose(got[0].toarray(), ref_A, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got[1], ref_c, rtol=1e-12, atol=1e-12)


def test_newton_keeps_the_free_index_of_the_last_two_masks():
    """The assembler knows a pattern by its free-index array: Newton hands out the same
    array for a mask while it is one of the last two seen."""
    from ipcsim.solver.newton import NewtonSolver

    newton = NewtonSolver(settings=None, linear_solver=None)
    a, b, c = (np.zeros(5, dtype=bool) for _ in range(3))
    a[0] = True
    c[4] = True
    def free_index(mask):
        return newton._dofs(mask).index

    first_a, first_b = free_index(a), free_index(b)
    assert free_index(a.copy()) is first_a and free_index(b) is first_b
    np.testing.assert_array_equal(first_a, [-1, -1, -1, *range(12)])
    free_index(c)  # a third mask: a, the least recently made, goes
    assert free_index(b) is first_b
    assert free_index(a) is not first_a
    assert newton._dofs(b).n_free == 15 and newton._dofs(c).prescribed[12:].all()


def _elastic_hessian(n_cells=(2, 1, 1)):
    """An ElementHessian (per-tet 12 × 12 blocks, evaluated when assembled) of a jittered
    box, and its vertex count."""
    from ipcsim.model.generate import box_tet_mesh
    from ipcsim.potentials.elasticity import Elasticity

    X, tets = box_tet_mesh(*n_cells)
    Dm = np.stack([X[tets[:, k]] - X[tets[:, 0]] for k in (1, 2, 3)], axis=2)
    elastic = Elasticity(tets, np.linalg.inv(Dm), np.linalg.det(Dm) / 6.0, (1e4, 4e4), "NH",
                         len(X))
    x = X + 0.05 * RNG.normal(size=X.shape)
    return elastic.hessian(x), len(X)


@pytest.mark.parametrize("prescribed", [0, 3])
def test_the_dense_assembly_is_the_sparse_one_as_an_array(prescribed):
    """DenseAssembler (DenseSolver's) gives the matrix and coupling of Assembler, for
    every kind of part: int32 and int64 triplets, element blocks, contact blocks."""
    from ipcsim.potentials.base import BlockHessian
    from ipcsim.solver.assembly import DenseAssembler

    elastic, n_vertices = _elastic_hessian()
    n_dofs = 3 * n_vertices
    dofs = np.arange(n_dofs, dtype=np.int32)
    inertia = Triplets(dofs, dofs, RNG.random(n_dofs) + 1.0)  # int32, as the mass's
    stencils = np.array([RNG.choice(n_vertices, 4, replace=False) for _ in range(6)])
    contact = BlockHessian(stencils, RNG.normal(size=144 * len(stencils))).scaled(3.0)
    friction = _random_triplets(n_dofs, 50).scaled(0.5)  # int64
    kinematic = np.zeros(n_vertices, dtype=bool)
    kinematic[RNG.choice(n_vertices, prescribed, replace=False)] = True
    kin_dofs = np.repeat(kinematic, 3)
    free_index = np.full(n_dofs, -1)
    free_index[~kin_dofs] = np.arange((~kin_dofs).sum())
    n_free = int((~kin_dofs).sum())
    p = RNG.normal(size=n_dofs)
    static = [inertia, elastic.scaled(0.01)]
    dynamic = [contact, Triplets.empty(), friction]
    sparse_A, sparse_c = Assembler().assemble(static, list(dynamic), free_index, n_free, p)
    given = list(dynamic)
    A, coupling = DenseAssembler().assemble(static, given, free_index, n_free, p)
    assert given == []  # taken over and let go, as Assembler does
    assert isinstance(A, np.ndarray) and A.shape == (n_free, n_free) and A.flags.c_contiguous
    np.testing.assert_allclose(A, sparse_A.toarray(), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(coupling, sparse_c, rtol=1e-12, atol=1e-9)
    if prescribed:
        assert np.abs(coupling).max() > 0.0


def test_newton_assembles_dense_for_a_solver_that_factors_dense_arrays():
    from ipcsim.solver.assembly import DenseAssembler
    from ipcsim.solver.linear import CholmodSolver, DenseSolver, ScipySolver
    from ipcsim.solver.newton import NewtonSolver

    assert isinstance(NewtonSolver(None, DenseSolver()).assembler, DenseAssembler)
    assert isinstance(NewtonSolver(None, ScipySolver()).assembler, Assembler)
    try:
        assert isinstance(NewtonSolver(None, CholmodSolver()).assembler, Assembler)
    except ImportError:
        pass


def test_the_block_product_is_the_matrix_product():
    """``block_matvec`` (the lagged damping's D·Δx) equals the product with the sparse
    matrix of the same blocks, duplicates summed."""
    from ipcsim.kernels.algebra.scatter import block_matvec

    elastic, n_vertices = _elastic_hessian((2, 2, 1))
    D = elastic.kept().scaled(0.3)
    v = RNG.normal(size=3 * n_vertices)
    np.testing.assert_allclose(block_matvec(D.vals, D.scale, D.elements, v),
                               D.tocsr(3 * n_vertices) @ v, rtol=1e-12, atol=1e-12)


def test_a_damped_run_leaves_scipy_unimported(tmp_path, repo_root):
    """Rayleigh damping multiplies by its blocks (``LaggedDamping.times``): a run with
    ``dampingRatio`` imports no scipy (0.13 s of imports) and still damps."""
    from generated import packages_a_run_imports, write_box_msh

    write_box_msh(tmp_path / "box.msh", cells=(1, 1, 1))
    scene = tmp_path / "damped.txt"
    scene.write_text("shapes input 1\nbox.msh 0 0.3 0  0 0 0  1 1 1\nground 0 0\n"
                     "time 0.2 0.01\ntimeIntegration NM\ndampingRatio 0.5\n")
    status, packages = packages_a_run_imports(scene, tmp_path / "out")
    assert status == 0 and "scipy" not in packages and "numpy" in packages
    terms = (tmp_path / "out" / "run.json").read_text()
    assert "damping" in terms
