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

from dataclasses import dataclass

import numpy as np

from ..kernels import friction as kf
from .collisions import Collisions
from .planes import Planes


@dataclass(frozen=True, eq=False)
class FrictionLag:
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
    s_hat = float(dhat) ** 2
    parts = []
    if mu_mesh > 0.0 and collisions is not None and collisions.may_be_active(dhat):
        keep, v, c, b, lam = kf.lag_mesh_pairs(x_lag, collisions.pt, collisions.ee,
                                               collisions.ee_eps_x, s_hat, float(kappa))
        parts.append((v[keep], c[keep], b[keep], float(mu_mesh) * lam[keep]))
    if planes is not None and len(planes.vertices):
        use = planes.friction > 0.0
        if np.any(use) and planes.count(x_lag, dhat)[0] > 0:
            origins = np.ascontiguousarray(planes.origins[use])
            normals = np.ascontiguousarray(planes.normals[use])
            pl, v, c, b, lam = kf.lag_plane_pairs(x_lag, planes.vertices, origins, normals,
                                                  s_hat, float(kappa))
            parts.append((v, c, b, planes.friction[use][pl] * lam))
    x_start = np.ascontiguousarray(x_start, dtype=float).reshape(-1, 3).copy()
    if not parts:
        return FrictionLag(x_start, np.zeros((0, 4), dtype=np.int64), np.zeros((0, 4)),
                           np.zeros((0, 3, 2)), np.zeros(0), np.zeros(1, dtype=np.int64))
    verts = np.ascontiguousarray(np.concatenate([p[0] for p in parts]))
    return FrictionLag(x_start, verts,
                       np.ascontiguousarray(np.concatenate([p[1] for p in parts])),
                       np.ascontiguousarray(np.concatenate([p[2] for p in parts])),
                       np.ascontiguousarray(np.concatenate([p[3] for p in parts])),
                       kf.triplet_offsets(verts))
