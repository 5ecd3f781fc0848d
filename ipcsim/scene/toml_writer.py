"""TOML scenes: the writer (``format_toml``, ``scene_to_dict``), every default written
out, whose text ``toml_reader.parse_toml`` reads back to the same scene.

A 2D scene is written in its own terms (``[scene] dimension = 2``, vectors of two numbers,
rotations about z as one number, its own keys with their defaults written out, none of
the keys it refuses). A 3D scene's text has no ``dimension`` and none of the 2D keys: it
is what it was before 2D scenes existed, so the inputs digest of a 3D run, which is taken
over this text (``digest.py``), has not changed.
"""

from __future__ import annotations

from pathlib import Path

import tomli_w

from . import paths
from .spec import (
    PlaneSpec,
    SceneSpec,
    ShapeSpec,
)


def _v3(v) -> list[float]:
    return [float(x) for x in v]


def scene_to_dict(spec: SceneSpec, folder: Path, name_path=None) -> dict:
    """The fully resolved scene as TOML data, every default written out; paths relative
    to ``folder`` (where the file will live) when possible. ``name_path(path) -> str``,
    when given, writes the paths instead (the input digest names files by content)."""
    s = spec
    rel = name_path or (lambda p: paths.relative_for_writing(p, folder))
    if s.dimension == 2:
        return _scene_to_dict_2d(s, rel)
    doc: dict = {
        "scene": _scene_table(s, rel),
        "time": {"duration": float(s.duration), "dt": float(s.dt),
                 **({} if s.time_tolerance is None
                    else {"tolerance": float(s.time_tolerance)})},
        "material": {"density": float(s.density), "youngs_modulus": float(s.youngs_modulus),
                     "poisson_ratio": float(s.poisson_ratio), "energy": s.energy},
        "integrator": {"type": s.integrator, "newmark_beta": float(s.newmark_beta),
                       "newmark_gamma": float(s.newmark_gamma),
                       "damping_stiff": float(s.damping_stiff),
                       "damping_ratio": float(s.damping_ratio),
                       "warm_start": int(s.warm_start)},
        "contact": _contact_table(s),
        "solver": {"newton_tol": [float(x) for x in s.newton_tol],
                   "constraint_solver": s.constraint_solver,
                   "constraint_type": s.constraint_type,
                   "constraint_offset": float(s.constraint_offset),
                   "active_set_convergence": bool(s.active_set_convergence),
                   "linear_solver": s.linear_solver or "auto"},
        "output": {"append_str": s.append_str, "playback_speed": float(s.playback_speed)},
    }
    doc["shapes"] = [_shape_table(sh, rel) for sh in s.shapes]
    doc["planes"] = [_plane_table(p) for p in s.planes]
    doc["mesh_obstacles"] = [
        {"path": rel(m.mesh_path), "position": _v3(m.position), "size": float(m.size),
         "stiffness": float(m.stiffness), "friction": float(m.friction),
         "rotation_deg": _v3(m.rotation_deg)} for m in s.mesh_obstacles]
    return doc


def _scene_to_dict_2d(s: SceneSpec, rel) -> dict:
    """``scene_to_dict`` of a 2D scene (module docstring)."""
    contact = {k: v for k, v in _contact_table(s).items()
               if k not in ("formulation", "penalty_stiffness")}
    contact["barrier"] = s.contact_barrier
    doc: dict = {
        "scene": {"dimension": 2, "gravity": s.gravity, "size": float(s.size),
                  "dbc_time_range": _v3(s.dbc_time_range),
                  "nbc_time_range": _v3(s.nbc_time_range)},
        "time": {"duration": float(s.duration), "dt": float(s.dt)},
        "material": {"density": float(s.density), "youngs_modulus": float(s.youngs_modulus),
                     "poisson_ratio": float(s.poisson_ratio), "energy": s.energy,
                     "node_masses": s.node_masses},
        "integrator": {"type": s.integrator, "newmark_beta": float(s.newmark_beta),
                       "newmark_gamma": float(s.newmark_gamma),
                       "damping_stiff": float(s.damping_stiff),
                       "damping_ratio": float(s.damping_ratio),
                       "warm_start": int(s.warm_start)},
        "contact": contact,
        "solver": {"newton_tol": [float(x) for x in s.newton_tol],
                   "linear_solver": s.linear_solver or "auto"},
        "output": {"append_str": s.append_str, "playback_speed": float(s.playback_speed)},
    }
    if s.gravity_acceleration is not None:
        doc["scene"]["gravity_acceleration"] = _v2(s.gravity_acceleration)
    doc["shapes"] = [_shape_table(sh, rel, 2) for sh in s.shapes]
    doc["planes"] = [_plane_table_2d(p) for p in s.planes]
    return doc


def _v2(v) -> list[float]:
    return [float(v[0]), float(v[1])]


def _plane_table_2d(p: PlaneSpec) -> dict:
    t = _plane_table(p)
    if t["kind"] == "halfSpace":
        t["origin"], t["normal"] = _v2(p.origin), _v2(p.normal)
    t["velocity"] = _v2(p.velocity)
    if p.limit is not None:
        t["limit"] = _v2(p.limit)
    return t


def _scene_table(s: SceneSpec, rel) -> dict:
    scene = {
        "gravity": s.gravity,
        "script": s.script,
        "script_params": [float(x) for x in s.script_params],
        "handle_ratio": float(s.handle_ratio),
        "size": float(s.size),
    }
    if s.rotate_model is not None:
        scene["rotate_model"] = [float(x) for x in s.rotate_model]
    if s.restart is not None:
        scene["restart"] = rel(s.restart)
    scene["dbc_time_range"] = _v3(s.dbc_time_range)
    scene["nbc_time_range"] = _v3(s.nbc_time_range)
    return scene


def _contact_table(s: SceneSpec) -> dict:
    contact = {
        "self_collision": s.self_collision,
        "self_friction": float(s.self_friction),
        "kappa": "adaptive" if s.kappa is None else float(s.kappa),
        "kappa_min_multiplier": float(s.kappa_min_multiplier),
        "dhat": float(s.dhat),
        "dhat_start": float(s.dhat if s.dhat_start is None else s.dhat_start),
    }
    if s.dhat_abs is not None:
        contact["dhat_abs"] = float(s.dhat_abs)
    contact["epsv"] = float(s.epsv)
    if s.epsv_abs is not None:
        contact["epsv_abs"] = float(s.epsv_abs)
    contact.update({
        "dtol": float(s.dtol),
        "friction_iterations": int(s.friction_iterations),
        "use_abs_parameters": s.use_abs_parameters,
        "formulation": s.contact_formulation,
        "penalty_stiffness": float(s.penalty_stiffness),
    })
    return contact


def _about_z(angles) -> float:
    return float(angles[2])


def _shape_table(sh: ShapeSpec, rel, dimension: int = 3) -> dict:
    """A shape's table: vectors with ``dimension`` components, and in 2D each rotation
    (about z) one angle."""
    vec, turn = (_v2, _about_z) if dimension == 2 else (_v3, _v3)
    if sh.rectangle is not None:
        t: dict = {"kind": "rectangle", "size": vec(sh.rectangle.size),
                   "resolution": [int(n) for n in sh.rectangle.resolution]}
    else:
        t = {"path": rel(sh.mesh_path)}
        kind = sh.kind if dimension == 2 else sh.mesh_kind
        if kind is not None:
            t["kind"] = kind
    t.update(translation=vec(sh.translation), rotation_deg=turn(sh.rotation_deg),
             scale=vec(sh.scale))
    if sh.spring_stiffness is not None:
        t["spring_stiffness"] = float(sh.spring_stiffness)
    if sh.material is not None:
        m = sh.material
        t["material"] = {"density": float(m.density),
                         "youngs_modulus": float(m.youngs_modulus),
                         "poisson_ratio": float(m.poisson_ratio)}
    if sh.linear_velocity is not None:
        t["linear_velocity"] = vec(sh.linear_velocity)
    if sh.angular_velocity_deg is not None:
        t["angular_velocity_deg"] = turn(sh.angular_velocity_deg)
    if sh.init_velocity is not None:
        t["init_velocity"] = {"linear": vec(sh.init_velocity.linear),
                              "angular_deg": turn(sh.init_velocity.angular_deg)}
    if sh.mesh_sequence is not None:
        t["mesh_sequence"] = rel(sh.mesh_sequence)
    if sh.dbc:
        t["dbc"] = [{"box_min": vec(d.box_min), "box_max": vec(d.box_max),
                     "linear_velocity": vec(d.linear_velocity),
                     "angular_velocity_deg": turn(d.angular_velocity_deg),
                     "time_range": _v3(d.time_range)} for d in sh.dbc]
    if sh.nbc:
        t["nbc"] = [{"box_min": vec(n.box_min), "box_max": vec(n.box_max),
                     "acceleration": vec(n.acceleration),
                     "time_range": _v3(n.time_range)} for n in sh.nbc]
    return t


def _plane_table(p: PlaneSpec) -> dict:
    if (p.kind == "ground" and p.normal == (0.0, 1.0, 0.0) and p.origin[0] == 0
            and p.origin[2] == 0 and p.stiffness == 0):
        return {"kind": "ground", "friction": float(p.friction), "height": float(p.origin[1])}
    return {"kind": "halfSpace", "origin": _v3(p.origin), "normal": _v3(p.normal),
            "stiffness": float(p.stiffness), "friction": float(p.friction)}


def _literal(v) -> str:
    """One TOML value on one line: scalars as tomli_w writes them, arrays inline."""
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_literal(x)}" for k, x in v.items()) + " }"
    if isinstance(v, list):
        return "[" + ", ".join(_literal(x) for x in v) + "]"
    return tomli_w.dumps({"v": v})[len("v = "):-1]


def _override_literal(v) -> str:
    try:
        return " ".join(_literal(v).split())
    except (TypeError, ValueError):  # a value the reader would have refused
        return repr(v)


def _emit_table(header: str, table: dict, out: list[str]) -> None:
    out.append(header)
    subtables = []
    for k, v in table.items():
        if isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            subtables.append((k, v))
        else:
            out.append(f"{k} = {_literal(v)}")
    for k, items in subtables:
        name = header.strip("[]")
        for item in items:
            out.append("")
            _emit_table(f"[[{name}.{k}]]", item, out)


_HEADER_COMMENT = """\
# ipcsim scene. Units: SI (m, kg, s, Pa); angles in degrees, angular velocities in deg/s.
# contact.dhat, contact.epsv, contact.dtol and solver.newton_tol are relative to the
# diagonal of the rest bounding box of all tet shapes unless contact.use_abs_parameters.
"""


def format_toml(spec: SceneSpec, path=None) -> str:
    """The scene as TOML text; mesh paths relative to ``path``'s folder (default: cwd)."""
    folder = paths.absolute(path).parent if path is not None else paths.absolute(".")
    doc = scene_to_dict(spec, folder)
    header = _HEADER_COMMENT if spec.dimension == 3 else _HEADER_COMMENT.replace(
        "all tet shapes", "all simulated shapes").replace(
        "# ipcsim scene.", "# ipcsim scene, 2D (the plane z = 0).")
    out: list[str] = [header]
    if spec.overrides:  # the values are below; this says which were not the file's
        out.insert(1, "# overrides of the scene file's values: " + ", ".join(
            f"{k} = {_override_literal(v)}" for k, v in spec.overrides.items()) + "\n")
    for name, value in doc.items():
        if isinstance(value, dict):
            _emit_table(f"[{name}]", value, out)
            out.append("")
        else:
            for item in value:
                _emit_table(f"[[{name}]]", item, out)
                out.append("")
    return "\n".join(out).rstrip("\n") + "\n"
