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


def _tiny(repo_root):
    return ipcsim.load_scene(repo_root / "input" / "cube_drop.toml", {"time.duration": 0.05})


BAD_ARGUMENTS = [  # (keyword arguments of ipcsim.run, fragment of the message)
    ({"steps": -1}, "steps: must be at least 1, got -1"),
    ({"steps": 0}, "steps: must be at least 1, got 0"),
    ({"steps": 1.5}, "steps: expected a whole number, got 1.5"),
    ({"steps": True}, "steps: expected a whole number, got True"),
    ({"steps": "two"}, "steps: expected a whole number, got 'two'"),
    ({"mode": "append"}, "mode must be one of"),
    ({"render": "yes"}, "render must be True or False"),
    ({"reporter": print}, "reporter must be an ipcsim.Reporter"),
    ({"out_dir": 3}, "out_dir must be a folder path"),
]


@pytest.mark.parametrize("kwargs, says", BAD_ARGUMENTS, ids=[str(k) for k, _ in BAD_ARGUMENTS])
def test_run_checks_its_arguments_before_writing_anything(repo_root, tmp_path, kwargs, says):
    """The API refuses what the command line refuses, with its words, before anything is
    written; the error is an IpcsimError (exit status 2) and a ValueError."""
    out = tmp_path / "out"
    arguments = {"out_dir": out, **kwargs}
    with pytest.raises(ValueError) as err:
        ipcsim.run(_tiny(repo_root), **arguments)
    assert isinstance(err.value, ipcsim.IpcsimError) and err.value.exit_status == 2
    assert says in str(err.value)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_run_takes_steps_as_the_command_line_does(repo_root, tmp_path):
    result = ipcsim.run(_tiny(repo_root), tmp_path / "out", steps="2")
    assert result.steps_done == result.steps_planned == 2


def test_the_command_line_says_the_same_about_steps(tmp_path, capsys):
    from ipcsim.cli import main

    assert main(["run", "scene.toml", "--steps", "-1"]) == 2
    assert "must be at least 1, got -1" in capsys.readouterr().err
    assert main(["run", "scene.toml", "--steps", "1.5"]) == 2
    assert "expected a whole number, got '1.5'" in capsys.readouterr().err


def test_run_refuses_what_is_no_scene(tmp_path):
    with pytest.raises(ValueError, match="spec must be a SceneSpec"):
        ipcsim.run("input/cube_drop.toml", tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("call, says", [
    (lambda root: ipcsim.load_scene(root / "input" / "cube_drop.toml", [("time.dt", 0.01)]),
     "overrides must be a mapping"),
    (lambda root: ipcsim.load_scene(root / "input" / "cube_drop.toml", "time.dt=0.01"),
     "overrides must be a mapping"),
    (lambda root: ipcsim.build_model(str(root / "input" / "cube_drop.toml")),
     "build_model takes a SceneSpec"),
    (lambda root: ipcsim.run(_tiny(root), root / "unused",
                             reporter=ipcsim.Reporter(progress="fancy")),
     "reporter.progress must be one of bar, lines, off"),
])
def test_the_api_names_an_argument_of_the_wrong_kind(repo_root, call, says):
    """These were AttributeError tracebacks (overrides, build_model) or silently taken
    (a progress mode that shows nothing)."""
    with pytest.raises(ipcsim.ArgumentError, match=says):
        call(repo_root)
    assert not (repo_root / "unused").exists()
