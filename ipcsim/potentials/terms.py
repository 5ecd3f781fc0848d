"""Which terms a scene's incremental potential has, and in which formulation.

``incremental_potential(model, force_weight)`` builds exactly the terms the model needs,
in the order they are summed: inertia, body forces, elasticity, damping, contact with
planes and between meshes, friction. Contact is IPC's barrier (scaled by κ, its steps
bounded by CCD) unless the scene asks for the penalty baseline
(``contact.formulation = "penalty"``), and absent with the SQP / QP baselines
(``constraintSolver SQP|QP``, contact as constraints): that choice is made here and
nowhere else.
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


def incremental_potential(model, force_weight: float) -> IncrementalPotential:
    """The terms of ``model``'s incremental potential; ``force_weight`` w weighs
    elasticity and body forces (h² for backward Euler, βh² for Newmark)."""
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
