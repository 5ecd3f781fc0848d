"""Smoke run of benchmarks/busy_machine.py: the three situations on a few steps of a tiny
scene, each timed and set against the quiet run."""

from __future__ import annotations

import pytest

from benchmarks import busy_machine as bm
from benchmarks import vs_original as vs


@pytest.mark.skipif(not vs.EXAMPLES_INPUT.is_dir(), reason="../shared/ipc-examples is absent")
def test_three_situations_are_timed(tmp_path):
    stage = vs.stage_input(tmp_path)
    rows = bm.measure(stage / "input" / bm.DEFAULT_SCENE, 3, 1, "", say=lambda *a: None)
    assert [r["situation"] for r in rows] == list(bm.SITUATIONS)
    assert [r["runs"] for r in rows] == [1, 1, 2]
    assert rows[0]["ratio"] == 1.0 and all(r["median_s"] > 0 for r in rows)
    assert "| no TBB | two runs at once | 2 |" in bm.markdown(rows)
