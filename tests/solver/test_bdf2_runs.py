"""BDF2 and adaptive steps in the time step, on the contact-free spinning bar
(input/spinning_bar.txt: inertia and elasticity alone): BDF2 is second order and BE
first, an adaptive run meets its tolerance against a fine reference and lands on the
scene's clock, and a run whose energy grows with no work done on it stops."""

from __future__ import annotations

import math
from pathlib import Path

from msgspec.structs import replace
import numpy as np
import pytest

from ipcsim.errors import SolverError
from ipcsim.model.build import build_model
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation
from ipcsim.solver.energy_growth import GROWTH_LIMIT, EnergyGrowth

BAR = Path(__file__).parents[2] / "input" / "spinning_bar.txt"


def simulate(**overrides) -> tuple[Simulation, list[np.ndarray], list[dict]]:
    """The bar run to its end: the simulation, the positions at every step of dt (the
    start included) and every attempted step's steps.csv row."""
    spec = load_scene(BAR, overrides=overrides)
    sim = Simulation(build_model(spec))
    frames, rows = [sim.state.x], []
    while sim.state.step < spec.n_steps:
        report = sim.step()
        rows.extend(report.rows)
        frames.append(sim.state.x)
    return sim, frames, rows


def rms_error(frames, reference, every: int, size: float) -> float:
    """Position RMS over the frames and vertices, relative to the scene size."""
    a, b = np.array(frames), np.array(reference[::every])
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=2)))) / size


@pytest.fixture(scope="module")
def reference():
    """BDF2 at dt / 32 over 0.2 s: the converged motion (its own error at dt / 16 is
    below a sixtieth of the smallest error compared with it)."""
    sim, frames, _ = simulate(**{"integrator.type": "BDF2", "time.dt": 0.02 / 32,
                                 "time.duration": 0.2})
    return frames, sim.model.bbox_diagonal


def test_bdf2_is_second_order_and_be_first(reference):
    frames_ref, size = reference
    for integrator, low, high in (("BDF2", 1.8, 2.2), ("BE", 0.8, 1.2)):
        errors = []
        for k in (1, 2, 4):
            _, frames, _ = simulate(**{"integrator.type": integrator, "time.dt": 0.02 / k,
                                       "time.duration": 0.2})
            errors.append(rms_error(frames[::k], frames_ref, 32, size))
        orders = [math.log2(e0 / e1) for e0, e1 in zip(errors, errors[1:])]
        assert low < orders[-1] < high, (integrator, errors, orders)


@pytest.mark.parametrize("integrator, tolerance", [("BDF2", 1e-2), ("BDF2", 1e-3),
                                                   ("BE", 1e-2)])
def test_an_adaptive_run_meets_its_tolerance_and_lands_on_the_clock(reference, integrator,
                                                                    tolerance):
    frames_ref, size = reference
    sim, frames, rows = simulate(**{"integrator.type": integrator, "time.dt": 0.02,
                                    "time.duration": 0.2, "time.tolerance": tolerance})
    assert rms_error(frames, frames_ref, 32, size) <= 3 * tolerance
    dt = sim.model.dt
    accepted = [r for r in rows if r["accepted"]]
    # dt the largest (a landing step to round-off)
    assert len(accepted) > 10 and all(r["dt"] <= dt * (1 + 1e-12) for r in rows)
    # the last attempt of each step of dt ends exactly on its time, accepted
    last = {r["step"]: r for r in rows}
    assert all(r["accepted"] and r["time"] == k * dt for k, r in last.items())
    assert sim.state.time == 10 * dt and sim.state.step == 10
    # the accepted steps' lengths add up to the time; their errors are within the allowed
    assert math.fsum(r["dt"] for r in accepted) == pytest.approx(0.2, rel=1e-12)
    control = sim.control
    assert all(r["error_estimate"] <= control.allowed(r["dt"]) for r in accepted)
    rejected = [r for r in rows if not r["accepted"]]
    assert sim.state.rejected == len(rejected)
    assert all(r["error_estimate"] > control.allowed(r["dt"]) or not r["converged"]
               for r in rejected)


def test_a_rejected_step_is_tried_again_shorter():
    """Started at a dt far above what the tolerance allows, the first attempts are
    rejected, each retried at a shorter step, and recorded."""
    sim, _, rows = simulate(**{"integrator.type": "BDF2", "time.dt": 0.1,
                               "time.duration": 0.2, "time.tolerance": 1e-4})
    first = [r for r in rows if r["step"] == 1]
    assert not first[0]["accepted"] and first[0]["dt"] == 0.1
    retried = [(r, after) for r, after in zip(rows, rows[1:]) if not r["accepted"]]
    assert retried and all(after["dt"] < r["dt"] and after["time"] < r["time"]
                           for r, after in retried)
    assert sim.state.rejected == len(retried)


def test_fixed_steps_have_an_error_estimate_and_are_all_accepted():
    _, _, rows = simulate(**{"integrator.type": "BDF2", "time.duration": 0.1})
    assert all(r["accepted"] == 1 and r["error_estimate"] > 0 for r in rows)
    _, _, rows = simulate(**{"integrator.type": "NM", "time.duration": 0.05})
    assert all(r["accepted"] == 1 and r["error_estimate"] is None for r in rows)


def test_energy_growth_with_no_work_done_stops_the_run():
    """The bar's energy made 10⁴ times the start's (its velocities ×100), as a Newmark
    blow-up makes it: the next step stops with the integrator, h and the ratio named."""
    spec = load_scene(BAR, overrides={"integrator.type": "NM"})
    sim = Simulation(build_model(spec))
    sim.step()
    sim.state = replace(sim.state, v=100.0 * sim.state.v)
    with pytest.raises(SolverError) as err:
        sim.step()
    message = str(err.value)
    assert message.startswith("step 2: the total energy grew ")
    ratio = float(message.split("grew ")[1].split("-fold")[0])
    assert ratio > GROWTH_LIMIT
    assert "the NM integrator is unstable at h = 0.025 s" in message
    assert sim.outcome == "Blow-up"


def test_the_energy_watch_measures_gravitys_work_and_skips_driven_scenes():
    spec = load_scene(BAR, overrides={"integrator.type": "NM"})
    model = build_model(spec)
    x, v = model.initial_positions, model.initial_velocities
    watch = EnergyGrowth(np.asarray(model.mass), np.array([0.0, -9.8, 0.0]), x, 1.0)
    fallen = x - np.array([0.0, 1.0, 0.0])
    # a fall of 1 m at rest turns m g (1 m) of potential energy into nothing else: E drops
    assert watch.energy(fallen, 0 * v, 0.0) == pytest.approx(-9.8 * model.mass.sum())
    assert watch.check(x, 100.0 * v, 0.0) is not None
    assert watch.check(x, v, 0.0) is None
    assert EnergyGrowth.of(model, x, v, 0.0) is not None
    from ipcsim.model.model import NeumannSet

    pushed = replace(model, nbc_sets=(NeumannSet(np.arange(3), (1.0, 0.0, 0.0)),))
    assert EnergyGrowth.of(pushed, x, v, 0.0) is None


def test_a_step_over_the_newton_budget_is_tried_again_shorter():
    """With adaptive steps a Newton solve stops at the controller's iteration budget
    (a CCD crawl ends there, not at the scene's cap); the step is tried at a quarter."""
    spec = load_scene(BAR, overrides={"integrator.type": "BDF2", "time.dt": 0.1,
                                      "time.duration": 0.2, "time.tolerance": 1e-1})
    sim = Simulation(build_model(spec))
    sim.control = replace(sim.control, iteration_budget=2)
    rows = []
    while sim.state.step < spec.n_steps:
        rows.extend(sim.step().rows)
    stalled = [(r, after) for r, after in zip(rows, rows[1:]) if not r["converged"]]
    assert stalled
    for r, after in stalled:
        assert r["newton_iterations"] == 2 and r["hit_iteration_cap"] and not r["accepted"]
        assert after["dt"] <= 0.25 * r["dt"] * (1 + 1e-12)
    assert all(r["newton_iterations"] <= 2 for r in rows)


def test_a_step_that_cannot_meet_the_tolerance_fails_and_logs_its_attempts(tmp_path,
                                                                          monkeypatch):
    """A step that shrinks below h_min stops the run (exit 3) with the time and the cause;
    steps.csv and newton.csv keep every attempt of that step, after the completed ones."""
    import csv

    from ipcsim.errors import RunFailed
    from ipcsim.runner import run
    from ipcsim.solver import step_size

    overrides = {"integrator.type": "BDF2", "time.duration": 0.1, "time.tolerance": 1e-6}
    sim = Simulation(build_model(load_scene(BAR, overrides=overrides)))
    sim.control = replace(sim.control, h_min_ratio=0.5)  # the first step's h only
    with pytest.raises(SolverError, match=r"^step 1: at t = 0 s the adaptive step fell "
                       r"below 0\.0125 s \(the error estimate [0-9.e-]+ stayed above the "
                       r"[0-9.e-]+ allowed, of l\); raise the time tolerance$") as failed:
        sim.step()  # BE's first step at dt, rejected; 0.2 dt would be below h_min
    (row,) = failed.value.attempts
    assert row["accepted"] == 0 and row["dt"] == 0.025 and failed.value.newton
    monkeypatch.setattr(step_size.StepSizeControl, "h_min",
                        property(lambda self: 0.5 * self.h_max))
    with pytest.raises(RunFailed, match="steps.csv ends with its 1 attempt"):
        run(load_scene(BAR, overrides=overrides), tmp_path / "out")
    with open(tmp_path / "out" / "steps.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["step"], r["accepted"], float(r["dt"])) for r in rows] == [("1", "0", 0.025)]
    assert float(rows[0]["error_estimate"]) > 1e-6 * 0.025 / 0.1
    with open(tmp_path / "out" / "newton.csv", newline="") as f:
        assert {r["step"] for r in csv.DictReader(f)} == {"1"}
    with pytest.raises(RunFailed):  # resumed, it fails again: the old attempt is dropped
        run(load_scene(BAR, overrides=overrides), tmp_path / "out", mode="resume")
    with open(tmp_path / "out" / "steps.csv", newline="") as f:
        assert len(list(csv.DictReader(f))) == 1


def test_a_fast_impact_goes_through_with_adaptive_steps():
    """A cube thrown at the ground at 20 m/s closes in to nanometres before the barrier
    stops it, and reverses its velocity faster than any step resolves; it goes through on
    steps shorter than h_floor that make the floor's error (before, at τ = 1e-3, the step
    fell below h_min and the run failed), and the ground stops the cube without being touched."""
    spec = load_scene(Path(__file__).parents[2] / "input" / "cube_drop.toml", overrides={
        "integrator.type": "BDF2", "time.tolerance": 1e-3, "time.duration": 0.05,
        "shapes.0.init_velocity": {"linear": [0.0, -20.0, 0.0]}})
    sim = Simulation(build_model(spec))
    rows = []
    while sim.state.step < spec.n_steps:
        rows.extend(sim.step().rows)
    control = sim.control
    h_floor = control.h_floor
    floored = [r for r in rows if r["accepted"] and r["dt"] < h_floor
               and r["error_estimate"] > control.tolerance * r["dt"] / control.duration]
    assert floored
    assert all(r["error_estimate"] <= control.allowed(r["dt"]) for r in rows if r["accepted"])
    assert min(r["min_distance"] for r in rows if r["accepted"]) > 0.0
    assert np.mean(sim.state.v[:, 1]) > -10.0  # the ground took most of its momentum
