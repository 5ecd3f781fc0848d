"""The model carries the integrator and the time tolerance, in 3D and 2D; the builder
refuses adaptive steps where they cannot work (Newmark has no error estimate) and warns
where they would be slow only because the scene names no integrator (BE by default)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from ipcsim.errors import SceneError
from ipcsim.model.build import build_model
from ipcsim.model.builder import time_settings
from ipcsim.scene import load_scene

SCENE = "shapes input 1\ncube1.msh 0 0 0  0 0 0  1 1 1\ntime 0.5 0.025\nturnOffGravity\n"


def _scene(mesh_dir, extra: str = "", name: str = "s.txt"):
    path = mesh_dir / name
    path.write_text(SCENE + extra)
    return path


def test_the_time_settings_carry_bdf2_and_the_tolerance_absolute(mesh_dir):
    spec = load_scene(_scene(mesh_dir, "timeIntegration BDF2\ntimeTolerance 1e-3\n"))
    time = time_settings(spec, 2.0)
    assert (time.integrator, time.dt, time.n_steps) == ("BDF2", 0.025, 20)
    assert time.tolerance == pytest.approx(2e-3) and time.duration == 0.5


def test_a_scene_without_them_builds_as_before(mesh_dir):
    model = build_model(load_scene(_scene(mesh_dir)))
    assert (model.time.integrator, model.time.tolerance) == ("BE", None)
    assert model.time.dt == 0.025 and model.time.n_steps == 20


def test_bdf2_and_adaptive_steps_build(mesh_dir):
    model = build_model(load_scene(_scene(mesh_dir, "timeIntegration BDF2\n"
                                                    "timeTolerance 1e-3\n")))
    assert model.time.integrator == "BDF2" and model.time.tolerance > 0.0


def test_the_builder_refuses_adaptive_newmark(mesh_dir):
    path = _scene(mesh_dir, "timeIntegration NM\ntimeTolerance 1e-3\n")
    with pytest.raises(SceneError) as err:
        build_model(load_scene(path))
    assert str(err.value).startswith(f"{path}:5: adaptive time steps (a time tolerance) "
                                     "need the BE or BDF2 integrator")


def test_run_says_so_on_one_line_and_exits_2(mesh_dir, tmp_path):
    path = _scene(mesh_dir, "timeIntegration NM\ntimeTolerance 1e-3\n")
    done = subprocess.run([sys.executable, "-m", "ipcsim", "run", str(path), "-o",
                           str(tmp_path / "out"), "-q"], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.strip() == (f"{path}:5: adaptive time steps (a time tolerance) need "
                                   "the BE or BDF2 integrator, which estimate their error; "
                                   "Newmark does not")


BE_DEFAULT = "adaptive time steps with backward Euler, the default integrator"


@pytest.mark.parametrize("extra, overrides, warned", [
    ("timeTolerance 1e-3\n", {}, True),  # BE only by default
    ("timeTolerance 1e-3\ntimeIntegration BE\n", {}, False),  # BE named
    ("timeTolerance 1e-3\n", {"integrator.type": "BE"}, False),  # named by --set
    ("timeTolerance 1e-3\ntimeIntegration BDF2\n", {}, False),
    ("", {}, False),  # fixed steps
])
def test_a_tolerance_with_be_by_default_is_warned(mesh_dir, extra, overrides, warned):
    model = build_model(load_scene(_scene(mesh_dir, extra), overrides=overrides))
    assert any(w.startswith(BE_DEFAULT) for w in model.warnings) == warned


def test_a_2d_scene_carries_its_tolerance_and_the_same_warning(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[scene]\ndimension = 2\n[time]\ndt = 0.01\nduration = 0.1\n'
                    'tolerance = 1e-3\n[[shapes]]\nkind = "rectangle"\nsize = [1.0, 1.0]\n'
                    'resolution = [2, 2]\n')
    model = build_model(load_scene(path))
    assert model.dimension == 2 and model.time.duration == pytest.approx(0.1)
    assert model.time.tolerance == pytest.approx(1e-3 * model.bbox_diagonal)
    assert any(w.startswith(BE_DEFAULT) for w in model.warnings)
    # an [integrator] table that names no type does not name the integrator
    path.write_text(path.read_text() + "[integrator]\ndamping_ratio = 0.0\n")
    assert any(w.startswith(BE_DEFAULT) for w in build_model(load_scene(path)).warnings)
