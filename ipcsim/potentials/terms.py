"""Which terms a scene's incremental potential has, and in which formulation.

``incremental_potential(model, force_weight)`` builds exactly the terms the model needs,
in the order they are summed: inertia, body forces, elasticity, damping, contact with
planes and between meshes, friction. Contact is IPC's barrier (scaled by κ, its steps
bounded by CCD) unless the scene asks for the penalty baseline
(``contact.formulation = "penalty"``), and absent with the SQP / QP baselines
(``constraintSolver SQP|QP``, contact as constraints): that choice is made here and
nowhere else.

A 2D scene (``model.dimension == 2``) has triangles and springs for elasticity, the
point–edge barrier for mesh contact and its lines for planes; with the lecture's barrier
(``contact_barrier = "lecture"``) the barriers are weighted by the vertices' contact
lengths and, as the lecture's incremental potential has them, barriers and friction
are weighed by h² (w) like the other forces.
"""

from __future__ import annotations

import numpy as np

from ..contact.planes import Planes
from .body_force import BodyForce
from .damping import Damping
from .elasticity import Elasticity
from .friction import Friction
from .incremental import IncrementalPotential, WeightedTerm
from .inertia import Inertia
from .mesh_contact import MeshContact
from .plane_contact import PlaneContact
from .planar import LineContact, PointEdgeContact, Springs, TriangleElasticity
from ..contact.setup import PlanarContact


def incremental_potential(model, force_weight: float) -> IncrementalPotential:
    """The terms of ``model``'s incremental potential; ``force_weight`` w weighs
    elasticity and body forces (h² for backward Euler, βh² for Newmark)."""
    if model.dimension == 2:
        return _planar_potential(model, force_weight)
    terms = [WeightedTerm(Inertia(model.mass)), WeightedTerm(BodyForce(model.mass), force_weight)]
    elasticity = elastic_term(model)
    if elasticity is not None:
        terms.append(WeightedTerm(elasticity, force_weight))
        if model.needs_damping:
            terms.append(WeightedTerm(Damping.of(model.damping_stiffness, model.dt)))
    terms.extend(contact_terms(model))
    if model.needs_friction:  # only where some μ > 0
        # ε_v·h with the scene's own h
        terms.append(WeightedTerm(Friction(
            model.epsv * model.dt, ramp_resolution=model.solver.friction_ramp_resolution,
            body=np.array(model.vertex_shape, dtype=np.int64))))  # writeable: one kernel variant
    return IncrementalPotential(tuple(terms))


def _friction(model) -> Friction:
    # ε_v·h with the scene's own h
    return Friction(model.epsv * model.dt, ramp_resolution=model.solver.friction_ramp_resolution,
                    body=np.array(model.vertex_shape, dtype=np.int64))  # writeable


def _planar_potential(model, force_weight: float) -> IncrementalPotential:
    """A 2D scene's terms (module docstring): inertia, body forces, triangles, springs,
    lines, point–edge contact, friction."""
    terms = [WeightedTerm(Inertia(model.mass)), WeightedTerm(BodyForce(model.mass), force_weight)]
    elastic = model.elastic_tri_elements
    if np.any(elastic):
        terms.append(WeightedTerm(TriangleElasticity(
            model.tri_elements[elastic], model.tri_Dm_inv[elastic],
            model.tri_rest_areas[elastic], model.tri_lame[elastic], model.energy),
            force_weight))
    springy = model.elastic_springs
    if np.any(springy):
        terms.append(WeightedTerm(Springs(model.springs[springy],
                                          model.spring_rest_length_sq[springy],
                                          model.spring_stiffness[springy]), force_weight))
    barrier = PlanarContact.from_model(model)
    lecture = barrier.line_weight is not None
    barrier_weight = force_weight if lecture else 1.0
    if model.needs_plane_contact:
        planes = Planes.from_model(model)
        term = (LineContact(planes, model.dhat, barrier.line_weight) if lecture
                else PlaneContact(planes, model.dhat))
        terms.append(WeightedTerm(term, barrier_weight, barrier=True))
    if model.needs_mesh_contact:
        terms.append(WeightedTerm(PointEdgeContact(model.dhat, barrier.form,
                                                   barrier.point_weight),
                                  barrier_weight, barrier=True))
    if model.needs_friction:
        terms.append(WeightedTerm(_friction(model), barrier_weight))
    return IncrementalPotential(tuple(terms))


def elastic_term(model) -> Elasticity | None:
    if not len(model.tets):
        return None
    return Elasticity(model.tets, model.Dm_inv, model.rest_volumes, model.lame, model.energy,
                      model.n_vertices)


def contact_terms(model) -> list[WeightedTerm]:
    """Plane and mesh contact, as barriers (weight κ) or as the penalty baseline; none for
    the SQP / QP baselines, whose contact is a set of constraints (ipcsim.baselines)."""
    if model.constraint_solver is not None:
        return []
    planes = Planes.from_model(model) if model.needs_plane_contact else None
    mesh = model.needs_mesh_contact
    if model.contact_formulation == "penalty":
        from .penalty_contact import PenaltyMeshContact, PenaltyPlaneContact  # the baseline

        k = model.penalty_stiffness
        return ([WeightedTerm(PenaltyPlaneContact(planes, model.dhat, k))] if planes else []) \
            + ([WeightedTerm(PenaltyMeshContact(model.dhat, k))] if mesh else [])
    return ([WeightedTerm(PlaneContact(planes, model.dhat), barrier=True)] if planes else []) \
        + ([WeightedTerm(MeshContact(model.dhat), barrier=True)] if mesh else [])
