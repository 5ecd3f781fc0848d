"""TOML scenes: the same meaning as the text format, one table or key per keyword.

Schema (docs/scene-format.md is the user's reference)::

    [scene]       dimension (3 or 2), gravity, gravity_acceleration (2D), script,
                  script_params, handle_ratio, size, rotate_model, restart, dbc_time_range,
                  nbc_time_range
    [time]        duration, dt, tolerance
    [material]    density, youngs_modulus, poisson_ratio, energy, node_masses (2D)
    [integrator]  type, newmark_beta, newmark_gamma, damping_stiff, damping_ratio, warm_start
    [contact]     self_collision, self_friction, kappa ("adaptive" or a number),
                  kappa_min_multiplier, dhat, dhat_start, dhat_abs, epsv, epsv_abs, dtol,
                  friction_iterations, use_abs_parameters, barrier (2D: "ipc", "lecture")
    [solver]      newton_tol, constraint_solver ("interiorPoint", "SQP", "QP"), constraint_type,
                  constraint_offset, active_set_convergence, linear_solver ("auto" or a name)
    [output]      append_str, playback_speed
    [[shapes]]    path, kind, translation, rotation_deg, scale, material = {...},
                  linear_velocity, angular_velocity_deg, init_velocity = {...},
                  mesh_sequence, matrix = {counts, spacing}, [[shapes.dbc]], [[shapes.nbc]];
                  2D: kind = "rectangle" with size, resolution (no path); spring_stiffness
    [[planes]]    kind = "ground" (friction, height) | "halfSpace" (origin, normal,
                  stiffness, friction); 2D: velocity, limit
    [[mesh_obstacles]]  path, position, size, stiffness, friction, rotation_deg

In a 2D scene (``[scene] dimension = 2``) positions, velocities, accelerations, box corners,
plane origins and normals and a shape's scale have two numbers (x, y), and rotations and
angular velocities are one number (degrees, about z). Keys that have no 2D meaning
(scripts, ``rotate_model``, ``restart``, mesh sequences, ``meshCO`` obstacles, the SQP/QP
baselines, the penalty formulation) are refused naming the key, as are the 2D keys in a
3D scene (``validate.py`` checks the values, this reader the keys and their shapes).

Every key is optional unless marked required below; unknown keys and wrong types are
``SceneError``s naming the key path (``shapes[1].dbc[0].velocty``) and, as far as it can be
found, the line. Reading uses ``tomllib``; values are written with ``tomli_w``.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from msgspec.structs import replace

from ..errors import SceneError, excerpt as _q
from . import paths
from .spec import (CONTACT_BARRIERS, CONTACT_FORMULATIONS, DEFAULTS, DIMENSIONS, INF,
                   INTEGRATORS, MESH_KINDS, MESH_KINDS_2D, NODE_MASSES, DirichletSpec,
                   InitialVelocitySpec, MaterialSpec, MeshObstacleSpec, NeumannSpec,
                   PlaneSpec, RectangleSpec, SceneSpec, ShapeSpec)
from .txt_reader import SOLVER_NAMES, suggest, unit_normal
from .validate import LINEAR_SOLVERS, line_of, validate_scene, warning_at

__all__ = []

_MAX_MATRIX_COPIES = 100_000
_MAX_RECTANGLE_CELLS = 10_000_000

# ----------------------------------------------------------------------------- key lines

_BARE = r"[A-Za-z0-9_\-]+"
_KEY = rf'(?:{_BARE}|"[^"]*"|\'[^\']*\')'
_DOTTED = rf"{_KEY}(?:\s*\.\s*{_KEY})*"
_AOT_HEADER = re.compile(rf"\[\[\s*({_DOTTED})\s*\]\]")
_HEADER = re.compile(rf"\[\s*({_DOTTED})\s*\]")
_ASSIGN = re.compile(rf"({_DOTTED})\s*=")


def _split_key(dotted: str) -> list[str]:
    return [p.strip().strip("\"'") for p in re.findall(rf"{_KEY}", dotted)]


def locate_keys(text: str) -> dict[str, int]:
    """Best-effort map from key path (``shapes[2].dbc[0].box_min``) to line number, found by
    scanning table headers and ``key =`` lines (inline tables' keys get their line too)."""
    lines: dict[str, int] = {}
    counts: dict[str, int] = {}
    resolved: dict[str, str] = {}  # header as written -> path with array indices
    current = ""

    def resolve(parts: list[str]) -> str:
        out = ""
        for k, part in enumerate(parts):
            written = ".".join(parts[: k + 1])
            out = resolved.get(written, f"{out}.{part}" if out else part)
        return out

    for ln, raw in enumerate(text.split("\n"), 1):
        s = raw.strip()
        if not s or s.startswith("#"):
            continue
        m = _AOT_HEADER.match(s)
        if m:
            parts = _split_key(m.group(1))
            base = resolve(parts[:-1])
            base = f"{base}.{parts[-1]}" if base else parts[-1]
            idx = counts.get(base, 0)
            counts[base] = idx + 1
            current = f"{base}[{idx}]"
            resolved[".".join(parts)] = current
            lines.setdefault(current, ln)
            continue
        m = _HEADER.match(s)
        if m:
            parts = _split_key(m.group(1))
            current = resolve(parts)
            resolved[".".join(parts)] = current
            lines.setdefault(current, ln)
            continue
        m = _ASSIGN.match(s)
        if m:
            key = ".".join(_split_key(m.group(1)))
            full = f"{current}.{key}" if current else key
            lines.setdefault(full, ln)
            rest = s[m.end():].lstrip()
            if rest.startswith("{"):
                for km in _ASSIGN.finditer(rest):
                    lines.setdefault(f"{full}.{'.'.join(_split_key(km.group(1)))}", ln)
    return lines


# ----------------------------------------------------------------------------- reader


def _type_name(v) -> str:
    if isinstance(v, bool):
        return f"a boolean ({str(v).lower()})"
    if isinstance(v, (int, float)):
        return f"a number ({_q(repr(v))})"
    if isinstance(v, str):
        return f"a string ('{_q(v)}')"
    if isinstance(v, list):
        return f"an array of {len(v)}"
    if isinstance(v, dict):
        return "a table"
    return type(v).__name__


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


class KeyedReader:
    """Typed access to a parsed TOML document (a scene, a study) whose errors name the file
    and the line of the dotted key (``lines``, from ``locate_keys``)."""

    def __init__(self, source, lines: dict[str, int]):
        self.source = str(source) if source is not None else None
        self.lines = lines

    def fail(self, key: str, message: str):
        raise SceneError(self.source, line_of(self.lines, key), message)

    def table(self, data, key: str, allowed, required=()) -> dict:
        """``data`` checked to be a table whose keys are all in ``allowed``."""
        if not isinstance(data, dict):
            self.fail(key, f"{key} must be a table, got {_type_name(data)}")
        for k in data:
            if k not in allowed:
                full = f"{key}.{k}" if key else k
                self.fail(full, f"unknown key {_q(full, 80)}{suggest(k, allowed)}")
        for k in required:
            if k not in data:
                self.fail(key, f"{key} is missing the required key '{k}'")
        return data

    def boolean(self, v, key: str) -> bool:
        if not isinstance(v, bool):
            self.fail(key, f"{key} must be true or false, got {_type_name(v)}")
        return v


class _Reader(KeyedReader):
    def __init__(self, text: str, source):
        super().__init__(source, {})
        self.scene_path = source
        self.text = text
        self.warnings: list[str] = []
        self.dimension = 3

    def warn(self, key: str, message: str) -> None:
        self.warnings.append(warning_at(self.source, self.lines, key, message))

    # typed access -------------------------------------------------------------------------

    def tables(self, data, key: str) -> list:
        if not isinstance(data, list) or not all(isinstance(t, dict) for t in data):
            self.fail(key, f"{key} must be an array of tables ([[{key}]]), got "
                           f"{_type_name(data)}")
        return data

    def number(self, v, key: str, *, allow_inf: bool = False) -> float:
        if not _is_num(v):
            self.fail(key, f"{key} must be a number, got {_type_name(v)}")
        x = float(v)
        if math.isnan(x) or (math.isinf(x) and not (allow_inf and x > 0)):
            self.fail(key, f"{key} must be a finite number, got {v!r}")
        return x

    def integer(self, v, key: str) -> int:
        if not isinstance(v, int) or isinstance(v, bool):
            self.fail(key, f"{key} must be an integer, got {_type_name(v)}")
        return v

    def string(self, v, key: str) -> str:
        if not isinstance(v, str):
            self.fail(key, f"{key} must be a string, got {_type_name(v)}")
        return v

    def numbers(self, v, key: str, n: int | None = None, *, inf_last: bool = False):
        if not isinstance(v, list):
            self.fail(key, f"{key} must be an array of numbers, got {_type_name(v)}")
        if n is not None and len(v) != n:
            self.fail(key, f"{key} must have {n} numbers, got {len(v)}")
        return tuple(self.number(x, f"{key}[{k}]", allow_inf=inf_last and k == len(v) - 1)
                     for k, x in enumerate(v))

    def vec3(self, v, key):
        return self.numbers(v, key, 3)

    # vectors of the scene's dimension, held as 3-vectors (a 2D scene's z is 0) --------------

    def point(self, v, key):
        """A position, velocity or acceleration: (x, y, z), or (x, y) in a 2D scene."""
        if self.dimension == 3:
            return self.vec3(v, key)
        if isinstance(v, list) and len(v) != 2:
            self.fail(key, f"{key} must have 2 numbers (x, y) in a 2D scene, got {len(v)}")
        x, y = self.numbers(v, key, 2)
        return (x, y, 0.0)

    def scale_vector(self, v, key):
        """A shape's scale: (sx, sy, sz), or (sx, sy) in a 2D scene (sz = 1)."""
        if self.dimension == 3:
            return self.vec3(v, key)
        x, y, _ = self.point(v, key)
        return (x, y, 1.0)

    def angles(self, v, key):
        """Rotation angles (degrees) or angular velocities (deg/s): about x, y and z, or
        in a 2D scene one number, about z."""
        if self.dimension == 3:
            return self.vec3(v, key)
        if not _is_num(v):
            self.fail(key, f"{key} must be one number (degrees about z) in a 2D scene, got "
                           f"{_type_name(v)}")
        return (0.0, 0.0, self.number(v, key))

    def zero_point(self):
        return [0.0] * self.dimension

    def zero_angles(self):
        return [0.0] * 3 if self.dimension == 3 else 0.0

    def time_range(self, v, key) -> tuple[float, float]:
        return self.numbers(v, key, 2, inf_last=True)  # type: ignore[return-value]

    def choice(self, v, key: str, options) -> str:
        s = self.string(v, key)
        if s not in options:
            self.fail(key, f"{key} must be one of {', '.join(map(repr, options))}, got "
                           f"'{_q(s)}'{suggest(s, options)}")
        return s

    def path(self, v, key: str, what: str, exists=paths.is_file) -> Path:
        written = self.string(v, key)
        found = paths.resolve(written, self.scene_path, exists)
        if found is None:
            self.fail(key, f"{key}: " + paths.not_found_message(what, written,
                                                                  self.scene_path, exists))
        return found

    # the document -------------------------------------------------------------------------

    def parse(self) -> SceneSpec:
        import tomllib  # a run of a text scene reads no TOML

        try:
            doc = tomllib.loads(self.text)
        except RecursionError:
            raise SceneError(self.source, None, "invalid TOML: arrays or tables nested too "
                                                "deeply") from None
        except tomllib.TOMLDecodeError as exc:
            msg = str(exc)
            m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
            line = int(m.group(1)) if m else None
            if m is None and "end of document" in msg:
                line = self.text.count("\n") + 1
            msg = re.sub(r"\s*\(at (line \d+, column \d+|end of document)\)", "", msg)
            raise SceneError(self.source, line, f"invalid TOML: {msg}") from None
        except ValueError as exc:  # an integer of thousands of digits
            raise SceneError(self.source, None, f"invalid TOML: {_q(exc, 80)}") from None
        self.lines = locate_keys(self.text)
        return self.document(doc)

    def document(self, doc: dict) -> SceneSpec:
        """The scene of TOML data ``doc`` (as ``tomllib`` reads it), checked and
        validated; ``self.lines`` names the lines where they are known."""
        self.table(doc, "", _TOP)
        v: dict = {}
        scene = doc.get("scene")
        if isinstance(scene, dict) and "dimension" in scene:
            self.dimension = self.value(scene["dimension"], "scene.dimension", "dimension")
        if self.dimension == 2:
            self.refuse_3d_only(doc)
        for table, keys in _SIMPLE.items():
            if table not in doc:
                continue
            data = self.table(doc[table], table, keys)
            for key, (field, kind) in keys.items():
                if key in data:
                    v[field] = self.value(data[key], f"{table}.{key}", kind)
        if "dhat_start" in v and v["dhat_start"] == v.get("dhat", DEFAULTS.dhat):
            v["dhat_start"] = None  # no homotopy when start and target agree
        shapes = self.shapes(doc.get("shapes", []))
        planes = tuple(self.plane(p, f"planes[{k}]")
                       for k, p in enumerate(self.tables(doc.get("planes", []), "planes")))
        obstacles = tuple(self.obstacle(m, f"mesh_obstacles[{k}]") for k, m in
                          enumerate(self.tables(doc.get("mesh_obstacles", []),
                                                "mesh_obstacles")))
        spec = SceneSpec(
            shapes=shapes, planes=planes, mesh_obstacles=obstacles,
            source=paths.absolute(self.scene_path) if self.scene_path is not None else None,
            **v,
        )
        more = validate_scene(spec, source=self.source, lines=self.lines, fmt="toml")
        return replace(spec, warnings=tuple(self.warnings) + more,
                       key_lines=dict(self.lines))

    def refuse_3d_only(self, doc: dict) -> None:
        """A 2D scene: fail on the first key that has no 2D meaning."""
        for table, keys in _NOT_2D.items():
            data = doc.get(table)
            if isinstance(data, dict):
                for k in keys:
                    if k in data:
                        self.fail(f"{table}.{k}", f"{table}.{k}: {_NOT_2D_WHY[k]} "
                                                  "(this is a 2D scene)")
        if doc.get("mesh_obstacles"):
            self.fail("mesh_obstacles", "mesh_obstacles: meshCO obstacles are 3D triangle "
                                        "meshes; a 2D scene's obstacles are .seg shapes or "
                                        "shapes that move (this is a 2D scene)")

    def value(self, v, key: str, kind: str):
        if kind == "float":
            return self.number(v, key)
        if kind == "int":
            return self.integer(v, key)
        if kind == "bool":
            return self.boolean(v, key)
        if kind == "str":
            return self.string(v, key)
        if kind == "floats":
            return self.numbers(v, key)
        if kind == "range":
            return self.time_range(v, key)
        if kind == "vec4":
            return self.numbers(v, key, 4)
        if kind == "tol":  # one number or a per-step list
            return (self.number(v, key),) if _is_num(v) else self.numbers(v, key)
        if kind == "kappa":
            if v == "adaptive":
                return None
            if isinstance(v, str):
                self.fail(key, f"{key} must be a number or \"adaptive\", got '{_q(v)}'")
            return self.number(v, key)
        if kind == "energy":
            return self.choice(v, key, ("NH", "FCR"))
        if kind == "integrator":
            return self.choice(v, key, INTEGRATORS)
        if kind == "formulation":
            return self.choice(v, key, CONTACT_FORMULATIONS)
        if kind == "solver":
            s = self.string(v, key)
            return SOLVER_NAMES[self.choice(v, key, tuple(SOLVER_NAMES))]
        if kind == "linear_solver":
            s = self.string(v, key)
            if s.lower() == "auto":
                return None
            if s.lower() not in LINEAR_SOLVERS:
                self.fail(key, f"{key} must be \"auto\" or one of "
                               f"{', '.join(LINEAR_SOLVERS)}, got '{_q(s)}'"
                               f"{suggest(s, (*LINEAR_SOLVERS, 'auto'))}")
            return s.lower()
        if kind == "restart":
            return self.path(v, key, "restart file")
        if kind == "point":
            return self.point(v, key)
        if kind == "dimension":
            if self.integer(v, key) not in DIMENSIONS:
                self.fail(key, f"{key} must be 2 or 3, got {v}")
            return v
        if kind == "node_masses":
            return self.choice(v, key, NODE_MASSES)
        if kind == "barrier":
            return self.choice(v, key, CONTACT_BARRIERS)
        raise AssertionError(kind)

    def shapes(self, data) -> tuple[ShapeSpec, ...]:
        out: list[ShapeSpec] = []
        for k, t in enumerate(self.tables(data, "shapes")):
            key = f"shapes[{k}]"
            rectangle = t.get("kind") == "rectangle"
            self.table(t, key, _SHAPE_KEYS, required=() if rectangle else ("path",))
            self.check_shape_keys(t, key)
            if "matrix" in t:
                out.extend(self.matrix(t, key))
                continue
            out.append(self.shape(t, key))
        return tuple(out)

    def check_shape_keys(self, t: dict, key: str) -> None:
        """The keys a shape of this scene's dimension may have."""
        if self.dimension == 3:
            extra = sorted(set(t) & {"size", "resolution", "spring_stiffness"})
            if extra or t.get("kind") == "rectangle":
                what = f"{key}.{extra[0]}" if extra else f"{key}.kind"
                self.fail(what, f"{what}: generated rectangles and mass-spring shapes are "
                                "2D ([scene] dimension = 2)")
            return
        if "mesh_sequence" in t:
            self.fail(f"{key}.mesh_sequence", f"{key}.mesh_sequence: mesh sequences are "
                                              "3D meshes (this is a 2D scene)")
        if t.get("kind") == "rectangle":
            for k in ("path", "matrix"):
                if k in t:
                    self.fail(f"{key}.{k}", f"{key}.{k}: a rectangle is generated from its "
                                            "size and resolution (no path, no matrix)")
            for k in ("size", "resolution"):
                if k not in t:
                    self.fail(key, f"{key} (kind = \"rectangle\") is missing the required "
                                   f"key '{k}'")
        else:
            for k in ("size", "resolution"):
                if k in t:
                    self.fail(f"{key}.{k}", f"{key}.{k}: only a shape of kind = "
                                            "\"rectangle\" has a size and a resolution")

    def rectangle(self, t: dict, key: str) -> RectangleSpec:
        size = self.numbers(t["size"], f"{key}.size", 2)
        if not all(x > 0 for x in size):
            self.fail(f"{key}.size", f"{key}.size {list(size)} must be two lengths > 0")
        res = t["resolution"]
        if not isinstance(res, list) or len(res) != 2:
            self.fail(f"{key}.resolution", f"{key}.resolution must be an array of 2 "
                                           f"integers (cells along x, y), got {_type_name(res)}")
        res = tuple(self.integer(r, f"{key}.resolution[{a}]") for a, r in enumerate(res))
        if min(res) < 1 or res[0] * res[1] > _MAX_RECTANGLE_CELLS:
            self.fail(f"{key}.resolution", f"{key}.resolution {list(res)} must be >= 1 and "
                                           f"make at most {_MAX_RECTANGLE_CELLS} cells")
        return RectangleSpec(size, res)

    def mesh_2d(self, t: dict, key: str) -> tuple[Path | None, str | None, str]:
        """A 2D scene's shape: its mesh file and kind (\"triangles\", \"segments\",
        \"points\"), or a generated rectangle (no file)."""
        if t.get("kind") == "rectangle":
            return None, None, ""
        written = self.string(t["path"], f"{key}.path")
        suffix = Path(written).suffix.lower()
        if suffix not in MESH_KINDS_2D:
            self.fail(f"{key}.path", f"{key}.path: a 2D scene's shapes are triangle meshes "
                                     "(.msh, .obj with z = 0), segments (.seg), points (.pt) "
                                     f"or kind = \"rectangle\"; got '{_q(suffix)}'")
        found, _, written = self.mesh({**t, "kind": MESH_KINDS[suffix]}, key)
        kind = MESH_KINDS_2D[suffix]
        if "kind" in t:
            kind = self.choice(t["kind"], f"{key}.kind", ("triangles", "rectangle",
                                                          "segments", "points"))
            if kind != MESH_KINDS_2D[suffix] and not (suffix == ".obj"
                                                      and kind in ("segments", "points")):
                self.fail(f"{key}.kind", f"{key}.kind {kind!r} does not fit the mesh "
                                         f"'{_q(written)}' (only an .obj may be read as "
                                         "\"segments\" or \"points\")")
        return found, kind, written

    def mesh(self, t: dict, key: str) -> tuple[Path, str | None, str]:
        written = self.string(t["path"], f"{key}.path")
        suffix = Path(written).suffix.lower()
        if suffix not in MESH_KINDS:
            self.fail(f"{key}.path", f"{key}.path: unknown mesh file extension '{_q(suffix)}' "
                                     "(tetrahedra: .msh, .vtk, .vtu, .ele or none; surface: "
                                     ".obj; segments: .seg; points: .pt)")
        exists = paths.is_tetgen if suffix in ("", ".ele") else paths.is_file
        found = paths.resolve(written, self.scene_path, exists)
        mesh_kind = None
        if found is None and suffix in (".seg", ".pt"):
            obj = Path(written).with_suffix(".obj").as_posix()
            found = paths.resolve(obj, self.scene_path)
            if found is not None:
                mesh_kind = MESH_KINDS[suffix]
                self.warn(f"{key}.path", f"'{_q(written)}' does not exist; using "
                                         f"'{_q(obj)}' instead (as the original does)")
        if found is None:
            self.fail(f"{key}.path", f"{key}.path: " + paths.not_found_message(
                "mesh file", written, self.scene_path, exists))
        if "kind" in t:
            kind = self.choice(t["kind"], f"{key}.kind", ("tet", "surface", "segments",
                                                          "points"))
            file_kind = MESH_KINDS[found.suffix.lower()]
            # an .obj can stand for its edges or its vertices; nothing else can change kind
            if kind != file_kind and not (file_kind == "surface"
                                          and kind in ("segments", "points")):
                self.fail(f"{key}.kind", f"{key}.kind {kind!r} does not fit the "
                                         f"{file_kind} mesh '{_q(written)}' (only an .obj may be "
                                         "read as \"segments\" or \"points\")")
            mesh_kind = None if kind == file_kind else kind
        return found, mesh_kind, written

    def shape(self, t: dict, key: str) -> ShapeSpec:
        mesh, mesh_kind, written = (self.mesh if self.dimension == 3 else self.mesh_2d)(t, key)
        f = {}
        readers = {"translation": self.point, "rotation_deg": self.angles,
                   "scale": self.scale_vector, "linear_velocity": self.point,
                   "angular_velocity_deg": self.angles}
        for name, read in readers.items():
            if name in t:
                f[name] = read(t[name], f"{key}.{name}")
        if t.get("kind") == "rectangle" and self.dimension == 2:
            f["rectangle"] = self.rectangle(t, key)
        if "spring_stiffness" in t:
            f["spring_stiffness"] = self.number(t["spring_stiffness"], f"{key}.spring_stiffness")
        if "material" in t:
            f["material"] = self.material(t["material"], f"{key}.material")
        if "init_velocity" in t:
            iv = self.table(t["init_velocity"], f"{key}.init_velocity", ("linear", "angular_deg"))
            f["init_velocity"] = InitialVelocitySpec(
                self.point(iv.get("linear", self.zero_point()), f"{key}.init_velocity.linear"),
                self.angles(iv.get("angular_deg", self.zero_angles()),
                            f"{key}.init_velocity.angular_deg"))
        if "mesh_sequence" in t:
            f["mesh_sequence"] = self.path(t["mesh_sequence"], f"{key}.mesh_sequence",
                                           "mesh sequence folder", paths.is_dir)
        dbc = []
        for j, d in enumerate(self.tables(t.get("dbc", []), f"{key}.dbc")):
            dk = f"{key}.dbc[{j}]"
            self.table(d, dk, _DBC_KEYS, required=("box_min", "box_max"))
            dbc.append(DirichletSpec(
                self.point(d["box_min"], f"{dk}.box_min"),
                self.point(d["box_max"], f"{dk}.box_max"),
                self.point(d.get("linear_velocity", self.zero_point()), f"{dk}.linear_velocity"),
                self.angles(d.get("angular_velocity_deg", self.zero_angles()),
                            f"{dk}.angular_velocity_deg"),
                self.time_range(d.get("time_range", [0.0, INF]), f"{dk}.time_range"),
                line=line_of(self.lines, dk)))
        nbc = []
        for j, d in enumerate(self.tables(t.get("nbc", []), f"{key}.nbc")):
            nk = f"{key}.nbc[{j}]"
            self.table(d, nk, _NBC_KEYS, required=("box_min", "box_max", "acceleration"))
            nbc.append(NeumannSpec(
                self.point(d["box_min"], f"{nk}.box_min"),
                self.point(d["box_max"], f"{nk}.box_max"),
                self.point(d["acceleration"], f"{nk}.acceleration"),
                self.time_range(d.get("time_range", [0.0, INF]), f"{nk}.time_range"),
                line=line_of(self.lines, nk)))
        return ShapeSpec(mesh_path=mesh, mesh_kind=mesh_kind, dbc=tuple(dbc), nbc=tuple(nbc),
                         path=written, line=line_of(self.lines, key), **f)

    def matrix(self, t: dict, key: str) -> list[ShapeSpec]:
        """``matrix = {counts = [nx, ny, nz], spacing = [dx, dy, dz]}``: copies at
        translation + (dx i, dy j, dz k), x outer, y, z inner (the text's shapeMatrix)."""
        bad = sorted(set(t) - {"path", "kind", "translation", "rotation_deg", "scale",
                               "material", "matrix", "spring_stiffness"})
        if bad:
            self.fail(f"{key}.{bad[0]}", f"{key}.{_q(bad[0])}: a shape with `matrix` takes only "
                                         "path, kind, translation, rotation_deg, scale and "
                                         "material (its copies carry no velocities or boundary "
                                         "conditions)")
        m = self.table(t["matrix"], f"{key}.matrix", ("counts", "spacing"),
                       required=("counts", "spacing"))
        counts = m["counts"]
        d = self.dimension
        if not isinstance(counts, list) or len(counts) != d:
            self.fail(f"{key}.matrix.counts", f"{key}.matrix.counts must be an array of {d} "
                                              f"integers, got {_type_name(counts)}")
        counts = [self.integer(c, f"{key}.matrix.counts[{a}]") for a, c in enumerate(counts)]
        if any(c < 0 for c in counts) or math.prod(counts) > _MAX_MATRIX_COPIES:
            self.fail(f"{key}.matrix.counts", f"{key}.matrix.counts {counts} must be >= 0 and "
                                              f"make at most {_MAX_MATRIX_COPIES} copies")
        counts += [1] * (3 - d)  # a 2D grid of copies: one layer
        spacing = self.point(m["spacing"], f"{key}.matrix.spacing")
        base = self.shape({k: v for k, v in t.items() if k != "matrix"}, key)
        px, py, pz = base.translation
        return [replace(base, translation=(px + spacing[0] * i, py + spacing[1] * j,
                                           pz + spacing[2] * k))
                for i in range(counts[0]) for j in range(counts[1]) for k in range(counts[2])]

    def material(self, v, key: str) -> MaterialSpec:
        t = self.table(v, key, _MATERIAL_KEYS, required=_MATERIAL_KEYS)
        return MaterialSpec(*(self.number(t[k], f"{key}.{k}") for k in _MATERIAL_KEYS))

    def plane(self, t: dict, key: str) -> PlaneSpec:
        if "kind" not in t:
            self.fail(key, f"{key} is missing the required key 'kind' (\"ground\" or "
                           "\"halfSpace\")")
        kind = self.choice(t["kind"], f"{key}.kind", ("ground", "halfSpace"))
        line = line_of(self.lines, key)
        motion = self.plane_motion(t, key)
        if kind == "ground":
            other = sorted(set(t) & {"origin", "normal", "stiffness"})
            if other:
                self.fail(f"{key}.{other[0]}", f"{key}.{other[0]}: a \"ground\" plane takes "
                                               "only friction and height (y = height, normal "
                                               "+y); use kind = \"halfSpace\" for a general "
                                               "plane")
            self.table(t, key, ("kind", "friction", "height", *_PLANE_MOTION),
                       required=("height",))
            return PlaneSpec("ground", (0.0, self.number(t["height"], f"{key}.height"), 0.0),
                             (0.0, 1.0, 0.0),
                             self.number(t.get("friction", 0.0), f"{key}.friction"), 0.0,
                             line=line, **motion)
        self.table(t, key, ("kind", "origin", "normal", "stiffness", "friction",
                            *_PLANE_MOTION), required=("origin", "normal"))
        n = self.point(t["normal"], f"{key}.normal")
        unit = unit_normal(n)
        if unit is None:
            self.fail(f"{key}.normal", f"{key}.normal {list(n[:self.dimension])} is the zero "
                                       "vector")
        return PlaneSpec("halfSpace", self.point(t["origin"], f"{key}.origin"), unit,
                         self.number(t.get("friction", 0.0), f"{key}.friction"),
                         self.number(t.get("stiffness", 0.0), f"{key}.stiffness"), line=line,
                         **motion)

    def plane_motion(self, t: dict, key: str) -> dict:
        """A 2D plane's ``velocity`` and ``limit`` (none in a 3D scene)."""
        given = [k for k in _PLANE_MOTION if k in t]
        if given and self.dimension == 3:
            self.fail(f"{key}.{given[0]}", f"{key}.{given[0]}: moving planes are 2D ([scene] "
                                           "dimension = 2)")
        motion = {}
        if "velocity" in t:
            motion["velocity"] = self.point(t["velocity"], f"{key}.velocity")
        if "limit" in t:
            motion["limit"] = self.point(t["limit"], f"{key}.limit")
        return motion

    def obstacle(self, t: dict, key: str) -> MeshObstacleSpec:
        self.table(t, key, ("path", "position", "size", "stiffness", "friction",
                            "rotation_deg"), required=("path", "position", "size"))
        written = self.string(t["path"], f"{key}.path")
        if Path(written).suffix.lower() != ".obj":
            self.fail(f"{key}.path", f"{key}.path must name an .obj triangle mesh, got "
                                     f"'{_q(written)}'")
        return MeshObstacleSpec(
            self.path(written, f"{key}.path", "mesh file"),
            self.vec3(t["position"], f"{key}.position"),
            self.number(t["size"], f"{key}.size"),
            self.number(t.get("stiffness", 0.0), f"{key}.stiffness"),
            self.number(t.get("friction", 0.0), f"{key}.friction"),
            self.vec3(t.get("rotation_deg", [0.0] * 3), f"{key}.rotation_deg"),
            path=written, line=line_of(self.lines, key))


# table -> key -> (SceneSpec field, kind)
_SIMPLE: dict[str, dict[str, tuple[str, str]]] = {
    "scene": {
        "dimension": ("dimension", "dimension"),
        "gravity": ("gravity", "bool"),
        "gravity_acceleration": ("gravity_acceleration", "point"),
        "script": ("script", "str"),
        "script_params": ("script_params", "floats"),
        "handle_ratio": ("handle_ratio", "float"),
        "size": ("size", "float"),
        "rotate_model": ("rotate_model", "vec4"),
        "restart": ("restart", "restart"),
        "dbc_time_range": ("dbc_time_range", "range"),
        "nbc_time_range": ("nbc_time_range", "range"),
    },
    "time": {"duration": ("duration", "float"), "dt": ("dt", "float"),
             "tolerance": ("time_tolerance", "float")},
    "material": {
        "density": ("density", "float"),
        "youngs_modulus": ("youngs_modulus", "float"),
        "poisson_ratio": ("poisson_ratio", "float"),
        "energy": ("energy", "energy"),
        "node_masses": ("node_masses", "node_masses"),
    },
    "integrator": {
        "type": ("integrator", "integrator"),
        "newmark_beta": ("newmark_beta", "float"),
        "newmark_gamma": ("newmark_gamma", "float"),
        "damping_stiff": ("damping_stiff", "float"),
        "damping_ratio": ("damping_ratio", "float"),
        "warm_start": ("warm_start", "int"),
    },
    "contact": {
        "self_collision": ("self_collision", "bool"),
        "self_friction": ("self_friction", "float"),
        "kappa": ("kappa", "kappa"),
        "kappa_min_multiplier": ("kappa_min_multiplier", "float"),
        "dhat": ("dhat", "float"),
        "dhat_start": ("dhat_start", "float"),
        "dhat_abs": ("dhat_abs", "float"),
        "epsv": ("epsv", "float"),
        "epsv_abs": ("epsv_abs", "float"),
        "dtol": ("dtol", "float"),
        "friction_iterations": ("friction_iterations", "int"),
        "use_abs_parameters": ("use_abs_parameters", "bool"),
        "formulation": ("contact_formulation", "formulation"),
        "penalty_stiffness": ("penalty_stiffness", "float"),
        "barrier": ("contact_barrier", "barrier"),
    },
    "solver": {
        "newton_tol": ("newton_tol", "tol"),
        "constraint_solver": ("constraint_solver", "solver"),
        "constraint_type": ("constraint_type", "str"),
        "constraint_offset": ("constraint_offset", "float"),
        "active_set_convergence": ("active_set_convergence", "bool"),
        "linear_solver": ("linear_solver", "linear_solver"),
    },
    "output": {
        "append_str": ("append_str", "str"),
        "playback_speed": ("playback_speed", "float"),
    },
}
_TOP = (*_SIMPLE, "shapes", "planes", "mesh_obstacles")
_SHAPE_KEYS = ("path", "kind", "translation", "rotation_deg", "scale", "material",
               "linear_velocity", "angular_velocity_deg", "init_velocity", "mesh_sequence",
               "matrix", "dbc", "nbc", "size", "resolution", "spring_stiffness")
_PLANE_MOTION = ("velocity", "limit")
# the keys of the simple tables that a 2D scene refuses, and why
_NOT_2D = {
    "scene": ("script", "script_params", "handle_ratio", "rotate_model", "restart"),
    "solver": ("constraint_solver", "constraint_type", "constraint_offset",
               "active_set_convergence"),
    "contact": ("formulation", "penalty_stiffness"),
}
_NOT_2D_WHY = {
    "script": "the original's legacy scripts are 3D scenes",
    "script_params": "the original's legacy scripts are 3D scenes",
    "handle_ratio": "the original's legacy scripts are 3D scenes",
    "rotate_model": "rotate_model turns about a 3D axis; turn the shapes (rotation_deg)",
    "restart": "the original's restart files are 3D",
    "constraint_solver": "the SQP and QP baselines are 3D",
    "constraint_type": "the SQP and QP baselines are 3D",
    "constraint_offset": "the SQP and QP baselines are 3D",
    "active_set_convergence": "the SQP and QP baselines are 3D",
    "formulation": "the penalty baseline is 3D",
    "penalty_stiffness": "the penalty baseline is 3D",
}
_DBC_KEYS = ("box_min", "box_max", "linear_velocity", "angular_velocity_deg", "time_range")
_NBC_KEYS = ("box_min", "box_max", "acceleration", "time_range")
_MATERIAL_KEYS = ("density", "youngs_modulus", "poisson_ratio")


def parse_toml(text: str, source=None) -> SceneSpec:
    """Parse a TOML scene. ``source`` names the file in messages and anchors relative
    paths; it is not read."""
    return _Reader(text, source).parse()


def parse_toml_data(doc: dict, source=None) -> SceneSpec:
    """A scene from TOML data (nested dicts and lists, as ``tomllib`` returns them),
    checked exactly as a TOML file is; messages name key paths but no lines."""
    return _Reader("", source).document(doc)
