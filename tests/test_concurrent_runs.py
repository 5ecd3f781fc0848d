"""One writer per folder: while a run (or a resumed run, or a study) writes its folder, a
second `ipcsim run` (new, --overwrite or --resume) or `ipcsim sweep` into it is refused
with exit status 2, naming the folder and the process that holds it, and changes nothing
there. The hold is an OS lock that ends with its process: a run killed with SIGKILL
leaves no stale lock, and its folder resumes at once."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.io.output_folder import LOCK_NAME

# a cube resting on the ground for ten thousand steps: long enough to be still running
# while the test tries to write its folder (it is killed then)
LONG = ("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1\nselfCollisionOff\n"
        "ground 0 0\ntime 100 0.01\n")
STUDY = '[study]\nscene = "long.txt"\n\n[[vary]]\n"time.dt" = [0.01]\n'


@pytest.fixture
def long_scene(tmp_path):
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "long.txt"
    scene.write_text(LONG)
    return scene


def _start(*argv) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "ipcsim", *argv, "-q"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _wait_for(proc, folder, pattern, timeout=240.0):
    """The first file under ``folder`` matching ``pattern``, once ``proc`` wrote it."""
    deadline = time.monotonic() + timeout
    while not (found := sorted(folder.glob(pattern))):
        assert proc.poll() is None, f"ended early: {proc.communicate()}"
        assert time.monotonic() < deadline, "the run never started"
        time.sleep(0.02)
    return found[0]


def _kill(proc) -> None:
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)


def _refused(capsys, argv, folder, pid) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert str(folder) in err and f"pid {pid}" in err and "in use" in err, err


def test_a_second_writer_is_refused_and_a_killed_run_leaves_no_stale_lock(long_scene,
                                                                         tmp_path, capsys):
    out = tmp_path / "out"
    first = _start("run", str(long_scene), "-o", str(out))
    try:
        _wait_for(first, out, "checkpoint.npz")
        scene_toml = (out / "scene.toml").read_bytes()
        for again in ("--overwrite", "--resume"):
            _refused(capsys, ["run", str(long_scene), "-o", str(out), "-q", again,
                              "--steps", "3"], out, first.pid)
        assert (out / "scene.toml").read_bytes() == scene_toml
        assert first.poll() is None  # the first run goes on, alone in its folder
    finally:
        _kill(first)
    # the lock died with the process: the folder resumes at once, one step further
    with np.load(out / "checkpoint.npz") as checkpoint:
        step = int(checkpoint["step"])
    assert main(["run", str(long_scene), "-o", str(out), "-q", "--resume", "--steps",
                 str(step + 1)]) == 0
    assert not (out / LOCK_NAME).exists()  # let go: no lock file left behind


def test_a_study_holds_its_folder_and_each_run_folder(long_scene, tmp_path, capsys):
    study = tmp_path / "study.toml"
    study.write_text(STUDY.replace("[study]", "[study]\nsteps = 10000"))
    out = tmp_path / "study_out"
    first = _start("sweep", str(study), "-o", str(out), "--serial")
    try:
        run_folder = _wait_for(first, out, "runs/*/checkpoint.npz").parent
        _refused(capsys, ["sweep", str(study), "-o", str(out), "--serial", "-q"], out,
                 first.pid)
        _refused(capsys, ["run", str(long_scene), "-o", str(run_folder), "-q",
                          "--overwrite", "--steps", "3"], run_folder, first.pid)
    finally:
        _kill(first)


def test_the_lock_is_refused_in_process_and_kept_by_overwrite(tmp_path):
    from ipcsim.io.output_folder import OutputFolderError, hold_folder, prepare_output_folder

    folder = tmp_path / "run"
    with hold_folder(folder) as held:
        assert (folder / LOCK_NAME).read_text().strip() == str(os.getpid())
        with pytest.raises(OutputFolderError, match=f"pid {os.getpid()}"):
            hold_folder(folder)
        (folder / "steps.csv").write_text("old")
        prepare_output_folder(folder, overwrite=True)
        assert (folder / LOCK_NAME).is_file() and not (folder / "steps.csv").exists()
        assert held.folder == folder
    assert not (folder / LOCK_NAME).exists()
    with hold_folder(folder):  # let go: free again
        pass
