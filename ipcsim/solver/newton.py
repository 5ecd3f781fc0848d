"""Projected Newton with a feasibility-filtered backtracking line search.

One call minimises an objective: anything with ``kinematic`` (n,) and ``target`` (n, 3),
``evaluate(x, order) -> Evaluation`` (E, ∇E, PSD Hessian triplets), ``max_step(x, p) ->
LineSearch`` (the feasible α and the energy along p), ``resolved(x, p) -> bool``, and
``follow_up(x, p, first) -> x``, ``prescribed_complete()`` and ``revision`` for the pull
of prescribed vertices that the first iteration could not take to their targets
(``potentials/boundary_pull.py``: they become free DOFs, pulled by a stiff spring, and
the step converges only once they are there; ``follow_up`` may place them there and
returns the x Newton goes on from; ``revision`` changes with the potential).
Kinematic DOFs are eliminated: their part of the search direction is the remaining
prescribed motion p_k = target − x_k, and the free part solves

    H_ff p_f = −g_f − H_fk p_k

(the Newton step of the constrained problem from a point that has not reached the
constraint yet). Every step is first bounded by ``max_step`` (CCD and the inversion bound),
so no iterate ever intersects or inverts. While prescribed motion remains, the largest
feasible step is taken (the energy of an unfinished constraint is not comparable); once
the kinematic DOFs sit on their targets, α is halved until the energy decreases.

Stopping rule, as the original: ‖p‖∞ < tol (absolute, tol·l·h) with the motion complete,
and the objective's own test of p (``resolved``: friction's static ramp); the
converged direction is still taken (it costs no solve), so a step always moves by at least
one Newton direction and a slow body does not stall below the tolerance.

On a small scene (a dense system, the terms fused) the iterations run as one compiled
call (``kernels/terms/newton_loop.py``): the loop of ``solve`` step by step, bit for bit. A
pull of prescribed vertices is decided, tightened and ended by Python between such
calls, one iteration each while it lasts. The loop here is the reference the kernel
mirrors, and takes over where an iteration would raise (Python names the culprit).
"""

from __future__ import annotations

import math

from msgspec import Struct, field
from msgspec.structs import replace
import numpy as np

from ..errors import NonFiniteError, SolverError
from ..kernels.terms.newton_loop import (CONVERGED, FOLLOW_UP, ITERATION_CAP,
                                    LINE_SEARCH_FAILED)
from ..kernels.algebra.linalg import dot
from ..records import same_bits
from .assembly import Assembler, DenseAssembler
from .timing import PhaseTimer


_ROW_KEYS = ("iteration", "step_inf_norm", "tolerance", "gradient_norm", "kappa",
             "residual_ratio", "alpha", "energy")  # the compiled iterations' row columns


def _norm(v: np.ndarray) -> float:
    """‖v‖₂ summed in index order, as the compiled iterations sum it."""
    v = np.ascontiguousarray(v, dtype=np.float64)
    return float(np.sqrt(dot(v, v)))


class _System(Struct, frozen=True, eq=False):
    """The Newton system H_ff p_f = rhs over the free DOFs (A, rhs, the coupling H_fk p_k)
    and the direction p (3n,) with its prescribed part filled in."""

    A: object
    rhs: np.ndarray
    coupling: np.ndarray
    p: np.ndarray
    remaining: float  # the prescribed motion still to go, ‖p_k‖∞
    free_dofs: np.ndarray
    n_free: int


class _Dofs(Struct, frozen=True, eq=False):
    """The DOF masks of a kinematic vertex mask: prescribed and free DOFs, each DOF's
    free number (−1 if prescribed) and how many are free."""

    kinematic: np.ndarray  # (n,) the vertex mask they come from
    prescribed: np.ndarray  # (3n,) bool
    free: np.ndarray  # (3n,) bool
    index: np.ndarray  # (3n,) int64
    n_free: int


class NewtonResult(Struct, frozen=True):
    """What one minimisation did. ``rows`` holds a newton.csv row per iteration;
    ``final`` is the objective's evaluation at ``x`` (energy and contacts)."""

    x: np.ndarray
    final: object
    iterations: int = 0
    converged: bool = False
    hit_iteration_cap: bool = False
    min_alpha: float = 1.0
    kinematic_complete: bool = True
    line_search_failures: int = 0
    rows: tuple[dict, ...] = field(default=())

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
        receives each newton.csv row once it is complete (``ipcsim run -v``)."""
        self.settings = settings
        self.linear_solver = linear_solver
        self.timer = timer or PhaseTimer()
        self.observer = observer
        # a solver that factors dense arrays (small systems) gets the matrix as one
        self.assembler = DenseAssembler() if getattr(linear_solver, "dense", False) \
            else Assembler()
        self._recent: list[_Dofs] = []  # the DOF masks of the last two kinematic masks

    def _dofs(self, kinematic) -> _Dofs:
        """The DOF masks of ``kinematic``, the same arrays while it is one of the last two
        masks seen (the same array, or equal): a step that pulls its prescribed vertices
        goes back and forth between two masks, and the assembler keeps its pattern per
        free-index array. An objective's mask is a value: a changed mask is a new array."""
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

    def solve(self, objective, x0: np.ndarray, tol: float) -> NewtonResult:
        """Minimise ``objective`` from ``x0`` (n, 3) until ‖p‖∞ < tol with the prescribed
        motion complete, or the iteration cap."""
        x = x0.copy()
        kin_dofs = self._dofs(objective.kinematic).prescribed
        target = objective.target.reshape(-1)
        run = _Progress(np.abs(target[kin_dofs] - x.reshape(-1)[kin_dofs]).max(initial=0.0),
                        tol)
        run.kinematic_complete = run.prescribed == 0.0
        energy = None  # E(x), known after a line search
        potential = None  # (κ, the objective's revision) of that energy
        first = 0
        if isinstance(self.assembler, DenseAssembler) and getattr(objective,
                                                                   "compiles_newton", False):
            x, first, energy, potential, finished = self._compiled(objective, x, run)
            if finished is not None:
                return finished
        for it in range(first, self.settings.max_newton_iterations):  # the loop as written
            ev = objective.evaluate(x, 2)
            self._complete_last_row(run, ev.contacts)
            if (ev.kappa, objective.revision) != potential:
                energy = None  # the potential itself changed (κ, a pull)
                potential = (ev.kappa, objective.revision)
            if not np.isfinite(ev.gradient).all():
                raise NonFiniteError("gradient", objective.nonfinite_terms(x), it)
            system = self._system(objective, x, ev, run)
            ev = ev.without_hessian()  # its triplets go before the factorisation
            p, remaining = self._direction(objective, x, system, run, it)
            del system  # the matrix too goes before the line search
            free = self._dofs(objective.kinematic).free
            step_norm = np.abs(p[free]).max(initial=0.0)
            row = {"iteration": it, "step_inf_norm": step_norm, "tolerance": tol,
                   "gradient_norm": _norm(ev.gradient[free]),
                   "kappa": ev.kappa,
                   "residual_ratio": step_norm / tol if tol > 0 else np.nan}
            converged = (run.kinematic_complete and step_norm < tol
                         and objective.prescribed_complete() and objective.resolved(x, p))
            if converged and step_norm == 0.0:
                alpha = 0.0  # nothing left to do
                energy = ev.energy if energy is None else energy
            else:
                # a converged direction is still taken: it is nearly free (no solve) and,
                # at a step's first iteration, it is the whole motion of a slow body
                x_new, alpha, energy, failed = self._line_search(objective, x, p, remaining,
                                                                 energy, run, it)
                if failed:
                    # no step along p lowers E in floating point: x is a minimiser to
                    # machine precision (typical when tol sits near round-off), unless
                    # the step is far above the tolerance
                    run.line_search_failures += 1
                    run.min_alpha = 0.0
                    run.iterations = it + 1
                    run.rows.append({**row, "alpha": 0.0, "energy": energy})
                    return self._finish(objective, x, run,
                                        converged=step_norm < self.settings
                                        .roundoff_tolerance_factor * tol)
                x = x_new
                run.min_alpha = min(run.min_alpha, alpha)
            run.rows.append({**row, "alpha": alpha, "energy": energy})
            if converged:
                run.iterations = it + 1
                return self._finish(objective, x, run, converged=True)
            x = objective.follow_up(x, p, first=it == 0)  # may pull prescribed vertices
        run.iterations = self.settings.max_newton_iterations
        return self._finish(objective, x, run, converged=False, hit_cap=True)

    def _compiled(self, objective, x, run: _Progress):
        """The iterations run as one compiled call (``StepObjective.newton_iterations``)
        for as long as the objective allows: (x, the next iteration's number, E(x) or
        None with its (κ, revision), the result when the solve is finished there, else
        None: the loop of ``solve`` goes on from that iteration)."""
        settings = self.settings
        cap, first = settings.max_newton_iterations, 0
        energy = None
        while True:
            if run.rows and "contacts_total" not in run.rows[-1]:
                # the row before ends where these iterations start
                self._complete_last_row(run, objective.contacts(x))
            with self.timer("newton"):
                out = objective.newton_iterations(
                    x, first, cap, self._dofs(objective.kinematic), run.prescribed, energy,
                    (run.min_alpha, run.kinematic_complete),
                    (run.tol, settings.max_halvings, settings.kinematic_completion))
            self._add_rows(run, out.rows, out.ended_at)
            x, first = out.x, out.next
            energy = None if math.isnan(out.state[0]) else float(out.state[0])
            potential = (objective.stiffness.kappa, objective.revision)
            run.min_alpha, run.kinematic_complete = float(out.state[2]), bool(out.state[3])
            status = out.status
            if status == CONVERGED:
                run.iterations = first
                return x, first, energy, potential, self._finish(objective, x, run,
                                                                 converged=True)
            if status == LINE_SEARCH_FAILED:
                run.line_search_failures += 1
                run.min_alpha = 0.0
                run.iterations = first
                step_norm = run.rows[-1]["step_inf_norm"]
                return x, first, energy, potential, self._finish(
                    objective, x, run,
                    converged=step_norm < settings.roundoff_tolerance_factor * run.tol)
            if status == ITERATION_CAP:
                run.iterations = cap
                return x, first, energy, potential, self._finish(
                    objective, x, run, converged=False, hit_cap=True)
            if status == FOLLOW_UP:  # after the step's first iteration, or during a pull
                revision = objective.revision
                x = objective.follow_up(x, out.p, first=first == 1)
                if objective.revision != revision:
                    energy = None  # a pull began, changed or ended: another potential
                if objective.compiles_newton:
                    continue
            return x, first, energy, potential, None  # HAND_BACK

    def _add_rows(self, run: _Progress, rows: np.ndarray, ended_at: tuple) -> None:
        """The compiled iterations' rows as ``solve`` writes them; each row but the last
        is complete (its contacts are the next iterate's) and goes to the observer."""
        for values, contacts in zip(rows.tolist(), ended_at):
            row = dict(zip(_ROW_KEYS, values))
            row["iteration"] = int(row["iteration"])
            run.rows.append(row)
            if contacts is not None:
                self._complete_last_row(run, contacts)

    def _system(self, objective, x, ev, run: _Progress) -> "_System":
        """The Newton system over the free DOFs at x (assembled from ev's Hessian) and the
        prescribed part of the direction: p_k = target − x_k, the motion still remaining."""
        dofs = self._dofs(objective.kinematic)
        kin_dofs, free_dofs = dofs.prescribed, dofs.free
        free_index, n_free = dofs.index, dofs.n_free  # DOF -> free DOF number, −1 if kinematic
        p = np.zeros(x.size)
        p_kin = objective.target.reshape(-1)[kin_dofs] - x.reshape(-1)[kin_dofs]
        remaining = np.abs(p_kin).max(initial=0.0)
        if remaining <= self.settings.kinematic_completion * run.prescribed:
            p_kin[:] = 0.0  # done: stop pushing the last 0.1 %
            remaining = 0.0
        run.kinematic_complete = remaining == 0.0
        p[kin_dofs] = p_kin
        static, dynamic = ev.hessian
        with self.timer("assembly"):
            A, coupling = self.assembler.assemble(static, dynamic, free_index, n_free, p)
            rhs = -ev.gradient[free_dofs] - coupling
        return _System(A, rhs, coupling, p, remaining, free_dofs, n_free)

    def _direction(self, objective, x, system: "_System", run: _Progress, it: int):
        """The Newton direction p (3n,) at x, solving the system, and the prescribed
        motion still remaining."""
        p, free_dofs = system.p, system.free_dofs
        with self.timer("solve"):
            try:
                p[free_dofs] = (self.linear_solver.solve(system.A, system.rhs) if system.n_free
                                else 0.0)
            except SolverError:
                bad = objective.nonfinite_terms(x)
                if bad:  # a NaN in the matrix is the cause: name its term
                    raise NonFiniteError("Hessian", bad, it) from None
                raise
        if not np.isfinite(p).all():
            raise NonFiniteError("Newton direction", objective.nonfinite_terms(x), it)
        if system.remaining > 0.0 and system.n_free and np.abs(p[free_dofs]).max() < run.tol:
            # the free DOFs are converged, the prescribed motion is not: follow it with
            # the free DOFs' linear response alone, H_ff p_f = −H_fk p_k. The free part's
            # own residual (below tol) would otherwise move them far more than the small
            # rest of the motion does, and CCD would cut every step to a part of it.
            with self.timer("solve"):
                p[free_dofs] = self.linear_solver.solve_again(-system.coupling)
        return p, system.remaining

    def _line_search(self, objective, x, p, remaining, energy, run: _Progress, it: int):
        """(x_new, α, E(x_new), failed): the feasible step along p, halved until E
        decreases once the prescribed motion is complete."""
        fused = objective.line_search(x, p, remaining, energy, run.kinematic_complete,
                                      self.settings.max_halvings)
        if fused is not None:  # the same search in one call (a small scene)
            return self._checked(objective, x, p, fused, run, it)
        line = objective.max_step(x, p)
        alpha = line.max_alpha
        if not alpha >= 0.0:  # NaN: a bound (CCD, inversion) saw a non-finite input
            raise NonFiniteError("step bound", objective.nonfinite_terms(x, p), it)
        if run.kinematic_complete:
            alpha, failed, energy = self._backtrack(line, alpha, energy, it)
            if failed:
                return x, 0.0, energy, True
        if alpha == 1.0 and remaining > 0.0:
            x_new = line.end_on_targets()  # land exactly on the targets
        else:
            x_new = line.point(alpha)
        if not run.kinematic_complete:
            energy = line.energy_at(x_new)
            if not np.isfinite(energy):
                raise NonFiniteError("energy", objective.nonfinite_terms(x_new), it)
        return x_new, alpha, energy, False

    def _checked(self, objective, x, p, found, run: _Progress, it: int):
        """``_line_search``'s result from a fused search, with its checks."""
        if not found.alpha >= 0.0:
            raise NonFiniteError("step bound", objective.nonfinite_terms(x, p), it)
        if run.kinematic_complete:
            if not np.isfinite(found.e0):
                raise NonFiniteError("energy", objective.nonfinite_terms(x), it)
            if found.failed:
                return x, 0.0, found.e0, True
        elif not np.isfinite(found.energy):
            raise NonFiniteError("energy", objective.nonfinite_terms(found.x_new), it)
        return found.x_new, found.alpha, found.energy, False

    def _backtrack(self, line, alpha, e0, it: int):
        """Halve α until E(x + αp) < E(x). Returns (α, True if it gave up, E at the point
        kept: x + αp, or x itself when it gave up). Equal energies count as no progress:
        they only occur once E has reached round-off. It gives up after ``max_halvings``
        or once a step that did not lower E was within round-off of x
        (``LineSearch.below_roundoff``)."""
        if e0 is None:
            e0 = line.energy(0.0)
        if not np.isfinite(e0):
            raise NonFiniteError("energy", line.objective.nonfinite_terms(line.x), it)
        for _ in range(self.settings.max_halvings):
            e = line.energy(alpha)
            if e < e0:  # a finite e0 and e < e0: e is finite too
                return alpha, False, e
            if line.below_roundoff(alpha):
                # shorter steps only move x by less than its own round-off: give up (a
                # converged direction of 1e-16 in free flight took all max_halvings)
                break
            alpha *= 0.5
        return 0.0, True, e0

    def _complete_last_row(self, run: _Progress, contacts) -> None:
        """The previous iteration's row gets the contacts at the iterate it ended at."""
        if run.rows and "contacts_total" not in run.rows[-1]:
            run.rows[-1].update(contacts.as_row())
            if self.observer is not None:
                self.observer(run.rows[-1])

    def _finish(self, objective, x, run: _Progress, converged: bool,
                hit_cap: bool = False) -> NewtonResult:
        final = objective.evaluate(x, 0)
        if not np.isfinite(final.energy):
            raise NonFiniteError("energy", objective.nonfinite_terms(x), run.iterations)
        self._complete_last_row(run, final.contacts)
        return NewtonResult(x=x, final=final, iterations=run.iterations, converged=converged,
                            hit_iteration_cap=hit_cap, min_alpha=run.min_alpha,
                            kinematic_complete=run.kinematic_complete,
                            line_search_failures=run.line_search_failures,
                            rows=tuple(run.rows))
