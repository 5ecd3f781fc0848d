"""What ``check`` and ``run`` share: a scene read (with its ``--set`` overrides), its
model built and its simulation set up, so that ``check`` refuses exactly what ``run``
refuses (an intersecting or touching start, a vertex on or below a plane, an inverted tet,
a linear solver that is not installed) before anything is written."""

from __future__ import annotations

import sys
from pathlib import Path


def load_and_build(scene_path, *, overrides=None, warn=None):
    """(scene, model, simulation) of ``scene_path``; ``warn(message)`` receives the
    scene's and the builder's warnings (default: printed to stderr)."""
    from ..runner import build
    from ..scene import load_scene

    warn = warn or (lambda message: print(message, file=sys.stderr))
    scene = load_scene(Path(scene_path), overrides)
    model, sim = build(scene, warn)
    return scene, model, sim
