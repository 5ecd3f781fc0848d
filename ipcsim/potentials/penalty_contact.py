"""Quadratic penalty contact: the baseline that IPC's barrier is measured against.

``PenaltyPlaneContact`` and ``PenaltyMeshContact`` keep the barrier terms' contact sets,
candidate updates and statistics and replace the energy by

    P = ½ k Σ max(0, d̂ − d)²

over the same pairs (signed d for planes, the unsigned closest-feature distance for mesh
pairs; see ``ipcsim/kernels/penalty.py``). There is no feasibility filter: ``max_step`` is
1, so nothing stops a step from crossing a surface. The stiffness k is fixed; ``kappa``
is kept only because the simulation sets it on every contact term, and is not used.
"""

from __future__ import annotations

from ..kernels import penalty as kp
from .base import Triplets
from .mesh_contact import MeshContact
from .plane_contact import PlaneContact


class PenaltyPlaneContact(PlaneContact):
    name = "plane penalty contact"

    def __init__(self, vertices, origins, normals, dhat: float, stiffness: float):
        super().__init__(vertices, origins, normals, dhat)
        self.dhat = dhat
        self.stiffness = float(stiffness)

    def value(self, x):
        return kp.plane_penalty_value(x, self.vertices, self.origins, self.normals,
                                      self.dhat, self.stiffness)

    def gradient(self, x):
        return kp.plane_penalty_gradient(x, self.vertices, self.origins, self.normals,
                                         self.dhat, self.stiffness)

    def hessian(self, x):
        return Triplets(*kp.plane_penalty_hessian(x, self.vertices, self.origins,
                                                  self.normals, self.dhat, self.stiffness))

    def max_step(self, x, p):
        return 1.0


class PenaltyMeshContact(MeshContact):
    name = "mesh penalty contact"

    def __init__(self, model, rest_positions, dhat: float, stiffness: float):
        super().__init__(model, rest_positions, dhat)
        self.stiffness = float(stiffness)

    def value(self, x):
        pt, ee, _ = self._swept if self._swept is not None else self._candidates(x)
        return kp.mesh_penalty_value(x, pt, ee, self.dhat, self.stiffness)

    def gradient(self, x):
        pt, ee, _ = self.update(x)
        return kp.mesh_penalty_gradient(x, pt, ee, self.dhat, self.stiffness)

    def hessian(self, x):
        pt, ee, _ = self.update(x)
        return Triplets(*kp.mesh_penalty_hessian(x, pt, ee, self.dhat, self.stiffness, True))

    def max_step(self, x, p):
        """No CCD: the full step is always allowed. The candidates over the swept segment
        are still gathered, so that the line search's energies see every pair that comes
        within d̂ along the step."""
        self._swept = self._candidates(x, x + p.reshape(-1, 3))
        return 1.0
