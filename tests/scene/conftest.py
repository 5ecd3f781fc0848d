"""Fixtures for the scene tests: a folder with (empty) mesh files. The scene readers only
check that files exist; reading them is the model builder's job."""

from __future__ import annotations

from pathlib import Path

import pytest
from scene_support import RICH_SCENE, make_mesh_folder

from ipcsim.scene import load_scene


@pytest.fixture
def scene_dir(tmp_path) -> Path:
    """tmp_path with empty mesh files under meshes/ and a restart file."""
    return make_mesh_folder(tmp_path)


@pytest.fixture
def write_scene(scene_dir):
    """write_scene(text, name="scene.txt") -> path of the written scene in scene_dir."""

    def write(text: str, name: str = "scene.txt") -> Path:
        path = scene_dir / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        return path

    return write


@pytest.fixture
def load_text(write_scene):
    """load_text(text, name="scene.txt") -> SceneSpec read from a written file."""

    def load(text: str, name: str = "scene.txt"):
        return load_scene(write_scene(text, name))

    return load


@pytest.fixture
def rich_scene(write_scene) -> Path:
    """A scene file using nearly every keyword, with its meshes."""
    return write_scene(RICH_SCENE, "rich.txt")


@pytest.fixture(scope="module")
def rich_scene_module(tmp_path_factory) -> Path:
    root = make_mesh_folder(tmp_path_factory.mktemp("rich"))
    path = root / "rich.txt"
    path.write_text(RICH_SCENE)
    return path
