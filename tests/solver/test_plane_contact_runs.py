"""End-to-end solver checks on generated cubes: free fall against the discrete analytic
backward-Euler trajectory, and resting contact on a ground plane and a tilted half space."""

import numpy as np
import pytest
from generated import write_box_msh
from iterates import watch_iterates

from ipcsim.model.build import build_model
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

H = 0.02


@pytest.fixture(scope="module")
def cube_mesh(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mesh")
    return write_box_msh(folder / "cube.msh", base_y=-0.1)


def _simulation(tmp_path, cube_mesh, body: str, h: float = H) -> Simulation:
    scene = tmp_path / "scene.txt"
    scene.write_text(f"shapes input 1\n{cube_mesh} 0 0.3 0  0 0 0  1 1 1\n"
                     f"selfCollisionOff\nstiffness 1e5 0.4\ntime 5 {h}\n" + body)
    return Simulation(build_model(load_scene(scene)))


@pytest.mark.parametrize("h", [H, 0.001])
def test_free_fall_matches_discrete_backward_euler(tmp_path, cube_mesh, h):
    # at h = 0.001 the first step's whole motion, h²g, is below the Newton tolerance
    # tol·l·h: it must still be taken
    sim = _simulation(tmp_path, cube_mesh, "", h)
    x0 = sim.state.x.copy()
    n = 30
    for _ in range(n):
        report = sim.step()
        assert report.result.converged
    # v_{k+1} = v_k + h g,  x_{k+1} = x_k + h v_{k+1}  =>  x_n = x_0 + h² g n(n+1)/2
    expected = x0 + h * h * np.array([0.0, -9.80665, 0.0]) * n * (n + 1) / 2
    # relative to the size of the trajectory (coordinates that are exactly 0 stay ~1e-15)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(sim.state.x, expected, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(sim.state.v[:, 1], -9.80665 * n * h, rtol=1e-9)


def test_free_fall_with_newmark_is_exact_for_constant_acceleration(tmp_path, cube_mesh):
    # Newmark with γ = ½ integrates a constant acceleration exactly: x = x₀ + ½ g t²
    sim = _simulation(tmp_path, cube_mesh, "timeIntegration NM 0.25 0.5\n")
    x0 = sim.state.x.copy()
    n = 30
    for _ in range(n):
        assert sim.step().result.converged
    t = n * H
    expected = x0 + 0.5 * np.array([0.0, -9.80665, 0.0]) * t * t
    np.testing.assert_allclose(sim.state.x, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    np.testing.assert_allclose(sim.state.v[:, 1], -9.80665 * t, rtol=1e-9)


def _drop_and_rest(sim, signed_distance, normal, steps_to_rest=150, steps_at_rest=200):
    """Every Newton iterate stays strictly on the positive side; the body comes to rest
    along the normal with its lowest vertex within d̂ and stays there. (Without friction a
    spin about the normal, or a slide along the plane, may persist.)"""
    iterate_min = [np.inf]

    def seen(xi, evaluation):
        iterate_min[0] = min(iterate_min[0], signed_distance(xi).min())

    watch_iterates(sim, seen)
    for _ in range(steps_to_rest):
        sim.step()
    gaps = []
    for _ in range(steps_at_rest):
        report = sim.step()
        assert report.result.converged
        gaps.append(signed_distance(sim.state.x).min())
    assert iterate_min[0] > 0.0
    dhat = sim.model.dhat
    gaps = np.array(gaps)
    assert np.all(gaps > 0.0) and np.all(gaps < dhat)
    assert np.abs(sim.state.v @ normal).max() < 1e-3  # at rest along the normal


def test_cube_rests_on_the_ground(tmp_path, cube_mesh):
    sim = _simulation(tmp_path, cube_mesh, "ground 0 0\n")
    _drop_and_rest(sim, lambda x: x[:, 1], np.array([0.0, 1.0, 0.0]))
    assert np.abs(sim.state.v).max() < 1e-3  # dropped square: no spin, fully at rest


def test_cube_rests_on_a_tilted_half_space(tmp_path, cube_mesh):
    # Gravity replaced by an NBC acceleration along −n, so a frictionless body can rest.
    n = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    a = -9.80665 * n
    body = ("turnOffGravity\n"
            "halfSpace 0 0 0  1 2 0.5  50 0\n")
    scene_nbc = f" NBC -1 -1 -1  2 2 2  {a[0]} {a[1]} {a[2]}"
    scene = tmp_path / "scene.txt"
    scene.write_text(f"shapes input 1\n{cube_mesh} 0 0.4 0  10 20 30  1 1 1{scene_nbc}\n"
                     f"selfCollisionOff\nstiffness 1e5 0.4\ntime 5 {H}\n" + body)
    sim = Simulation(build_model(load_scene(scene)))
    # NBC applies to boundary vertices only (as the original); all cube vertices here are.
    _drop_and_rest(sim, lambda x: x @ n, n)


@pytest.mark.parametrize("option", [0, 1, 2, 3, 4, 5])
def test_every_warm_start_reaches_the_same_step(tmp_path, cube_mesh, option):
    """The warm start only changes where Newton starts, not where it ends."""
    sims = [_simulation(tmp_path, cube_mesh, f"warmStart {o}\ntol 1\n1e-8\n") for o in (0, option)]
    for sim in sims:
        for _ in range(3):
            assert sim.step().result.converged
    np.testing.assert_allclose(sims[1].state.x, sims[0].state.x, rtol=0, atol=1e-8)
