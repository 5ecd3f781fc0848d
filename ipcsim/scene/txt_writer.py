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
    L += _given("timeTolerance", s.time_tolerance)
    L.append(f"dampingStiff {_f(s.damping_stiff)}")
    L.append(f"dampingRatio {_f(s.damping_ratio)}")
    L.append(f"warmStart {s.warm_start}")
    if not s.gravity:
        L.append("turnOffGravity")
    return L


def _given(keyword: str, value, spell=None) -> list[str]:
    """The line ``keyword value`` (value spelled by ``spell``, else as a number) where the
    scene gives a value; none where it is None."""
    return [] if value is None else [f"{keyword} {(spell or _f)(value)}"]


def _contact_lines(s: SceneSpec) -> list[str]:
    L = ["selfCollisionOn" if s.self_collision else "selfCollisionOff",
         f"selfFric {_f(s.self_friction)}"]
    if s.dhat_start is not None or s.dtol != DEFAULTS.dtol:
        # only `tuning` can say an initial dHat or dTol; its first entry is kappa (0: adaptive)
        L.append("tuning 6")
        L.extend(_f(x) for x in (s.kappa or 0.0, s.dhat_start or s.dhat, s.dhat, s.dtol,
                                 s.epsv, s.epsv))
    else:
        L += _given("kappa", s.kappa)
        L.append(f"dHat {_f(s.dhat)}")
        L.append(f"epsv {_f(s.epsv)}")
    L += _given("dHatAbs", s.dhat_abs) + _given("epsvAbs", s.epsv_abs)
    L.append(f"fricIterAmt {s.friction_iterations}")
    L.append(f"tol {len(s.newton_tol)}")
    L.extend(_f(x) for x in s.newton_tol)
    L.append(f"kappaMinMultiplier {_f(s.kappa_min_multiplier)}")
    if s.use_abs_parameters:
        L.append("useAbsParameters")
    L.append(f"constraintSolver {s.constraint_solver}")
    L.extend(_constraint_lines(s))
    L += _given("linearSolver", s.linear_solver, lambda v: _SOLVER_SPELLING.get(v, v))
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
    L += _given("rotateModel", s.rotate_model, _fs)
    L += _given("restart", s.restart, lambda p: _token_path(p, folder, "restart file", out))
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
    parts += _given("linearVelocity", sh.linear_velocity, _fs)
    parts += _given("angularVelocity", sh.angular_velocity_deg, _fs)
    parts += _given("initVel", sh.init_velocity,
                    lambda iv: f"{_fs(iv.linear)}  {_fs(iv.angular_deg)}")
    parts += _given("meshSeq", sh.mesh_sequence,
                    lambda p: _token_path(p, folder, "mesh sequence", out))
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
