"""Sparse SPD solvers on Newton systems of an elastic tet bar: analysis, factorisation, solve.

    python -m benchmarks.linear_solvers [--sizes 3k 30k 90k] [--threads 1 2] [--repeats 5]
                                        [--backends NAME ...] [--json FILE]

Test matrices are built the way the solver builds them: a bar of ``box_tet_mesh`` cells
(6 tets each, ~3k / ~30k / ~90k DOFs), neo-Hookean with E = 1e5, ν = 0.4, in a slightly
twisted and jittered configuration; A = h² · (PSD-projected elastic Hessian) + lumped mass
(ρ = 1000, V/4 per vertex), h² = 1e-3, all DOFs free, as the full symmetric CSC matrix that
``NewtonSolver`` hands to ``ipcsim.solver.linear``. b is standard normal.

For every backend that imports here, each phase is timed on its own, median (wall clock and
process CPU time) of ``--repeats`` runs, fewer when one run exceeds the case's time budget:

* convert: scipy CSC -> the backend's input, for a new pattern and for the same pattern with
  new values (where the backend keeps its input between calls);
* symbolic: fill-reducing ordering + symbolic analysis (for SuperLU and cholespy, which have
  no separate phase, the whole factorisation is reported under numeric);
* numeric: numeric factorisation on an analysed pattern; solve: one right-hand side.

The ``ipcsim:*`` rows time ``make_solver(name).solve(A, b)`` end to end: a first call (new
pattern) and a call with new values on the same pattern (what a Newton iteration without
contact changes pays). ``nnz(L)`` is the factor's fill (L + U for SuperLU), which does not
depend on the machine's load.

Each thread count runs in a fresh subprocess with OPENBLAS_NUM_THREADS, MKL_NUM_THREADS and
OMP_NUM_THREADS set before any BLAS loads; the load average (``os.getloadavg``) is recorded
before and after. Backends that are not installed are listed as skipped. The optional ones
install from PyPI wheels: ``pip install pymetis mkl pypardiso cholespy qdldl``. Slow cases stop
at the size named in CASES. The whole run takes about 8 minutes per thread setting on the
2-core VM; results and the decision: docs/linear-solvers.md.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np
import scipy.sparse as sp

SIZES = {"3k": (24, 6, 6), "30k": (60, 12, 12), "90k": (80, 18, 18)}
H2 = 1e-3
DENSITY = 1000.0
YOUNGS, POISSON = 1e5, 0.4


# --------------------------------------------------------------------------- test matrices

def build_system(cells, seed: int = 0):
    """(A full symmetric CSC with sorted indices, b) for a bar of ``cells`` grid cells."""
    from ipcsim.model.generate import box_tet_mesh
    from ipcsim.potentials.elasticity import Elasticity

    nx, ny, nz = cells
    size = (nx / ny, 1.0, nz / ny)
    points, tets = box_tet_mesh(nx, ny, nz, size=size)
    x0 = points[tets[:, 0]]
    Dm = np.stack([points[tets[:, k]] - x0 for k in (1, 2, 3)], axis=2)  # columns x_k - x_0
    volumes = np.linalg.det(Dm) / 6.0
    Dm_inv = np.linalg.inv(Dm)
    mu = YOUNGS / (2 * (1 + POISSON))
    lam = YOUNGS * POISSON / ((1 + POISSON) * (1 - 2 * POISSON))
    n = len(points)
    elastic = Elasticity(tets, Dm_inv, volumes, (mu, lam), "NH", n)

    rng = np.random.default_rng(seed)
    spacing = min(s / c for s, c in zip(size, cells))
    # twist of 0.3 rad end to end about the bar's axis, plus jitter of 5% of a cell
    angle = 0.3 * (points[:, 0] / points[:, 0].max() - 0.5)
    c, s = np.cos(angle), np.sin(angle)
    y, z = points[:, 1] - 0.5 * size[1], points[:, 2] - 0.5 * size[2]
    x = points.copy()
    x[:, 1] = 0.5 * size[1] + c * y - s * z
    x[:, 2] = 0.5 * size[2] + s * y + c * z
    x += 0.05 * spacing * rng.standard_normal(x.shape)

    H = elastic.hessian(x).tocsr(3 * n) * H2
    mass = np.zeros(n)
    np.add.at(mass, tets.ravel(), np.repeat(DENSITY * volumes / 4.0, 4))
    A = (H + sp.diags(np.repeat(mass, 3))).tocsc()
    A.sort_indices()
    b = rng.standard_normal(3 * n)
    return A, b


def perturbed(A, seed: int = 1):
    """Same pattern, new values, still SPD: D A D with D a positive diagonal near 1."""
    d = 1.0 + 0.1 * np.random.default_rng(seed).random(A.shape[0])
    B = A.copy()
    col = np.repeat(np.arange(A.shape[1]), np.diff(A.indptr))
    B.data = A.data * d[A.indices] * d[col]
    return B


def lower_csc(A):
    """Lower triangle of a full symmetric CSC A with sorted indices, as (indptr, indices, data)."""
    n = A.shape[0]
    col = np.repeat(np.arange(n), np.diff(A.indptr))
    mask = A.indices >= col
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(col[mask], minlength=n), out=indptr[1:])
    return indptr, A.indices[mask], A.data[mask], mask


# --------------------------------------------------------------------------- timing

class Timer:
    """Median wall / CPU seconds of up to ``repeats`` calls, stopping early past ``budget``."""

    def __init__(self, repeats: int, budget: float):
        self.repeats, self.budget = repeats, budget

    def __call__(self, fn, repeats=None):
        walls, cpus, result = [], [], None
        for _ in range(repeats or self.repeats):
            c0, w0 = time.process_time(), time.perf_counter()
            result = fn()
            walls.append(time.perf_counter() - w0)
            cpus.append(time.process_time() - c0)
            if sum(walls) > self.budget:
                break
        return {"wall": statistics.median(walls), "cpu": statistics.median(cpus),
                "runs": len(walls)}, result


def residual(A, x, b):
    return float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))


# --------------------------------------------------------------------------- backends
# Each case: (name, needs, fn(A, b, timer) -> dict of phases). ``needs`` is the import that
# decides availability; the dict has "convert", "convert_same", "symbolic", "numeric",
# "solve" (each {"wall", "cpu", "runs"} or absent), "nnz_L" and "residual".

def _phases(solver, A, b, timer, numeric_repeats=None):
    """Time the phases of an ipcsim backend (``_load`` / ``_analyse`` / ``_factorise`` /
    ``_backsolve``), the same code ``solve`` runs."""
    out = {}

    def convert_new():
        solver._pattern = None  # forget the pattern: measure the first-call conversion
        solver._load(A)

    out["convert"], _ = timer(convert_new)
    out["convert_same"], _ = timer(lambda: solver._load(A))
    out["symbolic"], _ = timer(solver._analyse)
    out["numeric"], _ = timer(solver._factorise, repeats=numeric_repeats)
    out["solve"], x = timer(lambda: solver._backsolve(b))
    out["residual"] = residual(A, x, b)
    return out


def _cholmod_case(supernodal: bool, ordering: str):
    def run(A, b, timer):
        from kvxopt import cholmod

        from ipcsim.solver.linear import CholmodSolver, group_nested_dissection

        solver = CholmodSolver(ordering=ordering, supernodal=supernodal)
        out = _phases(solver, A, b, timer, numeric_repeats=None if supernodal else 1)
        if ordering == "metis":
            out["ordering"], _ = timer(lambda: group_nested_dissection(A.indptr, A.indices, A.shape[0]))
        out["nnz_L"] = len(cholmod.getfactor(solver._factor))
        return out

    return run


def _superlu_case(permc: str | None, symmetric: bool = False):
    def run(A, b, timer):
        import scipy.sparse.linalg as spla

        out = {}
        if permc is None:  # spsolve: what the old scipy fallback did, all phases in one
            out["numeric"], x = timer(lambda: spla.spsolve(A, b))
        else:
            kw = {"permc_spec": permc}
            if symmetric:
                kw.update(diag_pivot_thresh=0.0, options={"SymmetricMode": True})
            out["numeric"], lu = timer(lambda: spla.splu(A, **kw))
            out["solve"], x = timer(lambda: lu.solve(b))
            out["nnz_L"] = int(lu.L.nnz + lu.U.nnz)
        out["residual"] = residual(A, x, b)
        return out

    return run


def _pardiso_case(ordering: int):
    """MKL PARDISO, real SPD (mtype 2), upper CSR = our lower CSC, through ipcsim's wrapper."""
    def run(A, b, timer):
        from ipcsim.solver.linear import PardisoSolver

        solver = PardisoSolver(ordering=ordering)
        out = _phases(solver, A, b, timer)
        out["nnz_L"] = int(solver._iparm[17])
        solver._release()
        return out

    return run


def _pypardiso_case(A, b, timer):
    """pypardiso as its README uses it: spsolve with the default real-unsymmetric type."""
    import pypardiso

    out = {}

    def total():
        solver = pypardiso.PyPardisoSolver()
        x = solver.solve(A.tocsr(), b)
        solver.free_memory(everything=True)
        return x

    out["numeric"], x = timer(total)
    out["residual"] = residual(A, x, b)
    return out


def _cholespy_case(A, b, timer):
    """cholespy (CHOLMOD built in, reference BLAS): analysis + factorisation in the constructor."""
    from cholespy import CholeskySolverD, MatrixType

    out = {}
    indptr, indices, data, _ = lower_csc(A)
    ii, jj = indptr.astype(np.int32), indices.astype(np.int32)
    out["numeric"], solver = timer(lambda: CholeskySolverD(A.shape[0], ii, jj, data, MatrixType.CSC),
                                   repeats=1)
    x = np.zeros_like(b)
    out["solve"], _ = timer(lambda: solver.solve(b, x))
    out["residual"] = residual(A, x, b)
    return out


def _qdldl_case(A, b, timer):
    """QDLDL: AMD + simplicial up-looking LDLᵀ, single-threaded, no BLAS. Its constructor
    orders, analyses and factors (reported as symbolic); ``update`` refactors (numeric)."""
    import qdldl

    out = {}
    U = sp.triu(A, format="csc")
    out["symbolic"], solver = timer(lambda: qdldl.Solver(U, upper=True), repeats=1)
    out["numeric"], _ = timer(lambda: solver.update(U, upper=True), repeats=1)
    out["solve"], x = timer(lambda: solver.solve(b))
    out["residual"] = residual(A, x, b)
    return out


def _ipcsim_case(name: str):
    def run(A, b, timer):
        from ipcsim.solver.linear import make_solver

        out = {}
        A2 = perturbed(A)

        def first():
            solver = make_solver(name)
            return solver, solver.solve(A, b)

        out["first_call"], (solver, x) = timer(first)
        calls = iter(range(1_000_000))
        # same pattern, values alternating between A2 and A as a Newton iteration's would change
        out["same_pattern"], _ = timer(lambda: solver.solve(A2 if next(calls) % 2 == 0 else A, b))
        out["residual"] = residual(A, solver.solve(A, b), b)
        out["solver_name"] = solver.name
        return out

    return run


# name, module that must import, case, largest size it runs at (slow ones stop early)
CASES = [
    ("cholmod-supernodal-amd", "kvxopt", _cholmod_case(True, "amd"), "90k"),
    ("cholmod-supernodal-metis", "pymetis", _cholmod_case(True, "metis"), "90k"),
    ("cholmod-simplicial-amd", "kvxopt", _cholmod_case(False, "amd"), "30k"),
    ("cholmod-simplicial-metis", "pymetis", _cholmod_case(False, "metis"), "30k"),
    ("pardiso-spd-metis", "pardiso", _pardiso_case(2), "90k"),
    ("pardiso-spd-amd", "pardiso", _pardiso_case(0), "90k"),
    ("pypardiso-default", "pypardiso", _pypardiso_case, "30k"),
    ("superlu-spsolve", "scipy", _superlu_case(None), "30k"),
    ("superlu-splu-COLAMD", "scipy", _superlu_case("COLAMD"), "30k"),
    ("superlu-splu-MMD_AT_PLUS_A", "scipy", _superlu_case("MMD_AT_PLUS_A"), "30k"),
    ("superlu-splu-MMD_AT_PLUS_A-sym", "scipy", _superlu_case("MMD_AT_PLUS_A", True), "90k"),
    ("superlu-splu-NATURAL", "scipy", _superlu_case("NATURAL"), "3k"),
    ("cholespy", "cholespy", _cholespy_case, "30k"),
    ("qdldl", "qdldl", _qdldl_case, "30k"),
    ("ipcsim:cholmod", "kvxopt", _ipcsim_case("cholmod"), "90k"),
    ("ipcsim:pardiso", "pardiso", _ipcsim_case("pardiso"), "90k"),
    ("ipcsim:scipy", "scipy", _ipcsim_case("scipy"), "90k"),
]
SIZE_ORDER = list(SIZES)


def available(module: str) -> bool:
    import importlib

    if module == "pardiso":
        from ipcsim.solver.linear import find_mkl_rt

        return find_mkl_rt() is not None
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True


def run_all(sizes, names, repeats, budget) -> list[dict]:
    rows = []
    timer = Timer(repeats, budget)
    for size in sizes:
        A, b = build_system(SIZES[size])
        for name, module, case, largest in CASES:
            if names and name not in names:
                continue
            base = {"size": size, "dofs": A.shape[0], "nnz_A": int(A.nnz), "backend": name}
            if SIZE_ORDER.index(size) > SIZE_ORDER.index(largest):
                continue
            if not available(module):
                why = ("libmkl_rt not found (pip install mkl)" if module == "pardiso"
                       else f"{module} not importable")
                rows.append({**base, "skipped": why})
                continue
            try:
                rows.append({**base, **case(A, b, timer)})
            except Exception as exc:  # a backend that fails here is a finding, not a crash
                rows.append({**base, "error": f"{type(exc).__name__}: {exc}"})
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    return rows


# --------------------------------------------------------------------------- driver

def _child(args) -> None:
    load0 = os.getloadavg()
    rows = run_all(args.sizes, args.backends, args.repeats, args.budget)
    load1 = os.getloadavg()
    for r in rows:
        r.update(threads=args.threads[0], load_before=load0[0], load_after=load1[0])
    print(json.dumps(rows))


def _fmt(t):
    if not t:
        return "—"
    return f"{t['wall']:.3f}" if t["wall"] < 10 else f"{t['wall']:.1f}"


def table(rows) -> str:
    head = ("| size (DOFs) | backend | thr | convert new / same | symbolic | numeric | solve "
            "| first call / same pattern | nnz(L) | CPU numeric | rel. residual |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        if "skipped" in r or "error" in r:
            lines.append(f"| {r['size']} ({r['dofs']}) | {r['backend']} | {r.get('threads', '')} "
                         f"| {r.get('skipped') or r.get('error')} |||||||")
            continue
        conv = f"{_fmt(r.get('convert'))} / {_fmt(r.get('convert_same'))}" if "convert" in r else "—"
        e2e = (f"{_fmt(r.get('first_call'))} / {_fmt(r.get('same_pattern'))}"
               if "first_call" in r else "—")
        nnz = f"{r['nnz_L'] / 1e6:.2f}M" if r.get("nnz_L") else "—"
        cpu = f"{r['numeric']['cpu']:.3f}" if "numeric" in r else "—"
        sym = _fmt(r.get("symbolic"))
        if "ordering" in r:
            sym += f" ({_fmt(r['ordering'])} METIS)"
        runs = r.get("numeric", r.get("first_call", {})).get("runs", "")
        lines.append(
            f"| {r['size']} ({r['dofs']}) | {r['backend']} | {r.get('threads', '')} | {conv} "
            f"| {sym} | {_fmt(r.get('numeric'))} (n={runs}) | {_fmt(r.get('solve'))} "
            f"| {e2e} | {nnz} | {cpu} | {r['residual']:.0e} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=list(SIZES), choices=list(SIZES))
    ap.add_argument("--threads", nargs="+", type=int, default=[1, 2])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--budget", type=float, default=20.0,
                    help="seconds per timed phase before it stops repeating")
    ap.add_argument("--backends", nargs="*", default=None, help="case names (default: all)")
    ap.add_argument("--json", default=None, help="also write all rows to this file")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        _child(args)
        return
    rows = []
    for k in args.threads:
        env = dict(os.environ, OPENBLAS_NUM_THREADS=str(k), MKL_NUM_THREADS=str(k),
                   OMP_NUM_THREADS=str(k))
        cmd = [sys.executable, "-m", "benchmarks.linear_solvers", "--child", "--threads", str(k),
               "--sizes", *args.sizes, "--repeats", str(args.repeats), "--budget", str(args.budget)]
        if args.backends:
            cmd += ["--backends", *args.backends]
        done = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, text=True, check=True)
        rows += json.loads(done.stdout.strip().splitlines()[-1])
    rows.sort(key=lambda r: (SIZE_ORDER.index(r["size"]), r["backend"], r["threads"]))
    loads = sorted({(r["threads"], round(r["load_before"], 2), round(r["load_after"], 2)) for r in rows})
    print(f"load average (1 min) before/after each thread setting: {loads}")
    print("median seconds (wall clock); n = timed runs of the numeric phase")
    print(table(rows))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
