"""The tutorial's half of the benchmark against the lecture's simulator, in small: a few
steps of lesson 3 in the tutorial's own code (skipped where ../shared/solid-sim-tutorial
is absent), and the reading of a lesson's set-up (always)."""

from __future__ import annotations

import csv
import sys

import numpy as np
import pytest

from benchmarks import vs_tutorial as vt


def _needs_tutorial():
    if not (vt.TUTORIAL / "3_contact" / "simulator.py").is_file():
        pytest.skip("../shared/solid-sim-tutorial is not present")


def test_lesson_3_falls_freely_at_first_and_its_rows_are_written(tmp_path):
    _needs_tutorial()
    run = vt.run_tutorial_lesson("3_contact", steps=3)
    assert run.h == 0.01 and run.wall_s.shape == (3,) and run.com.shape == (4, 2)
    assert np.all(run.wall_s > 0.0)
    # the square starts centred at the origin, at rest, its springs at their rest
    # lengths: backward Euler's first steps are a free fall, y_k = −g h² k(k+1)/2
    g, h = 9.81, run.h
    expected = -g * h * h * np.array([0, 1, 3, 6])
    np.testing.assert_allclose(run.com[:, 1], expected, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(run.com[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(run.kinetic[1:], 0.5 * 1000.0 * (g * h * np.arange(1, 4)) ** 2,
                               rtol=1e-6)
    assert np.all(run.barrier == 0.0)  # 0.5 m above the ground
    # backward Euler loses energy, it never gains any
    assert np.all(np.diff(run.total) <= 1e-9 * np.abs(run.total[0]))
    path = vt.write_csv(run, tmp_path)
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert [int(r["step"]) for r in rows] == [0, 1, 2, 3]
    assert rows[0]["wall_s"] == "" and float(rows[3]["com_y"]) == run.com[3, 1]
    assert float(rows[2]["total"]) == pytest.approx(run.total[2], rel=1e-15)


def test_a_lesson_leaves_no_module_of_the_tutorial_behind():
    _needs_tutorial()
    vt.run_tutorial_lesson("7_self_contact", steps=1)
    left = [name for name, m in sys.modules.items()
            if str(vt.TUTORIAL) in (getattr(m, "__file__", None) or "")]
    assert left == []
    assert all(str(vt.TUTORIAL) not in p for p in sys.path)


def test_the_set_up_is_the_simulators_lines_before_its_drawing_loop(tmp_path):
    simulator = tmp_path / "simulator.py"
    simulator.write_text(
        "import numpy as np\nimport pygame\npygame.init()\nh = 0.01\n"
        "# simulation with visualization\nwhile running:\n"
        "    [x, v] = time_integrator.step_forward(x, e, v, h, 1e-2)\n")
    setup, step = vt.setup_source(simulator)
    assert setup == "import numpy as np\nh = 0.01"
    assert step == "[x, v] = time_integrator.step_forward(x, e, v, h, 1e-2)"
    simulator.write_text("h = 0.01\n")
    with pytest.raises(ValueError, match="no '# simulation with visualization' line"):
        vt.setup_source(simulator)


def test_without_the_tutorial_the_benchmark_says_so_and_exits_0(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(vt, "TUTORIAL", tmp_path / "absent")
    assert vt.main(["--steps", "1", "--out", str(tmp_path / "out")]) == 0
    assert "is not there" in capsys.readouterr().out
    assert not (tmp_path / "out").exists()
    with pytest.raises(vt.TutorialMissing, match="no simulator.py"):
        vt.lesson_folder("3_contact", tmp_path / "absent")


def test_ipcsim_follows_the_tutorial_on_lesson_3_and_draws_the_chart(tmp_path):
    _needs_tutorial()
    tutorial = vt.run_tutorial_lesson("3_contact", steps=60)  # the fall and the landing
    ours = vt.run_ipcsim_lesson("3_contact", steps=60)
    assert ours.com.shape == tutorial.com.shape and np.all(ours.wall_s > 0.0)
    c = vt.compare(tutorial, ours)
    assert c.com_error < 1e-3 and c.ipcsim_step_s < c.tutorial_step_s
    path = vt.chart([(tutorial, ours)], tmp_path / "chart.png")
    assert path.stat().st_size > 0


def test_ipcsim_side_runs_without_the_tutorial():
    ours = vt.run_ipcsim_lesson("7_self_contact", steps=5)
    # the two squares fall freely at first: the centre of mass drops as y_k − y_0 =
    # −g h² k(k+1)/2 under backward Euler
    drop = ours.com[:, 1] - ours.com[0, 1]
    np.testing.assert_allclose(drop, -9.81 * 1e-4 * np.array([0, 1, 3, 6, 10, 15]),
                               rtol=1e-9, atol=1e-12)
