"""``build_model_2d(scene) -> Model``: a 2D scene's shapes in, frozen arrays out.

A 2D scene lies in the plane z = 0 and its Model is a 3D one confined there: positions
(n, 3) with z = 0, so that everything downstream keeps its layout. Its stages follow
``builder.py``'s, sharing those that mean the same in the plane:

1. each shape: a triangle mesh read from its file (``mesh_io.read_shape_2d``), a
   rectangle generated as the lecture's square_mesh makes it
   (``generate.rectangle_mesh``, centred on the origin), or kinematic segments / points;
   DBC/NBC vertices picked by relative boxes of the file-space bounding box among its
   boundary vertices; placed by p = Rz(angle) (s * p) + t (``builder.place``);
2. ``size`` (``builder._place_scene``);
3. prescribed motion and initial velocities (``builder._prescribed_motion``,
   ``builder._initial_velocities``): the shapes' velocities, DBCs, NBCs, ``initVel``;
4. the bodies: triangles with their rest shapes Dm⁻¹ (2 x 2), rest areas and Lamé
   parameters (plane strain: the 3D formulas), or, for a shape with a spring stiffness,
   springs (a rectangle's as the lecture makes them: cell sides and both cell diagonals;
   a mesh's: its triangles' edges) with rest lengths; masses lumped by area, ρ A / 3 per
   triangle corner, or, with ``node_masses = "uniform"`` (the lecture's), each shape's
   mass ρ Σ A split evenly over its vertices; kinematic segments and points get the mean
   body-vertex mass;
5. the collision mesh: the boundary edges of every body (directed so that the outward
   normal is on their right) and the segments of kinematic shapes, the vertices on them
   and kinematic points; each vertex's contact length, half the rest length of the
   boundary edges and segments it ends (the lecture's per-node contact length);
6. planes (lines: their normals have z = 0) with their velocities and limits, and the
   absolute parameters (``builder._contact_parameters``, l = the bodies' rest bounding-box
   diagonal).
"""

from __future__ import annotations

import msgspec
from msgspec import Struct
import numpy as np

from ..scene.spec import SceneSpec, ShapeSpec
from . import mesh_io
from .builder import (
    ENERGY_NAMES,
    _bc_terms,
    _contact_parameters,
    _elastic_shapes,
    _initial_velocities,
    _Part,
    _place_scene,
    _planes,
    _prescribed_motion,
    _scene_error,
    _shape_material,
    _solver_settings,
    _stack,
    _tet_bbox_diagonal,
    lame_parameters,
    place,
    refuse_what_is_not_simulated,
    time_settings,
    time_warnings,
)
from .generate import rectangle_mesh, rectangle_springs
from .model import Model
from .surface import boundary_edges, index_set, triangle_signed_areas, unique_edges


def _load_shape_2d(scene: SceneSpec, i: int, spec: ShapeSpec, warnings: list[str]) -> _Part:
    """Read or generate one shape, select its DBC/NBC vertices in file coordinates, then
    place it."""
    if spec.rectangle is not None:
        (w, h), (nx, ny) = spec.rectangle.size, spec.rectangle.resolution
        file_points, triangles = rectangle_mesh(nx, ny, (w, h), (-0.5 * w, -0.5 * h))
        data, kind = {"points": file_points, "triangles": triangles}, "triangles"
    else:
        kind = spec.kind
        data = mesh_io.read_shape_2d(spec.mesh_path, kind, spec.line)
    file_points = data["points"]
    triangles = data.get("triangles", np.zeros((0, 3), np.int64))
    if kind == "triangles":  # DBC/NBC candidates: a body's boundary vertices
        candidates = np.zeros(len(file_points), dtype=bool)
        candidates[boundary_edges(triangles).ravel()] = True
    else:
        candidates = np.ones(len(file_points), dtype=bool)
    label = f"shape {i + 1} ({spec.label})"
    part = _Part(index=i, name=spec.mesh_path.stem if spec.mesh_path else "rectangle",
                 kind=kind, line=spec.line, triangles=triangles,
                 edges=data.get("edges", np.zeros((0, 2), np.int64)),
                 points=place(file_points, spec.translation, spec.rotation_deg, spec.scale))
    part.select_boundary_conditions(spec, file_points, candidates)
    part.material = _shape_material(scene, spec, kind, label, warnings)
    return part


# ----------------------------------------------------------------------------- bodies


class _Bodies(Struct):
    """The triangles and springs of every body, in global vertex numbers, with their rest
    data, and the vertices' masses."""

    triangles: np.ndarray  # (t, 3)
    triangle_shape: np.ndarray  # (t,)
    areas: np.ndarray  # (t,)
    dm_inv: np.ndarray  # (t, 2, 2)
    lame: np.ndarray  # (t, 2)
    elastic: np.ndarray  # (t,) bool: a simulated shape's triangles that carry elasticity
    springs: np.ndarray  # (k, 2)
    spring_shape: np.ndarray  # (k,)
    rest_length_sq: np.ndarray  # (k,)
    stiffness: np.ndarray  # (k,)
    elastic_springs: np.ndarray  # (k,) bool
    mass: np.ndarray  # (n,)


def _triangles(scene, parts, offsets, rest) -> tuple[np.ndarray, ...]:
    """(triangles, their shapes, rest areas, Dm⁻¹) of every body."""
    bodies = [p for p in parts if p.kind == "triangles"]
    tris = _stack([p.triangles + offsets[p.index] for p in bodies], (0, 3))
    shape = _stack([np.full(len(p.triangles), p.index) for p in bodies], (0,))
    areas = triangle_signed_areas(rest, tris)
    if np.any(~(areas > 0.0)):
        bad = int(np.flatnonzero(~(areas > 0.0))[0])
        raise _scene_error(scene, parts[shape[bad]].line,
                           "placement or `size` made a triangle degenerate")
    x0 = rest[tris[:, 0], :2]
    dm = np.stack([rest[tris[:, 1], :2] - x0, rest[tris[:, 2], :2] - x0], axis=2)
    return tris, shape, areas, np.linalg.inv(dm)


def _springs(scene, parts, offsets, rest) -> tuple[np.ndarray, ...]:
    """(springs, their shapes, rest lengths², stiffnesses) of the mass-spring shapes."""
    blocks, shapes, stiff = [], [], []
    for p in parts:
        spec = scene.shapes[p.index]
        if spec.spring_stiffness is None:
            continue
        if spec.rectangle is not None:
            e = rectangle_springs(*spec.rectangle.resolution)
        else:
            e = unique_edges(p.triangles)
        blocks.append(e + offsets[p.index])
        shapes.append(np.full(len(e), p.index))
        stiff.append(np.full(len(e), float(spec.spring_stiffness)))
    springs = _stack(blocks, (0, 2))
    d = rest[springs[:, 0]] - rest[springs[:, 1]]
    return (springs, _stack(shapes, (0,)), np.einsum("ij,ij->i", d, d),
            np.concatenate(stiff) if stiff else np.zeros(0))


def _masses(scene, parts, offsets, tris, tri_shape, areas) -> np.ndarray:
    """Lumped (ρ A / 3 per corner) or uniform (ρ Σ A over the shape's vertices) masses;
    kinematic segments and points: the mean body-vertex mass."""
    n = int(offsets[-1])
    rho = np.array([p.material[0] for p in parts], dtype=np.float64)[tri_shape]
    if scene.node_masses == "uniform":
        shape_mass = np.bincount(tri_shape, weights=rho * areas, minlength=len(parts))
        counts = np.diff(offsets)
        mass = np.repeat(shape_mass / np.maximum(counts, 1), counts)
    else:
        mass = np.bincount(tris.ravel(), weights=np.repeat(rho * areas / 3.0, 3), minlength=n)
    body = np.zeros(n, dtype=bool)
    body[tris.ravel()] = True
    mass[~body] = float(mass[body].mean())
    return mass


def _bodies(scene, parts, offsets, rest, elastic_shapes) -> _Bodies:
    tris, tri_shape, areas, dm_inv = _triangles(scene, parts, offsets, rest)
    springs, spring_shape, rest_length_sq, stiffness = _springs(scene, parts, offsets, rest)
    mat = np.array([p.material for p in parts], dtype=np.float64).reshape(-1, 3)
    spring_shapes = np.array([s.spring_stiffness is not None for s in scene.shapes], dtype=bool)
    return _Bodies(tris, tri_shape, areas, dm_inv,
                   lame_parameters(mat[tri_shape, 1], mat[tri_shape, 2]),
                   elastic_shapes[tri_shape] & ~spring_shapes[tri_shape],
                   springs, spring_shape, rest_length_sq, stiffness,
                   elastic_shapes[spring_shape],
                   _masses(scene, parts, offsets, tris, tri_shape, areas))


# ----------------------------------------------------------------------------- contact


def _collision_mesh_2d(parts, offsets, rest) -> dict:
    """The colliding edges (bodies' boundaries, kinematic segments) and vertices, and each
    vertex's contact length (half the edges it ends)."""
    n = int(offsets[-1])
    blocks, shapes, points = [], [], []
    for p in parts:
        off = offsets[p.index]
        e = boundary_edges(p.triangles) if p.kind == "triangles" else p.edges
        if len(e):
            blocks.append(e + off)
            shapes.append(np.full(len(e), p.index))
        if p.kind == "points":
            points.append(np.arange(off, offsets[p.index + 1]))
    edges = _stack(blocks, (0, 2))
    length = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    contact_length = np.bincount(edges.ravel(), weights=np.repeat(0.5 * length, 2),
                                 minlength=n)
    vertices = index_set(np.concatenate([edges.ravel(), *points, np.zeros(0, np.int64)]))
    return dict(surface_triangles=np.zeros((0, 3), np.int64),
                triangle_shape=np.zeros(0, np.int64), surface_edges=edges,
                edge_shape=_stack(shapes, (0,)), surface_vertices=vertices,
                node_contact_length=contact_length)


# ----------------------------------------------------------------------------- build


def build_model_2d(scene: SceneSpec) -> Model:
    """The frozen Model of a 2D scene (module docstring)."""
    refuse_what_is_not_simulated(scene)
    for key in ("damping_ratio", "damping_stiff"):
        if getattr(scene, key) > 0.0:  # the damping term is the tets' Hessian's
            raise _scene_error(scene, scene.line_of(f"integrator.{key}"),
                               f"`{key}`: Rayleigh damping is not simulated in 2D "
                               "scenes; leave it out")
    warnings = time_warnings(scene)
    parts = [_load_shape_2d(scene, i, s, warnings) for i, s in enumerate(scene.shapes)]
    offsets = np.concatenate([[0], np.cumsum([len(p.points) for p in parts])]).astype(np.int64)
    rest, initial = _place_scene(scene, np.concatenate([p.points for p in parts]))
    motion = _prescribed_motion(scene, parts, offsets, (rest, initial), [], warnings)
    elastic_shapes = _elastic_shapes(parts, offsets, motion.always)
    bodies = _bodies(scene, parts, offsets, rest, elastic_shapes)
    l = _tet_bbox_diagonal(scene, rest, bodies.triangles)
    velocities = _initial_velocities(scene, parts, offsets, motion, warnings)
    empty = np.zeros(0)
    model = Model(
        time=time_settings(scene, l),
        solver=_solver_settings(scene, l), energy=scene.energy,
        rest_positions=rest, initial_positions=motion.initial, initial_velocities=velocities,
        mass=bodies.mass, vertex_shape=np.repeat(np.arange(len(parts)), np.diff(offsets)),
        always_kinematic=motion.always,
        tets=np.zeros((0, 4), np.int64), tet_shape=np.zeros(0, np.int64), rest_volumes=empty,
        Dm_inv=np.zeros((0, 3, 3)), lame=np.zeros((0, 2)), elastic_tets=np.zeros(0, bool),
        shape_names=tuple(p.name for p in parts), shape_kinds=tuple(p.kind for p in parts),
        shape_offsets=offsets, **_collision_mesh_2d(parts, offsets, rest),
        **_planes(scene), **_contact_parameters(scene, l),
        dbc_sets=tuple(motion.dbc_sets), nbc_sets=tuple(motion.nbc_sets),
        mesh_sequences=(), dbc_time_range=scene.dbc_time_range,
        nbc_time_range=scene.nbc_time_range, terms=(), warnings=tuple(warnings),
        dimension=2, tri_elements=bodies.triangles, tri_element_shape=bodies.triangle_shape,
        tri_rest_areas=bodies.areas, tri_Dm_inv=bodies.dm_inv, tri_lame=bodies.lame,
        elastic_tri_elements=bodies.elastic, springs=bodies.springs,
        spring_shape=bodies.spring_shape, spring_rest_length_sq=bodies.rest_length_sq,
        spring_stiffness=bodies.stiffness, elastic_springs=bodies.elastic_springs,
        contact_barrier=scene.contact_barrier,
    )
    return msgspec.structs.replace(model, terms=describe_terms_2d(model, scene))


def describe_terms_2d(model: Model, scene: SceneSpec) -> tuple[str, ...]:
    """Human-readable list of the terms a 2D scene needs."""
    masses = "uniform node masses" if scene.node_masses == "uniform" else "lumped masses"
    integrator = ("Newmark" if scene.integrator == "NM" else "backward Euler")
    terms = [f"2D, the plane z = 0 ({masses})", f"inertia ({integrator})"]
    if scene.gravity:
        terms.append("gravity")
    fem = sorted(set(model.tri_element_shape[model.elastic_tri_elements].tolist()))
    if fem:
        terms.append(f"elasticity: {ENERGY_NAMES.get(scene.energy, scene.energy)} triangles, "
                     f"plane strain ({len(fem)} shape{'s' if len(fem) != 1 else ''})")
    spring = sorted(set(model.spring_shape[model.elastic_springs].tolist()))
    if spring:
        terms.append(f"mass-spring ({len(spring)} shape{'s' if len(spring) != 1 else ''})")
    if model.needs_damping:
        terms.append(f"damping (stiffness {model.damping_stiffness:g})")
    barrier = "the lecture's barrier" if scene.contact_barrier == "lecture" else "barrier"
    moving = int(np.count_nonzero(np.any(model.plane_velocities != 0.0, axis=1)))
    if model.n_planes:
        extra = f", {moving} moving" if moving else ""
        terms.append(f"line contact ({model.n_planes} line{'s' if model.n_planes != 1 else ''}"
                     f"{extra}; {barrier})")
    if len(model.surface_edges):
        self_part = "self collision on" if scene.self_collision else "self collision off"
        terms.append(f"point-edge contact ({self_part}; {barrier})")
    frictional = [f"mu={scene.self_friction:g} point-edge"] if scene.self_friction > 0 else []
    frictional += [f"line {mu:g}" for mu in model.plane_friction if mu > 0]
    if frictional:
        terms.append(f"friction ({', '.join(frictional)})")
    return tuple(terms) + _bc_terms(model)
