"""The terms only a 2D scene has (the plane z = 0; positions stay (n, 3)):

* ``TriangleElasticity``: Σ A_rest Ψ(F) over the triangles, plane strain
  (``kernels/elasticity/triangles.py``), with the 2D inversion bound for NH;
* ``Springs``: the lecture's mass-spring energy (``kernels/elasticity/springs.py``);
* ``PointEdgeContact``: the barrier of the point–edge pairs of ``ctx.collisions``
  (``kernels/contact/point_edge_barrier.py``), in the paper's form with weight 1 or the
  lecture's, weighted by A d̂ / 16 (A the point's contact length);
* ``LineContact``: the lecture's half-plane barrier on the distance itself, weighted by
  A d̂ / 2 (``kernels/contact/line_barrier.py``); a 2D scene with the paper's barrier
  uses ``PlaneContact`` for its lines.

Barriers are at unit stiffness, as every barrier term is. Each is one kind of the
all-terms kernels (``kernel_data.py``); these methods are the terms on their own (the
sparse assembly's Hessians, checks and tests).
"""

from __future__ import annotations

from functools import partial
from typing import ClassVar

import numpy as np
from msgspec import Struct
from msgspec.structs import force_setattr

from ..contact.planes import Planes
from ..kernels.algebra.assembly import block_triplet_indices
from ..kernels.contact import line_barrier as kl
from ..kernels.contact import plane_barrier as kp
from ..kernels.contact import point_edge_barrier as kpe
from ..kernels.elasticity import springs as ks
from ..kernels.elasticity import triangles as ktri
from ..kernels.elasticity.tets import FIXED_COROTATED, NEO_HOOKEAN
from ..kernels.terms import all_terms as terms_kernels
from .base import ContactTerm, ElementHessian, StepContext, Triplets
from .plane_contact import CCD_KEEP_FRACTION


def _owned(a, dtype, shape=None) -> np.ndarray:
    """A writeable C-contiguous copy (numba compiles one variant for such arrays)."""
    a = np.array(a, dtype=dtype, order="C", copy=True)
    return a if shape is None else a.reshape(shape)


def _positions(x) -> np.ndarray:
    x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1, 3)
    return x if x.flags.writeable else x.copy()


class TriangleElasticity(Struct, frozen=True, eq=False):
    """Elastic energy of m triangles (plane strain): triangles (m, 3), Dm_inv (m, 2, 2),
    areas (m,) rest areas, lame (m, 2), energy "NH" or "FCR"."""

    triangles: np.ndarray
    Dm_inv: np.ndarray
    areas: np.ndarray
    lame: np.ndarray
    energy: str
    min_area_ratio: float = 0.1  # the NH bound: no triangle loses more than 90 % of its area
    name: ClassVar[str] = "elasticity"
    kind: ClassVar[int] = terms_kernels.TRIANGLES
    constant_pattern: ClassVar[bool] = True

    def __post_init__(self):
        m = len(self.triangles)
        force_setattr(self, "triangles", _owned(self.triangles, np.int64, (m, 3)))
        force_setattr(self, "Dm_inv", _owned(self.Dm_inv, np.float64, (m, 2, 2)))
        force_setattr(self, "areas", _owned(self.areas, np.float64, (m,)))
        force_setattr(self, "lame", _owned(self.lame, np.float64, (m, 2)))
        if self.energy not in ("NH", "FCR"):
            raise ValueError(f"unknown elastic energy {self.energy!r}; expected 'NH' or 'FCR'")

    @property
    def model(self) -> int:
        return NEO_HOOKEAN if self.energy == "NH" else FIXED_COROTATED

    def _args(self):
        return self.triangles, self.Dm_inv, self.areas, self.lame, self.model

    def value(self, x, ctx=None) -> float:
        return float(ktri.triangle_energy(_positions(x), *self._args()))

    def gradient(self, x, ctx=None) -> np.ndarray:
        return ktri.triangle_gradient(_positions(x), *self._args())

    def hessian(self, x, ctx=None, project_psd: bool = True) -> ElementHessian:
        return ElementHessian(self.triangles, _positions(x).copy(),
                              partial(self._block_values, bool(project_psd)),
                              block_triplet_indices)

    def _block_values(self, project_psd: bool, x, lo: int, hi: int) -> np.ndarray:
        return ktri.triangle_hessian_values(x, self.triangles[lo:hi], self.Dm_inv[lo:hi],
                                            self.areas[lo:hi], self.lame[lo:hi], self.model,
                                            project_psd)

    def max_step(self, x, p, ctx=None) -> float:
        if self.energy != "NH" or not len(self.triangles):
            return 1.0
        return float(ktri.max_step_no_inversion_2d(_positions(x), _positions(p),
                                                   self.triangles, self.min_area_ratio))


class Springs(Struct, frozen=True, eq=False):
    """Σ ½ k l² (|d|²/l² − 1)² over the springs (k, 2) with rest lengths² and stiffnesses."""

    springs: np.ndarray
    rest_length_sq: np.ndarray
    stiffness: np.ndarray
    name: ClassVar[str] = "springs"
    kind: ClassVar[int] = terms_kernels.SPRINGS
    constant_pattern: ClassVar[bool] = True

    def __post_init__(self):
        k = len(self.springs)
        force_setattr(self, "springs", _owned(self.springs, np.int64, (k, 2)))
        force_setattr(self, "rest_length_sq", _owned(self.rest_length_sq, np.float64, (k,)))
        force_setattr(self, "stiffness", _owned(self.stiffness, np.float64, (k,)))

    def _args(self):
        return self.springs, self.rest_length_sq, self.stiffness

    def value(self, x, ctx=None) -> float:
        return float(ks.spring_energy(_positions(x), *self._args()))

    def gradient(self, x, ctx=None) -> np.ndarray:
        return ks.spring_gradient(_positions(x), *self._args())

    def hessian(self, x, ctx=None, project_psd: bool = True) -> ElementHessian:
        return ElementHessian(self.springs, _positions(x).copy(),
                              partial(self._block_values, bool(project_psd)),
                              block_triplet_indices)

    def _block_values(self, project_psd: bool, x, lo: int, hi: int) -> np.ndarray:
        return ks.spring_hessian_values(x, self.springs[lo:hi], self.rest_length_sq[lo:hi],
                                        self.stiffness[lo:hi], project_psd)


class PointEdgeContact(Struct, ContactTerm, frozen=True, eq=False):
    """The barrier of the point–edge pairs of ``ctx.collisions`` at unit κ: Σ w b(d², d̂²),
    each pair weighted by its point's ``point_weight`` (n,), in barrier ``form``."""

    dhat: float
    form: int
    point_weight: np.ndarray
    name: ClassVar[str] = "mesh contact"
    kind: ClassVar[int] = terms_kernels.POINT_EDGE

    def __post_init__(self):
        force_setattr(self, "point_weight", _owned(self.point_weight, np.float64))

    def _pairs(self, ctx: StepContext):
        c = ctx.collisions
        if c is None or not c.may_be_active(self.dhat):
            return None
        return c.pt, terms_kernels.point_weights(c.pt, self.point_weight)

    def value(self, x, ctx: StepContext):
        pairs = self._pairs(ctx)
        if pairs is None:
            return 0.0
        return kpe.pe_barrier_value(_positions(x), *pairs, self.s_hat, 1.0, self.form)

    def gradient(self, x, ctx: StepContext):
        pairs = self._pairs(ctx)
        if pairs is None:
            return np.zeros(np.size(x))
        return kpe.pe_barrier_gradient(_positions(x), *pairs, self.s_hat, 1.0, self.form)

    def hessian(self, x, ctx: StepContext):
        pairs = self._pairs(ctx)
        if pairs is None:
            return Triplets.empty()
        return Triplets(*kpe.pe_barrier_hessian_triplets(_positions(x), *pairs, self.s_hat,
                                                         1.0, self.form, True))


class LineContact(Struct, ContactTerm, frozen=True, eq=False):
    """The lecture's half-plane barrier at unit κ: Σ w_j b_L(d, d̂) over every (line,
    vertex) pair, w_j = A_j d̂ / 2 (``vertex_weight``, one per vertex of ``planes``). The
    lines' origins are ``ctx.plane_origins`` where they move."""

    planes: Planes
    dhat: float
    vertex_weight: np.ndarray
    name: ClassVar[str] = "plane contact"
    kind: ClassVar[int] = terms_kernels.LINE_LECTURE

    def __post_init__(self):
        force_setattr(self, "vertex_weight", _owned(self.vertex_weight, np.float64))

    def _args(self, ctx):
        return self.planes.vertices, self.planes.at(ctx).origins, self.planes.normals

    def value(self, x, ctx: StepContext | None = None):
        return kl.line_barrier_value(_positions(x), *self._args(ctx), self.dhat,
                                     self.vertex_weight)

    def gradient(self, x, ctx: StepContext | None = None):
        return kl.line_barrier_gradient(_positions(x), *self._args(ctx), self.dhat,
                                        self.vertex_weight)

    def hessian(self, x, ctx: StepContext | None = None):
        return Triplets(*kl.line_barrier_hessian(_positions(x), *self._args(ctx), self.dhat,
                                                 self.vertex_weight))

    def max_step(self, x, p, ctx: StepContext | None = None):
        return kp.plane_ccd_max_step(_positions(x), np.ascontiguousarray(p).reshape(-1),
                                     *self._args(ctx), CCD_KEEP_FRACTION)
