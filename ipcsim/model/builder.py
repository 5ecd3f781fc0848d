"""``build_model(scene) -> Model``: meshes in, frozen arrays out.

Follows docs/ipc-scene-format.md §5.1 (assembly order):

1. each shape: load in file coordinates; pick DBC/NBC vertices by relative boxes of the
   file-space AABB among boundary vertices (§5.4); place p = R (s * p) + t with
   R = Rx Ry Rz (degrees); tet boundary triangles per shape;
2. ``rotateModel`` (initial positions only, pivot (max - min) / 2: the original's quirk),
   then ``size`` (rest and initial: scale to the largest extent, AABB min to the origin);
3. lumped masses, Lame parameters and rest shape per tet (per-shape materials);
4. the legacy script (``null``: codim shapes fixed, velocity shapes, DBCs, mesh sequences);
5. initial velocities (``initVel``, script ``null`` only), ``restart`` files;
6. meshCO obstacles are appended as fixed "obstacle" shapes (never rescaled, §8.15).

A 2D scene (``scene.dimension == 2``) is built by ``builder_2d.build_model_2d`` from the
same stages where they mean the same (placement, prescribed motion, initial velocities,
planes, parameters) and its own where they do not (triangles and springs, masses, the
boundary edges that collide).
"""

from __future__ import annotations

import math
from pathlib import Path

import msgspec
from msgspec import Struct, field
import numpy as np

from ..errors import MeshError, SceneError
from ..scene.spec import SUPPORTED_SCRIPTS, SceneSpec, ShapeSpec
from . import mesh_io
from .kinematics import rotation_axis_angle, rotation_xyz
from .model import (GRAVITY, ConstraintSolverSettings, DirichletSet, MeshSequence, Model,
                    NeumannSet, SolverSettings, TimeSettings)
from .surface import boundary_triangles, index_set, tet_signed_volumes, unique_edges

SEQUENCE_EXT = {"tet": "msh", "surface": "obj", "segments": "seg", "points": "pt"}
ELASTIC_PART_KINDS = ("tet", "triangles")  # simulated bodies: tets, a 2D scene's triangles
ENERGY_NAMES = {"NH": "neo-Hookean", "FCR": "fixed corotated"}


class _Part(Struct):
    """One shape after loading and placement (local vertex indices)."""

    index: int
    name: str
    kind: str  # tet | surface | segments | points | obstacle
    points: np.ndarray  # placed (n, 3)
    line: int | None = None
    tets: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.int64))
    triangles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    edges: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    material: tuple[float, float, float] = (0.0, 0.0, 0.0)  # density, E, nu
    dbc: list = field(default_factory=list)  # (local vertices, DirichletSpec)
    nbc: list = field(default_factory=list)  # (local vertices, NeumannSpec)

    def select_boundary_conditions(self, spec: ShapeSpec, file_points: np.ndarray,
                                   candidates: np.ndarray) -> None:
        """The shape's DBC and NBC vertices: the ``candidates`` inside each box, in file
        coordinates."""
        for j, d in enumerate(spec.dbc):
            self.dbc.append((select_in_box(file_points, candidates, d.box_min, d.box_max),
                             d, j))
        for j, nb in enumerate(spec.nbc):
            self.nbc.append((select_in_box(file_points, candidates, nb.box_min, nb.box_max),
                             nb, j))


# ----------------------------------------------------------------------------- helpers


def place(points: np.ndarray, translation, rotation_deg, scale) -> np.ndarray:
    """p_world = R (s * p) + t, R = Rx(rx) Ry(ry) Rz(rz) in degrees (column vectors)."""
    rot = rotation_xyz(np.radians(np.asarray(rotation_deg, dtype=np.float64)))
    scaled = np.asarray(points, dtype=np.float64) * np.asarray(scale, dtype=np.float64)
    return scaled @ rot.T + np.asarray(translation, dtype=np.float64)  # rows: (R p)^T = p^T R^T


def select_in_box(file_points: np.ndarray, candidates: np.ndarray, box_min, box_max) -> np.ndarray:
    """Local indices of candidate vertices inside a box given relative to the file-space AABB:
    [lo + (hi - lo) r0, lo + (hi - lo) r1], inclusive on both ends (written as the original
    does, (hi - lo) * r + lo, so boundary cases round the same way)."""
    lo, hi = file_points.min(axis=0), file_points.max(axis=0)
    bmin = (hi - lo) * np.asarray(box_min, dtype=np.float64) + lo
    bmax = (hi - lo) * np.asarray(box_max, dtype=np.float64) + lo
    inside = np.all(file_points >= bmin, axis=1) & np.all(file_points <= bmax, axis=1)
    return np.flatnonzero(inside & candidates).astype(np.int64)


def lame_parameters(youngs: np.ndarray, poisson: np.ndarray) -> np.ndarray:
    """(mu, lambda) = (E / (2 (1 + nu)), E nu / ((1 + nu)(1 - 2 nu)))."""
    e, nu = np.asarray(youngs, dtype=np.float64), np.asarray(poisson, dtype=np.float64)
    return np.stack([e / (2.0 * (1.0 + nu)), e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))], axis=-1)


def voronoi_triangle_masses(points: np.ndarray, triangles: np.ndarray, density: float) -> np.ndarray:
    """Per-corner masses (k, 3) of a kinematic triangle surface, as the original (§5.2):
    rho * (libigl Voronoi corner area) * (mean edge length / 3), i.e. a shell whose
    thickness is a third of the mean edge length."""
    x0, x1, x2 = (points[triangles[:, i]] for i in range(3))
    el = np.stack([np.linalg.norm(x1 - x2, axis=1), np.linalg.norm(x2 - x0, axis=1),
                   np.linalg.norm(x0 - x1, axis=1)], axis=1)  # l_i opposite corner i
    dbl_a = np.linalg.norm(np.cross(x1 - x0, x2 - x0), axis=1)  # twice the area
    with np.errstate(divide="ignore", invalid="ignore"):
        l0, l1, l2 = el[:, 0], el[:, 1], el[:, 2]
        cos = np.stack([(l2**2 + l1**2 - l0**2) / (2 * l1 * l2),
                        (l0**2 + l2**2 - l1**2) / (2 * l2 * l0),
                        (l1**2 + l0**2 - l2**2) / (2 * l0 * l1)], axis=1)
        bary = cos * el
        bary = bary / bary.sum(axis=1, keepdims=True)
        partial = bary * (0.5 * dbl_a)[:, None]
    quads = 0.5 * np.stack([partial[:, 1] + partial[:, 2], partial[:, 2] + partial[:, 0],
                            partial[:, 0] + partial[:, 1]], axis=1)
    for i in range(3):  # obtuse at corner i: that corner gets A/2, the others A/4
        w = np.full(3, 0.125)
        w[i] = 0.25
        quads = np.where((cos[:, i] < 0)[:, None], dbl_a[:, None] * w, quads)
    quads = np.where(np.isfinite(quads), quads, (dbl_a / 6.0)[:, None])  # degenerate: A/3 each
    return density * quads * (el.mean(axis=1) / 3.0)[:, None]


def _scene_error(scene: SceneSpec, line, message: str) -> SceneError:
    return SceneError(scene.source, line, message)


# ----------------------------------------------------------------------------- loading


def _load_shape(scene: SceneSpec, i: int, spec: ShapeSpec, warnings: list[str]) -> _Part:
    """Read one shape, select its DBC/NBC vertices in file coordinates, then place it."""
    try:
        kind = spec.kind
    except KeyError:
        raise _scene_error(scene, spec.line, f"unsupported mesh file type "
                                             f"'{spec.mesh_path.suffix}'") from None
    data = mesh_io.read_shape(spec.mesh_path, kind, spec.line)
    file_points = data["points"]
    tets = data.get("tets", np.zeros((0, 4), np.int64))
    triangles = data.get("triangles", np.zeros((0, 3), np.int64))
    edges = data.get("edges", np.zeros((0, 2), np.int64))
    label = f"shape {i + 1} ({spec.label})"

    scale = np.asarray(spec.scale, dtype=np.float64)
    if not np.all(np.isfinite(scale)) or np.any(scale == 0.0):
        raise _scene_error(scene, spec.line, f"{label}: scale {tuple(spec.scale)} must be "
                                             "finite and non-zero")
    if np.prod(scale) < 0.0:  # a mirror: keep tets positive and surfaces outward
        tets = tets[:, [0, 2, 1, 3]]
        triangles = triangles[:, [0, 2, 1]]
        warnings.append(f"{label}: negative scale mirrors the mesh; element orientation "
                        "was flipped to stay positive")

    if kind == "tet":
        triangles = boundary_triangles(tets)
    # DBC/NBC candidates: boundary vertices for tets and .obj, all vertices for .seg/.pt (§5.4)
    if kind in ("tet", "surface"):
        candidates = np.zeros(len(file_points), dtype=bool)
        candidates[triangles.ravel()] = True
    else:
        candidates = np.ones(len(file_points), dtype=bool)

    part = _Part(index=i, name=spec.mesh_path.stem, kind=kind, line=spec.line,
                 points=place(file_points, spec.translation, spec.rotation_deg, scale),
                 tets=tets, triangles=triangles, edges=edges)
    part.select_boundary_conditions(spec, file_points, candidates)
    part.material = _shape_material(scene, spec, kind, label, warnings)
    return part


def _shape_material(scene: SceneSpec, spec: ShapeSpec, kind: str, label: str,
                    warnings: list[str]) -> tuple[float, float, float]:
    """(density, E, nu) of a shape: its own material where it is a body with a usable
    one, else the scene's."""
    material = (scene.density, scene.youngs_modulus, scene.poisson_ratio)
    m = spec.material
    if m is not None:
        values = (m.density, m.youngs_modulus, m.poisson_ratio)
        if kind not in ELASTIC_PART_KINDS:
            what = "tet" if scene.dimension == 3 else "body"
            warnings.append(f"{label}: material ignored (only {what} shapes are elastic)")
        elif not all(math.isfinite(v) for v in values):
            warnings.append(f"{label}: material with non-finite values ignored")
        elif m.density <= 0.0 or m.youngs_modulus <= 0.0:
            warnings.append(f"{label}: material needs density > 0 and E > 0; "
                            "using the global material")
        else:
            material = values
    if kind in ELASTIC_PART_KINDS and not (-1.0 < material[2] < 0.5):
        raise _scene_error(scene, spec.line, f"{label}: Poisson ratio {material[2]} "
                                             "must be in (-1, 0.5)")
    return material


def _load_obstacle(scene: SceneSpec, k: int, ob) -> _Part:
    """meshCO: centre on the vertex average, rotate Rx Ry Rz (deg), scale uniformly so the
    largest AABB extent of the *original* mesh equals `size`, move the average to o (§4.2)."""
    points, triangles = mesh_io.read_obj(ob.mesh_path, ob.line)
    mesh_io.check_triangles(points, triangles, ob.mesh_path, ob.line)
    extent = float((points.max(axis=0) - points.min(axis=0)).max())
    if not extent > 0.0 or not ob.size > 0.0:
        raise _scene_error(scene, ob.line, f"meshCO {ob.path or ob.mesh_path.name}: "
                                           "zero extent or size")
    avg = points.mean(axis=0)
    rot = rotation_xyz(np.radians(np.asarray(ob.rotation_deg, dtype=np.float64)))
    placed = ((points - avg) @ rot.T) * (ob.size / extent) + np.asarray(ob.position)
    return _Part(index=k, name=f"meshCO {ob.mesh_path.stem}", kind="obstacle", points=placed,
                 triangles=triangles, line=ob.line)


# ----------------------------------------------------------------------------- build


def build_model_3d(scene: SceneSpec) -> Model:
    """The stages of §5.1, each a function of what the ones before produced."""
    _check_global_settings(scene)
    refuse_what_is_not_simulated(scene)
    warnings = time_warnings(scene)
    parts = [_load_shape(scene, i, s, warnings) for i, s in enumerate(scene.shapes)]
    if not any(p.kind == "tet" for p in parts):
        raise _scene_error(scene, None, "the scene needs at least one tetrahedral shape "
                                        "(.msh, .vtk, .vtu or TetGen .node/.ele)")
    offsets = np.concatenate([[0], np.cumsum([len(p.points) for p in parts])]).astype(np.int64)
    rest, initial = _place_scene(scene, np.concatenate([p.points for p in parts]))
    obstacles = [_load_obstacle(scene, len(parts) + k, ob)
                 for k, ob in enumerate(scene.mesh_obstacles)]
    motion = _prescribed_motion(scene, parts, offsets, (rest, initial), obstacles, warnings)
    all_parts = parts + obstacles
    for ob in obstacles:  # fixed surfaces after the scene's shapes (never rescaled, §8.15)
        rest = np.concatenate([rest, ob.points])
        motion.initial = np.concatenate([motion.initial, ob.points])
        offsets = np.append(offsets, len(rest))
        motion.always = np.concatenate([motion.always, np.ones(len(ob.points), dtype=bool)])
    elastic = _elastic_tets(scene, all_parts, offsets, rest)
    mesh = _collision_mesh(scene, all_parts, offsets, rest, elastic)
    bbox_diagonal = _tet_bbox_diagonal(scene, rest, elastic.tets)
    velocities = _initial_velocities(scene, parts, offsets, motion, warnings)
    initial = _apply_restart(scene, int(offsets[len(parts)]), motion.initial, velocities)
    model = Model(
        time=time_settings(scene, bbox_diagonal),
        solver=_solver_settings(scene, bbox_diagonal),
        energy=scene.energy,
        rest_positions=rest, initial_positions=initial, initial_velocities=velocities,
        mass=mesh.mass, vertex_shape=np.repeat(np.arange(len(all_parts)), np.diff(offsets)),
        always_kinematic=motion.always,
        tets=elastic.tets, tet_shape=elastic.tet_shape, rest_volumes=elastic.volumes,
        Dm_inv=elastic.dm_inv, lame=elastic.lame,
        elastic_tets=_elastic_shapes(all_parts, offsets, motion.always)[elastic.tet_shape],
        shape_names=tuple(p.name for p in all_parts),
        shape_kinds=tuple(p.kind for p in all_parts), shape_offsets=offsets,
        surface_triangles=mesh.triangles, triangle_shape=mesh.triangle_shape,
        surface_edges=mesh.edges, edge_shape=mesh.edge_shape,
        surface_vertices=mesh.vertices,
        **_planes(scene), **_contact_parameters(scene, bbox_diagonal),
        dbc_sets=tuple(motion.dbc_sets), nbc_sets=tuple(motion.nbc_sets),
        mesh_sequences=tuple(motion.sequences), dbc_time_range=scene.dbc_time_range,
        nbc_time_range=scene.nbc_time_range, terms=(),
        constraint_solver=_constraint_solver(scene, warnings), warnings=tuple(warnings),
    )
    return msgspec.structs.replace(model, terms=describe_terms(model, scene))


def time_settings(scene: SceneSpec, bbox_diagonal: float) -> TimeSettings:
    """The clock and the integrator; a tolerance becomes absolute, τ·l."""
    tolerance = None if scene.time_tolerance is None else scene.time_tolerance * bbox_diagonal
    return TimeSettings(scene.dt, scene.n_steps, scene.integrator, scene.newmark_beta,
                        scene.newmark_gamma, tolerance, scene.duration)


def refuse_what_is_not_simulated(scene: SceneSpec) -> None:
    """Adaptive steps need an integrator with an error estimate (BE, BDF2) and a clock
    that is time, not a step count: a scene that asks for them otherwise is refused
    here rather than run with something else."""
    if scene.time_tolerance is None:
        return
    if scene.integrator == "NM":
        raise _scene_error(scene, scene.line_of("integrator.type"),
                           "adaptive time steps (a time tolerance) need the BE or BDF2 "
                           "integrator, which estimate their error; Newmark does not")
    sequences = [i for i, s in enumerate(scene.shapes) if s.mesh_sequence is not None]
    if sequences:  # at the tolerance's line, else (set by --set) at the sequence's shape
        line = scene.line_of("time.tolerance") or scene.shapes[sequences[0]].line
        raise _scene_error(scene, line,
                           "adaptive time steps (a time tolerance) cannot follow the mesh "
                           f"sequence of shape {sequences[0] + 1}, whose frames are one per "
                           "step of dt; leave the tolerance out")


def time_warnings(scene: SceneSpec) -> list[str]:
    """A time tolerance with backward Euler only because the scene names no integrator:
    BE is first order, so its adaptive steps shrink in proportion to τ, BDF2's as √τ
    (the spinning bar at τ = 1e-4: BE 97 s, BDF2 2.4 s; docs/user-guide.md)."""
    named = "integrator.type" in scene.key_lines or "integrator.type" in scene.overrides
    if scene.time_tolerance is None or scene.integrator != "BE" or named:
        return []
    return ["adaptive time steps with backward Euler, the default integrator: first "
            "order, its steps shrink in proportion to the tolerance (BDF2's with its square "
            "root); name an integrator to choose (timeIntegration BDF2, or [integrator] "
            "type = \"BDF2\"; BE keeps it)"]


def _check_global_settings(scene: SceneSpec) -> None:
    if scene.script not in SUPPORTED_SCRIPTS:
        raise _scene_error(scene, None, f"script '{scene.script}' is not supported "
                                        f"(supported: {', '.join(SUPPORTED_SCRIPTS)})")
    if scene.density <= 0.0 or scene.youngs_modulus <= 0.0:
        raise _scene_error(scene, None, "density and Young's modulus must be positive")


def _place_scene(scene: SceneSpec, placed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rest, initial) positions after ``rotateModel`` and ``size`` (§5.1 step 2)."""
    rest, initial = placed, placed.copy()
    # rotateModel: initial positions only, about the axis through (max - min) / 2 (quirk)
    if scene.rotate_model is not None and scene.rotate_model[3] != 0.0:
        axis = np.asarray(scene.rotate_model[:3], dtype=np.float64)
        if not np.linalg.norm(axis) > 0.0:
            raise _scene_error(scene, None, "rotateModel needs a non-zero axis")
        rot = rotation_axis_angle(axis, math.radians(scene.rotate_model[3]))
        pivot = 0.5 * (initial.max(axis=0) - initial.min(axis=0))
        initial = (initial - pivot) @ rot.T + pivot
    # size: scale rest and initial so the initial AABB's largest extent is `size`, min at 0
    if scene.size > 0.0:
        f = scene.size / float((initial.max(axis=0) - initial.min(axis=0)).max())
        rest, initial = rest * f, initial * f
        shift = initial.min(axis=0)
        rest, initial = rest - shift, initial - shift
    return rest, initial


# ----------------------------------------------------------------------------- motion


class _Motion(Struct):
    """What is prescribed: DBC and NBC sets, mesh sequences, the always-kinematic mask,
    the initial positions and velocities (a legacy script may set them; None: from the
    shapes' initVel)."""

    initial: np.ndarray
    always: np.ndarray
    dbc_sets: list = field(default_factory=list)
    nbc_sets: list = field(default_factory=list)
    sequences: list = field(default_factory=list)
    velocities: np.ndarray | None = None


def _label(scene: SceneSpec, i: int) -> str:
    spec = scene.shapes[i]
    return f"shape {i + 1} ({spec.label})"


def _prescribed_motion(scene, parts, offsets, placed, obstacles, warnings) -> _Motion:
    """NBCs of every shape; with script ``null`` the shapes' own velocities, mesh
    sequences and DBCs; otherwise the legacy script's motion (§5.1 step 4). ``placed`` is
    (rest, initial) of the scene's shapes; ``obstacles`` the placed meshCO parts."""
    rest, initial = placed
    motion = _Motion(initial=initial, always=np.zeros(len(rest), dtype=bool))
    null_script = scene.script == "null"
    for p in parts:
        if p.kind not in ELASTIC_PART_KINDS:
            motion.always[offsets[p.index]:offsets[p.index + 1]] = True  # never simulated
        for verts, nb, j in p.nbc:  # NBCs apply whatever the script
            src = f"{_label(scene, p.index)} NBC {j + 1}"
            if len(verts) == 0:
                warnings.append(f"{src}: box selects no boundary vertex; no BC created")
                continue
            motion.nbc_sets.append(NeumannSet(verts + offsets[p.index], tuple(nb.acceleration),
                                              tuple(nb.time_range), gated=True, source=src))
        if null_script:
            _shape_motion(scene, p, offsets, motion, warnings)
    if null_script:
        for p in parts:
            _shape_dirichlet_sets(scene, p, offsets, motion, warnings)
    else:
        from . import legacy_scripts  # a script scene only

        _warn_ignored_shape_motion(scene, parts, warnings)
        obstacle_points = np.concatenate([ob.points for ob in obstacles] or [np.zeros((0, 3))])
        scripted = legacy_scripts.script_motion(legacy_scripts.ScriptScene(
            scene, tuple(p.kind for p in parts), offsets, rest, motion.initial,
            obstacle_points), warnings)
        motion.dbc_sets.extend(scripted.dbc_sets)
        motion.nbc_sets.extend(scripted.nbc_sets)
        motion.initial, motion.velocities = scripted.initial, scripted.velocities
    return motion


def _shape_motion(scene, p: _Part, offsets, motion: _Motion, warnings) -> None:
    """A shape's own prescribed motion (script null): a mesh sequence, a linear/angular
    velocity, or, for a codim shape without either, staying fixed."""
    rng_i = np.arange(offsets[p.index], offsets[p.index + 1])
    spec = scene.shapes[p.index]
    lin, ang = spec.linear_velocity, spec.angular_velocity_deg
    if spec.mesh_sequence is not None:
        motion.always[rng_i] = True
        motion.sequences.append(_mesh_sequence(scene, p, offsets, motion.initial, warnings))
    elif lin is not None or ang is not None:
        motion.always[rng_i] = True
        motion.dbc_sets.append(DirichletSet(
            rng_i, linear_velocity=tuple(lin or (0.0, 0.0, 0.0)),
            angular_velocity=tuple(math.radians(w) for w in (ang or (0.0, 0.0, 0.0))),
            source=f"{_label(scene, p.index)} velocity"))
    elif p.kind not in ELASTIC_PART_KINDS:
        motion.dbc_sets.append(DirichletSet(rng_i,
                                            source=f"{_label(scene, p.index)} (codim, fixed)"))


def _shape_dirichlet_sets(scene, p: _Part, offsets, motion: _Motion, warnings) -> None:
    for verts, d, j in p.dbc:
        src = f"{_label(scene, p.index)} DBC {j + 1}"
        if len(verts) == 0:
            warnings.append(f"{src}: box selects no boundary vertex; no BC created")
            continue
        motion.dbc_sets.append(DirichletSet(
            verts + offsets[p.index], linear_velocity=tuple(d.linear_velocity),
            angular_velocity=tuple(math.radians(w) for w in d.angular_velocity_deg),
            time_range=tuple(d.time_range), gated=True, source=src))


def _warn_ignored_shape_motion(scene, parts, warnings) -> None:
    """A legacy script replaces the shapes' own motion, as in the original."""
    from .legacy_scripts import FIXES_CODIM

    ignored = [k for k, present in (
        ("DBC", any(s.dbc for s in scene.shapes)),
        ("linearVelocity", any(s.linear_velocity is not None for s in scene.shapes)),
        ("angularVelocity", any(s.angular_velocity_deg is not None for s in scene.shapes)),
        ("initVel", any(s.init_velocity is not None for s in scene.shapes)),
        ("meshSeq", any(s.mesh_sequence is not None for s in scene.shapes))) if present]
    if ignored:
        warnings.append(f"script {scene.script}: per-shape {', '.join(ignored)} "
                        "not applied (as in the original)")
    if scene.script not in FIXES_CODIM and any(p.kind != "tet" for p in parts):
        warnings.append(f"script {scene.script}: codim shapes are kept fixed "
                        "(ipcsim does not simulate codim shapes)")


def _elastic_shapes(all_parts, offsets, always) -> np.ndarray:
    """(s,) bool: tet shapes that are simulated (velocity / meshSeq tet shapes are not)."""
    elastic = np.array([p.kind in ELASTIC_PART_KINDS for p in all_parts], dtype=bool)
    for i in range(len(all_parts)):
        if elastic[i] and np.all(always[offsets[i]:offsets[i + 1]]):
            elastic[i] = False
    return elastic


# ----------------------------------------------------------------------------- tets, masses


class _Elastic(Struct):
    """The tets of every elastic shape, in global vertex numbers, with their rest data."""

    tets: np.ndarray  # (m, 4) global vertex indices
    tet_shape: np.ndarray  # (m,)
    volumes: np.ndarray  # (m,) rest volumes
    dm_inv: np.ndarray  # (m, 3, 3)
    lame: np.ndarray  # (m, 2)
    mass: np.ndarray  # (n,) lumped tet masses


def _elastic_tets(scene, all_parts, offsets, rest) -> _Elastic:
    """Rest shapes Dm⁻¹, volumes, Lamé parameters and lumped masses of every tet."""
    tets = np.concatenate([p.tets + offsets[p.index] for p in all_parts]).astype(np.int64)
    tet_shape = np.repeat(np.arange(len(all_parts)), [len(p.tets) for p in all_parts])
    mat = np.array([p.material for p in all_parts], dtype=np.float64).reshape(-1, 3)
    x0 = rest[tets[:, 0]]
    dm = np.stack([rest[tets[:, 1]] - x0, rest[tets[:, 2]] - x0, rest[tets[:, 3]] - x0],
                  axis=2)  # Dm = [x1 - x0, x2 - x0, x3 - x0] as columns
    vol = tet_signed_volumes(rest, tets)  # V = det(Dm) / 6
    if np.any(~(vol > 0.0)):
        bad = int(np.flatnonzero(~(vol > 0.0))[0])
        raise _scene_error(scene, all_parts[tet_shape[bad]].line,
                           "placement or `size` made a tetrahedron degenerate")
    rho_tet = mat[tet_shape, 0]
    # lumped mass: each tet gives rho V / 4 to each of its 4 vertices
    mass = np.bincount(tets.ravel(), weights=np.repeat(rho_tet * vol / 4.0, 4),
                       minlength=len(rest))
    return _Elastic(tets, tet_shape, vol, np.linalg.inv(dm),
                    lame_parameters(mat[tet_shape, 1], mat[tet_shape, 2]), mass)


class _CollisionMesh(Struct):
    """The surface primitives that can collide, with the shape of each."""

    triangles: np.ndarray
    triangle_shape: np.ndarray
    edges: np.ndarray
    edge_shape: np.ndarray
    vertices: np.ndarray  # sorted: every vertex that can collide
    mass: np.ndarray  # (n,) tet masses plus the codim shapes' masses (§5.2)


def _collision_mesh(scene, all_parts, offsets, rest, elastic: _Elastic) -> _CollisionMesh:
    """Surface triangles, edges and points of every shape, and the masses of codim
    shapes: Voronoi shells for .obj, rods for .seg, the mean tet-vertex mass for .pt."""
    n = len(rest)
    mass = elastic.mass.copy()
    tri_blocks, tri_shape, edge_blocks, edge_shape, point_blocks = [], [], [], [], []
    for p in all_parts:
        off = offsets[p.index]
        if len(p.triangles):
            tris = p.triangles + off
            tri_blocks.append(tris)
            tri_shape.append(np.full(len(tris), p.index))
            e = unique_edges(tris)
            edge_blocks.append(e)
            edge_shape.append(np.full(len(e), p.index))
            if p.kind in ("surface", "obstacle"):
                corner = voronoi_triangle_masses(rest, tris, scene.density)
                mass += np.bincount(tris.ravel(), weights=corner.ravel(), minlength=n)
        if p.kind == "segments":
            e = p.edges + off
            edge_blocks.append(e)
            edge_shape.append(np.full(len(e), p.index))
            seg_len = np.linalg.norm(rest[e[:, 0]] - rest[e[:, 1]], axis=1)
            # each end of a segment of length L gets rho pi L^3 / 12
            mass += np.bincount(e.ravel(), weights=np.repeat(scene.density * math.pi
                                                              * seg_len**3 / 12.0, 2), minlength=n)
        if p.kind == "points":
            point_blocks.append(np.arange(offsets[p.index], offsets[p.index + 1]))
    tet_vertex = np.zeros(n, dtype=bool)
    tet_vertex[elastic.tets.ravel()] = True
    avg_tet_mass = float(mass[tet_vertex].mean())
    for pts in point_blocks:  # point clouds: the average tet-vertex mass each
        mass[pts] = avg_tet_mass
    triangles = _stack(tri_blocks, (0, 3))
    edges = _stack(edge_blocks, (0, 2))
    vertices = index_set(np.concatenate([triangles.ravel(), edges.ravel(), *point_blocks,
                                         np.zeros(0, np.int64)]))
    return _CollisionMesh(triangles, _stack(tri_shape, (0,)), edges, _stack(edge_shape, (0,)),
                          vertices, mass)


def _stack(blocks, empty_shape) -> np.ndarray:
    return np.concatenate(blocks) if blocks else np.zeros(empty_shape, np.int64)


def _tet_bbox_diagonal(scene, rest, tets) -> float:
    """l: the rest AABB diagonal of all tet shapes, the unit of relative parameters."""
    tet_rest = rest[index_set(tets)]
    l = float(np.linalg.norm(tet_rest.max(axis=0) - tet_rest.min(axis=0)))
    if not l > 0.0:
        raise _scene_error(scene, None, "the tet shapes have a zero bounding box")
    return l


# ----------------------------------------------------------------------------- initial state


def _initial_velocities(scene, parts, offsets, motion: _Motion, warnings) -> np.ndarray:
    """initVel on tet shapes (script null): v + ω × (x − c), c the shape's initial AABB
    centre; kinematic vertices start at rest (the original never gives DBC vertices an
    initVel)."""
    velocities = np.zeros((len(motion.always), 3))
    if scene.script != "null":
        if motion.velocities is not None:  # a legacy script's (DCOBallHitWall)
            velocities[:len(motion.velocities)] = motion.velocities
        return velocities
    scripted = motion.always.copy()
    for s in motion.dbc_sets:
        scripted[s.vertices] = True
    for p in parts:
        iv = scene.shapes[p.index].init_velocity
        if iv is None:
            continue
        if p.kind not in ELASTIC_PART_KINDS:
            warnings.append(f"shape {p.index + 1}: initVel ignored on a codim shape")
            continue
        sl = slice(offsets[p.index], offsets[p.index + 1])
        x = motion.initial[sl]
        c = 0.5 * (x.min(axis=0) + x.max(axis=0))
        w = np.radians(np.asarray(iv.angular_deg, dtype=np.float64))
        v = np.asarray(iv.linear, dtype=np.float64) + np.cross(w, x - c)
        v[scripted[sl]] = 0.0
        velocities[sl] = v
    return velocities


def _apply_restart(scene, n_own: int, initial, velocities) -> np.ndarray:
    """Positions and velocities of the scene's own vertices from a ``restart`` status
    file (in place for the velocities); the clock still starts at 0, as the original."""
    if scene.restart is None:
        return initial
    _, pos, vel = mesh_io.read_status(scene.restart)
    if len(pos) != n_own:
        raise SceneError(scene.restart, None, f"restart file has {len(pos)} vertices, "
                                              f"the scene has {n_own}")
    initial = initial.copy()
    initial[:n_own], velocities[:n_own] = pos, vel
    return initial


# ----------------------------------------------------------------------------- parameters


def _planes(scene) -> dict:
    """Analytic planes: origins, unit normals (solid side opposite), friction."""
    if not scene.planes:
        return dict(plane_origins=np.zeros((0, 3)), plane_normals=np.zeros((0, 3)),
                    plane_friction=np.zeros(0), plane_velocities=np.zeros((0, 3)),
                    plane_limits=np.zeros((0, 3)))
    origins = np.array([p.origin for p in scene.planes], dtype=np.float64)
    normals = np.array([p.normal for p in scene.planes], dtype=np.float64)
    norms = np.linalg.norm(normals, axis=1)
    if np.any(~(norms > 0.0)):
        raise _scene_error(scene, scene.planes[int(np.argmin(norms))].line,
                           "half-space normal must be non-zero")
    return dict(plane_origins=origins, plane_normals=normals / norms[:, None],
                plane_friction=np.array([p.friction for p in scene.planes], dtype=np.float64),
                plane_velocities=np.array([p.velocity for p in scene.planes], dtype=np.float64),
                plane_limits=np.array([p.limit if p.limit is not None else (np.nan,) * 3
                                       for p in scene.planes], dtype=np.float64))


def _contact_parameters(scene, l: float) -> dict:
    """Absolute contact and damping parameters (§4.4): relative ones times l unless
    useAbsParameters."""
    rel = 1.0 if scene.use_abs_parameters else l
    h = scene.dt
    damping = 0.75 * scene.damping_ratio * h**3 if scene.damping_ratio > 0 else max(
        scene.damping_stiff, 0.0)
    return dict(
        bbox_diagonal=l,
        dhat=float(scene.dhat_abs if scene.dhat_abs is not None else scene.dhat * rel),
        epsv=float(scene.epsv_abs if scene.epsv_abs is not None else scene.epsv * rel),
        dtol=float(scene.dtol * rel), kappa=scene.kappa if scene.kappa else None,
        kappa_min_multiplier=float(scene.kappa_min_multiplier),
        self_collision=bool(scene.self_collision), self_friction=float(scene.self_friction),
        contact_formulation=scene.contact_formulation,
        penalty_stiffness=float(scene.penalty_stiffness),
        damping_stiffness=float(damping),
        gravity=np.array((scene.gravity_acceleration or GRAVITY) if scene.gravity
                         else (0.0, 0.0, 0.0)),
    )


CONSTRAINT_KINDS = {"volume": "volume", "graphics": "gap", "gapFunction": "gap",
                    "Verschoor": "Verschoor"}


def _constraint_solver(scene, warnings) -> ConstraintSolverSettings | None:
    """The SQP / QP baseline's settings (None for IPC's interior point method)."""
    if scene.constraint_solver not in ("SQP", "QP"):
        return None
    kind = CONSTRAINT_KINDS.get(scene.constraint_type)
    if kind is None:
        raise _scene_error(scene, None, f"constraint type '{scene.constraint_type}' is not "
                                        f"implemented by ipcsim ({', '.join(CONSTRAINT_KINDS)})")
    if scene.self_friction > 0.0 or any(p.friction > 0.0 for p in scene.planes):
        warnings.append(f"constraintSolver {scene.constraint_solver}: friction is ignored "
                        "(the baselines are frictionless)")
    return ConstraintSolverSettings(scene.constraint_solver, kind,
                                    float(scene.constraint_offset),
                                    bool(scene.active_set_convergence))


def _solver_settings(scene, l: float) -> SolverSettings:
    """Newton tolerances tol·l·h per step (as given with useAbsParameters) and the rest
    of the solver's settings."""
    scale = 1.0 if scene.use_abs_parameters else l * scene.dt
    return SolverSettings(newton_tolerances=tuple(t * scale for t in scene.newton_tol),
                          warm_start=int(scene.warm_start), linear_solver=scene.linear_solver,
                          friction_iterations=int(scene.friction_iterations))


def _mesh_sequence(scene: SceneSpec, p: _Part, offsets, initial, warnings) -> MeshSequence:
    spec = scene.shapes[p.index]
    folder = Path(spec.mesh_sequence)
    if not folder.is_dir():
        raise MeshError(folder, spec.line, "meshSeq folder not found")
    seq = MeshSequence(shape=p.index, start=int(offsets[p.index]),
                       stop=int(offsets[p.index + 1]), folder=folder,
                       ext=SEQUENCE_EXT[p.kind], line=spec.line)
    first = mesh_io.read_frame_positions(seq.frame_path(0), seq.ext, spec.line)
    if len(first) != seq.stop - seq.start:
        raise MeshError(seq.frame_path(0), spec.line,
                        f"mesh-sequence frame has {len(first)} vertices, the shape has "
                        f"{seq.stop - seq.start}")
    x = initial[seq.start:seq.stop]
    size = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0))) or 1.0
    if float(np.abs(first - x).max()) > 1e-6 * size:
        warnings.append(f"shape {p.index + 1}: meshSeq frame 0 differs from the shape's "
                        "initial placement")
    return seq


def describe_terms(model: Model, scene: SceneSpec) -> tuple[str, ...]:
    """Human-readable list of exactly the terms the scene needs."""
    terms = []
    if scene.integrator == "NM":
        terms.append(f"inertia (Newmark, beta={scene.newmark_beta:g}, "
                     f"gamma={scene.newmark_gamma:g})")
    elif scene.integrator == "BDF2":
        terms.append("inertia (BDF2, its first step backward Euler)")
    else:
        terms.append("inertia (backward Euler)")
    if scene.gravity:
        terms.append("gravity")
    elastic_shapes = sorted(set(model.tet_shape[model.elastic_tets].tolist()))
    if elastic_shapes:
        k = len(elastic_shapes)
        terms.append(f"elasticity: {ENERGY_NAMES.get(scene.energy, scene.energy)} "
                     f"({k} shape{'s' if k != 1 else ''})")
    if model.needs_damping:
        terms.append(f"damping (stiffness {model.damping_stiffness:g})")
    if model.constraint_solver is not None and (model.needs_mesh_contact or model.n_planes):
        cs = model.constraint_solver
        terms.append(f"contact as constraints ({cs.method}, {scene.constraint_type} "
                     f"c(x) >= {cs.offset:g}, OSQP; no barrier)")
        return tuple(terms) + _bc_terms(model)
    if model.n_planes:
        terms.append(f"plane contact ({model.n_planes} plane{'s' if model.n_planes != 1 else ''})")
    if model.needs_mesh_contact:
        what = []
        if model.needs_self_contact:
            what.append("self collision on")
        elif not scene.self_collision:
            what.append("self collision off")
        n_ob = model.shape_kinds.count("obstacle")
        if n_ob:
            what.append(f"{n_ob} meshCO obstacle{'s' if n_ob != 1 else ''}")
        terms.append(f"mesh contact ({', '.join(what)})")
    if model.needs_friction:
        parts = []
        if scene.self_friction > 0 and model.needs_mesh_contact:
            parts.append(f"mu={scene.self_friction:g} mesh contacts")
        for pl, mu in zip(scene.planes, model.plane_friction):
            if mu > 0:
                parts.append(f"{'ground' if pl.kind == 'ground' else 'half-space'} {mu:g}")
        terms.append(f"friction ({', '.join(parts)})")
    return tuple(terms) + _bc_terms(model)


def _bc_terms(model: Model) -> tuple[str, ...]:
    terms = []
    if model.nbc_sets:
        k = len(model.nbc_sets)
        terms.append(f"Neumann BC ({k} set{'s' if k != 1 else ''})")
    if model.dbc_sets:
        moving = sum(1 for s in model.dbc_sets if s.moving)
        fixed = len(model.dbc_sets) - moving
        bits = []
        if moving:
            bits.append(f"{moving} moving set{'s' if moving != 1 else ''}")
        if fixed:
            bits.append(f"{fixed} fixed set{'s' if fixed != 1 else ''}")
        terms.append(f"Dirichlet BC ({', '.join(bits)})")
    if model.mesh_sequences:
        k = len(model.mesh_sequences)
        terms.append(f"mesh sequence ({k} shape{'s' if k != 1 else ''})")
    return tuple(terms)
