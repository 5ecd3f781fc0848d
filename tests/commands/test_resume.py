"""Nothing is lost on a crash: a run killed with SIGKILL, then stopped with Ctrl-C, then
resumed twice ends exactly where an uninterrupted run ends; and NaN stops a run with exit
status 3 naming the step and the term."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import meshio
import numpy as np
import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.io.csv_log import read_csv

STEPS = 150


@pytest.fixture
def stacked_cubes(tmp_path):
    """A cube dropped off-centre onto another on the ground: mesh contact, friction on
    both contacts and κ adaptation, so the resumed state must carry all of them."""
    write_box_msh(tmp_path / "cube.msh")
    scene = tmp_path / "stack.txt"
    scene.write_text("shapes input 2\n"
                     "cube.msh 0 0.002 0  0 0 0  1 1 1\n"
                     "cube.msh 0.08 0.21 0  0 0 0  1 1 1\n"
                     "selfFric 0.2\nground 0.3 0\ntime 1.5 0.01\n")
    return scene


def _rows(out):
    path = out / "steps.csv"
    return max(0, len(path.read_text().splitlines()) - 1) if path.is_file() else 0


def _start(scene, out, *extra):
    return subprocess.Popen([sys.executable, "-m", "ipcsim.cli", "run", str(scene), "-o",
                             str(out), "-q", "--steps", str(STEPS), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _wait_for_rows(proc, out, rows, timeout=240.0):
    deadline = time.monotonic() + timeout
    while _rows(out) < rows:
        assert proc.poll() is None, f"run ended early: {proc.communicate()}"
        assert time.monotonic() < deadline, "run made no progress"
        time.sleep(0.02)


def _final_positions(out):
    frames = sorted((out / "frames").glob("frame_*.vtu"))
    return frames, meshio.read(frames[-1]).points


def test_killed_interrupted_and_resumed_run_equals_an_uninterrupted_one(stacked_cubes,
                                                                         tmp_path):
    scene = stacked_cubes
    out = tmp_path / "resumed"

    proc = _start(scene, out)
    _wait_for_rows(proc, out, 25)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    killed_at = _rows(out)
    assert proc.returncode == -signal.SIGKILL and killed_at < STEPS

    proc = _start(scene, out, "--resume")
    _wait_for_rows(proc, out, killed_at + 25)
    proc.send_signal(signal.SIGINT)  # finishes the current step, then exits 130
    _, err = proc.communicate(timeout=240)
    assert proc.returncode == 130, err.decode()
    assert b"--resume" in err
    stopped_at = _rows(out)
    assert killed_at < stopped_at < STEPS

    assert main(["run", str(scene), "-o", str(out), "-q", "--steps", str(STEPS),
                 "--resume"]) == 0

    reference = tmp_path / "reference"
    assert main(["run", str(scene), "-o", str(reference), "-q", "--steps", str(STEPS)]) == 0

    frames, x = _final_positions(out)
    ref_frames, x_ref = _final_positions(reference)
    assert [f.name for f in frames] == [f.name for f in ref_frames]
    assert np.abs(x - x_ref).max() <= 1e-12
    steps, ref_steps = read_csv(out / "steps.csv"), read_csv(reference / "steps.csv")
    assert list(steps["step"]) == list(range(1, STEPS + 1))
    assert np.array_equal(steps["newton_iterations"], ref_steps["newton_iterations"])
    assert steps["contacts_point_triangle"].max() > 0 and np.nanmax(steps["friction_contacts"]) > 0
    newton, ref_newton = read_csv(out / "newton.csv"), read_csv(reference / "newton.csv")
    assert np.array_equal(newton["step"], ref_newton["step"])
    assert np.array_equal(newton["kappa"], ref_newton["kappa"])


def test_a_run_resumed_at_any_of_its_contact_steps_equals_the_uninterrupted_one(
        stacked_cubes, tmp_path):
    """Bit for bit, at fixed steps in mesh contact: the resumed run queries its first
    collision set afresh where the uninterrupted one takes the set its last step ended
    with, and both sets are in canonical order."""
    steps = 40
    reference = tmp_path / "reference"
    assert main(["run", str(stacked_cubes), "-o", str(reference), "-q", "--steps",
                 str(steps)]) == 0
    ref_steps = read_csv(reference / "steps.csv")
    _, x_ref = _final_positions(reference)
    for k in (12, 24, 33):
        assert ref_steps["contacts_point_triangle"][k] > 0  # step k + 1 starts in contact
        out = tmp_path / f"resumed_at_{k}"
        assert main(["run", str(stacked_cubes), "-o", str(out), "-q", "--steps", str(k)]) == 0
        assert main(["run", str(stacked_cubes), "-o", str(out), "-q", "--steps", str(steps),
                     "--resume"]) == 0
        _, x = _final_positions(out)
        assert np.array_equal(x, x_ref), k
        assert np.array_equal(read_csv(out / "newton.csv")["kappa"],
                              read_csv(reference / "newton.csv")["kappa"])


def test_sigterm_stops_after_the_current_step_like_ctrl_c(stacked_cubes, tmp_path):
    """A scheduler's SIGTERM is a request to stop: the step finishes, run.json records
    the interruption, exit status 130, and --resume finishes the run."""
    out = tmp_path / "terminated"
    proc = _start(stacked_cubes, out)
    _wait_for_rows(proc, out, 5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=240)
    assert proc.returncode == 130, err.decode()
    assert b"--resume" in err and b"Traceback" not in err
    stopped_at = _rows(out)
    assert 5 <= stopped_at < STEPS
    info = json.loads((out / "run.json").read_text())
    assert info["steps_done"] == stopped_at and info["status"] != "ok"
    assert main(["run", str(stacked_cubes), "-o", str(out), "-q", "--steps", str(STEPS),
                 "--resume"]) == 0
    assert _rows(out) == STEPS


def test_a_second_signal_inside_a_c_extension_still_stops_cleanly(stacked_cubes, tmp_path,
                                                                  monkeypatch, capsys):
    """The second signal stops at once by raising KeyboardInterrupt, which a C extension
    running at that moment may hand back as its own error (pymetis, inside METIS:
    "RuntimeError: Caught an unknown exception!"). The run still ends as interrupted:
    exit status 130, run.json written, no traceback, resumable."""
    from ipcsim.simulation import Simulation

    step = Simulation.step

    def step_then_signals(self):
        if self.state.step == 3:
            signal.raise_signal(signal.SIGTERM)  # stop after this step
            try:
                signal.raise_signal(signal.SIGTERM)  # stop at once, inside "the extension"
            except KeyboardInterrupt:
                raise RuntimeError("Caught an unknown exception!") from None
        return step(self)

    monkeypatch.setattr(Simulation, "step", step_then_signals)
    out = tmp_path / "twice"
    assert main(["run", str(stacked_cubes), "-o", str(out), "-q", "--steps", "8"]) == 130
    assert "--resume" in capsys.readouterr().err
    info = json.loads((out / "run.json").read_text())
    assert info["steps_done"] == 3 and info["status"] != "ok"
    monkeypatch.setattr(Simulation, "step", step)
    assert main(["run", str(stacked_cubes), "-o", str(out), "-q", "--steps", "8",
                 "--resume"]) == 0
    assert _rows(out) == 8


def test_resume_refuses_a_different_scene_and_a_folder_without_checkpoint(stacked_cubes,
                                                                          tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(stacked_cubes), "-o", str(out), "-q", "--steps", "2"]) == 0
    other = stacked_cubes.with_name("other.txt")
    other.write_text(stacked_cubes.read_text().replace("selfFric 0.2", "selfFric 0.3"))
    assert main(["run", str(other), "-o", str(out), "-q", "--resume"]) == 2
    assert "not the scene the run" in capsys.readouterr().err
    (out / "checkpoint.npz").unlink()
    assert main(["run", str(stacked_cubes), "-o", str(out), "-q", "--resume"]) == 2
    assert "nothing to resume" in capsys.readouterr().err


def test_nan_stops_the_run_with_status_3_naming_step_and_term(tmp_path, capsys):
    """A Young's modulus whose Lamé λ overflows makes the elastic Hessian NaN at step 1."""
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "nan.txt"
    scene.write_text("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1 material 1000 1e308 0.4\n"
                     "selfCollisionOff\nground 0 0\ntime 0.1 0.01\n")
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out), "-q"]) == 3
    err = capsys.readouterr().err
    assert "step 1" in err and "elasticity term" in err and "not finite" in err
    assert (out / "frames" / "frame_000000.vtu").is_file()  # what was written is kept
