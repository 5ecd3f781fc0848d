"""The lagged data of smoothed Coulomb friction (IPC, Li et al. 2020, §5).

Friction is solved as a sequence of problems in which the normal force λ of every contact,
its closest points and its tangent basis are frozen at a lagged configuration x_lag (the
start of the step, then optionally the last solution, ``fricIterAmt``). ``lag_friction``
freezes them for every active mesh pair (point–triangle and edge–edge, d² < d̂², with
μ = selfFric; mollified, nearly parallel edge–edge pairs get none, as in ipctk) and every
vertex–plane pair of a plane with μ > 0:

    λ_k = −κ b'(d_k², d̂²) · 2 d_k,   weight_k = μ_k λ_k

Tangential displacements are then measured from ``x_start`` (the start of the step).

A 2D scene (``planar``) has point–edge pairs and lines: their normal forces are those of
its barrier's form and weights (``setup.PlanarContact``), λ = −w κ ∂b/∂d.
"""

from __future__ import annotations

from msgspec import Struct
import numpy as np

from ..kernels.contact import friction as kf
from ..kernels.contact.line_barrier import lag_line_pairs
from ..kernels.terms.all_terms import point_weights
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
                 mu_mesh: float, kappa: float, dhat: float, planar=None) -> FrictionLag:
    """Freeze normal forces, closest points and tangent bases at x_lag (n, 3); pairs
    inactive at x_lag are dropped and nothing is built for μ = 0. ``planar``: a 2D
    scene's ``setup.PlanarContact``."""
    x_lag = np.ascontiguousarray(x_lag, dtype=float).reshape(-1, 3)
    if planar is not None:
        return _lag_planar(x_lag, x_start, collisions, planes, mu_mesh, kappa, dhat, planar)
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


def _lag_planar(x_lag, x_start, collisions, planes, mu_mesh, kappa, dhat,
                planar) -> FrictionLag:
    """``lag_friction`` of a 2D scene: its point–edge pairs, then its lines with μ > 0."""
    parts = []  # (verts, coeffs, basis, μλ) of each kind of pair
    if mu_mesh > 0.0 and collisions is not None and collisions.may_be_active(dhat):
        pe = collisions.pt
        keep, v, c, b, lam = kf.lag_point_edge_pairs(
            x_lag, pe, point_weights(pe, planar.point_weight), dhat * dhat, float(kappa),
            planar.form)
        parts.append((v[keep], c[keep], b[keep], mu_mesh * lam[keep]))
    use = planes.friction > 0.0 if planes is not None else np.zeros(0, bool)
    if use.any():
        args = (x_lag, planes.vertices, planes.origins[use], planes.normals[use])
        if planar.line_weight is None:
            line, v, c, b, lam = kf.lag_plane_pairs(*args, dhat * dhat, float(kappa))
        else:
            line, v, c, b, lam = lag_line_pairs(*args, float(dhat), planar.line_weight,
                                                float(kappa))
        parts.append((v, c, b, planes.friction[use][line] * lam))
    if not parts:
        parts.append((np.zeros((0, 4), np.int64), np.zeros((0, 4)), np.zeros((0, 3, 2)),
                      np.zeros(0)))
    verts, coeffs, basis, weight = (np.ascontiguousarray(np.concatenate(a)) for a in zip(*parts))
    x_start = np.ascontiguousarray(x_start, dtype=float).reshape(-1, 3).copy()
    return FrictionLag(x_start, verts, coeffs, basis, weight, kf.triplet_offsets(verts))


_NO_PLANES = Planes(np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3)),
                    np.zeros(0))
