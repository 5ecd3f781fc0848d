"""The line search of a Newton direction in one call: the feasible step along p and the
energy decrease along it (IPC, Algorithm 1: the CCD-bounded, backtracking line search).

``feasible_step`` bounds the step: the terms' own bounds (the neo-Hookean inversion bound
of tets or, in 2D, triangles, the planes' CCD), then the mesh's CCD (in 2D over its
point–edge pairs). Under large time steps CCD keeps cutting Newton's
directions to a small α, and the pairs swept over a whole direction are then mostly pairs
it never reaches; so the mesh is first swept over [0, β] with β twice the α of the
step's previous line search, and only when nothing stops the motion inside it over the
whole direction. A pair that stops the motion inside [0, β] makes that α safe: every
pair outside the shorter sweep stays farther apart than d̂ over it. The boxes are grown
by d̂ plus twice the snap reach (the prescribed vertices may be placed exactly on their
targets at the end of a direction that completes their motion, within round-off of
x + p), and the pairs swept are those the energies along the step must include.

``line_search`` then halves α until the energy decreases (once the prescribed motion is
complete; before that the largest feasible step is taken), gives up after ``halvings``
or once a step that did not lower E is within round-off of x, and lands the prescribed
vertices exactly on their targets where the whole direction is taken. The penalty
baseline has no CCD (``ccd`` False): its step is the terms' bound alone.

Arguments, besides x (n, 3) and p (n, 3):

    present, kinds, weights   which term kinds there are, each term's kind and weight
    barrier, kappa            in the potential's order, which of them κ scales, κ
    terms                     the kinds' data tuples (``all_terms``)
    mesh                      (vertices (v, 1), edges, triangles, tags, self collision,
                              rest positions, whether there is mesh contact, planar:
                              a 2D mesh, whose pairs are point–edge pairs)
    bounds                    (NH inversion bound applies, its minimum volume ratio,
                              the planes' keep fraction)
    prescribed                (kinematic (n,), targets (n, 3), motion remaining)
    sweep                     (d̂, the step's previous CCD α, CCD on, CCD gap fraction,
                              CCD iterations)
    backtrack                 (E(x) or NaN, prescribed motion complete, halvings)
"""

from __future__ import annotations

import math

import numpy as np

from ipcsim.kernels.contact.broad_phase import (candidate_pairs, point_edge_candidate_pairs,
                                                swept_pairs_within)
from ipcsim.kernels.contact.ccd import max_step
from ipcsim.kernels.contact.mollifier import edge_edge_mollifier_thresholds
from ipcsim.kernels.contact.plane_barrier import plane_ccd_max_step
from ipcsim.kernels.elasticity.tets import max_step_no_inversion
from ipcsim.kernels.elasticity.triangles import max_step_no_inversion_2d
from ipcsim.kernels.terms.all_terms import (ELASTICITY, LINE_LECTURE, N_KINDS, PLANE_CONTACT,
                                            TRIANGLES, term_values)
from ipcsim.compiler.twin import kernel


@kernel()
def weighted_energy(y, present, kinds, factors, terms, pairs):
    """(Σ factors[i]·value of term i at y, summed in the terms' order; the values by
    kind)."""
    values = term_values(y, present, terms, pairs)
    total = 0.0
    for i in range(kinds.shape[0]):
        total += factors[i] * values[kinds[i]]
    return total, values


@kernel()
def snap_reach(x, kinematic, target):
    """How far (per coordinate) landing the prescribed vertices on their targets may put
    one from x + p: with p = fl(t − x), |fl(x + p) − t| ≤ 2u(|t| + |x|) + O(u²), u = ε/2;
    four times that, over the largest coordinates (0 without prescribed vertices)."""
    scale = 0.0
    found = False
    for i in range(x.shape[0]):
        if kinematic[i]:
            found = True
            for a in range(3):
                scale = max(scale, abs(x[i, a]), abs(target[i, a]))
    return 4.0 * np.finfo(np.float64).eps * scale if found else 0.0


@kernel()
def _sweep(x, p3, beta, mesh, inflation, ccd, gap_fraction, ccd_iterations):
    """(the safe α within [0, β], pt, ee, ε_x, pt ids, ee ids): the pairs whose boxes,
    grown by ``inflation``, meet along [x, x + βp], narrowed to [x, x + αp] when CCD stops
    the motion at α < β. Ids are unique in the mesh: point·n_triangles + triangle,
    edge_a·n_edges + edge_b (2D: point–edge pairs as pt, point·n_edges + edge)."""
    vertices, edges, triangles, tags, self_collision, rest = (mesh[0], mesh[1], mesh[2],
                                                              mesh[3], mesh[4], mesh[5])
    x1 = x + beta * p3
    if mesh[7]:  # 2D: point–edge pairs in pt's place, ids point·n_edges + edge
        pt, pe_index = point_edge_candidate_pairs(x, x1, vertices, edges, (tags[0], tags[1]),
                                                  inflation, self_collision)
        pt_id = pe_index[:, 0] * edges.shape[0] + pe_index[:, 1]
        ee, ee_id, eps_x = np.zeros((0, 4), np.int64), np.zeros(0, np.int64), np.zeros(0)
    else:
        pt, ee, pt_index, ee_index = candidate_pairs(x, x1, vertices, edges, triangles, tags,
                                                     inflation, self_collision)
        eps_x = edge_edge_mollifier_thresholds(rest, ee) if ee.shape[0] > 0 else np.zeros(0)
        pt_id = pt_index[:, 0] * triangles.shape[0] + pt_index[:, 1]
        ee_id = ee_index[:, 0] * edges.shape[0] + ee_index[:, 1]
    if not ccd or pt.shape[0] + ee.shape[0] == 0:
        return beta, pt, ee, eps_x, pt_id, ee_id
    if mesh[7]:
        alpha = beta * max_step(x, x1, pt, 0, gap_fraction, ccd_iterations)
    else:
        stencils = np.empty((pt.shape[0] + ee.shape[0], 4), dtype=np.int64)
        stencils[:pt.shape[0]] = pt
        stencils[pt.shape[0]:] = ee
        alpha = beta * max_step(x, x1, stencils, pt.shape[0], gap_fraction, ccd_iterations)
    if alpha < beta:
        # the line search only visits [x, x + αp]: the pairs swept over that part alone
        # are far fewer, which makes each of its energy evaluations cheaper
        x_alpha = x + alpha * p3
        keep_pt = swept_pairs_within(x, x_alpha, pt, 1, inflation)
        keep_ee = swept_pairs_within(x, x_alpha, ee, 2, inflation)
        return alpha, pt[keep_pt], ee[keep_ee], eps_x[keep_ee], pt_id[keep_pt], ee_id[keep_ee]
    return alpha, pt, ee, eps_x, pt_id, ee_id


@kernel()
def feasible_step(x, p3, present, terms, mesh, bounds, prescribed, sweep):
    """(α, mesh CCD's α, the pairs swept: pt, ee, ε_x, pt ids, ee ids): the largest step
    fraction that keeps x + αp free of intersections and inversions (module docstring)."""
    dhat, previous_alpha, ccd, gap_fraction, ccd_iterations = (sweep[0], sweep[1], sweep[2],
                                                               sweep[3], sweep[4])
    alpha = 1.0
    elastic, plane = terms[ELASTICITY], terms[PLANE_CONTACT]
    if present[ELASTICITY] and bounds[0] and elastic[0].shape[0] > 0:
        alpha = min(alpha, max_step_no_inversion(x, p3, elastic[0], bounds[1]))
    triangles = terms[TRIANGLES]
    if present[TRIANGLES] and bounds[0] and triangles[0].shape[0] > 0:
        alpha = min(alpha, max_step_no_inversion_2d(x, p3, triangles[0], bounds[1]))
    if present[PLANE_CONTACT]:
        alpha = min(alpha, plane_ccd_max_step(x, p3.reshape(-1), plane[0], plane[1],
                                              plane[2], bounds[2]))
    if present[LINE_LECTURE]:
        line = terms[LINE_LECTURE]
        alpha = min(alpha, plane_ccd_max_step(x, p3.reshape(-1), line[0], line[1], line[2],
                                              bounds[2]))
    ccd_alpha = 1.0
    pt, ee, eps_x = np.zeros((0, 4), np.int64), np.zeros((0, 4), np.int64), np.zeros(0)
    pt_id, ee_id = np.zeros(0, np.int64), np.zeros(0, np.int64)
    if mesh[6]:
        inflation = dhat + 2.0 * snap_reach(x, prescribed[0], prescribed[1])
        beta = min(1.0, 2.0 * previous_alpha) if ccd else 1.0
        ccd_alpha, pt, ee, eps_x, pt_id, ee_id = _sweep(x, p3, beta, mesh, inflation, ccd,
                                                        gap_fraction, ccd_iterations)
        if beta < 1.0 and ccd_alpha >= beta:
            ccd_alpha, pt, ee, eps_x, pt_id, ee_id = _sweep(x, p3, 1.0, mesh, inflation, ccd,
                                                            gap_fraction, ccd_iterations)
        alpha = min(alpha, ccd_alpha)
    return alpha, ccd_alpha, pt, ee, eps_x, pt_id, ee_id


@kernel()
def _backtracked(x, p3, alpha, present, kinds, factors, terms, pairs, e0, halvings):
    """(α, failed, E at the point kept, E(x), the values by kind there): α halved until
    E(x + αp) < E(x), giving up after ``halvings`` or once a step that did not lower E is
    within round-off of x (‖αp‖∞ ≤ ε·max|x|). Equal energies count as no progress: they
    only occur once E has reached round-off."""
    values = np.full(N_KINDS, np.nan)
    if math.isnan(e0):
        e0, values = weighted_energy(x + 0.0 * p3, present, kinds, factors, terms, pairs)
    values_at_x = values
    if not np.isfinite(e0):
        return alpha, False, e0, e0, values
    p_max = 0.0
    for v in p3.reshape(-1):
        p_max = max(p_max, abs(v))
    x_max = 0.0
    for v in x.reshape(-1):
        x_max = max(x_max, abs(v))
    for _ in range(halvings):
        e, values = weighted_energy(x + alpha * p3, present, kinds, factors, terms, pairs)
        if e < e0:  # a finite e0 and e < e0: e is finite too
            return alpha, False, e, e0, values
        if alpha * p_max <= np.finfo(np.float64).eps * x_max:
            break  # shorter steps only move x by less than its own round-off
        alpha *= 0.5
    return 0.0, True, e0, e0, values_at_x


@kernel()
def line_search(x, p3, present, weighing, kappa, terms, mesh, bounds, prescribed, sweep,
                backtrack):
    """(x_new, α, E(x_new), failed, E(x), CCD's α, the terms' values by kind at the point
    returned (NaN where not evaluated here), the swept pairs: pt, ee, ε_x, pt ids, ee ids).
    On failure x_new is x and E(x_new) is E(x); where α is NaN (a bound saw a non-finite
    input) nothing else is evaluated."""
    kinds, weights, barrier = weighing[0], weighing[1], weighing[2]
    e0, complete, halvings = backtrack[0], backtrack[1], backtrack[2]
    factors = np.empty(kinds.shape[0])
    for i in range(kinds.shape[0]):  # ``WeightedTerm.factor``
        factors[i] = weights[i] * kappa if barrier[i] else weights[i]
    alpha, ccd_alpha, pt, ee, eps_x, pt_id, ee_id = feasible_step(x, p3, present, terms, mesh,
                                                                  bounds, prescribed, sweep)
    pairs = (pt, ee, eps_x, pt.shape[0] + ee.shape[0] > 0)
    energy = math.nan
    values = np.full(present.shape[0], np.nan)
    if not alpha >= 0.0:
        return x, alpha, energy, False, e0, ccd_alpha, values, pt, ee, eps_x, pt_id, ee_id
    failed = False
    if complete:
        alpha, failed, energy, e0, values = _backtracked(x, p3, alpha, present, kinds,
                                                         factors, terms, pairs, e0, halvings)
        if failed or not np.isfinite(e0):
            return x, alpha, energy, failed, e0, ccd_alpha, values, pt, ee, eps_x, pt_id, ee_id
    kinematic, target, remaining = prescribed[0], prescribed[1], prescribed[2]
    x_new = x + alpha * p3
    if alpha == 1.0 and remaining > 0.0:  # land exactly on the targets
        for i in range(x.shape[0]):
            if kinematic[i]:
                for a in range(3):
                    x_new[i, a] = target[i, a]
    if not complete:
        energy, values = weighted_energy(x_new, present, kinds, factors, terms, pairs)
    return x_new, alpha, energy, failed, e0, ccd_alpha, values, pt, ee, eps_x, pt_id, ee_id
