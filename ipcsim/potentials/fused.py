"""A small scene's terms evaluated together: one kernel call gives every term's value, one
every gradient, one adds every Hessian into the dense Newton matrix
(``kernels/terms/all_terms.py``), where the terms on their own make a call per term and per
quantity.

On a scene of tens of vertices those calls, not their arithmetic, were most of a Newton
iteration. ``FusedTerms.of(terms)`` packs the terms' own data once (None where a term
has no fused form, as the penalty baseline's); each evaluation adds what the step
context holds then (x̃, the collision set, the friction lag, the damping, the pull). The
fused kernels call the kernels the terms call, in the terms' order, so every value,
gradient and Newton matrix is the one the terms give, bit for bit. The potential
(``incremental.py``) uses them where the Newton system is dense (``linear.DenseSolver``),
the only place the dense Hessian fits.

``line_search`` does a Newton direction's line search in one call the same way
(``kernels/terms/line_search.py``): the terms' step bounds, the mesh's sweep and CCD,
and the backtracking on these energies, as ``StepObjective.max_step`` and
``NewtonSolver._line_search`` do it. ``newton_iterations`` goes further: Newton's
iterations themselves, evaluation, κ, the dense system, its Cholesky factor, the
stopping rule and the line search, in one call (``kernels/terms/newton_loop.py``).

Fusing pays where the fused kernels were compiled at install (``available``): left to
numba, compiling them at a scene's first run took 50 s on two tutorial cubes, more than
that whole first run took without them (36 s).
"""

from __future__ import annotations

import math
from functools import cached_property

from msgspec import Struct, field
import numpy as np

from ..kernels.terms import all_terms as kf
from ..kernels.contact.ccd import DEFAULT_MAX_ITERATIONS, DEFAULT_MIN_GAP_FRACTION
from ..kernels.terms import newton_loop as kn
from ..kernels.terms.line_search import line_search as fused_line_search
from ..contact.setup import ContactCount
from .base import StepContext, Triplets
from .body_force import BodyForce
from .boundary_pull import BoundaryPull
from .damping import Damping
from .elasticity import Elasticity
from .friction import Friction
from .inertia import Inertia
from .mesh_contact import MeshContact
from .plane_contact import CCD_KEEP_FRACTION, PlaneContact

_KIND = {Inertia: kf.INERTIA, BodyForce: kf.BODY_FORCE, Elasticity: kf.ELASTICITY,
         Damping: kf.DAMPING, PlaneContact: kf.PLANE_CONTACT, MeshContact: kf.MESH_CONTACT,
         Friction: kf.FRICTION, BoundaryPull: kf.PULL}


def available() -> bool:
    """Whether the fused kernels were compiled ahead of time for this process."""
    return all(k.compiled for k in (kf.term_values, kf.term_gradients,
                                     kf.add_term_hessians_dense, fused_line_search))


def newton_available() -> bool:
    """Whether the compiled Newton iterations were compiled ahead of time (numba would
    take minutes to compile them at a first run)."""
    return bool(kn.newton_iterations.compiled)


def _writeable(a, dtype=float) -> np.ndarray:
    """A C-contiguous, writeable array: the argument type the compiled kernels take."""
    a = np.ascontiguousarray(a, dtype=dtype)
    return a if a.flags.writeable else a.copy()


_NO_INDICES = np.zeros((0, 4), dtype=np.int64)
_NO_VECTOR = np.zeros(0)
_NO_POINTS = np.zeros((0, 3))
_ABSENT = {
    kf.INERTIA: (_NO_VECTOR, _NO_POINTS),
    kf.BODY_FORCE: (_NO_VECTOR, _NO_POINTS),
    kf.ELASTICITY: (_NO_INDICES, np.zeros((0, 3, 3)), _NO_VECTOR, np.zeros((0, 2)), 0, True),
    kf.DAMPING: (_NO_POINTS, _NO_VECTOR, 0.0, _NO_INDICES),
    kf.PLANE_CONTACT: (np.zeros(0, dtype=np.int64), _NO_POINTS, _NO_POINTS, 0.0),
    kf.MESH_CONTACT: (_NO_INDICES, _NO_INDICES, _NO_VECTOR, 0.0, False),
    kf.FRICTION: (_NO_POINTS, _NO_INDICES, np.zeros((0, 4)), np.zeros((0, 3, 2)), _NO_VECTOR,
                  1.0, True, np.zeros(1, dtype=np.int64)),
    kf.PULL: (np.zeros(0, dtype=np.int64), _NO_VECTOR, _NO_POINTS, 0.0, _NO_POINTS, False),
}


class FusedTerms(Struct, frozen=True, eq=False):
    """The terms of a potential, by kind: ``kinds[i]`` is the kind of the i-th term,
    ``present`` (N_KINDS,) which kinds there are, ``terms`` the term of each kind (None
    where absent) and ``fixed`` each kind's data tuple as far as it does not depend on
    the step context (``_data`` fills in the rest); ``weighing`` (kinds, weights, scaled
    by κ) as arrays in the terms' order and ``bounds`` (NH inversion bound, its volume
    ratio, the planes' CCD keep fraction) for the line search."""

    kinds: tuple[int, ...]
    present: np.ndarray
    terms: tuple
    fixed: tuple
    weighing: tuple
    bounds: tuple
    _last: dict = field(default_factory=dict)  # the last context's data

    @staticmethod
    def of(weighted_terms) -> "FusedTerms | None":
        """The fused form of these terms (``WeightedTerm``s), None if some term has none
        or a kind comes twice."""
        kinds = tuple(_KIND.get(type(t.term), -1) for t in weighted_terms)
        if -1 in kinds or len(set(kinds)) != len(kinds):
            return None
        present = np.zeros(kf.N_KINDS, dtype=np.bool_)
        present[list(kinds)] = True
        terms = [None] * kf.N_KINDS
        for kind, t in zip(kinds, weighted_terms):
            terms[kind] = t.term
        fixed = [_ABSENT[k] for k in range(kf.N_KINDS)]
        for k in (kf.INERTIA, kf.BODY_FORCE):
            if present[k]:  # x̃ and the acceleration come with the context
                fixed[k] = (_writeable(terms[k].mass), _NO_POINTS)
        if present[kf.ELASTICITY]:
            e = terms[kf.ELASTICITY]
            fixed[kf.ELASTICITY] = (e.tets, e.Dm_inv, e.volumes, e.lame, int(e.model), True)
        if present[kf.PLANE_CONTACT]:
            c = terms[kf.PLANE_CONTACT]
            fixed[kf.PLANE_CONTACT] = (_writeable(c.planes.vertices, np.int64),
                                       _writeable(c.planes.origins),
                                       _writeable(c.planes.normals), float(c.s_hat))
        if present[kf.PULL]:
            pull = terms[kf.PULL]
            lam = _NO_POINTS if pull.lam is None else _writeable(pull.lam)
            fixed[kf.PULL] = (_writeable(pull.vertices, np.int64), _writeable(pull.mass),
                              _writeable(pull.target), float(pull.rho), lam,
                              pull.lam is not None)
        weighing = (np.array(kinds, dtype=np.int64),
                    np.array([t.weight for t in weighted_terms], dtype=float),
                    np.array([t.barrier for t in weighted_terms], dtype=np.bool_))
        elasticity = terms[kf.ELASTICITY]
        nh = elasticity is not None and elasticity.energy == "NH"
        bounds = (nh, elasticity.min_volume_ratio if nh else 0.0, CCD_KEEP_FRACTION)
        return FusedTerms(kinds, present, tuple(terms), tuple(fixed), weighing, bounds)

    def _data(self, ctx: StepContext) -> tuple:
        """The eight kinds' data tuples in this context (kept for the next call with
        the same context: a Newton iteration asks three or four times)."""
        if self._last.get("ctx") is ctx:
            return self._last["data"]
        data = list(self.fixed)
        present = self.present
        if present[kf.INERTIA]:
            data[kf.INERTIA] = (data[kf.INERTIA][0], _writeable(ctx.x_tilde))
        if present[kf.BODY_FORCE]:
            data[kf.BODY_FORCE] = (data[kf.BODY_FORCE][0], _writeable(ctx.acceleration))
        if present[kf.DAMPING]:
            lag = ctx.damping
            D = lag.triplets
            data[kf.DAMPING] = (lag.x_start, D.vals, float(D.scale), D.elements)
        if present[kf.MESH_CONTACT]:
            c, term = ctx.collisions, self.terms[kf.MESH_CONTACT]
            data[kf.MESH_CONTACT] = (c.pt, c.ee, c.ee_eps_x, float(term.s_hat),
                                     bool(c.may_be_active(term.dhat)))
        if present[kf.FRICTION]:
            lag, term = ctx.friction, self.terms[kf.FRICTION]
            if lag is not None and lag.count:
                data[kf.FRICTION] = (lag.x_start, lag.verts, lag.coeffs, lag.basis,
                                     lag.weight, term.eps, bool(term.project), lag.offsets)
        self._last.update(ctx=ctx, data=tuple(data))
        return self._last["data"]

    def values(self, x, ctx: StepContext) -> tuple[float, ...]:
        """Each term's value at x, in the terms' order."""
        out = kf.term_values(_writeable(x), self.present, *self._data(ctx))
        return tuple(float(out[k]) for k in self.kinds)

    def gradients(self, x, ctx: StepContext) -> tuple[np.ndarray, ...]:
        """Each term's gradient (3n,) at x, in the terms' order."""
        out = kf.term_gradients(_writeable(x), self.present, *self._data(ctx))
        return tuple(out[k] for k in self.kinds)

    def hessian(self, x, ctx: StepContext, kappa: float) -> "FusedHessian":
        """Σ (the i-th term's weight, times κ for barriers)·(its Hessian) at x, to be
        added into a dense matrix."""
        kinds, weights, barrier = self.weighing
        by_kind = np.zeros(kf.N_KINDS)
        by_kind[kinds] = np.where(barrier, weights * kappa, weights)
        data = self._data(ctx)
        return FusedHessian(_writeable(x).copy(), self.present, by_kind,
                            data[:kf.BODY_FORCE] + data[kf.ELASTICITY:])


class FusedHessian(Struct, frozen=True, eq=False, dict=True):
    """The weighted sum of a potential's Hessians at x, as one part of a dense Newton
    matrix (``solver/assembly.DenseAssembler`` calls ``add_dense``); as triplets too
    (its nonzero entries), for whoever reads a Hessian so."""

    x: np.ndarray
    present: np.ndarray
    factors: np.ndarray  # (N_KINDS,) each kind's weight (κ included for barriers)
    data: tuple  # the kinds' data tuples but the body force's (no Hessian)
    scale: float = 1.0  # as a part of a Hessian: the factors hold every weight

    def add_dense(self, A, free_index, p, coupling) -> None:
        kf.add_term_hessians_dense(A, coupling, self.x, self.present, self.factors,
                                   free_index, p, *self.data)

    @cached_property
    def _triplets(self) -> Triplets:
        n = self.x.size
        H = np.zeros((n, n))
        self.add_dense(H, np.arange(n), np.zeros(n), np.zeros(n))
        rows, cols = np.nonzero(H)
        return Triplets(rows, cols, H[rows, cols])

    @property
    def size(self) -> int:
        return self._triplets.size

    @property
    def rows(self) -> np.ndarray:
        return self._triplets.rows

    @property
    def cols(self) -> np.ndarray:
        return self._triplets.cols

    @property
    def values(self) -> np.ndarray:
        return self._triplets.vals

    def tocsr(self, n_dofs: int):
        return self._triplets.tocsr(n_dofs)


_NO_MESH = (np.zeros((0, 1), dtype=np.int64), np.zeros((0, 2), dtype=np.int64),
            np.zeros((0, 3), dtype=np.int64), (np.zeros((0, 2), dtype=np.int64),) * 3, False,
            _NO_POINTS, False)


class LineSearchResult(Struct, frozen=True, eq=False):
    """What ``line_search`` found (``kernels/terms/line_search.py``)."""

    x_new: np.ndarray
    alpha: float
    energy: float  # E(x_new); E(x) when it failed
    failed: bool  # no step along p lowered E
    e0: float  # E(x)
    ccd_alpha: float  # mesh CCD's α (1 without mesh contact)
    values: tuple | None  # each term's value at the point returned (None: not evaluated)
    swept: tuple  # (pt, ee, ε_x, pt ids, ee ids): the pairs met along the step


def line_search(fused: FusedTerms, x, p3, kappa: float, ctx: StepContext, mesh,
                prescribed, search) -> LineSearchResult:
    """The feasible step along p3 and E's decrease along it in one kernel call:
    ``mesh`` a ``CollisionMesh`` or None, ``prescribed`` (kinematic (n,), targets,
    motion remaining), ``search`` (d̂, previous CCD α, E(x) or None, prescribed motion
    complete, halvings)."""
    dhat, previous_alpha, e0, complete, halvings = search
    kinematic, target, remaining = prescribed
    out = fused_line_search(
        _writeable(x), _writeable(p3), fused.present, *fused.weighing, float(kappa),
        fused._data(ctx), _NO_MESH if mesh is None else mesh.kernel_arrays + (True,),
        fused.bounds,
        (_writeable(kinematic, np.bool_), _writeable(target), float(remaining)),
        (float(dhat), float(previous_alpha), np.nan if e0 is None else float(e0),
         bool(complete), int(halvings), DEFAULT_MIN_GAP_FRACTION, DEFAULT_MAX_ITERATIONS))
    x_new, alpha, energy, failed, e0, ccd_alpha, by_kind = out[:7]
    values = None if np.isnan(by_kind[fused.kinds[0]]) else \
        tuple(float(by_kind[k]) for k in fused.kinds)
    return LineSearchResult(x_new, float(alpha), float(energy), bool(failed), float(e0),
                            float(ccd_alpha), values, tuple(out[7:]))


class NewtonIterations(Struct, frozen=True, eq=False):
    """What ``newton_iterations`` did: ``status`` (``kernels/terms/newton_loop.py``'s codes),
    the next iteration's number, x and the last direction p (3n,), κ's state, E(x) (NaN:
    not known at this κ), CCD's α, the smallest α, whether the prescribed motion was
    complete, the rows (k, 8) and the contacts each row ended at (k, 5; NaN where not
    known yet), the collision set and the contacts at x, the pairs swept to x and the
    terms' values by kind from the last line search with its κ (NaN: none)."""

    status: int
    next: int
    x: np.ndarray
    p: np.ndarray
    stiffness: tuple
    state: tuple
    rows: np.ndarray
    ended_at: tuple
    collisions: tuple
    contacts: ContactCount
    swept: tuple
    values: np.ndarray
    values_kappa: float


def newton_iterations(fused: FusedTerms, x, span: tuple[int, int], ctx: StepContext,
                      contact: tuple, newton: tuple) -> NewtonIterations:
    """Newton's iterations numbered from ``span`` = (first, cap) in one kernel call,
    until one Python must do or finish. ``contact``: (collision mesh or None, planes or
    None, the collision set at x: pt, ee, ε_x, ids, types and d²); ``newton``: (dofs,
    prescribed, stiffness, ramp, state, settings, pullable) as
    ``kernels/terms/newton_loop.py`` lists them."""
    mesh, planes, pairs = contact
    dofs, prescribed, stiffness, ramp, state, settings, pullable = newton
    prescribed_dofs, free, free_index, n_free = dofs
    kinematic, target, motion, pulling = prescribed
    int_pairs = {0, 1, 3, 4, 5, 7}  # pt, ee, their ids and types
    out = kn.newton_iterations(
        _writeable(x), int(span[0]), int(span[1]), fused.present, *fused.weighing,
        fused._data(ctx), _NO_MESH if mesh is None else mesh.kernel_arrays + (True,),
        fused.bounds,
        (_writeable(prescribed_dofs, np.bool_), _writeable(free, np.bool_),
         _writeable(free_index, np.int64), int(n_free)),
        (_writeable(kinematic, np.bool_), _writeable(target), float(motion), bool(pulling)),
        tuple(_writeable(a, np.int64 if i in int_pairs else float) for i, a in enumerate(pairs)),
        _NO_PLANES if planes is None else (planes.vertices, planes.origins, planes.normals,
                                           True),
        stiffness, (_writeable(ramp[0], np.int64), float(ramp[1]), float(ramp[2])), state,
        settings, (bool(pullable[0]), _writeable(pullable[1], np.bool_),
                   _writeable(pullable[2]), float(pullable[3])))
    contacts = out[7]
    ended_at = tuple(None if math.isnan(c[4]) else ContactCount(int(c[0]), int(c[1]),
                                                                int(c[2]), c[3])
                     for c in contacts.tolist())  # Python floats: math, not numpy
    plane, pt, ee, dmin = out[9]
    return NewtonIterations(int(out[0]), int(out[1]), *out[2:7], ended_at, out[8],
                            ContactCount(int(plane), int(pt), int(ee), float(dmin)), *out[10:])


_NO_PLANES = (np.zeros(0, dtype=np.int64), _NO_POINTS, _NO_POINTS, False)
