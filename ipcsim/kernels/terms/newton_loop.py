"""A small scene's Newton iterations in one call: ``solver/newton.py``'s loop, step by
step and in the same order, over the fused terms (``fused_terms.py``), the fused line
search (``fused_line_search.py``) and a dense Cholesky factor (``linalg.py``), so that
its iterates, κ and rows are the Python loop's bit for bit.

On a tutorial scene the kernels of one Newton iteration compute for about 150 µs; the
Python around their dozen calls (the evaluation, κ, the system, the direction, the row)
took more than twice that. Each step below names the function it mirrors.

Arguments, besides x (n, 3), the first iteration's number and the cap:

    present, kinds, weights, barrier   the fused potential (``fused_line_search.line_search``)
    terms, mesh, bounds                as there; the mesh contact's pairs are set here
    dofs          (prescribed DOFs (3n,), free DOFs (3n,), free number of each DOF, n free)
    prescribed    (kinematic (n,), targets (n, 3), motion remaining at the solve's start,
                  whether a pull of prescribed vertices is under way)
    collisions    the collision set at x (pt, ee, ε_x, pt ids, ee ids, pt types, pt d²,
                  ee types, ee d²); the sets after a line search are narrowed from it
    planes        (vertices, origins, normals) of the contact planes, and whether there are
    stiffness     (κ, κ_min, κ_max, (dTol·l)², adaptive, balanced, last d²)
    ramp          friction's stopping test: (body of each vertex, ε_v h, resolution)
    state         (E(x) or NaN, previous CCD α, smallest α, prescribed motion complete)
    settings      (tol, halvings, kinematic completion, d̂, CCD gap fraction, CCD
                   iterations)
    pullable      (whether a pull may start, the vertices it may take (n,), xₙ (n, 3),
                   the completion that ends a pull)

It stops, and says why (``status``), where Python takes over: converged, the line
search gave up, the iteration cap, after the first iteration when the prescribed
vertices may need a pull and after every iteration while one is under way
(``StepObjective.follow_up`` starts, tightens or ends it), or at the start of an
iteration that would raise (a non-finite value, a matrix Cholesky refuses): Python does
that iteration again and names the culprit.
"""

from __future__ import annotations

import math

import numpy as np

from ipcsim.kernels.contact.pair_barrier import near_pairs
from ipcsim.kernels.contact.friction import ramp_unresolved
from ipcsim.kernels.terms.line_search import line_search
from ipcsim.kernels.terms.all_terms import (FRICTION, MESH_CONTACT, N_KINDS, add_term_hessians_dense,
                          term_gradients, term_values)
from ipcsim.kernels.contact.barrier import balanced_stiffness, stiffness_doubles
from ipcsim.kernels.algebra.linalg import cholesky_in_place, cholesky_solve, dot
from ipcsim.kernels.contact.plane_barrier import plane_active_count_and_min_distance
from ipcsim.compiler.twin import kernel

CONVERGED, LINE_SEARCH_FAILED, ITERATION_CAP, FOLLOW_UP, HAND_BACK = 0, 1, 2, 3, 4
ROW_COLUMNS = 8  # iteration, ‖p‖∞, tol, ‖g_free‖, κ, residual ratio, α, E
CONTACT_COLUMNS = 5  # plane, point–triangle, edge–edge, smallest distance, total


@kernel()
def _with_pairs(terms, pt, ee, eps_x, active):
    """The terms with these mesh contact pairs (``FusedTerms._data``'s MESH_CONTACT)."""
    m = terms[MESH_CONTACT]
    return (terms[0], terms[1], terms[2], terms[3], terms[4], (pt, ee, eps_x, m[3], active),
            terms[6], terms[7])


@kernel()
def _smallest_d2(pt_d2, ee_d2):
    """The pairs' smallest squared distance, inf without pairs (``Collisions._min_d2``)."""
    return min(pt_d2.min() if pt_d2.shape[0] else np.inf,
               ee_d2.min() if ee_d2.shape[0] else np.inf)


@kernel()
def _count(x, planes, has_mesh, pt_d2, ee_d2, min_d2, s_hat):
    """``ContactSetup.count``: (plane, point–triangle, edge–edge, smallest distance);
    ``min_d2`` the pairs' smallest squared distance."""
    plane, dmin = 0, np.inf
    if planes[3]:
        plane, dmin = plane_active_count_and_min_distance(x, planes[0], planes[1], planes[2],
                                                          s_hat)
    n_pt = n_ee = 0
    if has_mesh:
        n_pt = int(np.count_nonzero(pt_d2 < s_hat))
        n_ee = int(np.count_nonzero(ee_d2 < s_hat))
        dmin = min(dmin, np.sqrt(min_d2))
    return plane, n_pt, n_ee, dmin


@kernel()
def _may_pull(x, kinematic, target, pullable):
    """Whether ``StepObjective._start_pull`` might start a pull at x: the completion of
    the prescribed motion of the vertices it may take (``BoundaryPull.completion``) is
    below the one that ends a pull, or within round-off of it (Python then decides: its
    sums are numpy's)."""
    may, start, done = pullable[1], pullable[2], pullable[3]
    total = 0.0
    offset = 0.0
    found = False
    for i in range(x.shape[0]):
        if kinematic[i] and may[i]:
            found = True
            for a in range(3):
                total += (target[i, a] - start[i, a]) ** 2
                offset += (x[i, a] - target[i, a]) ** 2
    if not found or total == 0.0:
        return False
    return 1.0 - np.sqrt(offset / total) < done + 1e-9


@kernel()
def _kappa(gradients, kinds, weights, barrier, free, contacts, dmin, kappa, balanced,
           last_d2, stiffness):
    """(κ, balanced) at an iterate with ``contacts`` active pairs, the closest at dmin
    (``StepObjective._adapt_stiffness``, ``BarrierStiffness.at_iterate``)."""
    kappa_min, kappa_max, eps_sq = stiffness[1], stiffness[2], stiffness[3]
    if contacts > 0 and not balanced:
        n3 = gradients.shape[1]
        g_barrier = np.zeros(n3)  # ``TermValues.split_gradient``
        g_rest = np.zeros(n3)
        for i in range(kinds.shape[0]):
            for j in range(n3):
                if barrier[i]:
                    g_barrier[j] += weights[i] * gradients[kinds[i], j]
                else:
                    g_rest[j] += weights[i] * gradients[kinds[i], j]
        kappa = balanced_stiffness(g_barrier[free], g_rest[free], kappa_min, kappa_max)
        balanced = True
    if stiffness_doubles(last_d2, dmin * dmin, eps_sq):
        kappa = min(kappa_max, 2.0 * kappa)
    return kappa, balanced


@kernel()
def _weighted(gradients, kinds, weights, barrier, kappa):
    """(each term's factor, ∇E) at κ (``WeightedTerm.factor``, ``TermValues.gradient``)."""
    factors = np.empty(kinds.shape[0])
    for i in range(kinds.shape[0]):
        factors[i] = weights[i] * kappa if barrier[i] else weights[i]
    g = np.zeros(gradients.shape[1])
    for i in range(kinds.shape[0]):
        for j in range(g.shape[0]):
            g[j] += factors[i] * gradients[kinds[i], j]
    return factors, g


@kernel()
def _direction(x, g, present, kinds, factors, at_x, dofs, target_flat, motion, completion,
               tol):
    """(solved, p (3n,), the prescribed motion remaining): the prescribed part of p and
    the dense system's solution (``NewtonSolver._system``, ``_direction``); not solved
    where Cholesky refuses the matrix or p is not finite (Python raises)."""
    prescribed_dofs, free, free_index, n_free = dofs[0], dofs[1], dofs[2], dofs[3]
    n3 = g.shape[0]
    p = np.zeros(n3)
    x_flat = x.reshape(-1)
    remaining = 0.0
    for j in range(n3):
        if prescribed_dofs[j]:
            p[j] = target_flat[j] - x_flat[j]
            remaining = max(remaining, abs(p[j]))
    if remaining <= completion * motion:
        for j in range(n3):
            if prescribed_dofs[j]:
                p[j] = 0.0  # done: stop pushing the last 0.1 %
        remaining = 0.0
    by_kind = np.zeros(N_KINDS)  # ``FusedTerms.hessian``
    for i in range(kinds.shape[0]):
        by_kind[kinds[i]] = factors[i]
    A = np.zeros((n_free, n_free))  # ``DenseAssembler.assemble``
    coupling = np.zeros(n_free)
    add_term_hessians_dense(A, coupling, x, present, by_kind, free_index, p, at_x[0],
                            at_x[2], at_x[3], at_x[4], at_x[5], at_x[6], at_x[7])
    if n_free == 0:
        return np.isfinite(p).all(), p, remaining
    rhs = np.empty(n_free)
    for j in range(n3):
        if free[j]:
            rhs[free_index[j]] = -g[j] - coupling[free_index[j]]
    if not cholesky_in_place(A):
        return False, p, remaining
    p_free = np.empty(n_free)
    cholesky_solve(A, rhs, p_free)
    if not np.isfinite(p_free).all():
        return False, p, remaining
    largest = 0.0
    for j in range(n3):
        if free[j]:
            p[j] = p_free[free_index[j]]
            largest = max(largest, abs(p[j]))
    if not np.isfinite(p).all():
        return False, p, remaining
    if remaining > 0.0 and largest < tol:
        # free DOFs converged, motion left: follow it with H_ff p_f = −H_fk p_k
        cholesky_solve(A, -coupling, p_free)
        if not np.isfinite(p_free).all():
            return False, p, remaining
        for j in range(n3):
            if free[j]:
                p[j] = p_free[free_index[j]]
    return True, p, remaining


@kernel()
def _stops(x, p3, g, free, tol, complete, present, friction, ramp):
    """(converged, ‖p_free‖∞, ‖g_free‖): ``NewtonSolver.solve``'s stopping rule, with
    friction's static ramp (``Friction.resolved``)."""
    p = p3.reshape(-1)
    step_norm = 0.0
    for j in range(p.shape[0]):
        if free[j]:
            step_norm = max(step_norm, abs(p[j]))
    g_free = g[free]
    converged = complete and step_norm < tol
    if converged and present[FRICTION] and friction[1].shape[0] > 0:
        converged = not ramp_unresolved(x - friction[0], p3, friction[1], friction[2],
                                        friction[3], friction[4], ramp[0], ramp[1], ramp[2])
    return converged, step_norm, np.sqrt(dot(g_free, g_free))


@kernel()
def _energy(x, present, at_x, kinds, factors):
    """E(x) from the terms' values (``TermValues.energy``)."""
    values = term_values(x, present, at_x[0], at_x[1], at_x[2], at_x[3], at_x[4], at_x[5],
                         at_x[6], at_x[7])
    energy = 0.0
    for i in range(kinds.shape[0]):
        energy += factors[i] * values[kinds[i]]
    return energy


@kernel()
def _evaluate(x, pairs, planes, has_mesh, dhat, present, terms):
    """(the contacts at x: plane, point–triangle, edge–edge, smallest distance; the terms
    with the pairs at x; each term's gradient) (``StepObjective.evaluate``)."""
    pt, ee, eps_x, pt_d2, ee_d2 = pairs[0], pairs[1], pairs[2], pairs[6], pairs[8]
    s_hat = dhat * dhat
    min_d2 = _smallest_d2(pt_d2, ee_d2)
    counts = _count(x, planes, has_mesh, pt_d2, ee_d2, min_d2, s_hat)
    active = has_mesh and min_d2 < s_hat  # ``Collisions.may_be_active``
    at_x = _with_pairs(terms, pt, ee, eps_x, active)
    gradients = term_gradients(x, present, at_x[0], at_x[1], at_x[2], at_x[3], at_x[4],
                               at_x[5], at_x[6], at_x[7])
    return counts, at_x, gradients


@kernel()
def _search(x, p3, present, kinds, weights, barrier, kappa, at_x, mesh, bounds, kinematic,
            target, remaining, ccd_alpha, known, settings):
    """``NewtonSolver._line_search`` with ``StepObjective.line_search``: the fused line
    search's result, and whether ``NewtonSolver._checked`` would raise on it."""
    complete = remaining == 0.0
    out = line_search(x, p3, present, kinds, weights, barrier, kappa, at_x, mesh, bounds,
                      (kinematic, target, remaining),
                      (settings[3], ccd_alpha, known, complete, settings[1], settings[4],
                       settings[5]))
    alpha, energy, e0 = out[1], out[2], out[4]
    raises = not alpha >= 0.0 or (complete and not np.isfinite(e0)) or (
        not complete and not np.isfinite(energy))
    return raises, out


@kernel()
def _where_it_ends(x, x_evaluated, pairs, swept, planes, has_mesh, dhat):
    """(the collision set at x, the contacts there), as ``StepObjective.collisions`` and
    ``ContactSetup.count`` find them for Newton's final evaluation (or the row before the
    next call): the set of the x last evaluated where x is that point, else the one
    narrowed from the pairs swept to x."""
    moved = False
    for i in range(x.shape[0]):
        for a in range(3):
            moved = moved or not x[i, a] == x_evaluated[i, a]  # as np.array_equal: NaN moved
    if has_mesh and moved:
        pairs = near_pairs(x, swept[0], swept[1], swept[2], swept[3], swept[4], dhat)
    pt_d2, ee_d2 = pairs[6], pairs[8]
    return pairs, _count(x, planes, has_mesh, pt_d2, ee_d2, _smallest_d2(pt_d2, ee_d2),
                         dhat * dhat)


@kernel()
def _end_row_at(contacts, row, counts):
    """Row ``row`` ended at an iterate with these contacts (and their total)."""
    contacts[row, 0] = counts[0]
    contacts[row, 1] = counts[1]
    contacts[row, 2] = counts[2]
    contacts[row, 3] = counts[3]
    contacts[row, 4] = counts[0] + counts[1] + counts[2]


@kernel()
def _record(rows, contacts, done, values):
    """The row arrays with ``values`` as row ``done`` (grown when full)."""
    if done >= rows.shape[0]:
        bigger = np.full((2 * done, ROW_COLUMNS), np.nan)
        bigger[:done] = rows
        more = np.full((2 * done, CONTACT_COLUMNS), np.nan)
        more[:done] = contacts
        rows, contacts = bigger, more
    rows[done, 0], rows[done, 1], rows[done, 2], rows[done, 3] = (values[0], values[1],
                                                                  values[2], values[3])
    rows[done, 4], rows[done, 5], rows[done, 6], rows[done, 7] = (values[4], values[5],
                                                                  values[6], values[7])
    return rows, contacts


@kernel()
def newton_iterations(x, first, cap, present, kinds, weights, barrier, terms, mesh, bounds,
                      dofs, prescribed, collisions, planes, stiffness, ramp, state, settings,
                      pullable):
    kinematic, target, pulling = prescribed[0], prescribed[1], prescribed[3]
    pairs = collisions  # the collision set at x
    kappa, balanced, last_d2 = stiffness[0], stiffness[5], stiffness[6]
    energy, ccd_alpha, min_alpha, complete = state[0], state[1], state[2], state[3]
    tol, dhat, has_mesh = settings[0], settings[3], mesh[6]
    rows, contacts = np.full((8, ROW_COLUMNS), np.nan), np.full((8, CONTACT_COLUMNS), np.nan)
    swept = (pairs[0], pairs[1], pairs[2], pairs[3], pairs[4])  # the last line search's
    values = np.full(N_KINDS, np.nan)  # the terms' values the last line search gave, at x
    values_kappa = kappa  # the κ in force then
    x_evaluated, p = x, np.zeros(3 * x.shape[0])
    status, it, done = ITERATION_CAP, first, 0
    while it < cap:
        if it > first and has_mesh:  # ``narrowed_collisions`` from the swept pairs
            pairs = near_pairs(x, swept[0], swept[1], swept[2], swept[3], swept[4], dhat)
        x_evaluated = x
        counts, at_x, gradients = _evaluate(x, pairs, planes, has_mesh, dhat, present, terms)
        total = counts[0] + counts[1] + counts[2]
        if done > 0:  # ``NewtonSolver._complete_last_row``
            _end_row_at(contacts, done - 1, counts)
        new_kappa, new_balanced = (_kappa(gradients, kinds, weights, barrier, dofs[1], total,
                                          counts[3], kappa, balanced, last_d2, stiffness)
                                   if stiffness[4] else (kappa, balanced))  # adaptive κ
        factors, g = _weighted(gradients, kinds, weights, barrier, new_kappa)
        if not np.isfinite(g).all():
            status = HAND_BACK
            break
        known = energy if new_kappa == kappa else math.nan  # else summed again at the new κ
        solved, p, remaining = _direction(x, g, present, kinds, factors, at_x, dofs,
                                          target.reshape(-1), prescribed[2], settings[2], tol)
        if not solved:
            status = HAND_BACK  # Python raises the solver's error
            break
        p3 = p.reshape(x.shape)
        # a step converges with its prescribed motion done and no pull under way
        converged, step_norm, g_norm = _stops(x, p3, g, dofs[1], tol, remaining == 0.0
                                              and not pulling, present, terms[FRICTION], ramp)
        alpha, failed, x_new, new_swept = 0.0, False, x, swept
        searched = not (converged and step_norm == 0.0)  # else: nothing left to do
        if searched:
            raises, out = _search(x, p3, present, kinds, weights, barrier, new_kappa, at_x,
                                  mesh, bounds, kinematic, target, remaining, ccd_alpha,
                                  known, settings)
            if raises:
                status = HAND_BACK
                break
            alpha, row_energy, failed = out[1], out[2], out[3]
            if not math.isnan(out[6][kinds[0]]):
                values, values_kappa = out[6], new_kappa
            if has_mesh:
                ccd_alpha = out[5]
            if not failed:
                x_new, new_swept = out[0], (out[7], out[8], out[9], out[10], out[11])
        else:
            row_energy = known if not math.isnan(known) else _energy(x, present, at_x,
                                                                     kinds, factors)
        rows, contacts = _record(rows, contacts, done, (
            it, step_norm, tol, g_norm, new_kappa, step_norm / tol if tol > 0 else np.nan,
            alpha, row_energy))
        done, it = done + 1, it + 1
        kappa, balanced, energy = new_kappa, new_balanced, row_energy
        complete = remaining == 0.0
        last_d2 = counts[3] * counts[3] if stiffness[4] else last_d2
        if failed:
            status = LINE_SEARCH_FAILED
            break
        x, swept = x_new, new_swept
        min_alpha = min(min_alpha, alpha) if searched else min_alpha
        if converged:
            status = CONVERGED
            break
        if pulling or (it == 1 and pullable[0] and _may_pull(x, kinematic, target, pullable)):
            status = FOLLOW_UP  # ``StepObjective.follow_up`` starts, tightens or ends a pull
            break
    pairs, counts = _where_it_ends(x, x_evaluated, pairs, swept, planes, has_mesh, dhat)
    return (status, it, x, p, (kappa, balanced, last_d2), (energy, ccd_alpha, min_alpha,
            complete), rows[:done], contacts[:done], pairs, counts, swept, values,
            values_kappa)
