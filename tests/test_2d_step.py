"""The 2D time step: the 2D kinds of the all-terms kernels against finite differences,
the lecture's half-plane barrier, moving lines, the initial check, and the lessons'
physics (the lesson-3 square at rest on the ground, the lesson-4 slide against the
analytic Coulomb deceleration)."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.contact.collisions import build_collisions
from ipcsim.errors import InfeasibleStartError
from ipcsim.kernels.contact import line_barrier as kl
from ipcsim.kernels.terms import all_terms as kt
from ipcsim.model.build import build_model
from ipcsim.model.kinematics import moving_plane_origins
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

DHAT = 0.01
LECTURE = ('[contact]\nbarrier = "lecture"\nkappa = 1e5\ndhat_abs = 0.01\nepsv_abs = 1e-3\n'
           "friction_iterations = 1\nuse_abs_parameters = true\n")


def scene_text(body: str, contact: str = LECTURE, dt: float = 0.01,
               duration: float = 1.0) -> str:
    return ("[scene]\ndimension = 2\ngravity_acceleration = [0.0, -9.81]\n"
            f"[time]\ndt = {dt}\nduration = {duration}\n[solver]\nnewton_tol = 1e-4\n"
            '[material]\ndensity = 1000\nnode_masses = "uniform"\nyoungs_modulus = 1e5\n'
            'poisson_ratio = 0.4\nenergy = "NH"\n' + contact + body)


def simulation(tmp_path, text: str) -> Simulation:
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return Simulation(build_model(load_scene(path)))


SQUARE = ('[[shapes]]\nkind = "rectangle"\nsize = [1.0, 1.0]\nresolution = [4, 4]\n'
          "{extra}")
GROUND = '[[planes]]\nkind = "halfSpace"\norigin = [0.0, {y}]\nnormal = [0.0, 1.0]\n'


def fd_gradient(f, x, h=1e-7):
    g = np.zeros(x.size)
    for i in range(x.size):
        if i % 3 == 2:
            continue  # z: nothing acts along it
        e = np.zeros(x.size)
        e[i] = h
        g[i] = (f((x.reshape(-1) + e).reshape(x.shape))
                - f((x.reshape(-1) - e).reshape(x.shape))) / (2 * h)
    return g


IPC = '[contact]\nkappa = 1e5\ndhat_abs = 0.01\nuse_abs_parameters = true\n'


@pytest.mark.parametrize("contact", [LECTURE, IPC])
def test_every_2d_kind_gradient_matches_finite_differences(tmp_path, contact):
    # two squares, one of triangles and one of springs, the second close under the first
    # and both close to the ground: every 2D kind is active
    text = scene_text(SQUARE.format(extra="") + SQUARE.format(
        extra="spring_stiffness = 2e4\ntranslation = [0.2, -1.006]\n")
        + GROUND.format(y=-1.512), contact)
    sim = simulation(tmp_path, text)
    rng = np.random.default_rng(4)
    x = sim.state.x.copy()
    x[:, :2] += rng.uniform(-1e-3, 1e-3, (len(x), 2))
    problem, start = sim.problem(sim.state)
    point = problem.at(start.__class__(x))
    k = problem.potential.kernel
    pairs = k.pairs(point.collisions, DHAT)
    assert pairs[3] and len(pairs[0]) > 0
    values = kt.term_values(x, k.present, problem.data, pairs)
    kinds = (kt.TRIANGLES, kt.SPRINGS, kt.POINT_EDGE,
             kt.LINE_LECTURE if contact == LECTURE else kt.PLANE_CONTACT)
    assert all(k.present[kind] and values[kind] > 0 for kind in kinds)
    gradients = kt.term_gradients(x, k.present, problem.data, pairs)
    for kind in kinds:
        fd = fd_gradient(lambda y, kind=kind: kt.term_values(y, k.present, problem.data,
                                                               pairs)[kind], x)
        scale = np.abs(gradients[kind]).max()
        np.testing.assert_allclose(gradients[kind], fd, atol=1e-5 * scale)


def test_lecture_line_barrier_hessian_matches_finite_differences():
    x = np.array([[0.0, 0.004, 0.0], [0.3, 0.0075, 0.0], [0.1, 0.5, 0.0]])
    args = (np.arange(3, dtype=np.int64), np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]),
            DHAT, np.array([0.5, 0.25, 1.0]) * DHAT / 2)
    rows, cols, vals = kl.line_barrier_hessian(x, *args)
    H = np.zeros((9, 9))
    np.add.at(H, (rows, cols), vals)
    fd = np.stack([fd_gradient(lambda y, i=i: kl.line_barrier_gradient(y, *args)[i], x, 1e-9)
                   for i in range(9)])
    np.testing.assert_allclose(H, fd, atol=1e-5 * np.abs(H).max())
    # the lecture's own formula: A d̂ κ/2 (d/d̂ − 1) ln(d/d̂) at unit κ, pairs within d̂
    d = np.array([0.004, 0.0075])
    expected = np.sum(args[4][:2] * (d / DHAT - 1) * np.log(d / DHAT))
    assert kl.line_barrier_value(x, *args) == pytest.approx(expected, rel=1e-14)


def test_moving_line_stops_at_its_limit():
    o = moving_plane_origins([[0, 0.6, 0]], [[0, -0.5, 0]], [[0, -0.6, 0]], 0.01, 1000)
    np.testing.assert_allclose(o, [[0, -0.6, 0]], atol=1e-12)
    steps = [moving_plane_origins([[0, 0.6, 0]], [[0, -0.5, 0]], [[0, -0.6, 0]], 0.01, k)[0, 1]
             for k in (0, 1, 10)]
    np.testing.assert_allclose(steps, [0.6, 0.595, 0.55])
    assert moving_plane_origins([[0, 1, 0]], [[0, 0, 0]], [[np.nan] * 3], 0.01, 5) is None


@pytest.mark.parametrize("body, message", [
    (SQUARE.format(extra="") + SQUARE.format(extra="translation = [0.5, 0.5]\n"),
     "cross or touch"),
    (SQUARE.format(extra="") + GROUND.format(y=-0.5), "on or below a plane"),
])
def test_an_intersecting_start_is_refused(tmp_path, body, message):
    with pytest.raises(InfeasibleStartError, match=message):
        simulation(tmp_path, scene_text(body))


def test_lesson_3_square_comes_to_rest_within_dhat_of_the_ground(tmp_path):
    sim = simulation(tmp_path, scene_text(
        SQUARE.format(extra="spring_stiffness = 2e4\n") + GROUND.format(y=-1.0)))
    lowest, height = [], []
    for _ in range(300):
        sim.step()
        lowest.append(sim.state.x[:, 1].min() + 1.0)
        height.append(sim.state.x[:, 1].mean() + 1.0)
    lowest = np.array(lowest[-100:])  # the last second: on the ground, within d̂ of it
    assert np.all(lowest > 0.0) and np.all(lowest < DHAT)
    # resting on it: the centre half a side up, the undamped springs still ringing a little
    assert np.all(np.abs(np.array(height[-100:]) - 0.5) < 0.05)


def test_lesson_4_slide_decelerates_as_coulomb_friction(tmp_path):
    # the lesson's slope and μ; the square set flat on it with a gap and pushed down it
    normal = np.array([0.1, 1.0]) / np.sqrt(1.01)
    down = np.array([normal[1], -normal[0]])
    centre = np.array([0.0, -1.0]) + (0.5 + 0.0093) * normal  # about where the barrier holds it
    angle = -np.degrees(np.arctan(0.1))
    v0 = 1.0 * down
    c, v0, angle = centre.tolist(), v0.tolist(), float(angle)
    extra = (f"spring_stiffness = 2e4\ntranslation = [{c[0]!r}, {c[1]!r}]\n"
             f"rotation_deg = {angle!r}\n"
             f"init_velocity = {{ linear = [{v0[0]!r}, {v0[1]!r}], angular_deg = 0 }}\n")
    plane = ('[[planes]]\nkind = "halfSpace"\norigin = [0.0, -1.0]\nnormal = [0.1, 1.0]\n'
             "friction = 0.11\n")
    sim = simulation(tmp_path, scene_text(SQUARE.format(extra=extra) + plane, duration=4.0))
    times, speeds = [], []
    for _ in range(400):
        sim.step()
        times.append(sim.state.time)
        speeds.append(sim.state.v[:, :2].mean(axis=0) @ down)  # uniform masses: the CoM's
    times, speeds = np.array(times), np.array(speeds)
    # the undamped springs ring across the slope, and the friction with the normal force:
    # the deceleration is their mean, over the many periods after the first half second
    late = times >= 0.5
    slope = np.polyfit(times[late], speeds[late], 1)[0]
    g, cos, tan = 9.81, normal[1], 0.1
    analytic = -g * cos * (0.11 - tan)  # a = g (sin θ − μ cos θ)
    assert slope == pytest.approx(analytic, rel=0.01)


def test_point_edge_collision_set_finds_the_close_pair(tmp_path):
    sim = simulation(tmp_path, scene_text(SQUARE.format(extra="") + SQUARE.format(
        extra="translation = [0.2, -1.005]\n")))
    c = build_collisions(sim.contact.mesh, sim.state.x, DHAT)
    assert c.pt.shape[1] == 3 and c.count(DHAT).point_triangle > 0
    assert c.count(DHAT).min_distance == pytest.approx(0.005, rel=1e-9)
