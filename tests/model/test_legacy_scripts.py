"""Legacy `script` scenarios translated into DirichletSets, checked against loops written
the way the original's AnimScripter / findBorderVerts are."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scipy.spatial.transform import Rotation

from ipcsim.model.build import build_model
from ipcsim.model.kinematics import kinematic_targets, nbc_accelerations
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


# -- the scripts of the example tree beyond the ones above: each on a small scene of its own,
# its prescribed motion stepped as the original's AnimScripter steps it --------------------

SQUARE_OBJ = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 3 2\nf 1 4 3\n"  # a unit square, y = 0
EDGE_SEG = "v 0 0 0\nv 1 0 0\ns 1 2\n"


def _write(folder, name, text):
    path = folder / name
    path.write_text(text)
    return path


def _step_targets(model, x, k, h):
    """Kinematic vertices moved to their targets of step k (free ones left where they are)."""
    mask, target = kinematic_targets(model, x, k * h, h)
    return np.where(mask[:, None], target, x), mask


def test_hang_left_fixes_the_min_x_handle(mesh_dir):
    """varyResolution/bar-test: findBorderVerts' first handle (REST x within handleRatio of
    min x) is fixed; nothing else is kinematic."""
    scene = SceneSpec(shapes=(ShapeSpec(mesh_dir / "bar.msh"),
                              ShapeSpec(mesh_dir / "bar.msh", translation=(0.5, 2, 0))),
                      script="hangLeft", handle_ratio=0.05)
    model = build_model(scene)
    left, _ = _loop_twist(model.rest_positions, 0.05)
    (s,) = model.dbc_sets
    assert s.vertices.tolist() == left and len(left) == 4 and not s.moving
    x, mask = _step_targets(model, model.initial_positions + 0.01, 3, 0.1)
    assert mask.sum() == 4 and np.array_equal(x[left], model.initial_positions[left] + 0.01)


def _loop_stretch_and_pause(x0, h, n):
    """AnimScripter AST_STRETCHNPAUSE: the ends (1 % of the x range) move at ∓1 m/s while
    the last left vertex is at x >= -0.28 at the start of the step."""
    lo, hi = x0.min(axis=0), x0.max(axis=0)
    rng = hi - lo
    vel, turning = {}, None
    for i, p in enumerate(x0):
        if p[0] < lo[0] + rng[0] * 0.01:
            vel[i] = np.array([-1.0, 0, 0])
            turning = i  # turningPointAdded is never set: the last one wins
        elif p[0] > hi[0] - rng[0] * 0.01:
            vel[i] = np.array([1.0, 0, 0])
    x, path = x0.copy(), []
    for _ in range(n):
        if x[turning, 0] >= -0.28:
            for i, v in vel.items():
                x[i] = x[i] + v * h
        path.append(x.copy())
    return sorted(vel), path


def test_stretch_and_pause_moves_the_ends_then_holds_them(mesh_dir):
    """paperExamples/12_sphereOnMat: after size 1 the bar spans x in [0, 1]; the left end
    passes −0.28 m after 6 steps of 0.05 s and both ends stop."""
    h = 0.05
    model = build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "bar.msh"),),
                                  script="stretchAndPause", size=1.0, dt=h, duration=1.0))
    handles, path = _loop_stretch_and_pause(model.initial_positions, h, model.n_steps)
    x = model.initial_positions.copy()
    for k in range(model.n_steps):
        x, mask = _step_targets(model, x, k, h)
        assert np.flatnonzero(mask).tolist() == handles
        assert np.allclose(x[handles], path[k][handles], atol=1e-12), k
    moved = path[-1][handles[0], 0] - model.initial_positions[handles[0], 0]
    assert moved == pytest.approx(-6 * h)


def test_dragright_drags_until_the_body_has_passed_every_obstacle(mesh_dir):
    """paperExamples/13_dolphinFunnel: shifted up as `fall`; vertices within 4 % of the x
    range of the right end move at +0.5 m/s until min x of the scene exceeds the right-most
    meshCO vertex; then nothing is kinematic."""
    from ipcsim.scene.spec import MeshObstacleSpec

    ob = MeshObstacleSpec(mesh_dir / "tri.obj", position=(5.0, 0.0, 0.5), size=1.0)
    model = build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "bar.msh"),),
                                  mesh_obstacles=(ob,), script="dragright"))
    n_own = model.shape_offsets[1]
    rest = model.rest_positions[:n_own]
    lifted = rest + [0, 0.5 * np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)), 0]
    assert np.allclose(model.initial_positions[:n_own], lifted)
    lo, hi = lifted.min(axis=0), lifted.max(axis=0)
    right = [i for i in range(n_own) if lifted[i, 0] > hi[0] - (hi[0] - lo[0]) * 0.04]
    (s,) = model.dbc_sets
    assert s.vertices.tolist() == right and s.linear_velocity == (0.5, 0.0, 0.0)
    past = model.initial_positions[n_own:, 0].max()  # the obstacle's right-most vertex
    h = 0.1
    x, mask = _step_targets(model, model.initial_positions, 0, h)
    assert np.allclose(x[right] - model.initial_positions[right], [0.5 * h, 0, 0])
    assert np.flatnonzero(mask[:n_own]).tolist() == right
    for shift, dragged in ((past - lo[0] - 1e-9, True), (past - lo[0] + 1e-9, False)):
        y = model.initial_positions.copy()
        y[:n_own, 0] += shift
        _, mask = _step_targets(model, y, 5, h)
        assert mask[right].all() == dragged and not mask[:n_own][~np.isin(
            np.arange(n_own), right)].any()
    assert model.kinematic_mask_at(0.0)[right].all()


def _plate_scene(mesh_dir, script, extra_shapes, **kw):
    cube = ShapeSpec(mesh_dir / "cube1.msh", translation=(0, 0.1, 0), scale=(0.5, 0.5, 0.5))
    return build_model(SceneSpec(shapes=(*extra_shapes, cube), script=script, **kw))


def test_squeeze_out_presses_until_the_plate_is_low_enough(mesh_dir):
    """paperExamples/1_squeezeOut: shape 1 (codim) moves down at 0.3 m/s while its top is
    above min + 0.9/3.8 (max − min) of shape 2 (codim); shape 2 stays fixed."""
    box = _write(mesh_dir, "box.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
                                      "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    top = ShapeSpec(_write(mesh_dir, "plate.obj", SQUARE_OBJ), translation=(-2, -0.6, 0))
    bottom = ShapeSpec(box, translation=(-4, -1, 0), scale=(1, 1.2, 1))
    h = 0.05
    model = _plate_scene(mesh_dir, "DCOSqueezeOut", (top, bottom), dt=h, duration=2.0)
    x0 = model.initial_positions
    plate, base = np.arange(4), np.arange(4, 8)
    b_min, b_max = x0[base, 1].min(), x0[base, 1].max()
    x, pressed = x0.copy(), 0
    for k in range(model.n_steps):
        if x0[plate, 1].max() - 0.3 * h * pressed > b_min + (b_max - b_min) / 3.8 * 0.9:
            pressed += 1
        x, mask = _step_targets(model, x, k, h)
        assert mask[:8].all() and not mask[8:].any()
        assert np.allclose(x[plate], x0[plate] - [0, 0.3 * h * pressed, 0], atol=1e-12)
        assert np.array_equal(x[base], x0[base])
    # from y = −0.6 to below −1 + 1.2·0.9/3.8 = −0.716 m in steps of 0.3·0.05 m
    assert pressed == 8


def test_ball_hit_wall_throws_every_tet_vertex(mesh_dir):
    """paperExamples/19_golfBall (`script DCOBallHitWall 1 67`): v_x = 67 on every tet
    vertex, codim shapes fixed; without parameters v_x = 1000 m/s."""
    tri = ShapeSpec(mesh_dir / "tri.obj", translation=(3, 0, 0))
    model = _plate_scene(mesh_dir, "DCOBallHitWall", (tri,), script_params=(67.0,))
    v = model.initial_velocities
    assert np.array_equal(v[3:], np.tile([67.0, 0, 0], (8, 1))) and not v[:3].any()
    assert [s.vertices.tolist() for s in model.dbc_sets] == [[0, 1, 2]]
    default = _plate_scene(mesh_dir, "DCOBallHitWall", ())
    assert np.array_equal(default.initial_velocities, np.tile([1000.0, 0, 0], (8, 1)))


def test_squash6_walls_close_in_and_reverse(mesh_dir):
    """paperExamples/15_trashComp_*: walls 1–6 at ±1 m/s along x, y, z; all reverse at the
    first step that starts with wall 2's left side less than 0.1 m right of wall 1."""
    plate = _write(mesh_dir, "plate.obj", SQUARE_OBJ)
    walls = [ShapeSpec(plate, translation=t, rotation_deg=r) for t, r in [
        ((-0.3, -0.5, -0.5), (0, 0, 90)), ((0.3, -0.5, -0.5), (0, 0, 90)),
        ((-0.5, -0.3, -0.5), (0, 0, 0)), ((-0.5, 0.3, -0.5), (0, 0, 0)),
        ((-0.5, -0.5, -0.3), (90, 0, 0)), ((-0.5, -0.5, 0.3), (90, 0, 0))]]
    h = 0.05
    cube = ShapeSpec(mesh_dir / "cube1.msh", translation=(-0.1, -0.1, -0.1),
                     scale=(0.2, 0.2, 0.2))
    model = build_model(SceneSpec(shapes=(*walls, cube), script="DCOSquash6", dt=h,
                                  duration=0.5, gravity=False))
    x0 = model.initial_positions
    vel = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    want, x, flips = x0.copy(), x0.copy(), []
    for k in range(model.n_steps):
        if want[4:8, 0].min() - want[0:4, 0].max() < 0.1:  # AST_DCOSQUASH6
            vel = -vel
            flips.append(k)
        for w in range(6):
            want[4 * w:4 * w + 4] = want[4 * w:4 * w + 4] + vel[w] * h
        x, mask = _step_targets(model, x, k, h)
        assert mask[:24].all() and not mask[24:].any()
        assert np.allclose(x, want, atol=1e-12), k
    assert flips == [5]  # the gap 0.6 m shrinks by 0.1 m a step


def test_seg_bed_squash_lowers_the_upper_bed(mesh_dir):
    """paperExamples/17_pinCushionBall: codim shapes with index ≥ (s + 1) / 2 move down at
    1 m/s while their lowest point is more than 0.1 m above the other codim shapes."""
    seg = _write(mesh_dir, "edge.seg", EDGE_SEG)
    ball = ShapeSpec(mesh_dir / "cube1.msh", translation=(0, 0.1, 0), scale=(0.2, 0.2, 0.2))
    beds = [ShapeSpec(seg, translation=(0.0, y, z)) for y in (0.0, 0.65) for z in (0.0, 0.2)]
    h = 0.1
    model = build_model(SceneSpec(shapes=(ball, *beds), script="DCOSegBedSquash", dt=h,
                                  duration=1.0))
    x0 = model.initial_positions
    # five shapes: the codim ones with index ≥ (5 + 1) // 2 = 3 (the 4th and 5th) press
    upper = np.arange(model.shape_offsets[3], model.shape_offsets[5])
    lower = np.arange(model.shape_offsets[1], model.shape_offsets[3])
    x, want, steps = x0.copy(), x0.copy(), 0
    for k in range(model.n_steps):
        if want[upper, 1].min() - want[lower, 1].max() > 0.1:  # AST_DCOSEGBEDSQUASH
            want[upper] = want[upper] + [0, -1.0 * h, 0]
            steps += 1
        x, mask = _step_targets(model, x, k, h)
        assert mask[8:].all() and not mask[:8].any()
        assert np.allclose(x, want, atol=1e-12)
    assert steps == 6  # a 0.65 m gap, until it is 0.1 m or less


def test_verschoor_roller_spins_six_rollers(mesh_dir):
    """paperExamples/16_armaRoller_E1e5: rollers 1–6 rotate about their initial AABB
    centres at −4, −2, 2, 4 rad/s about z and 2, −2 rad/s about x."""
    rollers = [ShapeSpec(mesh_dir / "tri.obj", translation=(2 * k, 0, 0)) for k in range(6)]
    h = 0.05
    model = _plate_scene(mesh_dir, "DCOVerschoorRoller", rollers, dt=h, duration=0.25)
    x0 = model.initial_positions
    omega = [(0, 0, -4), (0, 0, -2), (0, 0, 2), (0, 0, 4), (2, 0, 0), (-2, 0, 0)]
    x = x0.copy()
    for k in range(model.n_steps):
        x, mask = _step_targets(model, x, k, h)
        assert mask[:18].all() and not mask[18:].any()
        for r, w in enumerate(omega):
            sl = slice(3 * r, 3 * r + 3)
            c = (x0[sl].min(axis=0) + x0[sl].max(axis=0)) / 2
            rot = Rotation.from_euler("XYZ", np.asarray(w, float) * h * (k + 1))
            assert np.allclose(x[sl], rot.apply(x0[sl] - c) + c, atol=1e-12)


def test_utopia_comparison_pushes_the_top_and_fixes_the_bottom(mesh_dir):
    """AST_UTOPIA_COMPARISON: vertices within 1e-4 of the *x* range of the top get an
    extra −1.5 m/s² along y (a Neumann set); those as close to the bottom are fixed."""
    model = build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "bar.msh"),),
                                  script="utopiaComparison"))
    x = model.initial_positions
    lo, hi = x.min(axis=0), x.max(axis=0)
    tol = (hi[0] - lo[0]) * 1e-4
    top = [i for i in range(len(x)) if x[i, 1] > hi[1] - tol]
    bottom = [i for i in range(len(x)) if i not in top and x[i, 1] < lo[1] + tol]
    (fixed,) = model.dbc_sets
    (push,) = model.nbc_sets
    assert fixed.vertices.tolist() == bottom and not fixed.moving and len(bottom) == 10
    assert push.vertices.tolist() == top and push.acceleration == (0.0, -1.5, 0.0)
    acc = nbc_accelerations(model, 0.0)
    assert np.array_equal(acc[top], np.tile([0, -1.5, 0], (len(top), 1)))
