"""Every term of the incremental potential in one call: the values, the gradients, or the
Hessians added into a dense Newton matrix.

A term evaluated on its own (``potentials/``) is one Python call around one kernel; on a
scene of tens of vertices that call costs more than the kernel's arithmetic, and a Newton
iteration asks for every term's value and gradient. These kernels are how the potential
evaluates its terms at every size: they call the very kernels the terms' own methods
call, in the terms' order, so a term gives the same bits either way.

``terms`` holds one data tuple per kind (empty arrays where a scene has none, and
``present[kind]`` says whether the potential has it):

    INERTIA        (mass (n,), x̃ (n, 3))
    BODY_FORCE     (mass (n,), acceleration (n, 3))
    ELASTICITY     (tets (m, 4), Dm⁻¹ (m, 3, 3), rest volumes (m,), (μ, λ) (m, 2),
                    model, project to PSD)
    DAMPING        (xₙ (n, 3), block values (144 m,), scale, tets (m, 4))
    PLANE_CONTACT  (vertices (k,), origins (p, 3), unit normals (p, 3), d̂²)
    MESH_CONTACT   (d̂²,)
    FRICTION       (xₙ (n, 3), stencils (f, 4), coefficients (f, 4), tangent bases
                    (f, 3, 2), μλ (f,), ε_v h, project to PSD, triplet offsets (f + 1,))
    PULL           (vertices (k,), masses (k,), targets (k, 3), ρ, λ (k, 3), λ given)
    PLANE_PENALTY  (vertices (k,), origins (p, 3), unit normals (p, 3), d̂, stiffness)
    MESH_PENALTY   (d̂, stiffness)
    TRIANGLES      (triangles (m, 3), Dm⁻¹ (m, 2, 2), rest areas (m,), (μ, λ) (m, 2),
                    model, project to PSD)                                     2D
    SPRINGS        (springs (k, 2), rest lengths² (k,), stiffnesses (k,),
                    project to PSD)                                            2D
    POINT_EDGE     (d̂², barrier form, weight of each point (n,))              2D
    LINE_LECTURE   (vertices (k,), origins (p, 3), unit normals (p, 3), d̂,
                    weight of each vertex (k,))                                2D

and ``pairs`` the mesh's pairs the mesh kinds sum over: (point–triangle (a, 4),
edge–edge (b, 4), ε_x (b,), whether any pair may be within d̂); in a 2D scene the first
array holds the point–edge pairs (a, 3) instead, the second none. A point–edge pair's
weight is its point's (1 for the paper's barrier, the lecture's A d̂ / 16), and the
lecture's half-planes are barriers on the distance itself (``line_barrier.py``).

Barrier terms are evaluated at unit stiffness, as the terms are; the caller weighs them.
"""

from __future__ import annotations

import numpy as np

from ipcsim.kernels.algebra.assembly import add_blocks_dense, add_triplets_dense
from ipcsim.kernels.algebra.scatter import block_matvec
from ipcsim.kernels.contact.friction import (friction_gradient, friction_hessian_triplets,
                                             friction_value)
from ipcsim.kernels.contact.pair_barrier import (barrier_gradient, barrier_hessian_blocks,
                                                 barrier_value)
from ipcsim.kernels.contact.penalty import (mesh_penalty_gradient, mesh_penalty_hessian,
                                            mesh_penalty_value, plane_penalty_gradient,
                                            plane_penalty_hessian, plane_penalty_value)
from ipcsim.kernels.contact.plane_barrier import (plane_barrier_gradient,
                                                  plane_barrier_hessian, plane_barrier_value)
from ipcsim.kernels.contact.line_barrier import (line_barrier_gradient,
                                                 line_barrier_hessian, line_barrier_value)
from ipcsim.kernels.contact.point_edge_barrier import (pe_barrier_gradient,
                                                       pe_barrier_hessian_blocks,
                                                       pe_barrier_value)
from ipcsim.kernels.elasticity.springs import (spring_energy, spring_gradient,
                                               spring_hessian_values)
from ipcsim.kernels.elasticity.tets import (elastic_energy, elastic_gradient,
                                            elastic_hessian_values)
from ipcsim.kernels.elasticity.triangles import (triangle_energy, triangle_gradient,
                                                 triangle_hessian_values)
from ipcsim.kernels.terms.simple import (body_force_gradient, body_force_value,
                                         damping_value, inertia_gradient, inertia_value,
                                         lumped_mass_diagonal, pull_gradient,
                                         pull_hessian_diagonal, pull_value)
from ipcsim.compiler.jit import njit
from ipcsim.compiler.twin import kernel

INERTIA, BODY_FORCE, ELASTICITY, DAMPING = 0, 1, 2, 3
PLANE_CONTACT, MESH_CONTACT, FRICTION, PULL = 4, 5, 6, 7
PLANE_PENALTY, MESH_PENALTY = 8, 9
TRIANGLES, SPRINGS, POINT_EDGE, LINE_LECTURE = 10, 11, 12, 13
N_KINDS = 14


@njit(cache=True)
def point_weights(pairs, weight_of_point):
    """(k,) each point–edge pair's weight: its point's."""
    w = np.empty(pairs.shape[0])
    for i in range(pairs.shape[0]):
        w[i] = weight_of_point[pairs[i, 0]]
    return w


@kernel()
def term_values(x, present, terms, pairs):
    """(N_KINDS,) each present term's value at x (0 for the others)."""
    out = np.zeros(N_KINDS)
    if present[INERTIA]:
        t = terms[INERTIA]
        out[INERTIA] = inertia_value(t[0], x, t[1])
    if present[BODY_FORCE]:
        t = terms[BODY_FORCE]
        out[BODY_FORCE] = body_force_value(t[0], t[1], x)
    if present[ELASTICITY]:
        t = terms[ELASTICITY]
        out[ELASTICITY] = elastic_energy(x, t[0], t[1], t[2], t[3], t[4])
    if present[DAMPING]:
        t = terms[DAMPING]
        out[DAMPING] = damping_value(x, t[0], t[1], t[2], t[3])
    if present[PLANE_CONTACT]:
        t = terms[PLANE_CONTACT]
        out[PLANE_CONTACT] = plane_barrier_value(x, t[0], t[1], t[2], t[3], 1.0)
    if present[MESH_CONTACT] and pairs[3]:
        out[MESH_CONTACT] = barrier_value(x, pairs[0], pairs[1], pairs[2],
                                          terms[MESH_CONTACT][0], 1.0)
    if present[FRICTION] and terms[FRICTION][1].shape[0] > 0:
        t = terms[FRICTION]
        out[FRICTION] = friction_value(x - t[0], t[1], t[2], t[3], t[4], t[5])
    if present[PULL]:
        t = terms[PULL]
        out[PULL] = pull_value(x, t[0], t[1], t[2], t[3], t[4], t[5])
    if present[PLANE_PENALTY]:
        t = terms[PLANE_PENALTY]
        out[PLANE_PENALTY] = plane_penalty_value(x, t[0], t[1], t[2], t[3], t[4])
    if present[MESH_PENALTY]:
        t = terms[MESH_PENALTY]
        out[MESH_PENALTY] = mesh_penalty_value(x, pairs[0], pairs[1], t[0], t[1])
    if present[TRIANGLES]:
        t = terms[TRIANGLES]
        out[TRIANGLES] = triangle_energy(x, t[0], t[1], t[2], t[3], t[4])
    if present[SPRINGS]:
        t = terms[SPRINGS]
        out[SPRINGS] = spring_energy(x, t[0], t[1], t[2])
    if present[POINT_EDGE] and pairs[3]:
        t = terms[POINT_EDGE]
        out[POINT_EDGE] = pe_barrier_value(x, pairs[0], point_weights(pairs[0], t[2]), t[0],
                                           1.0, t[1])
    if present[LINE_LECTURE]:
        t = terms[LINE_LECTURE]
        out[LINE_LECTURE] = line_barrier_value(x, t[0], t[1], t[2], t[3], t[4])
    return out


@kernel()
def term_gradients(x, present, terms, pairs):
    """(N_KINDS, 3n) each present term's gradient at x (rows of zeros for the others)."""
    out = np.zeros((N_KINDS, 3 * x.shape[0]))
    if present[INERTIA]:
        t = terms[INERTIA]
        out[INERTIA] = inertia_gradient(t[0], x, t[1])
    if present[BODY_FORCE]:
        t = terms[BODY_FORCE]
        out[BODY_FORCE] = body_force_gradient(t[0], t[1])
    if present[ELASTICITY]:
        t = terms[ELASTICITY]
        out[ELASTICITY] = elastic_gradient(x, t[0], t[1], t[2], t[3], t[4])
    if present[DAMPING]:
        t = terms[DAMPING]
        out[DAMPING] = block_matvec(t[1], t[2], t[3], (x - t[0]).reshape(-1))
    if present[PLANE_CONTACT]:
        t = terms[PLANE_CONTACT]
        out[PLANE_CONTACT] = plane_barrier_gradient(x, t[0], t[1], t[2], t[3], 1.0)
    if present[MESH_CONTACT] and pairs[3]:
        out[MESH_CONTACT] = barrier_gradient(x, pairs[0], pairs[1], pairs[2],
                                             terms[MESH_CONTACT][0], 1.0)
    if present[FRICTION] and terms[FRICTION][1].shape[0] > 0:
        t = terms[FRICTION]
        out[FRICTION] = friction_gradient(x - t[0], t[1], t[2], t[3], t[4], t[5])
    if present[PULL]:
        t = terms[PULL]
        out[PULL] = pull_gradient(x, t[0], t[1], t[2], t[3], t[4], t[5])
    if present[PLANE_PENALTY]:
        t = terms[PLANE_PENALTY]
        out[PLANE_PENALTY] = plane_penalty_gradient(x, t[0], t[1], t[2], t[3], t[4])
    if present[MESH_PENALTY]:
        t = terms[MESH_PENALTY]
        out[MESH_PENALTY] = mesh_penalty_gradient(x, pairs[0], pairs[1], t[0], t[1])
    if present[TRIANGLES]:
        t = terms[TRIANGLES]
        out[TRIANGLES] = triangle_gradient(x, t[0], t[1], t[2], t[3], t[4])
    if present[SPRINGS]:
        t = terms[SPRINGS]
        out[SPRINGS] = spring_gradient(x, t[0], t[1], t[2])
    if present[POINT_EDGE] and pairs[3]:
        t = terms[POINT_EDGE]
        out[POINT_EDGE] = pe_barrier_gradient(x, pairs[0], point_weights(pairs[0], t[2]),
                                              t[0], 1.0, t[1])
    if present[LINE_LECTURE]:
        t = terms[LINE_LECTURE]
        out[LINE_LECTURE] = line_barrier_gradient(x, t[0], t[1], t[2], t[3], t[4])
    return out


@kernel()
def weighted_gradient(gradients, weighing, kappa):
    """(each kind's factor (N_KINDS,), ∇E (3n,) = Σ factorᵢ ∇termᵢ summed in the terms'
    order): a term's factor is its weight, times κ for a barrier. ``weighing`` (kinds,
    weights, barrier) in the terms' order."""
    kinds, weights, barrier = weighing[0], weighing[1], weighing[2]
    factors = np.zeros(N_KINDS)
    g = np.zeros(gradients.shape[1])
    for i in range(kinds.shape[0]):
        factor = weights[i] * kappa if barrier[i] else weights[i]
        factors[kinds[i]] = factor
        row = gradients[kinds[i]]
        for j in range(g.shape[0]):
            g[j] += factor * row[j]
    return factors, g


@kernel()
def add_term_hessians_dense(A, coupling, x, present, factors, free_index, p, terms, pairs):
    """A += Σ factors[kind]·∇²(term) over free DOFs, the free rows' kinematic columns
    going to coupling as H_fk p_k (``assembly.add_triplets_dense``): the constant-pattern
    terms first (inertia, elasticity, damping; in 2D triangles and springs), then the
    others, in the order ``solver/assembly.DenseAssembler`` adds the terms' own Hessians.
    Body forces have none."""
    if present[INERTIA]:
        dofs = np.arange(3 * x.shape[0])
        add_triplets_dense(A, dofs, dofs, lumped_mass_diagonal(terms[INERTIA][0]),
                           factors[INERTIA], free_index, p, coupling)
    if present[ELASTICITY]:
        t = terms[ELASTICITY]
        vals = elastic_hessian_values(x, t[0], t[1], t[2], t[3], t[4], t[5])
        add_blocks_dense(A, vals, factors[ELASTICITY], t[0], free_index, p, coupling)
    if present[DAMPING]:
        t = terms[DAMPING]
        add_blocks_dense(A, t[1], t[2] * factors[DAMPING], t[3], free_index, p, coupling)
    if present[TRIANGLES]:
        t = terms[TRIANGLES]
        vals = triangle_hessian_values(x, t[0], t[1], t[2], t[3], t[4], t[5])
        add_blocks_dense(A, vals, factors[TRIANGLES], t[0], free_index, p, coupling)
    if present[SPRINGS]:
        t = terms[SPRINGS]
        vals = spring_hessian_values(x, t[0], t[1], t[2], t[3])
        add_blocks_dense(A, vals, factors[SPRINGS], t[0], free_index, p, coupling)
    if present[PLANE_CONTACT]:
        t = terms[PLANE_CONTACT]
        rows, cols, vals = plane_barrier_hessian(x, t[0], t[1], t[2], t[3], 1.0)
        add_triplets_dense(A, rows, cols, vals, factors[PLANE_CONTACT], free_index, p,
                           coupling)
    if present[MESH_CONTACT] and pairs[3]:
        stencils, vals = barrier_hessian_blocks(x, pairs[0], pairs[1], pairs[2],
                                                terms[MESH_CONTACT][0], 1.0, True)
        add_blocks_dense(A, vals, factors[MESH_CONTACT], stencils, free_index, p, coupling)
    if present[FRICTION] and terms[FRICTION][1].shape[0] > 0:
        t = terms[FRICTION]
        rows, cols, vals = friction_hessian_triplets(x - t[0], t[1], t[2], t[3], t[4], t[5],
                                                     t[6], t[7])
        add_triplets_dense(A, rows, cols, vals, factors[FRICTION], free_index, p, coupling)
    if present[PULL]:
        t = terms[PULL]
        dofs, diagonal = pull_hessian_diagonal(t[0], t[1], t[3])
        add_triplets_dense(A, dofs, dofs, diagonal, factors[PULL], free_index, p, coupling)
    if present[PLANE_PENALTY]:
        t = terms[PLANE_PENALTY]
        rows, cols, vals = plane_penalty_hessian(x, t[0], t[1], t[2], t[3], t[4])
        add_triplets_dense(A, rows, cols, vals, factors[PLANE_PENALTY], free_index, p,
                           coupling)
    if present[MESH_PENALTY]:
        t = terms[MESH_PENALTY]
        rows, cols, vals = mesh_penalty_hessian(x, pairs[0], pairs[1], t[0], t[1], True)
        add_triplets_dense(A, rows, cols, vals, factors[MESH_PENALTY], free_index, p,
                           coupling)
    if present[POINT_EDGE] and pairs[3]:
        t = terms[POINT_EDGE]
        stencils, vals = pe_barrier_hessian_blocks(x, pairs[0], point_weights(pairs[0], t[2]),
                                                   t[0], 1.0, t[1], True)
        add_blocks_dense(A, vals, factors[POINT_EDGE], stencils, free_index, p, coupling)
    if present[LINE_LECTURE]:
        t = terms[LINE_LECTURE]
        rows, cols, vals = line_barrier_hessian(x, t[0], t[1], t[2], t[3], t[4])
        add_triplets_dense(A, rows, cols, vals, factors[LINE_LECTURE], free_index, p,
                           coupling)
