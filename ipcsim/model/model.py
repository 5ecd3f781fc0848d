"""The frozen simulation model: arrays built once from a SceneSpec by ``build_model``.

Vertices of all shapes are concatenated in scene order (the original's global vertex
numbering); ``meshCO`` obstacles follow as extra, fixed "obstacle" shapes so that one
collision mesh covers everything. Every array is read-only.

Units: SI. Angles are radians here (scene files use degrees). Relative scene parameters
(d-hat, eps_v, dtol, Newton tolerance) are stored absolute, i.e. already multiplied by the
rest bounding-box diagonal l where the scene says so.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import ClassVar

from msgspec import Struct, field
from msgspec.structs import force_setattr
import numpy as np

from ..records import ByMeaning
from .surface import index_set

INF = math.inf
GRAVITY = (0.0, -9.80665, 0.0)  # m/s², y up, as the original


def _freeze(obj, names) -> None:
    """Copy the named array fields of a frozen record into read-only C-contiguous arrays."""
    for name in names:
        value = getattr(obj, name)
        if isinstance(value, np.ndarray):
            arr = np.array(value, order="C", copy=True)
            arr.flags.writeable = False
            force_setattr(obj, name, arr)


def _vec3(v) -> tuple[float, float, float]:
    x, y, z = (float(c) for c in v)
    return (x, y, z)


def _window(w) -> tuple[float, float]:
    return (float(w[0]), float(w[1]))


def _in_window(t: float, window: tuple[float, float]) -> bool:
    """Time windows are half-open: t0 <= t < t1."""
    return window[0] <= t < window[1]


class Release(Struct, frozen=True, eq=False):
    """A condition on the positions at the start of a step: the smallest coordinate
    ``axis`` over ``vertices`` is above ``above``. A Dirichlet set with a release is
    inactive (its vertices are free) at every step that starts with the condition met
    (legacy ``dragright`` lets go of the body once it has passed every obstacle)."""

    vertices: np.ndarray  # (k,) int64 vertices whose smallest coordinate is watched
    axis: int
    above: float

    def __post_init__(self):
        force_setattr(self, "vertices", index_set(self.vertices))
        force_setattr(self, "axis", int(self.axis))
        force_setattr(self, "above", float(self.above))
        _freeze(self, ("vertices",))

    def met(self, x: np.ndarray) -> bool:
        return bool(len(self.vertices)) and bool(x[self.vertices, self.axis].min() > self.above)


class DirichletSet(Struct, frozen=True, eq=False):
    """Vertices moved kinematically while active: each step of length h,
    x' = R (x - c) + c + v h with R = Rx(wx h) Ry(wy h) Rz(wz h). Active while the step
    starts inside ``time_range`` (and the global gate, if ``gated``) and, with a
    ``release``, while its condition is not met at the step's start positions."""

    vertices: np.ndarray  # (k,) int64, sorted unique global indices
    linear_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m/s, world frame
    angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # rad/s
    time_range: tuple[float, float] = (0.0, INF)  # active while t0 <= t < t1
    centre: tuple[float, float, float] | None = None  # None: midpoint of the set's current AABB
    gated: bool = False  # the scene's global DBCTimeRange applies as well
    source: str = ""  # where it came from, for messages
    release: Release | None = None  # inactive at steps that start with it met

    def __post_init__(self):
        force_setattr(self, "vertices", index_set(self.vertices))
        force_setattr(self, "linear_velocity", _vec3(self.linear_velocity))
        force_setattr(self, "angular_velocity", _vec3(self.angular_velocity))
        force_setattr(self, "time_range", _window(self.time_range))
        if self.centre is not None:
            force_setattr(self, "centre", _vec3(self.centre))
        _freeze(self, ("vertices",))

    @property
    def moving(self) -> bool:
        return any(v != 0.0 for v in self.linear_velocity + self.angular_velocity)

    def active(self, t: float, gate: tuple[float, float] = (0.0, INF),
               x: np.ndarray | None = None) -> bool:
        """Active during the step that starts at time t (positions x; without x a release
        counts as not met)."""
        if not (_in_window(t, self.time_range) and (not self.gated or _in_window(t, gate))):
            return False
        return self.release is None or x is None or not self.release.met(x)


class NeumannSet(Struct, frozen=True, eq=False):
    """Extra body acceleration a (m/s^2) on free vertices while active: force m_i a."""

    vertices: np.ndarray  # (k,) int64
    acceleration: tuple[float, float, float]
    time_range: tuple[float, float] = (0.0, INF)
    gated: bool = True  # the scene's global NBCTimeRange applies as well
    source: str = ""

    def __post_init__(self):
        force_setattr(self, "vertices", index_set(self.vertices))
        force_setattr(self, "acceleration", _vec3(self.acceleration))
        force_setattr(self, "time_range", _window(self.time_range))
        _freeze(self, ("vertices",))

    def active(self, t: float, gate: tuple[float, float] = (0.0, INF)) -> bool:
        return _in_window(t, self.time_range) and (not self.gated or _in_window(t, gate))


class MeshSequence(ByMeaning, Struct, frozen=True):
    """All vertices [start, stop) of one shape follow ``<folder>/<k>.<ext>`` at step k
    (0-based step index; frame 0 is the initial placement), in world coordinates."""

    provenance: ClassVar[tuple[str, ...]] = ("line",)
    shape: int
    start: int
    stop: int
    folder: Path
    ext: str  # "msh" | "obj" | "seg" | "pt"
    line: int | None = None

    def frame_path(self, k: int) -> Path:
        return Path(self.folder) / f"{k}.{self.ext}"


class TimeSettings(Struct, frozen=True):
    """The clock and the integrator: backward Euler ("BE"), Newmark ("NM", β, γ) or BDF2
    ("BDF2"); with ``tolerance``, adaptive steps (dt the first and largest)."""

    dt: float  # s
    n_steps: int
    integrator: str = "BE"
    newmark_beta: float = 0.25
    newmark_gamma: float = 0.5
    tolerance: float | None = None  # m: the local error allowed, τ·l (None: fixed steps)
    duration: float | None = None  # s: the scene's simulated time (None: n_steps·dt)


class SolverSettings(Struct, frozen=True):
    """Every number Newton, its line search and the friction lagging use."""

    newton_tolerances: tuple[float, ...]  # absolute ‖p‖∞ per step; later steps the last
    warm_start: int = 0  # the original's warmStart 0..5
    linear_solver: str | None = None  # None: the fastest installed
    max_newton_iterations: int = 5000  # reported in steps.csv and warned about when hit
    friction_iterations: int = 1  # fricIterAmt: lagging updates per step (≤ 0: until settled)
    friction_iteration_cap: int = 20  # fricIterAmt ≤ 0: lagging updates per step at most
    friction_ramp_resolution: float = 0.1  # ramp pairs that must slide: p changes slip < this·ε
    kinematic_completion: float = 1e-3  # prescribed motion done when ≥ 99.9 % of it is
    max_halvings: int = 40  # line-search halvings before giving up
    roundoff_tolerance_factor: float = 1e3  # failed line search within this · tol: converged

    def newton_tol(self, step: int) -> float:
        """Absolute tolerance on ‖p‖∞ of step ``step`` (0-based)."""
        return self.newton_tolerances[min(step, len(self.newton_tolerances) - 1)]


class ConstraintSolverSettings(Struct, frozen=True):
    """The SQP and QP baselines (``constraintSolver SQP|QP``): contact as constraints
    c(x) ≥ offset linearised in a sequence of QPs (SQP) or in one per step (QP), instead of
    IPC's barrier. ``constraint_type`` "volume", "gap" (the original's graphics /
    gapFunction) or "Verschoor"."""

    method: str  # "SQP" | "QP"
    constraint_type: str
    offset: float  # in the units of c (m for gap and Verschoor, m³ for volume)
    active_set_convergence: bool = False  # iterate until the step adds no constraint
    max_iterations: int = 100  # QPs per step (SQP iterations, QP active-set rounds)
    qp_eps_rel: float = 1e-3  # OSQP's relative tolerance (the original's setting)
    qp_max_iterations: int = 4000  # OSQP's ADMM iterations
    blow_up_factor: float = 100.0  # a vertex moving more than this × the scene's extent


_ARRAY_FIELDS = (
    "rest_positions", "initial_positions", "initial_velocities", "tets", "tet_shape",
    "rest_volumes", "Dm_inv", "lame", "mass", "vertex_shape", "shape_offsets",
    "surface_triangles", "triangle_shape", "surface_edges", "edge_shape",
    "surface_vertices", "plane_origins", "plane_normals", "plane_friction", "always_kinematic",
    "elastic_tets", "gravity", "plane_velocities", "plane_limits", "tri_elements",
    "tri_element_shape", "tri_rest_areas", "tri_Dm_inv", "tri_lame", "elastic_tri_elements",
    "springs", "spring_shape", "spring_rest_length_sq", "spring_stiffness", "elastic_springs",
    "node_contact_length",
)


def _empty(*shape, dtype=np.float64):
    return field(default_factory=lambda: np.zeros(shape, dtype=dtype))


class Model(Struct, frozen=True, eq=False):
    """Everything the simulation needs that does not change during a run. Nothing after
    the builder reads the scene: every setting is resolved into these fields."""

    time: TimeSettings
    solver: SolverSettings
    energy: str  # "NH" (neo-Hookean) | "FCR" (fixed corotated)

    # vertices (n)
    rest_positions: np.ndarray  # (n, 3) float64
    initial_positions: np.ndarray  # (n, 3) float64
    initial_velocities: np.ndarray  # (n, 3) float64
    mass: np.ndarray  # (n,) lumped: rho V / 4 per tet corner; codim as §5.2
    vertex_shape: np.ndarray  # (n,) int64 shape id
    always_kinematic: np.ndarray  # (n,) bool: codim shapes, velocity / meshSeq shapes, obstacles

    # tets (m)
    tets: np.ndarray  # (m, 4) int64 global vertex indices, positively oriented
    tet_shape: np.ndarray  # (m,) int64
    rest_volumes: np.ndarray  # (m,) float64 > 0
    Dm_inv: np.ndarray  # (m, 3, 3) inverse of [x1 - x0, x2 - x0, x3 - x0] (columns), rest
    lame: np.ndarray  # (m, 2) (mu, lambda) per tet
    elastic_tets: np.ndarray  # (m,) bool: tets of simulated (non-kinematic) shapes

    # shapes (scene shapes, then meshCO obstacles)
    shape_names: tuple[str, ...]
    shape_kinds: tuple[str, ...]  # "tet" | "surface" | "segments" | "points" | "obstacle"
    shape_offsets: np.ndarray  # (s + 1,) vertex range of shape i is [off[i], off[i+1])

    # collision mesh
    surface_triangles: np.ndarray  # (k, 3) int64; tet boundaries outward, .obj and meshCO
    triangle_shape: np.ndarray  # (k,) int64
    surface_edges: np.ndarray  # (e, 2) int64; edges of surface triangles + .seg segments
    edge_shape: np.ndarray  # (e,) int64
    surface_vertices: np.ndarray  # (v,) int64 sorted: every vertex that can collide

    # analytic planes (ground / halfSpace): solid side opposite the normal
    plane_origins: np.ndarray  # (p, 3)
    plane_normals: np.ndarray  # (p, 3) unit
    plane_friction: np.ndarray  # (p,)

    # absolute parameters
    bbox_diagonal: float  # l: rest AABB diagonal of all tet shapes
    dhat: float  # barrier activation distance (m)
    epsv: float  # static-friction velocity threshold (m/s)
    dtol: float  # tiny-distance tolerance (m)
    kappa: float | None  # barrier stiffness; None = adaptive
    kappa_min_multiplier: float  # c in κ_min = c·m̄ / (4 d₀ b''(d₀))
    self_collision: bool  # contact between (and within) the scene's own shapes
    self_friction: float  # μ of every mesh–mesh contact
    contact_formulation: str  # "barrier" (IPC) | "penalty" (the baseline of benchmarks/)
    penalty_stiffness: float  # k of the penalty formulation (N/m per pair)
    damping_stiffness: float  # effective dampingStiff (dampingRatio r > 0: 0.75 r h^3)
    gravity: np.ndarray  # (3,) m/s^2 (zeros with turnOffGravity)

    # boundary conditions
    dbc_sets: tuple[DirichletSet, ...]
    nbc_sets: tuple[NeumannSet, ...]
    mesh_sequences: tuple[MeshSequence, ...]
    dbc_time_range: tuple[float, float]  # the scene's DBCTimeRange gate
    nbc_time_range: tuple[float, float]  # the scene's NBCTimeRange gate

    # what the scene needs, and what the builder noticed
    terms: tuple[str, ...]
    warnings: tuple[str, ...] = ()

    # contact as constraints of the SQP / QP baselines (None: IPC's barrier)
    constraint_solver: ConstraintSolverSettings | None = None

    # moving planes (2D scenes): the origin moves at its velocity while (limit − origin)·v
    # > 0 at a step's start; (p, 3) each (limits NaN: none), empty where the builder set
    # no motion (all planes still)
    plane_velocities: np.ndarray = _empty(0, 3)
    plane_limits: np.ndarray = _empty(0, 3)

    # 2D scenes (dimension 2): everything lies in the plane z = 0 (positions stay (n, 3),
    # z = 0); the bodies are triangles (plane strain) or springs, and their boundary edges
    # (in surface_edges, outward normal on the right of each) and vertices collide
    dimension: int = 3
    tri_elements: np.ndarray = _empty(0, 3, dtype=np.int64)  # (t, 3) counter-clockwise
    tri_element_shape: np.ndarray = _empty(0, dtype=np.int64)  # (t,)
    tri_rest_areas: np.ndarray = _empty(0)  # (t,) > 0
    tri_Dm_inv: np.ndarray = _empty(0, 2, 2)  # (t, 2, 2) inverse of [x1 − x0, x2 − x0], rest
    tri_lame: np.ndarray = _empty(0, 2)  # (t, 2) (mu, lambda): plane strain
    elastic_tri_elements: np.ndarray = _empty(0, dtype=bool)  # (t,) simulated, with elasticity
    springs: np.ndarray = _empty(0, 2, dtype=np.int64)  # (k, 2) mass-spring shapes' springs
    spring_shape: np.ndarray = _empty(0, dtype=np.int64)  # (k,)
    spring_rest_length_sq: np.ndarray = _empty(0)  # (k,) l²
    spring_stiffness: np.ndarray = _empty(0)  # (k,) k of E = ½ k l² (|d|²/l² − 1)²
    elastic_springs: np.ndarray = _empty(0, dtype=bool)  # (k,) springs of simulated shapes
    node_contact_length: np.ndarray = _empty(0)  # (n,) half the boundary edges at a vertex
    contact_barrier: str = "ipc"  # "lecture": its barrier, weighted by node_contact_length

    def __post_init__(self):
        _freeze(self, _ARRAY_FIELDS)

    # ---------------------------------------------------------------- sizes
    @property
    def n_vertices(self) -> int:
        return len(self.rest_positions)

    @property
    def n_tets(self) -> int:
        return len(self.tets)

    @property
    def n_shapes(self) -> int:
        return len(self.shape_kinds)

    @property
    def n_scene_shapes(self) -> int:
        """Shapes of the scene file (without the appended meshCO obstacles)."""
        return sum(1 for k in self.shape_kinds if k != "obstacle")

    @property
    def n_planes(self) -> int:
        return len(self.plane_origins)

    @property
    def dt(self) -> float:
        return self.time.dt

    @property
    def n_steps(self) -> int:
        return self.time.n_steps

    # ---------------------------------------------------------------- parameters
    def newton_tol(self, step: int) -> float:
        """Absolute Newton tolerance on ||p||_inf for step ``step`` (0-based):
        tol * l * h, or tol as given with useAbsParameters."""
        return self.solver.newton_tol(step)

    # ---------------------------------------------------------------- which terms
    @property
    def has_obstacles(self) -> bool:
        return "obstacle" in self.shape_kinds

    @property
    def needs_self_contact(self) -> bool:
        """Self collision on and the scene's own shapes have something that can touch:
        some triangle (PT pairs even within one body), two edges, or an edge and another
        point."""
        if not self.self_collision:
            return False
        own_tri = int(np.count_nonzero(~self._obstacle_mask(self.triangle_shape)))
        own_edges = int(np.count_nonzero(~self._obstacle_mask(self.edge_shape)))
        own_points = int(np.count_nonzero(~self._obstacle_mask(self.vertex_shape[self.surface_vertices])))
        return own_tri > 0 or own_edges > 1 or (own_edges == 1 and own_points > 2)

    @property
    def needs_mesh_contact(self) -> bool:
        """Any mesh-mesh contact (self contact, or meshCO obstacles, which collide even
        with selfCollisionOff)."""
        return self.needs_self_contact or self.has_obstacles

    @property
    def needs_plane_contact(self) -> bool:
        return self.n_planes > 0

    @property
    def needs_friction(self) -> bool:
        """Some contact with mu > 0: a plane with friction, or mesh contact (self contact
        or meshCO obstacles) with selfFric, which every mesh contact uses. Never with the
        SQP / QP baselines (frictionless)."""
        if self.constraint_solver is not None:
            return False
        planes = bool(np.any(self.plane_friction > 0.0))
        return planes or (self.self_friction > 0.0 and self.needs_mesh_contact)

    @property
    def needs_damping(self) -> bool:
        return self.damping_stiffness > 0.0

    @property
    def plane_contact_vertices(self) -> np.ndarray:
        """Collision vertices that take part in point-plane contact: every surface vertex
        that is not kinematic for the whole run (codim, velocity and meshSeq shapes and
        obstacles move as prescribed; halfspaces never push them). In 2D every vertex of a
        body, as the lecture has it: a mass-spring body may fold an inner node out."""
        vertices = self.surface_vertices
        if self.dimension == 2:
            body = np.zeros(self.n_vertices, dtype=bool)
            body[self.tri_elements.ravel()] = True
            body[self.springs.ravel()] = True
            body[vertices] = True
            vertices = np.flatnonzero(body)
        return vertices[~self.always_kinematic[vertices]]

    @property
    def kinematic_surface_triangles(self) -> np.ndarray:
        """Triangles of the shapes that have no tets (.obj shapes and meshCO obstacles),
        e.g. for writing frames: tets plus these cover every triangle of the scene."""
        kinds = np.array([k in ("surface", "obstacle") for k in self.shape_kinds], dtype=bool)
        return self.surface_triangles[kinds[self.triangle_shape]] if len(self.triangle_shape) \
            else self.surface_triangles

    @property
    def obstacle_vertices(self) -> np.ndarray:
        """(n,) bool: the vertices of obstacle shapes (meshCO and the like)."""
        return self._obstacle_mask(self.vertex_shape)

    def _obstacle_mask(self, shape_ids: np.ndarray) -> np.ndarray:
        kinds = np.array([k == "obstacle" for k in self.shape_kinds], dtype=bool)
        return kinds[shape_ids] if len(shape_ids) else np.zeros(0, dtype=bool)

    def shape_vertices(self, shape: int) -> slice:
        return slice(int(self.shape_offsets[shape]), int(self.shape_offsets[shape + 1]))

    def summary(self) -> dict[str, object]:
        """Counts for `ipcsim check` and logs."""
        kinds: dict[str, int] = {}
        for k in self.shape_kinds:
            kinds[k] = kinds.get(k, 0) + 1
        return {
            "shapes": kinds,
            "vertices": self.n_vertices,
            **({"triangles": len(self.tri_elements), "springs": len(self.springs)}
               if self.dimension == 2 else {"tets": self.n_tets}),
            "surface triangles": len(self.surface_triangles),
            "surface edges": len(self.surface_edges),
            "collision vertices": len(self.surface_vertices),
            "kinematic vertices at t=0": int(np.count_nonzero(self.kinematic_mask_at(0.0))),
            "planes": self.n_planes,
            "l (bbox diagonal)": self.bbox_diagonal,
            "dhat": self.dhat,
            "steps": self.n_steps,
        }

    def kinematic_mask_at(self, t: float, x: np.ndarray | None = None) -> np.ndarray:
        """(n,) bool: vertices kinematic during the step starting at time t (from
        positions x: sets with a release depend on them; without x, the initial ones)."""
        mask = np.array(self.always_kinematic, copy=True)
        x = self.initial_positions if x is None else x
        for s in self.dbc_sets:
            if s.active(t, self.dbc_time_range, x):
                mask[s.vertices] = True
        return mask
