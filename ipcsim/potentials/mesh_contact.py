"""Contact between mesh surfaces: κ Σ m·b(d², d̂²) over point–triangle and edge–edge pairs.

The sum runs over every candidate pair closer than d̂ without merging duplicates (which
equals the IPC Toolkit's merged, weighted set), each pair with its closest-feature
distance and, for edge–edge pairs, the mollifier m of nearly parallel edges (ε_x from
rest positions). Pairs that share a vertex never collide; kinematic–kinematic pairs are
dropped; with self collision off only pairs between a body and a ``meshCO`` obstacle are
kept, as in the original.

Which pairs are considered:
* ``update(x)`` (once per Newton iteration) finds the candidates at x, boxes inflated by
  d̂: these give the gradient and the Hessian at x;
* ``max_step(x, p)`` finds candidates over the swept boxes of x -> x + p inflated by d̂:
  they bound the step by CCD, and every pair within d̂ anywhere on the segment is among
  them, so the line search's energies ``value(x + αp)`` use them.
"""

from __future__ import annotations

import numpy as np

from ..contact.candidates import find_candidates
from ..kernels.ccd import DEFAULT_MAX_ITERATIONS, DEFAULT_MIN_GAP_FRACTION, ccd_max_step
from ..kernels import contact_barrier as kb
from ..kernels.broad_phase import swept_pairs_within
from ..kernels.mollifier import edge_edge_mollifier_thresholds
from .base import Triplets


class MeshContact:
    name = "mesh contact"

    def __init__(self, model, rest_positions, dhat: float):
        self.model = model
        self.surface_vertices = np.array(model.surface_vertices, dtype=np.int64)
        self.edges = np.array(model.surface_edges, dtype=np.int64).reshape(-1, 2)
        self.triangles = np.array(model.surface_triangles, dtype=np.int64).reshape(-1, 3)
        self.kinematic = np.array(model.always_kinematic, dtype=bool)
        self.self_collision = bool(model.scene.self_collision)
        body = np.array(model.vertex_shape, dtype=np.int64)
        if not self.self_collision:
            # only body–obstacle pairs: every non-obstacle shape counts as one body
            obstacle = np.array([k == "obstacle" for k in model.shape_kinds])
            body = np.where(obstacle[body], body + 1, 0)
        self.body = body
        self.rest = np.array(rest_positions, dtype=float)
        self.dhat = dhat
        self.s_hat = dhat * dhat
        self.kappa = 1.0
        self._at = None  # (x, pt, ee, ee_eps) candidates at the last update
        self._swept = None  # candidates over the last max_step's segment
        self._recent_alpha = 1.0  # CCD's α at the last iteration of this step

    # -- candidate sets ------------------------------------------------------------------
    def _candidates(self, x, x1=None):
        pt, ee = find_candidates(x, self.surface_vertices, self.edges, self.triangles,
                                 self.dhat, self.body, self.self_collision, self.kinematic,
                                 x1=x1)
        eps = edge_edge_mollifier_thresholds(self.rest, ee) if len(ee) else np.zeros(0)
        return pt, ee, eps

    def update(self, x):
        """Candidates at x (once per Newton iteration, before gradient and Hessian); kept
        while the solver keeps passing the same array."""
        if self._at is None or self._at[0] is not x:
            self._at = (x, *self._candidates(x))
        return self._at[1:]

    # -- potential -----------------------------------------------------------------------
    def value(self, x):
        pt, ee, eps = self._swept if self._swept is not None else self._candidates(x)
        return kb.barrier_value(x, pt, ee, eps, self.s_hat, self.kappa)

    def gradient(self, x):
        pt, ee, eps = self.update(x)
        return kb.barrier_gradient(x, pt, ee, eps, self.s_hat, self.kappa)

    def hessian(self, x):
        pt, ee, eps = self.update(x)
        return Triplets(*kb.barrier_hessian_triplets(x, pt, ee, eps, self.s_hat, self.kappa,
                                                     True))

    def start_step(self):
        """A new time step: forget how far CCD let the last step's iterations go."""
        self._recent_alpha = 1.0

    def max_step(self, x, p):
        """Largest α ≤ 1 such that x + αp keeps every surface pair apart (additive CCD).

        With large time steps CCD keeps cutting Newton's directions to a small α, and the
        pairs swept over the whole direction are then mostly pairs it never reaches. So CCD
        first runs over [0, β], β twice the α of this step's previous iteration. When some
        pair stops the motion inside it, that α is safe: every pair outside the shorter
        sweep stays farther apart than d̂ over [0, β]. Only otherwise is the whole direction
        swept."""
        p3 = p.reshape(-1, 3)
        beta = min(1.0, 2.0 * self._recent_alpha)
        alpha = self._ccd(x, p3, beta)
        if beta < 1.0 and alpha >= beta:
            alpha = self._ccd(x, p3, 1.0)
        self._recent_alpha = alpha
        return alpha

    def _ccd(self, x, p3, beta):
        """Safe fraction of p within [0, β]; keeps the pairs the line search must see."""
        x1 = x + beta * p3
        self._swept = self._candidates(x, x1)
        pt, ee, eps = self._swept  # swept boxes grown by d̂: a superset of CCD's candidates
        if len(pt) == 0 and len(ee) == 0:
            return beta
        alpha = beta * ccd_max_step(x, x1, pt, ee, DEFAULT_MIN_GAP_FRACTION,
                                    DEFAULT_MAX_ITERATIONS)
        if alpha < beta:
            # the line search only visits [x, x + αp]: the pairs swept over that part
            # alone are far fewer, which makes each of its energy evaluations cheaper
            xa = x + alpha * p3
            keep_pt = swept_pairs_within(x, xa, pt, 1, self.dhat)
            keep_ee = swept_pairs_within(x, xa, ee, 2, self.dhat)
            self._swept = pt[keep_pt], ee[keep_ee], eps[keep_ee]
        return alpha

    # -- statistics ----------------------------------------------------------------------
    def statistics(self, x):
        """(active PT pairs, active EE pairs, smallest distance among candidates)."""
        pt, ee, _ = self.update(x)
        _, pt_d2, _, ee_d2 = kb.classify_and_distance(x, pt, ee)
        n_pt = int(np.count_nonzero(pt_d2 < self.s_hat))
        n_ee = int(np.count_nonzero(ee_d2 < self.s_hat))
        dmin = np.sqrt(min(pt_d2.min(initial=np.inf), ee_d2.min(initial=np.inf)))
        return n_pt, n_ee, dmin
