"""Regression tests of the command line's promises that the broken-input suite does not
cover case by case: what happens to good data next to bad data, and what a run says
when it does not go as planned."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.io.csv_log import read_csv
from ipcsim.model.generate import box_tet_mesh
from ipcsim.model.surface import boundary_triangles

DROP = ("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1\nselfCollisionOff\nground 0 0\n"
        "time 0.05 0.01\n")


@pytest.fixture
def drop(tmp_path):
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "drop.txt"
    scene.write_text(DROP)
    return scene


def files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_dotdot_in_the_output_path_finds_the_existing_run(drop, tmp_path, capsys):
    """`-o missing/../old` skipped the 'exists' check and mixed two runs' frames."""
    old = tmp_path / "old"
    assert main(["run", str(drop), "-o", str(old), "-q", "--steps", "2"]) == 0
    before = files(old)
    assert main(["run", str(drop), "-o", str(tmp_path / "missing" / ".." / "old"), "-q"]) == 2
    assert "exists; pass --overwrite" in capsys.readouterr().err
    assert files(old) == before and not (tmp_path / "missing").exists()


def test_a_scene_named_dot_dot_does_not_write_into_the_current_directory(drop, tmp_path,
                                                                          monkeypatch, capsys):
    scene = tmp_path / "...txt"
    scene.write_text(DROP)
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(scene), "-q"]) == 2
    assert "cannot name an output folder" in capsys.readouterr().err
    assert not (tmp_path / "frames").exists() and not (tmp_path / "steps.csv").exists()


def test_overwrite_keeps_the_old_run_until_the_new_one_is_built(drop, tmp_path, capsys):
    old = tmp_path / "old"
    assert main(["run", str(drop), "-o", str(old), "-q", "--steps", "2"]) == 0
    before = files(old)
    huge = tmp_path / "huge.txt"
    huge.write_text(DROP + "time 1e300 1e-10\n")  # used to delete the old run, then crash
    assert main(["run", str(huge), "-o", str(old), "-q", "--overwrite"]) == 2
    assert "time steps" in capsys.readouterr().err and files(old) == before
    below = tmp_path / "below.txt"  # refused by the simulation's set-up, not the reader
    below.write_text(DROP.replace("0 0.01 0", "0 -0.05 0"))
    assert main(["run", str(below), "-o", str(old), "-q", "--overwrite"]) == 2
    assert "below a plane" in capsys.readouterr().err and files(old) == before
    # a good scene does replace it
    assert main(["run", str(drop), "-o", str(old), "-q", "--overwrite", "--steps", "1"]) == 0
    assert read_csv(old / "steps.csv")["step"].tolist() == [1]


def test_the_scene_folder_is_not_an_output_folder(drop, tmp_path, capsys):
    assert main(["run", str(drop), "-o", str(tmp_path), "-q", "--overwrite"]) == 2
    assert "the scene's folder" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cube.msh", "drop.txt"]


def test_append_str_names_the_default_output_folder(drop, tmp_path, monkeypatch):
    drop.write_text(DROP + "appendStr try2\n")
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(drop), "-q", "--steps", "1"]) == 0
    assert (tmp_path / "output" / "drop_try2" / "steps.csv").is_file()


def test_steps_must_be_positive(drop, tmp_path, capsys):
    assert main(["run", str(drop), "-o", str(tmp_path / "o"), "--steps", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--steps" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_resume_from_another_directory_and_with_moved_meshes(drop, tmp_path, monkeypatch):
    """--resume compared mesh paths as text: the same scene from another working
    directory was refused, while changed coordinates were accepted."""
    out = tmp_path / "out"
    monkeypatch.chdir(tmp_path)
    assert main(["run", "drop.txt", "-o", "out", "-q", "--steps", "2"]) == 0
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["run", "../drop.txt", "-o", "../out", "-q", "--steps", "3", "--resume"]) == 0
    moved = tmp_path / "moved"
    moved.mkdir()
    shutil.copy(drop, moved / "drop.txt")
    shutil.copy(tmp_path / "cube.msh", moved / "cube.msh")
    assert main(["run", str(moved / "drop.txt"), "-o", str(out), "-q", "--resume"]) == 0
    assert read_csv(out / "steps.csv")["step"].tolist() == [1, 2, 3, 4, 5]


def test_convert_writes_a_new_file_and_replaces_one_only_when_asked(drop, tmp_path, capsys):
    target = tmp_path / "drop.toml"
    assert main(["convert", str(drop), str(target)]) == 0
    target.write_text("# my notes\n")
    assert main(["convert", str(drop), str(target)]) == 2
    assert target.read_text() == "# my notes\n"
    assert main(["convert", str(drop), str(target), "--overwrite"]) == 0
    assert "[[shapes]]" in target.read_text()
    assert main(["convert", str(drop), str(drop)]) == 2
    assert drop.read_text() == DROP  # comments and layout of a source are never lost


def test_a_step_that_does_not_converge_is_warned_about_and_counted(drop, tmp_path, capsys,
                                                                    monkeypatch):
    from ipcsim.simulation import Simulation

    real_step = Simulation.step

    def step(self):
        report = real_step(self)
        if report.row["step"] in (2, 4):
            report.row["converged"] = 0
        return report

    monkeypatch.setattr(Simulation, "step", step)
    out = tmp_path / "out"
    assert main(["run", str(drop), "-o", str(out), "-q"]) == 0
    err = capsys.readouterr().err
    assert "step 2 did not converge" in err and "step 4 did not converge" in err
    assert "2 steps did not converge" in err
    assert json.loads((out / "run.json").read_text())["steps_not_converged"] == 2


def test_a_non_finite_energy_stops_the_run_with_status_3(tmp_path, capsys):
    """`initVel 0 -1e200 0` made the energy infinite; the step was logged converged=0,
    the velocity zeroed and the run exited 0."""
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "fast.txt"
    scene.write_text("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1 initVel 0 -1e200 0 "
                     "0 0 0\nselfCollisionOff\nground 0 0\ntime 0.05 0.01\n")
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out), "-q"]) == 3
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "step 1" in err and "energy is not finite" in err
    assert "inertia" in err
    assert (out / "frames" / "frame_000000.vtu").is_file()
    assert json.loads((out / "run.json").read_text())["status"].startswith("step 1")


def _cube_obj(path: Path, lo, hi) -> None:
    points, tets = box_tet_mesh(1, 1, 1, size=np.subtract(hi, lo), origin=lo)
    faces = boundary_triangles(tets)
    vertices = "".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in points)
    path.write_text(vertices + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))


def test_check_frames_does_not_judge_two_touching_obstacles(tmp_path, capsys):
    """An obstacle cube standing in an obstacle plane made every frame 'broken' (exit 1)
    although no body touched anything."""
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    _cube_obj(tmp_path / "box.obj", (-0.5, -0.1, -0.5), (-0.3, 0.1, -0.3))
    (tmp_path / "plane.obj").write_text("v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\n"
                                        "f 1 3 2\nf 1 4 3\n")
    scene = tmp_path / "obstacles.txt"
    scene.write_text("shapes input 3\ncube.msh 0.3 0.5 0.3  0 0 0  1 1 1\n"
                     "box.obj 0 0 0  0 0 0  1 1 1\nplane.obj 0 0 0  0 0 0  1 1 1\n"
                     "time 0.02 0.01\n")
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out), "-q"]) == 0
    assert main(["check", "--frames", str(out)]) == 0
    report = capsys.readouterr().out
    assert "note: kinematic obstacles touch or overlap" in report
    assert "no intersection" in report
    # a body pushed into the obstacle plane is still a problem
    frame = out / "frames" / "frame_000002.vtu"
    mesh = meshio.read(frame)
    body = mesh.point_data["body_id"] == 0
    mesh.points[body, 1] -= 0.55
    meshio.write(frame, mesh)
    assert main(["check", "--frames", str(out)]) == 1
    assert "frame_000002.vtu" in capsys.readouterr().out


def test_check_refuses_what_run_refuses(tmp_path, capsys):
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "overlap.txt"
    scene.write_text("shapes input 2\ncube.msh 0 0 0  0 0 0  1 1 1\n"
                     "cube.msh 0.05 0.05 0  0 0 0  1 1 1\n")
    assert main(["check", str(scene)]) == 2
    assert "intersect or touch" in capsys.readouterr().err


def test_python_dash_m_ipcsim_and_no_traceback_across_the_process_boundary(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    help_ = subprocess.run([sys.executable, "-m", "ipcsim", "--help"], capture_output=True,
                           text=True, env=env, timeout=120)
    assert help_.returncode == 0 and "run" in help_.stdout
    bad = tmp_path / "bad.txt"
    bad.write_text("shapes input 1\nmissing.msh 0 0 0 0 0 0 1 1 1\n")
    res = subprocess.run([sys.executable, "-m", "ipcsim", "run", str(bad), "-o",
                          str(tmp_path / "o")], capture_output=True, text=True, env=env,
                         timeout=120)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert res.stderr.strip().startswith(f"{bad}:2:")


def test_a_read_only_folder_is_refused_before_overwrite_or_resume_touch_it(drop, tmp_path,
                                                                          monkeypatch, capsys):
    """(Simulated: the tests may run as root, for whom every folder is writable.)"""
    import ipcsim.io.output_folder as output_folder

    old = tmp_path / "old"
    assert main(["run", str(drop), "-o", str(old), "-q", "--steps", "2"]) == 0
    before = files(old)
    monkeypatch.setattr(output_folder.os, "access", lambda path, mode: False)
    for extra in (["--overwrite"], ["--resume"]):
        assert main(["run", str(drop), "-o", str(old), "-q", *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert "permission denied" in err and "\n" not in err
        assert files(old) == before


def test_overwrite_that_cannot_remove_the_old_run_is_one_line(drop, tmp_path, monkeypatch,
                                                              capsys):
    old = tmp_path / "old"
    assert main(["run", str(drop), "-o", str(old), "-q", "--steps", "2"]) == 0

    def refuse(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "unlink", refuse)
    assert main(["run", str(drop), "-o", str(old), "-q", "--overwrite"]) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot prepare output folder" in err and "\n" not in err
