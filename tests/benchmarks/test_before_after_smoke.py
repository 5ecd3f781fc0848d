"""benchmarks/before_after.py on one small scene, the same build as before and after."""

from __future__ import annotations

import csv
import shutil
import sys
from pathlib import Path

import pytest

from benchmarks import before_after

IPCSIM = shutil.which("ipcsim", path=str(Path(sys.executable).parent)) or shutil.which("ipcsim")


@pytest.mark.skipif(IPCSIM is None, reason="no ipcsim console script installed")
def test_one_scene_before_and_after(repo_root, tmp_path, capsys):
    scene = repo_root / "input" / "cube_drop.toml"
    assert before_after.main([str(scene), "--before", IPCSIM, "--after", IPCSIM,
                              "--repeats", "2", "--steps", "3", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| cube_drop |" in out and "2 repeats, 1 thread(s)" in out
    with open(tmp_path / "before_after.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["build"] for r in rows] == ["before", "after"]
    for r in rows:
        assert r["runs"] == "2" and float(r["wall_s"]) > float(r["steps_s"]) > 0
        assert float(r["wall_min_s"]) <= float(r["wall_s"]) <= float(r["wall_max_s"])
        assert float(r["newton_iterations"]) >= 3  # three steps, one iteration at least each
        assert 0 < float(r["cpu_s"]) and float(r["paired_wall_ratio"]) > 0
    assert float(rows[0]["paired_wall_ratio"]) == 1.0  # before against itself


def test_a_missing_scene_is_refused(tmp_path, capsys):
    assert before_after.main([str(tmp_path / "none.txt"), "--before", "ipcsim"]) == 2
    assert "no such scene" in capsys.readouterr().err
