"""Friction end to end: a block sliding on the ground decelerates at μg (Coulomb), and a
frictional contact between two bodies in free space conserves linear momentum."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.model.builder import build_model
from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

G = 9.80665


@pytest.fixture(scope="module")
def block_mesh(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mesh")
    points, tets = box_tet_mesh(2, 1, 2, size=(0.2, 0.1, 0.2), origin=(-0.1, 0.0, -0.1))
    return write_msh(folder / "block.msh", points, tets)


@pytest.mark.parametrize("mu", [0.2, 0.5])
def test_sliding_block_decelerates_at_mu_g(tmp_path, block_mesh, mu):
    scene = tmp_path / "slide.txt"
    scene.write_text(f"shapes input 1\n{block_mesh} 0 0.0005 0  0 0 0  1 1 1  "
                     "initVel 2 0 0  0 0 0\n"
                     f"ground {mu} 0\nselfCollisionOff\nstiffness 1e7 0.3\ntime 1 0.005\n"
                     "tol 1\n1e-4\n")
    sim = Simulation(build_model(load_scene(scene)))
    assert sim.friction is not None
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
        row = sim.step()["step"]
        frictional += row["friction_contacts"] > 0
        p = (mass[:, None] * sim.state.v).sum(axis=0)
        np.testing.assert_allclose(p, p0, rtol=0, atol=1e-8 * np.linalg.norm(p0))
    assert frictional > 0
