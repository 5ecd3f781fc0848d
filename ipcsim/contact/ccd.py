"""Collision-free step bounds for linear motions x -> x + αp (additive CCD).

Broad phase on swept boxes (each box holds both positions of its primitive), then
additive CCD on every point–triangle and edge–edge candidate (``ipcsim.kernels.contact.ccd``).
The α returned keeps every candidate pair apart on all of [0, α], with a gap of at least
``min_gap_fraction`` times its distance at the start; pairs outside the candidate set
cannot meet during the step.

The time step's line search bounds its steps with the same CCD inside one kernel call
(``kernels/terms/line_search.py``); ``collision_free_step`` is the bound of one motion
on its own (checks, benchmarks).
"""

from __future__ import annotations


from ..kernels.contact import ccd as _ccd
from .candidates import find_candidates
from .collision_mesh import CollisionMesh

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
