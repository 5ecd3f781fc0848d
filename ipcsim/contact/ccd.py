"""Collision-free step bound for a line-search step x0 -> x1 (all trajectories linear).

Broad phase on swept boxes (each box holds both positions of its primitive, grown by
``margin / 2``), then additive CCD on every PT and EE candidate (``ipcsim.kernels.ccd``).
The step α returned keeps every candidate pair apart on the whole of [0, α], with a gap of at
least ``min_gap_fraction`` times its distance at x0; pairs outside the candidate set cannot
meet during the step. α = 1.0 when there is no candidate.
"""

from __future__ import annotations

from ..kernels import ccd as _ccd
from .candidates import find_candidates


def collision_free_step(x0, x1, surface_vertices, edges, triangles, *, body_of_vertex=None,
                        self_collision=True, kinematic_vertex_mask=None,
                        min_gap_fraction=_ccd.DEFAULT_MIN_GAP_FRACTION, margin=0.0,
                        max_iterations=_ccd.DEFAULT_MAX_ITERATIONS) -> float:
    """Largest α in [0, 1] such that the step x0 -> x0 + α (x1 - x0) is collision free.

    ``surface_vertices``, ``edges`` and ``triangles`` are the collision mesh in global vertex
    numbers; ``body_of_vertex``, ``self_collision`` and ``kinematic_vertex_mask`` filter pairs as
    in :func:`ipcsim.contact.candidates.find_candidates`."""
    pt_pairs, ee_pairs = find_candidates(x0, surface_vertices, edges, triangles, margin,
                                         body_of_vertex, self_collision, kinematic_vertex_mask,
                                         x1=x1)
    if pt_pairs.shape[0] == 0 and ee_pairs.shape[0] == 0:
        return 1.0
    return _ccd.ccd_max_step(x0, x1, pt_pairs, ee_pairs, min_gap_fraction, max_iterations)
