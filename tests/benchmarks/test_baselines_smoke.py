"""benchmarks/baselines.py in small: SQP and QP on one tutorial script and one of the
original's failures/ scripts, three steps each, every run labelled."""

from __future__ import annotations

import pytest
from examples import IPC_EXAMPLES_FULL

from benchmarks.baselines import markdown, run_all, scripts

LABELS = ("Pass", "Intersecting", "Blow-up", "Timeout", "QP failure")


def test_baselines_label_the_tutorial_and_failure_scripts(tmp_path):
    pytest.importorskip("osqp")
    if not IPC_EXAMPLES_FULL.is_dir():
        pytest.skip("../shared/ipc-examples-full is not present")
    names = {p.name for p in scripts()}
    assert {"2cubesFall.txt", "SQPMemoryIssue4.txt", "GurobiException.txt"} <= names
    rows = []
    for only in ("tutorialExamples/2cubesFall.txt", "failures/SQPMemoryIssue4"):
        rows += run_all(steps=3, budget=60, only=only, root=tmp_path, say=lambda *a: None)
    assert [(r["script"], r["method"]) for r in rows] == [
        ("tutorialExamples/2cubesFall", "SQP"), ("tutorialExamples/2cubesFall", "QP"),
        ("failures/SQPMemoryIssue4", "SQP"), ("failures/SQPMemoryIssue4", "QP")]
    for r in rows:
        assert r["label"] in LABELS, r
        assert r["label"] != "Pass" or (r["steps_done"] == 3 and r["frames_clean"]), r
    # the tutorial script names no constraint solver: it gets the SQP sections' settings
    scene = (tmp_path / "tutorialExamples_2cubesFall" / "SQP" / "scene"
             / "2cubesFall_SQP.toml").read_text()
    assert 'constraint_type = "graphics"' in scene and "active_set_convergence = true" in scene
    assert "| failures/SQPMemoryIssue4 | QP | 3 / 3 |" in markdown(rows)
