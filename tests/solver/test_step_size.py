"""The step-size controller and the landing on output times; and the two together with
BDF2's error estimate on a spring, where the global error must follow τ."""

from __future__ import annotations

import math

import numpy as np
import pytest
from spring import K, exact, spring_step

from ipcsim.solver.integrator import BDF2, error_norm
from ipcsim.solver.step_size import StepSizeControl, landing_step


def test_judge_accepts_within_the_allowed_error_and_limits_the_change():
    control = StepSizeControl(tolerance=1e-3, duration=2.0, h_max=0.05)
    h = 0.01
    allowed = control.allowed(h)
    assert allowed == pytest.approx(1e-3 * h / 2.0)
    ok, nxt = control.judge(h, allowed, order=2)
    assert ok and nxt == pytest.approx(0.9 * h)
    ok, nxt = control.judge(h, allowed / 1e6, order=2)
    assert ok and nxt == pytest.approx(2.0 * h)  # growth capped
    ok, nxt = control.judge(h, 0.0, order=2)
    assert ok and nxt == pytest.approx(2.0 * h)
    ok, nxt = control.judge(h, allowed * 4.0, order=2)
    assert not ok and nxt == pytest.approx(0.9 * h / 2.0)
    ok, nxt = control.judge(h, allowed * 1e6, order=1)
    assert not ok and nxt == pytest.approx(0.2 * h)  # shrink capped
    ok, nxt = control.judge(h, allowed / 1e6, order=2, after_rejection=True)
    assert ok and nxt == pytest.approx(h)  # no growth right after a rejection
    ok, nxt = control.judge(0.04, 0.0, order=2)
    assert nxt == 0.05  # never above the scene's dt
    assert control.stalled(h) == pytest.approx(0.25 * h)


def test_a_step_shorter_than_the_floor_may_make_the_floors_error():
    """Below h_floor the allowed error stops shrinking with h: across an impact the
    estimate is about h·Δv, and a step shorter than h_floor is accepted once within
    τ·h_floor/T, where error per unit step would reject every h."""
    control = StepSizeControl(tolerance=1e-3, duration=2.0, h_max=0.05)
    h_floor = control.h_floor
    assert control.h_min < h_floor < control.h_max
    assert control.allowed(h_floor / 10) == control.allowed(h_floor) == 1e-3 * h_floor / 2.0
    assert control.allowed(2 * h_floor) == pytest.approx(1e-3 * 2 * h_floor / 2.0)
    # err = 3·τh/T at every h (a velocity reversed within the step): h shrinks until the
    # floor takes it, above h_min
    h, accepted = control.h_max, False
    while not accepted:
        assert h >= control.h_min
        accepted, h_next = control.judge(h, 3 * 1e-3 * h / 2.0, order=2)
        h = h if accepted else h_next
    assert h_floor / 15 < h <= h_floor / 3  # one shrink of at most 0.2 took it below


def test_steps_land_on_output_times():
    assert landing_step(0.0, 0.03, 0.1) == pytest.approx(0.025)
    assert landing_step(0.09, 0.025, 0.1) == pytest.approx(0.01)
    assert landing_step(0.0, 0.025, 0.1) == pytest.approx(0.025)  # 4 whole steps
    t, steps = 0.0, 0
    while t < 0.1:
        t += landing_step(t, 0.03, 0.1)
        steps += 1
    assert steps == 4 and t == pytest.approx(0.1, abs=1e-15)
    with pytest.raises(ValueError):
        landing_step(0.1, 0.01, 0.1)


def adaptive_spring(tau: float, duration=2.0, h_max=0.05, every=0.05):
    """The spring under BDF2 with adaptive steps that land on the output times; the RMS
    error over the output times (relative to the amplitude, the scene size here) and the
    steps taken."""
    control = StepSizeControl(tau, duration, h_max)
    x, v = exact(0.0)
    a, t, h, history, rejected = -K * x, 0.0, h_max, None, False
    errors, steps = [], 0
    for t_out in every * np.arange(1, round(duration / every) + 1):
        while t < t_out:
            h_try = landing_step(t, h, t_out)
            integrator = BDF2(h_try, history)
            x_new, v_new, a_new = spring_step(integrator, x, v, a)
            error = error_norm(integrator.local_error(x_new, x, v), 1.0)
            ok, h = control.judge(h_try, error, 1 if history is None else 2, rejected)
            rejected = not ok
            if ok:
                history, (x, v, a) = integrator.after(x, v), (x_new, v_new, a_new)
                t = t_out if math.isclose(t + h_try, t_out) else t + h_try
                steps += 1
        errors.append(float(np.linalg.norm(x - exact(t_out)[0])))
    return math.sqrt(np.mean(np.square(errors))), steps


def test_the_global_error_follows_the_tolerance():
    """Error per unit step: the RMS error over the run stays within 3τ, and shrinks with
    τ (about in proportion, where error per step would not)."""
    results = {tau: adaptive_spring(tau) for tau in (1e-2, 1e-3, 1e-4)}
    for tau, (error, _) in results.items():
        assert error <= 3 * tau, (tau, error)
    assert results[1e-4][0] < results[1e-2][0] / 20
    assert results[1e-4][1] > results[1e-3][1] > results[1e-2][1]
