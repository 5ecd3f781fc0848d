"""Adaptive steps in 2D: a bar spinning in the plane (no gravity, no contact: inertia and
elasticity alone) run with a time tolerance meets it against a fine fixed-step run, and
its steps land on the scene's clock, as the 3D bar's do (test_bdf2_runs.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ipcsim.model.build import build_model
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

BAR_2D = ("[scene]\ndimension = 2\ngravity = false\n[time]\ndt = 0.02\nduration = 0.2\n"
          '[material]\ndensity = 1000\nyoungs_modulus = 1e5\npoisson_ratio = 0.4\n'
          'energy = "NH"\n[[shapes]]\nkind = "rectangle"\nsize = [1.0, 0.2]\n'
          "resolution = [8, 2]\ninit_velocity = { linear = [0.0, 0.0], angular_deg = 360 }\n")


def simulate(path, **overrides) -> tuple[Simulation, np.ndarray, list[dict]]:
    """The bar run to its end: the simulation, its positions at every step of dt (the
    start included) and every attempted step's steps.csv row."""
    spec = load_scene(path, overrides=overrides)
    sim = Simulation(build_model(spec))
    frames, rows = [sim.state.x], []
    while sim.state.step < spec.n_steps:
        rows.extend(sim.step().rows)
        frames.append(sim.state.x)
    return sim, np.array(frames), rows


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    path = tmp_path_factory.mktemp("bar2d") / "bar.toml"
    path.write_text(BAR_2D)
    sim, frames, _ = simulate(path, **{"integrator.type": "BDF2", "time.dt": 0.02 / 32})
    return path, frames[::32], sim.model.bbox_diagonal


@pytest.mark.parametrize("integrator, tolerance", [("BDF2", 1e-2), ("BDF2", 1e-3)])
def test_an_adaptive_2d_run_meets_its_tolerance_on_the_clock(bar, integrator, tolerance):
    path, reference, size = bar
    sim, frames, rows = simulate(path, **{"integrator.type": integrator,
                                          "time.tolerance": tolerance})
    assert sim.model.dimension == 2 and sim.control is not None
    assert np.all(frames[..., 2] == 0.0)  # the plane z = 0
    error = float(np.sqrt(np.mean(np.sum((frames - reference) ** 2, axis=2)))) / size
    # the bar turns a fifth of a revolution and stretches: a real motion, met within 3τ
    assert np.abs(frames[-1] - frames[0]).max() > 0.2 and error <= 3 * tolerance
    accepted = [r for r in rows if r["accepted"]]
    assert len(accepted) > 10 and all(r["dt"] <= 0.02 * (1 + 1e-12) for r in rows)
    last = {r["step"]: r for r in rows}
    assert all(r["accepted"] and r["time"] == k * 0.02 for k, r in last.items())
    assert math.fsum(r["dt"] for r in accepted) == pytest.approx(0.2, rel=1e-12)
    assert all(r["error_estimate"] <= sim.control.allowed(r["dt"]) for r in accepted)
