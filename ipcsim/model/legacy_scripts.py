"""The original program's hard-coded scenarios (``script NAME``, scene format §4.8).

Each script prescribes the motion of some vertices of the assembled scene. ``script_sets``
returns the Dirichlet sets a script creates and the initial positions it leaves (``fall``
lifts the whole scene). ``null`` (no script) is handled by the builder: its per-shape
velocities, DBCs and mesh sequences come from the scene itself.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SceneError
from ..scene.spec import SUPPORTED_SCRIPTS, SceneSpec
from .model import DirichletSet


def script_sets(scene: SceneSpec, parts, offsets, rest, initial, warnings):
    """DBC sets of the scene's legacy script; returns (sets, initial positions).

    ``parts`` are the loaded shapes (``kind``, ``index``), ``offsets`` (s + 1,) their vertex
    ranges, ``rest`` / ``initial`` (n, 3) the assembled positions. Sets that select no vertex
    are dropped with a warning."""
    name = scene.script
    sets: list[DirichletSet] = []
    lo, hi = initial.min(axis=0), initial.max(axis=0)
    rng = hi - lo
    src = f"script {name}"
    if name == "fall":
        # shift all initial positions up by half the scene AABB diagonal
        initial = initial.copy()
        initial[:, 1] += 0.5 * float(np.linalg.norm(rng))
    elif name == "fallNoShift":
        pass
    elif name == "DCOFix":
        for p in parts:
            if p.kind != "tet":
                sets.append(DirichletSet(np.arange(offsets[p.index], offsets[p.index + 1]),
                                         source=f"{src}: shape {p.index + 1} fixed"))
    elif name == "DCORotCylinders":
        sets = _rotating_cylinders(scene, offsets, initial, src)
    elif name == "twist":
        sets = _twist(scene, rest, src)
    elif name == "fixLowerHalf":
        lower = initial[:, 1] < lo[1] + 0.5 * rng[1]
        sets.append(DirichletSet(np.flatnonzero(lower), source=f"{src}: lower half fixed"))
    elif name == "pushRightMost1":
        right = np.flatnonzero(initial[:, 0] > hi[0] - 1e-3 * rng[0])
        sets.append(DirichletSet(right[:1], linear_velocity=(-0.15, 0.0, 0.0),
                                 source=f"{src}: right-most vertex pushed"))
    else:
        raise SceneError(scene.source, None, f"script '{name}' is not supported "
                                             f"(supported: {', '.join(SUPPORTED_SCRIPTS)})")
    for s in sets:
        if len(s.vertices) == 0:
            warnings.append(f"{s.source}: selects no vertex")
    return [s for s in sets if len(s.vertices)], initial


def _rotating_cylinders(scene, offsets, initial, src):
    """The first four shapes spin at π/2 rad/s about their initial AABB centres."""
    if len(offsets) < 5:
        raise SceneError(scene.source, None, "script DCORotCylinders needs at least 4 shapes")
    omegas = [(math.pi / 2, 0, 0), (-math.pi / 2, 0, 0), (0, 0, -math.pi / 2),
              (0, 0, math.pi / 2)]
    sets = []
    for k in range(4):
        x = initial[offsets[k]:offsets[k + 1]]
        centre = tuple(0.5 * (x.min(axis=0) + x.max(axis=0)))
        sets.append(DirichletSet(np.arange(offsets[k], offsets[k + 1]),
                                 angular_velocity=omegas[k], centre=centre,
                                 source=f"{src}: shape {k + 1} rotating"))
    return sets


def _twist(scene, rest, src):
    """Slabs of relative thickness handleRatio at min / max x of the REST positions,
    rotating −0.4π and +0.4π rad/s about x through the rest-AABB centre."""
    rlo, rhi = rest.min(axis=0), rest.max(axis=0)
    r = scene.handle_ratio * (rhi[0] - rlo[0])
    left = rest[:, 0] < rlo[0] + r
    right = ~left & (rest[:, 0] > rhi[0] - r)
    centre = tuple(0.5 * (rlo + rhi))
    return [DirichletSet(np.flatnonzero(left), angular_velocity=(-0.4 * math.pi, 0, 0),
                         centre=centre, source=f"{src}: min-x handle"),
            DirichletSet(np.flatnonzero(right), angular_velocity=(0.4 * math.pi, 0, 0),
                         centre=centre, source=f"{src}: max-x handle")]
