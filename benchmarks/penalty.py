"""A Simulation whose contact barrier is replaced by a quadratic penalty (the baseline).

Everything else is the real solver: the same integrator, elasticity (with its inversion
bound), projected Newton and line search, candidate sets and statistics. Only the contact
terms change (``ipcsim/potentials/penalty_contact.py``), and with them the CCD filter
disappears.

The stiffness is given as a multiple c of W/d̂, W the weight of the heaviest simulated
body: k = c·W/d̂ is the spring that holds that body up with a penetration of d̂/c when a
single pair carries it. c = 1e3 is soft (a resting body sinks visibly into the d̂ band under
impacts), 1e7 is stiff (the linear systems get ill conditioned and Newton needs many
iterations); 1e5 is in between.
"""

from __future__ import annotations

import numpy as np

from ipcsim.potentials.penalty_contact import PenaltyMeshContact, PenaltyPlaneContact
from ipcsim.simulation import GRAVITY, Simulation
from ipcsim.solver.incremental import IncrementalPotential

STIFFNESS_FACTORS = (1e3, 1e5, 1e7)


def heaviest_weight(model) -> float:
    """W = m g of the heaviest body with tets (kinematic vertices excluded)."""
    moving = ~np.asarray(model.always_kinematic, dtype=bool)
    shapes = np.asarray(model.vertex_shape)[moving]
    masses = np.bincount(shapes, weights=np.asarray(model.mass)[moving])
    return float(masses.max() * np.linalg.norm(GRAVITY))


def penalty_stiffness(model, factor: float) -> float:
    """k = c · W / d̂ (N/m per contact pair)."""
    return factor * heaviest_weight(model) / model.dhat


def penalty_simulation(model, stiffness: float) -> Simulation:
    """Simulation(model) with its plane and mesh contact terms swapped for penalties of
    stiffness k, and the incremental potential rebuilt over the same terms otherwise."""
    sim = Simulation(model)
    swap = {}
    if sim.plane_contact is not None:
        old = sim.plane_contact
        sim.plane_contact = PenaltyPlaneContact(model.plane_contact_vertices,
                                                model.plane_origins, model.plane_normals,
                                                model.dhat, stiffness)
        swap[id(old)] = sim.plane_contact
    if sim.mesh_contact is not None:
        old = sim.mesh_contact
        sim.mesh_contact = PenaltyMeshContact(model, model.rest_positions, model.dhat,
                                              stiffness)
        swap[id(old)] = sim.mesh_contact
    sim.contacts = [c for c in (sim.plane_contact, sim.mesh_contact) if c is not None]
    for c in sim.contacts:
        c.kappa = sim.state.kappa  # set by the simulation, unused by the energy
    terms = [[w, swap.get(id(t), t)] for w, t in sim.potential.terms]
    sim.potential = IncrementalPotential(terms, sim.timer)
    return sim
