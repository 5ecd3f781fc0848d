"""Which terms a scene's incremental potential has, and in which formulation.

``incremental_potential(model, integrator)`` builds exactly the terms the model needs,
in the order they are summed: inertia, body forces, elasticity, damping, contact with
planes and between meshes, friction. What depends on the step's length and integrator
(``solver/integrator.py``) is said once here: the weight w of elasticity and body forces
(h², βh² for Newmark, (βh)² for BDF2), friction's threshold ε_v·h_v and Rayleigh
damping's scale, with h_v the integrator's ``velocity_step`` (h; βh for BDF2);
``for_step`` gives a potential those of another step, its terms (and their caches)
otherwise the same. Contact is IPC's barrier (scaled by κ, its steps
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

from msgspec.structs import replace
import numpy as np

from ..contact.planes import Planes
from ..solver.integrator import damping_scale
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


# the terms weighted by w, the integrator's force weight
FORCE_WEIGHTED = ("body force", "elasticity", "springs")


def incremental_potential(model, integrator) -> IncrementalPotential:
    """The terms of ``model``'s incremental potential for a step of ``integrator``."""
    w = integrator.force_weight
    if model.dimension == 2:
        return _planar_potential(model, integrator)
    terms = [WeightedTerm(Inertia(model.mass)), WeightedTerm(BodyForce(model.mass), w)]
    elasticity = elastic_term(model)
    if elasticity is not None:
        terms.append(WeightedTerm(elasticity, w))
        if model.needs_damping:
            terms.append(WeightedTerm(damping_term(model, integrator)))
    terms.extend(contact_terms(model))
    if model.needs_friction:  # only where some μ > 0
        terms.append(WeightedTerm(_friction(model, integrator)))
    return IncrementalPotential(tuple(terms))


def for_step(potential: IncrementalPotential, model, integrator,
             scene_weight: float) -> IncrementalPotential:
    """``potential``'s terms weighted for a step of ``integrator`` (its length and
    coefficients): w, damping's scale and friction's threshold replaced, and the
    barriers weighted by w / ``scene_weight`` (the weight of a step of the scene's dt):
    κ is the stiffness of the scene's step, and a barrier is a potential energy like Ψ,
    whose force in a step must not grow as 1/h² when h shrinks. Nothing else changes."""
    w = integrator.force_weight
    terms = []
    for t in potential.terms:
        name = t.term.name
        if t.barrier:  # (the lecture's 2D barriers carry the scene's w besides)
            t = replace(t, weight=t.weight * w / scene_weight)
        elif name in FORCE_WEIGHTED:
            t = replace(t, weight=w)
        elif name == "damping":
            t = replace(t, term=damping_term(model, integrator))
        elif name == "friction":
            t = replace(t, term=replace(t.term, eps=friction_threshold(model, integrator)))
        terms.append(t)
    return IncrementalPotential(tuple(terms))


def friction_threshold(model, integrator) -> float:
    """ε_v·h_v: the slip per step below which friction is static (ε_v·h for BE and
    Newmark at the scene's h, the original's)."""
    return model.epsv * integrator.velocity_step


def damping_term(model, integrator) -> Damping:
    """Rayleigh damping whose coefficient is the scene's at every step length."""
    return Damping(damping_scale(integrator, model.damping_stiffness, model.dt))


def _friction(model, integrator) -> Friction:
    return Friction(friction_threshold(model, integrator),
                    ramp_resolution=model.solver.friction_ramp_resolution,
                    body=np.array(model.vertex_shape, dtype=np.int64))  # writeable: one variant


def _planar_potential(model, integrator) -> IncrementalPotential:
    """A 2D scene's terms (module docstring): inertia, body forces, triangles, springs,
    lines, point–edge contact, friction."""
    force_weight = integrator.force_weight
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
    if model.needs_friction:  # its normal forces carry the barriers' weight (lag_friction)
        terms.append(WeightedTerm(_friction(model, integrator)))
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
