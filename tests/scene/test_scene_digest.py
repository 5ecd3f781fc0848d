"""The digest of a run's inputs names files by content: where a scene and its meshes lie
does not change it, what they say does."""

from __future__ import annotations

import shutil

from ipcsim.scene import load_scene
from ipcsim.scene.digest import inputs_digest

SCENE = ("shapes input 2\nmeshes/cube.msh 0 0 0  0 0 0  1 1 1\n"
         "meshes/tg 2 0 0  0 0 0  1 1 1\nground 0 -1\n")


def digest(path):
    return inputs_digest(load_scene(path))


def test_the_same_inputs_elsewhere_have_the_same_digest(write_scene, scene_dir, tmp_path,
                                                        monkeypatch):
    path = write_scene(SCENE)
    first = digest(path)
    copy = tmp_path / "copy"
    shutil.copytree(scene_dir, copy)
    monkeypatch.chdir(copy / "meshes")
    assert digest(copy / "scene.txt") == first
    assert digest(write_scene(SCENE.replace("ground 0 -1", "ground 0 -1.0"), "b.txt")) == first


def test_a_setting_or_a_file_content_changes_the_digest(write_scene, scene_dir):
    path = write_scene(SCENE)
    first = digest(path)
    assert digest(write_scene(SCENE + "selfFric 0.1\n", "b.txt")) != first
    (scene_dir / "meshes" / "cube.msh").write_text("changed")
    second = digest(path)
    assert second != first
    (scene_dir / "meshes" / "tg.node").write_text("changed")  # a TetGen mesh is two files
    assert digest(path) != second
