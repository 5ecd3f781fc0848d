"""Projected Newton with a feasibility-filtered backtracking line search.

One call minimises the incremental potential of a time step. Kinematic DOFs are
eliminated: their part of the search direction is the remaining prescribed motion
p_k = target − x_k, and the free part solves

    H_ff p_f = −g_f − H_fk p_k

(the Newton step of the constrained problem from a point that has not reached the
constraint yet). Every step is first bounded by ``max_step`` (CCD and the inversion bound),
so no iterate ever intersects or inverts. While prescribed motion remains, the largest
feasible step is taken (the energy of an unfinished constraint is not comparable); once
the kinematic DOFs sit on their targets, α is halved until the energy decreases.

Stopping rule, as the original: ‖p‖∞ < tol (absolute, tol·l·h) with the motion complete;
the converged direction is still taken (it costs no solve), so a step always moves by at
least one Newton direction and a slow body does not stall below the tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import NonFiniteError, SolverError
from .assembly import Assembler
from .incremental import IncrementalPotential

# A prescribed motion counts as complete when ≥ 99.9 % of it is done, as in the original.
KINEMATIC_COMPLETION = 1e-3
MAX_HALVINGS = 40
# A failed line search ends the step as converged when ‖p‖∞ is within this factor of tol.
ROUNDOFF_TOLERANCE_FACTOR = 1e3


@dataclass
class NewtonResult:
    iterations: int = 0
    converged: bool = False
    hit_iteration_cap: bool = False
    min_alpha: float = 1.0
    kinematic_complete: bool = True
    line_search_failures: int = 0


class NewtonSolver:
    def __init__(self, linear_solver, max_iterations: int = 1000):
        self.linear_solver = linear_solver
        self.max_iterations = max_iterations
        self.assembler = Assembler()
        self._free = None  # (kinematic mask, DOF -> free index), reused while unchanged

    def _free_index(self, kinematic):
        if self._free is None or not np.array_equal(self._free[0], kinematic):
            free_dofs = ~np.repeat(kinematic, 3)
            index = np.full(free_dofs.size, -1, dtype=np.int64)
            index[free_dofs] = np.arange(int(free_dofs.sum()))
            self._free = (kinematic.copy(), index)
        return self._free[1]

    def solve(self, potential: IncrementalPotential, x: np.ndarray, kinematic: np.ndarray,
              target: np.ndarray, tol: float, before_iteration=None, after_iteration=None):
        """Minimise ``potential`` from ``x`` (n,3). ``kinematic`` (n,) bool marks vertices
        that must reach ``target`` (n,3). Returns (x, NewtonResult).

        ``before_iteration(x)`` refreshes contact sets and κ and returns True when that
        changed the potential; ``after_iteration(x, info)`` receives a dict per iteration
        for the Newton log.
        """
        timer = potential.timer
        x = x.copy()
        kin_dofs = np.repeat(kinematic, 3)
        free_dofs = ~kin_dofs
        n_free = int(free_dofs.sum())
        free_index = self._free_index(kinematic)  # DOF -> free DOF number, −1 if kinematic
        target_flat = target.reshape(-1)
        prescribed = np.abs(target_flat[kin_dofs] - x.reshape(-1)[kin_dofs]).max(initial=0.0)
        result = NewtonResult(kinematic_complete=prescribed == 0.0)
        energy = None  # E(x), known after a line search

        for it in range(self.max_iterations):
            if before_iteration is not None and before_iteration(x):
                energy = None  # the potential itself changed (κ)
            g = potential.gradient(x)
            if not np.isfinite(g).all():
                raise NonFiniteError("gradient", potential.nonfinite_terms(x), it)
            static, dynamic = potential.hessian(x)
            p = np.zeros(x.size)
            p_kin = target_flat[kin_dofs] - x.reshape(-1)[kin_dofs]
            remaining = np.abs(p_kin).max(initial=0.0)
            if remaining <= KINEMATIC_COMPLETION * prescribed:
                p_kin[:] = 0.0  # done: stop pushing the last 0.1 %
                remaining = 0.0
            result.kinematic_complete = remaining == 0.0
            p[kin_dofs] = p_kin

            with timer("assembly"):
                A, coupling = self.assembler.assemble(static, dynamic, free_index, n_free, p)
                rhs = -g[free_dofs] - coupling
            with timer("solve"):
                try:
                    p[free_dofs] = self.linear_solver.solve(A, rhs) if n_free else 0.0
                except SolverError:
                    bad = potential.nonfinite_terms(x)
                    if bad:  # a NaN in the matrix is the cause: name its term
                        raise NonFiniteError("Hessian", bad, it) from None
                    raise

            if not np.isfinite(p).all():
                raise NonFiniteError("Newton direction", potential.nonfinite_terms(x), it)
            step_norm = np.abs(p[free_dofs]).max(initial=0.0)
            info = {"iteration": it, "step_inf_norm": step_norm, "tolerance": tol,
                    "gradient_norm": float(np.linalg.norm(g[free_dofs]))}
            converged = result.kinematic_complete and step_norm < tol
            if converged and step_norm == 0.0:
                alpha = 0.0  # nothing left to do
            else:
                # a converged direction is still taken: it is nearly free (no solve) and,
                # at a step's first iteration, it is the whole motion of a slow body
                alpha = min(1.0, potential.max_step(x, p))
                if not alpha >= 0.0:  # NaN: a bound (CCD, inversion) saw a non-finite input
                    raise NonFiniteError("step bound", potential.nonfinite_terms(x, p), it)
                if result.kinematic_complete:
                    alpha, failed, energy = self._backtrack(potential, x, p, alpha, energy)
                    if not np.isfinite(energy):  # E at x (failed) or at x + αp
                        raise NonFiniteError("energy", potential.nonfinite_terms(x), it)
                    if failed:
                        # no step along p lowers E in floating point: x is a minimiser to
                        # machine precision (typical when tol sits near round-off), unless
                        # the step is far above the tolerance
                        result.line_search_failures += 1
                        result.min_alpha = 0.0
                        result.converged = step_norm < ROUNDOFF_TOLERANCE_FACTOR * tol
                        result.iterations = it + 1
                        info.update(alpha=0.0, energy=energy)
                        if after_iteration is not None:
                            after_iteration(x, info)
                        return x, result
                x_new = x + alpha * p.reshape(-1, 3)
                if alpha == 1.0 and remaining > 0.0:
                    x_new[kinematic] = target[kinematic]  # land exactly on the targets
                x = x_new
                if not result.kinematic_complete:
                    energy = potential.value(x)
                result.min_alpha = min(result.min_alpha, alpha)
            info["alpha"] = alpha
            info["energy"] = potential.value(x) if energy is None else energy
            if not np.isfinite(info["energy"]):
                raise NonFiniteError("energy", potential.nonfinite_terms(x), it)
            if after_iteration is not None:
                after_iteration(x, info)
            if converged:
                result.converged = True
                result.iterations = it + 1
                return x, result

        result.iterations = self.max_iterations
        result.hit_iteration_cap = True
        return x, result

    @staticmethod
    def _backtrack(potential, x, p, alpha, e0=None):
        """Halve α until E(x + αp) < E(x). Returns (α, True if it gave up, E at the point
        kept: x + αp, or x itself when it gave up). Equal energies count as no progress:
        they only occur once E has reached round-off."""
        if e0 is None:
            e0 = potential.value(x)
        p3 = p.reshape(-1, 3)
        for _ in range(MAX_HALVINGS):
            e = potential.value(x + alpha * p3)
            if e < e0:
                return alpha, False, e
            alpha *= 0.5
        return 0.0, True, e0
