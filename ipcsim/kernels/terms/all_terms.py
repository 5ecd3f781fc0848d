"""Every term of a small scene's incremental potential in one call: the values, the
gradients, or the Hessians added into a dense Newton matrix.

A term evaluated on its own (``potentials/``) is one Python call around one kernel; on a
scene of tens of vertices that call costs more than the kernel's arithmetic, and a Newton
iteration makes about twenty of them. These kernels call the very kernels the terms call,
in the terms' order, so they give the same bits (``potentials/fused.py`` packs the data).

Each kind of term has its data as one tuple, empty arrays where a scene has none, and
``present[kind]`` says whether the potential has it:

    INERTIA        (mass (n,), x̃ (n, 3))
    BODY_FORCE     (mass (n,), acceleration (n, 3))
    ELASTICITY     (tets (m, 4), Dm⁻¹ (m, 3, 3), rest volumes (m,), (μ, λ) (m, 2),
                    model, project to PSD)
    DAMPING        (xₙ (n, 3), block values (144 m,), scale, tets (m, 4))
    PLANE_CONTACT  (vertices (k,), origins (p, 3), unit normals (p, 3), d̂²)
    MESH_CONTACT   (point–triangle pairs (a, 4), edge–edge pairs (b, 4), ε_x (b,), d̂²,
                    whether any pair may be within d̂)
    FRICTION       (xₙ (n, 3), stencils (f, 4), coefficients (f, 4), tangent bases
                    (f, 3, 2), μλ (f,), ε_v h, project to PSD, triplet offsets (f + 1,))
    PULL           (vertices (k,), masses (k,), targets (k, 3), ρ, λ (k, 3), λ given)

Barrier terms are evaluated at unit stiffness, as the terms are; the caller weighs them.
"""

from __future__ import annotations

import numpy as np

from ipcsim.kernels.algebra.assembly import add_blocks_dense, add_triplets_dense
from ipcsim.kernels.contact.pair_barrier import barrier_gradient, barrier_hessian_blocks, barrier_value
from ipcsim.kernels.elasticity.tets import elastic_energy, elastic_gradient, elastic_hessian_values
from ipcsim.kernels.contact.friction import friction_gradient, friction_hessian_triplets, friction_value
from ipcsim.kernels.contact.plane_barrier import plane_barrier_gradient, plane_barrier_hessian, plane_barrier_value
from ipcsim.kernels.algebra.scatter import block_matvec
from ipcsim.kernels.terms.simple import (body_force_value, damping_value, inertia_value, pull_gradient,
                           pull_value)
from ipcsim.compiler.twin import kernel

INERTIA, BODY_FORCE, ELASTICITY, DAMPING = 0, 1, 2, 3
PLANE_CONTACT, MESH_CONTACT, FRICTION, PULL = 4, 5, 6, 7
N_KINDS = 8


@kernel()
def term_values(x, present, inertia, body, elastic, damping, plane, mesh, friction, pull):
    """(N_KINDS,) each present term's value at x (0 for the others)."""
    out = np.zeros(N_KINDS)
    if present[INERTIA]:
        out[INERTIA] = inertia_value(inertia[0], x, inertia[1])
    if present[BODY_FORCE]:
        out[BODY_FORCE] = body_force_value(body[0], body[1], x)
    if present[ELASTICITY]:
        out[ELASTICITY] = elastic_energy(x, elastic[0], elastic[1], elastic[2], elastic[3],
                                         elastic[4])
    if present[DAMPING]:
        out[DAMPING] = damping_value(x, damping[0], damping[1], damping[2], damping[3])
    if present[PLANE_CONTACT]:
        out[PLANE_CONTACT] = plane_barrier_value(x, plane[0], plane[1], plane[2], plane[3],
                                                 1.0)
    if present[MESH_CONTACT] and mesh[4]:
        out[MESH_CONTACT] = barrier_value(x, mesh[0], mesh[1], mesh[2], mesh[3], 1.0)
    if present[FRICTION] and friction[1].shape[0] > 0:
        out[FRICTION] = friction_value(x - friction[0], friction[1], friction[2],
                                       friction[3], friction[4], friction[5])
    if present[PULL]:
        out[PULL] = pull_value(x, pull[0], pull[1], pull[2], pull[3], pull[4], pull[5])
    return out


@kernel()
def term_gradients(x, present, inertia, body, elastic, damping, plane, mesh, friction,
                   pull):
    """(N_KINDS, 3n) each present term's gradient at x (rows of zeros for the others)."""
    n = x.shape[0]
    out = np.zeros((N_KINDS, 3 * n))
    if present[INERTIA]:
        mass, x_tilde = inertia
        for i in range(n):
            for a in range(3):
                out[INERTIA, 3 * i + a] = mass[i] * (x[i, a] - x_tilde[i, a])
    if present[BODY_FORCE]:
        mass, acceleration = body
        for i in range(n):
            for a in range(3):
                out[BODY_FORCE, 3 * i + a] = -(mass[i] * acceleration[i, a])
    if present[ELASTICITY]:
        out[ELASTICITY] = elastic_gradient(x, elastic[0], elastic[1], elastic[2], elastic[3],
                                           elastic[4])
    if present[DAMPING]:
        out[DAMPING] = block_matvec(damping[1], damping[2], damping[3],
                                    (x - damping[0]).reshape(-1))
    if present[PLANE_CONTACT]:
        out[PLANE_CONTACT] = plane_barrier_gradient(x, plane[0], plane[1], plane[2], plane[3],
                                                    1.0)
    if present[MESH_CONTACT] and mesh[4]:
        out[MESH_CONTACT] = barrier_gradient(x, mesh[0], mesh[1], mesh[2], mesh[3], 1.0)
    if present[FRICTION] and friction[1].shape[0] > 0:
        out[FRICTION] = friction_gradient(x - friction[0], friction[1], friction[2],
                                          friction[3], friction[4], friction[5])
    if present[PULL]:
        out[PULL] = pull_gradient(x, pull[0], pull[1], pull[2], pull[3], pull[4], pull[5])
    return out


@kernel()
def add_term_hessians_dense(A, coupling, x, present, factors, free_index, p, inertia,
                            elastic, damping, plane, mesh, friction, pull):
    """A += Σ factors[kind]·∇²(term) over free DOFs, the free rows' kinematic columns
    going to coupling as H_fk p_k (``assembly.add_triplets_dense``): the constant-pattern
    terms first (inertia, elasticity, damping), then the others, in the order
    ``solver/assembly.DenseAssembler`` adds the terms' own Hessians. Body forces have none."""
    n3 = 3 * x.shape[0]
    if present[INERTIA]:
        dofs = np.arange(n3)
        diagonal = np.empty(n3)
        for t in range(n3):
            diagonal[t] = inertia[0][t // 3]
        add_triplets_dense(A, dofs, dofs, diagonal, factors[INERTIA], free_index, p, coupling)
    if present[ELASTICITY]:
        tets = elastic[0]
        vals = elastic_hessian_values(x, tets, elastic[1], elastic[2], elastic[3], elastic[4],
                                      elastic[5])
        add_blocks_dense(A, vals, factors[ELASTICITY], tets, free_index, p, coupling)
    if present[DAMPING]:
        add_blocks_dense(A, damping[1], damping[2] * factors[DAMPING], damping[3], free_index,
                         p, coupling)
    if present[PLANE_CONTACT]:
        rows, cols, vals = plane_barrier_hessian(x, plane[0], plane[1], plane[2], plane[3],
                                                 1.0)
        if rows.shape[0] > 0:
            add_triplets_dense(A, rows, cols, vals, factors[PLANE_CONTACT], free_index, p,
                               coupling)
    if present[MESH_CONTACT] and mesh[4]:
        stencils, vals = barrier_hessian_blocks(x, mesh[0], mesh[1], mesh[2], mesh[3], 1.0,
                                                True)
        if vals.shape[0] > 0:
            add_blocks_dense(A, vals, factors[MESH_CONTACT], stencils, free_index, p,
                             coupling)
    if present[FRICTION] and friction[1].shape[0] > 0:
        rows, cols, vals = friction_hessian_triplets(x - friction[0], friction[1],
                                                     friction[2], friction[3], friction[4],
                                                     friction[5], friction[6], friction[7])
        if rows.shape[0] > 0:
            add_triplets_dense(A, rows, cols, vals, factors[FRICTION], free_index, p,
                               coupling)
    if present[PULL]:
        vertices = pull[0]
        k = vertices.shape[0]
        dofs = np.empty(3 * k, dtype=np.int64)
        diagonal = np.empty(3 * k)
        for j in range(k):
            for a in range(3):
                dofs[3 * j + a] = 3 * vertices[j] + a
                diagonal[3 * j + a] = pull[3] * pull[1][j]
        add_triplets_dense(A, dofs, dofs, diagonal, factors[PULL], free_index, p, coupling)
