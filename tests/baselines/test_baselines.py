"""The SQP and QP baselines (ipcsim.baselines): the active set and its linearisation, the
time step on small generated scenes, and how each way of failing is labelled."""

from __future__ import annotations

import json

import msgspec
import numpy as np
import pytest
from generated import write_box_msh

from ipcsim.baselines import active_set as AS
from ipcsim.baselines.qp import QPResult
from ipcsim.cli import main
from ipcsim.contact.collision_mesh import CollisionMesh
from ipcsim.errors import SolverError
from ipcsim.model.build import build_model
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

pytest.importorskip("osqp")

SQP_SETTINGS = ("warmStart 1\nconstraintType graphics\nconstraintOffset 1e-3\n"
                "useActiveSetConvergence\n")


def _point_and_triangle():
    """A point 1 above the triangle (0,0,0) (1,0,0) (0,1,0) (normal +z), falling to −1."""
    x0 = np.array([[0.2, 0.2, 1.0], [0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    x1 = x0.copy()
    x1[0, 2] = -1.0
    mesh = CollisionMesh.of(4, [0, 1, 2, 3], [[1, 2], [2, 3], [1, 3]], [[1, 2, 3]],
                            kinematic=np.array([False, True, True, True]))
    return x0, x1, mesh


@pytest.mark.parametrize("kind", ["volume", "gap", "Verschoor"])
def test_a_pair_the_motion_passes_through_joins_with_its_start_side(kind):
    x0, x1, mesh = _point_and_triangle()
    geo = AS.ConstraintGeometry(mesh, None, kind, 1e-3)
    active, added = AS.grow(AS.ActiveSet.empty(), geo, x0, x1)
    assert added == 1 and active.pt.tolist() == [[0, 1, 2, 3]]
    assert active.pt_sign.tolist() == [1.0]  # above the triangle at the start
    again, added = AS.grow(active, geo, x0, x1)
    assert added == 0 and again.pt.tolist() == [[0, 1, 2, 3]]
    if kind == "Verschoor":  # the contact point (0.2, 0.2, 0): weights 1, −0.6, −0.2, −0.2
        assert np.allclose(active.pt_w, [[1, -0.6, -0.2, -0.2]], atol=1e-3)
    # linearised at x1, only the point is free: c(x1) < 0, the row asks for ≥ offset
    free_index = np.array([0, 1, 2] + [-1] * 9)
    lin = AS.linearise(active, geo, x1, free_index, 3)
    assert lin.counts == (0, 1, 0) and lin.values[0] < 0
    assert lin.lower[0] == pytest.approx(1e-3 - lin.values[0])
    row = lin.A.toarray()[0]
    assert row[2] > 0 and np.allclose(row[:2], 0)  # moving the point up raises c
    # the QP's answer, the point moved back by lower / row: satisfies the constraint
    x = x1.copy()
    x[0, 2] += lin.lower[0] / row[2]
    c, _ = AS._values(x, active.pt, False, kind, active.pt_w)
    assert c[0] == pytest.approx(1e-3, rel=1e-6, abs=1e-9) or c[0] > 1e-3


def test_a_pair_the_motion_stays_clear_of_is_not_added():
    x0, _, mesh = _point_and_triangle()
    x1 = x0 + [0.5, 0, 0]  # sideways, a unit above
    geo = AS.ConstraintGeometry(mesh, None, "gap", 1e-3)
    assert AS.grow(AS.ActiveSet.empty(), geo, x0, x1)[1] == 0


def _scene(tmp_path, solver, extra="", init_velocity=0.0, steps_time="time 0.4 0.02"):
    mesh = write_box_msh(tmp_path / "cube.msh", cells=(1, 1, 1), size=(0.1, 0.1, 0.1))
    scene = tmp_path / "scene.txt"
    scene.write_text(f"shapes input 1\n{mesh.name} 0 0.05 0  0 0 0  1 1 1  "
                     f"initVel 0 {init_velocity:g} 0  0 0 0\n"
                     f"{steps_time}\nenergy FCR\nstiffness 1e5 0.4\nground 0 0\n"
                     f"constraintSolver {solver}\n{extra}")
    return scene


@pytest.mark.parametrize("solver", ["SQP", "QP"])
def test_a_falling_cube_rests_on_the_ground_at_the_offset(tmp_path, solver):
    model = build_model(load_scene(_scene(tmp_path, solver, SQP_SETTINGS)))
    assert any(t.startswith(f"contact as constraints ({solver}, graphics") for t in model.terms)
    assert not model.needs_friction
    sim = Simulation(model)
    for _ in range(model.n_steps):
        report = sim.step()
        assert report.notes == ()
    assert sim.outcome == "Pass"
    assert sim.state.x[:, 1].min() == pytest.approx(1e-3, rel=1e-3)  # c ≥ offset, held
    assert report.row["contacts_plane"] == 4  # the bottom face's vertices
    assert abs(sim.state.v[:, 1]).max() < 0.05  # at rest, not bouncing


def test_one_qp_per_step_lets_a_fast_cube_through_and_says_so(tmp_path, capsys):
    """QP without warm start or active-set iterations: the step that reaches the ground
    has no constraint yet, so the cube ends below it: "Intersecting" on the terminal and in
    run.json; ``ipcsim check --frames`` finds the frames that are bad."""
    scene = _scene(tmp_path, "QP", "", init_velocity=-4.0, steps_time="time 0.06 0.02")
    out = tmp_path / "out"
    assert main(["run", str(scene), "-o", str(out), "-q"]) == 0
    err = capsys.readouterr().err
    assert "warning: step 1: the state intersects (4 vertices below a plane)" in err
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "ok" and info["outcome"] == "Intersecting"
    assert main(["check", "--frames", str(out)]) == 1


def test_sqp_keeps_the_same_cube_out(tmp_path):
    scene = _scene(tmp_path, "SQP", SQP_SETTINGS, init_velocity=-4.0,
                   steps_time="time 0.06 0.02")
    sim = Simulation(build_model(load_scene(scene)))
    for _ in range(3):
        sim.step()
    assert sim.outcome == "Pass" and sim.state.x[:, 1].min() > 0.0


def test_a_blow_up_is_a_labelled_solver_failure(tmp_path, capsys):
    model = build_model(load_scene(_scene(tmp_path, "SQP", SQP_SETTINGS, init_velocity=-4.0)))
    cs = msgspec.structs.replace(model.constraint_solver, blow_up_factor=1e-3)
    sim = Simulation(msgspec.structs.replace(model, constraint_solver=cs))
    with pytest.raises(SolverError, match="step 1: blow-up") as err:
        sim.step()
    assert err.value.label == "Blow-up" and sim.outcome == "Blow-up"


def test_two_failed_qps_in_a_row_are_a_labelled_failure(tmp_path, monkeypatch):
    import ipcsim.baselines.sqp as sqp

    calls = []

    def infeasible(P, q, A, lower, settings, linear_solver):
        calls.append(A.shape[0])
        return QPResult(np.zeros(len(q)), np.zeros(A.shape[0]), "primal infeasible", 7)

    monkeypatch.setattr(sqp, "solve_qp", infeasible)
    sim = Simulation(build_model(load_scene(_scene(tmp_path, "SQP", SQP_SETTINGS))))
    with pytest.raises(SolverError, match="the QP failed twice in a row") as err:
        sim.step()
    assert err.value.label == "QP failure" and len(calls) == 2


def test_run_json_and_exit_status_of_a_failed_baseline(tmp_path, monkeypatch, capsys):
    import ipcsim.baselines.sqp as sqp

    monkeypatch.setattr(sqp, "solve_qp", lambda P, q, A, lower, s, ls: QPResult(
        np.zeros(len(q)), np.zeros(A.shape[0]), "dual infeasible", 3))
    out = tmp_path / "out"
    assert main(["run", str(_scene(tmp_path, "QP", SQP_SETTINGS)), "-o", str(out), "-q"]) == 3
    assert "the QP failed twice in a row (OSQP: dual infeasible)" in capsys.readouterr().err
    info = json.loads((out / "run.json").read_text())
    assert info["outcome"] == "QP failure" and info["status"].startswith("step 1:")
