"""One time step's incremental potential as Newton sees it: ``evaluate(x, order)`` and
``max_step(x, p)``.

The objective owns the step's refreshes, so that Newton knows nothing of contact:

* ``evaluate(x, 2)`` at a Newton iterate finds the collision set at x, counts the contacts,
  adapts κ (balanced at the step's first iterate with a contact, doubled while the closest
  contact keeps closing in below dTol) and returns E, ∇E and the PSD Hessian at x;
* ``max_step(x, p)`` bounds the step (the terms' own bounds, mesh CCD) and returns a
  ``LineSearch`` whose energies use every pair that comes within d̂ along [x, x + αp];
* ``resolved(x, p)`` is the terms' own stopping test (friction's static ramp);
* ``lag_friction(x)`` freezes friction's normal forces and bases at x;
* ``follow_up(x, p, first)`` after each Newton iteration: where the step's first
  iteration left the prescribed motion of bodies unfinished, their prescribed vertices
  are pulled towards their targets from then on (``boundary_pull.py``), as free DOFs;
  the pull tightens until they are there (``prescribed_complete``), or, in its tail,
  places them there; it returns the x Newton goes on from.

Its state is explicit: the step's ``StepContext`` (replaced, never written to), the
``BarrierStiffness``, the pull, the α of the last CCD sweep
(``contact.ccd.line_search_bound`` starts from it) and ``revision``, which counts the
changes of the potential itself (a pull started, tightened or ended: energies from
before are not comparable). The collision set of the last evaluated x is kept for a
repeat call at equal positions (compared by value), and handed to the next step, which
starts where this one ended (``kept_collisions``): a step's first set is then narrowed
from its last line search instead of queried again. Sets at a step's start are in
canonical order (by pair id), so that a run resumed from a checkpoint, which queries
its first set afresh, sums the barrier exactly as the uninterrupted run did.
"""

from __future__ import annotations

import math
from functools import cached_property

from msgspec import Struct
from msgspec.structs import replace
import numpy as np

from ..contact.ccd import line_search_bound, unbounded_step
from ..contact.collisions import (Collisions, PairDistances, build_collisions,
                                  narrowed_collisions)
from ..contact.friction_lag import FrictionLag, lag_friction
from ..contact.setup import ContactCount, ContactSetup
from ..contact.stiffness import BarrierStiffness
from ..kernels.contact.ccd import DEFAULT_MAX_ITERATIONS, DEFAULT_MIN_GAP_FRACTION
from ..records import same_bits
from .base import StepContext, Triplets
from .boundary_pull import BoundaryPull, PullSchedule
from .fused import LineSearchResult, NewtonIterations, newton_available
from .fused import line_search as fused_line_search
from .fused import newton_iterations as fused_newton_iterations
from .incremental import IncrementalPotential, TermValues, WeightedTerm


class Evaluation(Struct, frozen=True, eq=False, dict=True):
    """The incremental potential at one x: energy, gradient (order ≥ 1) and Hessian
    triplets split by pattern (order 2) at the κ in force, and the contacts at x. The
    energy is summed when first read (``TermValues.values``)."""

    x: np.ndarray
    values: TermValues
    kappa: float
    contacts: ContactCount
    gradient: np.ndarray | None = None
    hessian: tuple[list[Triplets], list[Triplets]] | None = None

    @cached_property
    def energy(self) -> float:
        return self.values.energy(self.kappa)

    def without_hessian(self) -> "Evaluation":
        """The same evaluation without its Hessian (whose contact entries, in heavy
        contact, are more memory than anything else Newton holds), once assembled."""
        return replace(self, hessian=None)


class LineSearch(Struct, frozen=True, eq=False):
    """The feasible part of a Newton direction: α ≤ ``max_alpha`` keeps x + αp free of
    intersections and inversions; ``energy(α)`` uses the pairs met along it."""

    objective: "StepObjective"
    x: np.ndarray
    p3: np.ndarray  # (n, 3)
    max_alpha: float
    ctx: StepContext

    def energy(self, alpha: float) -> float:
        return self.energy_at(self.x + alpha * self.p3)

    def below_roundoff(self, alpha: float) -> bool:
        """Whether the step αp is within round-off of the positions: ‖αp‖∞ ≤ ε·max|x|."""
        return alpha * float(np.abs(self.p3).max(initial=0.0)) \
            <= np.finfo(float).eps * float(np.abs(self.x).max(initial=0.0))

    def point(self, alpha: float) -> np.ndarray:
        """x + αp, remembered by the objective as a point of this segment: its collision
        set is then narrowed from the pairs swept here instead of queried again."""
        y = self.x + alpha * self.p3
        self.objective.took(y, self.ctx.collisions)
        return y

    def end_on_targets(self) -> np.ndarray:
        """x + p with the prescribed vertices exactly on their targets (the end of a
        direction that completes their motion, within round-off of x + p), remembered
        as a point of this segment: the sweep kept the pairs of points that close
        (``StepObjective.max_step``)."""
        obj = self.objective
        y = self.x + self.p3
        y[obj.kinematic] = obj.target[obj.kinematic]
        obj.took(y, self.ctx.collisions)
        return y

    def energy_at(self, y: np.ndarray) -> float:
        """E at a point of the segment (e.g. one whose kinematic rows were snapped onto
        their targets)."""
        obj = self.objective
        with obj.timer("energy"):
            return obj.potential.value(y, self.ctx, obj.stiffness.kappa)


def snap_reach(x: np.ndarray, target: np.ndarray) -> float:
    """How far (per coordinate) ``LineSearch.end_on_targets`` may put a prescribed vertex
    from x + p: with p = fl(t − x), |fl(x + p) − t| ≤ 2u(|t| + |x|) + O(u²), u = ε/2;
    four times that, over the largest coordinates (0 without prescribed vertices)."""
    if not x.size:
        return 0.0
    scale = max(np.abs(x).max(), np.abs(target).max())
    return 4.0 * np.finfo(float).eps * float(scale)


class StepObjective:
    def __init__(self, potential: IncrementalPotential, ctx: StepContext,
                 contact: ContactSetup, stiffness: BarrierStiffness, timer,
                 pullable: tuple[np.ndarray, np.ndarray] | None = None,
                 small_step: float = 0.0,
                 collisions_at: tuple[np.ndarray, Collisions] | None = None):
        """``pullable``: (mass (n,), mask (n,) of the vertices a pull may take of the
        prescribed ones: of bodies, with mass), None for no pull; ``small_step``: the pull
        schedule's ‖p‖∞ (``PullSchedule``); ``collisions_at``: (x, the collision set at x
        in canonical order) known already: the last step's ``kept_collisions``."""
        self.potential = self._base_potential = potential
        self.ctx = ctx
        self.contact = contact
        self.stiffness = stiffness
        self.timer = timer
        self.pullable = pullable
        self.small_step = small_step
        self.pull: BoundaryPull | None = None
        self._kinematic = ctx.kinematic  # changes with the pull only (_set_pull)
        self._schedule: PullSchedule | None = None
        self.revision = 0
        self.last_ccd_alpha = 1.0  # CCD's α at this step's previous line search
        self._collisions_at = collisions_at
        # (y, swept set): the last point Newton took along a line search, and its pairs
        self._on_segment: tuple[np.ndarray, Collisions | None] | None = None
        # (y, κ, revision, the terms' values at y) from the last fused line search
        self._values_at: tuple | None = None
        # (x, the contacts at x) where the compiled iterations ended
        self._contacts_at: tuple[np.ndarray, ContactCount] | None = None

    # -- what Newton reads -----------------------------------------------------------------
    @property
    def kinematic(self) -> np.ndarray:
        """The vertices Newton eliminates: the prescribed ones, but those being pulled."""
        return self._kinematic

    @property
    def target(self) -> np.ndarray:
        return self.ctx.target

    def prescribed_complete(self) -> bool:
        """No pull is under way (a pulled body's prescribed motion is done)."""
        return self.pull is None

    def evaluate(self, x: np.ndarray, order: int = 2, adapt: bool = True) -> Evaluation:
        """E (order 0), ∇E (1) and the Hessian (2) at x with the collision set at x. At
        order 2 κ adapts first (unless ``adapt`` is False, as for a warm start)."""
        with self.timer("contact_set"):
            collisions = self.collisions(x)
            contacts = self._count(x, collisions)
        self.ctx = replace(self.ctx, collisions=collisions)
        with self.timer("energy"):
            values = self.potential.evaluate(x, self.ctx, order)
            if order == 0:
                known = self._values_at
                if known is not None and known[0] is x and known[1:3] == (
                        self.stiffness.kappa, self.revision):
                    values = replace(values, known=known[3])  # the line search's
                values.values  # read at once: what order 0 is asked for
        if order == 2 and adapt:
            self._adapt_stiffness(values, contacts)
        kappa = self.stiffness.kappa
        hessian = values.hessian(kappa) if order >= 2 else None
        if values.hessians is not None:  # held by ``hessian`` alone from here
            # a copy starts without the values read above (a cached property): order 0
            # has no Hessians to drop, and copying there summed the energy again
            values = replace(values, hessians=None)
        return Evaluation(x, values, kappa, contacts,
                          values.gradient(kappa) if order >= 1 else None, hessian)

    def _adapt_stiffness(self, values: TermValues, contacts: ContactCount) -> None:
        if not self.contact.adaptive_kappa:
            return
        g_barrier = g_rest = None
        if self.stiffness.needs_balance(contacts.total):
            free = np.repeat(~self.kinematic, 3)
            g_barrier, g_rest = (g[free] for g in values.split_gradient())
        self.stiffness = self.stiffness.at_iterate(contacts.total, contacts.min_distance,
                                                   g_barrier, g_rest)

    def max_step(self, x: np.ndarray, p: np.ndarray) -> LineSearch:
        """The feasible fraction of the direction p (3n,) from x."""
        p3 = p.reshape(-1, 3)
        with self.timer("ccd_line_search"):
            alpha = min(1.0, self.potential.max_step(x, p, self.ctx))
            ctx = self.ctx
            mesh = self.contact.mesh
            if mesh is not None:
                reach = self._snap_reach(x)
                if self.contact.ccd:
                    bound = line_search_bound(mesh, x, p3, self.contact.dhat,
                                              self.last_ccd_alpha, reach)
                else:
                    bound = unbounded_step(mesh, x, p3, self.contact.dhat, reach)
                self.last_ccd_alpha = bound.alpha
                alpha = min(alpha, bound.alpha)
                ctx = replace(ctx, collisions=bound.collisions)
        return LineSearch(self, x, p3, alpha, ctx)

    def line_search(self, x: np.ndarray, p: np.ndarray, remaining: float, energy,
                    complete: bool, halvings: int) -> LineSearchResult | None:
        """``max_step`` and Newton's search along it in one kernel call where the
        potential is fused (``fused.line_search``: the same steps and energies, bit for
        bit), None elsewhere. The pairs swept go with the point taken, as ``point``'s."""
        fused = self.potential.fused
        if fused is None:
            return None
        mesh = self.contact.mesh
        with self.timer("ccd_line_search"):
            found = fused_line_search(
                fused, x, p.reshape(-1, 3), self.stiffness.kappa, self.ctx, mesh,
                (self.kinematic, self.target, remaining),
                (self.contact.dhat, self.last_ccd_alpha, energy, complete, halvings))
        if mesh is not None:
            self.last_ccd_alpha = found.ccd_alpha
            if not found.failed:
                self.took(found.x_new, Collisions(*found.swept[:3], None, *found.swept[3:]))
        if found.values is not None:  # what evaluate(·, 0) at that point would sum again
            self._values_at = (x if found.failed else found.x_new, self.stiffness.kappa,
                               self.revision, found.values)
        return found

    def contacts(self, x: np.ndarray) -> ContactCount:
        """The contacts at x (``evaluate``'s count)."""
        with self.timer("contact_set"):
            return self._count(x, self.collisions(x))

    def _count(self, x: np.ndarray, collisions: Collisions | None) -> ContactCount:
        """The contacts at x with its collision set: those the compiled iterations
        counted where they ended, else counted here."""
        known = self._contacts_at
        if known is not None and known[0] is x:
            return known[1]
        return self.contact.count(x, collisions)

    @property
    def compiles_newton(self) -> bool:
        """Whether Newton may run its iterations as one compiled call here
        (``newton_iterations``): a fused potential (a pull under way is one more fused
        term; the call then ends after each iteration, for ``follow_up``)."""
        return self.potential.fused is not None and newton_available()

    @cached_property
    def _pull_may_take(self) -> tuple:
        """(whether a pull may start, the vertices it may take, xₙ, the completion that
        ends a pull): what the compiled iterations test after the first one."""
        if self.pullable is None:
            return (False, np.zeros(len(self.ctx.x_start), np.bool_), self.ctx.x_start,
                    PullSchedule.done)
        return (True, self.pullable[1], np.ascontiguousarray(self.ctx.x_start, dtype=float),
                PullSchedule.done)

    def newton_iterations(self, x: np.ndarray, first: int, cap: int, dofs, motion: float,
                          energy, progress: tuple, settings: tuple) -> NewtonIterations:
        """Newton's iterations from x, numbered from ``first``, in one compiled call
        (``fused.newton_iterations``), adopting what they leave as ``evaluate`` and
        ``line_search`` would: κ, CCD's α, the collision set and the contacts at the x
        they end at, and the terms' values there. ``dofs`` (prescribed, free, free
        numbers, count), ``motion`` the prescribed motion at the solve's start,
        ``energy`` E(x) at the κ in force or None, ``progress`` (smallest α so far,
        prescribed motion complete), ``settings`` (tol, halvings, kinematic
        completion)."""
        with self.timer("contact_set"):
            collisions = self.collisions(x)
        self.ctx = replace(self.ctx, collisions=collisions)
        c = Collisions.empty() if collisions is None else collisions
        d = c.distances or PairDistances(np.zeros(0, np.int64), np.zeros(0),
                                         np.zeros(0, np.int64), np.zeros(0))
        pairs = (c.pt, c.ee, c.ee_eps_x, c.pt_id, c.ee_id, d.pt_type, d.pt_d2, d.ee_type,
                 d.ee_d2)
        st = self.stiffness
        adaptive = self.contact.adaptive_kappa and st.adaptive
        friction = self.potential.term("friction")
        ramp = ((friction.body if friction.body is not None
                 else np.zeros(len(x), np.int64), float(friction.eps),
                 float(friction.ramp_resolution)) if friction is not None
                else (np.zeros(0, np.int64), 1.0, 0.0))
        out = fused_newton_iterations(
            self.potential.fused, x, (first, cap), self.ctx,
            (self.contact.mesh, self.contact.planes, pairs),
            ((dofs.prescribed, dofs.free, dofs.index, dofs.n_free),
             (self.kinematic, self.target, float(motion), self.pull is not None),
             (float(st.kappa), float(st.kappa_min), float(st.kappa_max), float(st.eps_sq),
              bool(adaptive), bool(st.balanced), float(st.min_distance_sq)),
             ramp, (np.nan if energy is None else float(energy), float(self.last_ccd_alpha),
                    float(progress[0]), bool(progress[1])),
             (float(settings[0]), int(settings[1]), float(settings[2]),
              float(self.contact.dhat), DEFAULT_MIN_GAP_FRACTION, DEFAULT_MAX_ITERATIONS),
             self._pull_may_take))
        kappa, balanced, min_distance_sq = out.stiffness
        self.stiffness = replace(st, kappa=float(kappa), balanced=bool(balanced),
                                 min_distance_sq=float(min_distance_sq))
        if self.contact.mesh is not None:
            self.last_ccd_alpha = float(out.state[1])
            pt, ee, eps_x, pt_id, ee_id, *distances = out.collisions
            at_x = Collisions(pt, ee, eps_x, PairDistances(*distances), pt_id, ee_id)
            self._collisions_at = (out.x.copy(), at_x)
            self.ctx = replace(self.ctx, collisions=at_x)
        self._contacts_at = (out.x, out.contacts)
        kinds, values = self.potential.fused.kinds, out.values.tolist()
        if not math.isnan(values[kinds[0]]):
            self._values_at = (out.x, float(out.values_kappa), self.revision,
                               tuple(values[k] for k in kinds))
        return out

    def _snap_reach(self, x: np.ndarray) -> float:
        k = self.kinematic
        return snap_reach(x[k], self.target[k])

    def resolved(self, x: np.ndarray, p: np.ndarray) -> bool:
        """The terms' own stopping tests (friction's static ramp) on the direction p."""
        return self.potential.resolved(x, p, self.ctx)

    def nonfinite_terms(self, x: np.ndarray, p: np.ndarray | None = None) -> list[str]:
        """The terms that are not finite at x (or whose bound along p is not), each
        evaluated with the collision set at x."""
        ctx = replace(self.ctx, collisions=self.collisions(x))
        return self.potential.nonfinite_terms(x, ctx, p)

    # -- refreshes ---------------------------------------------------------------------------
    def follow_up(self, x: np.ndarray, p: np.ndarray, first: bool) -> np.ndarray:
        """Newton moved to x along p: after the step's first iteration, pull the bodies'
        prescribed vertices that have not reached their targets; during a pull, tighten
        it or, once they are there, end it and keep them where they are. Returns the x
        Newton goes on from: x, or x with the pulled vertices placed on their targets."""
        if self.pull is None:
            if first and self.pullable is not None:
                self._start_pull(x)
            return x
        if self._schedule.in_tail(self.pull, x, p):
            placed = self._place_pulled(x)
            if placed is not None:
                return placed
        pull, changed = self._schedule.next(self.pull, x, p)
        if pull is None:  # done: they stay at x for the rest of the step
            target = self.ctx.target.copy()
            target[self.pull.vertices] = x[self.pull.vertices]
            self.ctx = replace(self.ctx, target=target)
        if changed:
            self._set_pull(pull)
        return x

    def _place_pulled(self, x: np.ndarray) -> np.ndarray | None:
        """x with the pulled vertices moved alone onto their targets, the pull ended (they
        are prescribed again, their motion done), where that move is free of contact and
        inversion in full (``max_step``); None where it is not."""
        vertices, target = self.pull.vertices, self.pull.target
        move = np.zeros_like(x)
        move[vertices] = target - x[vertices]
        hint = self.last_ccd_alpha  # a probe: the line searches keep their own CCD hint
        free = self.max_step(x, move).max_alpha >= 1.0
        self.last_ccd_alpha = hint
        if not free:
            return None
        placed = x.copy()
        placed[vertices] = target
        self._set_pull(None)
        return placed

    def _start_pull(self, x: np.ndarray) -> None:
        mass, takeable = self.pullable
        vertices = np.flatnonzero(self.ctx.kinematic & takeable)
        if not len(vertices):
            return
        pull = BoundaryPull(vertices, mass[vertices], self.ctx.target[vertices],
                            self.ctx.x_start[vertices])
        completion = pull.completion(x)
        schedule = PullSchedule(completion, self.small_step)
        if completion < schedule.done:
            self._schedule = schedule
            self._set_pull(pull)

    def _set_pull(self, pull: BoundaryPull | None) -> None:
        self.pull = pull
        self._kinematic = self.ctx.kinematic
        if pull is not None:
            self._kinematic = self._kinematic.copy()
            self._kinematic[pull.vertices] = False
        self.potential = (self._base_potential if pull is None
                          else self._base_potential.with_term(WeightedTerm(pull)))
        self.revision += 1

    @property
    def kept_collisions(self) -> tuple[np.ndarray, Collisions] | None:
        """(x, the collision set at x) of the last x evaluated, in canonical order: the
        start of the next step."""
        kept = self._collisions_at
        if kept is None or kept[1] is None:
            return None
        return kept[0], kept[1].in_canonical_order()

    def took(self, y: np.ndarray, swept: Collisions | None) -> None:
        """Newton takes y, a point of a line search that swept the pairs ``swept``."""
        self._on_segment = (y, swept)

    def collisions(self, x: np.ndarray) -> Collisions | None:
        """The collision set at x (kept for the next call at equal positions)."""
        if self.contact.mesh is None:
            return None
        kept = self._collisions_at
        if kept is not None and same_bits(kept[0], x):
            return kept[1]
        on = self._on_segment
        if on is not None and on[0] is x and on[1] is not None:
            collisions = narrowed_collisions(on[1], x, self.contact.dhat)
            self._on_segment = None  # its one use: the swept pairs go before the next sweep
        else:
            collisions = build_collisions(self.contact.mesh, x, self.contact.dhat)
            if np.array_equal(x, self.ctx.x_start):  # as a step's start is handed over
                collisions = collisions.in_canonical_order()
        self._collisions_at = (x.copy(), collisions)
        return collisions

    def lag_friction(self, x_lag: np.ndarray) -> FrictionLag:
        """Friction lagged at x_lag with the κ in force; displacements from xₙ."""
        with self.timer("contact_set"):
            collisions = self.collisions(x_lag)
        lag = lag_friction(x_lag, self.ctx.x_start, collisions, self.contact.planes,
                           self.contact.self_friction, self.stiffness.kappa, self.contact.dhat)
        self.ctx = replace(self.ctx, friction=lag)
        return lag
