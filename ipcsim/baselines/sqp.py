"""The time step of the SQP and QP baselines (Li et al. 2020, §8 and its supplement).

The step minimises the same incremental potential E as IPC's, less the barrier (and less
friction: the baselines are frictionless), subject to collision constraints c(x) ≥ offset
over the active set of ``active_set`` (empty at the start of each step, grown by CCD):

    Δx = argmin ½ ΔxᵀH Δx + ∇Eᵀ Δx   s.t.  c_s(x_k) + ∇c_s(x_k)·Δx ≥ offset,

H the (PSD-projected) Hessian of E over the free DOFs; kinematic vertices are put on their
targets first and do not move in the QP.

* **SQP** iterates: linearise at x_k, solve, step x_{k+1} = x_k + αΔx (α = 1, except that
  with neo-Hookean elasticity α is the inversion-free bound of the step), grow the active set with the pairs the motion x_n -> x_{k+1}
  brings into contact; until ‖αΔx‖∞ < tol (the Newton tolerance) and, with
  ``useActiveSetConvergence``, no pair was added.
* **QP** solves one QP per step, linearised at the step's start x_0: x = x_0 + Δx. With
  ``useActiveSetConvergence`` the same QP is solved again from x_0 while the motion
  x_n -> x adds pairs.

No barrier, no CCD filter of the step (CCD only finds the pairs, as in the original): the
result can intersect. Where the original warm-starts, its warm start only seeds the active
set (the motion x_n -> x_n + warm-start displacement); the iteration starts at x_n.

Failures are ``SolverError``s with a label: "Blow-up" (a vertex moved by more than
``blow_up_factor`` times the scene's extent in one QP, or non-finite), "QP failure" (OSQP reports
the QP infeasible twice in a row; after the first, the active set is cleared, as the
original does). ``intersections(x)`` tells whether a state intersects.
"""

from __future__ import annotations

import msgspec
from msgspec import Struct, field
import numpy as np

from ..contact.collisions import pair_distances
from ..contact.intersection import find_intersections
from ..contact.setup import ContactCount
from ..errors import NonFiniteError, SolverError
from ..solver.assembly import Assembler
from ..solver.newton import NewtonResult
from .active_set import ActiveSet, ConstraintGeometry, Stencils, grow, linearise
from .qp import require_osqp, solve_qp


class _Run(Struct):
    """The running record of one step."""

    x_start: np.ndarray  # x_n
    x0: np.ndarray  # x_n with the kinematic vertices on their targets
    free_index: np.ndarray  # DOF -> free DOF number, −1 for kinematic DOFs
    n_free: int
    extent: float  # the scene's largest extent at x_n
    active: ActiveSet = field(default_factory=ActiveSet.empty)
    failures: int = 0  # QP failures in a row
    alpha: float = 1.0  # the step fraction of the last QP's direction
    min_alpha: float = 1.0
    rows: list = field(default_factory=list)


class ConstrainedSolver:
    """The minimisation of one time step by SQP or QP (``settings``: the model's
    ConstraintSolverSettings; ``contact``: its ContactSetup; ``energy``: "NH" or "FCR")."""

    def __init__(self, settings, contact, linear_solver, timer, energy: str):
        require_osqp()
        self.settings = settings
        self.geometry = ConstraintGeometry(contact.mesh, contact.planes,
                                           settings.constraint_type, settings.offset)
        self.linear_solver = linear_solver
        self.timer = timer
        self.energy = energy
        self.assembler = Assembler()

    def minimise(self, problem, x_guess: np.ndarray, tol: float) -> NewtonResult:
        """The step's problem (``potentials/step_problem.py``, without barriers)
        minimised from the start xₙ with the prescribed vertices on their targets; a
        warm start ``x_guess`` only seeds the active set."""
        run = self._start(problem, x_guess)
        s, x = self.settings, run.x0
        ev, converged = None, False
        for it in range(s.max_iterations):
            if ev is None or s.method == "SQP":
                _, ev = problem.evaluate(problem.start(x), 2, adapt=False)
                H, g = self._system(ev, run)
            x_lin = run.x0 if s.method == "QP" else x
            x_new, step_norm = self._qp_step(problem, x_lin, (H, g), run, it)
            with self.timer("ccd_line_search"):
                run.active, added = grow(run.active, self.geometry, run.x_start, x_new)
            x = x_new
            run.rows.append(self._row(it, x, ev, step_norm, tol, run))
            settled = not (s.active_set_convergence and added)
            if settled and (s.method == "QP" or step_norm < tol) and run.failures == 0:
                converged = True
                break
        _, final = problem.evaluate(problem.start(x), 0)
        final = msgspec.structs.replace(final, contacts=self._contacts(x, run.active))
        return NewtonResult(x=x, final=final, iterations=len(run.rows), converged=converged,
                            hit_iteration_cap=not converged, min_alpha=run.min_alpha,
                            rows=tuple(run.rows), problem=problem)

    # -- the pieces of a step --------------------------------------------------------------------
    def _start(self, problem, x_guess) -> _Run:
        ctx = problem.ctx
        x_n, kinematic = ctx.x_start, ctx.kinematic
        x0 = x_n.copy()
        x0[kinematic] = ctx.target[kinematic]
        free = ~np.repeat(kinematic, 3)
        index = np.full(free.size, -1, dtype=np.int64)
        index[free] = np.arange(int(free.sum()))
        extent = float((x_n.max(axis=0) - x_n.min(axis=0)).max()) or 1.0
        run = _Run(x_n, x0, index, int(free.sum()), extent)
        if not np.array_equal(x_guess, x_n):  # a warm start: it seeds the active set
            trial = x_guess.copy()
            trial[kinematic] = ctx.target[kinematic]
            with self.timer("ccd_line_search"):
                run.active, _ = grow(run.active, self.geometry, x_n, trial)
        return run

    def _system(self, ev, run: _Run):
        """H over the free DOFs (CSC) and the free part of ∇E."""
        with self.timer("assembly"):
            static, dynamic = ev.hessian
            H, _ = self.assembler.assemble(static, dynamic, run.free_index, run.n_free,
                                           np.zeros(run.free_index.size))
        return H.to_scipy(), ev.gradient[run.free_index >= 0]

    def _qp_step(self, problem, x_lin, system, run: _Run, it: int):
        """Solve the QP linearised at x_lin; returns (x_new, ‖αΔx‖∞)."""
        H, g = system
        lin = linearise(run.active, self.geometry, x_lin, run.free_index, run.n_free)
        with self.timer("solve"):
            qp = solve_qp(H, g, lin.A, lin.lower, self.settings, self.linear_solver)
        if not qp.ok:
            run.failures += 1
            if run.failures >= 2:
                raise SolverError(f"the QP failed twice in a row (OSQP: {qp.status})",
                                  label="QP failure")
            run.active = ActiveSet.empty()  # as the original: start the set afresh
            run.alpha = 0.0
            return x_lin.copy(), 0.0
        run.failures = 0
        dx = np.zeros(x_lin.size)
        dx[run.free_index >= 0] = qp.dx
        dx3 = dx.reshape(-1, 3)
        # the longest vertex move (the original tests ‖Δx‖₂ over all DOFs, which grows with
        # the number of vertices: a uniform 5 m fall of 54 vertices would count)
        length = float(np.sqrt((dx3 * dx3).sum(axis=1).max(initial=0.0)))
        if not np.isfinite(length) or length > self.settings.blow_up_factor * run.extent:
            raise SolverError(f"blow-up: QP {it + 1} moves a vertex by {length:.3g} m, more "
                              f"than {self.settings.blow_up_factor:g} times the scene's "
                              f"extent ({run.extent:.3g} m)", label="Blow-up")
        alpha = self._inversion_free(problem, x_lin, dx3, it)
        run.alpha, run.min_alpha = alpha, min(run.min_alpha, alpha)
        return x_lin + alpha * dx3, alpha * float(np.abs(qp.dx).max(initial=0.0))

    def _inversion_free(self, problem, x, dx3, it: int) -> float:
        """α = 1, or with neo-Hookean elasticity the inversion bound (halved while a tet
        still inverts). The original halves that bound at least once, which takes only
        half of every QP's step (its SQP and QP examples all use fixed corotated
        elasticity, where it takes the whole step)."""
        elasticity = problem.potential.term("elasticity")
        if self.energy != "NH" or elasticity is None:
            return 1.0
        alpha = min(1.0, problem.max_step(x, dx3.reshape(-1), with_mesh=False)[0])
        if not alpha >= 0.0:
            raise NonFiniteError("step bound", problem.nonfinite_terms(x), it)
        for _ in range(60):
            if np.isfinite(elasticity.value(x + alpha * dx3, problem.ctx)):
                return alpha
            alpha *= 0.5
        return 0.0

    def _contacts(self, x, active: ActiveSet) -> ContactCount:
        """The active constraints by kind and the smallest distance among them (signed for
        planes; inf without any)."""
        dmin = np.inf
        if len(active.pt) + len(active.ee):
            d = pair_distances(x, Stencils(active.pt, active.ee))
            dmin = float(np.sqrt(min(d.pt_d2.min(initial=np.inf), d.ee_d2.min(initial=np.inf))))
        planes = self.geometry.planes
        if len(active.planes) and planes is not None:
            v, p = active.planes[:, 0], active.planes[:, 1]
            signed = ((x[v] - planes.origins[p]) * planes.normals[p]).sum(axis=1)
            dmin = min(dmin, float(signed.min()))
        return ContactCount(len(active.planes), len(active.pt), len(active.ee), dmin)

    def _row(self, it, x, ev, step_norm, tol, run: _Run) -> dict:
        free = run.free_index >= 0
        return {"iteration": it, "alpha": run.alpha, "step_inf_norm": step_norm,
                "tolerance": tol, "residual_ratio": step_norm / tol if tol > 0 else np.nan,
                "energy": ev.energy, "gradient_norm": float(np.linalg.norm(ev.gradient[free])),
                "kappa": 0.0, **self._contacts(x, run.active).as_row()}

    # -- after the step ------------------------------------------------------------------------------
    def intersections(self, x: np.ndarray) -> str | None:
        """What intersects in state x (edge–triangle pairs of the collision mesh, except
        between two kinematic primitives; vertices below a plane), or None."""
        found = []
        mesh = self.geometry.mesh
        if mesh is not None:
            edge_body = triangle_body = None
            if not mesh.self_collision:
                edge_body, triangle_body = (mesh.body[mesh.edges[:, 0]],
                                            mesh.body[mesh.triangles[:, 0]])
            pairs = find_intersections(x, mesh.edges, mesh.triangles, edge_body, triangle_body)
            if len(pairs):
                kin = mesh.kinematic
                pairs = pairs[~(kin[mesh.edges[pairs[:, 0]]].all(axis=1)
                                & kin[mesh.triangles[pairs[:, 1]]].all(axis=1))]
            if len(pairs):
                found.append(f"{len(pairs)} edge–triangle pairs cross")
        planes = self.geometry.planes
        if planes is not None and len(planes.vertices):
            v = planes.vertices
            d = ((x[v][:, None, :] - planes.origins[None]) * planes.normals[None]).sum(axis=2)
            below = int(np.count_nonzero((d < 0.0).any(axis=1)))
            if below:
                found.append(f"{below} vertices below a plane")
        return "; ".join(found) or None
