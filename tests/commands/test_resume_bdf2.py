"""--resume with BDF2 and with adaptive steps: a run of N steps and a run of k steps
resumed to N write the same bytes, frame for frame (the checkpoint carries BDF2's step
before, the time, the next step's length and the rejected count); steps.csv records
every attempt and run.json the totals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.io.csv_log import read_csv

BAR = Path(__file__).parents[2] / "input" / "spinning_bar.txt"


@pytest.fixture
def stack(tmp_path):
    """A cube dropped off-centre onto another on the ground: mesh contact, friction and
    κ adaptation, so the resumed state must carry all of them."""
    write_box_msh(tmp_path / "cube.msh")

    def scene(extra: str):
        path = tmp_path / f"stack_{abs(hash(extra))}.txt"
        path.write_text("shapes input 2\n"
                        "cube.msh 0 0.002 0  0 0 0  1 1 1\n"
                        "cube.msh 0.08 0.21 0  0 0 0  1 1 1\n"
                        "selfFric 0.2\nground 0.3 0\ntime 1.5 0.01\n" + extra)
        return path
    return scene


@pytest.fixture
def bar(tmp_path):
    """The spinning bar (no contact) over 0.3 s."""
    def scene(extra: str):
        path = tmp_path / f"bar_{abs(hash(extra))}.txt"
        text = BAR.read_text().replace("input/meshes/bar.msh",
                                       str(BAR.parent / "meshes" / "bar.msh"))
        path.write_text(text.replace("time 1 0.025", "time 0.3 0.025") + extra)
        return path
    return scene


def _frames(out) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((out / "frames").glob("frame_*.vtu"))}


def _same_runs(scene, tmp_path, steps: int, stops: tuple[int, ...]) -> None:
    reference = tmp_path / "reference"
    assert main(["run", str(scene), "-o", str(reference), "-q", "--steps", str(steps)]) == 0
    frames = _frames(reference)
    assert len(frames) == steps + 1
    for k in stops:
        out = tmp_path / f"resumed_at_{k}"
        assert main(["run", str(scene), "-o", str(out), "-q", "--steps", str(k)]) == 0
        assert main(["run", str(scene), "-o", str(out), "-q", "--steps", str(steps),
                     "--resume"]) == 0
        assert _frames(out) == frames, k
        rows, ref_rows = read_csv(out / "steps.csv"), read_csv(reference / "steps.csv")
        for column in ("step", "time", "dt", "error_estimate", "accepted", "kappa"):
            assert np.array_equal(rows[column], ref_rows[column], equal_nan=True), column
        info = json.loads((out / "run.json").read_text())
        ref_info = json.loads((reference / "run.json").read_text())
        for key in ("steps_accepted", "steps_rejected", "simulated_time"):
            assert info[key] == ref_info[key], key


def test_a_resumed_bdf2_run_in_contact_writes_the_bytes_of_an_uninterrupted_one(stack,
                                                                                tmp_path):
    _same_runs(stack("timeIntegration BDF2\n"), tmp_path, 30, (9, 22))


@pytest.mark.parametrize("extra", ["timeIntegration BDF2\ntimeTolerance 1e-3\n",
                                   "timeTolerance 1e-2\n"])
def test_a_resumed_adaptive_run_writes_the_bytes_of_an_uninterrupted_one(bar, tmp_path,
                                                                         extra):
    _same_runs(bar(extra), tmp_path, 12, (1, 7))


def test_an_adaptive_run_records_every_attempt_and_its_totals(bar, tmp_path):
    out = tmp_path / "out"
    assert main(["run", str(bar("timeIntegration BDF2\ntimeTolerance 1e-4\n")), "-o",
                 str(out), "-q"]) == 0
    rows = read_csv(out / "steps.csv")
    info = json.loads((out / "run.json").read_text())
    accepted = rows["accepted"] == 1
    assert info["steps_accepted"] == accepted.sum() > 12
    assert info["steps_rejected"] == (~accepted).sum() > 0
    assert info["simulated_time"] == pytest.approx(0.3, rel=1e-12)
    assert info["newton_iterations"] == rows["newton_iterations"].sum()
    # every step of dt ends on its time exactly, where its frame is written
    last = {int(s): t for s, t in zip(rows["step"], rows["time"])}
    assert all(t == s * 0.025 for s, t in last.items()) and len(last) == 12
    assert (rows["dt"] <= 0.025 * (1 + 1e-12)).all()
