"""A run killed anywhere, or stopped by a full disk, loses nothing: ``--resume`` finishes
it bit-identical to a run that was never interrupted, and no temporary file is left.

SIGKILL comes at points chosen from a fixed seed: while a frame, ``series.pvd``,
``checkpoint.npz`` or ``scene.toml`` is half written or fully written but not yet
renamed, right after a rename, halfway through a CSV row or right after one (through
tests/kill_points.py), or after a random number of logged steps. Some trials kill the
resumed run too. CI makes ``IPCSIM_FAULT_KILLS`` (default 4) kills; the full check is
``IPCSIM_FAULT_KILLS=24 python -m pytest tests/test_fault_injection.py``.

The full disk is simulated in-process: writes raise ``OSError(ENOSPC)`` from a chosen
point on, the run stops with a one-line error, and a resume with space again finishes it.
"""

from __future__ import annotations

import errno
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from generated import write_box_msh

from ipcsim.atomic import is_temporary_name
from ipcsim.cli import main
from ipcsim.io import csv_log
from ipcsim.io.output_folder import LOCK_NAME

KILLS = int(os.environ.get("IPCSIM_FAULT_KILLS", "4"))
SEED = 20240611
HELPER = Path(__file__).with_name("kill_points.py")
REPO = Path(__file__).resolve().parents[1]

# two cubes falling on each other and the ground, with friction: mesh and plane contact,
# friction lagging and kappa adaptation all carried across a resume; a frame every 2 steps
SCENE = ("shapes input 2\ncube.msh 0 0.002 0  0 0 0  1 1 1\n"
         "cube.msh 0.05 0.21 0  0 0 0  1 1 1\nselfFric 0.2\nground 0.3 0\n"
         "time 0.2 0.005\n")
STEPS = 40
POINTS = {"before-rename": 60, "mid-write": 60, "after-rename": 60, "mid-row": 150,
          "after-row": 150, "rows": STEPS}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = tmp_path_factory.mktemp("fault")
    write_box_msh(root / "cube.msh", cells=(1, 1, 1))
    path = root / "stack.txt"
    path.write_text(SCENE)
    return path


@pytest.fixture(scope="module")
def reference(scene):
    out = scene.parent / "reference"
    assert main(["run", str(scene), "-o", str(out), "-q"]) == 0
    return out


def _helper(point: str, n: int, argv: list[str]) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), str(REPO / "tests")])}
    cmd = ([sys.executable, str(HELPER), point, str(n)] if point != "rows"
           else [sys.executable, "-m", "ipcsim"])
    return subprocess.Popen(cmd + argv, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)


def _rows(out: Path) -> int:
    path = out / "steps.csv"
    return max(0, len(path.read_bytes().split(b"\n")) - 2) if path.is_file() else 0


def _kill_once(point: str, n: int, argv: list[str], out: Path) -> bool:
    """Run ``argv`` until it dies at (point, n); True when it was killed."""
    proc = _helper(point, n, argv)
    if point == "rows":  # SIGKILL from outside once n steps are logged
        deadline = time.monotonic() + 300
        while _rows(out) < n and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        if proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode in (0, -signal.SIGKILL), err.decode()
    return proc.returncode == -signal.SIGKILL


def _table(path: Path, drop_wall: bool) -> list[list[str]]:
    rows = [line.split(",") for line in path.read_text().splitlines()]
    keep = [j for j, c in enumerate(rows[0]) if not (drop_wall and c.startswith("wall_"))]
    return [[r[j] for j in keep] for r in rows]


def assert_same_end_state(out: Path, ref: Path) -> None:
    """Every frame, the series, the scene and the logs (but their wall times) equal to
    the byte; the checkpoint's arrays equal; no temporary file anywhere."""
    names = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    ref_names = sorted(p.relative_to(ref).as_posix() for p in ref.rglob("*") if p.is_file())
    assert [n for n in names if is_temporary_name(Path(n).name)] == []
    assert names == ref_names
    for name in names:
        if name.startswith("frames/") or name == "scene.toml":
            assert (out / name).read_bytes() == (ref / name).read_bytes(), name
    assert _table(out / "steps.csv", True) == _table(ref / "steps.csv", True)
    assert (out / "newton.csv").read_bytes() == (ref / "newton.csv").read_bytes()
    with np.load(out / "checkpoint.npz") as a, np.load(ref / "checkpoint.npz") as b:
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            assert np.array_equal(a[key], b[key]), key


def test_sigkill_at_random_points_then_resume_ends_bit_identical(scene, reference):
    rng = random.Random(SEED)
    kills, trial, where = 0, 0, {}
    while kills < KILLS:
        trial += 1
        out = scene.parent / f"killed{trial}"  # beside the reference: the same scene.toml
        run = ["run", str(scene), "-o", str(out), "-q"]
        attempts = [run]
        if rng.random() < 0.5:
            attempts.append(run + ["--resume"])  # kill the resumed run as well
        for argv in attempts:
            if "--resume" in argv and not (out / "checkpoint.npz").is_file():
                break
            point = rng.choice(sorted(POINTS))
            if _kill_once(point, rng.randint(1, POINTS[point]), argv, out):
                kills += 1
                where[point] = where.get(point, 0) + 1
        again = run + (["--resume"] if (out / "checkpoint.npz").is_file() else ["--overwrite"])
        assert main(again) == 0
        assert_same_end_state(out, reference)
    print(f"\n{kills} SIGKILLs in {trial} trials, each resumed: {where}")
    assert kills >= KILLS


class _FullDisk:
    """Writes fail with ENOSPC from the ``after``-th one on, in files whose name
    contains ``name`` (a frame, the checkpoint, ...), or in CSV rows (``name="csv"``):
    at the opening of a file that ``ipcsim.atomic`` creates (``open``, ``os.open``)."""

    def __init__(self, monkeypatch, name: str, after: int):
        self.name, self.after, self.count = name, after, 0
        import ipcsim.atomic

        real_open, real_line = open, csv_log.CsvLog._write_line

        def fail_now(path) -> bool:
            if self.name in str(path) and Path(path).name != LOCK_NAME:  # output files only
                self.count += 1
            return self.count >= self.after

        def fake_open(path, mode="r", *args, **kwargs):
            f = real_open(path, mode, *args, **kwargs)
            if "w" in mode and self.name != "csv" and fail_now(path):
                f.close()
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
            return f

        real_os_open = os.open

        def fake_os_open(path, flags, *args, **kwargs):  # atomic_write_bytes's files
            fd = real_os_open(path, flags, *args, **kwargs)
            if flags & os.O_CREAT and self.name != "csv" and fail_now(path):
                os.close(fd)
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
            return fd

        def fake_line(log, line):
            if self.name == "csv" and fail_now("csv"):
                log._file.write(line[: len(line) // 3])  # a part of the row got out
                log._file.flush()
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            real_line(log, line)

        monkeypatch.setattr(ipcsim.atomic, "open", fake_open, raising=False)
        monkeypatch.setattr(os, "open", fake_os_open)
        monkeypatch.setattr(csv_log.CsvLog, "_write_line", fake_line)


@pytest.mark.parametrize("name,after", [("frame_", 7), ("checkpoint", 5), ("series", 9),
                                        ("csv", 30), ("run.json", 1)])
def test_a_full_disk_stops_the_run_with_one_line_and_a_resumable_folder(
        scene, reference, monkeypatch, capsys, name, after):
    out = scene.parent / f"full-{name.strip('_').replace('.', '-')}"
    run = ["run", str(scene), "-o", str(out), "-q"]
    with monkeypatch.context() as m:
        _FullDisk(m, name, after)
        assert main(run) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "No space left on device" in err, err
    assert "--resume" in err
    assert not [p for p in out.rglob("*") if is_temporary_name(p.name)]
    assert main(run + ["--resume"]) == 0
    assert_same_end_state(out, reference)


def test_a_full_disk_before_the_first_checkpoint_says_to_run_again(scene, monkeypatch,
                                                                   capsys):
    out = scene.parent / "full-at-start"
    with monkeypatch.context() as m:
        _FullDisk(m, "scene.toml", 1)
        assert main(["run", str(scene), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert "No space left on device" in err and "run again" in err and "\n" not in err


def test_a_full_disk_while_resuming_leaves_the_folder_resumable(scene, reference,
                                                                monkeypatch, capsys):
    out = scene.parent / "full-resume"
    run = ["run", str(scene), "-o", str(out), "-q"]
    assert main(run + ["--steps", "16"]) == 0  # a frame step: the same frames as a whole run
    with monkeypatch.context() as m:
        _FullDisk(m, "steps.csv", 1)  # the log is rewritten without the dropped rows
        assert main(run + ["--resume"]) == 2
    err = capsys.readouterr().err.strip()
    assert "No space left on device" in err and "--resume" in err and "\n" not in err
    assert main(run + ["--resume"]) == 0
    assert_same_end_state(out, reference)
