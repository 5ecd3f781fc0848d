"""Simulation: chooses the terms a scene needs (and no more) and owns the step loop.

Each step: compute the kinematic targets and body forces of this step, predict x̃ with the
integrator, set κ, minimise the incremental potential with projected Newton, then update
velocities. ``step()`` returns a report (a dict per step plus one per Newton iteration)
that the run command writes to steps.csv and newton.csv.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from .contact.stiffness import balanced_kappa, kappa_bounds, should_double
from .errors import InfeasibleStartError, NonFiniteError, SolverError
from .model.kinematics import kinematic_targets, nbc_accelerations
from .potentials.body_force import BodyForce
from .potentials.damping import Damping
from .potentials.elasticity import Elasticity
from .potentials.friction import Friction
from .potentials.inertia import Inertia
from .potentials.mesh_contact import MeshContact
from .potentials.base import Triplets
from .potentials.plane_contact import PlaneContact
from .solver.incremental import IncrementalPotential, PhaseTimer
from .solver.integrator import fix_kinematic_velocities, kinetic_energy, make_integrator
from .solver.linear import make_solver
from .solver.newton import NewtonSolver

GRAVITY = np.array([0.0, -9.80665, 0.0])
FRICTION_TOL_FRACTION = 0.1  # Newton tolerance at most this fraction of ε_v·h
FRICTION_ITERATION_CAP = 20  # fricIterAmt <= 0: lagging updates per step at most
MAX_NEWTON_ITERATIONS = 5000  # reported in steps.csv and warned about when hit


@dataclass
class State:
    """Everything the next step needs: positions, velocities, accelerations, κ, the clock."""

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    step: int = 0
    kappa: float = 0.0
    dx_elastic: np.ndarray | None = None  # previous step's non-inertial displacement


class Simulation:
    def __init__(self, model, linear_solver: str | None = None):
        self.model = model
        scene = model.scene
        self.h = scene.dt
        self.integrator = make_integrator(scene.integrator, self.h, scene.newmark_beta,
                                          scene.newmark_gamma)
        self.timer = PhaseTimer()
        self.linear_solver = make_solver(linear_solver or scene.linear_solver)
        self.newton = NewtonSolver(self.linear_solver, MAX_NEWTON_ITERATIONS)
        n = len(model.mass)
        fw = self.integrator.force_weight

        self.inertia = Inertia(model.mass)
        self.body_force = BodyForce(model.mass)
        terms = [[1.0, self.inertia], [fw, self.body_force]]
        self.elasticity = None
        if len(model.tets):
            self.elasticity = Elasticity(model.tets, model.Dm_inv, model.rest_volumes,
                                         model.lame, scene.energy, n)
            terms.append([fw, self.elasticity])
        self.damping = None
        if model.needs_damping and self.elasticity is not None:
            self.damping = Damping(model.damping_stiffness, self.h, fw)
            terms.append([1.0, self.damping])
        self.plane_contact = self.mesh_contact = None
        if model.needs_plane_contact:
            self.plane_contact = PlaneContact(model.plane_contact_vertices, model.plane_origins,
                                              model.plane_normals, model.dhat)
        if model.needs_mesh_contact:
            self.mesh_contact = MeshContact(model, model.rest_positions, model.dhat)
        self.contacts = [c for c in (self.plane_contact, self.mesh_contact) if c is not None]
        terms.extend([1.0, c] for c in self.contacts)
        self.friction = None
        if model.needs_friction:  # only where some μ > 0
            self.friction = Friction(model.epsv * self.h)  # ε_v·h with the scene's own h
            terms.append([1.0, self.friction])
        self.potential = IncrementalPotential(terms, self.timer)

        tet_vertices = np.unique(model.tets) if len(model.tets) else np.arange(n)
        self.kappa_min, self.kappa_max = kappa_bounds(
            model.bbox_diagonal, model.dhat, float(model.mass[tet_vertices].mean()),
            scene.kappa_min_multiplier)
        kappa0 = model.kappa if model.kappa is not None else self.kappa_min
        # initial acceleration (Newmark needs aₙ): body forces on free vertices; the rest
        # shape is unstressed, and contact forces at t = 0 are left out
        a0 = np.zeros((n, 3))
        if scene.gravity:
            a0 += GRAVITY
        a0 += nbc_accelerations(model, 0.0)
        a0[model.kinematic_mask_at(0.0)] = 0.0
        self.state = State(model.initial_positions.copy(), model.initial_velocities.copy(),
                           a0, 0, kappa0)
        self._set_kappa(kappa0)
        self.on_iteration = None  # called with each Newton iteration's log row (-v)
        self._statistics_at = None  # (x, contact statistics at x) of the last iterate
        self.check_initial_state()

    def restore(self, checkpoint: dict):
        """Continue from a state saved by ``io.checkpoint`` (the model must be the same)."""
        n = len(self.model.mass)
        if checkpoint["x"].shape != (n, 3):
            raise ValueError(f"checkpoint has {len(checkpoint['x'])} vertices, the scene {n}")
        dx = checkpoint["dx_elastic"]
        self.state = State(checkpoint["x"].copy(), checkpoint["v"].copy(),
                           checkpoint["a"].copy(), checkpoint["step"], checkpoint["kappa"],
                           None if dx is None else dx.copy())
        self._set_kappa(checkpoint["kappa"])

    # -- contact helpers -------------------------------------------------------------
    def _set_kappa(self, kappa: float):
        self.state.kappa = kappa
        for c in self.contacts:
            c.kappa = kappa

    def contact_statistics(self, x) -> dict:
        """Active contacts by kind and the smallest distance (signed for planes). Newton
        asks twice per iterate (after one iteration, before the next) with the same
        array, so the last answer is kept for that array."""
        cached = self._statistics_at
        if cached is not None and cached[0] is x:
            return dict(cached[1])
        stats = self._contact_statistics(x)
        self._statistics_at = (x, stats)
        return dict(stats)

    def _contact_statistics(self, x) -> dict:
        stats = {"contacts_plane": 0, "contacts_point_triangle": 0, "contacts_edge_edge": 0,
                 "min_distance": np.inf}
        if self.plane_contact is not None:
            count, dmin = self.plane_contact.statistics(x)
            stats.update(contacts_plane=count, min_distance=min(stats["min_distance"], dmin))
        if self.mesh_contact is not None:
            n_pt, n_ee, dmin = self.mesh_contact.statistics(x)
            stats.update(contacts_point_triangle=n_pt, contacts_edge_edge=n_ee,
                         min_distance=min(stats["min_distance"], dmin))
        stats["contacts_total"] = (stats["contacts_plane"] + stats["contacts_point_triangle"]
                                   + stats["contacts_edge_edge"])
        return stats

    def check_initial_state(self):
        x = self.state.x
        if self.plane_contact is not None and not np.isfinite(self.plane_contact.value(x)):
            raise InfeasibleStartError(
                "initial state is infeasible: a surface vertex is on or below a plane "
                "(ground/halfSpace); move the shapes or the plane")
        if self.elasticity is not None and self.model.scene.energy == "NH":
            if not np.isfinite(self.elasticity.value(x)):
                raise InfeasibleStartError("initial state has an inverted tetrahedron")
        if self.mesh_contact is not None:
            self._check_initial_mesh_contact(x)

    def _check_initial_mesh_contact(self, x):
        """IPC starts from a strictly positive distance: intersecting or touching surfaces
        at t = 0 are an input error that names the two shapes."""
        from .contact.intersection import find_intersections
        from .kernels.contact_barrier import classify_and_distance

        mc, model = self.mesh_contact, self.model
        pt, ee, _ = mc.update(x)
        _, pt_d2, _, ee_d2 = classify_and_distance(x, pt, ee)
        touching = [(int(pt[i, 0]), int(pt[i, 1])) for i in np.flatnonzero(pt_d2 <= 0.0)[:1]]
        touching += [(int(ee[i, 0]), int(ee[i, 2])) for i in np.flatnonzero(ee_d2 <= 0.0)[:1]]
        body = mc.body if not mc.self_collision else None
        pairs = find_intersections(
            x, mc.edges, mc.triangles,
            None if body is None else body[mc.edges[:, 0]],
            None if body is None else body[mc.triangles[:, 0]])
        if len(pairs):
            kin = mc.kinematic
            moving = ~(kin[mc.edges[pairs[:, 0]]].all(axis=1)
                       & kin[mc.triangles[pairs[:, 1]]].all(axis=1))
            pairs = pairs[moving]
        crossing = [(int(mc.edges[e, 0]), int(mc.triangles[t, 0])) for e, t in pairs[:1]]
        for what, found in (("intersect or touch", crossing), ("touch", touching)):
            if found:
                a, b = (int(model.vertex_shape[v]) for v in found[0])
                names = model.shape_names
                who = (f"shape {a + 1} ({names[a]}) and shape {b + 1} ({names[b]})" if a != b
                       else f"shape {a + 1} ({names[a]}) and itself")
                raise InfeasibleStartError(
                    f"initial state: {who} {what}; IPC needs a positive distance between "
                    "all surfaces at the start")

    def _balance_kappa(self, x):
        """κ = clamp(−g_B·g_E/‖g_B‖², κ_min, κ_max) over free DOFs (contact terms at κ=1)."""
        free = np.repeat(~self._kinematic, 3)
        g_all = self.potential.gradient(x)
        g_b = np.zeros(x.size)
        for c in self.contacts:
            g_b += c.gradient(x) / c.kappa
        g_rest = g_all - self.state.kappa * g_b
        return balanced_kappa(g_b[free], g_rest[free], self.kappa_min, self.kappa_max)

    # -- the step ----------------------------------------------------------------------
    def step(self) -> dict:
        """One time step; a solver failure is reported with the number of this step."""
        number = self.state.step + 1
        try:
            return self._step()
        except NonFiniteError as exc:
            exc.step = number
            raise
        except SolverError as exc:
            raise SolverError(f"step {number}: {exc}") from None

    def _step(self) -> dict:
        model, scene, st, h = self.model, self.model.scene, self.state, self.h
        wall0 = time.perf_counter()
        self.timer.reset()
        t = st.step * h
        kinematic, target = kinematic_targets(model, st.x, t, h)
        self._kinematic = kinematic
        accel = np.zeros_like(st.x)
        if scene.gravity:
            accel += GRAVITY
        accel += nbc_accelerations(model, t)
        accel[kinematic] = 0.0
        self.body_force.acceleration = accel

        x_n = st.x
        x_tilde = self.integrator.predict(x_n, st.v, st.a)
        x_tilde[kinematic] = target[kinematic]
        self.inertia.x_tilde = x_tilde
        if self.damping is not None:
            self.damping.start_step(x_n, self.elasticity.hessian(x_n))

        if self.mesh_contact is not None:
            self.mesh_contact.start_step()
        x0 = self._warm_start(kinematic)
        tol = model.newton_tol(st.step)
        if self.friction is not None:
            # Newton must resolve the static-friction ramp |u| < ε_v·h: its stiffness μλ/ε
            # makes every step from rest tiny, so a tolerance above the ramp stops a body
            # that should start sliding (it then creeps at ε_v instead)
            tol = min(tol, FRICTION_TOL_FRACTION * self.friction.eps)
        newton_rows = []
        fixed_kappa = model.kappa is not None
        balanced = [fixed_kappa]
        prev_min_d_sq = [np.inf]
        eps_sq = (model.dtol) ** 2

        def before_iteration(x) -> bool:
            """Refresh contact data; adapt κ. True when κ changed."""
            if not self.contacts:
                return False
            with self.timer("contact_set"):
                if self.mesh_contact is not None:
                    self.mesh_contact.update(x)
                stats = self.contact_statistics(x)
            count, dmin = stats["contacts_total"], stats["min_distance"]
            if fixed_kappa:
                return False
            kappa = st.kappa
            if count and not balanced[0]:
                self._set_kappa(self._balance_kappa(x))
                balanced[0] = True
            d_sq = dmin * dmin
            if should_double(prev_min_d_sq[0], d_sq, eps_sq):
                self._set_kappa(min(self.kappa_max, 2.0 * st.kappa))
            prev_min_d_sq[0] = d_sq
            return st.kappa != kappa

        def after_iteration(x, info):
            # step: the number the step will have in steps.csv once it completes
            info.update(step=st.step + 1, kappa=st.kappa, **self.contact_statistics(x),
                        residual_ratio=info["step_inf_norm"] / tol if tol > 0 else np.nan)
            newton_rows.append(info)
            if self.on_iteration is not None:
                self.on_iteration(info)

        friction_iterations = 0
        if self.friction is not None:
            self._lag_friction(x_n, x_n)
            friction_iterations = 1
        x_new, result = self.newton.solve(self.potential, x0, kinematic, target, tol,
                                          before_iteration, after_iteration)
        if self.friction is not None:
            # fricIterAmt n: re-lag normal forces and tangents at the solution n − 1 more
            # times; ≤ 0: until the solution stops moving (at most FRICTION_ITERATION_CAP)
            wanted = scene.friction_iterations
            cap = wanted if wanted > 0 else FRICTION_ITERATION_CAP
            while friction_iterations < cap:
                self._lag_friction(x_new, x_n)
                friction_iterations += 1
                x_prev = x_new
                x_new, more = self.newton.solve(self.potential, x_new, kinematic, target, tol,
                                                before_iteration, after_iteration)
                result.iterations += more.iterations
                result.converged = more.converged
                result.hit_iteration_cap |= more.hit_iteration_cap
                result.min_alpha = min(result.min_alpha, more.min_alpha)
                if wanted <= 0 and np.abs(x_new - x_prev).max() < tol:
                    break
            else:
                if wanted <= 0:
                    warnings.warn(f"step {st.step}: friction lagging did not settle in "
                                  f"{FRICTION_ITERATION_CAP} updates", stacklevel=2)
        if not np.all(np.isfinite(x_new)):
            raise SolverError("positions became non-finite")

        v_new, a_new = self.integrator.update(x_new, x_n, st.v, st.a)
        v_new, a_new = fix_kinematic_velocities(v_new, a_new, kinematic, x_new, x_n, st.v, h)
        st.dx_elastic = x_new - (x_n + h * st.v + h * h * accel)
        st.x, st.v, st.a = x_new, v_new, a_new
        st.step += 1

        stats = self.contact_statistics(x_new)
        phases = self.timer.reset()
        row = {
            "step": st.step, "time": st.step * h, "dt": h,
            "newton_iterations": result.iterations, "converged": int(result.converged),
            "hit_iteration_cap": int(result.hit_iteration_cap),
            "line_search_min_alpha": result.min_alpha, "kappa": st.kappa,
            "dhat": model.dhat, **stats,
            "energy": self.potential.value(x_new),
            "kinetic_energy": kinetic_energy(model.mass, v_new),
            "elastic_energy": self.elasticity.value(x_new) if self.elasticity else 0.0,
            # empty cells in a scene without friction
            "friction_contacts": self.friction.count if self.friction is not None else None,
            "friction_iterations": friction_iterations if self.friction is not None else None,
            "friction_energy": self.friction.value(x_new) if self.friction is not None else None,
            "wall_s": time.perf_counter() - wall0,
            "wall_energy_s": phases.get("energy", 0.0),
            "wall_assembly_s": phases.get("assembly", 0.0),
            "wall_solve_s": phases.get("solve", 0.0),
            "wall_ccd_line_search_s": phases.get("ccd_line_search", 0.0),
            "wall_contact_set_s": phases.get("contact_set", 0.0),
        }
        return {"step": row, "newton": newton_rows, "result": result}

    def _lag_friction(self, x_lag, x_start):
        """Freeze normal forces and tangent bases of every active contact at x_lag."""
        model = self.model
        empty = np.zeros((0, 4), dtype=np.int64)
        pt, ee, eps = empty, empty, np.zeros(0)
        if self.mesh_contact is not None:
            with self.timer("contact_set"):
                pt, ee, eps = self.mesh_contact.update(x_lag)
        has_planes = self.plane_contact is not None
        self.friction.lag(
            x_lag, pt, ee, eps,
            model.plane_contact_vertices if has_planes else np.zeros(0, dtype=np.int64),
            model.plane_origins, model.plane_normals, model.plane_friction,
            model.scene.self_friction, self.state.kappa, model.dhat, x_start=x_start)

    def _warm_start(self, kinematic):
        """The initial guess of the step for free vertices (``warmStart`` 0..5), cut back
        by the feasibility bound so it never intersects or inverts."""
        st, h, scene = self.state, self.h, self.model.scene
        option = scene.warm_start
        if option == 0:
            return st.x.copy()
        guess = st.x + h * st.v
        if option >= 2:
            guess = guess + h * h * self.body_force.acceleration
        if option == 3 and st.dx_elastic is not None:
            guess = guess + st.dx_elastic
        elif option == 4 and st.dx_elastic is not None:
            guess = guess + 0.5 * st.dx_elastic
        elif option == 5:
            # one Jacobi step on the incremental potential from x_n
            g = self.potential.gradient(st.x)
            H = Triplets.concat(sum(self.potential.hessian(st.x), []))
            on_diagonal = H.rows == H.cols
            diag = np.bincount(H.rows[on_diagonal], weights=H.vals[on_diagonal],
                               minlength=st.x.size)
            guess = st.x - (g / np.where(diag > 0, diag, 1.0)).reshape(-1, 3)
        p = guess - st.x
        p[kinematic] = 0.0
        alpha = min(1.0, self.potential.max_step(st.x, p.reshape(-1)))
        return st.x + alpha * p
