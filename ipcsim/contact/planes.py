"""Analytic contact planes (``ground``, ``halfSpace``) and the vertices they push.

A plane (o, n) has a unit normal n; its solid side is opposite n, and the signed
distance of a vertex x is d = n·(x − o). Every collision vertex that is not kinematic for
the whole run takes part (codim, velocity and meshSeq shapes and obstacles move as
prescribed; planes never push them).
"""

from __future__ import annotations

from msgspec import Struct
from msgspec.structs import force_setattr
import numpy as np

from ..kernels.contact.plane_barrier import plane_active_count_and_min_distance


class Planes(Struct, frozen=True, eq=False):
    """The contact planes and the vertices tested against them, with each plane's μ."""

    vertices: np.ndarray  # (v,) int64, the vertices tested against every plane
    origins: np.ndarray  # (p, 3)
    normals: np.ndarray  # (p, 3) unit
    friction: np.ndarray  # (p,) μ of each plane

    def __post_init__(self):
        # writable copies: numba compiles a second version of every kernel for the
        # model's read-only arrays
        force_setattr(self, "vertices", np.array(self.vertices, dtype=np.int64))
        force_setattr(self, "origins", np.array(self.origins, dtype=float).reshape(-1, 3))
        force_setattr(self, "normals", np.array(self.normals, dtype=float).reshape(-1, 3))
        force_setattr(self, "friction", np.array(self.friction, dtype=float).reshape(-1))

    @staticmethod
    def from_model(model) -> "Planes":
        return Planes(model.plane_contact_vertices, model.plane_origins, model.plane_normals,
                      model.plane_friction)

    def at(self, ctx) -> "Planes":
        """The planes in the step context ``ctx``: with its ``plane_origins`` where the
        planes move (a 2D scene's moving lines), else these."""
        origins = None if ctx is None else ctx.plane_origins
        if origins is None:
            return self
        return Planes(self.vertices, origins, self.normals, self.friction)

    def moved(self, origins: np.ndarray) -> "Planes":
        """The same planes through ``origins`` (p, 3)."""
        return Planes(self.vertices, origins, self.normals, self.friction)

    def count(self, x: np.ndarray, dhat: float) -> tuple[int, float]:
        """(pairs with d² < d̂², the smallest signed distance) at x."""
        return plane_active_count_and_min_distance(x, self.vertices, self.origins,
                                                   self.normals, dhat * dhat)
