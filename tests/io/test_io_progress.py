"""What `ipcsim run` prints while it works: periodic lines off a terminal, a live bar on
one, per-iteration lines with -v, nothing with -q."""

from __future__ import annotations

import io
import re

import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.io.progress import RunProgress


@pytest.fixture
def drop_scene(tmp_path):
    write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1))
    scene = tmp_path / "drop.txt"
    scene.write_text("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1\n"
                     "selfCollisionOff\nground 0 0\ntime 1 0.01\n")
    return scene


def test_plain_lines_every_five_percent_when_not_a_terminal(drop_scene, tmp_path, capsys):
    assert main(["run", str(drop_scene), "-o", str(tmp_path / "a")]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("step ")]
    steps = [int(re.match(r"step (\d+)/100", ln).group(1)) for ln in lines]
    assert steps[-1] == 100 and 20 <= len(steps) <= 21  # 5 %: every 5 steps, and the last
    assert all("newton=" in ln and "contacts=" in ln and "ETA=" in ln for ln in lines)


def test_quiet_prints_nothing_and_verbose_prints_iterations(drop_scene, tmp_path, capsys):
    assert main(["run", str(drop_scene), "-o", str(tmp_path / "q"), "-q", "--steps", "3"]) == 0
    assert capsys.readouterr().out == ""
    assert main(["run", str(drop_scene), "-o", str(tmp_path / "v"), "-v", "--steps", "3"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"step 1 it 0: alpha=\S+ \|p\|=\S+ tol=\S+ contacts=0", out)
    assert "step 3 it " in out


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_bar_on_a_terminal_shows_step_time_iterations_contacts_and_eta():
    term = _Terminal()
    assert RunProgress.mode_for(False, term) == "bar"
    assert RunProgress.mode_for(True, term) == "off"
    assert RunProgress.mode_for(False, io.StringIO()) == "lines"
    bar = RunProgress(0, 10, "bar", term)
    for k in range(1, 6):
        bar.update(k, 0.01 * k, 7, 42)
    bar.close()
    text = term.getvalue()
    assert "step 5/10" in text and "t=0.05s" in text
    assert "newton=7" in text and "contacts=42" in text and "ETA" in text


def test_the_time_left_leaves_out_compiling(monkeypatch):
    """A first run compiles kernels during its first steps: the estimate of the time left
    counts only the time spent stepping."""
    import io

    from ipcsim.io import progress as pr

    clock = [100.0]
    monkeypatch.setattr(pr.time, "perf_counter", lambda: clock[0])
    compiled = [0.0]
    p = pr.RunProgress(0, 100, "lines", stream=io.StringIO(), compiled=lambda: compiled[0])
    clock[0] += 40.0  # 10 steps in 40 s, 38 of them compiling
    compiled[0] = 38.0
    assert p.eta(10) == pytest.approx(2.0 / 10 * 90)
    compiled[0] = 0.0
    assert p.eta(10) == pytest.approx(40.0 / 10 * 90)


def test_a_compiling_run_says_so_once(capsys):
    from ipcsim.compiler import compiling
    from ipcsim.compiler.jit import numba_module

    said = []
    compiling.when_compiling_starts(lambda: said.append(1))
    njit = numba_module().njit  # numba as ipcsim loads it: with the compile clock listening

    @njit  # not cached: always compiles
    def twice(x):
        return 2 * x

    assert twice(3) == 6 and twice(2.5) == 5.0
    assert said == [1] and compiling.compile_seconds() > 0.0


def test_the_time_left_follows_the_simulated_time(monkeypatch):
    """Adaptive steps: 10 of 100 steps done but 0.5 of 1 s simulated in 40 s leaves
    40 s, not 360."""
    import io

    from ipcsim.io import progress as pr

    clock = [100.0]
    monkeypatch.setattr(pr.time, "perf_counter", lambda: clock[0])
    p = pr.RunProgress(0, 100, "off", stream=io.StringIO(), first_time=0.0, end_time=1.0)
    clock[0] += 40.0
    p.update(10, 0.5, 3, 0)
    assert p.eta(10) == pytest.approx(40.0)
