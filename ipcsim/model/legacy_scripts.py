"""The original program's hard-coded scenarios (``script NAME``, scene format §4.8).

Each script prescribes the motion of some vertices of the assembled scene, and a few also
move the initial positions (``fall``, ``dragright``), give initial velocities
(``DCOBallHitWall``) or add Neumann accelerations (``utopiaComparison``). ``script_motion``
returns all of that as data: Dirichlet sets, Neumann sets, initial positions and
velocities. ``null`` (no script) is handled by the builder: its per-shape velocities, DBCs
and mesh sequences come from the scene itself.

Motion that changes during the run is data too. Where the original switches a velocity
when a prescribed (kinematic) vertex reaches some position, the switch depends on nothing
but the prescribed motion, so the steps at which it happens are found here by running that
motion forward, and the script becomes Dirichlet sets with time windows: the handles of
``stretchAndPause`` move, then stay; the walls of ``DCOSquash6`` reverse; the plates of
``DCOSqueezeOut`` and ``DCOSegBedSquash`` stop. Only ``dragright`` depends on the
simulated body (it lets go once the body has passed every obstacle): its set carries a
``Release`` condition that ``kinematics`` tests at the start of each step.

Every switch is tested where the original tests it, at the start of the step, on the
positions the prescribed motion has reached (x₀ + k·v·h after k steps); a window edge is
put half a step before the first step it excludes, so that t = k·h falls clearly inside.
"""

from __future__ import annotations

import math

from msgspec import Struct, field
import numpy as np

from ..errors import SceneError
from ..scene.spec import SUPPORTED_SCRIPTS, SceneSpec
from .model import INF, DirichletSet, NeumannSet, Release

# Scripts whose setup fixes every codim (non-tet) shape, as DCOFix does.
FIXES_CODIM = ("DCOFix", "DCOBallHitWall", "DCOSegBedSquash", "DCOSqueezeOut",
               "DCOSquash6", "DCOVerschoorRoller")


class ScriptScene(Struct, frozen=True, eq=False):
    """What a script reads of the assembled scene: its spec, the shapes' kinds and
    vertex ranges [off[i], off[i+1]), rest and initial positions (scene shapes only, no
    meshCO), and the positions of the meshCO obstacles (m, 3)."""

    spec: SceneSpec
    kinds: tuple[str, ...]
    offsets: np.ndarray
    rest: np.ndarray
    initial: np.ndarray
    obstacles: np.ndarray

    @property
    def source(self) -> str:
        return f"script {self.spec.script}"

    def shape(self, i: int) -> np.ndarray:
        return np.arange(self.offsets[i], self.offsets[i + 1])

    def codim_shapes(self) -> list[int]:
        return [i for i, k in enumerate(self.kinds) if k != "tet"]


class ScriptMotion(Struct):
    """What a script prescribes: Dirichlet and Neumann sets, the initial positions it
    leaves, and initial velocities (None: at rest)."""

    initial: np.ndarray
    dbc_sets: list[DirichletSet] = field(default_factory=list)
    nbc_sets: list[NeumannSet] = field(default_factory=list)
    velocities: np.ndarray | None = None


def script_motion(ss: ScriptScene, warnings: list[str]) -> ScriptMotion:
    """The motion of the scene's legacy script. Sets that select no vertex are dropped
    with a warning."""
    name = ss.spec.script
    make = _SCRIPTS.get(name)
    if make is None:
        raise SceneError(ss.spec.source, None, f"script '{name}' is not supported "
                                               f"(supported: {', '.join(SUPPORTED_SCRIPTS)})")
    motion = ScriptMotion(initial=ss.initial)
    if name in FIXES_CODIM:
        motion.dbc_sets += [DirichletSet(ss.shape(i), source=f"{ss.source}: shape {i + 1} "
                                                             "fixed") for i in ss.codim_shapes()]
    make(ss, motion)
    for s in motion.dbc_sets + motion.nbc_sets:
        if len(s.vertices) == 0:
            warnings.append(f"{s.source}: selects no vertex")
    motion.dbc_sets = [s for s in motion.dbc_sets if len(s.vertices)]
    motion.nbc_sets = [s for s in motion.nbc_sets if len(s.vertices)]
    return motion


# -- switching motion as time windows ---------------------------------------------------------

def _windows(scales: list[float], h: float) -> list[tuple[float, tuple[float, float]]]:
    """Runs of equal per-step scale factors as (scale, window): step k starts at t = k·h,
    a window edge sits half a step before the first step of the next run; the last run
    lasts for ever (so does the motion of a run longer than the scene's steps)."""
    runs, start = [], 0
    for k in range(1, len(scales) + 1):
        if k == len(scales) or scales[k] != scales[start]:
            t0 = 0.0 if start == 0 else (start - 0.5) * h
            t1 = INF if k == len(scales) else (k - 0.5) * h
            runs.append((scales[start], (t0, t1)))
            start = k
    return runs


def _scheduled_sets(vertices, velocity, scales, h, source) -> list[DirichletSet]:
    """Sets moving ``vertices`` at ``scale·velocity`` during each run of ``scales``
    (a zero scale holds them fixed)."""
    v = np.asarray(velocity, dtype=np.float64)
    return [DirichletSet(vertices, linear_velocity=tuple(scale * v + 0.0), time_range=window,
                         source=f"{source} (t in [{window[0]:g}, {window[1]:g}))")
            for scale, window in _windows(scales, h)]


def _moving_steps(value: float, rate: float, h: float, n_steps: int, keep) -> list[float]:
    """1.0 for each step at whose start ``keep(value)`` holds, then 0.0 for good (the
    value moving by rate·h per moving step): a motion that stops at a position."""
    scales = []
    for _ in range(n_steps):
        moving = bool(scales[-1] if scales else True) and keep(value)
        scales.append(1.0 if moving else 0.0)
        if moving:
            value = value + rate * h
    return scales


# -- the scripts -------------------------------------------------------------------------------

def _fall(ss: ScriptScene, motion: ScriptMotion) -> None:
    """Shift every initial position up by half the scene's AABB diagonal."""
    motion.initial = _lifted(ss.initial)


def _lifted(x: np.ndarray) -> np.ndarray:
    x = x.copy()
    x[:, 1] += 0.5 * float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))
    return x


def _nothing(ss: ScriptScene, motion: ScriptMotion) -> None:
    """fallNoShift, DCOFix: no motion beyond the fixed codim shapes."""


def _fix_lower_half(ss: ScriptScene, motion: ScriptMotion) -> None:
    x = ss.initial
    lo, hi = x.min(axis=0), x.max(axis=0)
    lower = np.flatnonzero(x[:, 1] < lo[1] + 0.5 * (hi[1] - lo[1]))
    motion.dbc_sets.append(DirichletSet(lower, source=f"{ss.source}: lower half fixed"))


def _push_right_most_1(ss: ScriptScene, motion: ScriptMotion) -> None:
    """The first vertex (by index) within 1e-3 of the x range of the right end, pushed
    left at 0.15 m/s."""
    x = ss.initial
    lo, hi = x.min(axis=0), x.max(axis=0)
    right = np.flatnonzero(x[:, 0] > hi[0] - 1e-3 * (hi[0] - lo[0]))
    motion.dbc_sets.append(DirichletSet(right[:1], linear_velocity=(-0.15, 0.0, 0.0),
                                        source=f"{ss.source}: right-most vertex pushed"))


def _handles(ss: ScriptScene) -> tuple[np.ndarray, np.ndarray]:
    """The original's two border handles (``findBorderVerts``): vertices whose REST x is
    within handleRatio of the x range of the min / of the max end (min first)."""
    rest = ss.rest
    rlo, rhi = rest.min(axis=0), rest.max(axis=0)
    r = ss.spec.handle_ratio * (rhi[0] - rlo[0])
    left = rest[:, 0] < rlo[0] + r
    right = ~left & (rest[:, 0] > rhi[0] - r)
    return np.flatnonzero(left), np.flatnonzero(right)


def _twist(ss: ScriptScene, motion: ScriptMotion) -> None:
    """The handles rotate at −0.4π and +0.4π rad/s about x through the rest-AABB centre."""
    left, right = _handles(ss)
    centre = tuple(0.5 * (ss.rest.min(axis=0) + ss.rest.max(axis=0)))
    motion.dbc_sets += [
        DirichletSet(left, angular_velocity=(-0.4 * math.pi, 0, 0), centre=centre,
                     source=f"{ss.source}: min-x handle"),
        DirichletSet(right, angular_velocity=(0.4 * math.pi, 0, 0), centre=centre,
                     source=f"{ss.source}: max-x handle")]


def _hang_left(ss: ScriptScene, motion: ScriptMotion) -> None:
    """The min-x handle is fixed (the rest hangs from it)."""
    left, _ = _handles(ss)
    motion.dbc_sets.append(DirichletSet(left, source=f"{ss.source}: min-x handle fixed"))


def _stretch_and_pause(ss: ScriptScene, motion: ScriptMotion) -> None:
    """Vertices within 1 % of the x range of the left end move at −1 m/s along x, those
    within 1 % of the right end at +1 m/s, while the last left vertex (by index) is at
    x ≥ −0.28 m at the start of a step; then both stay where they are."""
    x = ss.initial
    lo, hi = x.min(axis=0), x.max(axis=0)
    rng = hi - lo
    left = np.flatnonzero(x[:, 0] < lo[0] + 0.01 * rng[0])
    right = np.flatnonzero(~(x[:, 0] < lo[0] + 0.01 * rng[0])
                           & (x[:, 0] > hi[0] - 0.01 * rng[0]))
    if not len(left):
        return
    h, n = ss.spec.dt, ss.spec.n_steps
    scales = _moving_steps(float(x[left[-1], 0]), -1.0, h, n, lambda v: v >= -0.28)
    motion.dbc_sets += _scheduled_sets(left, (-1.0, 0, 0), scales, h, f"{ss.source}: left end")
    motion.dbc_sets += _scheduled_sets(right, (1.0, 0, 0), scales, h, f"{ss.source}: right end")


def _drag_right(ss: ScriptScene, motion: ScriptMotion) -> None:
    """Shift up as ``fall``; vertices within 4 % of the x range of the right end are
    dragged at +0.5 m/s along x until every vertex of the scene is right of the right-most
    meshCO vertex (tested at the start of each step); then all of them are free."""
    motion.initial = x = _lifted(ss.initial)
    lo, hi = x.min(axis=0), x.max(axis=0)
    right = np.flatnonzero(x[:, 0] > hi[0] - 0.04 * (hi[0] - lo[0]))
    past = float(ss.obstacles[:, 0].max()) if len(ss.obstacles) else -INF
    release = Release(np.arange(len(x)), axis=0, above=past)
    motion.dbc_sets.append(DirichletSet(right, linear_velocity=(0.5, 0, 0), release=release,
                                        source=f"{ss.source}: right end dragged"))


def _rotating_shapes(ss: ScriptScene, motion: ScriptMotion, omegas) -> None:
    """Shape k spins at omegas[k] (rad/s, Rx Ry Rz) about its initial AABB centre."""
    if len(ss.kinds) < len(omegas) + 1:
        raise SceneError(ss.spec.source, None, f"{ss.source} needs at least "
                                               f"{len(omegas) + 1} shapes")
    for k, w in enumerate(omegas):
        x = ss.initial[ss.shape(k)]
        centre = tuple(0.5 * (x.min(axis=0) + x.max(axis=0)))
        motion.dbc_sets.append(DirichletSet(ss.shape(k), angular_velocity=w, centre=centre,
                                            source=f"{ss.source}: shape {k + 1} rotating"))


def _rot_cylinders(ss: ScriptScene, motion: ScriptMotion) -> None:
    half = math.pi / 2
    _rotating_shapes(ss, motion, [(half, 0, 0), (-half, 0, 0), (0, 0, -half), (0, 0, half)])


def _verschoor_roller(ss: ScriptScene, motion: ScriptMotion) -> None:
    """Six rollers: about z at −4, −2, 2, 4 rad/s and about x at 2, −2 rad/s."""
    _rotating_shapes(ss, motion, [(0, 0, -4.0), (0, 0, -2.0), (0, 0, 2.0), (0, 0, 4.0),
                                  (2.0, 0, 0), (-2.0, 0, 0)])


def _ball_hit_wall(ss: ScriptScene, motion: ScriptMotion) -> None:
    """Every tet vertex starts at v_x = the first script parameter (default 1000 m/s)."""
    params = ss.spec.script_params
    vx = params[0] if params and params[0] == params[0] else 1000.0
    v = np.zeros_like(ss.initial)
    for i, kind in enumerate(ss.kinds):
        if kind == "tet":
            v[ss.shape(i), 0] = vx
    motion.velocities = v


def _extent(ss: ScriptScene, shapes, axis: int, largest: bool) -> float:
    """Largest (or smallest) coordinate ``axis`` of the initial positions of ``shapes``."""
    if not shapes:
        return -INF if largest else INF
    values = np.concatenate([ss.initial[ss.shape(i), axis] for i in shapes])
    return float(values.max() if largest else values.min())


def _squeeze_out(ss: ScriptScene, motion: ScriptMotion) -> None:
    """Shape 1 (a codim plate) moves down at 0.3 m/s while its top is above the bottom of
    shape 2 (codim) plus 0.9 / 3.8 of shape 2's height; then it stays."""
    codim = set(ss.codim_shapes())
    top = [0] if 0 in codim else []
    bottom = [1] if 1 in codim else []
    top_max = _extent(ss, top, 1, True)
    b_min, b_max = _extent(ss, bottom, 1, False), _extent(ss, bottom, 1, True)
    threshold = b_min + (b_max - b_min) / 3.8 * 0.9
    h, n = ss.spec.dt, ss.spec.n_steps
    scales = _moving_steps(top_max, -0.3, h, n, lambda v: v > threshold)
    for i in top:
        motion.dbc_sets += _scheduled_sets(ss.shape(i), (0, -0.3, 0), scales, h,
                                           f"{ss.source}: shape {i + 1} pressing")


def _seg_bed_squash(ss: ScriptScene, motion: ScriptMotion) -> None:
    """The codim shapes of the second half of the shape list (index ≥ ⌊(s + 1) / 2⌋)
    move down at 1 m/s while their lowest point is more than 0.1 m above the highest point
    of the other codim shapes; then they stay."""
    half = (len(ss.kinds) + 1) // 2
    top = [i for i in ss.codim_shapes() if i >= half]
    bottom = [i for i in ss.codim_shapes() if i < half]
    bottom_max = _extent(ss, bottom, 1, True)
    h, n = ss.spec.dt, ss.spec.n_steps
    scales = _moving_steps(_extent(ss, top, 1, False), -1.0, h, n,
                           lambda v: v - bottom_max > 0.1)
    if top:
        vertices = np.concatenate([ss.shape(i) for i in top])
        motion.dbc_sets += _scheduled_sets(vertices, (0, -1.0, 0), scales, h,
                                           f"{ss.source}: upper bed pressing")


def _squash6(ss: ScriptScene, motion: ScriptMotion) -> None:
    """Shapes 1–6 (walls) move at +1, −1 m/s along x, y, z (two each); all six reverse
    at each step that starts with the gap between shape 2's left side and shape 1's right
    side below 0.1 m."""
    if len(ss.kinds) < 7:
        raise SceneError(ss.spec.source, None, f"{ss.source} needs at least 7 shapes")
    right0, left1 = _extent(ss, [0], 0, True), _extent(ss, [1], 0, False)
    h, sign, scales = ss.spec.dt, 1.0, []
    for _ in range(ss.spec.n_steps):
        if left1 - right0 < 0.1:
            sign = -sign
        scales.append(sign)
        right0, left1 = right0 + sign * h, left1 - sign * h
    for k in range(6):
        v = [0.0, 0.0, 0.0]
        v[k // 2] = 1.0 if k % 2 == 0 else -1.0
        motion.dbc_sets += _scheduled_sets(ss.shape(k), v, scales, h,
                                           f"{ss.source}: wall {k + 1}")


def _utopia_comparison(ss: ScriptScene, motion: ScriptMotion) -> None:
    """Vertices within 1e-4 of the x range of the top get an extra −1.5 m/s² along y;
    the others within as much of the bottom are fixed."""
    x = ss.initial
    lo, hi = x.min(axis=0), x.max(axis=0)
    tol = (hi[0] - lo[0]) * 1e-4  # the original measures both against the x range
    top = x[:, 1] > hi[1] - tol
    bottom = ~top & (x[:, 1] < lo[1] + tol)
    motion.dbc_sets.append(DirichletSet(np.flatnonzero(bottom),
                                        source=f"{ss.source}: bottom fixed"))
    motion.nbc_sets.append(NeumannSet(np.flatnonzero(top), (0.0, -1.5, 0.0),
                                      source=f"{ss.source}: top pushed down"))


_SCRIPTS = {
    "fall": _fall, "fallNoShift": _nothing, "DCOFix": _nothing,
    "DCORotCylinders": _rot_cylinders, "twist": _twist, "fixLowerHalf": _fix_lower_half,
    "pushRightMost1": _push_right_most_1, "hangLeft": _hang_left,
    "stretchAndPause": _stretch_and_pause, "dragright": _drag_right,
    "DCOVerschoorRoller": _verschoor_roller, "DCOBallHitWall": _ball_hit_wall,
    "DCOSqueezeOut": _squeeze_out, "DCOSegBedSquash": _seg_bed_squash,
    "DCOSquash6": _squash6, "utopiaComparison": _utopia_comparison,
}
