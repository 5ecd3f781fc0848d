"""What ``check`` and ``run`` share: a scene read, its model built and its simulation set
up, so that ``check`` refuses exactly what ``run`` refuses (an intersecting or touching
start, a vertex on or below a plane, an inverted tet, a linear solver that is not
installed) before anything is written."""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import SceneError, excerpt


def load_and_build(scene_path, *, warn=None):
    """(scene, model, simulation) of ``scene_path``; ``warn(message)`` receives the
    scene's and the builder's warnings (default: printed to stderr)."""
    from ..model.builder import build_model
    from ..scene import load_scene

    warn = warn or (lambda message: print(message, file=sys.stderr))
    scene = load_scene(Path(scene_path))
    for w in scene.warnings:
        warn(w)
    model = build_model(scene)
    for w in getattr(model, "warnings", ()):
        warn(w)
    return scene, model, make_simulation(scene, model)


def make_simulation(scene, model):
    """``Simulation(model)``; a named linear solver that is not installed here (PARDISO
    without MKL) is a SceneError at the scene's ``linearSolver`` line."""
    from ..simulation import Simulation

    try:
        return Simulation(model)
    except ImportError as exc:
        if scene.linear_solver is None:
            raise  # "auto" falls back to scipy: an ImportError here is a broken install
        raise SceneError(scene.source, scene.line_of("solver.linear_solver"),
                         f"linear solver '{scene.linear_solver}' is not available here "
                         f"({excerpt(exc, 120)}); use linearSolver auto") from None
