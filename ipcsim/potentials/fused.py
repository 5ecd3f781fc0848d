"""A small scene's terms evaluated together: one kernel call gives every term's value, one
every gradient, one adds every Hessian into the dense Newton matrix
(``kernels/fused_terms.py``), where the terms on their own make a call per term and per
quantity.

On a scene of tens of vertices those calls, not their arithmetic, were most of a Newton
iteration. ``FusedTerms.of(terms)`` packs the terms' own data once (None where a term
has no fused form, as the penalty baseline's); each evaluation adds what the step
context holds then (x̃, the collision set, the friction lag, the damping, the pull). The
fused kernels call the kernels the terms call, in the terms' order, so every value,
gradient and Newton matrix is the one the terms give, bit for bit. The potential
(``incremental.py``) uses them where the Newton system is dense (``linear.DenseSolver``),
the only place the dense Hessian fits.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..kernels import fused_terms as kf
from .base import StepContext, Triplets
from .body_force import BodyForce
from .boundary_pull import BoundaryPull
from .damping import Damping
from .elasticity import Elasticity
from .friction import Friction
from .inertia import Inertia
from .mesh_contact import MeshContact
from .plane_contact import PlaneContact

_KIND = {Inertia: kf.INERTIA, BodyForce: kf.BODY_FORCE, Elasticity: kf.ELASTICITY,
         Damping: kf.DAMPING, PlaneContact: kf.PLANE_CONTACT, MeshContact: kf.MESH_CONTACT,
         Friction: kf.FRICTION, BoundaryPull: kf.PULL}


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


@dataclass(frozen=True, eq=False)
class FusedTerms:
    """The terms of a potential, by kind: ``kinds[i]`` is the kind of the i-th term,
    ``present`` (N_KINDS,) which kinds there are, ``terms`` the term of each kind (None
    where absent) and ``fixed`` each kind's data tuple as far as it does not depend on
    the step context (``_data`` fills in the rest)."""

    kinds: tuple[int, ...]
    present: np.ndarray
    terms: tuple
    fixed: tuple

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
        return FusedTerms(kinds, present, tuple(terms), tuple(fixed))

    def _data(self, ctx: StepContext) -> tuple:
        """The eight kinds' data tuples in this context."""
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
        return tuple(data)

    def values(self, x, ctx: StepContext) -> tuple[float, ...]:
        """Each term's value at x, in the terms' order."""
        out = kf.term_values(_writeable(x), self.present, *self._data(ctx))
        return tuple(float(out[k]) for k in self.kinds)

    def gradients(self, x, ctx: StepContext) -> tuple[np.ndarray, ...]:
        """Each term's gradient (3n,) at x, in the terms' order."""
        out = kf.term_gradients(_writeable(x), self.present, *self._data(ctx))
        return tuple(out[k] for k in self.kinds)

    def hessian(self, x, ctx: StepContext, factors) -> "FusedHessian":
        """Σ factors[i]·(the i-th term's Hessian) at x, to be added into a dense matrix."""
        by_kind = np.zeros(kf.N_KINDS)
        by_kind[list(self.kinds)] = factors
        data = self._data(ctx)
        return FusedHessian(_writeable(x).copy(), self.present, by_kind,
                            data[:kf.BODY_FORCE] + data[kf.ELASTICITY:])


@dataclass(frozen=True, eq=False)
class FusedHessian:
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
    def vals(self) -> np.ndarray:
        return self._triplets.vals

    @property
    def values(self) -> np.ndarray:
        return self._triplets.vals

    def tocsr(self, n_dofs: int):
        return self._triplets.tocsr(n_dofs)
