"""The line search's CCD bound (``kernels/terms/line_search.feasible_step``): CCD first
over twice the step's last α, then, only when nothing stops the motion there, over the
whole direction. Both give the same safe step."""

from __future__ import annotations

import numpy as np
import pytest

from msgspec import Struct

from ipcsim.contact.ccd import DEFAULT_MAX_ITERATIONS, DEFAULT_MIN_GAP_FRACTION
from ipcsim.contact.collision_mesh import CollisionMesh
from ipcsim.contact.collisions import (Collisions, build_collisions, narrowed_collisions,
                                       swept_collisions)
from ipcsim.contact.intersection import find_intersections
from ipcsim.kernels.terms import all_terms as kt
from ipcsim.kernels.terms.line_search import feasible_step, snap_reach
from ipcsim.model.build import build_model
from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.potentials.kernel_data import NO_TERMS
from ipcsim.scene import load_scene

DHAT = 0.01


class Bound(Struct, frozen=True, eq=False):
    alpha: float
    collisions: Collisions


def line_search_bound(mesh, x, p, dhat, previous_alpha=1.0) -> Bound:
    """The mesh's CCD bound of the direction p from x (no term bounds), and its pairs."""
    n = len(x)
    out = feasible_step(x, np.ascontiguousarray(p), np.zeros(kt.N_KINDS, dtype=np.bool_),
                        NO_TERMS, mesh.line_search_arrays, (False, 0.0, 0.1),
                        (np.zeros(n, dtype=np.bool_), np.zeros((n, 3)), 0.0),
                        (float(dhat), float(previous_alpha), True, DEFAULT_MIN_GAP_FRACTION,
                         DEFAULT_MAX_ITERATIONS))
    return Bound(float(out[0]), Collisions(out[2], out[3], out[4], None, out[5], out[6]))


@pytest.fixture(scope="module")
def falling_cube(tmp_path_factory):
    """A turned cube 5 cm above another; p throws it 3 m down through the lower one."""
    folder = tmp_path_factory.mktemp("ccd")
    write_msh(folder / "cube.msh", *box_tet_mesh(2, 2, 2, size=(1, 1, 1)))
    scene = folder / "scene.txt"
    scene.write_text("shapes input 2\ncube.msh 0 0 0  0 0 0  1 1 1\n"
                     "cube.msh 0.13 1.05 0.07  17 11 23  1 1 1\n"
                     f"dHatAbs {DHAT}\nturnOffGravity\n")
    model = build_model(load_scene(scene))
    x = np.array(model.initial_positions)
    top = model.vertex_shape == 1
    x[top, 1] += 1.05 - x[top, 1].min()
    rng = np.random.default_rng(3)
    p = np.zeros_like(x)
    p[top] = [0.0, -3.0, 0.0]
    p[top] += 0.05 * rng.normal(size=(int(top.sum()), 3))
    return model, x, p


def _min_distance(mesh, x):
    return build_collisions(mesh, x, DHAT).count(DHAT).min_distance  # pairs within d̂


def test_the_short_sweep_gives_the_whole_sweeps_step_and_it_is_safe(falling_cube):
    model, x, p = falling_cube
    mesh = CollisionMesh.from_model(model)
    whole = line_search_bound(mesh, x, p, DHAT).alpha  # first iteration of a step: β = 1
    assert 0.0 < whole < 0.05  # the 3 m throw is stopped after about 5 cm
    swept_whole = len(swept_collisions(mesh, x, x + p, DHAT).pt)
    staged = line_search_bound(mesh, x, p, DHAT, previous_alpha=whole).alpha  # β = 2·whole
    assert staged == pytest.approx(whole, rel=1e-9)
    short = len(swept_collisions(mesh, x, x + 2 * whole * p, DHAT).pt)
    assert short < swept_whole / 5  # what the shortcut saves
    xa = x + staged * p
    assert len(find_intersections(xa, mesh.edges, mesh.triangles)) == 0
    assert _min_distance(mesh, xa) > 0.0


def test_a_direction_free_beyond_the_short_sweep_is_swept_whole(falling_cube):
    model, x, p = falling_cube
    mesh = CollisionMesh.from_model(model)
    small = line_search_bound(mesh, x, p, DHAT).alpha  # a small α: the next try sweeps 2α
    away = np.zeros_like(x)
    away[model.vertex_shape == 1] = [0.0, 2.0, 0.0]  # straight up, nothing in the way
    assert line_search_bound(mesh, x, away, DHAT, previous_alpha=small).alpha == 1.0


def _rows(a):
    return sorted(map(tuple, np.asarray(a).tolist()))


def test_the_set_narrowed_from_a_sweep_is_the_query_at_each_point_of_it(falling_cube):
    """At points x + αp of a line search's segment (α up to the CCD bound, and the
    halvings below it), the collision set narrowed from the swept pairs has exactly the
    pairs, thresholds and distances of a fresh query there."""
    model, x, p = falling_cube
    mesh = CollisionMesh.from_model(model)
    bound = line_search_bound(mesh, x, p, DHAT)
    checked = 0
    for alpha in (bound.alpha, 0.5 * bound.alpha, 0.3 * bound.alpha, 1e-3 * bound.alpha, 0.0):
        y = x + alpha * p
        fresh = build_collisions(mesh, y, DHAT)
        narrowed = narrowed_collisions(bound.collisions, y, DHAT)
        assert _rows(narrowed.pt) == _rows(fresh.pt) and _rows(narrowed.ee) == _rows(fresh.ee)
        by_row = dict(zip(map(tuple, fresh.ee.tolist()), fresh.ee_eps_x))
        assert all(by_row[tuple(r)] == e for r, e in zip(narrowed.ee.tolist(), narrowed.ee_eps_x))
        assert sorted(narrowed.distances.pt_d2) == sorted(fresh.distances.pt_d2)
        assert sorted(narrowed.distances.ee_d2) == sorted(fresh.distances.ee_d2)
        assert narrowed.count(DHAT) == fresh.count(DHAT)
        checked += len(fresh)
    assert checked > 0  # the segment passes pairs within d̂


def test_the_reach_holds_every_end_snapped_onto_its_target():
    """The line search puts prescribed vertices on their targets t instead of
    fl(x + fl(t − x)); the sweep keeps the pairs of every point within the reach of that
    end, so the reach must bound the difference: checked on coordinates of every
    magnitude and sign."""
    rng = np.random.default_rng(5)
    worst = 0.0
    for ex in range(-3, 4):
        for et in range(-3, 4):
            x = rng.normal(size=(2000, 3)) * 10.0 ** ex
            t = rng.normal(size=x.shape) * 10.0 ** et
            near = x + rng.normal(size=x.shape) * 1e-6 * 10.0 ** ex  # short motions too
            for target in (t, near):
                reach = snap_reach(x, np.ones(len(x), dtype=np.bool_), target)
                off = np.abs((x + (target - x)) - target).max()
                assert off <= reach
                worst = max(worst, off / reach)
    assert worst > 0.05  # the bound is not vacuous: round-off reaches a part of it


def test_the_set_at_a_prescribed_motions_end_is_narrowed_from_the_sweep(tmp_path,
                                                                       monkeypatch):
    """A body on a prescribed path: the first iteration of each step lands its vertices
    exactly on their targets. The collision set there is narrowed from the line search's
    sweep (no new broad phase), and it is exactly the set a fresh query finds."""
    import ipcsim
    import ipcsim.potentials.step_problem as step_problem
    from generated import write_box_msh

    write_box_msh(tmp_path / "box.msh")
    (tmp_path / "scene.txt").write_text(
        "shapes input 2\n"
        "box.msh 0 0 0  0 0 0  1 1 1  DBC -1 -1 -1  2 2 2  0 0.4 0  0 0 0\n"
        "box.msh 0.03 0.215 0.01  0 0 0  1 1 1\n"
        "dHatAbs 0.004\nturnOffGravity\ntime 0.04 0.01\n")
    at_ends = []
    at = step_problem.StepProblem.at

    def checked_at(self, point):
        if point.swept is None or point.collisions is not None:
            return at(self, point)
        got = at(self, point)
        fresh = build_collisions(self.contact.mesh, point.x, self.contact.dhat)
        assert _rows(got.collisions.pt) == _rows(fresh.pt)
        assert _rows(got.collisions.ee) == _rows(fresh.ee)
        kin = self.kinematic
        if kin.any() and np.array_equal(point.x[kin], self.target[kin]):
            at_ends.append(len(fresh))
        return got

    monkeypatch.setattr(step_problem.StepProblem, "at", checked_at)
    ipcsim.run(load_scene(tmp_path / "scene.txt"), tmp_path / "out", steps=4)
    assert len(at_ends) >= 4  # every step's first iteration landed and was narrowed
    assert sum(at_ends) > 0  # and pairs were within d̂ there


def test_a_step_starts_with_the_collision_set_the_last_one_ended_with(tmp_path, monkeypatch):
    """Each step starts where the last one ended: its first collision set is the one
    the last step found there (no broad phase at the step's start), and the run is the
    same bit for bit as one that queries it again."""
    import ipcsim
    import ipcsim.potentials.step_problem as step_problem
    from generated import write_box_msh

    write_box_msh(tmp_path / "box.msh")
    (tmp_path / "scene.txt").write_text(
        "shapes input 2\nbox.msh 0 0 0  0 0 0  1 1 1\nbox.msh 0.03 0.2025 0.01  0 0 0  1 1 1\n"
        "dHatAbs 0.004\ntime 0.05 0.01\n")
    queried = []
    build = step_problem.build_collisions

    def counting(mesh, x, dhat):
        queried.append(x.copy())
        return build(mesh, x, dhat)

    monkeypatch.setattr(step_problem, "build_collisions", counting)
    spec = load_scene(tmp_path / "scene.txt")
    ipcsim.run(spec, tmp_path / "kept", steps=5)
    kept_queries = list(queried)
    ends = np.load(tmp_path / "kept" / "checkpoint.npz")["x"]

    queried.clear()
    monkeypatch.setattr("ipcsim.simulation._kept", lambda result: None)  # no hand-over
    ipcsim.run(spec, tmp_path / "fresh", steps=5)
    assert len(queried) == len(kept_queries) + 4  # one per step but the first
    np.testing.assert_array_equal(np.load(tmp_path / "fresh" / "checkpoint.npz")["x"], ends)
    contacts = np.genfromtxt(tmp_path / "kept" / "steps.csv", delimiter=",", names=True)
    assert contacts["contacts_total"].max() > 0  # sets with pairs were handed over


def test_a_narrowed_set_in_canonical_order_is_the_fresh_query_in_canonical_order():
    """The same pairs, ids and distances, row for row, whether the set at x came from a
    BVH query at x or from a sweep through x."""
    from ipcsim.model.surface import boundary_triangles, unique_edges

    points, tets = box_tet_mesh(3, 3, 3)
    top = points + [0.1, 1.0005, 0.05]  # a second box just above the first
    x = np.concatenate([points, top])
    tris = boundary_triangles(tets)
    triangles = np.concatenate([tris, tris + len(points)])
    mesh = CollisionMesh.of(len(x), np.arange(len(x)), unique_edges(triangles), triangles,
                            body=np.repeat([0, 1], len(points)), rest=x.copy())
    p = np.zeros_like(x)
    p[len(points):] = [0.0014, 0.0033, 0.0013]  # the top box sweeps through x, off-centre
    dhat = 0.002
    fresh = build_collisions(mesh, x, dhat)
    narrowed = narrowed_collisions(swept_collisions(mesh, x - 3 * p, x + p, dhat), x, dhat)
    assert not (np.array_equal(fresh.pt, narrowed.pt)  # the same pairs in another order
                and np.array_equal(fresh.ee, narrowed.ee))
    fresh, narrowed = fresh.in_canonical_order(), narrowed.in_canonical_order()
    assert len(fresh) > 20 and len(fresh.pt) and len(fresh.ee)
    for name in ("pt", "ee", "ee_eps_x", "pt_id", "ee_id"):
        np.testing.assert_array_equal(getattr(fresh, name), getattr(narrowed, name))
    for name in ("pt_type", "pt_d2", "ee_type", "ee_d2"):
        np.testing.assert_array_equal(getattr(fresh.distances, name),
                                      getattr(narrowed.distances, name))
    assert (np.diff(fresh.pt_id) > 0).all() and (np.diff(fresh.ee_id) > 0).all()
