"""Checks on a whole ``SceneSpec`` that both readers share.

Each reader checks the syntax of its own format (tokens, types, unknown keys) and hands the
finished spec here together with ``lines``: where each value was written, keyed by its TOML
key path (``time.dt``, ``shapes[2].dbc[0]``, ``planes[1]``; the text reader uses the same
keys for its keywords). A failing check raises ``SceneError(path, line, message)`` naming
the value the way the user wrote it (a text keyword, or a TOML key path).

Checks that need the mesh content (unreadable mesh, no tets, inverted tets, NaN
coordinates, a DBC box that selects nothing) belong to the model builder.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

from ..errors import SceneError, excerpt as _q
from .spec import (CONSTRAINT_SOLVERS, CONSTRAINT_TYPES, CONTACT_BARRIERS, DEFAULTS,
                   DIMENSIONS, ENERGIES, INTEGRATORS, NODE_MASSES, SIMULATED_KINDS,
                   SUPPORTED_SCRIPTS, UNSUPPORTED_CONSTRAINT_TYPES, SceneSpec)

__all__ = ["validate_scene", "LINEAR_SOLVERS", "MAX_STEPS", "text_name"]

# Names `linearSolver` / `solver.linear_solver` accept (lower case). The solver maps the
# original's CHOLMOD/EIGEN/AMGCL onto what is installed; None means "the fastest one".
LINEAR_SOLVERS = ("cholmod", "pardiso", "scipy", "superlu", "eigen", "amgcl")

# How the text format names a value, by its TOML key path with indices removed.
_TEXT_NAMES = {
    "time.duration": "`time` duration",
    "time.dt": "`time` step dt",
    "time.tolerance": "`timeTolerance`",
    "material.density": "`density`",
    "material.youngs_modulus": "`stiffness` Young's modulus",
    "material.poisson_ratio": "`stiffness` Poisson ratio",
    "material.energy": "`energy`",
    "integrator.type": "`timeIntegration`",
    "integrator.newmark_beta": "`timeIntegration NM` beta",
    "integrator.newmark_gamma": "`timeIntegration NM` gamma",
    "integrator.damping_stiff": "`dampingStiff`",
    "integrator.damping_ratio": "`dampingRatio`",
    "integrator.warm_start": "`warmStart`",
    "contact.self_friction": "`selfFric`",
    "contact.kappa": "`kappa` (or `tuning` entry 1)",
    "contact.dhat": "`dHat` (or `tuning` entry 3)",
    "contact.dhat_start": "`tuning` initial dHat (entry 2)",
    "contact.dhat_abs": "`dHatAbs`",
    "contact.epsv": "`epsv` (or `tuning` entry 6)",
    "contact.epsv_abs": "`epsvAbs`",
    "contact.dtol": "`tuning` dTol (entry 4)",
    "contact.friction_iterations": "`fricIterAmt`",
    "contact.kappa_min_multiplier": "`kappaMinMultiplier`",
    "solver.newton_tol": "`tol`",
    "solver.constraint_solver": "`constraintSolver`",
    "solver.constraint_type": "`constraintType`",
    "solver.constraint_offset": "`constraintOffset`",
    "solver.linear_solver": "`linearSolver`",
    "scene.dbc_time_range": "`DBCTimeRange`",
    "scene.nbc_time_range": "`NBCTimeRange`",
    "scene.script": "`script`",
    "scene.script_params": "`script` parameters",
    "scene.handle_ratio": "`handleRatio`",
    "scene.size": "`size`",
    "scene.rotate_model": "`rotateModel`",
    "output.playback_speed": "`playBackSpeed`",
    "output.append_str": "`appendStr`",
    "shapes[]": "shape",
    "shapes[].translation": "shape translation",
    "shapes[].rotation_deg": "shape rotation",
    "shapes[].scale": "shape scale",
    "shapes[].material.density": "`material` density",
    "shapes[].material.youngs_modulus": "`material` Young's modulus",
    "shapes[].material.poisson_ratio": "`material` Poisson ratio",
    "shapes[].linear_velocity": "`linearVelocity`",
    "shapes[].angular_velocity_deg": "`angularVelocity`",
    "shapes[].init_velocity.linear": "`initVel` linear velocity",
    "shapes[].init_velocity.angular_deg": "`initVel` angular velocity",
    "shapes[].dbc[].box_min": "`DBC` box min corner",
    "shapes[].dbc[].box_max": "`DBC` box max corner",
    "shapes[].dbc[].linear_velocity": "`DBC` velocity",
    "shapes[].dbc[].angular_velocity_deg": "`DBC` angular velocity",
    "shapes[].dbc[].time_range": "`DBC` time range",
    "shapes[].nbc[].box_min": "`NBC` box min corner",
    "shapes[].nbc[].box_max": "`NBC` box max corner",
    "shapes[].nbc[].acceleration": "`NBC` acceleration",
    "shapes[].nbc[].time_range": "`NBC` time range",
    "planes[].origin": "`halfSpace` origin",
    "planes[].height": "`ground` height",
    "planes[].normal": "`halfSpace` normal",
    "planes[].stiffness": "`halfSpace` stiffness",
    "mesh_obstacles[].position": "`meshCO` position",
    "mesh_obstacles[].size": "`meshCO` scale",
    "mesh_obstacles[].stiffness": "`meshCO` stiffness",
    "mesh_obstacles[].friction": "`meshCO` friction",
    "mesh_obstacles[].rotation_deg": "`meshCO rotate` angles",
}

_INDEX = re.compile(r"\[\d+\]")

# Bounds on numbers that no scene needs to exceed; beyond them the simulation's arithmetic
# would overflow (volumes, masses, barrier stiffness) and fail with a misleading message.
MAX_STEPS = 10**8
MAX_FRICTION_ITERATIONS = 100
MAX_DENSITY = 1e9  # kg/m^3
MAX_LENGTH = 1e9  # m: translations, plane origins, obstacle sizes and positions
MAX_SCALE = 1e9  # shape scale factors, in size


def text_name(key: str) -> str:
    """The text format's name for the value at TOML key path ``key``."""
    return _TEXT_NAMES.get(_INDEX.sub("[]", key), key)


def line_of(lines: Mapping[str, int], key: str) -> int | None:
    """Line of ``key``, else of the nearest enclosing key (``a[1].b.c`` -> ``a[1].b`` ...)."""
    while key:
        if key in lines:
            return lines[key]
        cut = max(key.rfind("."), key.rfind("["))
        key = key[:cut] if cut > 0 else ""
    return None


def warning_at(source, lines: Mapping[str, int], key: str, message: str) -> str:
    """``file:line: warning: message``, the line that of ``key`` (``line_of``)."""
    where = source or "<scene>"
    line = line_of(lines, key)
    return f"{where}:{line}: warning: {message}" if line is not None \
        else f"{where}: warning: {message}"


def _num(x) -> str:
    return repr(float(x)) if isinstance(x, float) else str(x)


class _Checker:
    def __init__(self, source, fmt: str, lines: Mapping[str, int]):
        self.source = source
        self.fmt = fmt
        self.lines = lines
        self.warnings: list[str] = []

    def name(self, key: str, plane_kind: str | None = None) -> str:
        if self.fmt != "txt":
            return key
        if plane_kind is not None and key.endswith(".friction"):
            return f"`{plane_kind}` friction"
        return text_name(key)

    def fail(self, key: str, message: str, plane_kind: str | None = None):
        raise SceneError(
            self.source, line_of(self.lines, key), f"{self.name(key, plane_kind)} {message}"
        )

    def warn(self, key: str, message: str) -> None:
        self.warnings.append(warning_at(self.source, self.lines, key, message))

    # value checks ---------------------------------------------------------------------

    def one_of(self, key: str, value, allowed) -> None:
        if value not in allowed:
            self.fail(key, f"must be one of {', '.join(allowed)} (got {_q(repr(value))})")

    def number(self, key, x, *, positive=False, nonneg=False, lo=None, hi_open=None,
               plane_kind=None):
        """Finite, and optionally > 0, >= 0, or in [lo, hi_open)."""
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            self.fail(key, f"must be a number (got {_q(repr(x))})", plane_kind)
        if not math.isfinite(x):
            self.fail(key, f"must be finite (got {_num(x)})", plane_kind)
        if positive and not x > 0:
            self.fail(key, f"must be > 0 (got {_num(x)})", plane_kind)
        if nonneg and not x >= 0:
            self.fail(key, f"must be >= 0 (got {_num(x)})", plane_kind)
        if lo is not None and not (lo <= x < hi_open):
            self.fail(key, f"must lie in [{_num(lo)}, {_num(hi_open)}) (got {_num(x)})",
                      plane_kind)

    def vector(self, key, v, n=3, *, length=False):
        """``n`` finite numbers; ``length``: each a length of at most MAX_LENGTH."""
        if len(v) != n:
            self.fail(key, f"needs {n} numbers (got {len(v)})")
        for x in v:
            self.number(key, x)
            if length:
                self.length(key, x)

    def length(self, key, x):
        """A length in metres no scene needs to exceed (coordinates, sizes)."""
        if abs(x) > MAX_LENGTH:
            self.fail(key, f"{_num(x)} m is beyond any scene (lengths and coordinates are "
                           f"at most {MAX_LENGTH:.0e} m)")

    def scale(self, key, v):
        """Per-axis scale factors, none zero or beyond [1/MAX_SCALE, MAX_SCALE] in size."""
        self.vector(key, v)
        if any(x == 0 for x in v):
            self.fail(key, f"has a zero component {tuple(v)}: the shape would be flat")
        if any(not 1.0 / MAX_SCALE <= abs(x) <= MAX_SCALE for x in v):
            self.fail(key, f"{tuple(v)} has a factor beyond {1.0 / MAX_SCALE:.0e}.."
                           f"{MAX_SCALE:.0e} in size")

    def time_range(self, key, r):
        t0, t1 = r
        self.number(key, t0)
        # the upper end may be +inf ("never ends"); NaN or -inf make no sense
        if isinstance(t1, bool) or not isinstance(t1, (int, float)) or math.isnan(t1) \
                or t1 == -math.inf:
            self.fail(key, f"end must be a number or inf (got {_q(repr(t1))})")
        if t0 > t1:
            self.fail(key, f"starts after it ends ({_num(t0)} > {_num(t1)})")

    def box(self, key, lo, hi):
        self.vector(f"{key}.box_min", lo)
        self.vector(f"{key}.box_max", hi)
        for axis, a, b in zip("xyz", lo, hi):
            if a > b:
                self.fail(f"{key}.box_min",
                          f"is above the max corner on the {axis} axis ({_num(a)} > {_num(b)}); "
                          "the box would select nothing")

    def material(self, key, density, youngs, poisson):
        self.number(f"{key}.density", density, positive=True)
        if density > MAX_DENSITY:
            self.fail(f"{key}.density", f"{_num(density)} kg/m^3 is beyond any material "
                                        f"(at most {MAX_DENSITY:.0e}; osmium, the densest "
                                        "element, has 2.26e4)")
        self.number(f"{key}.youngs_modulus", youngs, positive=True)
        # nu = 0.5 is incompressible: lambda = E nu / ((1 + nu)(1 - 2 nu)) is infinite
        self.number(f"{key}.poisson_ratio", poisson, lo=0.0, hi_open=0.5)


def validate_scene(
    spec: SceneSpec,
    *,
    source=None,
    lines: Mapping[str, int] | None = None,
    fmt: str = "toml",
) -> tuple[str, ...]:
    """Raise ``SceneError`` for the first thing wrong with ``spec``; return warnings.

    ``source`` is the file named in messages (default: ``spec.source``); ``lines`` maps TOML
    key paths to line numbers; ``fmt`` ("txt" or "toml") chooses how values are named.
    """
    c = _Checker(source if source is not None else spec.source, fmt, lines or {})
    _check_dimension(c, spec)
    _check_time(c, spec)
    _check_material_and_integrator(c, spec)
    _check_contact(c, spec)
    _check_solver(c, spec)
    _check_scene_switches(c, spec)
    _check_shapes(c, spec)
    _check_planes_and_obstacles(c, spec)
    return tuple(c.warnings)


def _check_dimension(c: _Checker, s: SceneSpec) -> None:
    """What a scene of its dimension may hold: the lecture's conventions, rectangles,
    springs and moving planes only in 2D; legacy scripts, ``rotate_model``, restarts,
    meshCO obstacles, mesh sequences and the baselines only in 3D."""
    if s.dimension not in DIMENSIONS:
        c.fail("scene.dimension", f"must be 2 or 3 (got {_q(repr(s.dimension))})")
    c.one_of("material.node_masses", s.node_masses, NODE_MASSES)
    c.one_of("contact.barrier", s.contact_barrier, CONTACT_BARRIERS)
    if s.dimension == 3:
        two_d = [("material.node_masses", s.node_masses != DEFAULTS.node_masses),
                 ("scene.gravity_acceleration", s.gravity_acceleration is not None),
                 ("contact.barrier", s.contact_barrier != DEFAULTS.contact_barrier)]
        two_d += [(f"shapes[{i}].kind", sh.rectangle is not None)
                  for i, sh in enumerate(s.shapes)]
        two_d += [(f"shapes[{i}].spring_stiffness", sh.spring_stiffness is not None)
                  for i, sh in enumerate(s.shapes)]
        two_d += [(f"planes[{k}].velocity", p.velocity != (0.0, 0.0, 0.0) or
                   p.limit is not None) for k, p in enumerate(s.planes)]
        for key, present in two_d:
            if present:
                c.fail(key, "is a setting of 2D scenes ([scene] dimension = 2)")
        return
    three_d = [("scene.script", s.script != "null"), ("scene.rotate_model", s.rotate_model),
               ("scene.restart", s.restart is not None),
               ("mesh_obstacles", bool(s.mesh_obstacles)),
               ("solver.constraint_solver", s.constraint_solver != "interiorPoint"),
               ("contact.formulation", s.contact_formulation != "barrier")]
    three_d += [(f"shapes[{i}].mesh_sequence", sh.mesh_sequence is not None)
                for i, sh in enumerate(s.shapes)]
    three_d += [(f"shapes[{i}].kind", sh.kind in ("tet", "surface"))
                for i, sh in enumerate(s.shapes)]
    for key, present in three_d:
        if present:
            c.fail(key, "has no 2D meaning (this is a 2D scene)")
    if s.gravity_acceleration is not None:
        c.vector("scene.gravity_acceleration", s.gravity_acceleration)
    for k, p in enumerate(s.planes):
        if p.normal[2] != 0.0 or p.origin[2] != 0.0 or p.velocity[2] != 0.0:
            c.fail(f"planes[{k}]", "must lie in the plane z = 0 (a 2D scene's planes are lines)")


def _check_time(c: _Checker, s: SceneSpec) -> None:
    # IPC takes ceil(duration / dt) implicit steps of h = dt
    c.number("time.dt", s.dt, positive=True)
    c.number("time.duration", s.duration, positive=True)
    if s.duration < s.dt * (1 - 1e-12):
        c.fail("time.duration", f"({_num(s.duration)} s) is shorter than one time step "
                                f"dt = {_num(s.dt)} s")
    steps = s.duration / s.dt
    if not steps <= MAX_STEPS:  # also catches an overflow to inf
        c.fail("time.duration", f"({_num(s.duration)} s) with dt = {_num(s.dt)} s makes "
                                f"{steps:.3g} time steps; ipcsim runs at most {MAX_STEPS:.0e}")
    if s.time_tolerance is not None:
        # a position error relative to the scene size, as d-hat is
        c.number("time.tolerance", s.time_tolerance, positive=True)
        if not s.time_tolerance < 1.0:
            c.fail("time.tolerance", f"must be below 1: it is an error relative to the "
                                     f"scene size (got {_num(s.time_tolerance)})")


def _check_material_and_integrator(c: _Checker, s: SceneSpec) -> None:
    c.material("material", s.density, s.youngs_modulus, s.poisson_ratio)
    c.one_of("material.energy", s.energy, ENERGIES)
    c.one_of("integrator.type", s.integrator, INTEGRATORS)
    # Newmark's incremental potential is scaled by beta: beta = 0 would be explicit
    c.number("integrator.newmark_beta", s.newmark_beta, positive=True)
    c.number("integrator.newmark_gamma", s.newmark_gamma, nonneg=True)
    c.number("integrator.damping_stiff", s.damping_stiff, nonneg=True)
    c.number("integrator.damping_ratio", s.damping_ratio, nonneg=True)
    if s.damping_ratio > 1:
        c.fail("integrator.damping_ratio", f"must lie in [0, 1] (got {_num(s.damping_ratio)})")
    if isinstance(s.warm_start, bool) or s.warm_start not in range(6):
        c.fail("integrator.warm_start", f"must be an integer 0..5 "
                                        f"(got {_q(repr(s.warm_start))})")


def _check_contact(c: _Checker, s: SceneSpec) -> None:
    c.number("contact.self_friction", s.self_friction, nonneg=True)
    if s.kappa is not None:
        c.number("contact.kappa", s.kappa, positive=True)
    c.number("contact.dhat", s.dhat, positive=True)
    if s.dhat_start is not None:
        c.number("contact.dhat_start", s.dhat_start, positive=True)
        # the homotopy halves d-hat^2 from the start value down to the target
        if s.dhat_start < s.dhat:
            c.fail("contact.dhat_start", f"must not be smaller than the target dHat "
                                         f"({_num(s.dhat_start)} < {_num(s.dhat)})")
    if s.dhat_abs is not None:
        c.number("contact.dhat_abs", s.dhat_abs, positive=True)
    c.number("contact.epsv", s.epsv, positive=True)
    if s.epsv_abs is not None:
        c.number("contact.epsv_abs", s.epsv_abs, positive=True)
    c.number("contact.dtol", s.dtol, nonneg=True)
    n = s.friction_iterations
    if isinstance(n, bool) or not isinstance(n, int):
        c.fail("contact.friction_iterations", f"must be an integer (got {_q(repr(n))})")
    if n > MAX_FRICTION_ITERATIONS:
        c.fail("contact.friction_iterations",
               f"must be at most {MAX_FRICTION_ITERATIONS} lagged friction updates per step "
               f"(got {_q(n)}; 0 or less: until the friction forces settle)")
    c.number("contact.kappa_min_multiplier", s.kappa_min_multiplier, positive=True)
    if s.contact_formulation == "penalty":
        c.number("contact.penalty_stiffness", s.penalty_stiffness, positive=True)


def _check_solver(c: _Checker, s: SceneSpec) -> None:
    if not s.newton_tol:
        c.fail("solver.newton_tol", "needs at least one value")
    for x in s.newton_tol:
        c.number("solver.newton_tol", x, positive=True)
    c.one_of("solver.constraint_solver", s.constraint_solver, CONSTRAINT_SOLVERS)
    if s.constraint_type in UNSUPPORTED_CONSTRAINT_TYPES:
        c.fail("solver.constraint_type", f"{_q(repr(s.constraint_type))} is not implemented "
                                         f"by ipcsim (it implements {', '.join(CONSTRAINT_TYPES)})")
    c.one_of("solver.constraint_type", s.constraint_type, CONSTRAINT_TYPES)
    c.number("solver.constraint_offset", s.constraint_offset, nonneg=True)
    if s.linear_solver is not None:
        c.one_of("solver.linear_solver", s.linear_solver, LINEAR_SOLVERS)


def _check_scene_switches(c: _Checker, s: SceneSpec) -> None:
    c.time_range("scene.dbc_time_range", s.dbc_time_range)
    c.time_range("scene.nbc_time_range", s.nbc_time_range)
    if s.script not in SUPPORTED_SCRIPTS:
        c.fail("scene.script", f"{_q(repr(s.script))} is not supported; ipcsim implements: "
                               f"{', '.join(SUPPORTED_SCRIPTS)}")
    for x in s.script_params:
        c.number("scene.script_params", x)
    c.number("scene.handle_ratio", s.handle_ratio, nonneg=True)
    c.length("scene.size", s.size)
    if s.rotate_model is not None:
        c.vector("scene.rotate_model", s.rotate_model, 4)
        if s.rotate_model[3] != 0 and not any(s.rotate_model[:3]):
            c.fail("scene.rotate_model", "axis is the zero vector")
    c.number("output.playback_speed", s.playback_speed, positive=True)
    if re.search(r"[\s/\\]", s.append_str) or s.append_str in (".", ".."):
        c.fail("output.append_str", f"must be one word without slashes "
                                    f"(got {_q(repr(s.append_str))}); "
                                    "it becomes part of a folder name")


def _check_planes_and_obstacles(c: _Checker, s: SceneSpec) -> None:
    for k, p in enumerate(s.planes):
        key = f"planes[{k}]"
        c.vector(f"{key}.height" if p.kind == "ground" else f"{key}.origin", p.origin,
                 length=True)
        c.vector(f"{key}.normal", p.normal)
        if abs(math.hypot(*p.normal) - 1.0) > 1e-9:
            c.fail(f"{key}.normal", "must be a unit vector")
        c.number(f"{key}.friction", p.friction, nonneg=True, plane_kind=p.kind)
        c.number(f"{key}.stiffness", p.stiffness)
        c.vector(f"{key}.velocity", p.velocity)
        if p.limit is not None:
            c.vector(f"{key}.limit", p.limit, length=True)
    for k, m in enumerate(s.mesh_obstacles):
        key = f"mesh_obstacles[{k}]"
        c.vector(f"{key}.position", m.position, length=True)
        c.number(f"{key}.size", m.size, positive=True)
        c.length(f"{key}.size", m.size)
        c.number(f"{key}.stiffness", m.stiffness)
        c.number(f"{key}.friction", m.friction, nonneg=True)
        c.vector(f"{key}.rotation_deg", m.rotation_deg)


def _check_shapes(c: _Checker, s: SceneSpec) -> None:
    if not s.shapes:
        hint = "a `shapes input N` block" if c.fmt == "txt" else "a [[shapes]] table"
        raise SceneError(c.source, None, f"the scene has no shapes (add {hint})")
    for i, sh in enumerate(s.shapes):
        key = f"shapes[{i}]"
        simulated = sh.kind in SIMULATED_KINDS
        c.vector(f"{key}.translation", sh.translation, length=True)
        c.vector(f"{key}.rotation_deg", sh.rotation_deg)
        c.scale(f"{key}.scale", sh.scale)
        if simulated and math.prod(sh.scale) < 0:
            c.fail(f"{key}.scale", f"{sh.scale} mirrors the mesh, which turns every "
                                   f"{'tetrahedron' if sh.kind == 'tet' else 'triangle'} "
                                   "inside out")
        if sh.spring_stiffness is not None:
            c.number(f"{key}.spring_stiffness", sh.spring_stiffness, positive=True)
            if not simulated:
                c.fail(f"{key}.spring_stiffness", f"makes springs of a body's edges, but the "
                                                  f"{sh.kind} shape '{sh.label}' is kinematic")
        if sh.material is not None:
            m = sh.material
            c.material(f"{key}.material", m.density, m.youngs_modulus, m.poisson_ratio)
            if not simulated:
                c.warn(f"{key}.material", f"`material` is ignored for the kinematic "
                                          f"{sh.kind} shape '{sh.label}'")
        if sh.linear_velocity is not None:
            c.vector(f"{key}.linear_velocity", sh.linear_velocity)
        if sh.angular_velocity_deg is not None:
            c.vector(f"{key}.angular_velocity_deg", sh.angular_velocity_deg)
        if sh.init_velocity is not None:
            c.vector(f"{key}.init_velocity.linear", sh.init_velocity.linear)
            c.vector(f"{key}.init_velocity.angular_deg", sh.init_velocity.angular_deg)
            if not simulated:
                c.warn(f"{key}.init_velocity", "an initial velocity is ignored for the "
                                               f"kinematic {sh.kind} shape '{sh.label}'")
            elif s.script != "null":
                c.warn(f"{key}.init_velocity", f"an initial velocity is only applied with "
                                               f"script null (this scene uses {_q(repr(s.script))})")
        for j, d in enumerate(sh.dbc):
            dk = f"{key}.dbc[{j}]"
            c.box(dk, d.box_min, d.box_max)
            c.vector(f"{dk}.linear_velocity", d.linear_velocity)
            c.vector(f"{dk}.angular_velocity_deg", d.angular_velocity_deg)
            c.time_range(f"{dk}.time_range", d.time_range)
        for j, nb in enumerate(sh.nbc):
            nk = f"{key}.nbc[{j}]"
            c.box(nk, nb.box_min, nb.box_max)
            c.vector(f"{nk}.acceleration", nb.acceleration)
            c.time_range(f"{nk}.time_range", nb.time_range)
    if s.dimension == 2 and not any(sh.kind in SIMULATED_KINDS for sh in s.shapes):
        raise SceneError(
            c.source, line_of(c.lines, "shapes[0]"),
            "no simulated body: a 2D scene needs at least one triangle mesh (.msh, .obj) or "
            "kind = \"rectangle\"; every shape here is a kinematic "
            + "/".join(sorted({sh.kind for sh in s.shapes})) + " obstacle",
        )
    if s.dimension == 3 and not any(sh.kind == "tet" for sh in s.shapes):
        raise SceneError(
            c.source, line_of(c.lines, "shapes[0]"),
            "no tetrahedral shape: IPC needs at least one simulated body (.msh, .vtk, .vtu "
            "or TetGen .ele); every shape here is a kinematic "
            + "/".join(sorted({sh.kind for sh in s.shapes})) + " obstacle",
        )
