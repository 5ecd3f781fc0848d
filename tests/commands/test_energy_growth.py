"""A Newmark run that blows up is stopped: a soft cube thrown spinning onto frictionless
ground at h = 5 ms (the issue's scene, one cell) gains energy at every impact; once its
energy is a thousand times the start's with no work done on it, the run stops with exit
status 3 and says why. Backward Euler and BDF2 on the same scene run to the end."""

from __future__ import annotations

import json

import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.io.csv_log import read_csv


@pytest.fixture
def thrown_cube(tmp_path):
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))

    def scene(integrator: str):
        path = tmp_path / f"thrown_{integrator}.txt"
        path.write_text("shapes input 1\n"
                        "cube.msh 0 0.3 0  0 0 0  1 1 1  initVel 2 -5 0  300 0 500\n"
                        "ground 0 0\ntime 1.5 0.005\ndensity 1000\nstiffness 1e4 0.4\n"
                        f"timeIntegration {integrator}\n")
        return path
    return scene


def test_a_newmark_blow_up_stops_with_status_3(thrown_cube, tmp_path, capsys):
    out = tmp_path / "nm"
    assert main(["run", str(thrown_cube("NM")), "-o", str(out), "-q"]) == 3
    err = capsys.readouterr().err
    assert "the total energy grew" in err and "-fold with no work done on the scene: the " \
        "NM integrator is unstable at h = 0.005 s here; use BE or BDF2" in err
    steps = read_csv(out / "steps.csv")
    assert 0 < len(steps["step"]) < 300
    info = json.loads((out / "run.json").read_text())
    # the step that blew up is named, and the run ends where its logs do
    assert f"step {len(steps['step']) + 1}: the total energy grew" in err
    assert info["outcome"] == "Blow-up" and info["steps_done"] == len(steps["step"])


@pytest.mark.parametrize("integrator", ["BE", "BDF2"])
def test_damping_integrators_run_the_same_scene_to_its_end(thrown_cube, tmp_path,
                                                          integrator):
    out = tmp_path / integrator
    assert main(["run", str(thrown_cube(integrator)), "-o", str(out), "-q"]) == 0
    assert len(read_csv(out / "steps.csv")["step"]) == 300
