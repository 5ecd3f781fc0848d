"""``ipcsim sweep``: a study of six tiny runs on a local Dask cluster of two worker
processes survives one worker killed (SIGKILL) mid-run, and, re-run, gives the same
study.csv as the same study run serially.

"The same" means: every run finished, and for each run the same steps, the same Newton
iteration count and bitwise the same final positions (study.csv's
``final_positions_sha256``, a SHA-256 of the float64 bytes of the last state)."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import threading
import time

import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.study import load_study

STUDY = """\
[study]
scene = "drop.toml"

[[vary]]
"time.dt" = [0.02, 0.01]

[[vary]]
"contact.dhat" = [1e-3, 3e-3, 1e-2]

[record]
columns = ["newton_iterations", "min_distance"]
check_frames = true

[chart]
x = "contact.dhat"
y = "newton_iterations"
"""

SCENE = """\
[time]
duration = 0.5
dt = 0.01

[contact]
self_collision = false

[[shapes]]
path = "cube.msh"
translation = [0.0, 0.02, 0.0]

[[planes]]
kind = "ground"
height = 0.0
"""


@pytest.fixture
def study(tmp_path, monkeypatch):
    monkeypatch.setenv("IPCSIM_THREADS", "1")  # what --serial sets, undone after the test
    write_box_msh(tmp_path / "cube.msh")
    (tmp_path / "drop.toml").write_text(SCENE)
    path = tmp_path / "study.toml"
    path.write_text(STUDY)
    return path


def _rows(folder):
    with open(folder / "study.csv", newline="") as f:
        return {r["run"]: r for r in csv.DictReader(f)}


def _kill_a_worker_mid_run(proc, out, timeout=240.0):
    """SIGKILL the worker process that is writing a run's steps.csv, a few steps into
    the run; returns that run's folder."""
    import psutil

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        for child in psutil.Process(proc.pid).children(recursive=True):
            try:
                files = [f.path for f in child.open_files()]
            except psutil.Error:
                continue
            for path in files:
                if path.endswith("steps.csv") and str(out) in path:
                    with open(path) as f:
                        written = len(f.read().splitlines()) - 1
                    if 3 <= written <= 15:  # mid-run: runs take 25 or 50 steps
                        child.send_signal(signal.SIGKILL)
                        return path.rsplit("/", 1)[0]
        time.sleep(0.01)
    raise AssertionError("no run was seen in progress")


def test_a_study_survives_a_killed_worker_and_equals_a_serial_run(study, tmp_path):
    import json

    serial, cluster = tmp_path / "serial", tmp_path / "cluster"
    assert main(["sweep", str(study), "-o", str(serial), "--serial", "-q"]) == 0

    proc = subprocess.Popen([sys.executable, "-m", "ipcsim.cli", "sweep", str(study), "-o",
                             str(cluster), "--workers", "2", "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        killed = _kill_a_worker_mid_run(proc, cluster)
        _, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode in (0, 1), err.decode()

    # re-run: what is finished is skipped, what is not resumes from its checkpoint (a
    # checkpoint comes with a frame at most every 2 s, so for these short runs it may
    # still be step 0's); the killed run's cut rows are dropped, each step logged once
    assert main(["sweep", str(study), "-o", str(cluster), "--workers", "2", "-q"]) == 0
    folder = tmp_path / killed
    info = json.loads((folder / "run.json").read_text())
    assert info["status"] == "ok" and info["resumed_from_step"] >= 0
    with open(folder / "steps.csv", newline="") as f:
        logged = [int(r["step"]) for r in csv.DictReader(f)]
    assert logged == list(range(1, info["steps_done"] + 1))

    a, b = _rows(serial), _rows(cluster)
    assert sorted(a) == sorted(b) == [str(i) for i in range(6)]
    for run in a:
        assert a[run]["status"] == b[run]["status"] == "ok", (a[run], b[run])
        for column in ("time.dt", "contact.dhat", "steps_done", "newton_iterations",
                       "final_positions_sha256", "frames_clean"):
            assert a[run][column] == b[run][column], (run, column)
        assert a[run]["frames_clean"] == "True"
    assert len({r["final_positions_sha256"] for r in a.values()}) == 6
    assert (cluster / "study.png").read_bytes()[:4] == b"\x89PNG"


def test_a_failed_run_is_a_row_and_the_study_exits_1(study, tmp_path, capsys):
    study.write_text(STUDY.replace('"contact.dhat" = [1e-3, 3e-3, 1e-2]',
                                   '"material.E" = [1e5, 1e308]')
                     .replace('"time.dt" = [0.02, 0.01]', '"time.dt" = [0.02]')
                     .replace('x = "contact.dhat"', 'x = "material.E"')
                     .replace("[study]", "[study]\nsteps = 3"))
    out = tmp_path / "out"
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q"]) == 1
    rows = _rows(out)
    assert rows["0"]["status"] == "ok" and rows["0"]["steps_done"] == "3"
    assert rows["1"]["status"] == "failed" and "not finite" in rows["1"]["error"]


@pytest.mark.parametrize("change, says", [
    (('"time.dt" = [0.02, 0.01]', '"time.dtt" = [0.02, 0.01]'),
     "study.toml: run 0 (time.dtt = 0.02, contact.dhat = 0.001): "),
    (('"time.dt" = [0.02, 0.01]', '"time.dt" = [0.02, 0.01]\n"contact.epsv" = [1e-3]'),
     "study.toml:4: vary[0]: keys of one [[vary]] table change together"),
    (("[record]", "[recrod]"), "study.toml:10: unknown key recrod (did you mean 'record'?)"),
    (('columns = ["newton_iterations", "min_distance"]', 'columns = ["newton"]'),
     "'newton' is no steps.csv column"),
])
def test_a_bad_study_exits_2_naming_the_file_and_key(study, tmp_path, capsys, change, says):
    study.write_text(STUDY.replace(*change))
    assert main(["sweep", str(study), "-o", str(tmp_path / "out"), "--serial"]) == 2
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "out").exists()


def test_without_dask_the_study_says_how_to_install_it(study, tmp_path, capsys,
                                                       monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import fails
    assert main(["sweep", str(study), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and 'pip install "ipcsim[cluster]"' in err


def test_ranges_zips_and_products(tmp_path, study):
    study.write_text(STUDY.replace('"time.dt" = [0.02, 0.01]',
                                   'time.dt = { start = 0.01, stop = 0.03, step = 0.01 }\n'
                                   '"material.E" = { start = 1e4, stop = 1e6, num = 3, '
                                   'spacing = "log" }'))
    spec = load_study(study)
    points = spec.points()
    assert len(points) == 9 and spec.keys == ("time.dt", "material.E", "contact.dhat")
    assert [p["time.dt"] for p in points[::3]] == pytest.approx([0.01, 0.02, 0.03])
    assert [p["material.E"] for p in points[::3]] == pytest.approx([1e4, 1e5, 1e6])
    assert [p["contact.dhat"] for p in points[:3]] == [1e-3, 3e-3, 1e-2]


def test_the_example_study_of_the_user_guide_plans(repo_root, tmp_path):
    from ipcsim.study.runs import plan

    spec = load_study(repo_root / "input" / "studies" / "cube_drop_dt.toml")
    tasks, reference = plan(spec, tmp_path)
    assert [t.parameters for t in tasks] == [{"time.dt": h} for h in (0.04, 0.02, 0.01, 0.005)]
    assert reference is not None and reference.steps == 800
    assert len({t.folder for t in tasks}) == 4 and spec.output.name == "cube_drop_dt"


def _one_run(steps: int) -> str:
    return (STUDY.replace('"time.dt" = [0.02, 0.01]', '"time.dt" = [0.02]')
            .replace('"contact.dhat" = [1e-3, 3e-3, 1e-2]', '"contact.dhat" = [1e-3]')
            .replace("[study]", f"[study]\nsteps = {steps}"))


def test_fewer_steps_never_replace_a_finished_run(study, tmp_path, capsys):
    """A finished 20-step run is found again by its digest (which leaves the step count
    out) when the study asks for 5: it is kept, and the study refused, until --overwrite."""
    out = tmp_path / "out"
    study.write_text(_one_run(20))
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q"]) == 0
    folder = next((out / "runs").iterdir())
    kept = {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}
    study.write_text(_one_run(5))
    capsys.readouterr()
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(folder) in err and "--overwrite" in err, err
    assert {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()} == kept
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q", "--overwrite"]) == 0
    assert _rows(out)["0"]["steps_done"] == "5"


def test_a_study_continues_in_its_own_folder_and_overwrite_keeps_the_users_files(
        study, tmp_path):
    out = tmp_path / "out"
    study.write_text(_one_run(3))
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q"]) == 0
    (out / "notes.txt").write_text("mine")
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q"]) == 0
    assert _rows(out)["0"]["action"] == "skipped"
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q", "--overwrite"]) == 0
    assert _rows(out)["0"]["action"] == "ran" and (out / "notes.txt").read_text() == "mine"


def _ipcsim(*argv, timeout: float, env=None) -> subprocess.CompletedProcess:
    """``python -m ipcsim ARGV`` in a fresh process, killed after ``timeout`` s (a hang
    fails the test instead of holding the suite)."""
    return subprocess.run([sys.executable, "-m", "ipcsim", *argv], capture_output=True,
                          text=True, timeout=timeout, env=env)


def _one_error_line(done, status: int, *fragments: str) -> None:
    err = done.stderr.strip()
    assert done.returncode == status, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for fragment in fragments:
        assert fragment in err, err


def test_a_study_file_that_is_a_fifo_is_refused_at_once(tmp_path):
    fifo = tmp_path / "study.toml"
    os.mkfifo(fifo)
    done = _ipcsim("sweep", str(fifo), "-o", str(tmp_path / "out"), "--serial", timeout=60)
    _one_error_line(done, 2, str(fifo), "not a regular file")
    assert not (tmp_path / "out").exists()


@pytest.fixture
def http_server():
    """An HTTP server on a free local port: something that listens but is no Dask
    scheduler (it waits for a request line that Dask's handshake never sends)."""
    from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

    server = ThreadingHTTPServer(("127.0.0.1", 0), BaseHTTPRequestHandler)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def test_a_scheduler_that_is_no_dask_scheduler_is_refused_in_bounded_time(study, tmp_path,
                                                                           http_server):
    env = {**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "2s"}
    done = _ipcsim("sweep", str(study), "-o", str(tmp_path / "out"), "--scheduler",
                   http_server, "-q", timeout=120, env=env)
    _one_error_line(done, 2, http_server, "no Dask scheduler answered within 2 s")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_sigterm_ends_a_study_on_dask_as_it_ends_a_serial_one(study, tmp_path, sig):
    """SIGTERM to `ipcsim sweep` (a batch scheduler's) stops it as Ctrl-C does, on Dask
    as with --serial: exit status 130, no traceback, no leaked resources reported, and
    the interrupted run resumes when the study is run again. Ctrl-C (SIGINT) too, even
    where the process started with SIGINT ignored (in a script's background), as `ipcsim
    run` stops there (the study used to run on to its end)."""
    out = tmp_path / "out"
    study.write_text(_one_run(100_000).replace("duration = 0.5", "duration = 10000"))
    (tmp_path / "drop.toml").write_text(SCENE.replace("duration = 0.5", "duration = 10000"))
    proc = subprocess.Popen([sys.executable, "-m", "ipcsim", "sweep", str(study), "-o",
                             str(out), "--workers", "1", "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        deadline = time.monotonic() + 240
        while not list(out.glob("runs/*/checkpoint.npz")):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no run started"
            time.sleep(0.05)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "leaked" not in err, err
    assert "run the same `ipcsim sweep` again" in err, err
    import numpy as np

    folder = next((out / "runs").iterdir())
    with np.load(folder / "checkpoint.npz") as checkpoint:
        step = int(checkpoint["step"])
    study.write_text(_one_run(step + 3).replace("duration = 0.5", "duration = 10000"))
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q"]) == 0
    row = _rows(out)["0"]
    assert row["action"] == "resumed" and row["steps_done"] == str(step + 3), row


def test_study_csv_has_exactly_the_columns_the_study_declares(study, tmp_path):
    """StudySpec.columns (what chart.y is checked against) is study.csv's header: with
    final_state, check_frames and a reference run, and without them."""
    out = tmp_path / "out"
    full = _one_run(3) + '\n[reference]\nset = { "time.dt" = 0.01 }\n'
    for text, name in ((full, "full"), (_one_run(3).replace("check_frames = true",
                                                             "final_state = false"), "bare")):
        study.write_text(text)
        assert main(["sweep", str(study), "-o", str(out / name), "--serial", "-q"]) == 0
        with open(out / name / "study.csv", newline="") as f:
            header = next(csv.reader(f))
        assert sorted(header) == sorted(load_study(study).columns), name


def test_another_study_is_refused_in_a_studys_folder(study, tmp_path, capsys):
    """A second study file run into the folder of the first replaced its study.csv and
    study.png: the folder names the study file that writes it (.ipcsim-study)."""
    out = tmp_path / "out"
    study.write_text(_one_run(2))
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q"]) == 0
    table = (out / "study.csv").read_bytes()
    other = tmp_path / "other.toml"
    other.write_text(_one_run(2).replace('"time.dt" = [0.02]', '"time.dt" = [0.05]'))
    capsys.readouterr()
    assert main(["sweep", str(other), "-o", str(out), "--serial", "-q"]) == 2
    err = capsys.readouterr().err
    assert "holds the study of study.toml, not of other.toml" in err, err
    assert (out / "study.csv").read_bytes() == table
    assert main(["sweep", str(other), "-o", str(out), "--serial", "-q", "--overwrite"]) == 0
    assert _rows(out)["0"]["time.dt"] == "0.05"


@pytest.mark.parametrize("name", ["run.json", "study_row.json"])
def test_a_fifo_in_a_finished_run_folder_does_not_hang_the_study(study, tmp_path, name):
    """Re-running a study read a run's run.json and study_row.json whatever they were: a
    FIFO blocked it for ever. A FIFO study_row.json is no row to reuse (the finished run
    is found by its checkpoint and skipped); without a readable run.json the run is not
    known to be finished, its folder cannot be resumed (a FIFO where run.json belongs),
    and the study runs it again, as it does any damaged run folder of its own."""
    out = tmp_path / "out"
    study.write_text(_one_run(2))
    assert main(["sweep", str(study), "-o", str(out), "--serial", "-q"]) == 0
    folder = next((out / "runs").iterdir())
    for gone in {name, "study_row.json"}:
        (folder / gone).unlink()
    os.mkfifo(folder / name)
    done = _ipcsim("sweep", str(study), "-o", str(out), "--serial", "-q", timeout=120)
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode == 0, done.stderr
    row = _rows(out)["0"]
    assert row["status"] == "ok" and row["steps_done"] == "2"
    assert row["action"] == ("ran" if name == "run.json" else "skipped")
    assert (folder / "run.json").is_file()
