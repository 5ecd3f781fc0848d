"""The model carries the integrator and the time tolerance; until the time step takes
BDF2 and adaptive steps, the builder refuses a scene that asks for them."""

from __future__ import annotations

import subprocess
import sys

import pytest

from ipcsim.errors import SceneError
from ipcsim.model.builder import build_model, time_settings
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


@pytest.mark.parametrize("extra, line, says", [
    ("timeIntegration BDF2\n", 5, "the BDF2 integrator is read but not simulated"),
    ("timeTolerance 1e-3\n", 5, "adaptive time steps (a time tolerance) are read but not "
                                "simulated"),
])
def test_the_builder_refuses_what_the_step_does_not_take(mesh_dir, extra, line, says):
    path = _scene(mesh_dir, extra)
    with pytest.raises(SceneError) as err:
        build_model(load_scene(path))
    assert str(err.value).startswith(f"{path}:{line}: {says}")


def test_run_says_so_on_one_line_and_exits_2(mesh_dir, tmp_path):
    path = _scene(mesh_dir, "timeIntegration BDF2\n")
    done = subprocess.run([sys.executable, "-m", "ipcsim", "run", str(path), "-o",
                           str(tmp_path / "out"), "-q"], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.strip() == (f"{path}:5: the BDF2 integrator is read but not simulated "
                                   "by this version of ipcsim; use BE or NM")
