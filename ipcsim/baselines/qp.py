"""One QP of the baselines: min ½ Δxᵀ P Δx + qᵀ Δx subject to A Δx ≥ l, solved with OSQP
(the solver the original program uses; its settings: relative tolerance 1e-3, no absolute
one, scaled termination, no polishing). Without constraints the QP is the
linear system P Δx = −q, solved by ipcsim's own factorisation.

OSQP's own statuses are kept: a primal or dual infeasible QP is a failure (as in the
original); "maximum iterations reached" and "solved inaccurate" are taken as solutions.
"""

from __future__ import annotations

from msgspec import Struct
import numpy as np
import scipy.sparse as sp

from ..errors import IpcsimError

_FAILED = ("infeasible", "non_cvx", "non-convex", "unsolved")


def require_osqp():
    """The osqp module, or an input error saying how to install it."""
    try:
        import osqp
    except ImportError:
        raise IpcsimError("constraintSolver SQP / QP needs the osqp package "
                          "(pip install 'ipcsim[baselines]')") from None
    return osqp


class QPResult(Struct, frozen=True, eq=False):
    dx: np.ndarray  # (n,) the minimiser (zeros after a failure)
    dual: np.ndarray  # (m,) multipliers of the rows (OSQP's sign: ≤ 0 for ≥ rows)
    status: str
    iterations: int

    @property
    def ok(self) -> bool:
        return not any(word in self.status for word in _FAILED)


def solve_qp(P: sp.csc_matrix, q: np.ndarray, A: sp.csc_matrix, lower: np.ndarray,
             settings, linear_solver) -> QPResult:
    """Minimise ½ΔᵀPΔ + qᵀΔ subject to AΔ ≥ lower (``settings``: the model's
    ConstraintSolverSettings; ``linear_solver`` solves P Δ = −q when there is no row)."""
    n = len(q)
    if A.shape[0] == 0:
        dx = linear_solver.solve(P, -q) if n else np.zeros(0)
        return QPResult(np.asarray(dx, dtype=float), np.zeros(0), "solved (no constraint)", 0)
    osqp = require_osqp()
    solver = osqp.OSQP()
    solver.setup(sp.triu(P, format="csc"), np.ascontiguousarray(q, dtype=float),
                 sp.csc_matrix(A), np.ascontiguousarray(lower, dtype=float),
                 np.full(A.shape[0], np.inf), verbose=False, eps_abs=1e-20,
                 eps_rel=settings.qp_eps_rel, scaled_termination=True, polishing=False,
                 max_iter=settings.qp_max_iterations)
    res = solver.solve(raise_error=False)
    status = str(res.info.status).lower()
    if res.x is None or not np.all(np.isfinite(res.x)):
        status = f"{status}, unsolved (no finite solution)"
    failed = QPResult(np.zeros(n), np.zeros(A.shape[0]), status, int(res.info.iter))
    if not failed.ok:
        return failed
    return QPResult(np.asarray(res.x, dtype=float), np.asarray(res.y, dtype=float), status,
                    int(res.info.iter))
