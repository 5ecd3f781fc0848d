"""The benchmark against the original IPC program, in small.

Always: the shortening of scripts (and that ipcsim reads the shortened scripts of the
default list as the table says), and the ipcsim half with the table, CSV and chart
written for two steps of the hello world. With the original program able to run here
(its libraries installed, or ``IPC_LIB_PATH`` naming them): 20 steps of 2cubesFall
through both programs."""

from __future__ import annotations

import csv
import dataclasses
import os
from pathlib import Path

import pytest
from examples import IPC_EXAMPLES, IPC_EXAMPLES_FULL

from benchmarks import vs_original as vs
from ipcsim.scene import load_scene


def test_an_installed_ipcsim_runs_without_the_callers_python_path(monkeypatch):
    # a checkout on PYTHONPATH would make two installs under comparison run its sources
    monkeypatch.setenv("PYTHONPATH", "/some/checkout")
    assert "PYTHONPATH" not in vs.ipcsim_env(1)
    assert vs.ipcsim_env(2, own_install=False)["PYTHONPATH"] == "/some/checkout"
    assert vs.ipcsim_env(2)["IPCSIM_THREADS"] == "2"


def test_the_time_line_is_added_at_the_end_after_a_last_line_without_newline():
    text = vs.shortened("time 5 0.025\nselfFric 0.1\ntol 1\n1e-4", 0.5, 0.025)
    lines = text.splitlines()
    assert lines[-2:] == ["1e-4", "time 0.5 0.025  # added by benchmarks.vs_original"]
    assert text.endswith("\n")


def test_the_time_line_goes_before_the_first_section():
    text = "time 6 0.04\nshapes input 1\nm.msh 0 0 0\nsection QP\ntime 10 5e-3\nsection\n"
    lines = vs.shortened(text, 0.08, 0.04).splitlines()
    k = lines.index("section QP")
    assert lines[k - 1].startswith("time 0.08 0.04 ")
    assert lines[k:] == ["section QP", "time 10 5e-3", "section"]


def _staged_defaults(tmp_path):
    stage = vs.stage_input(tmp_path)
    return [vs.stage_scene(sc, path, stage) for sc, path in vs.expand()]


def test_the_default_list_has_every_tutorial_and_ipcsim_reads_each_shortening(tmp_path):
    if not IPC_EXAMPLES.is_dir():
        pytest.skip("../shared/ipc-examples is not present")
    tutorials = sorted(IPC_EXAMPLES.joinpath("input", "tutorialExamples").rglob("*.txt"))
    staged = _staged_defaults(tmp_path)
    assert {st.source for st in staged} >= set(tutorials)
    assert len({st.name for st in staged}) == len(staged) == len(vs.expand())
    assert len({st.script for st in staged}) == len(staged)  # no two share a copy
    for st in staged:
        spec, as_written = load_scene(st.script), load_scene(st.source)
        if st.scene.shorten is None:
            assert (spec.duration, spec.dt) == (as_written.duration, as_written.dt), st.name
            continue
        duration, dt = st.scene.shorten
        assert spec.dt == as_written.dt == dt, st.name  # shortened, never a new step size
        assert spec.duration == duration and spec.duration < as_written.duration, st.name
        assert spec.n_steps == round(duration / dt), st.name


def test_ipcsim_half_and_the_written_table(tmp_path):
    stage = vs.stage_input(tmp_path)
    st = vs.stage_scene(vs.SMOKE_REPO, vs.REPO_ROOT / vs.SMOKE_REPO.script, stage)
    s = vs.Settings(tmp_path, say=lambda *a: None)
    run = vs.run_ipcsim(st.script, tmp_path / "runs" / "ipcsim", stage, s)
    assert run.rc == 0 and run.steps == 2 and run.vertices == 432
    assert run.newton_per_step >= 1 and run.steps_wall_s > 0 and run.peak_mb > 10
    assert 0 < run.cpu_s  # user + system time of the process
    st.runs["ipcsim"].append(run)
    row = vs.summarise(st, {})
    info = vs.machine() | {"load_after": vs._load(), "output_fs": "tmpfs"}
    paths = vs.write_outputs([row], info, s, tmp_path / "docs")
    assert [p.name for p in paths] == ["vs_original.csv", "vs_original_table.md",
                                       "vs_original.png"]
    assert all(p.stat().st_size > 0 for p in paths)
    table = paths[1].read_text()
    assert "Machine: " in table and "load average" in table
    assert "outputs written to tmpfs" in table
    cells = [c.strip() for c in table.splitlines()[-1].strip("|").split("|")]
    assert cells[:3] == ["hello world, 0.05 s", "432", "2"]
    assert cells[3] == "–" and cells[5] == cells[6] == "–" and cells[-1] == "not compared"
    assert cells[7] == f"– / {vs._sec(run.cpu_s)}"  # CPU s, original / ipcsim
    with open(paths[0], newline="") as f:
        (written,) = list(csv.DictReader(f))
    assert written["ipcsim_steps"] == "2" and written["original_wall_s"] == ""
    assert written["output_fs"] == "tmpfs"


@pytest.mark.skipif(not os.path.isfile("/proc/mounts"), reason="no /proc/mounts here")
def test_the_file_system_of_the_outputs(tmp_path):
    """The type /proc/mounts gives the longest mount point holding the folder: the root's
    for the root, and the same for a folder inside another one."""
    mounts = [ln.split() for ln in open("/proc/mounts").read().splitlines()]
    root_type = next(f[2] for f in reversed(mounts) if f[1] == "/")
    assert vs.file_system(Path("/")) == root_type
    assert vs.file_system(tmp_path / "not there yet") == vs.file_system(tmp_path) != ""
    if any(f[1] == "/proc" for f in mounts):
        assert vs.file_system(Path("/proc/self")) == "proc"


def test_both_programs_on_a_tiny_scene(tmp_path, capsys):
    if not IPC_EXAMPLES.is_dir():
        pytest.skip("../shared/ipc-examples is not present")
    assert vs.main(["--smoke", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    if "vs_original: skipped:" in printed:
        pytest.skip(printed.strip().splitlines()[-1])
    with open(tmp_path / "vs_original.csv", newline="") as f:
        (row,) = list(csv.DictReader(f))
    assert row["original_rc"] == row["ipcsim_rc"] == "0"
    assert row["original_steps"] == row["ipcsim_steps"] == "20"  # the same steps
    assert row["original_vertices"] == row["ipcsim_vertices"] == "16"
    for program in ("original", "ipcsim"):
        assert float(row[f"{program}_newton_per_step"]) >= 1
        assert float(row[f"{program}_wall_s"]) >= float(row[f"{program}_steps_wall_s"]) > 0
        assert float(row[f"{program}_peak_mb"]) > 1
        assert float(row[f"{program}_cpu_s"]) > 0
    assert float(row["cpu_time_ratio"]) == pytest.approx(
        float(row["ipcsim_cpu_s"]) / float(row["original_cpu_s"]))
    assert float(row["paired_ratio"]) == pytest.approx(  # one repeat: the ratio itself
        float(row["ipcsim_wall_s"]) / float(row["original_wall_s"]))
    assert row["ipcsim_faster_repeats"] in ("0", "1")
    assert row["compare_verdict"] in ("same", "different")
    assert float(row["compare_max_rel"]) >= 0


def test_the_original_run_directly_is_the_run_of_run_ipc_sh(tmp_path):
    if not IPC_EXAMPLES.is_dir():
        pytest.skip("../shared/ipc-examples is not present")
    stage = vs.stage_input(tmp_path)
    s = vs.Settings(tmp_path, lib_path=os.environ.get("IPC_LIB_PATH", ""))
    why = vs.can_run_original(stage, s)
    if why:
        pytest.skip(why)
    (scene, path), = vs.expand((vs.SMOKE,))
    st = vs.stage_scene(scene, path, stage)
    direct = vs.run_original(st.script, tmp_path / "direct" / "original", stage, s)
    script = vs.run_original(st.script, tmp_path / "script" / "original", stage,
                             dataclasses.replace(s, via_script=True))
    assert direct.rc == script.rc == 0
    assert (direct.steps, direct.newton_per_step) == (script.steps, script.newton_per_step)
    for name in ("20.obj", "status20"):
        assert (tmp_path / "direct" / "original" / name).read_bytes() == \
            (tmp_path / "script" / "original" / name).read_bytes()


def test_without_the_original_it_says_so_and_exits_0(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(vs, "ORIGINAL", tmp_path / "no-such-program")
    assert vs.main(["--smoke", "--work", str(tmp_path / "work")]) == 0
    assert "vs_original: skipped: the original program is not installed" in \
        capsys.readouterr().out


def test_shortening_reaches_the_time_line_of_an_sqp_section(tmp_path):
    """With ``constraintSolver SQP`` the ``time`` line of a ``section SQP ... section end``
    block is the one read: the shortened script must say the shortened time there too."""
    if not IPC_EXAMPLES_FULL.is_dir():
        pytest.skip("../shared/ipc-examples-full is not present")
    source = IPC_EXAMPLES_FULL / "input" / "failures" / "GurobiException.txt"
    as_written = load_scene(source)
    short = tmp_path / "input" / "failures" / "short.txt"
    short.parent.mkdir(parents=True)
    for folder in ("tetMeshes", "triMeshes"):
        (tmp_path / "input" / folder).symlink_to(source.parents[1] / folder)
    short.write_text(vs.shortened(source.read_text(), 5 * as_written.dt, as_written.dt))
    spec = load_scene(short)
    assert spec.dt == as_written.dt and spec.n_steps == 5 < as_written.n_steps


def test_a_failed_run_has_no_ratio(tmp_path):
    """The original exits 1 at once on a script whose meshes its build cannot find: the
    row keeps both times and exit statuses but no ratio of them."""
    scene = vs.SMOKE_REPO  # a script of this repository: there with or without examples
    staged = vs.Staged(scene, vs.REPO_ROOT / scene.script, tmp_path / "a.txt", "a")
    staged.runs["ipcsim"].append(vs.Run(0, 0.6, 50.0, cpu_s=0.5, steps_wall_s=0.4))
    staged.runs["original"].append(vs.Run(1, 0.004, 11.0, cpu_s=0.003))
    row = vs.summarise(staged, {})
    assert row["original_rc"] == 1 and row["ipcsim_wall_s"] == 0.6
    assert row["ratio"] is None and row["steps_ratio"] is None
    assert row["cpu_time_ratio"] is None and row["ipcsim_cpu_s"] == 0.5
    assert "paired_ratio" not in row and "–" in vs.markdown([row])
    staged.runs["original"][0] = vs.Run(0, 0.3, 11.0, cpu_s=0.25, steps_wall_s=0.29)
    row = vs.summarise(staged, {})
    assert row["ratio"] == 0.6 / 0.3 and row["steps_ratio"] == 0.4 / 0.29
    assert row["cpu_time_ratio"] == 0.5 / 0.25


def test_the_ratio_repeat_by_repeat(tmp_path):
    """Each repeat's two runs give one ratio: their median and range, and how many
    repeats ipcsim won. Here the medians' ratio (0.5 / 0.5 = 1) hides that ipcsim was
    the faster in two of three repeats, each run beside the original's of its repeat."""
    scene = vs.SMOKE_REPO
    staged = vs.Staged(scene, vs.REPO_ROOT / scene.script, tmp_path / "a.txt", "a")
    for original, ipcsim in ((0.4, 0.3), (0.5, 0.5), (0.8, 0.6)):
        staged.runs["original"].append(vs.Run(0, original, 11.0))
        staged.runs["ipcsim"].append(vs.Run(0, ipcsim, 40.0))
    row = vs.summarise(staged, {})
    assert row["ratio"] == 1.0
    assert row["paired_ratio"] == row["paired_ratio_min"] == pytest.approx(0.75)
    assert row["paired_ratio_max"] == 1.0 and row["ipcsim_faster_repeats"] == 2
    table = vs.markdown([row])
    assert "| 1.00 | 0.75 (0.75–1.00), 2 of 3 |" in table
    assert table.splitlines()[0].count("|") == table.splitlines()[2].count("|")
