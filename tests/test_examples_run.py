"""The original program's frictionless example scenes that finish in about a minute run
to the end here, every step converges, and every frame passes the exact check (no
intersection, no inverted tet, no vertex below a plane). The longer ones (the twisted
mat, the time-step sweep of tb1_diffDt) run in benchmarks/scene_table.py instead."""

from __future__ import annotations

import pytest
from examples import IPC_EXAMPLES

from ipcsim.cli import main
from ipcsim.io.csv_log import read_csv

SCENES = [
    "paperExamples/10_cubeStack.txt",
    "tutorialExamples/advanced/2cubesFall_NM.txt",
    "otherExamples/barTwist_noCollisions.txt",
    "paperExamples/2_matKnives.txt",
]


@pytest.mark.parametrize("scene", SCENES, ids=lambda s: s.split("/")[-1])
def test_frictionless_example_runs_to_the_end(scene, tmp_path, capsys):
    path = IPC_EXAMPLES / "input" / scene
    if not path.is_file():
        pytest.skip("../shared/ipc-examples is not present")
    out = tmp_path / "out"
    assert main(["run", str(path), "-o", str(out), "-q"]) == 0
    steps = read_csv(out / "steps.csv")
    assert steps["converged"].all() and not steps["hit_iteration_cap"].any()
    assert main(["check", "--frames", str(out)]) == 0
    assert "checked" in capsys.readouterr().out
