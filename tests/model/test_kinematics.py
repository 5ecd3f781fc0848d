"""kinematic_targets / nbc_accelerations: rotations, windows, overlaps, mesh sequences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ipcsim.errors import MeshError, SceneError
from ipcsim.model.build import build_model
from ipcsim.model.kinematics import (kinematic_targets, nbc_accelerations,
                                     rotation_axis_angle, rotation_xyz)
from ipcsim.scene.spec import DirichletSpec, NeumannSpec, SceneSpec, ShapeSpec

INF = math.inf


def test_rotation_helpers_match_scipy():
    angles = np.array([0.3, -1.1, 2.0])
    # intrinsic X-Y-Z Euler angles = the matrix product Rx Ry Rz
    assert np.allclose(rotation_xyz(angles), Rotation.from_euler("XYZ", angles).as_matrix())
    axis = np.array([1.0, 2.0, -0.5])
    want = Rotation.from_rotvec(0.7 * axis / np.linalg.norm(axis)).as_matrix()
    assert np.allclose(rotation_axis_angle(axis, 0.7), want)


def test_rotating_shape_matches_explicit_rotation(mesh_dir):
    """angularVelocity 10 90 0 deg/s (2cubesFall_rotateCO): rotation about the current AABB
    centre by Rx(wx h) Ry(wy h), plus a linear velocity."""
    shapes = (ShapeSpec(mesh_dir / "cube3.msh", translation=(0, 3, 0)),
              ShapeSpec(mesh_dir / "bar.msh", translation=(0, 1, 0), angular_velocity_deg=(10, 90, 0),
                        linear_velocity=(0.5, 0, 0)))
    model = build_model(SceneSpec(shapes=shapes))
    h = 0.04
    rng = np.random.default_rng(1)
    x = model.initial_positions + rng.normal(scale=0.01, size=model.initial_positions.shape)
    mask, targets = kinematic_targets(model, x, 0.0, h)
    sl = model.shape_vertices(1)
    assert mask[sl].all() and not mask[model.shape_vertices(0)].any()
    xs = x[sl]
    c = (xs.min(axis=0) + xs.max(axis=0)) / 2
    rot = Rotation.from_euler("XYZ", np.radians([10, 90, 0]) * h)
    assert np.allclose(targets[sl], rot.apply(xs - c) + c + [0.5 * h, 0, 0])
    assert np.array_equal(targets[model.shape_vertices(0)], x[model.shape_vertices(0)])
    assert len(model.dbc_sets) == 1 and model.dbc_sets[0].moving


def test_dbc_windows_gate_and_overlap(mesh_dir):
    # 2cubesFall_DBC_timeRange: the same box moves in [0, 2.5), is fixed from 2.5
    lo, hi = (-0.1, -0.1, -0.1), (0.1, 1.1, 0.1)
    dbc = (DirichletSpec(lo, hi, (-0.2, 0, -0.2), (0, 0, 0), (0.0, 2.5)),
           DirichletSpec(lo, hi, (0, 0, 0), (0, 0, 0), (2.5, INF)),
           DirichletSpec((0.9, -0.1, 0.9), (1.1, 1.1, 1.1), (0, 0, 0), (0, 0, 0), (1.0, 2.0)))
    shapes = (ShapeSpec(mesh_dir / "cube3.msh", dbc=dbc),)
    model = build_model(SceneSpec(shapes=shapes))
    h = 0.025
    first, second, third = model.dbc_sets
    x = model.initial_positions
    mask, targets = kinematic_targets(model, x, 99 * h, h)  # t = 2.475: first window
    assert mask[first.vertices].all() and not mask[third.vertices].any()
    assert np.allclose(targets[first.vertices] - x[first.vertices], [-0.2 * h, 0, -0.2 * h])
    mask, targets = kinematic_targets(model, x, 100 * h, h)  # t = 2.5: t0 <= t < t1
    assert mask[second.vertices].all() and mask.sum() == len(second.vertices)
    assert np.array_equal(targets, x)
    assert model.kinematic_mask_at(1.0)[third.vertices].all()
    assert not model.kinematic_mask_at(2.0)[third.vertices].any()
    # the global DBCTimeRange gates per-shape DBCs
    gated = build_model(SceneSpec(shapes=shapes, dbc_time_range=(0.0, 1.0)))
    assert gated.kinematic_mask_at(0.5)[first.vertices].all()
    assert not gated.kinematic_mask_at(1.5).any()


def test_later_set_overrides_earlier(mesh_dir):
    """A DBC on a shape with a linear velocity overwrites that motion for its vertices."""
    d = DirichletSpec((-0.1, -0.1, -0.1), (0.1, 1.1, 0.1), (0, 1, 0))
    model = build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube1.msh",
                                                    linear_velocity=(1, 0, 0), dbc=(d,)),)))
    x = model.initial_positions
    mask, targets = kinematic_targets(model, x, 0.0, 0.1)
    assert mask.all()
    moved = targets - x
    in_dbc = np.zeros(len(x), dtype=bool)
    in_dbc[model.dbc_sets[1].vertices] = True
    assert np.allclose(moved[in_dbc], [0, 0.1, 0]) and np.allclose(moved[~in_dbc], [0.1, 0, 0])


def test_fixed_centre_does_not_drift(mesh_dir):
    """Twist-like sets rotate about a fixed point, DBC sets about their current AABB."""
    scene = SceneSpec(shapes=(ShapeSpec(mesh_dir / "bar.msh"),), script="twist",
                      handle_ratio=0.1)
    model = build_model(scene)
    left = model.dbc_sets[0]
    assert left.centre == (2.0, 0.5, 0.5)
    x = model.initial_positions.copy()
    h = 0.1
    for _ in range(3):
        _, x = kinematic_targets(model, x, 0.0, h)
    # three steps of -0.4 pi rad/s about the x axis through (2, 0.5, 0.5)
    rot = Rotation.from_euler("X", -0.4 * math.pi * 3 * h)
    x0 = model.initial_positions[left.vertices]
    assert np.allclose(x[left.vertices], rot.apply(x0 - left.centre) + left.centre)


def test_mesh_sequence(tmp_path, mesh_dir):
    folder = tmp_path / "seq"
    folder.mkdir()
    base = np.array([[0.0, 1, 0], [1, 1, 0], [0, 1, 1]])
    for k in range(3):
        pts = base + [0.1 * k, 0, 0]
        folder.joinpath(f"{k}.seg").write_text(
            "".join(f"v {a} {b} {c}\n" for a, b, c in pts) + "s 1 2\ns 2 3\n")
    folder.joinpath("3.seg").write_text("v 0 0 0\nv 1 0 0\ns 1 2\n")  # wrong vertex count
    (tmp_path / "tri.seg").write_text("v 0 0 0\nv 1 0 0\nv 0 0 1\ns 1 2\ns 2 3\n")
    shapes = (ShapeSpec(mesh_dir / "cube1.msh", translation=(0, 3, 0)),
              ShapeSpec(tmp_path / "tri.seg", translation=(0, 1, 0), mesh_sequence=folder, line=5))
    model = build_model(SceneSpec(shapes=shapes))
    assert model.mesh_sequences[0].ext == "seg"
    assert "mesh sequence (1 shape)" in model.terms
    x = model.initial_positions
    sl = model.shape_vertices(1)
    for k in range(3):  # the step starting at t = k h goes to frame k
        mask, targets = kinematic_targets(model, x, k * 0.025, 0.025)
        assert mask[sl].all()
        assert np.allclose(targets[sl], base + [0.1 * k, 0, 0])
    with pytest.raises(MeshError, match="3 vertices|has 2 vertices") as info:
        kinematic_targets(model, x, 3 * 0.025, 0.025)
    assert info.value.line == 5 and "3.seg" in str(info.value)
    with pytest.raises(MeshError):
        kinematic_targets(model, x, 4 * 0.025, 0.025)  # frame 4 does not exist
    # adaptive steps cannot follow it (a frame per step of dt): refused at the shape's
    # line where the tolerance has none (set by --set)
    with pytest.raises(SceneError, match="cannot follow the mesh sequence of shape 2") as e:
        build_model(SceneSpec(shapes=shapes, time_tolerance=1e-3))
    assert e.value.line == 5


def test_nbc_accelerations(mesh_dir):
    lo, hi = (-0.1, -0.1, -0.1), (0.1, 1.1, 0.1)
    nbc = (NeumannSpec(lo, hi, (-5, 0, -5), (0.0, 1.0)),
           NeumannSpec((-0.1, -0.1, -0.1), (1.1, 0.1, 1.1), (0, 2, 0), (0.0, INF)))
    dbc = (DirichletSpec((-0.1, -0.1, -0.1), (0.1, 0.1, 0.1), time_range=(0.5, INF)),)
    shapes = (ShapeSpec(mesh_dir / "cube3.msh", nbc=nbc, dbc=dbc),)
    model = build_model(SceneSpec(shapes=shapes))
    a_set, b_set = model.nbc_sets
    acc = nbc_accelerations(model, 0.25)
    both = np.intersect1d(a_set.vertices, b_set.vertices)
    assert len(both) == 1  # the corner (0, 0, 0)
    assert np.allclose(acc[both], [-5, 2, -5])  # overlapping sets add up
    only_a = np.setdiff1d(a_set.vertices, b_set.vertices)
    assert np.allclose(acc[only_a], [-5, 0, -5])
    untouched = np.setdiff1d(np.arange(model.n_vertices), np.union1d(a_set.vertices, b_set.vertices))
    assert np.allclose(acc[untouched], 0)
    corner = model.dbc_sets[0].vertices
    assert np.allclose(nbc_accelerations(model, 0.75)[corner], 0)  # kinematic from t = 0.5
    assert np.allclose(nbc_accelerations(model, 1.0)[only_a], 0)  # window closed at t1 = 1
    gated = build_model(SceneSpec(shapes=shapes, nbc_time_range=(0.0, 0.2)))
    assert np.allclose(nbc_accelerations(gated, 0.25), 0)
