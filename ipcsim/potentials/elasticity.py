"""Hyperelasticity of the tetrahedral meshes: E(x) = Σₑ V_restₑ Ψ(Fₑ), Fₑ = Ds Dm⁻¹.

Energies (as in the original IPC program), per rest volume:

    "NH"   neo-Hookean      Ψ = μ/2 (tr FᵀF − 3) − μ ln J + λ/2 (ln J)²   (+∞ for J ≤ 0)
    "FCR"  fixed corotated  Ψ = μ Σ (σᵢ − 1)² + λ/2 (J − 1)²

The math lives in ``ipcsim.kernels.elasticity.tets``; this class holds the per-tet data and
turns the kernels' arrays into what the solver expects. ``hessian`` projects every element
Hessian to PSD with the analytic eigensystem of Smith, de Goes and Kim (2019).

``max_step(x, p)`` is this term's line-search bound: for NH the largest α ∈ [0, 1] such that
no tet loses more than 1 − ``min_volume_ratio`` of its current volume on [x, x + α p] (the
original IPC's rule, ratio 0.1), so the energy stays finite; FCR is defined for inverted
elements and returns 1.
"""

from __future__ import annotations

from functools import partial
from typing import ClassVar

from msgspec import Struct
from msgspec.structs import force_setattr
import numpy as np

from ..kernels.terms import all_terms as terms_kernels
from ..kernels.elasticity import tets as kern
from .base import ElementHessian

_MODELS = {
    "NH": kern.NEO_HOOKEAN,
    "NEOHOOKEAN": kern.NEO_HOOKEAN,
    "FCR": kern.FIXED_COROTATED,
    "FIXEDCOROTATED": kern.FIXED_COROTATED,
}


class Elasticity(Struct, frozen=True, eq=False):
    """Elastic energy of m tets over n vertices.

    tets (m, 4) int, Dm_inv (m, 3, 3), volumes (m,) rest volumes, lame (m, 2) = (μ, λ) per tet
    (a single (μ, λ) pair is broadcast), energy "NH" or "FCR", n_vertices = n.
    Positions may be passed as (n, 3) or flat (3n,). The step context is not used.
    """

    tets: np.ndarray
    Dm_inv: np.ndarray
    volumes: np.ndarray
    lame: np.ndarray
    energy: str
    n_vertices: int
    min_volume_ratio: float = 0.1
    name: ClassVar[str] = "elasticity"
    kind: ClassVar[int] = terms_kernels.ELASTICITY  # its data in the all-terms kernels
    constant_pattern: ClassVar[bool] = True  # same triplet index arrays on every call

    def __post_init__(self):
        key = str(self.energy).replace("-", "").replace("_", "").replace(" ", "").upper()
        if key not in _MODELS:
            raise ValueError(f"unknown elastic energy {self.energy!r}; expected 'NH' or 'FCR'")
        put = partial(force_setattr, self)
        put("energy", "NH" if _MODELS[key] == kern.NEO_HOOKEAN else "FCR")
        put("n_vertices", int(self.n_vertices))
        # private writeable C-contiguous copies: the Model's arrays are read-only, and numba
        # compiles a separate specialisation of every kernel for read-only arguments
        tets = np.array(self.tets, dtype=np.int64, order="C", copy=True).reshape(-1, 4)
        m = len(tets)
        put("tets", tets)
        put("Dm_inv", np.array(self.Dm_inv, dtype=np.float64, order="C", copy=True).reshape(m, 3, 3))
        put("volumes", np.array(self.volumes, dtype=np.float64, order="C", copy=True).reshape(m))
        put("lame", np.array(np.broadcast_to(np.asarray(self.lame, dtype=np.float64), (m, 2)),
                             order="C", copy=True))
        if m and (tets.min() < 0 or tets.max() >= self.n_vertices):
            raise ValueError("tet vertex index out of range")
        if 3 * self.n_vertices > np.iinfo(np.int32).max:  # the pattern's int32 DOFs
            raise ValueError(f"{self.n_vertices} vertices: more than int32 DOF numbers hold")
        if not (0.0 <= self.min_volume_ratio < 1.0):
            raise ValueError("min_volume_ratio must lie in [0, 1)")
        put("min_volume_ratio", float(self.min_volume_ratio))

    @property
    def model(self) -> int:
        """The kernels' code of the energy."""
        return _MODELS[self.energy]

    def _positions(self, x) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1, 3)
        if not x.flags.writeable:  # see __post_init__: keep one numba specialisation
            x = x.copy()
        if len(x) != self.n_vertices:
            raise ValueError(f"expected {self.n_vertices} vertices, got {len(x)}")
        return x

    def _args(self):
        return self.tets, self.Dm_inv, self.volumes, self.lame, self.model

    def value(self, x, ctx=None) -> float:
        return float(kern.elastic_energy(self._positions(x), *self._args()))

    def per_tet_energy(self, x) -> np.ndarray:
        return kern.elastic_energy_per_tet(self._positions(x), *self._args())

    def gradient(self, x, ctx=None) -> np.ndarray:
        return kern.elastic_gradient(self._positions(x), *self._args())

    def hessian(self, x, ctx=None, project_psd: bool = True) -> ElementHessian:
        """The tets' 12×12 blocks (PSD-projected unless told otherwise) at x, evaluated
        chunk by chunk as they are assembled."""
        x = self._positions(x).copy()  # the blocks are evaluated later, at this x
        return ElementHessian(self.tets, x, partial(self._block_values, bool(project_psd)),
                              kern.tet_hessian_pattern)

    def _block_values(self, project_psd: bool, x, lo: int, hi: int) -> np.ndarray:
        return kern.elastic_hessian_values(x, self.tets[lo:hi], self.Dm_inv[lo:hi],
                                           self.volumes[lo:hi], self.lame[lo:hi], self.model,
                                           project_psd)

    def max_step(self, x, p, ctx=None) -> float:
        if self.model != kern.NEO_HOOKEAN or len(self.tets) == 0:
            return 1.0
        alpha = kern.max_step_no_inversion(self._positions(x), self._positions(p), self.tets,
                                           self.min_volume_ratio)
        return float(alpha)
