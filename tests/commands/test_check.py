"""`ipcsim check`: exit 0 with counts on every example script; bad meshes give
`scene:line: mesh: problem`, exit status 2 and no traceback."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from examples import example_scripts, extra_scripts_with_meshes, extra_scripts_without_meshes

from ipcsim.cli import main
from ipcsim.model.generate import box_tet_mesh


@pytest.mark.parametrize("script", example_scripts() + extra_scripts_with_meshes(),
                         ids=lambda p: p.name)
def test_check_passes_on_every_example(script, capsys):
    assert main(["check", str(script)]) == 0
    out = capsys.readouterr().out
    for label in ("vertices", "tets", "surface triangles", "surface edges",
                  "kinematic vertices", "terms"):
        assert label in out


@pytest.mark.parametrize("script", sorted(extra_scripts_without_meshes()), ids=lambda p: p.name)
def test_check_names_the_mesh_an_example_lacks(script, capsys):
    """The original's tree never shipped a few meshes: the scripts that use them are
    refused for that reason alone, naming the mesh."""
    assert main(["check", str(script)]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and "Traceback" not in err


POINTS, TETS = box_tet_mesh(1, 1, 1)
NAN_POINTS = POINTS.copy()
NAN_POINTS[3, 1] = np.nan
FLAT_POINTS = POINTS.copy()
FLAT_POINTS[:, 2] = 0.0  # every tet has zero volume
INVERTED_TETS = TETS.copy()
INVERTED_TETS[0, [0, 1]] = INVERTED_TETS[0, [1, 0]]

TRIANGLE_ONLY = meshio.Mesh(POINTS[:3], [("triangle", np.array([[0, 1, 2]]))])
BAD_MESHES = [  # (name, file content or a meshio.Mesh, fragment of the message)
    ("unreadable", "this is not a mesh\n", "cannot read mesh"),
    ("no tets", TRIANGLE_ONLY, "no tet"),
    ("nan coordinates", meshio.Mesh(NAN_POINTS, [("tetra", TETS)]), "nan"),
    ("zero volume", meshio.Mesh(FLAT_POINTS, [("tetra", TETS)]), "volume"),
    ("inverted", meshio.Mesh(POINTS, [("tetra", INVERTED_TETS)]), "inverted"),
]


@pytest.mark.parametrize("name,content,fragment", BAD_MESHES, ids=[b[0] for b in BAD_MESHES])
def test_bad_mesh_is_a_clear_error(tmp_path, capsys, name, content, fragment):
    mesh = "body.vtu"
    if isinstance(content, meshio.Mesh):
        meshio.write(tmp_path / mesh, content)
    else:
        (tmp_path / mesh).write_text(content)
    scene = tmp_path / "scene.txt"
    scene.write_text(f"# a scene\nshapes input 1\n{mesh} 0 0 0  0 0 0  1 1 1\n")
    assert main(["check", str(scene)]) == 2
    err = capsys.readouterr().err
    assert f"{scene}:3: " in err and mesh in err
    assert fragment in err.lower()
    assert "Traceback" not in err


def test_dbc_box_that_selects_nothing_is_a_warning(tmp_path, capsys):
    meshio.write(tmp_path / "body.vtu", meshio.Mesh(POINTS, [("tetra", TETS)]))
    scene = tmp_path / "scene.txt"
    scene.write_text("shapes input 1\nbody.vtu 0 0 0  0 0 0  1 1 1 "
                     "DBC 0.4 0.4 0.4  0.6 0.6 0.6  0 0 0  0 0 0\n")
    assert main(["check", str(scene)]) == 0
    captured = capsys.readouterr()
    assert "selects no" in (captured.err + captured.out).lower()


@pytest.fixture
def dropped(tmp_path):
    """A cube dropped on the ground, run for 3 steps at dt = 0.02 (an override) into
    ``out``: (scene, out)."""
    from generated import write_box_msh

    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "drop.txt"
    scene.write_text("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1\nselfCollisionOff\n"
                     "ground 0 0\ntime 1 0.01\n")
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out), "-q", "--steps", "3",
                 "--set", "time.dt=0.02"]) == 0
    return scene, out


def _sink_a_vertex(out, depth=1.0):
    frame = out / "frames" / "frame_000002.vtu"
    mesh = meshio.read(frame)
    mesh.points[0, 1] = -depth
    meshio.write(frame, mesh)


def test_frames_without_their_scene_are_not_passed(dropped, capsys):
    """Without scene.toml the plane test cannot be made: the check says so and fails
    (status 2) instead of passing a vertex 1 m below the ground; given the scene, it
    checks everything."""
    scene, out = dropped
    _sink_a_vertex(out)
    (out / "scene.toml").unlink()
    capsys.readouterr()
    assert main(["check", "--frames", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "scene.toml" in err and "check SCENE --frames" in err and len(err.splitlines()) == 1
    assert main(["check", str(scene), "--frames", str(out), "--set", "time.dt=0.02"]) == 1
    assert "below a plane" in capsys.readouterr().out
    (out / "scene.toml").mkdir()  # not a regular file either
    assert main(["check", "--frames", str(out)]) == 2
    assert "scene.toml" in capsys.readouterr().err


def test_check_with_a_scene_and_frames_uses_the_scene_and_its_overrides(dropped, capsys):
    """`check SCENE --frames OUT` checks OUT's frames against SCENE (with --set), which
    must be the run's scene; --set without a scene is refused, not ignored."""
    scene, out = dropped
    capsys.readouterr()
    assert main(["check", str(scene), "--frames", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "is not the scene" in err and str(out) in err and len(err.splitlines()) == 1
    assert main(["check", str(scene), "--frames", str(out), "--set", "time.dt=0.02"]) == 0
    capsys.readouterr()
    assert main(["check", "--frames", str(out), "--set", "time.dt=0.02"]) == 2
    assert "--set" in capsys.readouterr().err


def test_check_frames_finds_a_cube_moved_inside_another(tmp_path, capsys):
    """Two cubes apart on the ground; in frame 2 the second sits wholly inside the first
    (scaled 3x): no surface crosses, yet it is an intersection (exit 1)."""
    from generated import write_box_msh

    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "two.txt"
    scene.write_text("shapes input 2\ncube.msh 0 0.01 0  0 0 0  3 3 3\n"
                     "cube.msh 1 0.01 0  0 0 0  1 1 1\nground 0 0\ntime 1 0.01\n")
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out), "-q", "--steps", "3"]) == 0
    assert main(["check", "--frames", str(out)]) == 0
    frame = out / "frames" / "frame_000002.vtu"
    mesh = meshio.read(frame)
    second = mesh.point_data["body_id"] == 1
    mesh.points[second] += [-1.0, 0.2, 0.0]  # into the big cube's middle
    meshio.write(frame, mesh)
    capsys.readouterr()
    assert main(["check", "--frames", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "frame_000002.vtu" in printed and "inside another" in printed
    assert "body 1 inside body 0" in printed
