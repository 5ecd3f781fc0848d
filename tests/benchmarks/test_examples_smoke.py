"""Smoke run of the example sweep (benchmarks/examples.py): one tutorial script, a few
steps, ipcsim only; its row, the frame check and the table."""

from __future__ import annotations

import pytest

from benchmarks import examples as ex


@pytest.mark.skipif(not ex.FULL_INPUT.is_dir(), reason="../shared/ipc-examples-full is absent")
def test_one_script_runs_checks_and_lands_in_the_table(tmp_path, capsys):
    assert ex.main(["--only", "tutorialExamples/2cubesFall.txt", "--steps", "3",
                    "--no-original", "--out", str(tmp_path / "out"),
                    "--work", str(tmp_path / "work")]) == 0
    table = (tmp_path / "out" / "examples_table.md").read_text()
    row = next(ln for ln in table.splitlines() if ln.startswith("| tutorialExamples/2cubesFall"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1:4] == ["16", "12", "3"] and cells[6] == "yes" and cells[-1] == "ok"
    assert "1 scripts: 1 ran (1 with every frame clean)" in table


def test_the_step_budget_and_a_missing_mesh(tmp_path):
    assert ex.steps_for(ex.FULL_INPUT / "paperExamples/1_squeezeOut.txt", 5) == 2
    assert ex.steps_for(ex.FULL_INPUT / "tutorialExamples/2cubesFall.txt", 5) == 5
    script = tmp_path / "lost.txt"
    script.write_text("shapes input 1\nnowhere/cube.msh 0 0 0  0 0 0  1 1 1\n")
    row = ex.Row("lost.txt")
    assert ex._read_scene(script, row) is None and row.status == "no meshes"
