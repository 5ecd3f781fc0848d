"""`ipcsim run` end to end: the output folder, the refusal of scenes that need what is not
implemented yet, and `ipcsim check --frames` on the written frames."""

from __future__ import annotations

import json
import subprocess
import sys

import meshio
import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.io.csv_log import read_csv
from ipcsim.io.vtk import read_series
from ipcsim.scene import load_scene


@pytest.fixture
def drop_scene(tmp_path):
    write_box_msh(tmp_path / "cube.msh")
    scene = tmp_path / "drop.txt"
    scene.write_text("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1\n"
                     "selfCollisionOff\nground 0 0\ntime 0.2 0.01\n")
    return scene


def test_run_writes_the_output_folder(drop_scene, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(drop_scene), "-o", str(out), "-q"]) == 0
    steps = read_csv(out / "steps.csv")
    newton = read_csv(out / "newton.csv")
    assert list(steps["step"]) == list(range(1, 21))
    assert steps["converged"].all() and steps["contacts_plane"].max() > 0
    assert len(newton["step"]) >= steps["newton_iterations"].sum()
    frames = sorted((out / "frames").glob("frame_*.vtu"))
    assert len(frames) == 21  # every step at h = 0.01, plus the initial state
    assert meshio.read(frames[-1]).points.shape == (27, 3)
    # the series, rewritten at most once a second during the run, names every frame
    assert [p.name for _, p in read_series(out / "frames" / "series.pvd")] == \
        [p.name for p in frames]
    info = json.loads((out / "run.json").read_text())
    assert info["steps_done"] == 20 and "plane contact (1 plane)" in info["modelled_terms"]
    assert info["peak_memory_mb"] > 10.0
    # the resolved scene reproduces the run's scene
    assert load_scene(out / "scene.toml") == load_scene(drop_scene)
    # an existing output folder is never silently overwritten
    assert main(["run", str(drop_scene), "-o", str(out), "-q"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    # the written frames pass the exact check; a vertex pushed below the ground does not
    assert main(["check", "--frames", str(out)]) == 0
    mesh = meshio.read(frames[5])
    mesh.points[0, 1] = -0.01
    meshio.write(frames[5], mesh)
    assert main(["check", "--frames", str(out)]) == 1
    assert "below a plane" in capsys.readouterr().out


def _exit_by_raising(status):
    """``end_process`` in a test's process: the exit it asks for, as ``sys.exit`` gives
    it (``os._exit`` would end the tests)."""
    raise SystemExit(status)


def test_the_command_exits_with_mains_status_and_frozen_objects(monkeypatch):
    """``console`` (the ``ipcsim`` script, ``python -m ipcsim``) ends the process with
    what ``main`` returned, having frozen the objects left out of the exit's collector
    pass, and with the collector running again even where ``main`` did not resume it."""
    import ipcsim.cli as cli

    calls = []
    monkeypatch.setattr(cli, "main", lambda: calls.append("main") or 3)
    monkeypatch.setattr(cli.gc, "freeze", lambda: calls.append("freeze"))
    monkeypatch.setattr(cli, "end_process",
                        lambda status: calls.append("end") or _exit_by_raising(status))
    try:
        with pytest.raises(SystemExit) as exit_info:
            cli.console()
        assert exit_info.value.code == 3 and calls[0] == "main"
        assert calls[-2:] == ["freeze", "end"]
        assert cli.gc.isenabled()
    finally:
        cli.gc.enable()


def _console_with(monkeypatch, argv, seen: dict):
    """Run ``console`` as the ``ipcsim`` process would, on ``argv``, recording in ``seen``
    whether the collector ran when ``main`` began, at the first step and in ``check``;
    returns its exit status. The collector runs again afterwards whatever happened."""
    import gc

    import ipcsim.cli as cli
    from ipcsim.commands import check as check_command
    from ipcsim.simulation import Simulation

    real_main, real_step, real_check = cli.main, Simulation.step, check_command.main

    def main():
        seen["main"] = gc.isenabled()
        return real_main(argv)

    def step(self):
        seen.setdefault("step", gc.isenabled())
        return real_step(self)

    def check(args):
        seen["check"] = gc.isenabled()
        return real_check(args)

    with monkeypatch.context() as patch:
        patch.setattr(cli, "main", main)
        patch.setattr(Simulation, "step", step)
        patch.setattr(check_command, "main", check)
        patch.setattr(gc, "freeze", lambda: None)  # leave pytest's objects collectable
        patch.setattr(cli, "end_process", _exit_by_raising)
        try:
            with pytest.raises(SystemExit) as exit_info:
                cli.console()
            return exit_info.value.code, gc.isenabled()
        finally:
            gc.enable()


def test_the_collector_is_paused_while_the_command_starts_only(drop_scene, tmp_path,
                                                                monkeypatch):
    """``console`` pauses the cycle collector while modules load and the scene is built
    (ipcsim/start_up.py); a run's steps, other commands and failures run with it."""
    seen = {}
    status = _console_with(monkeypatch, ["run", str(drop_scene), "-o",
                                         str(tmp_path / "out"), "-q"], seen)
    assert status == (0, True) and seen == {"main": False, "step": True}
    seen = {}
    assert _console_with(monkeypatch, ["check", str(drop_scene)], seen) == (0, True)
    assert seen == {"main": False, "check": True}
    seen = {}
    assert _console_with(monkeypatch, ["run", str(tmp_path / "no.txt")], seen) == (2, True)
    assert seen == {"main": False}


def test_a_plain_run_leaves_the_legacy_scripts_and_the_penalty_baseline_unloaded(
        drop_scene, tmp_path):
    """What only a ``script NAME`` scene or the penalty baseline uses is imported by
    those alone (a few milliseconds of a tiny scene's start)."""
    from generated import modules_a_run_imports

    status, modules = modules_a_run_imports(drop_scene, tmp_path / "out", "--steps", "2")
    assert status == 0 and "ipcsim.model.builder" in modules
    assert "ipcsim.model.legacy_scripts" not in modules
    assert "ipcsim.potentials.penalty_contact" not in modules


def test_python_m_ipcsim_runs_a_scene_and_exits_0(tmp_path):
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "drop.txt"
    scene.write_text("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1\nground 0 0\n"
                     "time 0.03 0.01\n")
    done = subprocess.run([sys.executable, "-m", "ipcsim", "run", str(scene), "-o",
                           str(tmp_path / "out"), "-q"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert len(list((tmp_path / "out" / "frames").glob("*.vtu"))) == 4
    missing = subprocess.run([sys.executable, "-m", "ipcsim", "run", str(tmp_path / "no.txt")],
                             capture_output=True, text=True)
    assert missing.returncode == 2 and "not found" in missing.stderr
