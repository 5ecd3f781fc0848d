"""Collision-free step bounds for linear motions x -> x + αp (additive CCD).

Broad phase on swept boxes (each box holds both positions of its primitive), then
additive CCD on every point–triangle and edge–edge candidate (``ipcsim.kernels.contact.ccd``).
The α returned keeps every candidate pair apart on all of [0, α], with a gap of at least
``min_gap_fraction`` times its distance at the start; pairs outside the candidate set
cannot meet during the step.

``line_search_bound`` is what the time step's line search uses: with large time steps CCD
keeps cutting Newton's directions to a small α, and the pairs swept over the whole direction
are then mostly pairs it never reaches. So CCD first runs over [0, β], β twice the α of the
step's previous iteration. When some pair stops the motion inside it, that α is safe:
every pair outside the shorter sweep stays farther apart than d̂ over [0, β]. Only
otherwise is the whole direction swept.
"""

from __future__ import annotations

from msgspec import Struct

from ..kernels.contact import ccd as _ccd
from .candidates import find_candidates
from .collision_mesh import CollisionMesh
from .collisions import Collisions, swept_collisions

DEFAULT_MIN_GAP_FRACTION = _ccd.DEFAULT_MIN_GAP_FRACTION
DEFAULT_MAX_ITERATIONS = _ccd.DEFAULT_MAX_ITERATIONS


def collision_free_step(mesh: CollisionMesh, x0, x1, *,
                        min_gap_fraction: float = DEFAULT_MIN_GAP_FRACTION,
                        margin: float = 0.0,
                        max_iterations: int = DEFAULT_MAX_ITERATIONS) -> float:
    """Largest α in [0, 1] such that the step x0 -> x0 + α (x1 - x0) is collision free
    (candidates over swept boxes grown by ``margin``)."""
    pt_pairs, ee_pairs = find_candidates(mesh, x0, margin, x1=x1)
    if pt_pairs.shape[0] == 0 and ee_pairs.shape[0] == 0:
        return 1.0
    return _ccd.ccd_max_step(x0, x1, pt_pairs, ee_pairs, min_gap_fraction, max_iterations)


class StepBound(Struct, frozen=True, eq=False):
    """A safe step fraction along p and every pair that comes within d̂ on [x, x + αp]
    (the pairs the line search's energies must include)."""

    alpha: float
    collisions: Collisions


def line_search_bound(mesh: CollisionMesh, x, p3, dhat: float,
                      previous_alpha: float = 1.0, reach: float = 0.0) -> StepBound:
    """The CCD bound of the direction p3 (n, 3) from x: over [0, β] with β = min(1,
    2·previous_alpha) first, over [0, 1] only when nothing stops the motion inside β.
    The pairs kept are those within d̂ + 2·reach of the motion: every pair within d̂ of
    a point that lies within ``reach`` (per coordinate) of the segment."""
    beta = min(1.0, 2.0 * previous_alpha)
    bound = _sweep(mesh, x, p3, dhat, beta, reach)
    if beta < 1.0 and bound.alpha >= beta:
        bound = _sweep(mesh, x, p3, dhat, 1.0, reach)
    return bound


def _sweep(mesh, x, p3, dhat, beta, reach) -> StepBound:
    """Safe fraction of p within [0, β]; keeps the pairs the line search must see."""
    x1 = x + beta * p3
    swept = swept_collisions(mesh, x, x1, dhat + 2.0 * reach)  # a superset of CCD's
    if len(swept) == 0:
        return StepBound(beta, swept)
    alpha = beta * _ccd.ccd_max_step(x, x1, swept.pt, swept.ee, DEFAULT_MIN_GAP_FRACTION,
                                     DEFAULT_MAX_ITERATIONS)
    if alpha < beta:
        # the line search only visits [x, x + αp]: the pairs swept over that part
        # alone are far fewer, which makes each of its energy evaluations cheaper
        swept = swept.within_motion(x, x + alpha * p3, dhat + 2.0 * reach)
    return StepBound(alpha, swept)


def unbounded_step(mesh: CollisionMesh, x, p3, dhat: float,
                   reach: float = 0.0) -> StepBound:
    """No CCD (the penalty baseline): the whole step, with the pairs it sweeps (within
    d̂ + 2·reach, as in ``line_search_bound``)."""
    return StepBound(1.0, swept_collisions(mesh, x, x + p3, dhat + 2.0 * reach))
