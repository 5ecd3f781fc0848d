"""BDF2 and adaptive time steps in scene files: ``timeIntegration BDF2`` and
``timeTolerance`` (ipcsim's extensions of the original's format), ``[integrator] type =
"BDF2"`` and ``[time] tolerance`` in TOML, ``--set time.tolerance=``, their checks and
their round trips."""

from __future__ import annotations

import pytest

from ipcsim.errors import SceneError
from ipcsim.scene import load_scene, save_scene

TXT = "shapes input 1\nmeshes/cube.msh 0 0 0  0 0 0  1 1 1\ntime 1 0.025\n"
TOML = '[time]\nduration = 1.0\ndt = 0.025\n\n[[shapes]]\npath = "meshes/cube.msh"\n'


def test_text_keywords(load_text):
    spec = load_text(TXT + "timeIntegration BDF2\ntimeTolerance 1e-3\n")
    assert (spec.integrator, spec.time_tolerance, spec.dt) == ("BDF2", 1e-3, 0.025)
    assert spec.line_of("integrator.type") == 4 and spec.line_of("time.tolerance") == 5
    plain = load_text(TXT)
    assert (plain.integrator, plain.time_tolerance) == ("BE", None)


def test_toml_keys(load_text):
    text = TOML.replace("dt = 0.025\n", "dt = 0.025\ntolerance = 1e-4\n") \
        + '\n[integrator]\ntype = "BDF2"\n'
    spec = load_text(text, "s.toml")
    assert (spec.integrator, spec.time_tolerance) == ("BDF2", 1e-4)
    assert spec.line_of("time.tolerance") == 4


@pytest.mark.parametrize("name", ["s.txt", "s.toml"])
def test_both_round_trips_keep_them(load_text, scene_dir, name):
    spec = load_text(TXT + "timeIntegration BDF2\ntimeTolerance 2.5e-3\n")
    again = load_scene(save_scene(spec, scene_dir / name))
    assert (again.integrator, again.time_tolerance) == ("BDF2", 2.5e-3)
    assert again == spec


def test_an_override_sets_the_tolerance(write_scene):
    spec = load_scene(write_scene(TXT), {"time.tolerance": 1e-3})
    assert spec.time_tolerance == 1e-3 and spec.overrides == {"time.tolerance": 1e-3}
    assert load_scene(write_scene(TXT), {"integrator.type": "BDF2"}).integrator == "BDF2"


@pytest.mark.parametrize("line, message", [
    ("timeTolerance 0", "scene.txt:4: `timeTolerance` must be > 0 (got 0.0)"),
    ("timeTolerance -1e-3", "scene.txt:4: `timeTolerance` must be > 0 (got -0.001)"),
    ("timeTolerance 1", "scene.txt:4: `timeTolerance` must be below 1: it is an error "
                        "relative to the scene size (got 1.0)"),
    ("timeTolerance nan", "scene.txt:4: `timeTolerance` relative error must be a finite number"),
    ("timeTolerance", "scene.txt:4:"),
    ("timeIntegration BDF", "scene.txt:4: unknown time integrator 'BDF' (did you mean "),
])
def test_bad_text_values_name_the_line(write_scene, line, message):
    with pytest.raises(SceneError) as err:
        load_scene(write_scene(TXT + line + "\n"))
    text = str(err.value)
    assert message in text and "\n" not in text


@pytest.mark.parametrize("value, message", [
    ("0.0", "time.tolerance must be > 0"),
    ('"small"', "time.tolerance"),
    ("2.0", "time.tolerance must be below 1"),
])
def test_bad_toml_values_name_the_key(write_scene, value, message):
    text = TOML.replace("dt = 0.025\n", f"dt = 0.025\ntolerance = {value}\n")
    with pytest.raises(SceneError) as err:
        load_scene(write_scene(text, "s.toml"))
    assert message in str(err.value) and "s.toml:4" in str(err.value)


def test_bad_override_names_the_override(write_scene):
    with pytest.raises(SceneError, match="override time.tolerance = -1: time.tolerance "
                                         "must be > 0"):
        load_scene(write_scene(TXT), {"time.tolerance": -1})
