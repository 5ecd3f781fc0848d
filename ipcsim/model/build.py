"""A scene's Model: built by ``builder.py`` (tet meshes in 3D) or ``builder_2d.py``
(triangles and springs in the plane, on the same stages where they mean the same)."""

from __future__ import annotations

from ..errors import ArgumentError, MeshError
from ..scene.spec import SceneSpec
from .builder import build_model_3d
from .builder_2d import build_model_2d
from .model import Model


def build_model(scene: SceneSpec) -> Model:
    """Load every mesh of the scene and assemble the frozen Model (§5)."""
    if not isinstance(scene, SceneSpec):
        raise ArgumentError("build_model takes a SceneSpec (ipcsim.load_scene(path)), got "
                            f"{type(scene).__name__}")
    try:
        return (build_model_2d if scene.dimension == 2 else build_model_3d)(scene)
    except MeshError as exc:
        if exc.scene is None and scene.source is not None:
            exc.scene = str(scene.source)
        raise
