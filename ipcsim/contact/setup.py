"""What contact a scene has, resolved once from the model, and how contacts are counted.

``ContactSetup`` names the collision mesh (None without mesh contact), the planes (None
without), d̂, friction's mesh μ and the formulation: IPC's barrier with CCD-bounded steps
and adaptive κ, or the penalty baseline (no CCD, no κ).
"""

from __future__ import annotations

from msgspec import Struct
import numpy as np

from ..kernels.contact.barrier import BARRIER_IPC, BARRIER_LECTURE
from .collision_mesh import CollisionMesh
from .collisions import Collisions
from .planes import Planes


class ContactCount(Struct, frozen=True):
    """Active contacts (d² < d̂²) by kind and the smallest distance (signed for planes;
    inf when there is nothing to measure)."""

    plane: int = 0
    point_triangle: int = 0
    edge_edge: int = 0
    min_distance: float = np.inf

    @property
    def total(self) -> int:
        return self.plane + self.point_triangle + self.edge_edge

    def as_row(self) -> dict:
        """The contact columns of steps.csv and newton.csv."""
        return {"contacts_plane": self.plane, "contacts_point_triangle": self.point_triangle,
                "contacts_edge_edge": self.edge_edge, "min_distance": self.min_distance,
                "contacts_total": self.total}


class PlanarContact(Struct, frozen=True, eq=False):
    """A 2D scene's barrier: its ``form`` (``kernels/contact/barrier.py``), each vertex's
    weight in the point–edge barrier (n,) and each plane vertex's in the lines' barrier
    (v,; None for the paper's barrier, whose lines are ``PlaneContact``'s)."""

    form: int
    point_weight: np.ndarray
    line_weight: np.ndarray | None

    @staticmethod
    def from_model(model) -> "PlanarContact":
        """The paper's barrier (weights 1), or the lecture's: a point–edge pair weighted by
        A d̂ / 16, a vertex against a line by A d̂ / 2, A the vertex's contact length."""
        dhat = model.dhat
        if model.contact_barrier != "lecture":
            return PlanarContact(BARRIER_IPC, np.ones(model.n_vertices), None)
        length = np.array(model.node_contact_length, dtype=float)
        # an inner node has no boundary edges: it gets its shape's mean boundary length,
        # as the lecture gives every node of its square the same (its lines push all)
        shape = np.asarray(model.vertex_shape)
        on_boundary = length > 0.0
        counts = np.bincount(shape[on_boundary], minlength=model.n_shapes)
        mean = np.bincount(shape[on_boundary], weights=length[on_boundary],
                           minlength=model.n_shapes) / np.maximum(counts, 1)
        length = np.where(on_boundary, length, mean[shape])
        vertices = model.plane_contact_vertices
        return PlanarContact(BARRIER_LECTURE, length * dhat / 16.0,
                             length[vertices] * dhat / 2.0)


class ContactSetup(Struct, frozen=True, eq=False):
    """What a scene's contact needs at every step: the collision mesh, the planes, d̂,
    mesh friction and how steps and κ are handled."""

    mesh: CollisionMesh | None
    planes: Planes | None
    dhat: float
    self_friction: float = 0.0  # μ of mesh–mesh contacts
    ccd: bool = True  # steps bounded by CCD (barrier); False for the penalty baseline
    adaptive_kappa: bool = True  # κ balanced and doubled; False: fixed κ, or no barrier
    planar: PlanarContact | None = None  # a 2D scene's barrier

    @staticmethod
    def from_model(model) -> "ContactSetup":
        # the SQP / QP baselines have no barrier and no CCD filter of their steps
        barrier = (model.contact_formulation == "barrier"
                   and getattr(model, "constraint_solver", None) is None)
        return ContactSetup(
            mesh=CollisionMesh.from_model(model) if model.needs_mesh_contact else None,
            planes=Planes.from_model(model) if model.needs_plane_contact else None,
            dhat=model.dhat, self_friction=model.self_friction, ccd=barrier,
            adaptive_kappa=barrier and model.kappa is None,
            planar=PlanarContact.from_model(model) if model.dimension == 2 else None)

    def count(self, x: np.ndarray, collisions: Collisions | None, ctx=None) -> ContactCount:
        """Contacts at x, with ``collisions`` the mesh's collision set at x (the planes
        where the step context ``ctx`` has them)."""
        plane, dmin = 0, np.inf
        if self.planes is not None:
            plane, dmin = self.planes.at(ctx).count(x, self.dhat)
        pt = ee = 0
        if collisions is not None:
            mesh = collisions.count(self.dhat)
            pt, ee = mesh.point_triangle, mesh.edge_edge
            dmin = min(dmin, mesh.min_distance)
        return ContactCount(int(plane), pt, ee, float(dmin))
