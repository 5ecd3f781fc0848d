"""Every script of the original program parses, and survives conversion both ways."""

from __future__ import annotations

import math

import pytest
from scene_support import example_scripts, extra_scripts_with_meshes

from ipcsim.scene import load_scene, save_scene

# the curated set, and the scripts only the full example tree has (those whose meshes exist)
SCRIPTS = example_scripts() + extra_scripts_with_meshes()


def _id(path):
    return f"{path.parent.name}/{path.name}"


@pytest.mark.parametrize("script", SCRIPTS, ids=_id)
def test_example_parses(script):
    spec = load_scene(script)
    assert spec.shapes, "every example has shapes"
    assert any(s.kind == "tet" for s in spec.shapes)
    assert all(s.mesh_path.is_absolute() and s.mesh_path.exists() for s in spec.shapes)
    assert spec.n_steps == max(1, math.ceil(spec.duration / spec.dt - 1e-9))
    # warnings (e.g. a .seg read from its .obj) name the script and a line
    for w in spec.warnings:
        assert w.startswith(f"{script}:") and ": warning: " in w


@pytest.mark.parametrize("script", SCRIPTS, ids=_id)
def test_example_round_trips(script, tmp_path):
    spec = load_scene(script)
    via_toml = load_scene(save_scene(spec, tmp_path / "scene.toml"))
    assert via_toml == spec
    (tmp_path / "sub").mkdir()  # another folder: relative mesh paths must be rewritten
    via_txt = load_scene(save_scene(spec, tmp_path / "sub" / "scene.txt"))
    assert via_txt == spec
    # and once more through the written forms: the writers are stable
    assert load_scene(save_scene(via_toml, tmp_path / "again.txt")) == spec


def test_known_example_contents(ipc_examples):
    """Spot checks against the scripts' text (values read by eye from the files)."""
    root = ipc_examples / "input"
    s = load_scene(root / "tutorialExamples/BC/2cubesFall_DBC_timeRange.txt")
    assert [d.time_range for d in s.shapes[1].dbc] == [(0, 2.5), (2.5, math.inf),
                                                       (0, 2.5), (2.5, math.inf)]
    assert s.shapes[1].dbc[3].linear_velocity == (0.2, 0.0, 0.2)
    assert s.planes[0].kind == "ground" and s.planes[0].friction == 0.1

    s = load_scene(root / "otherExamples/friction/slopeTest_highSchoolPhysics_0.49.txt")
    assert s.newton_tol == (1e-4,) and s.epsv == 1e-5 and s.dhat_start is None
    assert s.friction_iterations == -1 and s.energy == "FCR" and s.script == "fall"
    n = s.planes[0].normal
    assert n == pytest.approx((1 / math.sqrt(5), 2 / math.sqrt(5), 0.0))
    assert set(s.ignored) == {"zoom 0.3", "view orthographic"}

    s = load_scene(root / "paperExamples/2_matKnives.txt")
    # the `section QP` block (dt 5e-3, tol 1e-4) is skipped for the interior-point solver
    assert (s.duration, s.dt, s.newton_tol) == (6.0, 0.04, (1e-2,))
    assert len(s.shapes) == 10 and s.script == "DCOFix"

    s = load_scene(root / "tutorialExamples/MCO/2cubesFall_rotateCO_edges.txt")
    edge = s.shapes[1]
    assert edge.kind == "segments" and edge.mesh_path.name == "triangle.obj"
    assert any("triangle.seg' does not exist" in w for w in s.warnings)

    s = load_scene(root / "tutorialExamples/advanced/2cubesFall_rotateCO_meshSeq.txt")
    assert s.shapes[1].mesh_sequence.is_dir()
