"""Golden regression tests: each scene of golden_scenes.py, run now for its few steps,
matches its reference in golden/ (sampled vertex positions of a few frames, every step's
Newton iterations and contact counts) through the same comparison as ``ipcsim compare``.
After an intended change: ``python tests/regression/regenerate.py`` (see README.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from golden_scenes import RTOL, SCENES

from ipcsim.cli import main
from ipcsim.io.compare import (CompareError, compare_runs, format_summary, golden_from_run,
                               read_golden, write_golden)

BY_NAME = {s.name: s for s in SCENES}


@pytest.fixture(scope="module")
def run_of(tmp_path_factory):
    """Each scene's run, made once per module (the failure tests reuse cube_drop's)."""
    done = {}

    def run(name):
        if name not in done:
            scene = BY_NAME[name]
            if scene.path() is None:
                pytest.skip("../shared/ipc-examples is not present")
            out = tmp_path_factory.mktemp(name) / "run"
            assert scene.run(out) == 0
            done[name] = out
        return done[name]

    return run


@pytest.mark.parametrize("name", list(BY_NAME))
def test_scene_matches_its_golden_reference(name, run_of):
    scene = BY_NAME[name]
    assert scene.golden.is_file(), (f"no reference: python tests/regression/regenerate.py "
                                    f"{name}")
    res = compare_runs(run_of(name), scene.golden, rtol=RTOL)
    assert res.same, format_summary(res)
    # the whole reference was compared: its frames and every step's counts
    golden = json.loads(scene.golden.read_text())
    assert res.steps == [f["step"] for f in golden["frames"]]
    assert len(res.log_steps) == scene.steps == golden["about"]["steps"]


def test_references_are_compact():
    for scene in SCENES:
        if scene.golden.is_file():
            assert scene.golden.stat().st_size < 8000, scene.golden.name


def test_a_moved_vertex_is_named_with_its_frame(run_of):
    out, golden = run_of("cube_drop"), BY_NAME["cube_drop"].golden
    ref = read_golden(golden)
    tol = compare_runs(out, ref, rtol=RTOL).tolerance
    last = max(ref.frames)
    moved = ref.frames[last]().copy()
    moved[7, 1] += 2 * tol
    ref.frames[last] = lambda: moved
    res = compare_runs(out, ref, rtol=RTOL)
    assert not res.same and res.first_count_diff is None
    assert res.first_frame_diff.startswith(f"frame frame_{last:06d}.vtu vs cube_drop.json "
                                           f"(step {last})")
    assert f"(vertex {int(ref.index[7])})" in res.first_frame_diff
    moved[7, 1] -= 1.5 * tol  # now half the tolerance away: the same again
    assert compare_runs(out, ref, rtol=RTOL).same


def test_a_changed_count_is_named_with_its_step(run_of):
    ref = read_golden(BY_NAME["cube_drop"].golden)
    k = int(np.argmax(ref.log["contacts_plane"] > 0))  # the landing step
    ref.log["contacts_plane"][k] += 1
    res = compare_runs(run_of("cube_drop"), ref, rtol=RTOL)
    step = int(ref.log["step"][k])
    assert not res.same and res.first_frame_diff is None
    assert res.first_difference().startswith(f"step {step}: contacts_plane")


def test_compare_command_reads_a_golden_file(run_of, tmp_path, capsys):
    """``ipcsim compare OUT golden.json``: a fresh reference of the run is exactly equal,
    one with a frame moved by 2e-5 m (1e-5 of the scene size) is different (exit 1)."""
    out = run_of("cube_drop")
    fresh = golden_from_run(out)
    write_golden(tmp_path / "fresh.json", fresh)
    assert max(compare_runs(out, tmp_path / "fresh.json").max_rel) == 0.0  # repr round trip
    assert main(["compare", str(out), str(tmp_path / "fresh.json")]) == 0
    frame = fresh["frames"][2]
    frame["positions"] = (np.asarray(frame["positions"]) + [0.0, 0.0, 2e-5]).tolist()
    write_golden(tmp_path / "moved.json", fresh)
    capsys.readouterr()
    assert main(["compare", str(out), str(tmp_path / "moved.json")]) == 1
    assert f"frame_{frame['step']:06d}.vtu vs moved.json" in capsys.readouterr().out


def test_mismatched_golden_cannot_be_compared(run_of, tmp_path):
    out = run_of("cube_drop")
    ref = read_golden(BY_NAME["cube_drop"].golden)
    ref.frames[999] = ref.frames[max(ref.frames)]
    with pytest.raises(CompareError, match="frame_000999 in the golden reference"):
        compare_runs(out, ref)
    ref = read_golden(BY_NAME["cube_drop"].golden)
    ref.mesh = {**ref.mesh, "sha256": "0" * 64}
    with pytest.raises(CompareError, match="different meshes"):
        compare_runs(out, ref)
    (tmp_path / "bad.json").write_text('{"format": "something else"}')
    with pytest.raises(CompareError, match="not a golden reference"):
        compare_runs(out, tmp_path / "bad.json")


def test_regenerate_reports_an_unchanged_scene(tmp_path, capsys):
    """The documented command, on a copy of a reference: the same run, so "same"."""
    import regenerate

    scene = BY_NAME["cube_drop"]
    (tmp_path / scene.golden.name).write_bytes(scene.golden.read_bytes())
    assert regenerate.main(["cube_drop", "--into", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "same within tolerance" in printed and "counts unchanged" in printed
    new, old = read_golden(tmp_path / scene.golden.name), read_golden(scene.golden)
    assert all(np.array_equal(new.log[c], old.log[c]) for c in old.log)
