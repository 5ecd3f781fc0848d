"""Small Newton systems: the dense Cholesky kernel against CHOLMOD, as Newton calls them.

    python -m benchmarks.small_solves [--vertices 16 32 40 64 100] [--repeats 7] [--calls 300]

For each size, a bar of ``box_tet_mesh`` cells with that many vertices (1 × 1 cells across,
as benchmarks/linear_solvers.py builds its matrices: NH, twisted and jittered, h² H + M) is
solved ``--calls`` times with new values on the same pattern, the call a Newton iteration
makes (``solver.solve(A, b)`` end to end, as ``CscMatrix`` with int32 indices). Prints the
median over ``--repeats`` of the time per call, for ``DenseSolver`` and ``CholmodSolver``
(and which one ``make_solver("auto", n)`` picks), with the load average before and after.
The two-cube tutorial scenes have 16 vertices (48 DOFs); 10_cubeStack has 40.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from benchmarks.linear_solvers import build_system, perturbed


def newton_matrices(n_vertices: int, calls: int):
    """``calls`` matrices of one pattern (new values each) and right sides, for a bar of
    ``n_vertices`` vertices (n_vertices / 4 − 1 cells long, 1 × 1 across)."""
    from ipcsim.solver.assembly import CscMatrix

    A, b = build_system((n_vertices // 4 - 1, 1, 1))
    out = []
    for k in range(calls):
        B = perturbed(A, seed=k)
        out.append((CscMatrix(B.data, B.indices.astype(np.int32), B.indptr.astype(np.int32),
                              B.shape), np.roll(b, k)))
    return out


def per_call(solver, systems, repeats: int) -> float:
    """Median seconds per ``solve`` over ``repeats`` passes over ``systems``."""
    solver.solve(*systems[0])  # the pattern's first call (analysis) is not what repeats
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        for A, b in systems:
            solver.solve(A, b)
        times.append((time.perf_counter() - t) / len(systems))
    return statistics.median(times)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", nargs="+", type=int, default=[16, 32, 40, 64, 100])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--calls", type=int, default=300)
    args = ap.parse_args(argv)
    from ipcsim.solver.linear import CholmodSolver, DenseSolver, make_solver

    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print("| vertices | DOFs | dense µs/call | cholmod µs/call | cholmod / dense | auto picks |")
    print("|---|---|---|---|---|---|")
    for n in args.vertices:
        systems = newton_matrices(n, args.calls)
        dofs = systems[0][0].shape[0]
        dense = per_call(DenseSolver(), systems, args.repeats)
        cholmod = per_call(CholmodSolver(), systems, args.repeats)
        # both solve the same system to round-off
        x_d, x_c = DenseSolver().solve(*systems[0]), CholmodSolver().solve(*systems[0])
        assert np.allclose(x_d, x_c, rtol=1e-9, atol=1e-12)
        print(f"| {n} | {dofs} | {dense * 1e6:.1f} | {cholmod * 1e6:.1f} | "
              f"{cholmod / dense:.2f} | {make_solver('auto', dofs).name} |")
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
