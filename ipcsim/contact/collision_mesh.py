"""The collision mesh: which primitives can touch, and which pairs of them count.

Built once from the model: every surface vertex, edge and triangle (tet boundaries, .obj
surfaces, .seg segments, .pt points, meshCO obstacles), a body id per vertex that filters
pairs, and the mask of vertices that are kinematic for the whole run (pairs whose
primitives are all kinematic never collide). With self collision off only pairs between a
body and a ``meshCO`` obstacle remain, as in the original.
"""

from __future__ import annotations

from functools import cached_property

from msgspec import Struct
from msgspec.structs import force_setattr
import numpy as np

from ..kernels.contact.broad_phase import primitive_tags


def _index_array(a, cols: int, name: str) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.int64)
    if a.size == 0:
        return a.reshape(0, cols)
    if a.ndim != 2 or a.shape[1] != cols:
        raise ValueError(f"{name} must be an (m, {cols}) integer array")
    return a


class CollisionMesh(Struct, frozen=True, eq=False, dict=True):
    """Surface primitives in global vertex numbers.

    vertices (v,) points that can collide; edges (e, 2); triangles (t, 3); body (n,) the
    body id of each vertex (a primitive's body is its first vertex's; pairs within one
    body are skipped unless ``self_collision``); kinematic (n,) bool; rest (n, 3) rest
    positions (the edge–edge mollifier's ε_x) or None when unused; ``planar``: a 2D
    scene's mesh (no triangles), whose pairs are its points against its edges."""

    vertices: np.ndarray
    edges: np.ndarray
    triangles: np.ndarray
    body: np.ndarray
    kinematic: np.ndarray
    self_collision: bool = True
    rest: np.ndarray | None = None
    planar: bool = False

    def __post_init__(self):
        # writable C-contiguous copies: numba compiles a second version of every kernel
        # for read-only arrays (the model's are read-only)
        verts = np.array(np.asarray(self.vertices).reshape(-1), dtype=np.int64)
        force_setattr(self, "vertices", verts)
        force_setattr(self, "edges", np.array(_index_array(self.edges, 2, "edges")))
        force_setattr(self, "triangles", np.array(_index_array(self.triangles, 3, "triangles")))
        force_setattr(self, "body", np.array(self.body, dtype=np.int64))
        force_setattr(self, "kinematic", np.array(self.kinematic, dtype=np.bool_))
        if self.rest is not None:
            force_setattr(self, "rest", np.array(self.rest, dtype=np.float64))
        n = len(self.body)
        if self.kinematic.shape != (n,):
            raise ValueError("body and kinematic need one entry per vertex")
        for prims in (self.vertices, self.edges, self.triangles):
            if prims.size and (prims.min() < 0 or prims.max() >= n):
                raise ValueError("vertex index out of range")

    @cached_property
    def tags(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """[body, all kinematic] of every point, edge and triangle (the broad phase's
        filters)."""
        return tuple(primitive_tags(prims, self.body, self.kinematic)
                     for prims in (self.vertices.reshape(-1, 1), self.edges, self.triangles))

    @cached_property
    def kernel_arrays(self) -> tuple:
        """(vertices (v, 1), edges, triangles, tags, self collision, rest positions): the
        mesh as the broad phase's kernels take it (a mesh made without rest positions
        has zeros there: no edge–edge mollifier)."""
        rest = np.zeros((len(self.body), 3)) if self.rest is None else self.rest
        return (self.vertices.reshape(-1, 1), self.edges, self.triangles, self.tags,
                bool(self.self_collision), rest)

    @cached_property
    def line_search_arrays(self) -> tuple:
        """``kernel_arrays``, True (there is mesh contact) and whether the mesh is planar:
        the line search's mesh."""
        return self.kernel_arrays + (True, bool(self.planar))

    @staticmethod
    def of(n_vertices: int, vertices, edges, triangles, body=None, kinematic=None,
           self_collision: bool = True, rest=None) -> "CollisionMesh":
        """A mesh over n vertices; body defaults to one body, kinematic to none."""
        return CollisionMesh(
            vertices, edges, triangles,
            np.zeros(n_vertices, np.int64) if body is None else body,
            np.zeros(n_vertices, np.bool_) if kinematic is None else kinematic,
            self_collision, rest)

    @staticmethod
    def from_model(model) -> "CollisionMesh":
        body = np.asarray(model.vertex_shape, dtype=np.int64)
        if not model.self_collision:
            # only body–obstacle pairs: every non-obstacle shape counts as one body
            obstacle = np.array([k == "obstacle" for k in model.shape_kinds])
            body = np.where(obstacle[body], body + 1, 0)
        return CollisionMesh(model.surface_vertices, model.surface_edges,
                             model.surface_triangles, body, model.always_kinematic,
                             bool(model.self_collision), model.rest_positions,
                             planar=model.dimension == 2)

    @property
    def n_vertices(self) -> int:
        return len(self.body)
