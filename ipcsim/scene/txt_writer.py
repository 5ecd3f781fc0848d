"""The original IPC program's scene scripts: the writer (``format_txt``), whose text
``txt_reader.parse_txt`` reads back to the same scene.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import SceneError, excerpt as _q
from . import paths
from .spec import (
    DEFAULTS,
    INF,
    MESH_KINDS,
    SceneSpec,
    ShapeSpec,
)


# linearSolver spellings the original knows (upper case); others are written as stored.
_SOLVER_SPELLING = {"cholmod": "CHOLMOD", "eigen": "EIGEN", "amgcl": "AMGCL"}


def _f(x) -> str:
    """Short text that reads back to the same float: ``%g`` when that is exact
    (0.025, 1e+11), else repr (the shortest exact form)."""
    x = float(x)
    g = f"{x:g}"
    if float(g) == x:
        return g
    r = repr(x)
    return r[:-2] if r.endswith(".0") else r


def _fs(values) -> str:
    return " ".join(_f(x) for x in values)


def _window(rng: tuple[float, float]) -> list[str]:
    """Optional ``t0 [t1]`` of a DBC/NBC: omitted when (0, inf); t1 omitted when inf."""
    t0, t1 = rng
    if t1 == INF:
        return [] if t0 == 0 else [_f(t0)]
    return [_f(t0), _f(t1)]


def _token_path(target: Path, folder: Path, what: str, out) -> str:
    rel = paths.relative_for_writing(target, folder)
    if any(ch.isspace() for ch in rel) or rel.startswith("#") or rel == "\\":
        raise SceneError(out, None, f"cannot write {what} '{rel}' in the text format (its "
                                    "tokens are separated by whitespace); write TOML instead")
    return rel


def _constraint_lines(s: SceneSpec) -> list[str]:
    """The SQP / QP settings, where they differ from the defaults."""
    if (s.constraint_type, s.constraint_offset, s.active_set_convergence) == ("volume", 0.0,
                                                                              False):
        return []
    return [f"constraintType {s.constraint_type}", f"constraintOffset {_f(s.constraint_offset)}",
            *(["useActiveSetConvergence"] if s.active_set_convergence else [])]


def format_txt(spec: SceneSpec, path=None) -> str:
    """The scene as an IPC script. Paths are written relative to ``path``'s folder (the
    file being written; default: the current directory). Defaults are written out too, so
    the script means the same wherever it is read."""
    out = str(path) if path is not None else None
    if spec.dimension != 3:
        raise SceneError(out, None, "a 2D scene has no text form (the original's format is "
                                    "3D); write the scene as .toml")
    if spec.contact_formulation != "barrier":
        raise SceneError(out, None, f"contact formulation {spec.contact_formulation!r} has no "
                                    "text form; write the scene as .toml")
    folder = paths.absolute(path).parent if path is not None else paths.absolute(".")
    L = ["# ipcsim scene (IPC script format). SI units; angles in degrees.",
         "# dHat, epsv and tol are relative to the rest bounding-box diagonal unless "
         "useAbsParameters is given."]
    L += _physics_lines(spec)
    L += _contact_lines(spec)
    L += _switch_lines(spec, folder, out)
    L += _plane_and_obstacle_lines(spec, folder, out)
    L.append(f"shapes input {len(spec.shapes)}")
    L += [_shape_line(sh, folder, out) for sh in spec.shapes]
    return "\n".join(L) + "\n"


def _physics_lines(s: SceneSpec) -> list[str]:
    L = [f"time {_f(s.duration)} {_f(s.dt)}", f"density {_f(s.density)}",
         f"stiffness {_f(s.youngs_modulus)} {_f(s.poisson_ratio)}", f"energy {s.energy}"]
    if s.integrator == "NM":
        L.append(f"timeIntegration NM {_f(s.newmark_beta)} {_f(s.newmark_gamma)}")
    else:
        L.append(f"timeIntegration {s.integrator}")
    if s.time_tolerance is not None:
        L.append(f"timeTolerance {_f(s.time_tolerance)}")
    L.append(f"dampingStiff {_f(s.damping_stiff)}")
    L.append(f"dampingRatio {_f(s.damping_ratio)}")
    L.append(f"warmStart {s.warm_start}")
    if not s.gravity:
        L.append("turnOffGravity")
    return L


def _contact_lines(s: SceneSpec) -> list[str]:
    L = ["selfCollisionOn" if s.self_collision else "selfCollisionOff",
         f"selfFric {_f(s.self_friction)}"]
    if s.dhat_start is not None or s.dtol != DEFAULTS.dtol:
        # only `tuning` can say an initial dHat or dTol; its first entry is kappa (0: adaptive)
        L.append("tuning 6")
        L.extend(_f(x) for x in (s.kappa or 0.0, s.dhat_start or s.dhat, s.dhat, s.dtol,
                                 s.epsv, s.epsv))
    else:
        if s.kappa is not None:
            L.append(f"kappa {_f(s.kappa)}")
        L.append(f"dHat {_f(s.dhat)}")
        L.append(f"epsv {_f(s.epsv)}")
    if s.dhat_abs is not None:
        L.append(f"dHatAbs {_f(s.dhat_abs)}")
    if s.epsv_abs is not None:
        L.append(f"epsvAbs {_f(s.epsv_abs)}")
    L.append(f"fricIterAmt {s.friction_iterations}")
    L.append(f"tol {len(s.newton_tol)}")
    L.extend(_f(x) for x in s.newton_tol)
    L.append(f"kappaMinMultiplier {_f(s.kappa_min_multiplier)}")
    if s.use_abs_parameters:
        L.append("useAbsParameters")
    L.append(f"constraintSolver {s.constraint_solver}")
    L.extend(_constraint_lines(s))
    if s.linear_solver is not None:
        L.append(f"linearSolver {_SOLVER_SPELLING.get(s.linear_solver, s.linear_solver)}")
    return L


def _switch_lines(s: SceneSpec, folder: Path, out) -> list[str]:
    L = []
    for kw, rng in (("DBCTimeRange", s.dbc_time_range), ("NBCTimeRange", s.nbc_time_range)):
        if rng != (0.0, INF):
            L.append(f"{kw} {_f(rng[0])}" + ("" if rng[1] == INF else f" {_f(rng[1])}"))
    if s.script != "null" or s.script_params:
        params = f" {len(s.script_params)} {_fs(s.script_params)}" if s.script_params else ""
        L.append(f"script {s.script}{params}")
    L.append(f"handleRatio {_f(s.handle_ratio)}")
    L.append(f"size {_f(s.size)}")
    if s.rotate_model is not None:
        L.append(f"rotateModel {_fs(s.rotate_model)}")
    if s.restart is not None:
        L.append(f"restart {_token_path(s.restart, folder, 'restart file', out)}")
    L.append(f"playBackSpeed {_f(s.playback_speed)}")
    if s.append_str:
        if any(ch.isspace() for ch in s.append_str):
            raise SceneError(out, None, f"appendStr {_q(repr(s.append_str))} contains "
                                        "whitespace")
        L.append(f"appendStr {s.append_str}")
    return L


def _plane_and_obstacle_lines(s: SceneSpec, folder: Path, out) -> list[str]:
    L = []
    for p in s.planes:
        if (p.kind == "ground" and p.normal == (0.0, 1.0, 0.0) and p.origin[0] == 0
                and p.origin[2] == 0 and p.stiffness == 0):
            L.append(f"ground {_f(p.friction)} {_f(p.origin[1])}")
        else:
            L.append(f"halfSpace {_fs(p.origin)}  {_fs(p.normal)}  {_f(p.stiffness)} "
                     f"{_f(p.friction)}")
    for m in s.mesh_obstacles:
        rot = f" rotate {_fs(m.rotation_deg)}" if any(m.rotation_deg) else ""
        L.append(f"meshCO {_token_path(m.mesh_path, folder, 'mesh path', out)} "
                 f"{_fs(m.position)} {_f(m.size)} {_f(m.stiffness)} {_f(m.friction)}{rot}")
    return L


def _shape_line(sh: ShapeSpec, folder: Path, out) -> str:
    mesh = sh.mesh_path
    if sh.mesh_kind is not None and sh.mesh_kind != MESH_KINDS.get(mesh.suffix.lower()):
        # an .obj read as segments/points: name the .seg/.pt, which falls back to it
        mesh = mesh.with_suffix({"segments": ".seg", "points": ".pt"}[sh.mesh_kind])
    parts = [f"{_token_path(mesh, folder, 'mesh path', out)}  {_fs(sh.translation)}  "
             f"{_fs(sh.rotation_deg)}  {_fs(sh.scale)}"]
    if sh.material is not None:
        m = sh.material
        parts.append(f"material {_f(m.density)} {_f(m.youngs_modulus)} "
                     f"{_f(m.poisson_ratio)}")
    if sh.linear_velocity is not None:
        parts.append(f"linearVelocity {_fs(sh.linear_velocity)}")
    if sh.angular_velocity_deg is not None:
        parts.append(f"angularVelocity {_fs(sh.angular_velocity_deg)}")
    if sh.init_velocity is not None:
        iv = sh.init_velocity
        parts.append(f"initVel {_fs(iv.linear)}  {_fs(iv.angular_deg)}")
    if sh.mesh_sequence is not None:
        parts.append(f"meshSeq "
                     f"{_token_path(sh.mesh_sequence, folder, 'mesh sequence', out)}")
    line = "  ".join(parts)
    conts = []
    for d in sh.dbc:
        conts.append(" ".join([f"DBC {_fs(d.box_min)}  {_fs(d.box_max)}  "
                               f"{_fs(d.linear_velocity)}  {_fs(d.angular_velocity_deg)}",
                               *_window(d.time_range)]))
    for nb in sh.nbc:
        conts.append(" ".join([f"NBC {_fs(nb.box_min)}  {_fs(nb.box_max)}  "
                               f"{_fs(nb.acceleration)}", *_window(nb.time_range)]))
    # one boundary condition per continuation line keeps long shape lines readable
    return " \\\n    ".join([line, *conts])
