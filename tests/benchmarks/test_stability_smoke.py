"""The stability suite in small: one case per family, three steps, ipcsim's barrier, one
penalty stiffness and the SQP and QP baselines. ipcsim's frames must be free of
intersections, inverted tets and vertices below a plane; the penalty baseline must show
its known failure (a cube at 1000 m/s passes straight through a fixed plate); every
baseline run is labelled as the paper's supplement labels them, in agreement with the
exact check of its frames."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.stability import run_suite
from benchmarks.stability_meshes import graded_box_mesh, link_mesh, slot_mesh
from ipcsim.model.surface import boundary_triangles


def _signed_volumes(points, tets):
    e = [points[tets[:, k]] - points[tets[:, 0]] for k in (1, 2, 3)]
    return np.einsum("ij,ij->i", e[0], np.cross(e[1], e[2])) / 6.0


@pytest.mark.parametrize("points,tets,volume", [
    (*link_mesh(0.05, 0.15, 0.3, 0.05), 0.05 * (0.25 * 0.4 - 0.15 * 0.3)),
    (*slot_mesh(0.2, 1e-6, 0.1, 0.3, 0.05), 0.3 * ((0.4 + 0.2e-6) * 0.35 - (0.2 + 0.2e-6) * 0.3)),
])
def test_meshes_with_holes_are_positive_and_have_the_right_volume(points, tets, volume):
    vol = _signed_volumes(points, tets)
    assert vol.min() > 0.0
    assert vol.sum() == pytest.approx(volume, rel=1e-9)
    assert len(np.unique(tets)) == len(points)  # no unused vertex
    # closed surface: every boundary edge is shared by exactly two boundary triangles
    tri = boundary_triangles(tets)
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert set(counts) == {2}


def test_graded_box_removes_the_named_cell():
    points, tets = graded_box_mesh([0, 1, 3], [0, 2], [0, 1], removed_cells=[(1, 0, 0)])
    assert len(tets) == 6 and _signed_volumes(points, tets).sum() == pytest.approx(2.0)


@pytest.fixture(scope="module")
def smoke_rows(tmp_path_factory):
    pytest.importorskip("osqp")
    return run_suite(smoke=True, contact="all", root=tmp_path_factory.mktemp("stability"),
                     say=lambda *a: None)


def test_smoke_covers_every_family_with_every_model(smoke_rows):
    families = {"speed", "time step", "stiffness", "mass ratio", "slot", "chain"}
    for model in ("ipcsim", "penalty 1e+05", "SQP", "QP"):
        assert {r["family"] for r in smoke_rows if r["contact"] == model} == families


def test_baseline_runs_are_labelled_as_their_frames_are(smoke_rows):
    for r in (r for r in smoke_rows if r["contact"] in ("SQP", "QP")):
        assert r["label"] in ("Pass", "Intersecting", "Blow-up", "Timeout", "QP failure"), r
        if r["label"] == "Pass":
            assert r["checker_clean"] and r["steps_done"] == 3 and not r["reason"], r
        if r["label"] == "Intersecting":
            assert not r["checker_clean"] or r["escaped"], r
        if r["label"] in ("Blow-up", "QP failure"):
            assert r["reason"].startswith("step "), r  # the failed step, from run.json
    assert {r["label"] for r in smoke_rows if r["contact"] == "ipcsim"} == {"Pass"}


def test_ipcsim_frames_are_clean(smoke_rows):
    for r in (r for r in smoke_rows if r["contact"] == "ipcsim"):
        assert r["reason"] == "" and r["steps_done"] == r["planned"] == 3, r
        assert r["intersections"] == r["inverted"] == r["below_plane"] == 0, r
        assert r["checker_clean"] and r["verdict"] == "ok", r
        assert r["min_distance"] > 0.0


def test_penalty_tunnels_through_the_plate_at_1000_m_s(smoke_rows):
    (plate,) = [r for r in smoke_rows
                if r["contact"].startswith("penalty") and r["case"] == "plate v=1000"]
    assert plate["verdict"] == "tunnelled"
    (barrier,) = [r for r in smoke_rows
                  if r["contact"] == "ipcsim" and r["case"] == "plate v=1000"]
    assert barrier["verdict"] == "ok" and not barrier["escaped"]
