"""benchmarks/accuracy.py in small: its rules on their own, then ``--smoke`` with
ipcsim alone, and with the original program where it runs here (its libraries
installed, or ``IPC_LIB_PATH`` naming them)."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from benchmarks import accuracy as acc
from benchmarks import vs_original as vo
from ipcsim.model.build import build_model
from ipcsim.runner import frame_interval_for
from ipcsim.scene import load_scene
from ipcsim.scene.spec import SceneSpec


@pytest.mark.parametrize("scene", acc.SCENES + acc.EXTRA + (acc.SMOKE,),
                         ids=lambda sc: sc.name)
def test_every_run_of_every_scene_has_frames_at_the_sample_times(scene):
    """ipcsim's own frame rule, with the line frame_lines adds, lands on every multiple
    of h0 at every h of the ladder and the references."""
    for h in scene.ladder() + scene.references():
        speed = [float(line.split()[1]) for line in acc.frame_lines(h, scene.h0)]
        every = frame_interval_for(SceneSpec(dt=h, playback_speed=(speed or [1.0])[0]))
        assert round(scene.h0 / h) % every == 0, (scene.name, h, every)
        # the script's time line says h to the last digit (9.765625e-05 is not 9.76562e-05)
        words = vo.shortened("", scene.duration, h).split()
        assert (float(words[1]), float(words[2])) == (scene.duration, h)
    assert scene.references()[1] < scene.references()[0] < scene.ladder()[-1]
    assert math.isclose(scene.sample_times()[-1], scene.duration)


def test_denser_frames_only_where_the_default_ones_miss():
    assert acc.frame_lines(0.025, 0.05) == acc.frame_lines(0.00625, 0.05) == ()
    (line,) = acc.frame_lines(0.003125, 0.05)  # every 3 steps would miss 0.05 s
    assert line.startswith("playBackSpeed ") and \
        math.isclose(float(line.split()[1]) * 0.03, 0.00625)
    with pytest.raises(ValueError, match="does not divide"):
        acc.frame_lines(0.003, 0.05)


def test_observed_order_and_error():
    hs = [0.1, 0.05, 0.025]
    assert acc.observed_order([(h, 3.0 * h ** 2) for h in hs]) == pytest.approx(2.0)
    assert acc.observed_order([(0.1, 1e-3)]) is None
    x = np.zeros((2, 4, 3))
    ref = x.copy()
    ref[..., 0] = 3.0  # every vertex 3 m off at every time
    assert acc.rms_error(x, ref, 2.0) == pytest.approx(1.5)
    assert acc.rms_error(None, ref, 2.0) is None


def test_the_spinning_bar_is_contact_free_and_spins(repo_root):
    model = build_model(load_scene(repo_root / "input" / "spinning_bar.txt"))
    assert not model.needs_mesh_contact and not model.needs_plane_contact
    assert not np.any(model.gravity) and np.abs(model.initial_velocities).max() > 1.0


def _rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _check_program(rows: list[dict], program: str) -> None:
    mine = [r for r in rows if r["program"] == program]
    refs = [r for r in mine if r["role"] == "reference"]
    ladder = [r for r in mine if r["role"] == "ladder"]
    own = {v.integrator for v in acc.VARIANTS if v.program == program}
    assert len(refs) == 2 and {r["integrator"] for r in ladder} == own
    assert all(r["rc"] == "0" for r in mine)
    for r in ladder:  # BE at these steps is far from its reference: a real error
        assert float(r["error"]) >= 0 and float(r["wall_s"]) > 0
    be = sorted((float(r["h"]), float(r["error"])) for r in ladder if r["integrator"] == "BE")
    assert be[0][1] < be[1][1]  # the smaller step is the more accurate


def test_smoke_with_ipcsim_alone_writes_the_tables_and_charts(tmp_path, capsys):
    out = tmp_path / "out"
    assert acc.main(["--smoke", "--no-original", "--work", str(tmp_path / "w"),
                     "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "the original is not run: --no-original" in printed
    assert "ipcsim's references h = 0.0125 and 0.00625 s differ by" in printed
    assert "### Time to accuracy" in printed and "Machine: " in printed
    _check_program(_rows(out / "accuracy.csv"), "ipcsim")
    names = {p.name for p in out.iterdir()}
    assert {"accuracy.csv", "accuracy_table.md", "accuracy_two_cubes_smoke.png",
            "accuracy_energy_two_cubes_smoke.png"} <= names


def test_smoke_with_both_programs(tmp_path, capsys):
    assert acc.main(["--smoke", "--work", str(tmp_path / "w"), "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    if "the original is not run:" in printed:
        pytest.skip(next(ln for ln in printed.splitlines() if "the original is not run" in ln))
    rows = _rows(tmp_path / "accuracy.csv")
    for program in ("original", "ipcsim"):
        _check_program(rows, program)
    assert "original's references h = 0.0125 and 0.00625 s differ by" in printed


def test_tolerances_add_adaptive_runs_judged_against_three_tau(tmp_path):
    assert acc.parse_args(["--tolerances", "1e-2,1e-3"]).tolerances == (1e-2, 1e-3)
    for bad in ("1e-2,x", "0", "2"):
        with pytest.raises(SystemExit):
            acc.parse_args(["--tolerances", bad])
    tau = acc.Variant("ipcsim", "BDF2", 1e-3)
    assert tau.lines() == ("timeIntegration BDF2", "timeTolerance 0.001")
    (tmp_path / "scripts").mkdir()
    runs = acc.plan(acc.SMOKE, "", [acc.Variant("ipcsim", "BE"), tau], tmp_path, tmp_path)
    adaptive = [m for m in runs if m.variant == tau]
    assert [m.h for m in adaptive] == [acc.SMOKE.default_h]  # once, from the scene's h
    # the smoke scene has contact: the adaptive runs get references of their own model
    refs = [(m.variant.integrator, m.variant.tolerance, m.h) for m in runs
            if m.role == "reference"]
    assert refs == [("BDF2", None, h) for h in acc.SMOKE.references()] + [
        ("BDF2", pytest.approx(1e-3 / 30), 0.025), ("BDF2", pytest.approx(1e-3 / 300), 0.025)]

    def judged(error, resolved):
        m = acc.Measured("s", tau, 0.025, "ladder", tmp_path, tmp_path,
                         runs=[vo.Run(rc=0, wall_s=1.0, peak_mb=None)],
                         error=error, resolved=resolved)
        (line,) = acc.tolerance_lines([m])
        return line
    assert judged(2.9e-3, True).endswith("(≤ 3 τ: met)")
    assert judged(3.1e-3, True).endswith("(≤ 3 τ: NOT met)")
    assert "unresolved" in judged(1e-3, False)


def test_references_by_newmark_only_without_contact():
    by_name = {sc.name: sc for sc in acc.SCENES}
    assert by_name["spinning_bar"].reference_integrator("ipcsim") == "NM"
    assert by_name["two_cubes"].reference_integrator("ipcsim") == "BDF2"
    assert all(sc.reference_integrator("original") == "NM" for sc in acc.SCENES)
    assert [sc.name for sc in acc.SCENES if sc.contact_free] == ["spinning_bar"]


def test_each_model_is_scored_against_its_own_references(tmp_path, monkeypatch):
    """Fixed steps against the fixed-step references, adaptive runs of a contact scene
    against the adaptive ones; without contact one model, the fixed-step references."""
    be, tau = acc.Variant("ipcsim", "BE"), acc.Variant("ipcsim", "BDF2", 1e-2)
    ok = [vo.Run(rc=0, wall_s=1.0, peak_mb=None)]

    def run(variant, role, offset):
        m = acc.Measured("s", variant, 0.025, role, tmp_path / f"{offset}", tmp_path,
                         runs=list(ok))
        return m
    where = {}  # every vertex of a run sits at its offset along x
    monkeypatch.setattr(acc, "trajectory", lambda m, times: np.full((len(times), 2, 3),
                                                                    where[m.folder.name]))
    fixed_refs = [run(acc.Variant("ipcsim", "BDF2"), "reference", o) for o in (0.01, 0.0)]
    adaptive_refs = [run(acc.Variant("ipcsim", "BDF2", t), "reference", o)
                     for t, o in ((1e-3, 5.001), (1e-4, 5.0))]
    ladder = [run(be, "ladder", 1.0), run(tau, "ladder", 5.2)]
    for m in fixed_refs + adaptive_refs + ladder:
        where[m.folder.name] = float(m.folder.name)
    checks = acc.score(acc.SMOKE, fixed_refs + adaptive_refs + ladder, math.sqrt(3.0))
    assert ladder[0].error == pytest.approx(1.0) and ladder[1].error == pytest.approx(0.2)
    assert ladder[1].reference_difference == pytest.approx(0.001)
    assert [c.references for c in checks] == [
        "ipcsim's references h = 0.025 and 0.025 s",
        "ipcsim's adaptive references τ = 0.001 and 0.0001"]
    adaptive_refs[1].runs = [vo.Run(rc=3, wall_s=1.0, peak_mb=None)]  # a reference failed
    assert acc._references_named(adaptive_refs).endswith(
        "(failed: ipcsim BDF2 τ=0.0001 h = 0.025: exit 3)")
    spinning = next(sc for sc in acc.SCENES if sc.contact_free)
    assert acc.model_of(spinning, tau) == acc.model_of(spinning, be) == "ipcsim"
    assert [v for v, _ in acc.references(spinning, [be, tau])] == [
        acc.Variant("ipcsim", "NM")] * 2


def test_energy_of_an_adaptive_run_is_read_at_its_frames(tmp_path):
    """An adaptive run logs every attempt, rejected ones too; its energy series is the
    accepted steps' at the frames' times. In free fall (the smoke scene before its
    landing) adaptive BDF2 keeps its energy within 1e-5."""
    scene = acc.Scene("falling", "the smoke scene's cubes in free fall", 0.1, 0.05, 1,
                      0.025, acc.SMOKE.make)
    (tmp_path / "scripts").mkdir()
    tau = acc.Variant("ipcsim", "BDF2", 1e-3)
    (m,) = [r for r in acc.plan(scene, scene.make(tmp_path), [tau], tmp_path, tmp_path)
            if r.role == "ladder"]
    acc.execute(m, tmp_path, vo.Settings(work=tmp_path), keep=False)
    assert m.ok, m.last
    assert "0" in {r["accepted"] for r in _rows(m.folder / "steps.csv")}  # a retried step
    times, energy = acc.energy_series(m, tmp_path)
    assert times == pytest.approx(0.025 * np.arange(1, 5))
    assert energy == pytest.approx(energy[0], rel=1e-5)
