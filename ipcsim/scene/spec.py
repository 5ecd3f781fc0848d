"""SceneSpec: exactly what a scene file says, with every default filled in.

Both readers (the original's text format and TOML) produce a ``SceneSpec``; the model
builder turns it into arrays. Units are SI; angles stay in degrees here (as written in
scene files) and become radians in the model. Parameters documented as *relative* are
multiplied by l, the rest bounding-box diagonal of all tet shapes, when the model is built
(unless ``use_abs_parameters``).

A 2D scene (``dimension = 2``, TOML only) lies in the plane z = 0 and is held in the same
records: its vectors have z = 0 (a scale's z is 1), its rotations turn about z
(``rotation_deg = (0, 0, angle)``), its shapes are triangle meshes (kind "triangles"),
generated rectangles ("rectangle", ``ShapeSpec.rectangle``), kinematic segments or points;
its planes are lines (normals with z = 0), which may move (``PlaneSpec.velocity``, up to
``limit``). ``node_masses`` and ``contact_barrier`` select the lecture's conventions
(uniform node masses; its area-weighted barrier) instead of the paper's.

The fields a record names in ``provenance`` say where something came from (file, line,
the path as written); two scenes that mean the same simulation compare equal
(``records.ByMeaning``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import ClassVar

from msgspec import Struct, field

from ..records import ByMeaning

Vec3 = tuple[float, float, float]
INF = math.inf

ENERGIES = ("NH", "FCR")
# BDF2: ipcsim's extension of the original's format (`timeIntegration BDF2`)
INTEGRATORS = ("BE", "NM", "BDF2")
# IPC's barrier, or the quadratic penalty baseline of benchmarks/ (no feasibility filter)
CONTACT_FORMULATIONS = ("barrier", "penalty")
# ``constraintSolver``: IPC's interior point (barrier) method, or the SQP / QP baselines
CONSTRAINT_SOLVERS = ("interiorPoint", "SQP", "QP")
# ``constraintType`` of the SQP / QP baselines that ipcsim implements (graphics and
# gapFunction are one constraint, the original's two names for it)
CONSTRAINT_TYPES = ("volume", "graphics", "gapFunction", "Verschoor")
# the original's other constraint types, refused by name
UNSUPPORTED_CONSTRAINT_TYPES = ("nonsmoothNewmark", "CMR", "STIV")

# Legacy hard-coded scenarios of the original program that ipcsim implements.
SUPPORTED_SCRIPTS = (
    "null",
    "fall",
    "fallNoShift",
    "DCOFix",
    "DCORotCylinders",
    "twist",
    "fixLowerHalf",
    "pushRightMost1",
    "hangLeft",
    "stretchAndPause",
    "dragright",
    "DCOVerschoorRoller",
    "DCOBallHitWall",
    "DCOSqueezeOut",
    "DCOSegBedSquash",
    "DCOSquash6",
    "utopiaComparison",
)

# Mesh kind by file extension; "tet" shapes are simulated, the others kinematic.
MESH_KINDS = {".msh": "tet", ".vtk": "tet", ".vtu": "tet", ".ele": "tet", "": "tet",
              ".obj": "surface", ".seg": "segments", ".pt": "points"}
# ... in a 2D scene: triangle meshes in the plane are simulated
MESH_KINDS_2D = {".msh": "triangles", ".obj": "triangles", ".seg": "segments",
                 ".pt": "points"}
SIMULATED_KINDS = ("tet", "triangles", "rectangle")  # the kinds that are elastic bodies
DIMENSIONS = (2, 3)
NODE_MASSES = ("lumped", "uniform")  # by element area or volume; each shape's mass evenly
CONTACT_BARRIERS = ("ipc", "lecture")  # the paper's barrier; the lecture's (area-weighted)


class MaterialSpec(Struct, frozen=True):
    """A shape's material."""

    density: float  # kg/m^3
    youngs_modulus: float  # Pa
    poisson_ratio: float


class DirichletSpec(ByMeaning, Struct, frozen=True):
    """``DBC``: vertices in a box (relative to the shape's file-space AABB) move kinematically."""
    provenance: ClassVar[tuple[str, ...]] = ("line",)

    box_min: Vec3
    box_max: Vec3
    linear_velocity: Vec3 = (0.0, 0.0, 0.0)  # m/s, world frame
    angular_velocity_deg: Vec3 = (0.0, 0.0, 0.0)  # deg/s, Rx*Ry*Rz
    time_range: tuple[float, float] = (0.0, INF)  # active while t0 <= t < t1
    line: int | None = None


class NeumannSpec(ByMeaning, Struct, frozen=True):
    """``NBC``: extra body acceleration on the vertices in a box."""
    provenance: ClassVar[tuple[str, ...]] = ("line",)

    box_min: Vec3
    box_max: Vec3
    acceleration: Vec3  # m/s^2
    time_range: tuple[float, float] = (0.0, INF)
    line: int | None = None


class InitialVelocitySpec(Struct, frozen=True):
    """A shape's initial velocity."""

    linear: Vec3  # m/s
    angular_deg: Vec3  # deg/s about the shape's initial AABB centre


class RectangleSpec(Struct, frozen=True):
    """A generated rectangle of a 2D scene (``model.generate.rectangle_mesh``): ``size``
    (width, height) centred on the origin, ``resolution`` (nx, ny) cells of two triangles."""

    size: tuple[float, float]
    resolution: tuple[int, int]


class ShapeSpec(ByMeaning, Struct, frozen=True):
    """One shape line: a mesh file placed by p = R(rx,ry,rz) (s * p_file) + t."""
    provenance: ClassVar[tuple[str, ...]] = ("path", "line")

    mesh_path: Path | None = None  # resolved, absolute (None: a generated rectangle)
    translation: Vec3 = (0.0, 0.0, 0.0)
    rotation_deg: Vec3 = (0.0, 0.0, 0.0)
    scale: Vec3 = (1.0, 1.0, 1.0)
    material: MaterialSpec | None = None  # None: the scene's global material
    linear_velocity: Vec3 | None = None  # every vertex kinematic
    angular_velocity_deg: Vec3 | None = None
    dbc: tuple[DirichletSpec, ...] = ()
    nbc: tuple[NeumannSpec, ...] = ()
    init_velocity: InitialVelocitySpec | None = None
    mesh_sequence: Path | None = None  # resolved folder of per-step meshes
    # Set only where the extension does not tell the kind: a missing `x.seg` / `x.pt` falls
    # back to `x.obj` (as in the original), read as its edges / its vertices.
    mesh_kind: str | None = None
    path: str = ""  # as written in the scene
    line: int | None = None
    rectangle: RectangleSpec | None = None  # 2D: generated instead of read
    spring_stiffness: float | None = None  # 2D: a mass-spring network, springs of this k

    @property
    def kind(self) -> str:
        """'tet' (simulated), 'surface', 'segments' or 'points' (kinematic); in a 2D
        scene 'triangles' or 'rectangle' (simulated), 'segments' or 'points'."""
        if self.rectangle is not None:
            return "rectangle"
        return self.mesh_kind or MESH_KINDS[self.mesh_path.suffix.lower()]

    @property
    def label(self) -> str:
        """The shape as messages name it: its path as written, else its file name, or
        ``rectangle`` for a generated one."""
        if self.rectangle is not None:
            return "rectangle"
        return self.path or self.mesh_path.name


class PlaneSpec(ByMeaning, Struct, frozen=True):
    """``ground <mu> <height>`` or ``halfSpace o n stiffness mu``; solid side opposite n."""
    provenance: ClassVar[tuple[str, ...]] = ("line",)

    kind: str  # "ground" | "halfSpace"
    origin: Vec3
    normal: Vec3  # unit length
    friction: float = 0.0
    stiffness: float = 0.0  # read and ignored, as in the original
    line: int | None = None
    velocity: Vec3 = (0.0, 0.0, 0.0)  # 2D: the origin moves at this velocity (m/s) ...
    limit: Vec3 | None = None  # ... while (limit − origin)·velocity > 0 at a step's start


class MeshObstacleSpec(ByMeaning, Struct, frozen=True):
    """``meshCO``: a static triangle-mesh obstacle (legacy)."""
    provenance: ClassVar[tuple[str, ...]] = ("path", "line")

    mesh_path: Path
    position: Vec3
    size: float  # largest AABB extent after placement, absolute
    stiffness: float = 0.0
    friction: float = 0.0
    rotation_deg: Vec3 = (0.0, 0.0, 0.0)
    path: str = ""
    line: int | None = None


class SceneSpec(ByMeaning, Struct, frozen=True):
    """A whole scene as written (module docstring): shapes, planes, obstacles, time,
    material, contact and solver settings."""
    provenance: ClassVar[tuple[str, ...]] = ("source", "warnings", "ignored", "key_lines",
                                              "overrides")

    shapes: tuple[ShapeSpec, ...] = ()
    planes: tuple[PlaneSpec, ...] = ()
    mesh_obstacles: tuple[MeshObstacleSpec, ...] = ()
    dimension: int = 3  # 2: the scene lies in the plane z = 0 (module docstring)

    # time
    duration: float = 5.0
    dt: float = 0.025  # with time_tolerance: the first and largest step
    # beyond the original: adaptive steps to this local error, relative to l (None: fixed)
    time_tolerance: float | None = None

    # material (global)
    density: float = 1000.0
    youngs_modulus: float = 1e5
    poisson_ratio: float = 0.4
    energy: str = "NH"
    node_masses: str = "lumped"  # 2D: or "uniform", each shape's mass split evenly

    # integrator
    integrator: str = "BE"
    newmark_beta: float = 0.25
    newmark_gamma: float = 0.5
    damping_stiff: float = 0.0
    damping_ratio: float = 0.0
    warm_start: int = 0
    gravity: bool = True
    gravity_acceleration: Vec3 | None = None  # 2D: instead of (0, −9.80665, 0) m/s²

    # contact and accuracy; dhat, epsv, dtol and newton_tol are relative to l
    self_collision: bool = True
    self_friction: float = 0.0
    kappa: float | None = None  # None: adaptive, as the original
    dhat: float = 1e-3
    dhat_start: float | None = None  # tuning homotopy start (None: = dhat)
    dhat_abs: float | None = None  # beyond the original: absolute d-hat in metres
    epsv: float = 1e-3
    epsv_abs: float | None = None  # beyond the original: absolute eps_v in m/s
    dtol: float = 1e-9
    friction_iterations: int = 1
    newton_tol: tuple[float, ...] = (1e-2,)
    kappa_min_multiplier: float = 1e11
    use_abs_parameters: bool = False
    constraint_solver: str = "interiorPoint"  # or "SQP" / "QP" (baselines)
    constraint_type: str = "volume"  # SQP / QP: the collision constraint function
    constraint_offset: float = 0.0  # SQP / QP: c(x) >= offset (units of c)
    active_set_convergence: bool = False  # SQP / QP: iterate until no constraint is added
    contact_formulation: str = "barrier"  # beyond the original: "penalty" for baselines
    penalty_stiffness: float = 0.0  # N/m per pair, with the penalty formulation
    contact_barrier: str = "ipc"  # 2D: or "lecture", its area-weighted barrier
    linear_solver: str | None = None  # None: the fastest installed

    # boundary-condition gates and legacy scene switches
    dbc_time_range: tuple[float, float] = (0.0, INF)
    nbc_time_range: tuple[float, float] = (0.0, INF)
    script: str = "null"
    script_params: tuple[float, ...] = ()
    handle_ratio: float = 0.01
    size: float = -1.0  # <= 0: off
    rotate_model: tuple[float, float, float, float] | None = None  # axis, degrees
    restart: Path | None = None

    # output
    playback_speed: float = 1.0
    append_str: str = ""

    # provenance and diagnostics (not part of the scene's meaning)
    source: Path | None = None
    warnings: tuple[str, ...] = ()
    ignored: tuple[str, ...] = ()  # viewer-only keys seen
    # where each value was written: TOML key path (``solver.linear_solver``) -> line
    key_lines: Mapping[str, int] = field(default_factory=dict)
    # the overrides applied to the file's values (``load_scene(path, overrides)``, ``ipcsim
    # run --set``): dotted key as given -> value; their values are in the fields above
    overrides: Mapping[str, object] = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        """ceil(duration / dt), guarded against round-off (5 / 0.025 is 200, not 201)."""
        return max(1, math.ceil(self.duration / self.dt - 1e-9))

    def line_of(self, key: str) -> int | None:
        """The line that wrote ``key`` (or the nearest enclosing key), None if unknown."""
        while key:
            if key in self.key_lines:
                return self.key_lines[key]
            cut = max(key.rfind("."), key.rfind("["))
            key = key[:cut] if cut > 0 else ""
        return None

    def newton_tol_at(self, step: int) -> float:
        """Per-step tolerance list: step i uses entry i, later steps the last entry."""
        return self.newton_tol[min(step, len(self.newton_tol) - 1)]


DEFAULTS = SceneSpec()  # every default, for the readers and writers to compare with
