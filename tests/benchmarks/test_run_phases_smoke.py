"""benchmarks/run_phases.py on a few steps of a small scene."""

from __future__ import annotations

import csv
import sys

import pytest

from benchmarks import run_phases

TOP = ("interpreter start and exit", "imports", "main")
UNDER_MAIN = ("build", "output", "step loop", "run.json")
UNDER_LOOP = ("steps", "frames", "logs", "checkpoints")
UNDER_STEPS = ("the step's problem", "final evaluation", "rest (Python)")


def test_every_phase_of_a_run_is_timed_and_they_add_up(repo_root, tmp_path, capsys):
    scene = repo_root / "input" / "cube_drop.toml"
    assert run_phases.main([str(scene), "--python", sys.executable, "--repeats", "1",
                            "--steps", "3", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "cube_drop.toml: medians of 1 runs" in out and "| whole process |" in out
    with open(tmp_path / "run_phases.csv", newline="") as f:
        rows = [(r["phase"], int(r["depth"]), float(r["seconds"])) for r in csv.DictReader(f)]
    names = [name for name, _, _ in rows]
    for name in TOP + UNDER_MAIN + UNDER_LOOP + UNDER_STEPS:
        assert name in names, name  # a function renamed in ipcsim shows here
    # the records are Structs: no dataclass is made while a run starts (30–50 ms they took)
    assert "of which making the dataclasses" not in names
    by_depth = {}
    for name, depth, seconds in rows:
        assert seconds >= -1e-3, (name, seconds)  # each "rest" is what its phase has left
        by_depth.setdefault(depth, {})[name] = seconds
    whole = by_depth[0]["whole process"]
    assert sum(by_depth[1][n] for n in TOP) == pytest.approx(whole, abs=1e-3)
    main = by_depth[1]["main"]
    assert all(0.0 < by_depth[2][n] < main for n in UNDER_MAIN)
    # the collector's passes fall inside the phases, not beside them
    assert 0.0 <= by_depth[1]["cycle collector (inside the phases above)"] < whole


def test_a_missing_scene_is_refused(tmp_path, capsys):
    assert run_phases.main([str(tmp_path / "none.txt")]) == 2
    assert "no such scene" in capsys.readouterr().err
