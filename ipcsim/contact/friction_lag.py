"""The lagged data of smoothed Coulomb friction (IPC, Li et al. 2020, §5).

Friction is solved as a sequence of problems in which the normal force λ of every contact,
its closest points and its tangent basis are frozen at a lagged configuration x_lag (the
start of the step, then optionally the last solution, ``fricIterAmt``). ``lag_friction``
freezes them for every active mesh pair (point–triangle and edge–edge, d² < d̂², with
μ = selfFric; mollified, nearly parallel edge–edge pairs get none, as in ipctk) and every
vertex–plane pair of a plane with μ > 0:

    λ_k = −κ b'(d_k², d̂²) · 2 d_k,   weight_k = μ_k λ_k

Tangential displacements are then measured from ``x_start`` (the start of the step).
"""

from __future__ import annotations

from msgspec import Struct
import numpy as np

from ..kernels.contact import friction as kf
from .collisions import Collisions
from .planes import Planes


class FrictionLag(Struct, frozen=True, eq=False):
    """Frozen friction data of k pairs: verts (k, 4) stencil vertices (−1 unused),
    coeffs (k, 4) closest-point weights, basis (k, 3, 2) tangent bases, weight (k,) μλ,
    offsets (k + 1,) Hessian triplet offsets; x_start (n, 3) the reference positions."""

    x_start: np.ndarray
    verts: np.ndarray
    coeffs: np.ndarray
    basis: np.ndarray
    weight: np.ndarray
    offsets: np.ndarray

    @property
    def count(self) -> int:
        """Number of frictional pairs (mesh and plane)."""
        return int(self.verts.shape[0])


def lag_friction(x_lag, x_start, collisions: Collisions | None, planes: Planes | None,
                 mu_mesh: float, kappa: float, dhat: float) -> FrictionLag:
    """Freeze normal forces, closest points and tangent bases at x_lag (n, 3); pairs
    inactive at x_lag are dropped and nothing is built for μ = 0."""
    x_lag = np.ascontiguousarray(x_lag, dtype=float).reshape(-1, 3)
    if collisions is None:
        collisions = Collisions.empty()
    mesh = (collisions.pt, collisions.ee, collisions.ee_eps_x, float(mu_mesh),
            bool(mu_mesh > 0.0 and collisions.may_be_active(dhat)))
    if planes is None:
        planes = _NO_PLANES
    lagged = kf.lag_pairs(x_lag, mesh, (planes.vertices, planes.origins, planes.normals,
                                         planes.friction), float(dhat) ** 2, float(kappa))
    x_start = np.ascontiguousarray(x_start, dtype=float).reshape(-1, 3).copy()
    return FrictionLag(x_start, *lagged)


_NO_PLANES = Planes(np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3)),
                    np.zeros(0))
