"""Scatter-adds of per-stencil gradients into a flat gradient.

Every per-stencil gradient of the package (elastic tets, barrier and penalty contact pairs,
friction pairs) is summed into the flat (3n,) gradient by ``add_local_gradients``: serial,
row by row in order, the stencil's vertices in order, so the sum is race-free and
deterministic (the local gradients themselves are computed in parallel by the callers).
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit


@njit(cache=True, inline="always")
def local_dof(stencils, k, i):
    """The global DOF of local DOF i of stencil k (an element, a contact stencil): DOF
    a of its vertex i // 3 is 3·v + a."""
    return 3 * stencils[k, i // 3] + i % 3


@njit(cache=True, inline="always")
def gather_dofs(stencils, k, values, dofs, at):
    """Stencil k's global DOFs into dofs and ``values`` there into at (the stencil's part of
    a DOF vector, or of a DOF map such as the free DOFs' numbering)."""
    for i in range(dofs.shape[0]):
        dofs[i] = local_dof(stencils, k, i)
        at[i] = values[dofs[i]]


@njit(cache=True)
def add_local_gradients(grad, local, stencils):
    """grad[3 v + a] += local[i, 3 j + a] for v = stencils[i, j] ≥ 0, in place.

    ``local (k, 3 w)``: one row per stencil, vertex-major (3 j + a is axis a of the
    stencil's j-th vertex); ``stencils (k, w)`` int: global vertex ids, negative entries
    (unused slots) are skipped. Serial: rows in order, a row's vertices in order."""
    w = stencils.shape[1]
    for i in range(stencils.shape[0]):
        for j in range(w):
            v = stencils[i, j]
            if v < 0:
                continue
            for a in range(3):
                grad[3 * v + a] += local[i, 3 * j + a]


@njit(cache=True)
def scatter_local_gradients(local, stencils, n_vertices):
    """Flat (3 n_vertices,) sum of per-stencil gradients ``local (k, 3 w)`` over
    ``stencils (k, w)`` (see ``add_local_gradients``; negative ids are skipped)."""
    grad = np.zeros(3 * n_vertices)
    add_local_gradients(grad, local, stencils)
    return grad


@njit(cache=True)
def scatter_stencil_gradients(G, pt_pairs, ee_pairs, n_vertices):
    """Flat (3n,) gradient from per-pair local gradients ``G`` (k + j, 12): row i belongs
    to pt_pairs[i] (i < k), then to ee_pairs[i − k]."""
    k = pt_pairs.shape[0]
    grad = np.zeros(3 * n_vertices)
    add_local_gradients(grad, G[:k], pt_pairs)
    add_local_gradients(grad, G[k:], ee_pairs)
    return grad


@njit(cache=True)
def block_matvec(vals, scale, elements, v):
    """The flat (3n,) product scale·(Σₑ Bₑ) v of a matrix of per-element blocks: entry
    e·B + nd·i + j of ``vals`` (nd = 3·nv, B = nd², nv = elements.shape[1]) couples DOF
    3·elements[e, i // 3] + i % 3 with DOF 3·elements[e, j // 3] + j % 3. Each element's
    block times its vertices' part of v is added in element order (the lagged damping's
    D·Δx, without building D as a sparse matrix)."""
    nd = 3 * elements.shape[1]
    out = np.zeros(v.shape[0])
    dofs = np.empty(nd, np.int64)  # the element's DOFs, and v there
    v_e = np.empty(nd)
    t = 0
    for e in range(elements.shape[0]):
        gather_dofs(elements, e, v, dofs, v_e)
        for i in range(nd):
            total = 0.0
            for j in range(nd):
                total += vals[t] * v_e[j]
                t += 1
            out[dofs[i]] += scale * total
    return out
