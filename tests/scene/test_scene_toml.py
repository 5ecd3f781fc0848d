"""TOML scenes: same meaning as the text format, strict keys, complete writer."""

from __future__ import annotations

import math
import tomllib

import pytest

from ipcsim.errors import SceneError
from ipcsim.scene import format_toml, load_scene, parse_toml, save_scene
from ipcsim.scene.spec import SceneSpec
from ipcsim.scene.toml_reader import _SIMPLE, locate_keys
from ipcsim.scene.toml_writer import scene_to_dict

BASE = '[[shapes]]\npath = "meshes/cube.msh"\n'


def test_rich_scene_round_trips_both_ways(rich_scene, scene_dir):
    spec = load_scene(rich_scene)
    assert len(spec.shapes) == 7 and len(spec.planes) == 2 and spec.mesh_obstacles
    toml_path = save_scene(spec, scene_dir / "rich.toml")
    assert load_scene(toml_path) == spec
    assert load_scene(save_scene(load_scene(toml_path), scene_dir / "back.txt")) == spec


def test_writer_fills_in_every_default(write_scene, scene_dir):
    spec = load_scene(write_scene(BASE, "s.toml"))
    doc = tomllib.loads((save_scene(spec, scene_dir / "out.toml")).read_text())
    for table, keys in _SIMPLE.items():
        optional = {"rotate_model", "restart", "dhat_abs", "epsv_abs", "tolerance"}  # None
        optional |= {"dimension", "node_masses", "barrier", "gravity_acceleration"}  # 2D only
        assert set(doc[table]) == set(keys) - optional, table
    assert doc["contact"]["kappa"] == "adaptive" and doc["solver"]["linear_solver"] == "auto"
    assert doc["scene"]["dbc_time_range"] == [0.0, math.inf]
    assert doc["shapes"][0] == {"path": "meshes/cube.msh", "translation": [0.0, 0.0, 0.0],
                                "rotation_deg": [0.0, 0.0, 0.0], "scale": [1.0, 1.0, 1.0]}
    d = SceneSpec()
    assert (doc["time"]["dt"], doc["material"]["youngs_modulus"], doc["contact"]["dtol"]) == (
        d.dt, d.youngs_modulus, d.dtol)


def test_written_text_is_what_scene_to_dict_says(rich_scene, scene_dir):
    spec = load_scene(rich_scene)
    text = format_toml(spec, scene_dir / "x.toml")
    assert tomllib.loads(text) == scene_to_dict(spec, scene_dir)


def test_infinity_round_trips(write_scene, scene_dir):
    text = ("[scene]\nnbc_time_range = [1.5, inf]\n" + BASE +
            "[[shapes.dbc]]\nbox_min = [0, 0, 0]\nbox_max = [1, 1, 1]\ntime_range = [2, inf]\n")
    spec = load_scene(write_scene(text, "s.toml"))
    assert spec.nbc_time_range == (1.5, math.inf)
    assert spec.shapes[0].dbc[0].time_range == (2.0, math.inf)
    out = save_scene(spec, scene_dir / "o.toml")
    assert "[1.5, inf]" in out.read_text()
    assert load_scene(out) == spec
    assert load_scene(save_scene(spec, scene_dir / "o.txt")) == spec


def test_paths_are_written_relative_to_the_written_file(write_scene, scene_dir):
    spec = load_scene(write_scene(BASE, "s.toml"))
    (scene_dir / "out" / "deep").mkdir(parents=True)
    out = save_scene(spec, scene_dir / "out" / "deep" / "scene.toml")
    assert tomllib.loads(out.read_text())["shapes"][0]["path"] == "../../meshes/cube.msh"
    assert load_scene(out).shapes[0].mesh_path == scene_dir / "meshes" / "cube.msh"


def test_text_and_toml_mean_the_same(write_scene):
    txt = load_scene(write_scene(
        "time 2 0.01\nselfFric 0.2\nground 0.1 -1\nhalfSpace 0 0 0 0 2 0 3 0.4\nkappa 1e5\n"
        "dHatAbs 1e-4\ntol 2\n1e-2\n1e-3\nshapes input 1\n"
        "meshes/cube.msh 0 1 0 0 0 0 1 1 1 DBC 0 0 0 1 1 1 0 1 0 0 0 0 1\n"))
    toml = load_scene(write_scene(
        "[time]\nduration = 2\ndt = 0.01\n[contact]\nself_friction = 0.2\nkappa = 1e5\n"
        "dhat_abs = 1e-4\n[solver]\nnewton_tol = [1e-2, 1e-3]\n"
        '[[shapes]]\npath = "meshes/cube.msh"\ntranslation = [0, 1, 0]\n'
        "[[shapes.dbc]]\nbox_min = [0, 0, 0]\nbox_max = [1, 1, 1]\nlinear_velocity = [0, 1, 0]\n"
        "time_range = [1, inf]\n"
        '[[planes]]\nkind = "ground"\nfriction = 0.1\nheight = -1\n'
        '[[planes]]\nkind = "halfSpace"\norigin = [0, 0, 0]\nnormal = [0, 2, 0]\n'
        "stiffness = 3\nfriction = 0.4\n", "s.toml"))
    assert toml == txt


def test_matrix_matches_shape_matrix(write_scene):
    txt = load_scene(write_scene("shapeMatrix input 2 1 2 0 5 0\n"
                                 "meshes/cube.msh 1 1 2 0 0 30 1 1 1 material 900 1e5 0.3\n"))
    toml = load_scene(write_scene(
        '[[shapes]]\npath = "meshes/cube.msh"\ntranslation = [0, 5, 0]\nrotation_deg = [0, 0, 30]\n'
        "material = {density = 900, youngs_modulus = 1e5, poisson_ratio = 0.3}\n"
        "matrix = {counts = [2, 1, 2], spacing = [1, 1, 2]}\n", "s.toml"))
    assert toml == txt and len(toml.shapes) == 4


def test_kind_reads_an_obj_as_segments_or_points(write_scene):
    spec = load_scene(write_scene(BASE + '[[shapes]]\npath = "meshes/tri.obj"\nkind = "points"\n'
                                  '[[shapes]]\npath = "meshes/edge.seg"\nkind = "segments"\n',
                                  "s.toml"))
    assert [s.kind for s in spec.shapes] == ["tet", "points", "segments"]
    assert [s.mesh_kind for s in spec.shapes] == [None, "points", None]


def test_fallback_shape_is_written_with_its_kind(write_scene, scene_dir):
    spec = load_scene(write_scene(
        "shapes input 2\nmeshes/cube.msh 0 0 0 0 0 0 1 1 1\n"
        "meshes/fallback.seg 0 0 0 0 0 0 1 1 1\n"))
    doc = tomllib.loads(format_toml(spec, scene_dir / "o.toml"))
    assert doc["shapes"][1]["path"] == "meshes/fallback.obj"
    assert doc["shapes"][1]["kind"] == "segments"
    assert "meshes/fallback.seg" in (save_scene(spec, scene_dir / "o.txt")).read_text()


def test_small_conveniences(write_scene):
    spec = load_scene(write_scene(
        '[solver]\nnewton_tol = 1e-3\nlinear_solver = "CHOLMOD"\nconstraint_solver = "IP"\n'
        "[contact]\ndhat = 2e-3\ndhat_start = 2e-3\n" + BASE, "s.toml"))
    assert spec.newton_tol == (1e-3,) and spec.linear_solver == "cholmod"
    assert spec.constraint_solver == "interiorPoint"
    assert spec.dhat_start is None  # equal to the target: no homotopy


def test_locate_keys():
    text = ('# c\n[time]\ndt = 1\n\n[[shapes]]\npath = "a"\nmaterial = { density = 1 }\n'
            "[[shapes.dbc]]\nbox_min = [0,\n  0, 0]\n[[shapes]]\n[[shapes.dbc]]\n"
            "[[shapes.dbc]]\nx.y = 2\n")
    lines = locate_keys(text)
    assert lines["time"] == 2 and lines["time.dt"] == 3
    assert lines["shapes[0]"] == 5 and lines["shapes[0].material.density"] == 7
    assert lines["shapes[0].dbc[0].box_min"] == 9
    assert lines["shapes[1].dbc[1]"] == 13 and lines["shapes[1].dbc[1].x.y"] == 14


def test_failed_write_leaves_old_file_and_no_temporary(scene_dir):
    spec = parse_toml(BASE, scene_dir / "s.toml")
    (scene_dir / "my meshes").mkdir()
    (scene_dir / "my meshes" / "c.msh").write_text("")
    spaced = parse_toml('[[shapes]]\npath = "my meshes/c.msh"\n', scene_dir / "s.toml")
    target = scene_dir / "keep.txt"
    save_scene(spec, target)
    before = target.read_text()
    with pytest.raises(SceneError, match="whitespace"):
        save_scene(spaced, target)  # the text format cannot hold a path with a space
    assert target.read_text() == before
    assert not [p for p in scene_dir.iterdir() if ".tmp-" in p.name]
    # TOML can
    assert load_scene(save_scene(spaced, scene_dir / "spaced.toml")) == spaced
