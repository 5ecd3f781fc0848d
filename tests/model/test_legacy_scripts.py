"""Legacy `script` scenarios translated into DirichletSets, checked against loops written
the way the original's AnimScripter / findBorderVerts are."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ipcsim.model.builder import build_model
from ipcsim.scene.spec import DirichletSpec, PlaneSpec, SceneSpec, ShapeSpec


def _loop_twist(rest, ratio):
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    rng = hi - lo
    left, right = [], []
    for i, x in enumerate(rest):  # IglUtils::findBorderVerts
        if x[0] < lo[0] + rng[0] * ratio:
            left.append(i)
        elif x[0] > hi[0] - rng[0] * ratio:
            right.append(i)
    return left, right


def test_twist_rods(ipc_examples):
    """paperExamples/tb1_diffDt/rodsTwist_*: 4 rods, size 1, script twist."""
    rod = ipc_examples / "input/tetMeshes/rod.msh"
    shapes = tuple(ShapeSpec(rod, translation=(0, y, z)) for y, z in
                   [(-0.1, -0.1), (-0.1, 0.1), (0.1, -0.1), (0.1, 0.1)])
    model = build_model(SceneSpec(shapes=shapes, script="twist", size=1.0, gravity=False,
                                  energy="FCR", dt=0.025, duration=6))
    left, right = _loop_twist(model.rest_positions, 0.01)
    assert len(model.dbc_sets) == 2 and left and right
    a, b = model.dbc_sets
    assert a.vertices.tolist() == left and b.vertices.tolist() == right
    assert a.angular_velocity == pytest.approx((-0.4 * math.pi, 0, 0))
    assert b.angular_velocity == pytest.approx((0.4 * math.pi, 0, 0))
    centre = (model.rest_positions.min(axis=0) + model.rest_positions.max(axis=0)) / 2
    assert a.centre == pytest.approx(tuple(centre)) and b.centre == a.centre
    assert not a.gated and a.time_range == (0.0, math.inf)
    # every rod contributes to both handles
    assert set(model.vertex_shape[a.vertices]) == {0, 1, 2, 3}
    assert np.allclose(model.initial_positions, model.rest_positions)
    assert model.initial_positions.max(axis=0).max() == pytest.approx(1.0)


def test_twist_mat(ipc_examples):
    """paperExamples/21_scalability/mat40x40_twist.txt: rotated 90 deg about x, size 1."""
    mat = ipc_examples / "input/tetMeshes/mat40x40.msh"
    model = build_model(SceneSpec(shapes=(ShapeSpec(mat, rotation_deg=(90, 0, 0)),),
                                  script="twist", size=1.0, gravity=False))
    left, right = _loop_twist(model.rest_positions, 0.01)
    assert [s.vertices.tolist() for s in model.dbc_sets] == [left, right]
    assert "Dirichlet BC (2 moving sets)" in model.terms


def test_push_right_most_1(ipc_examples):
    """paperExamples/20_pencilStickSlip.txt: the first vertex with x > max - 1e-3 range."""
    rod = ipc_examples / "input/tetMeshes/rod.msh"
    scene = SceneSpec(shapes=(ShapeSpec(rod, rotation_deg=(0, 0, 89.5)),),
                      script="pushRightMost1", size=0.1,
                      planes=(PlaneSpec("halfSpace", (0, -1e-9, 0), (0, 1, 0), 0.35, 50),))
    model = build_model(scene)
    x = model.initial_positions
    lo, hi = x.min(axis=0), x.max(axis=0)
    want = None
    for i in range(len(x)):
        if x[i, 0] > hi[0] - 1e-3 * (hi[0] - lo[0]):
            want = i
            break
    (s,) = model.dbc_sets
    assert s.vertices.tolist() == [want]
    assert s.linear_velocity == (-0.15, 0.0, 0.0)
    assert model.initial_positions.max(axis=0).max() == pytest.approx(0.1)
    assert "friction (half-space 0.35)" in model.terms


def test_fall_shifts_initial_positions_only(ipc_examples):
    """paperExamples/10_cubeStack.txt: 5 cubes, size 1, script fall."""
    cube = ipc_examples / "input/tetMeshes/cube.msh"
    shapes = tuple(ShapeSpec(cube, translation=(0, 1.01 * k, 0)) for k in range(5))
    scene = SceneSpec(shapes=shapes, script="fall", size=1.0, energy="FCR",
                      planes=(PlaneSpec("halfSpace", (0, 0.5, 0), (0, 1, 0), 0.0, 50),))
    model = build_model(scene)
    rest = model.rest_positions
    shift = 0.5 * np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))
    assert np.allclose(model.initial_positions - rest, [0, shift, 0])
    assert model.dbc_sets == () and not model.always_kinematic.any()
    assert not model.needs_friction
    no_shift = build_model(SceneSpec(shapes=shapes, script="fallNoShift", size=1.0))
    assert np.array_equal(no_shift.initial_positions, no_shift.rest_positions)


def test_dcofix_mat_knives(ipc_examples):
    """paperExamples/2_matKnives.txt: a mat and 9 fixed triangles."""
    mat = ipc_examples / "input/tetMeshes/mat40x40.msh"
    tri = ipc_examples / "input/triMeshes/triangle.obj"
    knives = [((0.2 * k, -0.1, -0.7), (0, 0, 90)) for k in range(1, 5)]
    knives += [((0.1 + 0.2 * k, -0.1, 0.3), (0, 180, 90)) for k in range(5)]
    shapes = (ShapeSpec(mat, translation=(0.5, 1, 0.1), rotation_deg=(0, 0, 0.05),
                        scale=(1.2, 1.2, 1.2)),)
    shapes += tuple(ShapeSpec(tri, translation=t, rotation_deg=r) for t, r in knives)
    model = build_model(SceneSpec(shapes=shapes, script="DCOFix", size=1.0))
    assert len(model.dbc_sets) == 9
    fixed = np.concatenate([s.vertices for s in model.dbc_sets])
    assert fixed.tolist() == list(range(model.shape_offsets[1], model.n_vertices))
    assert not any(s.moving for s in model.dbc_sets)
    assert model.always_kinematic[fixed].all() and not model.always_kinematic[:3200].any()
    assert "elasticity: neo-Hookean (1 shape)" in model.terms
    assert len(model.surface_triangles) == 6396 + 9


def test_dco_rot_cylinders(mesh_dir):
    shapes = tuple(ShapeSpec(mesh_dir / "tri.obj", translation=(3 * k, 0, 0)) for k in range(4))
    shapes += (ShapeSpec(mesh_dir / "cube1.msh", translation=(0, 2, 0)),)
    model = build_model(SceneSpec(shapes=shapes, script="DCORotCylinders"))
    omegas = [(math.pi / 2, 0, 0), (-math.pi / 2, 0, 0), (0, 0, -math.pi / 2), (0, 0, math.pi / 2)]
    assert len(model.dbc_sets) == 4
    for k, (s, w) in enumerate(zip(model.dbc_sets, omegas)):
        x = model.initial_positions[model.shape_vertices(k)]
        assert s.vertices.tolist() == list(range(3 * k, 3 * k + 3))
        assert s.angular_velocity == pytest.approx(w)
        assert s.centre == pytest.approx(tuple((x.min(axis=0) + x.max(axis=0)) / 2))


def test_fix_lower_half(mesh_dir):
    model = build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube3.msh", scale=(1, 3, 1)),),
                                  script="fixLowerHalf"))
    x = model.initial_positions
    lo, hi = x.min(axis=0), x.max(axis=0)
    want = [i for i in range(len(x)) if x[i, 1] < lo[1] + (hi[1] - lo[1]) * 0.5]
    (s,) = model.dbc_sets
    assert s.vertices.tolist() == want and len(want) == 32  # layers y = 0 and y = 1
    assert not s.moving


def test_script_ignores_per_shape_bcs(mesh_dir):
    d = DirichletSpec((-0.1, -0.1, -0.1), (0.1, 1.1, 0.1), (1, 0, 0))
    scene = SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube1.msh", dbc=(d,),
                                        linear_velocity=(1, 0, 0)),), script="fallNoShift")
    model = build_model(scene)
    assert model.dbc_sets == () and not model.always_kinematic.any()
    assert any("DBC, linearVelocity" in w for w in model.warnings)
    assert "elasticity: neo-Hookean (1 shape)" in model.terms
