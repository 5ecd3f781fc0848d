"""Lagged, smoothed Coulomb friction (IPC, Li et al. 2020) in displacement form:

    D(x) = Σ_k μ_k λ_k f0(|P_kᵀ r_k(x − x_lag)|, ε_v h)

over mesh PT/EE pairs and vertex–plane pairs active at x_lag (d² < d̂²). The normal force
λ_k, closest-point coefficients and tangent basis are frozen by ``lag`` (see
kernels/friction.py); near-parallel (mollified) edge–edge pairs get no friction, as in
ipctk. With ε = ε_v h and u = x − x_lag this equals ipctk's FrictionPotential(ε) at V = u.
"""

from __future__ import annotations

import numpy as np

from ..kernels import friction as kf
from .base import Triplets


class Friction:
    name = "friction"
    constant_pattern = False

    def __init__(self, eps_v_h: float, project: bool = True):
        if not eps_v_h > 0.0:
            raise ValueError(f"friction threshold eps_v*h must be > 0, got {eps_v_h}")
        self.eps = float(eps_v_h)
        self.project = bool(project)
        self._clear()

    def _clear(self):
        self.x_lag = None
        self.verts = np.zeros((0, 4), dtype=np.int64)
        self.coeffs = np.zeros((0, 4))
        self.basis = np.zeros((0, 3, 2))
        self.weight = np.zeros(0)
        self.offsets = np.zeros(1, dtype=np.int64)

    @property
    def count(self) -> int:
        """Number of frictional pairs (mesh and plane)."""
        return int(self.verts.shape[0])

    def lag(self, x_lag, pt_pairs, ee_pairs, ee_eps_x, plane_vertices, plane_origins,
            plane_normals, plane_mu, mu_mesh, kappa, dhat, x_start=None):
        """Freeze normal forces, closest points and tangent bases at x_lag (n, 3).

        Displacements are measured from ``x_start`` (the start of the time step; default
        x_lag): a later friction update re-lags forces and bases at the step's current
        solution while the sliding displacement still counts from the step's start.

        pt_pairs (k, 4), ee_pairs (j, 4) int64 candidate pairs with ee_eps_x (j,) their
        mollifier thresholds; plane_vertices (v,) the vertices tested against each plane
        (plane_origins, plane_normals (p, 3), plane_mu (p,)); mu_mesh the mesh–mesh
        friction coefficient. Pairs inactive at x_lag are dropped; nothing is built for
        μ = 0."""
        x_lag = np.ascontiguousarray(x_lag, dtype=float).reshape(-1, 3)
        s_hat = float(dhat) ** 2
        kappa = float(kappa)
        parts = []
        if mu_mesh > 0.0:
            pt = np.ascontiguousarray(pt_pairs, dtype=np.int64).reshape(-1, 4)
            ee = np.ascontiguousarray(ee_pairs, dtype=np.int64).reshape(-1, 4)
            eps_x = np.ascontiguousarray(ee_eps_x, dtype=float).reshape(-1)
            if len(pt) or len(ee):
                keep, v, c, b, lam = kf.lag_mesh_pairs(x_lag, pt, ee, eps_x, s_hat, kappa)
                parts.append((v[keep], c[keep], b[keep], float(mu_mesh) * lam[keep]))
        plane_mu = np.asarray(plane_mu, dtype=float).reshape(-1)
        use = plane_mu > 0.0
        if np.any(use) and len(plane_vertices):
            origins = np.ascontiguousarray(np.asarray(plane_origins, float).reshape(-1, 3)[use])
            normals = np.ascontiguousarray(np.asarray(plane_normals, float).reshape(-1, 3)[use])
            verts = np.ascontiguousarray(plane_vertices, dtype=np.int64).reshape(-1)
            pl, v, c, b, lam = kf.lag_plane_pairs(x_lag, verts, origins, normals, s_hat,
                                                  kappa)
            parts.append((v, c, b, plane_mu[use][pl] * lam))
        self._clear()
        self.x_lag = (x_lag if x_start is None
                      else np.ascontiguousarray(x_start, dtype=float).reshape(-1, 3)).copy()
        if parts:
            self.verts = np.ascontiguousarray(np.concatenate([p[0] for p in parts]))
            self.coeffs = np.ascontiguousarray(np.concatenate([p[1] for p in parts]))
            self.basis = np.ascontiguousarray(np.concatenate([p[2] for p in parts]))
            self.weight = np.ascontiguousarray(np.concatenate([p[3] for p in parts]))
            self.offsets = kf.triplet_offsets(self.verts)

    # -- potential -----------------------------------------------------------------------
    def _u(self, x):
        return np.ascontiguousarray(np.asarray(x, dtype=float).reshape(-1, 3) - self.x_lag)

    def value(self, x):
        if self.count == 0:
            return 0.0
        return kf.friction_value(self._u(x), self.verts, self.coeffs, self.basis,
                                 self.weight, self.eps)

    def gradient(self, x):
        if self.count == 0:
            return np.zeros(np.asarray(x).size)
        return kf.friction_gradient(self._u(x), self.verts, self.coeffs, self.basis,
                                    self.weight, self.eps)

    def hessian(self, x):
        if self.count == 0:
            return Triplets.empty()
        return Triplets(*kf.friction_hessian_triplets(
            self._u(x), self.verts, self.coeffs, self.basis, self.weight, self.eps,
            self.project, self.offsets))
