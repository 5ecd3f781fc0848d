"""The terms of a potential as the all-terms kernels take them (``kernels/terms/``).

``TermData.of(terms)`` packs what the terms hold themselves (masses, tets, planes, ...)
once per potential; ``data(ctx)`` adds what a step's context holds (x̃, the body
forces, the damping and friction lags) and ``pairs(collisions)`` the mesh's pairs at a
point. A kind the potential lacks gets empty arrays of the kernels' types, so every
call has the types compiled ahead of time. ``DenseHessian`` is the weighted sum of the
terms' Hessians at x, added into a small system's dense Newton matrix in one call.
"""

from __future__ import annotations

from functools import cached_property

from msgspec import Struct
import numpy as np

from ..kernels.terms import all_terms as kt
from .base import StepContext, Triplets
from .plane_contact import CCD_KEEP_FRACTION


def writeable(a, dtype=float) -> np.ndarray:
    """A C-contiguous, writeable array: the argument type the compiled kernels take."""
    a = np.ascontiguousarray(a, dtype=dtype)
    return a if a.flags.writeable else a.copy()


_NO_INDICES = np.zeros((0, 4), dtype=np.int64)
_NO_VECTOR = np.zeros(0)
_NO_POINTS = np.zeros((0, 3))
_NO_VERTICES = np.zeros(0, dtype=np.int64)
_ABSENT = (
    (_NO_VECTOR, _NO_POINTS),  # INERTIA
    (_NO_VECTOR, _NO_POINTS),  # BODY_FORCE
    (_NO_INDICES, np.zeros((0, 3, 3)), _NO_VECTOR, np.zeros((0, 2)), 0, True),  # ELASTICITY
    (_NO_POINTS, _NO_VECTOR, 0.0, _NO_INDICES),  # DAMPING
    (_NO_VERTICES, _NO_POINTS, _NO_POINTS, 0.0),  # PLANE_CONTACT
    (0.0,),  # MESH_CONTACT
    (_NO_POINTS, _NO_INDICES, np.zeros((0, 4)), np.zeros((0, 3, 2)), _NO_VECTOR, 1.0, True,
     np.zeros(1, dtype=np.int64)),  # FRICTION
    (_NO_VERTICES, _NO_VECTOR, _NO_POINTS, 0.0, _NO_POINTS, False),  # PULL
    (_NO_VERTICES, _NO_POINTS, _NO_POINTS, 0.0, 0.0),  # PLANE_PENALTY
    (0.0, 0.0),  # MESH_PENALTY
    (np.zeros((0, 3), dtype=np.int64), np.zeros((0, 2, 2)), _NO_VECTOR, np.zeros((0, 2)), 0,
     True),  # TRIANGLES
    (np.zeros((0, 2), dtype=np.int64), _NO_VECTOR, _NO_VECTOR, True),  # SPRINGS
    (0.0, 0, _NO_VECTOR),  # POINT_EDGE
    (_NO_VERTICES, _NO_POINTS, _NO_POINTS, 0.0, _NO_VECTOR),  # LINE_LECTURE
)
assert len(_ABSENT) == kt.N_KINDS
NO_TERMS = _ABSENT  # the data of a potential without terms (bounds of the mesh alone)
NO_PAIRS = (_NO_INDICES, _NO_INDICES, _NO_VECTOR, False)


def _fixed(kind: int, term) -> tuple:
    """A kind's data as far as the term itself holds it."""
    if kind in (kt.INERTIA, kt.BODY_FORCE):  # x̃ and the acceleration come with the context
        return writeable(term.mass), _NO_POINTS
    if kind == kt.ELASTICITY:
        return term.tets, term.Dm_inv, term.volumes, term.lame, int(term.model), True
    if kind == kt.TRIANGLES:
        return term.triangles, term.Dm_inv, term.areas, term.lame, int(term.model), True
    if kind == kt.SPRINGS:
        return term.springs, term.rest_length_sq, term.stiffness, True
    if kind == kt.POINT_EDGE:
        return float(term.s_hat), int(term.form), term.point_weight
    if kind == kt.LINE_LECTURE:
        planes = term.planes
        return (writeable(planes.vertices, np.int64), writeable(planes.origins),
                writeable(planes.normals), float(term.dhat), term.vertex_weight)
    if kind in (kt.PLANE_CONTACT, kt.PLANE_PENALTY):
        planes = term.planes
        arrays = (writeable(planes.vertices, np.int64), writeable(planes.origins),
                  writeable(planes.normals))
        if kind == kt.PLANE_CONTACT:
            return (*arrays, float(term.s_hat))
        return (*arrays, float(term.dhat), float(term.stiffness))
    if kind == kt.MESH_CONTACT:
        return (float(term.s_hat),)
    if kind == kt.MESH_PENALTY:
        return float(term.dhat), float(term.stiffness)
    if kind == kt.PULL:
        lam = _NO_POINTS if term.lam is None else writeable(term.lam)
        return (writeable(term.vertices, np.int64), writeable(term.mass),
                writeable(term.target), float(term.rho), lam, term.lam is not None)
    return _ABSENT[kind]  # damping and friction: all from the context


class TermData(Struct, frozen=True, eq=False):
    """The terms of a potential, by kind: ``kinds[i]`` is the kind of the i-th term,
    ``present`` (N_KINDS,) which kinds there are, ``terms`` the term of each kind (None
    where absent) and ``fixed`` each kind's data as far as it does not depend on the
    step's context; ``weighing`` (kinds, weights, scaled by κ) in the terms' order and
    ``bounds`` (NH inversion bound, its volume ratio, the planes' CCD keep fraction) for
    the line search."""

    kinds: tuple[int, ...]
    present: np.ndarray
    terms: tuple
    fixed: tuple
    weighing: tuple
    bounds: tuple

    @staticmethod
    def of(weighted_terms) -> "TermData":
        kinds = tuple(t.term.kind for t in weighted_terms)
        if len(set(kinds)) != len(kinds):
            raise ValueError("a potential has at most one term of each kind")
        present = np.zeros(kt.N_KINDS, dtype=np.bool_)
        present[list(kinds)] = True
        terms = [None] * kt.N_KINDS
        for kind, t in zip(kinds, weighted_terms):
            terms[kind] = t.term
        fixed = tuple(_ABSENT[k] if terms[k] is None else _fixed(k, terms[k])
                      for k in range(kt.N_KINDS))
        weighing = (np.array(kinds, dtype=np.int64),
                    np.array([t.weight for t in weighted_terms], dtype=float),
                    np.array([t.barrier for t in weighted_terms], dtype=np.bool_))
        elasticity = terms[kt.ELASTICITY]
        if elasticity is None:  # a 2D scene's triangles
            elasticity = terms[kt.TRIANGLES]
        nh = elasticity is not None and elasticity.energy == "NH"
        ratio = getattr(elasticity, "min_volume_ratio", getattr(elasticity, "min_area_ratio",
                                                                0.0))
        bounds = (nh, ratio if nh else 0.0, CCD_KEEP_FRACTION)
        return TermData(kinds, present, tuple(terms), fixed, weighing, bounds)

    def data(self, ctx: StepContext) -> tuple:
        """The kinds' data tuples in the step context ``ctx``."""
        data = list(self.fixed)
        present = self.present
        if present[kt.INERTIA]:
            data[kt.INERTIA] = (data[kt.INERTIA][0], writeable(ctx.x_tilde))
        if present[kt.BODY_FORCE]:
            data[kt.BODY_FORCE] = (data[kt.BODY_FORCE][0], writeable(ctx.acceleration))
        if present[kt.DAMPING]:
            lag = ctx.damping
            D = lag.triplets
            data[kt.DAMPING] = (lag.x_start, D.vals, float(D.scale), D.elements)
        if ctx.plane_origins is not None:  # a 2D scene's moving lines
            origins = writeable(ctx.plane_origins)
            for kind in (kt.PLANE_CONTACT, kt.LINE_LECTURE):
                if present[kind]:
                    t = data[kind]
                    data[kind] = (t[0], origins, *t[2:])
        if present[kt.FRICTION]:
            lag, term = ctx.friction, self.terms[kt.FRICTION]
            if lag is not None and lag.count:
                data[kt.FRICTION] = (lag.x_start, lag.verts, lag.coeffs, lag.basis,
                                     lag.weight, term.eps, bool(term.project), lag.offsets)
        return tuple(data)

    def pairs(self, collisions, dhat: float) -> tuple:
        """The mesh's pairs for the mesh kinds: (pt, ee, ε_x, whether any may be within
        d̂); none without a collision set."""
        if collisions is None:
            return NO_PAIRS
        return (collisions.pt, collisions.ee, collisions.ee_eps_x,
                bool(collisions.may_be_active(dhat)))

    def factors(self, kappa: float) -> np.ndarray:
        """(N_KINDS,) each kind's weight at κ (barriers scaled by it)."""
        kinds, weights, barrier = self.weighing
        by_kind = np.zeros(kt.N_KINDS)
        by_kind[kinds] = np.where(barrier, weights * kappa, weights)
        return by_kind


class DenseHessian(Struct, frozen=True, eq=False, dict=True):
    """The weighted sum of a potential's Hessians at x, as one part of a dense Newton
    matrix (``solver/assembly.DenseAssembler`` calls ``add_dense``); as triplets too
    (its nonzero entries), for whoever reads a Hessian so."""

    x: np.ndarray
    present: np.ndarray
    factors: np.ndarray  # (N_KINDS,) each kind's weight (κ included for barriers)
    data: tuple
    pairs: tuple
    scale: float = 1.0  # as a part of a Hessian: the factors hold every weight

    def add_dense(self, A, free_index, p, coupling) -> None:
        kt.add_term_hessians_dense(A, coupling, self.x, self.present, self.factors,
                                   free_index, p, self.data, self.pairs)

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
