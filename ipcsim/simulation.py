"""Simulation: the terms a scene needs (and no more) and the step loop.

One step is values flowing through functions:

    state ─┬─ kinematic targets, body forces, x̃ ─► StepContext ─► StepProblem
           │                                     (+ friction lagged at xₙ)
           ├─ warm start (bounded by the problem's max_step) ─► x₀
           └─ Newton on the problem from x₀ (re-lagging friction fricIterAmt times)
                  ─► x ─► velocities ─► the next State, and a StepReport

``step()`` replaces ``state`` and returns a report (the steps.csv row and the newton.csv
rows) that the run command writes. The simulation writes nothing itself.
"""

from __future__ import annotations

import time
import warnings

from msgspec import Struct
from msgspec.structs import replace
import numpy as np

from .contact.collisions import build_collisions
from .contact.intersection import find_intersections, start_containment
from .contact.setup import ContactSetup
from .contact.stiffness import BarrierStiffness, kappa_bounds
from .errors import InfeasibleStartError, NonFiniteError, SolverError
from .compiler.twin import use_threads
from .contact.intersection import crossing_edges_2d, inverted_triangles
from .model.kinematics import kinematic_targets, nbc_accelerations, plane_origins
from .model.surface import index_set
from .potentials.base import StepContext, Triplets
from .potentials.plane_contact import CCD_KEEP_FRACTION
from .potentials.step_problem import StepProblem
from .potentials.terms import for_step, incremental_potential
from .solver.energy_growth import EnergyGrowth
from .solver.integrator import (StepHistory, error_norm, fix_kinematic_velocities,
                                kinetic_energy, make_integrator)
from .solver.linear import DENSE_HESSIAN_UP_TO, DENSE_UP_TO, make_solver
from .solver.newton import NewtonResult, NewtonSolver
from .solver.step_size import StepSizeControl, landing_step
from .solver.timing import PhaseTimer


def _read_only(a: np.ndarray) -> np.ndarray:
    view = a.view()
    view.flags.writeable = False
    return view


class State(Struct, frozen=True, eq=False):
    """Everything the next step needs: positions, velocities, accelerations (n, 3), the
    step counter (steps of the scene's dt completed), κ, the previous step's
    non-inertial displacement (kept for warm starts 3 and 4 only, which read it; None
    otherwise), the simulated time (the boundary conditions' clock: step·dt with fixed
    steps), BDF2's step before (None for BE and Newmark, and before the first step), and
    with adaptive steps the length the next one tries and the attempts rejected so far.
    Replaced, never modified, by a step.

    ``positions``, ``velocities`` (m, m/s; (n, 3) float64, vertex order of the model)
    and ``time`` (s) are the public, read-only face of it (``ipcsim.Simulation.state``).
    """

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    step: int = 0
    kappa: float = 0.0
    dx_elastic: np.ndarray | None = None
    time: float = 0.0  # s: step·dt with fixed steps, landed on exactly with adaptive ones
    history: StepHistory | None = None  # BDF2: (xₙ₋₁, vₙ₋₁, hₙ₋₁) of the step before
    h_next: float = 0.0  # s, adaptive steps: the next step's length to try (0: dt)
    rejected: int = 0  # adaptive steps: attempts rejected so far (error or a stalled solve)
    plane_origins: np.ndarray | None = None  # (p, 3) a 2D scene's moving lines, else None

    @property
    def positions(self) -> np.ndarray:
        """Vertex positions (n, 3) in m, a read-only view."""
        return _read_only(self.x)

    @property
    def velocities(self) -> np.ndarray:
        """Vertex velocities (n, 3) in m/s, a read-only view."""
        return _read_only(self.v)


class StepReport(Struct, frozen=True, eq=False):
    """What one step did: ``row`` is its steps.csv row (docs/output-format.md: step,
    time, newton_iterations, converged, contacts, energies, wall times ...), ``newton``
    its newton.csv rows, ``result`` the Newton solver's own result. With adaptive steps
    a step of the scene's dt is made of attempts: ``attempts`` holds the rows of those
    before the last (rejected ones and accepted shorter steps), ``row`` the last's."""

    row: dict  # the steps.csv row of the step
    newton: tuple[dict, ...]  # its newton.csv rows
    result: NewtonResult
    notes: tuple[str, ...] = ()  # what went wrong without stopping the run (baselines)
    attempts: tuple[dict, ...] = ()  # adaptive steps: the rows of the attempts before

    @property
    def rows(self) -> tuple[dict, ...]:
        """Every attempt's steps.csv row, in order."""
        return (*self.attempts, self.row)


class Simulation:
    """The time stepping of a built model: ``step()`` advances ``state`` by one time step
    h = ``model.dt`` (implicit Euler, Newmark or BDF2, as the scene says; with a time
    tolerance in steps of error-controlled length that land on t + dt) and returns the
    step's ``StepReport``. ``state`` is the current ``State``; a step replaces it.
    ``linear_solver`` names a solver in place of the scene's (None: the scene's)."""

    def __init__(self, model, linear_solver: str | None = None):
        self.model = model
        self.threads = use_threads(model.n_vertices)
        self.integrator = make_integrator(model.time)
        self.potential = incremental_potential(model, self.integrator)
        # the potential weighted for other step lengths (BDF2's steps after its first,
        # adaptive steps), by (w, h_v, damping weight): the last few
        self._potentials = {_weights(self.integrator): self.potential}
        self.control = step_size_control(model)  # None: fixed steps of dt
        self.contact = ContactSetup.from_model(model)
        self.timer = PhaseTimer()
        # the terms' Hessians go into a small system's dense matrix in one call (warm
        # start 5 reads their triplets, the baselines their sparse Hessian): "auto" factors
        # dense up to a larger size there
        self.one_call_hessian = (model.constraint_solver is None
                                 and model.solver.warm_start != 5)
        self.linear_solver = make_solver(
            linear_solver or model.solver.linear_solver, 3 * model.n_vertices,
            dense_up_to=DENSE_HESSIAN_UP_TO if self.one_call_hessian else DENSE_UP_TO)
        self.newton = NewtonSolver(model.solver, self.linear_solver, self.timer,
                                   observer=self._observe)
        self.on_iteration = None  # called with each newton.csv row as it completes (-v)
        self.stiffness = _initial_stiffness(model, self.contact)
        self.state = _initial_state(model, self.stiffness.kappa)
        # the vertices whose prescribed motion a step may pull (potentials/boundary_pull.py):
        # of bodies, with mass; and the pull schedule's small step: the original's
        # √(10⁻⁴ l² h²)
        mass = np.asarray(model.mass, dtype=float)
        self._pullable = (mass, np.ascontiguousarray(~model.obstacle_vertices & (mass > 0.0)))
        self._pull_step = 0.01 * model.bbox_diagonal * model.dt
        # (x, collision set at x) of the last step's last iterate: the next one starts there
        self._collisions_at = None
        # the SQP / QP baselines minimise the step with contact as constraints
        self.constrained = None
        if model.constraint_solver is not None:
            from .baselines.sqp import ConstrainedSolver

            self.constrained = ConstrainedSolver(model.constraint_solver, self.contact,
                                                 self.linear_solver, self.timer, model.energy)
        # "Pass" until a step ends intersecting ("Intersecting") or fails with a label
        self.outcome = "Pass"
        check_initial_state(self)
        self.energy_growth = EnergyGrowth.of(model, self.state.x, self.state.v,
                                             self._elastic_energy(self.state.x))

    @property
    def h(self) -> float:
        return self.model.dt

    def restore(self, checkpoint: dict):
        """Continue from a state saved by ``io.checkpoint`` (the model must be the same)."""
        n = self.model.n_vertices
        if checkpoint["x"].shape != (n, 3):
            raise ValueError(f"checkpoint has {len(checkpoint['x'])} vertices, the scene {n}")
        dx = checkpoint["dx_elastic"]
        history = checkpoint.get("history")
        if history is not None:
            history = StepHistory(history[0].copy(), history[1].copy(), history[2])
        self._collisions_at = None  # found afresh where the checkpoint starts
        origins = checkpoint.get("plane_origins")
        if origins is None and self.state.plane_origins is not None:
            origins = plane_origins(self.model, checkpoint["step"])  # on their schedule
        self.state = State(checkpoint["x"].copy(), checkpoint["v"].copy(),
                           checkpoint["a"].copy(), checkpoint["step"], checkpoint["kappa"],
                           None if dx is None else dx.copy(),
                           checkpoint.get("time", checkpoint["step"] * self.h), history,
                           checkpoint.get("h_next", 0.0), checkpoint.get("rejected", 0),
                           None if origins is None else origins.copy())

    def _elastic_energy(self, x) -> float:
        """Ψ(x): the elements' and the springs' (as steps.csv's elastic_energy)."""
        terms = (self.potential.term(name) for name in ("elasticity", "springs"))
        return sum(t.value(x) for t in terms if t is not None)

    def _check_energy(self, row: dict) -> None:
        """Stop a run whose energy grew by orders of magnitude with no work done on it
        (``solver/energy_growth.py``)."""
        if self.energy_growth is None:
            return
        st = self.state
        ratio = self.energy_growth.check(st.x, st.v, row["elastic_energy"])
        if ratio is not None:
            self.outcome = "Blow-up"
            raise SolverError(
                f"step {st.step}: the total energy grew {ratio:.3g}-fold with no work done "
                f"on the scene: the {self.integrator.name} integrator is unstable at h = "
                f"{row['dt']:.6g} s here; use BE or BDF2, or a smaller dt", label="Blow-up")

    def _observe(self, row: dict) -> None:
        if self.on_iteration is not None:
            # step: the number the step will have in steps.csv once it completes
            self.on_iteration({**row, "step": self.state.step + 1})

    # -- the step ----------------------------------------------------------------------------
    def step(self) -> StepReport:
        """One time step; a solver failure is reported with the number of this step."""
        number, before = self.state.step + 1, self.state
        try:
            report = self._step() if self.control is None else self._adaptive_step()
        except NonFiniteError as exc:
            exc.step = number
            self.outcome = "Blow-up" if self.constrained is not None else "failed"
            raise
        except SolverError as exc:
            self.outcome = exc.label or "failed"
            numbered = SolverError(f"step {number}: {exc}", label=exc.label)
            numbered.attempts, numbered.newton = exc.attempts, exc.newton
            raise numbered from None
        try:
            self._check_energy(report.row)
        except SolverError:
            self.state = before  # the run ends where its logs and frames do
            raise
        return report

    def _step(self) -> StepReport:
        """One step of length dt."""
        wall0 = time.perf_counter()
        self.timer.reset()
        before = self.state
        number = before.step + 1
        after, result, lags, integrator = self._attempt(before, self.h, number * self.h,
                                                        number)
        self.state = after
        self._collisions_at = _kept(result)  # the next step starts at x
        return self._report(result, lags, wall0, integrator, before, after, True)

    def _adaptive_step(self) -> StepReport:
        """One step of the scene's dt, [t, t + dt], made of steps whose length the local
        error controls (``solver/step_size.py``): each tries the length the last one
        proposed, shortened to land on t + dt in equal parts; a step whose error is too
        large, or whose Newton solve stalls (the iteration cap, a failed line search,
        non-finite values), is tried again shorter; the last one lands on t + dt exactly,
        so frames and the boundary conditions' windows keep the scene's clock."""
        control, number = self.control, self.state.step + 1
        end = number * self.h
        reports, retry = [], False
        while True:
            wall0 = time.perf_counter()
            self.timer.reset()
            before = self.state
            h = landing_step(before.time, before.h_next or self.h, end)
            lands = h == end - before.time  # in one part
            try:
                after, result, lags, integrator = self._attempt(
                    before, h, end if lands else before.time + h,
                    number if lands else before.step)
            except NonFiniteError as exc:
                stalled, after, error = exc, None, None
            else:
                stalled = None if result.converged else "Newton stalled"
                error = self._error(integrator, result.x, before, result.problem)
            if stalled is None:
                accepted, h_next = control.judge(h, error, integrator.order, retry)
            else:
                accepted, h_next = False, control.stalled(h)
            if after is None:  # non-finite values: a row of what is known
                reports.append(StepReport(
                    {"step": number, "time": before.time + h, "dt": h, "converged": 0,
                     "accepted": 0, "wall_s": time.perf_counter() - wall0}, (), None))
            else:
                reports.append(self._report(result, lags, wall0, integrator, before, after,
                                            accepted, number))
            if h_next < control.h_min:
                why = stalled or (f"the error estimate {error:.3g} stayed above the "
                                  f"{control.allowed(h):.3g} allowed, of l")
                fix = "raise the time tolerance" + (" or lower dt" if stalled else "")
                failure = stalled if isinstance(stalled, NonFiniteError) else SolverError(
                    f"at t = {before.time:.9g} s the adaptive step fell below "
                    f"{control.h_min:.3g} s ({why}); {fix}")
                tried = _one_report(reports)
                failure.attempts, failure.newton = tried.rows, tried.newton
                raise failure
            retry = not accepted
            if not accepted:
                self.state = replace(before, h_next=h_next, rejected=before.rejected + 1)
                continue
            self.state = replace(after, h_next=h_next)
            self._collisions_at = _kept(result)
            if lands:
                return _one_report(reports)

    def _attempt(self, before: State, h: float, t_end: float, number: int):
        """A step of length h from ``before``, ending at t_end with ``number`` steps of dt
        completed; nothing of the simulation changes. (the state after it, the Newton
        result, friction's lag updates, the step's integrator)."""
        integrator = self.integrator.at(h, before.history)
        problem, start = self.problem(before, integrator)
        start = self.warm_start(problem, start, before, h)
        budget = None
        if self.control is not None:
            budget = min(self.control.iteration_budget, self.model.solver.max_newton_iterations)
        result, lag_updates = self.minimise(problem, start, self.tolerance(before.step, h),
                                            budget)
        if not np.isfinite(result.x).all():
            raise SolverError("positions became non-finite")
        after = self.advance(before, result.x, result.problem, integrator, t_end, number)
        return after, result, lag_updates, integrator

    def _error(self, integrator, x_new, before: State, problem: StepProblem) -> float:
        """The step's estimated local position error (``integrator.local_error``) relative
        to the scene size, over the vertices it moved freely; None for Newmark."""
        if getattr(integrator, "local_error", None) is None:
            return None
        free = ~problem.ctx.kinematic & (np.asarray(self.model.mass) > 0.0)
        return error_norm(integrator.local_error(x_new, before.x, before.v),
                          self.model.bbox_diagonal, free)

    def _report(self, result: NewtonResult, lag_updates: int, wall0, integrator,
                before: State, after: State, accepted: bool,
                number: int | None = None) -> StepReport:
        """The report of a step (with adaptive steps, of an attempt) from ``before`` to
        ``after``; ``number``: the step of dt it belongs to (default after's)."""
        number = after.step if number is None else number
        rows = tuple({**r, "step": number} for r in result.rows)
        notes = ()
        if self.constrained is not None:
            crossing = self.constrained.intersections(result.x)
            if crossing is not None:
                notes = (f"the state intersects ({crossing})",)
                if self.outcome == "Pass":
                    self.outcome = "Intersecting"
        error = self._error(integrator, result.x, before, result.problem)
        row = self._step_row(result, lag_updates, wall0, after, integrator.h)
        row.update(step=number, error_estimate=error, accepted=int(accepted))
        return StepReport(row, rows, result, notes)

    def problem(self, state: State, integrator=None):
        """(the step's problem, its start at xₙ): kinematic targets and body forces at
        the state's time, the prediction x̃, damping and friction lagged at xₙ (their
        displacements measured from the integrator's lag origin); ``integrator``: of the
        step (default: a step of dt)."""
        if integrator is None:
            integrator = self.integrator.at(self.h, state.history)
        model, h, x = self.model, integrator.h, state.x
        potential = self._potential_for(integrator)
        kinematic, target = kinematic_targets(model, x, state.time, h)
        accel = np.zeros_like(x)
        accel += model.gravity
        accel += nbc_accelerations(model, state.time, x)
        accel[kinematic] = 0.0
        x_tilde = integrator.predict(x, state.v, state.a)
        x_tilde[kinematic] = target[kinematic]
        origin = integrator.lag_origin(x)
        damping = potential.term("damping")
        if damping is not None:
            damping = damping.lag(origin, potential.term("elasticity").hessian(x))
        ctx = StepContext(x_start=x, slip_origin=origin, x_tilde=x_tilde,
                          acceleration=accel, kinematic=kinematic, target=target,
                          dhat=model.dhat, damping=damping,
                          plane_origins=self.moved_lines(state, h))
        stiffness = replace(self.stiffness, kappa=state.kappa).new_step()
        problem = StepProblem(potential, ctx, self.contact, stiffness, self.timer,
                              dense=self.one_call_hessian
                              and getattr(self.linear_solver, "dense", False),
                              pullable=self._pullable,
                              small_step=0.01 * model.bbox_diagonal * h)
        start = problem.start(x, self._collisions_at)
        if potential.term("friction") is not None:
            problem, start = problem.lag_friction(start)
        return problem, start

    def _potential_for(self, integrator):
        """The incremental potential weighted for a step of ``integrator``."""
        key = _weights(integrator)
        potential = self._potentials.get(key)
        if potential is None:
            if len(self._potentials) >= 8:  # adaptive steps: each length once or so
                self._potentials = {_weights(self.integrator): self.potential}
            potential = self._potentials[key] = for_step(
                self.potential, self.model, integrator, self.integrator.force_weight)
        return potential

    def moved_lines(self, state: State, h: float) -> np.ndarray | None:
        """Where a 2D scene's moving lines are at the end of the step from ``state``
        (None: no line moves). A line advances by v h (h the step's) while (limit − o)·v > 0 at the
        step's start (the lecture's ceiling), but no further than leaves every vertex
        it approaches 10 % of its gap at xₙ: the step starts feasible, and a line held
        back by a body (a squashed stack) catches up at the steps that follow."""
        o = state.plane_origins
        if o is None:
            return None
        model, planes = self.model, self.contact.planes
        v = model.plane_velocities
        moving = np.einsum("ij,ij->i", model.plane_limits - o, v) > 0.0  # NaN limit: False
        moving |= np.isnan(model.plane_limits).any(axis=1) & np.any(v != 0.0, axis=1)
        move = np.where(moving[:, None], h * v, 0.0)
        normals = planes.normals
        gaps = np.einsum("pk,pvk->pv", normals, state.x[planes.vertices][None] - o[:, None])
        closing = np.einsum("pk,pk->p", normals, move)  # how much nearer each vertex gets
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(closing > 0.0, (1.0 - CCD_KEEP_FRACTION) * gaps.min(axis=1,
                            initial=np.inf) / closing, 1.0)
        return o + np.clip(room, 0.0, 1.0)[:, None] * move

    def tolerance(self, step: int, h: float | None = None) -> float:
        """Newton's ‖p‖∞ tolerance of step ``step`` (tol·l·h, h = dt; for a shorter step
        in proportion to its length; with adaptive steps at most a share of the error
        allowed, ``StepSizeControl.solve_tolerance``); friction's static ramp has a test
        of its own (``Friction.resolved``)."""
        tol = self.model.newton_tol(step)
        if h is None or (h == self.h and self.control is None):
            return tol
        tol *= h / self.h
        if self.control is not None:
            tol = min(tol, self.control.solve_tolerance(h) * self.model.bbox_diagonal)
        return tol

    def minimise(self, problem: StepProblem, start, tol,
                 max_iterations: int | None = None) -> tuple[NewtonResult, int]:
        """Newton from the start point (at most ``max_iterations`` iterations a solve where
        given); with friction, normal forces and tangents are
        re-lagged at the solution fricIterAmt − 1 more times (≤ 0: until the solution stops
        moving, at most the cap). Returns the result and the number of friction lags. The
        SQP / QP baselines minimise with their own solver (x₀ then only seeds their
        constraints)."""
        if self.constrained is not None:
            return self.constrained.minimise(problem, start.x, tol), 0
        result = self.newton.solve(problem, start, tol, max_iterations)
        if self.potential.term("friction") is None:
            return result, 0
        settings = self.model.solver
        wanted = settings.friction_iterations
        cap = wanted if wanted > 0 else settings.friction_iteration_cap
        lags = 1
        while lags < cap:
            problem, point = result.problem.lag_friction(result.point)
            lags += 1
            before = result.x
            result = result.then(self.newton.solve(problem, point, tol, max_iterations))
            if wanted <= 0 and np.abs(result.x - before).max() < tol:
                break
        else:
            if wanted <= 0:
                warnings.warn(f"step {self.state.step}: friction lagging did not settle in "
                              f"{cap} updates", stacklevel=2)
        return result, lags

    def advance(self, before: State, x_new, problem: StepProblem, integrator,
                t_end: float, number: int) -> State:
        """The state after the step of ``integrator`` from ``before`` that ends at x_new,
        at time t_end, with ``number`` steps of dt completed."""
        h, ctx = integrator.h, problem.ctx
        v_new, a_new = integrator.update(x_new, before.x, before.v, before.a)
        if not integrator.kinematic_rates:
            v_new, a_new = fix_kinematic_velocities(v_new, a_new, ctx.kinematic, x_new,
                                                    before.x, before.v, h)
        dx_elastic = (x_new - (before.x + h * before.v + h * h * ctx.acceleration)
                      if self.model.solver.warm_start in (3, 4) else None)
        history = integrator.after(before.x, before.v) if integrator.uses_history else None
        return State(x_new, v_new, a_new, number, problem.stiffness.kappa, dx_elastic, t_end,
                     history, before.h_next, before.rejected, ctx.plane_origins)

    def _step_row(self, result: NewtonResult, lag_updates: int, wall0, st: State,
                  h: float) -> dict:
        model, final = self.model, result.final
        phases = self.timer.reset()
        friction = result.problem.ctx.friction
        return {
            "step": st.step, "time": st.time, "dt": h,
            "newton_iterations": result.iterations, "converged": int(result.converged),
            "hit_iteration_cap": int(result.hit_iteration_cap),
            "line_search_min_alpha": result.min_alpha, "kappa": st.kappa,
            "dhat": model.dhat, **final.contacts.as_row(),
            "energy": final.energy,
            "kinetic_energy": kinetic_energy(model.mass, st.v),
            "elastic_energy": (final.values.value_of("elasticity") or 0.0)
            + (final.values.value_of("springs") or 0.0),
            # empty cells in a scene without friction
            "friction_contacts": friction.count if friction is not None else None,
            "friction_iterations": lag_updates if friction is not None else None,
            "friction_energy": final.values.value_of("friction") if friction is not None
            else None,
            "wall_s": time.perf_counter() - wall0,
            "wall_energy_s": phases.get("energy", 0.0),
            "wall_assembly_s": phases.get("assembly", 0.0),
            "wall_solve_s": phases.get("solve", 0.0),
            "wall_ccd_line_search_s": phases.get("ccd_line_search", 0.0),
            "wall_contact_set_s": phases.get("contact_set", 0.0),
        }

    def warm_start(self, problem: StepProblem, start, state: State | None = None,
                   h: float | None = None):
        """The point the step of length h (default dt) from ``state`` (default the
        current one) starts Newton from for free vertices (``warmStart`` 0..5), cut back
        by the feasibility bound so it never intersects or inverts."""
        st = self.state if state is None else state
        h = self.h if h is None else h
        option = self.model.solver.warm_start
        if option == 0:
            return replace(start, x=st.x.copy())
        guess = st.x + h * st.v
        if option >= 2:
            guess = guess + h * h * problem.ctx.acceleration
        if option == 3 and st.dx_elastic is not None:
            guess = guess + st.dx_elastic
        elif option == 4 and st.dx_elastic is not None:
            guess = guess + 0.5 * st.dx_elastic
        elif option == 5:
            # one Jacobi step on the incremental potential from x_n
            _, ev = problem.evaluate(start, 2, adapt=False)
            H = Triplets.concat(ev.hessian[0] + ev.hessian[1])
            on_diagonal = H.rows == H.cols
            diag = np.bincount(H.rows[on_diagonal], weights=H.vals[on_diagonal],
                               minlength=st.x.size)
            guess = st.x - (ev.gradient / np.where(diag > 0, diag, 1.0)).reshape(-1, 3)
        p = guess - st.x
        p[problem.kinematic] = 0.0
        alpha, ccd_alpha = problem.max_step(st.x, p.reshape(-1))
        return problem.start(st.x + min(1.0, alpha) * p, self._collisions_at, ccd_alpha)


def _weights(integrator) -> tuple[float, float, float]:
    """What the incremental potential of a step of ``integrator`` depends on."""
    return integrator.force_weight, integrator.velocity_step, integrator.damping_weight


def step_size_control(model) -> StepSizeControl | None:
    """The controller of a model with a time tolerance (None: fixed steps of dt)."""
    time_settings = model.time
    if time_settings.tolerance is None:
        return None
    duration = time_settings.duration or time_settings.n_steps * time_settings.dt
    return StepSizeControl(time_settings.tolerance / model.bbox_diagonal, duration,
                           time_settings.dt)


def _kept(result: NewtonResult):
    """(x, the collision set at x in canonical order) where the step ended: the next
    step's start."""
    point = result.point
    if point.collisions is None:
        return None
    return point.x, point.collisions.in_canonical_order()


def _one_report(reports: list[StepReport]) -> StepReport:
    """The attempts of one step of dt as one report: the last's, the others' rows before
    it, every attempt's Newton rows."""
    return replace(reports[-1], attempts=tuple(r.row for r in reports[:-1]),
                   newton=tuple(row for r in reports for row in r.newton))


# -- the start of a run ---------------------------------------------------------------------

def _initial_stiffness(model, contact: ContactSetup) -> BarrierStiffness:
    n = model.n_vertices
    elements = model.tets if model.dimension == 3 else model.tri_elements
    tet_vertices = index_set(elements) if len(elements) else np.arange(n)
    kappa_min, kappa_max = kappa_bounds(model.bbox_diagonal, model.dhat,
                                        float(model.mass[tet_vertices].mean()),
                                        model.kappa_min_multiplier)
    # with adaptive steps κ is κ_max throughout unless the scene fixes it: a κ adapted
    # per step would change the contact model with h, and the error estimate would
    # compare different models (solver/step_size.py)
    adaptive_steps = model.time.tolerance is not None
    if model.kappa is not None:
        kappa = model.kappa
    else:
        kappa = kappa_max if adaptive_steps else kappa_min
    return BarrierStiffness(kappa, kappa_min, kappa_max, model.dtol ** 2,
                            adaptive=contact.adaptive_kappa and not adaptive_steps)


def _initial_state(model, kappa: float) -> State:
    """Initial positions and velocities; Newmark needs a₀: body forces on free vertices
    (the rest shape is unstressed, and contact forces at t = 0 are left out)."""
    a0 = np.zeros((model.n_vertices, 3))
    a0 += model.gravity
    a0 += nbc_accelerations(model, 0.0)
    a0[model.kinematic_mask_at(0.0)] = 0.0
    origins = plane_origins(model, 0)  # a 2D scene's moving lines: part of the state
    return State(model.initial_positions.copy(), model.initial_velocities.copy(), a0, 0, kappa,
                 plane_origins=None if origins is None else origins.copy())


def check_initial_state(sim: Simulation) -> None:
    """IPC starts from a feasible state: every surface vertex strictly above every plane,
    no inverted tet (neo-Hookean), and a positive distance between all surfaces."""
    x, contact = sim.state.x, sim.contact
    planes = contact.planes
    if planes is not None:
        origins = plane_origins(sim.model, 0)
        planes = planes if origins is None else planes.moved(origins)
    if planes is not None and not planes.count(x, contact.dhat)[1] > 0.0:
        raise InfeasibleStartError(
            "initial state is infeasible: a surface vertex is on or below a plane "
            "(ground/halfSpace); move the shapes or the plane")
    if sim.model.dimension == 2:
        _check_initial_planar(sim.model, contact, x)
        return
    elasticity = sim.potential.term("elasticity")
    if elasticity is not None and sim.model.energy == "NH":
        if not np.isfinite(elasticity.value(x)):
            raise InfeasibleStartError("initial state has an inverted tetrahedron")
    if contact.mesh is not None:
        _check_initial_mesh_contact(sim.model, contact, x)
    inside = start_containment(sim.model, contact.mesh, x)
    if inside is not None:
        inner, outer = (_shape(sim.model, v) for v in inside)
        where = (f"{inner} has a part inside another of its parts (its tets overlap)"
                 if inner == outer else f"{inner} lies inside {outer}")
        raise InfeasibleStartError(f"initial state: {where}, though no surfaces cross: a "
                                   "solid inside a solid intersects it; IPC needs an "
                                   "intersection-free start")


def _check_initial_mesh_contact(model, contact: ContactSetup, x) -> None:
    """Intersecting or touching surfaces at t = 0 are an input error naming the shapes."""
    mesh = contact.mesh
    collisions = build_collisions(mesh, x, contact.dhat)
    d = collisions.distances
    pt, ee = collisions.pt, collisions.ee
    touching = [(int(pt[i, 0]), int(pt[i, 1])) for i in np.flatnonzero(d.pt_d2 <= 0.0)[:1]]
    touching += [(int(ee[i, 0]), int(ee[i, 2])) for i in np.flatnonzero(d.ee_d2 <= 0.0)[:1]]
    edge_body = triangle_body = None
    if not mesh.self_collision:
        edge_body, triangle_body = mesh.body[mesh.edges[:, 0]], mesh.body[mesh.triangles[:, 0]]
    pairs = find_intersections(x, mesh.edges, mesh.triangles, edge_body, triangle_body)
    if len(pairs):
        kin = mesh.kinematic
        moving = ~(kin[mesh.edges[pairs[:, 0]]].all(axis=1)
                   & kin[mesh.triangles[pairs[:, 1]]].all(axis=1))
        pairs = pairs[moving]
    crossing = [(int(mesh.edges[e, 0]), int(mesh.triangles[t, 0])) for e, t in pairs[:1]]
    for what, found in (("intersect or touch", crossing), ("touch", touching)):
        if found:
            raise InfeasibleStartError(
                f"initial state: {_shapes(model, *found[0])} {what}; IPC needs a positive "
                "distance between all surfaces at the start")


def _check_initial_planar(model, contact: ContactSetup, x) -> None:
    """A 2D scene's start: no inverted or flat triangle, no two boundary edges that
    cross or touch (of moving shapes), no point–edge pair at distance 0."""
    bad = inverted_triangles(x, model.tri_elements)
    if len(bad):
        shape = _shape(model, int(model.tri_elements[bad[0], 0]))
        raise InfeasibleStartError(f"initial state: {shape} has an inverted or flat "
                                   "triangle")
    mesh = contact.mesh
    if mesh is None:
        return
    edges = mesh.edges
    pairs = crossing_edges_2d(x, edges, None if mesh.self_collision else mesh.body)
    if len(pairs):
        kin = mesh.kinematic
        pairs = pairs[~(kin[edges[pairs[:, 0]]].all(axis=1) & kin[edges[pairs[:, 1]]].all(axis=1))]
    found = [(int(edges[a, 0]), int(edges[b, 0])) for a, b in pairs[:1]]
    what = "cross or touch"
    if not found:
        collisions = build_collisions(mesh, x, contact.dhat)
        touching = np.flatnonzero(collisions.distances.pt_d2 <= 0.0)[:1]
        found = [(int(collisions.pt[i, 0]), int(collisions.pt[i, 1])) for i in touching]
        what = "touch"
    if found:
        raise InfeasibleStartError(
            f"initial state: the boundaries of {_shapes(model, *found[0])} {what}; IPC needs "
            "a positive distance between all boundaries at the start")


def _shape(model, v: int) -> str:
    """The shape of vertex v as a message names it."""
    a = int(model.vertex_shape[v])
    return f"shape {a + 1} ({model.shape_names[a]})"


def _shapes(model, u: int, v: int) -> str:
    """The shapes of vertices u and v as a message names them."""
    a, b = _shape(model, u), _shape(model, v)
    return f"{a} and {b}" if a != b else f"{a} and itself"
