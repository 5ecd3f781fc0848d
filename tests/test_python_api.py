"""The Python API: the worked example of docs/python-api.md runs as written, and the
names it documents are the package's ``__all__``."""

from __future__ import annotations

import re
import shutil

import pytest

import ipcsim

DOC = "docs/python-api.md"


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_the_worked_example_runs(repo_root, tmp_path, monkeypatch, capsys):
    blocks = _python_blocks((repo_root / DOC).read_text())
    assert len(blocks) == 1
    shutil.copytree(repo_root / "input", tmp_path / "input")
    monkeypatch.chdir(tmp_path)
    exec(compile(blocks[0], DOC, "exec"), {"__name__": "python_api_example"})
    printed = capsys.readouterr().out
    assert "vertices" in printed and "Newton iterations" in printed
    assert (tmp_path / "output" / "cube_drop_api" / "steps.csv").is_file()


def test_every_exported_name_is_documented(repo_root):
    doc = (repo_root / DOC).read_text()
    names = [n for n in ipcsim.__all__ if n != "__version__"]
    assert names and [n for n in names if f"`{n}" not in doc] == []
    for name in names:  # and each resolves
        assert getattr(ipcsim, name) is not None


def test_state_views_are_read_only_but_the_arrays_are_not(repo_root):
    spec = ipcsim.load_scene(repo_root / "input" / "cube_drop.toml",
                             {"time.duration": 0.05})
    sim = ipcsim.Simulation(ipcsim.build_model(spec))
    before = sim.state
    sim.step()
    assert sim.state is not before and sim.state.step == 1
    assert sim.state.time == pytest.approx(spec.dt)
    with pytest.raises(ValueError):
        sim.state.positions[0, 0] = 1.0
    assert sim.state.x.flags.writeable  # numba compiles one specialisation only
