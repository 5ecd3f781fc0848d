"""Friction end to end: a block sliding on the ground decelerates at μg (Coulomb), and a
frictional contact between two bodies in free space conserves linear momentum."""

from __future__ import annotations

import numpy as np
import pytest
from generated import write_box_msh

from ipcsim.model.build import build_model
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

G = 9.80665


@pytest.fixture(scope="module")
def block_mesh(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mesh")
    return write_box_msh(folder / "block.msh", cells=(2, 1, 2), size=(0.2, 0.1, 0.2))


@pytest.mark.parametrize("mu", [0.2, 0.5])
def test_sliding_block_decelerates_at_mu_g(tmp_path, block_mesh, mu):
    scene = tmp_path / "slide.txt"
    scene.write_text(f"shapes input 1\n{block_mesh} 0 0.0005 0  0 0 0  1 1 1  "
                     "initVel 2 0 0  0 0 0\n"
                     f"ground {mu} 0\nselfCollisionOff\nstiffness 1e7 0.3\ntime 1 0.005\n"
                     "tol 1\n1e-4\n")
    sim = Simulation(build_model(load_scene(scene)))
    assert sim.potential.term("friction") is not None
    for _ in range(20):  # settle into contact
        sim.step()
    times, speeds = [], []
    for _ in range(30):
        sim.step()
        times.append(sim.state.step * sim.h)
        speeds.append(sim.state.v[:, 0].mean())
    assert min(speeds) > 0.5  # still sliding: the kinetic regime
    decel = -np.polyfit(times, speeds, 1)[0]
    assert decel == pytest.approx(mu * G, rel=0.02)


def test_frictional_contact_in_free_space_conserves_momentum(tmp_path, block_mesh):
    """Two blocks, no gravity, no planes, the upper one grazing the lower one sideways
    with friction: internal forces only, so Σ m v stays constant."""
    scene = tmp_path / "free.txt"
    scene.write_text(f"shapes input 2\n{block_mesh} 0 0 0  0 0 0  1 1 1  initVel 0 0.5 0  0 0 0\n"
                     f"{block_mesh} 0.05 0.101 0.02  0 0 0  1 1 1  initVel 1 -0.5 0  0 0 0\n"
                     "turnOffGravity\nselfFric 0.4\nstiffness 1e6 0.3\ntime 1 0.01\n"
                     "tol 1\n1e-6\n")
    sim = Simulation(build_model(load_scene(scene)))
    mass = sim.model.mass
    p0 = (mass[:, None] * sim.state.v).sum(axis=0)
    frictional = 0
    for _ in range(30):
        row = sim.step().row
        frictional += row["friction_contacts"] > 0
        p = (mass[:, None] * sim.state.v).sum(axis=0)
        np.testing.assert_allclose(p, p0, rtol=0, atol=1e-8 * np.linalg.norm(p0))
    assert frictional > 0


SLOPE_NORMAL = np.array([1.0, 2.0, 0.0]) / np.sqrt(5.0)  # θ = atan(1/2) = 26.565°
SLOPE_DOWN = np.array([2.0, -1.0, 0.0]) / np.sqrt(5.0)


def _incline(tmp_path, block_mesh, mu):
    """A block resting on a half space tilted by θ (tan θ = 0.5), rotated to lie flat on it."""
    scene = tmp_path / "incline.txt"
    # the block's bottom face (y = 0 in file coordinates) rotated by −θ about z lies on
    # the plane through the origin with normal SLOPE_NORMAL, lifted 0.5 mm off it
    lift = 5e-4 * SLOPE_NORMAL
    scene.write_text(f"shapes input 1\n{block_mesh} {lift[0]} {lift[1]} 0  0 0 -26.565051177  1 1 1\n"
                     f"halfSpace 0 0 0  1 2 0  50 {mu}\nselfCollisionOff\nstiffness 1e7 0.3\n"
                     "time 2 0.01\n")
    return Simulation(build_model(load_scene(scene)))


@pytest.mark.parametrize("mu", [0.3, 0.45])
def test_block_slides_down_an_incline_at_g_sin_minus_mu_cos(tmp_path, block_mesh, mu):
    sim = _incline(tmp_path, block_mesh, mu)
    for _ in range(20):
        sim.step()
    times, speeds = [], []
    for _ in range(40):
        sim.step()
        times.append(sim.state.step * sim.h)
        speeds.append(sim.state.v.mean(axis=0) @ SLOPE_DOWN)
    accel = np.polyfit(times, speeds, 1)[0]
    sin, cos = 1 / np.sqrt(5), 2 / np.sqrt(5)
    assert accel == pytest.approx(G * (sin - mu * cos), rel=0.02)


def test_block_sticks_on_an_incline_when_mu_exceeds_tan_theta(tmp_path, block_mesh):
    """μ = 0.6 > tan θ = 0.5: once landed (the 0.5 mm drop gives it a little tangential
    speed, which friction stops within 0.3 s), the block slides in the next second no
    more than the smoothed friction's creep allows: ε_v·(1 s), ε_v = 1e-3·l m/s."""
    sim = _incline(tmp_path, block_mesh, 0.6)
    for _ in range(30):
        sim.step()
    x0 = sim.state.x.mean(axis=0)
    for _ in range(100):
        sim.step()
    slide = (sim.state.x.mean(axis=0) - x0) @ SLOPE_DOWN
    assert abs(slide) < sim.model.epsv * 1.0
