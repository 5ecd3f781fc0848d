"""A small scene's line search in one call: the feasible step along a Newton direction
and the energy decrease along it, as ``potentials/objective.py`` (``max_step``,
``LineSearch``), ``contact/ccd.py`` (``line_search_bound``) and ``solver/newton.py``
(``_line_search``, ``_backtrack``) take them, step by step and in the same order, with
the same kernels, so the results are theirs bit for bit.

One Newton iteration of a tutorial scene made a dozen calls from Python for this (the
terms' bounds, the broad phase, CCD, the pair filter, an energy per trial step), whose
own cost was most of the line search's. Arguments, besides x (n, 3) and p (n, 3):

    present, kinds, weights   which term kinds there are, each term's kind and weight
    barrier, kappa            in the potential's order, which of them κ scales, κ
    terms                     the eight kinds' data tuples (``fused_terms``); the mesh
                              contact's pairs are the ones swept here
    mesh                      (vertices (v, 1), edges, triangles, tags, self collision,
                              rest positions, whether there is mesh contact)
    bounds                    (NH inversion bound applies, its minimum volume ratio,
                              the planes' keep fraction)
    prescribed                (kinematic (n,), targets (n, 3), motion remaining)
    search                    (d̂, the step's previous CCD α, E(x) or NaN, prescribed
                              motion complete, halvings, CCD gap fraction, CCD
                              iterations)

Returns (x_new, α, E(x_new), failed, E(x), CCD's α, the terms' values by kind at the
point returned (NaN where it was not evaluated here), the swept pairs pt, ee, ε_x and
their ids, ``contact.collisions.pair_ids``).
"""

from __future__ import annotations

import math

import numpy as np

from ipcsim.kernels.contact.broad_phase import candidate_pairs, swept_pairs_within
from ipcsim.kernels.contact.ccd import max_step_serial
from ipcsim.kernels.elasticity.tets import max_step_no_inversion
from ipcsim.kernels.terms.all_terms import ELASTICITY, MESH_CONTACT, N_KINDS, PLANE_CONTACT, term_values
from ipcsim.kernels.contact.mollifier import edge_edge_mollifier_thresholds
from ipcsim.kernels.contact.plane_barrier import plane_ccd_max_step
from ipcsim.compiler.twin import kernel


@kernel()
def _energy(y, present, kinds, factors, terms):
    """(Σ factors[i]·value of term i at y, summed in the terms' order as
    ``IncrementalPotential.value`` sums it; the values by kind)."""
    values = term_values(y, present, terms[0], terms[1], terms[2], terms[3], terms[4],
                         terms[5], terms[6], terms[7])
    total = 0.0
    for i in range(kinds.shape[0]):
        total += factors[i] * values[kinds[i]]
    return total, values


@kernel()
def _sweep(x, p3, beta, mesh, inflation, gap_fraction, ccd_iterations):
    """``contact.ccd._sweep``: (α, pt, ee, ε_x, pt ids, ee ids)."""
    vertices, edges, triangles, tags, self_collision, rest = (mesh[0], mesh[1], mesh[2],
                                                              mesh[3], mesh[4], mesh[5])
    x1 = x + beta * p3
    pt, ee, pt_index, ee_index = candidate_pairs(x, x1, vertices, edges, triangles, tags,
                                                 inflation, self_collision)
    eps_x = edge_edge_mollifier_thresholds(rest, ee) if ee.shape[0] > 0 else np.zeros(0)
    # one id per pair, unique in the mesh (``contact.collisions.pair_ids``)
    pt_id = pt_index[:, 0] * triangles.shape[0] + pt_index[:, 1]
    ee_id = ee_index[:, 0] * edges.shape[0] + ee_index[:, 1]
    if pt.shape[0] + ee.shape[0] == 0:
        return beta, pt, ee, eps_x, pt_id, ee_id
    stencils = np.empty((pt.shape[0] + ee.shape[0], 4), dtype=np.int64)
    stencils[:pt.shape[0]] = pt
    stencils[pt.shape[0]:] = ee
    alpha = beta * max_step_serial(x, x1, stencils, pt.shape[0], gap_fraction,
                                    ccd_iterations)
    if alpha < beta:
        x_alpha = x + alpha * p3
        keep_pt = swept_pairs_within(x, x_alpha, pt, 1, inflation)
        keep_ee = swept_pairs_within(x, x_alpha, ee, 2, inflation)
        return alpha, pt[keep_pt], ee[keep_ee], eps_x[keep_ee], pt_id[keep_pt], ee_id[keep_ee]
    return alpha, pt, ee, eps_x, pt_id, ee_id


@kernel()
def _snap_reach(x, kinematic, target):
    """``objective.snap_reach`` of the prescribed vertices."""
    scale = 0.0
    found = False
    for i in range(x.shape[0]):
        if kinematic[i]:
            found = True
            for a in range(3):
                scale = max(scale, abs(x[i, a]), abs(target[i, a]))
    return 4.0 * np.finfo(np.float64).eps * scale if found else 0.0


@kernel()
def line_search(x, p3, present, kinds, weights, barrier, kappa, terms, mesh, bounds,
                prescribed, search):
    dhat, previous_alpha, e0, complete, halvings, gap_fraction, ccd_iterations = (
        search[0], search[1], search[2], search[3], search[4], search[5], search[6])
    factors = np.empty(kinds.shape[0])
    for i in range(kinds.shape[0]):  # ``WeightedTerm.factor``
        factors[i] = weights[i] * kappa if barrier[i] else weights[i]
    # the terms' own bounds, in the terms' order (``IncrementalPotential.max_step``)
    alpha = 1.0
    elastic, plane = terms[ELASTICITY], terms[PLANE_CONTACT]
    if present[ELASTICITY] and bounds[0] and elastic[0].shape[0] > 0:
        b = max_step_no_inversion(x, p3, elastic[0], bounds[1])
        if b < alpha:
            alpha = b
    if present[PLANE_CONTACT]:
        b = plane_ccd_max_step(x, p3.reshape(-1), plane[0], plane[1], plane[2], bounds[2])
        if b < alpha:
            alpha = b
    # mesh contact: CCD over [0, β] first, the whole direction only if nothing stops it
    kinematic, target, remaining = prescribed[0], prescribed[1], prescribed[2]
    ccd_alpha = 1.0
    pt, ee, eps_x = np.zeros((0, 4), np.int64), np.zeros((0, 4), np.int64), np.zeros(0)
    pt_id, ee_id = np.zeros(0, np.int64), np.zeros(0, np.int64)
    if mesh[6]:
        inflation = dhat + 2.0 * _snap_reach(x, kinematic, target)
        beta = min(1.0, 2.0 * previous_alpha)
        ccd_alpha, pt, ee, eps_x, pt_id, ee_id = _sweep(x, p3, beta, mesh, inflation,
                                                        gap_fraction, ccd_iterations)
        if beta < 1.0 and ccd_alpha >= beta:
            ccd_alpha, pt, ee, eps_x, pt_id, ee_id = _sweep(x, p3, 1.0, mesh, inflation,
                                                            gap_fraction, ccd_iterations)
        if ccd_alpha < alpha:
            alpha = ccd_alpha
    m = terms[MESH_CONTACT]
    swept = (terms[0], terms[1], terms[2], terms[3], terms[4],
             (pt, ee, eps_x, m[3], pt.shape[0] + ee.shape[0] > 0), terms[6], terms[7])
    failed = False
    energy = math.nan
    values = np.full(N_KINDS, np.nan)  # the terms' values at the point taken, if known
    if not alpha >= 0.0:  # NaN: the caller names the term
        return x, alpha, energy, failed, e0, ccd_alpha, values, pt, ee, eps_x, pt_id, ee_id
    if complete:
        # halve α until E decreases (``NewtonSolver._backtrack``)
        if math.isnan(e0):
            e0, values = _energy(x + 0.0 * p3, present, kinds, factors, swept)
        if not np.isfinite(e0):
            return x, alpha, e0, failed, e0, ccd_alpha, values, pt, ee, eps_x, pt_id, ee_id
        values_at_x = values
        p_max = 0.0
        for v in p3.reshape(-1):
            p_max = max(p_max, abs(v))
        x_max = 0.0
        for v in x.reshape(-1):
            x_max = max(x_max, abs(v))
        failed = True
        for _ in range(halvings):
            e, values = _energy(x + alpha * p3, present, kinds, factors, swept)
            if e < e0:
                failed = False
                energy = e
                break
            if alpha * p_max <= np.finfo(np.float64).eps * x_max:
                break  # ``LineSearch.below_roundoff``
            alpha *= 0.5
        if failed:
            return (x, 0.0, e0, failed, e0, ccd_alpha, values_at_x, pt, ee, eps_x, pt_id,
                    ee_id)
    x_new = x + alpha * p3
    if alpha == 1.0 and remaining > 0.0:  # land exactly on the targets
        x_new = x + p3
        for i in range(x.shape[0]):
            if kinematic[i]:
                for a in range(3):
                    x_new[i, a] = target[i, a]
    if not complete:
        energy, values = _energy(x_new, present, kinds, factors, swept)
    return x_new, alpha, energy, failed, e0, ccd_alpha, values, pt, ee, eps_x, pt_id, ee_id


assert N_KINDS == 8  # the tuples above list the kinds one by one
