"""One time step's minimisation problem as Newton sees it, and the values it passes on.

A ``StepProblem`` is frozen: the step's incremental potential, its ``StepContext``, the
barrier stiffness κ with its adaptive state, and the pull of prescribed vertices while
one acts. A ``Point`` is an iterate with what is known there: the collision set at x, or
the pairs the line search that reached x swept (the set at x is narrowed from them, no
new query), the energy and the terms' values that line search gave, and CCD's α (the
next sweep's hint). Newton passes both along; whatever changes comes back as a new
value (``msgspec.structs.replace``), and nothing is written into a problem:

* ``evaluate(point, 2)`` finds the collision set at x, counts the contacts, adapts κ
  (balanced at the step's first iterate with a contact, doubled while the closest
  contact keeps closing in below dTol) and gives E, ∇E and the PSD Hessian at x, with
  the problem at the new κ;
* ``line_search(point, p, ...)`` bounds the step (the terms' bounds, CCD) and backtracks
  on E in one kernel call (``kernels/terms/line_search.py``), giving the next point;
* ``resolved(x, p)`` is the terms' own stopping test (friction's static ramp);
* ``follow_up(point, p, first)`` after each Newton iteration: where the step's first
  iteration left the prescribed motion of bodies unfinished, their prescribed vertices
  are pulled towards their targets from then on (``boundary_pull.py``), as free DOFs;
  the pull tightens until they are there (``prescribed_complete``), or, in its tail,
  places them there;
* ``lag_friction(point)`` freezes friction's normal forces and bases at the point.

Sets at a step's start are in canonical order (by pair id), so that a run resumed from a
checkpoint, which queries its first set afresh, sums the barrier exactly as the
uninterrupted run did.
"""

from __future__ import annotations

import math

from msgspec import Struct
from msgspec.structs import force_setattr, replace
import numpy as np

from ..contact.ccd import DEFAULT_MAX_ITERATIONS, DEFAULT_MIN_GAP_FRACTION
from ..contact.collisions import (Collisions, build_collisions,
                                  narrowed_collisions)
from ..contact.friction_lag import lag_friction
from ..contact.setup import ContactCount, ContactSetup
from ..contact.stiffness import BarrierStiffness
from ..kernels.terms.line_search import feasible_step
from ..kernels.terms.line_search import line_search as line_search_kernel
from ..records import same_bits
from .base import StepContext
from .boundary_pull import BoundaryPull, PullSchedule
from .incremental import IncrementalPotential, TermValues, WeightedTerm
from .kernel_data import writeable


class Point(Struct, frozen=True, eq=False):
    """An iterate x and what is known there (module docstring)."""

    x: np.ndarray
    collisions: Collisions | None = None  # the collision set at x, once found
    swept: Collisions | None = None  # the pairs swept by the line search that reached x
    known: tuple | None = None  # (κ, E(x), the terms' values) the line search gave
    ccd_alpha: float = 1.0  # CCD's α at the step's last line search


class Evaluation(Struct, frozen=True, eq=False, dict=True):
    """The incremental potential at one point: its energy (summed when first read),
    gradient (order ≥ 1) and Hessian split by pattern (order 2) at the κ in force, and
    the contacts there."""

    point: Point
    values: TermValues
    kappa: float
    contacts: ContactCount
    gradient: np.ndarray | None = None
    hessian: tuple[list, list] | None = None

    @property
    def x(self) -> np.ndarray:
        return self.point.x

    @property
    def energy(self) -> float:
        return self.values.energy(self.kappa)

    def without_hessian(self) -> "Evaluation":
        """The same evaluation without its Hessian (whose contact entries, in heavy
        contact, are more memory than anything else Newton holds), once assembled."""
        return replace(self, hessian=None)


class LineStep(Struct, frozen=True, eq=False):
    """What a line search found: the point taken (x itself when it failed), α, E there,
    whether no step along p lowered E, and E(x)."""

    point: Point
    alpha: float
    energy: float
    failed: bool
    e0: float


class StepProblem(Struct, frozen=True, eq=False, dict=True):
    """A time step's minimisation problem (module docstring). ``pullable``: (mass (n,),
    mask (n,) of the vertices a pull may take of the prescribed ones: of bodies, with
    mass), None for no pull; ``small_step``: the pull schedule's ‖p‖∞; ``dense``:
    Hessians added into a dense matrix (a small system)."""

    potential: IncrementalPotential  # with the pull's term while one acts
    ctx: StepContext
    contact: ContactSetup
    stiffness: BarrierStiffness
    timer: object
    dense: bool = False
    pullable: tuple | None = None
    small_step: float = 0.0
    base: IncrementalPotential | None = None  # the potential without a pull
    pull: BoundaryPull | None = None
    schedule: PullSchedule | None = None
    data: tuple = ()  # the terms' kernel data in ctx (``kernel_data.TermData.data``)
    kinematic: np.ndarray | None = None  # the vertices Newton eliminates

    def __post_init__(self):
        if not self.data:
            force_setattr(self, "data", self.potential.kernel.data(self.ctx))
        if self.kinematic is None:
            force_setattr(self, "kinematic", self.ctx.kinematic)
        if self.base is None:
            force_setattr(self, "base", self.potential)

    # -- what Newton reads -----------------------------------------------------------------
    @property
    def target(self) -> np.ndarray:
        return self.ctx.target

    def prescribed_complete(self) -> bool:
        """No pull is under way (a pulled body's prescribed motion is done)."""
        return self.pull is None

    def start(self, x0: np.ndarray, kept: tuple | None = None,
              ccd_alpha: float = 1.0) -> Point:
        """The point Newton starts from; ``kept`` (x, its collision set), known already."""
        if kept is not None and same_bits(kept[0], x0):
            return Point(x0, collisions=kept[1], ccd_alpha=ccd_alpha)
        return Point(x0, ccd_alpha=ccd_alpha)

    def at(self, point: Point) -> Point:
        """The point with its collision set found (None without mesh contact): narrowed
        from the pairs its line search swept, else queried (in canonical order at the
        step's start)."""
        if point.collisions is not None or self.contact.mesh is None:
            return point
        with self.timer("contact_set"):
            if point.swept is not None:
                collisions = narrowed_collisions(point.swept, point.x, self.contact.dhat)
            else:
                collisions = build_collisions(self.contact.mesh, point.x, self.contact.dhat)
                if np.array_equal(point.x, self.ctx.x_start):
                    collisions = collisions.in_canonical_order()
        return replace(point, collisions=collisions, swept=None)

    def evaluate(self, point: Point, order: int = 2,
                 adapt: bool = True) -> tuple["StepProblem", Evaluation]:
        """(the problem at the κ adapted here, E (order 0), ∇E (1) and the Hessian (2) at
        the point with its collision set). At order 2 κ adapts first (unless ``adapt`` is
        False, as for a warm start)."""
        point = self.at(point)
        contacts = self.contacts(point)
        ctx = replace(self.ctx, collisions=point.collisions)
        with self.timer("energy"):
            values = self.potential.evaluate(point.x, ctx, self.data, order)
        problem = self
        if order == 2 and adapt:
            problem = self._adapted(values, contacts)
        kappa = problem.stiffness.kappa
        known = point.known
        if known is not None and known[0] == kappa:  # the line search's values at x
            values = replace(values, known=known[2])
        if order == 0:
            with self.timer("energy"):
                values.values  # read at once: what order 0 is asked for
        factors = gradient = hessian = None
        if order >= 1:
            factors, gradient = values.weighted(kappa)
        if order >= 2:
            hessian = self.potential.hessian(point.x, ctx, self.data, kappa, self.dense,
                                             factors)
        return problem, Evaluation(point, values, kappa, contacts, gradient, hessian)

    def _adapted(self, values: TermValues, contacts: ContactCount) -> "StepProblem":
        """The problem at κ adapted to this iterate (``BarrierStiffness.at_iterate``)."""
        if not self.contact.adaptive_kappa:
            return self
        g_barrier = g_rest = None
        if self.stiffness.needs_balance(contacts.total):
            free = np.repeat(~self.kinematic, 3)
            g_barrier, g_rest = (g[free] for g in values.split_gradient())
        stiffness = self.stiffness.at_iterate(contacts.total, contacts.min_distance,
                                              g_barrier, g_rest)
        return self if stiffness == self.stiffness else replace(self, stiffness=stiffness)

    def contacts(self, point: Point) -> ContactCount:
        """The contacts at a point whose collision set is found (``at``)."""
        with self.timer("contact_set"):
            return self.contact.count(point.x, point.collisions, self.ctx)

    def energy_known(self, point: Point) -> float | None:
        """E at the point where its line search gave it at the κ in force, else None."""
        known = point.known
        return known[1] if known is not None and known[0] == self.stiffness.kappa else None

    # -- the line search ---------------------------------------------------------------------
    def _mesh_arrays(self, with_mesh: bool = True) -> tuple:
        mesh = self.contact.mesh
        return _NO_MESH if mesh is None or not with_mesh else mesh.line_search_arrays

    def _sweep(self, hint: float) -> tuple:
        return (float(self.contact.dhat), float(hint), bool(self.contact.ccd),
                DEFAULT_MIN_GAP_FRACTION, DEFAULT_MAX_ITERATIONS)

    def _prescribed(self, remaining: float = 0.0) -> tuple:
        return writeable(self.kinematic, np.bool_), writeable(self.target), float(remaining)

    def max_step(self, x: np.ndarray, p: np.ndarray, hint: float = 1.0,
                 with_mesh: bool = True) -> tuple[float, float]:
        """(the largest feasible fraction of p (3n,) from x, mesh CCD's α): the bounds of
        the line search (``feasible_step``), without its energies."""
        with self.timer("ccd_line_search"):
            found = feasible_step(writeable(x), writeable(p.reshape(-1, 3)),
                                  self.potential.kernel.present, self.data,
                                  self._mesh_arrays(with_mesh), self.potential.kernel.bounds,
                                  self._prescribed(), self._sweep(hint))
        return float(found[0]), float(found[1])

    def line_search(self, point: Point, p: np.ndarray, remaining: float, complete: bool,
                    halvings: int) -> LineStep:
        """The feasible step along p (3n,) from the point, halved until E decreases once
        the prescribed motion is complete (``kernels/terms/line_search.py``)."""
        e0 = self.energy_known(point)
        kappa = float(self.stiffness.kappa)
        k = self.potential.kernel
        with self.timer("ccd_line_search"):
            out = line_search_kernel(
                writeable(point.x), writeable(p.reshape(-1, 3)), k.present, k.weighing, kappa,
                self.data, self._mesh_arrays(), k.bounds, self._prescribed(remaining),
                self._sweep(point.ccd_alpha),
                (math.nan if e0 is None else float(e0), bool(complete), int(halvings)))
        x_new, alpha, energy, failed, e0, ccd_alpha, by_kind = out[:7]
        ccd_alpha = float(ccd_alpha) if self.contact.mesh is not None else point.ccd_alpha
        by_kind = by_kind.tolist()
        values = None if math.isnan(by_kind[k.kinds[0]]) else tuple(by_kind[i]
                                                                     for i in k.kinds)
        if failed or not alpha >= 0.0:
            known = (kappa, float(e0), values) if values is not None else point.known
            return LineStep(replace(point, ccd_alpha=ccd_alpha, known=known), float(alpha),
                            float(energy), bool(failed), float(e0))
        swept = Collisions(out[7], out[8], out[9], None, out[10], out[11]) \
            if self.contact.mesh is not None else None
        known = (kappa, float(energy), values) if values is not None else None
        return LineStep(Point(x_new, swept=swept, known=known, ccd_alpha=ccd_alpha),
                        float(alpha), float(energy), False, float(e0))

    def resolved(self, x: np.ndarray, p: np.ndarray) -> bool:
        """The terms' own stopping tests (friction's static ramp) on the direction p."""
        return self.potential.resolved(x, p, self.ctx)

    def nonfinite_terms(self, x: np.ndarray, p: np.ndarray | None = None) -> list[str]:
        """The terms that are not finite at x (or whose bound along p is not), each
        evaluated with the collision set at x."""
        point = self.at(Point(x))
        ctx = replace(self.ctx, collisions=point.collisions)
        return self.potential.nonfinite_terms(x, ctx, p)

    # -- refreshes ---------------------------------------------------------------------------
    def follow_up(self, point: Point, p: np.ndarray,
                  first: bool) -> tuple["StepProblem", Point]:
        """Newton moved to the point along p: after the step's first iteration, pull the
        bodies' prescribed vertices that have not reached their targets; during a pull,
        tighten it or, once they are there, end it and keep them where they are; in its
        tail place them on their targets where that move alone is free. Returns the
        problem and the point Newton goes on with (a changed potential: E unknown)."""
        x = point.x
        if self.pull is None:
            if first and self.pullable is not None:
                problem = self._start_pull(x)
                if problem is not self:
                    return problem, replace(point, known=None)
            return self, point
        if self.schedule.in_tail(self.pull, x, p):
            placed = self._placed(point)
            if placed is not None:
                return placed
        pull, changed = self.schedule.next(self.pull, x, p)
        problem = self
        if pull is None:  # done: they stay at x for the rest of the step
            target = self.ctx.target.copy()
            target[self.pull.vertices] = x[self.pull.vertices]
            problem = replace(self, ctx=replace(self.ctx, target=target))
        if changed:
            return problem._with_pull(pull), replace(point, known=None)
        return problem, point

    def _placed(self, point: Point):
        """(the problem without the pull, the point with the pulled vertices moved alone
        onto their targets: their motion done) where that move is free of contact and
        inversion in full (``max_step``); None where it is not."""
        x = point.x
        vertices, target = self.pull.vertices, self.pull.target
        move = np.zeros_like(x)
        move[vertices] = target - x[vertices]
        if self.max_step(x, move.reshape(-1), point.ccd_alpha)[0] < 1.0:
            return None
        placed = x.copy()
        placed[vertices] = target
        return self._with_pull(None), Point(placed, ccd_alpha=point.ccd_alpha)

    def _start_pull(self, x: np.ndarray) -> "StepProblem":
        mass, takeable = self.pullable
        vertices = np.flatnonzero(self.ctx.kinematic & takeable)
        if not len(vertices):
            return self
        pull = BoundaryPull(vertices, mass[vertices], self.ctx.target[vertices],
                            self.ctx.x_start[vertices])
        completion = pull.completion(x)
        schedule = PullSchedule(completion, self.small_step)
        if completion >= schedule.done:
            return self
        return replace(self, schedule=schedule)._with_pull(pull)

    def _with_pull(self, pull: BoundaryPull | None) -> "StepProblem":
        """The problem with this pull acting (None: none): its term in the potential, its
        vertices free."""
        kinematic = self.ctx.kinematic
        potential = self.base
        if pull is not None:
            kinematic = kinematic.copy()
            kinematic[pull.vertices] = False
            potential = self.base.with_term(WeightedTerm(pull))
        return replace(self, pull=pull, potential=potential, kinematic=kinematic,
                       data=potential.kernel.data(self.ctx))

    def lag_friction(self, point: Point) -> tuple["StepProblem", Point]:
        """Friction lagged at the point with the κ in force; slips measured from the
        step's slip origin (xₙ; x̂ for BDF2)."""
        point = self.at(point)
        origin = self.ctx.x_start if self.ctx.slip_origin is None else self.ctx.slip_origin
        planes = self.contact.planes
        lag = lag_friction(point.x, origin, point.collisions,
                           planes.at(self.ctx) if planes is not None else None,
                           self.contact.self_friction,
                           self.stiffness.kappa * self.base.barrier_weight,
                           self.contact.dhat, self.contact.planar)
        ctx = replace(self.ctx, friction=lag)
        return replace(self, ctx=ctx, data=self.potential.kernel.data(ctx)), \
            replace(point, known=None)


_NO_MESH = (np.zeros((0, 1), dtype=np.int64), np.zeros((0, 2), dtype=np.int64),
            np.zeros((0, 3), dtype=np.int64), (np.zeros((0, 2), dtype=np.int64),) * 3, False,
            np.zeros((0, 3)), False, False)
