"""With adaptive steps the barrier stiffness κ is κ_max throughout (a κ adapted per step
would change the contact model with h, and the error estimate would compare different
models); a scene that fixes κ keeps its own; fixed steps adapt κ as before."""

from __future__ import annotations

import pytest
from generated import write_box_msh

from ipcsim.model.build import build_model
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation


@pytest.fixture
def stack(tmp_path):
    """A cube dropped off-centre onto another on the ground: plane and mesh contact
    within the first steps."""
    write_box_msh(tmp_path / "cube.msh")
    path = tmp_path / "stack.txt"
    path.write_text("shapes input 2\n"
                    "cube.msh 0 0.002 0  0 0 0  1 1 1\n"
                    "cube.msh 0.08 0.21 0  0 0 0  1 1 1\n"
                    "selfFric 0.2\nground 0.3 0\ntime 0.08 0.01\n")
    return path


def run(scene, **overrides) -> tuple[Simulation, list[dict]]:
    """The scene run to its end: the simulation and every attempted step's row."""
    spec = load_scene(scene, overrides=overrides)
    sim = Simulation(build_model(spec))
    rows = []
    while sim.state.step < spec.n_steps:
        rows.extend(sim.step().rows)
    return sim, rows


def test_with_adaptive_steps_kappa_is_kappa_max_throughout(stack):
    sim, rows = run(stack, **{"time.tolerance": 1e-3})
    kappa_max = sim.stiffness.kappa_max
    assert any(r["contacts_total"] > 0 for r in rows)
    assert any(not r["accepted"] for r in rows)  # rejected attempts too
    assert all(r["kappa"] == kappa_max for r in rows)
    assert sim.state.kappa == kappa_max


def test_with_adaptive_steps_a_scene_that_sets_kappa_keeps_its_own(stack):
    sim, rows = run(stack, **{"time.tolerance": 1e-2, "contact.kappa": 1e5})
    assert any(r["contacts_total"] > 0 for r in rows)
    assert all(r["kappa"] == 1e5 for r in rows)


def test_with_fixed_steps_kappa_still_adapts(stack):
    sim, rows = run(stack)
    assert rows[0]["kappa"] == sim.stiffness.kappa_min
    assert len({r["kappa"] for r in rows}) > 1
