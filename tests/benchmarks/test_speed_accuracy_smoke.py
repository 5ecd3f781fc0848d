"""Smoke run of the speed-accuracy benchmark: the two-cube scene for 0.3 s at two h.

The smoke sweep's second setting repeats the reference run exactly, so its error must be
0 (runs are deterministic); the first uses twice the time step and must be worse.
"""

from __future__ import annotations

import csv
import math

import numpy as np

from ipcsim.model.build import build_model
from ipcsim.scene import load_scene

from benchmarks.speed_accuracy import (
    SCENES, Settings, main, material_points, pareto, write_scene)


def test_smoke_writes_csv_and_chart(tmp_path):
    assert main(["--smoke", "--out", str(tmp_path)]) == 0
    png = tmp_path / "speed_accuracy_two_cubes.png"
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"
    with open(tmp_path / "speed_accuracy.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(r["parameter"], r["value"]) for r in rows] == [
        ("reference", ""), ("dt", "0.05"), ("dt", "0.025")]
    for r in rows:
        for key in ("wall_s", "error", "rest_gap_m", "dhat_m"):
            assert math.isfinite(float(r[key])), (key, r)
        assert float(r["wall_s"]) > 0 and int(r["newton_iterations"]) >= int(r["steps"])
    reference, coarse, same = rows
    assert float(reference["error"]) == 0.0
    assert float(same["error"]) == 0.0  # same settings as the reference
    assert float(coarse["error"]) > 1e-6  # h doubled: a visible error
    assert [r["is_default"] for r in rows] == ["0", "0", "1"]

    png.unlink()  # the charts can be redrawn from the CSV alone
    assert main(["--replot", "--out", str(tmp_path)]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_pareto_front_keeps_only_undominated_points():
    points = [(1.0, 1e-2), (2.0, 1e-3), (3.0, 5e-3), (0.5, 1e-1), (4.0, 1e-4), (2.0, 2e-3)]
    assert pareto(points) == [3, 0, 1, 4]


def test_material_points_are_the_same_on_every_mesh(tmp_path):
    """The error compares runs at lattice points; they must not move with the mesh."""
    scene = SCENES["twisted_bar"]
    rest = []
    for res in (1, 3):
        path, _ = write_scene(scene, Settings(res=res), tmp_path / f"r{res}", 0.1)
        model = build_model(load_scene(path))
        verts, weights = material_points(scene, model)
        assert np.all(weights >= -1e-9) and np.allclose(weights.sum(axis=1), 1.0)
        rest.append(np.einsum("qk,qkd->qd", weights, model.rest_positions[verts]))
    assert rest[0].shape == (11 * 3 * 3, 3)
    np.testing.assert_allclose(rest[0], rest[1], atol=1e-12)
    assert np.isclose(rest[0][:, 0].max(), 1.0) and np.isclose(rest[0][:, 1].max(), 0.1)
