"""Prescribed motion: which vertices are kinematic during a step, where they must be at its
end (docs/ipc-scene-format.md §5.3, §5.5, §5.6), and the Neumann accelerations.

Time windows are half-open, t0 <= t < t1, tested against t = step * h as computed by the
caller (ipcsim does not accumulate h in floating point like the original, §5.7).

Overlapping sets follow the original's order, each later set overwriting earlier targets:
codim shapes (fixed), shapes with linear/angular velocity, per-shape DBCs, legacy-script
sets, then mesh sequences. Sets are few, so there is a Python loop over sets, never over
vertices.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .mesh_io import read_frame_positions
from .model import Model
from ..errors import MeshError


def rotation_xyz(angles: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """R = Rx(a) Ry(b) Rz(c) (radians, right-handed, column vectors): rotate about world Z
    first, then Y, then X."""
    a, b, c = (float(v) for v in angles)
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rx @ ry @ rz


def rotation_axis_angle(axis, angle: float) -> np.ndarray:
    """Rodrigues: R = I + sin(t) K + (1 - cos(t)) K^2 for the unit axis k (K = [k]x)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)


def active_dirichlet_sets(model: Model, t: float, x: np.ndarray | None = None):
    """The DBC sets active during the step that starts at time t from positions x
    (default: the initial positions)."""
    x = model.initial_positions if x is None else x
    return [s for s in model.dbc_sets if s.active(t, model.dbc_time_range, x)]


@lru_cache(maxsize=64)
def _step_rotation(angular_velocity: tuple, h: float) -> np.ndarray | None:
    """A set's rotation over one step, R = Rx(wx h) Ry(wy h) Rz(wz h), or None for none;
    the same every step of a run, so made once (read-only)."""
    if not any(angular_velocity):
        return None
    rot = rotation_xyz(np.asarray(angular_velocity, dtype=np.float64) * h)
    rot.flags.writeable = False
    return rot


@lru_cache(maxsize=64)
def _step_translation(linear_velocity: tuple, h: float) -> np.ndarray:
    """A set's translation over one step, v h, made once (read-only)."""
    move = np.asarray(linear_velocity, dtype=np.float64) * h
    move.flags.writeable = False
    return move


@lru_cache(maxsize=8)
def _frame(path: str, ext: str, line: int | None) -> np.ndarray:
    pos = read_frame_positions(path, ext, line)
    pos.flags.writeable = False
    return pos


def kinematic_targets(model: Model, x: np.ndarray, t_step_start: float, h: float,
                      step: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Kinematic vertices of the step [t, t + h] and their end-of-step positions.

    Returns ``(mask (n,) bool, targets (n, 3))``; rows of free vertices hold x unchanged.
    For a set with centre c (fixed, or the midpoint of the set's *current* AABB) the
    target is x' = R (x - c) + c + v h, R = Rx(wx h) Ry(wy h) Rz(wz h). A set with a
    release is left out at a step whose start positions x meet it. A mesh-sequence
    shape goes to frame k = step (default round(t / h)), i.e. ``<folder>/<k>.<ext>``.
    """
    x = np.asarray(x, dtype=np.float64)
    mask = model.kinematic_mask_at(t_step_start, x)
    targets = np.array(x, copy=True)
    for s in active_dirichlet_sets(model, t_step_start, x):
        if not s.moving:
            targets[s.vertices] = x[s.vertices]  # a later fixed set overrides earlier motion
            continue
        xs = x[s.vertices]
        if s.centre is None:
            c = 0.5 * (xs.min(axis=0) + xs.max(axis=0))  # midpoint of the current AABB
        else:
            c = np.asarray(s.centre, dtype=np.float64)
        # x' = R (x - c) + c + v h, rows as points: (x - c) R^T
        arm = xs - c
        rot = _step_rotation(tuple(s.angular_velocity), h)
        if rot is not None:
            arm = arm @ rot.T
        targets[s.vertices] = arm + c + _step_translation(tuple(s.linear_velocity), h)
    if model.mesh_sequences:
        k = int(round(t_step_start / h)) if step is None else int(step)
        for seq in model.mesh_sequences:
            pos = _frame(str(seq.frame_path(k)), seq.ext, seq.line)
            if len(pos) != seq.stop - seq.start:
                raise MeshError(seq.frame_path(k), seq.line,
                                f"mesh-sequence frame has {len(pos)} vertices, the shape has "
                                f"{seq.stop - seq.start}")
            targets[seq.start:seq.stop] = pos
            mask[seq.start:seq.stop] = True
    return mask, targets


def nbc_accelerations(model: Model, t: float, x: np.ndarray | None = None) -> np.ndarray:
    """(n, 3) sum of the Neumann accelerations active at time t, zero on the vertices
    kinematic at positions x (the extra potential is -h^2 m_i a . x_i, i.e. force m_i a)."""
    acc = np.zeros((model.n_vertices, 3))
    gate = model.nbc_time_range
    any_active = False
    for s in model.nbc_sets:
        if s.active(t, gate):
            acc[s.vertices] += np.asarray(s.acceleration, dtype=np.float64)  # unique vertices
            any_active = True
    if any_active:
        acc[model.kinematic_mask_at(t, x)] = 0.0
    return acc


def plane_origins(model: Model, step: int) -> np.ndarray | None:
    """(p, 3) where the model's planes are after ``step`` steps, None where none moves
    (``moving_plane_origins``)."""
    return moving_plane_origins(model.plane_origins, model.plane_velocities,
                                model.plane_limits, model.dt, step)


def moving_plane_origins(origins, velocities, limits, h: float, step: int):
    """(p, 3) where planes are after ``step`` steps of h, None where none moves: a moving
    plane's origin o advances by v h each step that starts with (limit − o)·v > 0 (the
    lecture's ceiling), i.e. o_k = o_0 + min(k, K) v h with K the first k at which
    (limit − o_k)·v ≤ 0 (a NaN limit: none, K = ∞)."""
    v = np.asarray(velocities, dtype=np.float64).reshape(-1, 3)
    if not len(v) or not np.any(v != 0.0):
        return None
    o0 = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    speed_sq = np.einsum("ij,ij->i", v, v)
    gap = np.einsum("ij,ij->i", np.asarray(limits, dtype=np.float64).reshape(-1, 3) - o0, v)
    with np.errstate(invalid="ignore", divide="ignore"):
        moves = np.where(speed_sq > 0.0, np.ceil(gap / (h * speed_sq)), 0.0)
    moves = np.where(np.isnan(moves), np.inf, np.maximum(moves, 0.0))
    return o0 + np.minimum(float(step), moves)[:, None] * h * v
