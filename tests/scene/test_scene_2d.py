"""2D scenes in TOML ([scene] dimension = 2): vectors of two numbers and rotations about z
held as 3D records with z = 0, generated rectangles, springs, moving planes, the
lecture's conventions; the writer's round trip; every key without a 2D meaning refused
naming the key, and the 2D keys refused in a 3D scene; 3D text unchanged."""

from __future__ import annotations

import math
import re
import tomllib

import pytest

from ipcsim.errors import SceneError
from ipcsim.scene import apply_overrides, format_toml, load_scene, parse_toml, save_scene
from ipcsim.scene.digest import inputs_digest

HEAD = "[scene]\ndimension = 2\n"
RECT = ('[[shapes]]\nkind = "rectangle"\nsize = [1.0, 0.5]\nresolution = [4, 2]\n')

LESSON = HEAD + """gravity_acceleration = [0.0, -9.81]
[time]
duration = 1.0
dt = 0.01
[material]
density = 1000
node_masses = "uniform"
energy = "FCR"
[contact]
kappa = 1e5
dhat_abs = 0.01
barrier = "lecture"
self_friction = 0.2
[[shapes]]
kind = "rectangle"
size = [1.0, 1.0]
resolution = [4, 4]
spring_stiffness = 2e4
translation = [0.5, 0.25]
rotation_deg = 30
scale = [2.0, 1.0]
linear_velocity = [0.1, 0.0]
angular_velocity_deg = 15
init_velocity = { linear = [1.0, -1.0], angular_deg = 5 }
[[shapes.dbc]]
box_min = [0.0, 0.9]
box_max = [1.0, 1.0]
linear_velocity = [0.0, -0.5]
angular_velocity_deg = 10
time_range = [0.0, 2.0]
[[shapes.nbc]]
box_min = [0.0, 0.0]
box_max = [0.5, 0.5]
acceleration = [3.0, 0.0]
[[shapes]]
path = "meshes/cube.msh"
translation = [0.0, 3.0]
[[shapes]]
path = "meshes/edge.seg"
[[planes]]
kind = "ground"
height = -1.0
friction = 0.11
[[planes]]
kind = "halfSpace"
origin = [0.0, 0.6]
normal = [0.0, -2.0]
velocity = [0.0, -0.5]
limit = [0.0, -0.6]
"""


def test_a_2d_scene_is_held_in_the_plane_z_0(load_text):
    s = load_text(LESSON, "lesson.toml")
    assert s.dimension == 2 and s.node_masses == "uniform" and s.contact_barrier == "lecture"
    assert s.gravity_acceleration == (0.0, -9.81, 0.0)
    rect, tri, seg = s.shapes
    assert rect.kind == "rectangle" and rect.mesh_path is None and rect.label == "rectangle"
    assert rect.rectangle.size == (1.0, 1.0) and rect.rectangle.resolution == (4, 4)
    assert rect.spring_stiffness == 2e4
    assert rect.translation == (0.5, 0.25, 0.0) and rect.rotation_deg == (0.0, 0.0, 30.0)
    assert rect.scale == (2.0, 1.0, 1.0) and rect.linear_velocity == (0.1, 0.0, 0.0)
    assert rect.angular_velocity_deg == (0.0, 0.0, 15.0)
    assert rect.init_velocity.linear == (1.0, -1.0, 0.0)
    assert rect.init_velocity.angular_deg == (0.0, 0.0, 5.0)
    d, = rect.dbc
    assert (d.box_min, d.box_max) == ((0.0, 0.9, 0.0), (1.0, 1.0, 0.0))
    assert d.angular_velocity_deg == (0.0, 0.0, 10.0) and d.time_range == (0.0, 2.0)
    assert rect.nbc[0].acceleration == (3.0, 0.0, 0.0)
    assert tri.kind == "triangles" and seg.kind == "segments"
    ground, ceiling = s.planes
    assert ground.velocity == (0.0, 0.0, 0.0) and ground.limit is None
    assert ceiling.normal == (0.0, -1.0, 0.0) and ceiling.origin == (0.0, 0.6, 0.0)
    assert ceiling.velocity == (0.0, -0.5, 0.0) and ceiling.limit == (0.0, -0.6, 0.0)


def test_the_writer_round_trips_a_2d_scene_in_its_own_terms(load_text, scene_dir):
    s = load_text(LESSON, "lesson.toml")
    out = save_scene(s, scene_dir / "out.toml")
    assert load_scene(out) == s
    doc = tomllib.loads(out.read_text())
    assert doc["scene"] == {"dimension": 2, "gravity": True, "size": -1.0,
                            "dbc_time_range": [0.0, math.inf],
                            "nbc_time_range": [0.0, math.inf],
                            "gravity_acceleration": [0.0, -9.81]}
    assert doc["material"]["node_masses"] == "uniform" and doc["contact"]["barrier"] == "lecture"
    assert "formulation" not in doc["contact"] and set(doc["solver"]) == {"newton_tol",
                                                                         "linear_solver"}
    rect = doc["shapes"][0]
    assert rect["rotation_deg"] == 30.0 and rect["translation"] == [0.5, 0.25]
    assert rect["dbc"][0]["box_min"] == [0.0, 0.9] and "path" not in rect
    assert doc["shapes"][1] == {"path": "meshes/cube.msh", "kind": "triangles",
                                "translation": [0.0, 3.0], "rotation_deg": 0.0,
                                "scale": [1.0, 1.0]}
    assert doc["planes"][0]["velocity"] == [0.0, 0.0] and "mesh_obstacles" not in doc
    assert "2D" in out.read_text().splitlines()[0]


def test_overrides_work_in_2d_terms(load_text):
    s = load_text(LESSON, "lesson.toml")
    t = apply_overrides(s, {"shapes.0.translation": [2.0, 1.0], "planes.1.velocity": [0, -1],
                            "shapes[0].rotation_deg": 45})
    assert t.shapes[0].translation == (2.0, 1.0, 0.0)
    assert t.shapes[0].rotation_deg == (0.0, 0.0, 45.0)
    assert t.planes[1].velocity == (0.0, -1.0, 0.0)
    with pytest.raises(SceneError, match=r"shapes\[0\].translation must have 2 numbers"):
        apply_overrides(s, {"shapes.0.translation": [1, 2, 3]})
    with pytest.raises(SceneError, match="scene.script"):
        apply_overrides(s, {"scene.script": "twist"})


def test_3d_scenes_have_no_2d_keys_in_their_text(load_text, scene_dir):
    text = '[[shapes]]\npath = "meshes/cube.msh"\n[[planes]]\nkind = "ground"\nheight = 0\n'
    s = load_text(text, "three.toml")
    doc = tomllib.loads(format_toml(s, scene_dir / "x.toml"))

    def keys(v):
        if isinstance(v, dict):
            return set(v) | {k for x in v.values() for k in keys(x)}
        if isinstance(v, list):
            return {k for x in v for k in keys(x)}
        return set()

    assert not keys(doc) & {"dimension", "node_masses", "barrier", "velocity", "limit",
                            "gravity_acceleration", "spring_stiffness", "resolution"}
    assert inputs_digest(s) == inputs_digest(parse_toml(format_toml(s, scene_dir / "x.toml"),
                                                        scene_dir / "x.toml"))


@pytest.mark.parametrize("body, message", [
    ('[[shapes]]\npath = "meshes/cube.msh"\ntranslation = [0, 0, 0]\n',
     r"shapes\[0\]\.translation must have 2 numbers \(x, y\) in a 2D scene, got 3"),
    ('[[shapes]]\npath = "meshes/cube.msh"\nrotation_deg = [0, 0, 30]\n',
     r"shapes\[0\]\.rotation_deg must be one number \(degrees about z\)"),
    (RECT + '[[shapes.dbc]]\nbox_min = [0, 0, 0]\nbox_max = [1, 1]\n',
     r"shapes\[0\]\.dbc\[0\]\.box_min must have 2 numbers"),
    ('script = "twist"\n' + RECT, r"scene\.script: the original's legacy scripts are 3D"),
    ('rotate_model = [0, 0, 1, 30]\n' + RECT, r"scene\.rotate_model: .*3D axis"),
    ('[solver]\nconstraint_solver = "QP"\n' + RECT,
     r"solver\.constraint_solver: the SQP and QP baselines are 3D"),
    ('[contact]\nformulation = "penalty"\n' + RECT, r"contact\.formulation: the penalty"),
    (RECT + '[[mesh_obstacles]]\npath = "meshes/plane.obj"\nposition = [0, 0, 0]\nsize = 1\n',
     r"mesh_obstacles: meshCO obstacles are 3D"),
    (RECT.replace("kind", 'mesh_sequence = "meshes"\nkind'),
     r"shapes\[0\]\.mesh_sequence: mesh sequences are 3D"),
    ('[[shapes]]\npath = "meshes/tg.ele"\n', r"shapes\[0\]\.path: a 2D scene's shapes are"),
    ('[[shapes]]\nkind = "rectangle"\nsize = [1, 1]\n',
     r"shapes\[0\] \(kind = \"rectangle\"\) is missing the required key 'resolution'"),
    (RECT.replace("[4, 2]", "[0, 2]"), r"shapes\[0\]\.resolution \[0, 2\] must be >= 1"),
    (RECT.replace("[1.0, 0.5]", "[1.0, -0.5]"), r"shapes\[0\]\.size .* two lengths > 0"),
    (RECT + 'path = "meshes/cube.msh"\n', r"shapes\[0\]\.path: a rectangle is generated"),
    ('[[shapes]]\npath = "meshes/cube.msh"\nsize = [1, 1]\n',
     r"shapes\[0\]\.size: only a shape of kind"),
    (RECT + "spring_stiffness = -1\n", r"shapes\[0\]\.spring_stiffness must be > 0"),
    ('[[shapes]]\npath = "meshes/edge.seg"\n', r":\d+: no simulated body: a 2D scene needs"),
    ('[[shapes]]\npath = "meshes/tri.obj"\nkind = "tet"\n', r"shapes\[0\]\.kind must be one of"),
    (RECT + '[[planes]]\nkind = "halfSpace"\norigin = [0, 0]\nnormal = [0, 0]\n',
     r"planes\[0\]\.normal \[0\.0, 0\.0\] is the zero vector"),
    (RECT + '[material]\nnode_masses = "even"\n', r"material\.node_masses must be one of"),
])
def test_what_a_2d_scene_refuses_is_named(write_scene, body, message):
    path = write_scene(HEAD + body, "bad.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    text = str(info.value)
    assert text.startswith(f"{path}:") and "\n" not in text
    assert re.search(message, text), text


@pytest.mark.parametrize("body, key", [
    ('[material]\nnode_masses = "uniform"\n', "material.node_masses"),
    ('[contact]\nbarrier = "lecture"\n', "contact.barrier"),
    ('[scene]\ngravity_acceleration = [0, -9.81, 0]\n', "scene.gravity_acceleration"),
    ('[[shapes]]\nkind = "rectangle"\nsize = [1, 1]\nresolution = [2, 2]\n', "shapes[0]."),
    ('[[shapes]]\npath = "meshes/cube.msh"\nspring_stiffness = 1\n',
     "shapes[0].spring_stiffness"),
    ('[[shapes]]\npath = "meshes/cube.msh"\n[[planes]]\nkind = "ground"\nheight = 0\n'
     'velocity = [0, 1, 0]\n', "planes[0].velocity"),
    ('[scene]\ndimension = 4\n', "scene.dimension"),
])
def test_2d_keys_are_refused_in_a_3d_scene(write_scene, body, key):
    text = body if "shapes" in body else body + '[[shapes]]\npath = "meshes/cube.msh"\n'
    path = write_scene(text, "bad3.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert key in str(info.value) and str(info.value).startswith(str(path))


def test_the_text_format_refuses_a_2d_scene(load_text, scene_dir):
    s = load_text(HEAD + RECT, "s.toml")
    with pytest.raises(SceneError, match="a 2D scene has no text form"):
        save_scene(s, scene_dir / "s.txt")
    assert not (scene_dir / "s.txt").exists()


def test_a_2d_grid_of_copies(load_text):
    s = load_text(HEAD + '[[shapes]]\npath = "meshes/cube.msh"\ntranslation = [1, 2]\n'
                  'matrix = { counts = [2, 3], spacing = [10, 20] }\n', "m.toml")
    assert [sh.translation for sh in s.shapes] == [
        (1.0 + 10 * i, 2.0 + 20 * j, 0.0) for i in range(2) for j in range(3)]
