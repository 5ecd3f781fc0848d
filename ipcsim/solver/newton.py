"""Projected Newton with a feasibility-filtered backtracking line search (IPC, Algorithm 1).

One call minimises a time step's problem from x₀; each iteration is

    evaluate   E, ∇E and the PSD-projected Hessian at x (κ adapted there)
    direction  H_ff p_f = −g_f − H_fk p_k                     (assemble, solve)
    stop?      ‖p‖∞ < tol, the prescribed motion complete, the terms' own test
    CCD bound  the largest α that keeps x + αp free of intersections and inversions
    backtrack  α halved until E(x + αp) < E(x)
    follow up  the pull of prescribed vertices that the first iteration left behind

Newton knows nothing of contact. It sees the problem through a small protocol
(``potentials/step_problem.py``): ``kinematic`` (n,) and ``target`` (n, 3);
``start(x0)`` → a point; ``evaluate(point, order)`` → (the problem at the adapted κ,
an ``Evaluation``: E, ∇E, Hessian triplets, contacts); ``line_search(point, p,
remaining, complete, halvings)`` → a ``LineStep`` (the next point, α, E, failed, E(x));
``resolved(x, p)``; ``prescribed_complete()``; ``follow_up(point, p, first)`` → (problem,
point); ``nonfinite_terms(x, p)`` to name a culprit. Every value passes through the loop
and comes back new; nothing is written into the problem.

Kinematic DOFs are eliminated: their part of the direction is the remaining prescribed
motion p_k = target − x_k (the Newton step of the constrained problem from a point that
has not reached the constraint yet), set to 0 once 99.9 % of it is done. While
prescribed motion remains, the largest feasible step is taken (the energy of an
unfinished constraint is not comparable); once the kinematic DOFs sit on their targets,
α is halved until the energy decreases.

Stopping rule, as the original: ‖p‖∞ < tol (absolute, tol·l·h) with the motion complete,
and the problem's own test of p (friction's static ramp); the converged direction is
still taken (it costs no solve), so a step always moves by at least one Newton direction
and a slow body does not stall below the tolerance.
"""

from __future__ import annotations

from msgspec import Struct, field
from msgspec.structs import replace
import numpy as np

from ..errors import NonFiniteError, SolverError
from ..kernels.algebra.linalg import dot
from ..records import same_bits
from .assembly import Assembler, DenseAssembler
from .timing import PhaseTimer


def _norm(v: np.ndarray) -> float:
    """‖v‖₂ summed in index order."""
    v = np.ascontiguousarray(v, dtype=np.float64)
    return float(np.sqrt(dot(v, v)))


class _Dofs(Struct, frozen=True, eq=False):
    """The DOF masks of a kinematic vertex mask: prescribed and free DOFs, each DOF's
    free number (−1 if prescribed) and how many are free."""

    kinematic: np.ndarray  # (n,) the vertex mask they come from
    prescribed: np.ndarray  # (3n,) bool
    free: np.ndarray  # (3n,) bool
    index: np.ndarray  # (3n,) int64
    n_free: int


class _System(Struct, frozen=True, eq=False):
    """The Newton system H_ff p_f = rhs over the free DOFs (A, rhs, the coupling H_fk p_k)
    and the direction p (3n,) with its prescribed part filled in."""

    A: object
    rhs: np.ndarray
    coupling: np.ndarray
    p: np.ndarray
    remaining: float  # the prescribed motion still to go, ‖p_k‖∞
    dofs: _Dofs


class NewtonResult(Struct, frozen=True):
    """What one minimisation did. ``rows`` holds a newton.csv row per iteration;
    ``final`` is the problem's evaluation at ``x`` (energy and contacts), and ``problem``
    the problem as the minimisation left it (κ, the pull's end)."""

    x: np.ndarray
    final: object
    iterations: int = 0
    converged: bool = False
    hit_iteration_cap: bool = False
    min_alpha: float = 1.0
    kinematic_complete: bool = True
    line_search_failures: int = 0
    rows: tuple[dict, ...] = field(default=())
    problem: object = None

    @property
    def point(self):
        """Where the minimisation ended, with what is known there."""
        return self.final.point

    def then(self, later: "NewtonResult") -> "NewtonResult":
        """This minimisation followed by ``later`` from where it ended (a friction update)."""
        return replace(later, iterations=self.iterations + later.iterations,
                       hit_iteration_cap=self.hit_iteration_cap or later.hit_iteration_cap,
                       min_alpha=min(self.min_alpha, later.min_alpha),
                       line_search_failures=self.line_search_failures
                       + later.line_search_failures, rows=self.rows + later.rows)


class _Progress(Struct):
    """The running record of one ``solve``."""

    prescribed: float  # ‖target − x‖∞ over kinematic DOFs at the start
    tol: float = 0.0  # the ‖p‖∞ tolerance
    iterations: int = 0
    min_alpha: float = 1.0
    kinematic_complete: bool = True
    line_search_failures: int = 0
    rows: list = field(default_factory=list)


class NewtonSolver:
    def __init__(self, settings, linear_solver, timer: PhaseTimer | None = None,
                 observer=None):
        """``settings``: the model's ``SolverSettings``; ``observer(row)``, when given,
        receives each newton.csv row once it is complete (``ipcsim run -v``); ``watch``,
        when set, receives every evaluation (tests watch the iterates so)."""
        self.settings = settings
        self.linear_solver = linear_solver
        self.timer = timer or PhaseTimer()
        self.observer = observer
        self.watch = None
        # a solver that factors dense arrays (small systems) gets the matrix as one
        self.assembler = DenseAssembler() if getattr(linear_solver, "dense", False) \
            else Assembler()
        self._recent: list[_Dofs] = []  # the DOF masks of the last two kinematic masks

    def _dofs(self, kinematic) -> _Dofs:
        """The DOF masks of ``kinematic``, the same arrays while it is one of the last two
        masks seen (the same array, or equal): a step that pulls its prescribed vertices
        goes back and forth between two masks, and the assembler keeps its pattern per
        free-index array. A problem's mask is a value: a changed mask is a new array."""
        for dofs in self._recent:
            if dofs.kinematic is kinematic:
                return dofs
        for i, dofs in enumerate(self._recent):
            if same_bits(dofs.kinematic, kinematic):
                # each step brings a new, equal mask: found by identity from now on
                self._recent[i] = dofs = replace(dofs, kinematic=kinematic)
                return dofs
        prescribed = np.repeat(kinematic, 3)
        free = ~prescribed
        index = np.full(free.size, -1, dtype=np.int64)
        n_free = int(free.sum())
        index[free] = np.arange(n_free)
        dofs = _Dofs(kinematic, prescribed, free, index, n_free)
        self._recent = [dofs, *self._recent[:1]]
        return dofs

    def solve(self, problem, point, tol: float,
              max_iterations: int | None = None) -> NewtonResult:
        """Minimise ``problem`` from ``point`` (``problem.start(x0)``) until ‖p‖∞ < tol
        with the prescribed motion complete, or the iteration cap (``max_iterations``
        where given: an adaptive step's budget)."""
        cap = self.settings.max_newton_iterations if max_iterations is None \
            else max_iterations
        kin_dofs = self._dofs(problem.kinematic).prescribed
        target, x0 = problem.target.reshape(-1), point.x.reshape(-1)
        run = _Progress(np.abs(target[kin_dofs] - x0[kin_dofs]).max(initial=0.0), tol)
        run.kinematic_complete = run.prescribed == 0.0
        for it in range(cap):
            problem, ev = self._evaluate(problem, point, 2)
            point = ev.point
            self._complete_last_row(run, ev.contacts)
            if not np.isfinite(ev.gradient).all():
                raise NonFiniteError("gradient", problem.nonfinite_terms(point.x), it)
            system = self._system(problem, ev, run)
            ev = ev.without_hessian()  # its triplets go before the factorisation
            p, remaining = self._direction(problem, point.x, system, run, it)
            del system  # the matrix too goes before the line search
            free = self._dofs(problem.kinematic).free
            step_norm = np.abs(p[free]).max(initial=0.0)
            row = {"iteration": it, "step_inf_norm": step_norm, "tolerance": tol,
                   "gradient_norm": _norm(ev.gradient[free]), "kappa": ev.kappa,
                   "residual_ratio": step_norm / tol if tol > 0 else np.nan}
            converged = (run.kinematic_complete and step_norm < tol
                         and problem.prescribed_complete() and problem.resolved(point.x, p))
            if converged and step_norm == 0.0:  # nothing left to do
                known = problem.energy_known(point)
                run.rows.append({**row, "alpha": 0.0,
                                 "energy": ev.energy if known is None else known})
            else:
                # a converged direction is still taken: it is nearly free (no solve) and,
                # at a step's first iteration, it is the whole motion of a slow body
                step = self._line_search(problem, point, p, remaining, run, it)
                run.rows.append({**row, "alpha": step.alpha, "energy": step.energy})
                point = step.point
                if step.failed:
                    # no step along p lowers E in floating point: x is a minimiser to
                    # machine precision (typical when tol sits near round-off), unless
                    # the step is far above the tolerance
                    run.line_search_failures += 1
                    run.min_alpha = 0.0
                    run.iterations = it + 1
                    return self._finish(problem, point, run, converged=step_norm < self
                                        .settings.roundoff_tolerance_factor * tol)
                run.min_alpha = min(run.min_alpha, step.alpha)
            if converged:
                run.iterations = it + 1
                return self._finish(problem, point, run, converged=True)
            problem, point = problem.follow_up(point, p, first=it == 0)  # may pull
        run.iterations = cap
        return self._finish(problem, point, run, converged=False, hit_cap=True)

    def _evaluate(self, problem, point, order: int):
        """The problem's evaluation at the point; the previous row ends there."""
        problem, ev = problem.evaluate(point, order)
        if self.watch is not None:
            self.watch(ev.x, ev)
        return problem, ev

    def _system(self, problem, ev, run: _Progress) -> "_System":
        """The Newton system over the free DOFs at x (assembled from ev's Hessian) and the
        prescribed part of the direction: p_k = target − x_k, the motion still remaining
        (0 once 99.9 % of it is done)."""
        dofs = self._dofs(problem.kinematic)
        p = np.zeros(ev.x.size)
        p_kin = (problem.target.reshape(-1)[dofs.prescribed]
                 - ev.x.reshape(-1)[dofs.prescribed])
        remaining = np.abs(p_kin).max(initial=0.0)
        if remaining <= self.settings.kinematic_completion * run.prescribed:
            p_kin[:] = 0.0  # done: stop pushing the last 0.1 %
            remaining = 0.0
        run.kinematic_complete = remaining == 0.0
        p[dofs.prescribed] = p_kin
        with self.timer("assembly"):
            A, coupling = self.assembler.assemble(*ev.hessian, dofs.index, dofs.n_free, p)
            rhs = -ev.gradient[dofs.free] - coupling
        return _System(A, rhs, coupling, p, remaining, dofs)

    def _direction(self, problem, x, system: "_System", run: _Progress, it: int):
        """The Newton direction p (3n,) at x, its free part solving
        H_ff p_f = −g_f − H_fk p_k, and the prescribed motion still remaining."""
        p, dofs = system.p, system.dofs
        with self.timer("solve"):
            try:
                p[dofs.free] = (self.linear_solver.solve(system.A, system.rhs)
                                if dofs.n_free else 0.0)
            except SolverError:
                bad = problem.nonfinite_terms(x)
                if bad:  # a NaN in the matrix is the cause: name its term
                    raise NonFiniteError("Hessian", bad, it) from None
                raise
        if not np.isfinite(p).all():
            raise NonFiniteError("Newton direction", problem.nonfinite_terms(x), it)
        if system.remaining > 0.0 and dofs.n_free and np.abs(p[dofs.free]).max() < run.tol:
            # the free DOFs are converged, the prescribed motion is not: follow it with
            # the free DOFs' linear response alone, H_ff p_f = −H_fk p_k. The free part's
            # own residual (below tol) would otherwise move them far more than the small
            # rest of the motion does, and CCD would cut every step to a part of it.
            with self.timer("solve"):
                p[dofs.free] = self.linear_solver.solve_again(-system.coupling)
        return p, system.remaining

    def _line_search(self, problem, point, p, remaining, run: _Progress, it: int):
        """The problem's line search along p, with its checks: a NaN bound or energy
        names the term that is not finite."""
        step = problem.line_search(point, p, remaining, run.kinematic_complete,
                                   self.settings.max_halvings)
        if not step.alpha >= 0.0:  # NaN: a bound (CCD, inversion) saw a non-finite input
            raise NonFiniteError("step bound", problem.nonfinite_terms(point.x, p), it)
        if run.kinematic_complete:
            if not np.isfinite(step.e0):
                raise NonFiniteError("energy", problem.nonfinite_terms(point.x), it)
        elif not np.isfinite(step.energy):
            raise NonFiniteError("energy", problem.nonfinite_terms(step.point.x), it)
        return step

    def _complete_last_row(self, run: _Progress, contacts) -> None:
        """The previous iteration's row gets the contacts at the iterate it ended at."""
        if run.rows and "contacts_total" not in run.rows[-1]:
            run.rows[-1].update(contacts.as_row())
            if self.observer is not None:
                self.observer(run.rows[-1])

    def _finish(self, problem, point, run: _Progress, converged: bool,
                hit_cap: bool = False) -> NewtonResult:
        problem, final = self._evaluate(problem, point, 0)
        if not np.isfinite(final.energy):
            raise NonFiniteError("energy", problem.nonfinite_terms(point.x), run.iterations)
        self._complete_last_row(run, final.contacts)
        return NewtonResult(x=final.x, final=final, iterations=run.iterations,
                            converged=converged, hit_iteration_cap=hit_cap,
                            min_alpha=run.min_alpha, kinematic_complete=run.kinematic_complete,
                            line_search_failures=run.line_search_failures,
                            rows=tuple(run.rows), problem=problem)
