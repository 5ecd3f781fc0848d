"""The constraint set of the SQP and QP baselines, and its linearisation.

As in the original program, a time step starts with an empty set, and a pair joins it once
the step's motion would bring it into contact: every point–triangle and edge–edge pair of
ipcsim's broad phase over the straight motion x_n -> x (boxes grown by η = 2·offset, the
original's CCD separation) whose additive CCD query stops before the end, or that ends
closer than η; and every vertex that would end less than η above a plane. Pairs never
leave the set during the step (the original keeps them too).

A pair's "outside" is the side it is on at the start of the step: its constraint is
c_s(x) = s·c(x) with s the sign of c(x_n) (+1 at zero). For edge–edge pairs that is the
original's rule (it orders the edges by the sign of their volume at the step's start); for
point–triangle pairs the original trusts the triangle's winding, which is the same for a
closed surface approached from outside and wrong for an open one approached from behind.

``linearise`` gives the rows of c_s(x) + ∇c_s(x)·Δx ≥ offset over the free DOFs.
"""

from __future__ import annotations

from msgspec import Struct
import numpy as np
import scipy.sparse as sp

from ..contact.collision_mesh import CollisionMesh
from ..contact.collisions import pair_distances, swept_collisions
from ..contact.planes import Planes
from ..kernels.contact import ccd as _ccd
from ..kernels.contact import constraints as _kc

KINDS = {"volume": _kc.VOLUME, "gap": _kc.GAP, "Verschoor": _kc.VERSCHOOR}


class ActiveSet(Struct, frozen=True, eq=False):
    """Pairs kept apart: pt (k, 4), ee (j, 4) stencils with their signs and contact
    weights (Verschoor; zeros otherwise), and (vertex, plane) rows."""

    pt: np.ndarray
    ee: np.ndarray
    pt_sign: np.ndarray
    ee_sign: np.ndarray
    pt_w: np.ndarray
    ee_w: np.ndarray
    planes: np.ndarray  # (q, 2) int64

    @staticmethod
    def empty() -> "ActiveSet":
        z4 = np.zeros((0, 4), dtype=np.int64)
        return ActiveSet(z4, z4, np.zeros(0), np.zeros(0), np.zeros((0, 4)),
                         np.zeros((0, 4)), np.zeros((0, 2), dtype=np.int64))

    def __len__(self) -> int:
        return len(self.pt) + len(self.ee) + len(self.planes)


class ConstraintGeometry(Struct, frozen=True, eq=False):
    """What the constraints are between: the collision mesh (None without mesh contact),
    the planes (None without), the constraint kind and the offset."""

    mesh: CollisionMesh | None
    planes: Planes | None
    kind: str  # "volume" | "gap" | "Verschoor"
    offset: float

    @property
    def eta(self) -> float:
        """The CCD separation that makes a pair active (the original's 2·offset)."""
        return 2.0 * self.offset


def _values(x, pairs, is_ee, kind, weights):
    if len(pairs) == 0:
        return np.zeros(0), np.zeros((0, 4, 3))
    return _kc.constraint_values_and_gradients(x, pairs, is_ee, KINDS[kind], weights)


def _new_rows(old: np.ndarray, found: np.ndarray) -> np.ndarray:
    """Indices of the rows of ``found`` that are not rows of ``old``."""
    if len(found) == 0:
        return np.zeros(0, dtype=np.int64)
    known = {tuple(r) for r in old.tolist()}
    return np.array([i for i, r in enumerate(found.tolist()) if tuple(r) not in known],
                    dtype=np.int64)


def _colliding(geo: ConstraintGeometry, x0, x1, pairs, n_pt):
    """Which candidate stencils (PT first) come into contact on x0 -> x1, with their CCD
    times of impact."""
    pt, ee = pairs[:n_pt], pairs[n_pt:]
    toi, _ = _ccd.ccd_query_steps(x0, x1, pt, ee)
    d = pair_distances(x1, Stencils(pt, ee))
    end2 = np.concatenate([d.pt_d2, d.ee_d2])
    return (toi < 1.0) | (end2 < geo.eta ** 2), toi


class Stencils(Struct, frozen=True):
    """PT and EE stencils, as ``pair_distances`` reads them."""

    pt: np.ndarray
    ee: np.ndarray


def grow(active: ActiveSet, geo: ConstraintGeometry, x_start, x_end) -> tuple[ActiveSet, int]:
    """The set with every pair the motion x_start -> x_end brings into contact added;
    returns (set, number of pairs added). With Verschoor constraints the weights of the
    pairs already in the set are those of this motion's contact point, and a pair that
    this motion does not bring into contact is switched off (as the original does)."""
    hits = _hits(geo, x_start, x_end)
    pt, pt_sign, pt_w, n_pt = _merge(geo, (x_start, x_end), (active.pt, active.pt_sign,
                                                              active.pt_w), hits[0], False)
    ee, ee_sign, ee_w, n_ee = _merge(geo, (x_start, x_end), (active.ee, active.ee_sign,
                                                              active.ee_w), hits[1], True)
    planes_new = _plane_rows(active, geo, x_end)
    added = n_pt + n_ee + len(planes_new)
    if added == 0 and geo.kind != "Verschoor":
        return active, 0
    return ActiveSet(pt, ee, pt_sign, ee_sign, pt_w, ee_w,
                     np.concatenate([active.planes, planes_new])), added


def _hits(geo: ConstraintGeometry, x_start, x_end):
    """((PT stencils, their tois), (EE stencils, their tois)) that x_start -> x_end brings
    into contact."""
    empty = (np.zeros((0, 4), np.int64), np.zeros(0))
    if geo.mesh is None:
        return empty, empty
    swept = swept_collisions(geo.mesh, x_start, x_end, geo.eta)
    pairs = np.concatenate([swept.pt, swept.ee]).reshape(-1, 4)
    if not len(pairs):
        return empty, empty
    n = len(swept.pt)
    hit, toi = _colliding(geo, x_start, x_end, pairs, n)
    return ((swept.pt[hit[:n]], toi[:n][hit[:n]]), (swept.ee[hit[n:]], toi[n:][hit[n:]]))


def _merge(geo, motion, current, hits, is_ee):
    """(stencils, signs, weights, number added): the current rows, then the new hits."""
    pairs, sign, weights = current
    found, toi = hits
    fresh = _new_rows(pairs, found)
    new_sign, new_w = _signs_and_weights(geo, *motion, found[fresh], toi[fresh], is_ee)
    if geo.kind == "Verschoor" and len(pairs):
        weights = np.full_like(weights, np.nan)  # off unless this motion hits it
        row_of = {tuple(r): i for i, r in enumerate(pairs.tolist())}
        again = [(row_of[tuple(r)], k) for k, r in enumerate(found.tolist())
                 if tuple(r) in row_of]
        if again:
            rows, ks = (np.array(v, dtype=np.int64) for v in zip(*again))
            weights[rows] = _kc.contact_weights(*motion, found[ks], is_ee, toi[ks])
    return (np.concatenate([pairs, found[fresh]]), np.concatenate([sign, new_sign]),
            np.concatenate([weights, new_w]), len(fresh))


def _plane_rows(active: ActiveSet, geo: ConstraintGeometry, x_end) -> np.ndarray:
    """(vertex, plane) rows not yet active whose vertex ends less than η above the plane."""
    planes = geo.planes
    if planes is None or len(planes.vertices) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    d = (x_end[planes.vertices][:, None, :] - planes.origins[None]) * planes.normals[None]
    v, p = np.nonzero(d.sum(axis=2) < geo.eta)
    rows = np.stack([planes.vertices[v], p], axis=1).astype(np.int64)
    return rows[_new_rows(active.planes, rows)]


def _signs_and_weights(geo, x_start, x_end, pairs, toi, is_ee):
    """Signs of the new pairs' constraints at the step's start, and their contact weights
    at the time of impact (Verschoor only; zeros otherwise)."""
    weights = np.zeros((len(pairs), 4))
    if len(pairs) and geo.kind == "Verschoor":
        weights = _kc.contact_weights(x_start, x_end, pairs, is_ee, np.asarray(toi, float))
    kind = "gap" if geo.kind == "Verschoor" else geo.kind  # the same value
    c, _ = _values(x_start, pairs, is_ee, kind, weights)
    return np.where(c < 0.0, -1.0, 1.0), weights


class Linearised(Struct, frozen=True, eq=False):
    """Rows A Δx ≥ lower over the free DOFs (A as CSC), and c_s(x) of every row."""

    A: sp.csc_matrix
    lower: np.ndarray
    values: np.ndarray
    counts: tuple[int, int, int]  # rows from planes, PT, EE


def linearise(active: ActiveSet, geo: ConstraintGeometry, x, free_index, n_free) -> Linearised:
    """c_s(x) + ∇c_s(x)·Δx ≥ offset for every active pair; columns are free DOFs (kinematic
    DOFs do not move); rows whose stencil is all kinematic, or degenerate, are left out."""
    blocks = [_plane_block(active, geo, x, free_index)]
    for pairs, sign, w, is_ee in ((active.pt, active.pt_sign, active.pt_w, False),
                                  (active.ee, active.ee_sign, active.ee_w, True)):
        blocks.append(_pair_block(geo, x, free_index, (pairs, sign, w), is_ee))
    rows, cols, vals, values, start = [], [], [], [], 0
    for c, local_row, col, val in blocks:
        rows.append(local_row + start)
        cols.append(col)
        vals.append(val)
        values.append(c)
        start += len(c)
    A = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(start, n_free))
    c = np.concatenate(values)
    return Linearised(A, geo.offset - c, c, tuple(len(b[0]) for b in blocks))


def _pair_block(geo, x, free_index, pairs_sign_w, is_ee):
    """(c_s, row, free column, ∇c_s entry) of the usable rows of PT or EE pairs."""
    pairs, sign, w = pairs_sign_w
    c, g = _values(x, pairs, is_ee, geo.kind, w)
    dofs = (3 * pairs[:, :, None] + np.arange(3)).reshape(len(pairs), 12)
    cols = free_index[dofs]
    usable = (c < _kc.INACTIVE) & (cols >= 0).any(axis=1)
    g = (g.reshape(len(pairs), 12) * sign[:, None])[usable]
    cols = cols[usable]
    local = np.repeat(np.arange(int(usable.sum())), 12).reshape(-1, 12)
    keep = cols >= 0
    return (sign[usable] * c[usable], local[keep], cols[keep], g[keep])


def _plane_block(active: ActiveSet, geo, x, free_index):
    """Plane rows: c = n·(x_v − o), ∇c = n on vertex v (free vertices only)."""
    rows = active.planes
    if geo.planes is None or len(rows) == 0:
        z = np.zeros(0)
        return z, z.astype(np.int64), z.astype(np.int64), z
    v, p = rows[:, 0], rows[:, 1]
    n, o = geo.planes.normals[p], geo.planes.origins[p]
    cols = free_index[3 * v[:, None] + np.arange(3)]
    usable = (cols >= 0).all(axis=1)
    c = ((x[v] - o) * n).sum(axis=1)[usable]
    local = np.repeat(np.arange(int(usable.sum())), 3)
    return c, local, cols[usable].reshape(-1), n[usable].reshape(-1)
