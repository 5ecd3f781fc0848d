"""The pull of prescribed vertices (potentials/boundary_pull.py): its derivatives against
finite differences, its schedule, when a step's objective starts and ends it, and steps
that need it: they converge with the prescribed motion done, intersection- and
inversion-free, in as few iterations as the original needs where a step's first
iteration could not take the prescribed vertices to their targets."""

from __future__ import annotations

import numpy as np
import pytest
from generated import write_press_scene

from ipcsim.contact.intersection import find_intersections
from ipcsim.kernels.algebra.linalg import tet_signed_volumes
from ipcsim.model.build import build_model
from ipcsim.potentials.boundary_pull import MAX_RHO, START_RHO, BoundaryPull, PullSchedule
from ipcsim.scene import load_scene
from ipcsim.potentials.step_problem import Point, StepProblem
from ipcsim.simulation import Simulation


def _pull(rng, k=5, n=9, lam=True) -> tuple[BoundaryPull, np.ndarray]:
    vertices = np.sort(rng.choice(n, k, replace=False)).astype(np.int64)
    start = rng.random((k, 3))
    pull = BoundaryPull(vertices, rng.random(k) + 0.5, start + rng.normal(size=(k, 3)),
                        start, rho=3.0, lam=rng.normal(size=(k, 3)) if lam else None)
    return pull, rng.random((n, 3))


def _at(pull: BoundaryPull, x: np.ndarray, completion: float) -> np.ndarray:
    """x with the pulled vertices at ``completion`` of the way from start to target."""
    y = x.copy()
    y[pull.vertices] = completion * pull.target + (1 - completion) * pull.start
    return y


def test_gradient_and_hessian_match_finite_differences():
    rng = np.random.default_rng(0)
    pull, x = _pull(rng)
    g = pull.gradient(x)
    eps = 1e-6
    for i in range(x.size):
        d = np.zeros(x.size)
        d[i] = eps
        d = d.reshape(x.shape)
        fd = (pull.value(x + d) - pull.value(x - d)) / (2 * eps)
        assert fd == pytest.approx(g[i], rel=1e-6, abs=1e-8)
    H = pull.hessian(x)
    dense = np.zeros((x.size, x.size))
    np.add.at(dense, (H.rows, H.cols), H.values)
    for i in range(x.size):
        d = np.zeros(x.size)
        d[i] = eps
        fd = (pull.gradient(x + d.reshape(x.shape)) - pull.gradient(x - d.reshape(x.shape)))
        np.testing.assert_allclose(fd / (2 * eps), dense[:, i], rtol=1e-6, atol=1e-6)


def test_completion_measures_the_distance_left_against_the_whole_motion():
    rng = np.random.default_rng(1)
    pull, x = _pull(rng, lam=False)
    x[pull.vertices] = pull.start
    assert pull.completion(x) == pytest.approx(0.0)
    x[pull.vertices] = pull.target
    assert pull.completion(x) == 1.0
    x[pull.vertices] = 0.75 * pull.target + 0.25 * pull.start
    assert pull.completion(x) == pytest.approx(0.75)
    still = BoundaryPull(pull.vertices, pull.mass, pull.start, pull.start)
    assert still.completion(x) == 1.0  # fixed vertices: nothing to do


def test_the_multipliers_keep_the_force_the_spring_exerted():
    """λ ← λ − ρ√m (x − x̂): the multipliers take over the force the spring exerted at x
    (from zero multipliers, the pull's force at x doubles), so the vertices are pulled on
    with the stiffness unchanged."""
    rng = np.random.default_rng(2)
    pull, x = _pull(rng, lam=False)
    updated = pull.with_updated_multipliers(x)
    assert updated.rho == pull.rho
    np.testing.assert_allclose(updated.gradient(x), 2.0 * pull.gradient(x), rtol=1e-12)
    again = updated.with_updated_multipliers(x)
    np.testing.assert_allclose(again.gradient(x), 3.0 * pull.gradient(x), rtol=1e-12)


def test_the_schedule_stiffens_until_the_vertices_are_close_then_updates_multipliers():
    rng = np.random.default_rng(3)
    pull, x = _pull(rng, lam=False)
    schedule = PullSchedule(started_at=0.5, small_step=1e-3)
    big, small = np.full(6, 1.0), np.full(6, 1e-4)

    def at(completion):
        return _at(pull, x, completion)

    assert schedule.next(pull, at(0.9995), big) == (None, True)  # done
    nxt, changed = schedule.next(pull, at(0.3), big)  # fell back behind its start
    assert changed and nxt.rho == 2 * pull.rho
    assert schedule.next(pull, at(0.8), big) == (pull, False)  # still moving: wait
    nxt, changed = schedule.next(pull, at(0.8), small)  # stalled far from the targets
    assert changed and nxt.rho == 2 * pull.rho and nxt.lam is None
    nxt, changed = schedule.next(pull, at(0.995), small)  # stalled close to them
    assert changed and nxt.rho == pull.rho and nxt.lam is not None
    capped = BoundaryPull(pull.vertices, pull.mass, pull.target, pull.start, rho=MAX_RHO)
    nxt, _ = schedule.next(capped, at(0.3), big)
    assert nxt.rho == MAX_RHO


def test_the_schedules_tail_is_a_small_step_from_99_percent_until_done():
    rng = np.random.default_rng(4)
    pull, x = _pull(rng, lam=False)
    schedule = PullSchedule(started_at=0.5, small_step=1e-3)
    big, small = np.full(6, 1.0), np.full(6, 1e-4)

    def at(completion):
        return _at(pull, x, completion)

    assert schedule.in_tail(pull, at(0.995), small)
    assert not schedule.in_tail(pull, at(0.995), big)  # still moving
    assert not schedule.in_tail(pull, at(0.98), small)  # stiffen first
    assert not schedule.in_tail(pull, at(0.9995), small)  # done already


@pytest.fixture(scope="module")
def press_scene(tmp_path_factory):
    """``generated.write_press_scene``: each step's first iteration is cut short by the
    contact."""
    return write_press_scene(tmp_path_factory.mktemp("press"))


def test_a_step_that_cannot_finish_its_prescribed_motion_at_once_pulls_the_vertices(
        press_scene):
    """The problem's own view: after an incomplete first iteration the bodies'
    prescribed vertices are free DOFs with the pull in the potential; once they are at
    their targets the pull ends and they stay there. Each is a new problem; the one it
    came from is unchanged."""
    sim = Simulation(build_model(load_scene(press_scene)))
    problem, start = sim.problem(sim.state)
    ctx = problem.ctx
    kin = ctx.kinematic
    assert kin.sum() > 0 and problem.prescribed_complete()
    halfway = ctx.x_start.copy()
    halfway[kin] = 0.5 * (ctx.x_start[kin] + ctx.target[kin])
    p = np.zeros(halfway.size)
    same, _ = problem.follow_up(Point(halfway), p, first=False)  # not the first: nothing
    assert same is problem
    pulling, point = problem.follow_up(Point(halfway), p, first=True)
    pull = pulling.pull
    assert pull is not None and pull.rho == START_RHO and problem.pull is None
    assert not pulling.prescribed_complete() and problem.prescribed_complete()
    assert not pulling.kinematic.any()  # every prescribed vertex here is a body's
    assert "boundary_pull" in [t.term.name for t in pulling.potential.terms]
    assert point.known is None  # another potential: energies from before do not count
    there = halfway.copy()
    there[kin] = ctx.target[kin] + 1e-6  # within 0.1 % of the motion
    done, _ = pulling.follow_up(Point(there), p, first=False)
    assert done.pull is None and done.prescribed_complete()
    np.testing.assert_array_equal(done.kinematic, kin)
    np.testing.assert_array_equal(done.target[kin], there[kin])
    assert "boundary_pull" not in [t.term.name for t in done.potential.terms]
    np.testing.assert_array_equal(problem.target, ctx.target)  # unchanged


def test_pulled_steps_finish_their_motion_without_intersection_or_inversion(press_scene):
    sim = Simulation(build_model(load_scene(press_scene)))
    mesh = sim.contact.mesh
    from ipcsim.model.kinematics import kinematic_targets

    for _ in range(3):
        kin, target = kinematic_targets(sim.model, sim.state.x, sim.state.step * sim.h, sim.h)
        start = sim.state.x.copy()
        row = sim.step().row
        x = sim.state.x
        assert row["converged"] and row["newton_iterations"] < 40
        moved = np.sum((x[kin] - target[kin]) ** 2) / np.sum((start[kin] - target[kin]) ** 2)
        assert np.sqrt(moved) <= 1e-3  # ≥ 99.9 % of the prescribed motion done
        assert len(find_intersections(x, mesh.edges, mesh.triangles)) == 0
        assert tet_signed_volumes(x, np.ascontiguousarray(sim.model.tets)).min() > 0.0


def _pulling(press_scene, completion):
    """The press scene's first step with its pull started and the top face at
    ``completion`` of its motion."""
    sim = Simulation(build_model(load_scene(press_scene)))
    problem, _ = sim.problem(sim.state)
    ctx = problem.ctx
    kin = ctx.kinematic.copy()
    x = ctx.x_start.copy()
    x[kin] = 0.5 * (ctx.x_start[kin] + ctx.target[kin])
    problem, _ = problem.follow_up(Point(x), np.zeros(x.size), first=True)
    assert problem.pull is not None
    x[kin] = completion * ctx.target[kin] + (1.0 - completion) * ctx.x_start[kin]
    return problem, x, kin


def test_in_the_tail_the_pulled_vertices_are_placed_on_their_targets(press_scene):
    """Nearly there and barely moving, with nothing in their way, the pulled vertices go
    the rest of the way at once: the pull ends (another potential) with them exactly on
    their targets, prescribed again; the rest of x and the line searches' CCD hint are
    unchanged."""
    problem, x, kin = _pulling(press_scene, 0.995)
    done, point = problem.follow_up(Point(x, ccd_alpha=0.25), np.zeros(x.size), first=False)
    assert done.pull is None and done.prescribed_complete()
    y = point.x
    np.testing.assert_array_equal(y[kin], done.target[kin])
    np.testing.assert_array_equal(y[~kin], x[~kin])
    np.testing.assert_array_equal(done.kinematic, kin)
    assert "boundary_pull" not in [t.term.name for t in done.potential.terms]
    assert point.ccd_alpha == 0.25 and point.known is None


def test_where_the_rest_of_the_move_is_not_free_the_multipliers_update(press_scene,
                                                                         monkeypatch):
    """If contact or inversion would stop the pulled vertices short of their targets, they
    stay pulled, and the multipliers take over the spring's force, as the original does."""
    problem, x, kin = _pulling(press_scene, 0.995)
    monkeypatch.setattr(StepProblem, "max_step", lambda self, *a, **k: (0.5, 0.5))
    start = Point(x)
    updated, point = problem.follow_up(start, np.zeros(x.size), first=False)
    assert point.x is x and updated.pull is not None and updated.pull.lam is not None
    assert updated.pull.rho == problem.pull.rho and problem.pull.lam is None


def test_steps_whose_pulls_end_by_placement_finish_their_motion_exactly(
        press_scene, pulls_end_by_placement):
    """With pulls that end only in their tail (never at 99.9 % done), the press scene's
    steps still converge, with every prescribed vertex exactly on its target, free of
    intersection and inversion."""
    from ipcsim.model.kinematics import kinematic_targets

    placed = pulls_end_by_placement
    sim = Simulation(build_model(load_scene(press_scene)))
    mesh = sim.contact.mesh
    for _ in range(3):
        kin, target = kinematic_targets(sim.model, sim.state.x, sim.state.step * sim.h, sim.h)
        row = sim.step().row
        x = sim.state.x
        assert row["converged"] and row["newton_iterations"] < 40
        np.testing.assert_array_equal(x[kin], target[kin])
        assert len(find_intersections(x, mesh.edges, mesh.triangles)) == 0
        assert tet_signed_volumes(x, np.ascontiguousarray(sim.model.tets)).min() > 0.0
    assert any(p is not None for p in placed)
