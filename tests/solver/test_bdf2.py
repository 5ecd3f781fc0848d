"""BDF2 on its own: a linear spring (the incremental potential minimised exactly), free
fall, prescribed motion, the BE first step, and the local error estimate."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from spring import K, exact, spring_step

from ipcsim.model.model import TimeSettings
from ipcsim.potentials.damping import Damping
from ipcsim.solver.integrator import (
    BDF2,
    BackwardEuler,
    Newmark,
    StepHistory,
    bdf2_coefficients,
    damping_scale,
    error_norm,
    make_integrator,
)

G = np.array([[0.0, -9.80665, 0.0]])


def run(make, steps: list[float]) -> np.ndarray:
    """The spring over the given step lengths from t = 0; the final position."""
    x, v = exact(0.0)
    a, history = -K * x, None
    for h in steps:
        integrator = make(h, history)
        x_new, v_new, a = spring_step(integrator, x, v, a)
        history = integrator.after(x, v)
        x, v = x_new, v_new
    return x


def observed_orders(make, pattern: tuple[float, ...], period_steps: list[int]) -> list[float]:
    """log2 of the error ratios at t = 1 as the steps (``pattern`` repeated, scaled to
    fill the period) halve."""
    errors = []
    for n in period_steps:
        unit = 1.0 / (n * sum(pattern))
        steps = [p * unit for _ in range(n) for p in pattern]
        errors.append(float(np.abs(run(make, steps) - exact(1.0)[0]).max()))
    return [math.log2(e0 / e1) for e0, e1 in itertools.pairwise(errors)]


def test_bdf2_is_second_order_and_be_first_on_the_spring():
    bdf2 = observed_orders(BDF2, (1.0,), [100, 200, 400, 800])
    be = observed_orders(lambda h, hist: BackwardEuler(h), (1.0,), [100, 200, 400, 800])
    assert all(1.9 < p < 2.1 for p in bdf2), bdf2
    assert all(0.9 < p < 1.1 for p in be), be


def test_bdf2_with_variable_steps_is_second_order_too():
    """Steps alternating h and 0.6h (ω = 0.6 and 1/0.6), all halved together."""
    orders = observed_orders(BDF2, (1.0, 0.6), [60, 120, 240, 480])
    assert all(1.85 < p < 2.15 for p in orders), orders


def test_the_coefficients_at_constant_steps_and_the_prediction():
    c1, c2, beta = bdf2_coefficients(0.01, 0.01)
    assert (c1, c2, beta) == pytest.approx((4 / 3, -1 / 3, 2 / 3), rel=1e-15)
    for omega in (0.3, 1.0, 2.2):
        c1, c2, beta = bdf2_coefficients(omega * 0.01, 0.01)
        assert c1 + c2 == pytest.approx(1.0, rel=1e-15)
    rng = np.random.default_rng(1)
    x, v, xp, vp = rng.normal(size=(4, 5, 3))
    h = 0.02
    integrator = BDF2(h, StepHistory(xp, vp, h))
    np.testing.assert_allclose(
        integrator.predict(x, v, None),
        4 / 3 * x - 1 / 3 * xp + 8 / 9 * h * v - 2 / 9 * h * vp, rtol=1e-14, atol=1e-14)
    assert integrator.force_weight == pytest.approx((2 * h / 3) ** 2, rel=1e-15)


def test_predict_and_update_agree():
    """Without force (x = x̃) the acceleration is zero and the velocity the base
    velocity; the velocity always takes x̂ to x in the step βh (friction's slip)."""
    rng = np.random.default_rng(2)
    x, v, xp, vp = rng.normal(size=(4, 6, 3))
    for history in (None, StepHistory(xp, vp, 0.03)):
        integrator = BDF2(0.02, history)
        x_tilde = integrator.predict(x, v, None)
        v_new, a_new = integrator.update(x_tilde, x, v, None)
        np.testing.assert_allclose(a_new, 0.0, atol=1e-11)
        x_new = x_tilde + 0.01 * rng.normal(size=x.shape)
        v_new, a_new = integrator.update(x_new, x, v, None)
        np.testing.assert_allclose(integrator.lag_origin(x) + integrator.velocity_step * v_new,
                                   x_new, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(a_new, (x_new - x_tilde) / integrator.force_weight,
                                   rtol=1e-9, atol=1e-9)


def test_the_first_step_is_backward_euler_bit_for_bit():
    rng = np.random.default_rng(3)
    x, v, a = rng.normal(size=(3, 7, 3))
    x_new = x + 0.01 * rng.normal(size=x.shape)
    be, first = BackwardEuler(0.025), BDF2(0.025)
    assert first.force_weight == be.force_weight and first.velocity_step == be.h
    assert first.predict(x, v, a).tobytes() == be.predict(x, v, a).tobytes()
    for mine, theirs in zip(first.update(x_new, x, v, a), be.update(x_new, x, v, a)):
        assert mine.tobytes() == theirs.tobytes()
    assert make_integrator(TimeSettings(0.025, 40, "BDF2")).history is None


@pytest.mark.parametrize("omega", [0.5, 1.0, 2.0])
def test_free_fall_from_exact_history_is_exact(omega):
    """Constant acceleration: x quadratic, v linear in t, which BDF2 reproduces at any
    step ratio (the BE first step does not: it is off by ½h²g)."""
    h_prev, x0, v0 = 0.02, np.array([[0.3, 2.0, -1.0]]), np.array([[1.0, 0.5, 0.0]])
    h = omega * h_prev

    def at(t):
        return x0 + v0 * t + 0.5 * G * t * t, v0 + G * t

    (xp, vp), (x, v) = at(0.0), at(h_prev)
    integrator = BDF2(h, StepHistory(xp, vp, h_prev))
    x_new = integrator.predict(x, v, G) + integrator.force_weight * G  # argmin ½|x−x̃|² − w g·x
    v_new, a_new = integrator.update(x_new, x, v, G)
    np.testing.assert_allclose(x_new, at(h_prev + h)[0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(v_new, at(h_prev + h)[1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a_new, G, rtol=0, atol=1e-9)
    first = BDF2(h)
    x1 = first.predict(x, v, G) + first.force_weight * G
    np.testing.assert_allclose(x1 - at(h_prev + h)[0], 0.5 * h * h * G, rtol=1e-9, atol=1e-15)


def test_prescribed_linear_motion_gets_its_own_velocity():
    u, x0 = np.array([[0.35, 0.0, -0.1]]), np.array([[1.0, 2.0, 3.0]])
    for history, h in ((None, 0.01), (StepHistory(x0 - 0.02 * u, u, 0.02), 0.01)):
        integrator = BDF2(h, history)
        v_new, _ = integrator.update(x0 + h * u, x0, u, None)
        np.testing.assert_allclose(v_new, u, rtol=1e-12)


@pytest.mark.parametrize("omega", [0.5, 1.0, 2.0])
def test_the_error_estimate_tracks_the_true_local_error(omega):
    """From exact data at t = 0.3 (after a step h/ω), one step: the estimate over the
    true error x(t + h) − x tends to 1 as h shrinks (BDF2: order 3; BE: order 2)."""
    t = 0.3
    for history_of in (lambda h: StepHistory(*exact(t - h / omega), h / omega),
                       lambda h: None):
        ratios = []
        for h in (0.004, 0.002, 0.001):
            x, v = exact(t)
            integrator = BDF2(h, history_of(h))
            x_new, _, _ = spring_step(integrator, x, v, -K * x)
            true = (exact(t + h)[0] - x_new)[0, 0]
            ratios.append(integrator.local_error(x_new, x, v)[0, 0] / true)
        assert abs(ratios[-1] - 1.0) < 0.05 and abs(ratios[-1] - 1.0) < abs(ratios[0] - 1.0)


def test_the_error_estimate_is_zero_for_free_fall_and_its_norm():
    (x0, v0), h = (np.zeros((2, 3)), np.ones((2, 3))), 0.01
    xp, vp = x0 - h * v0 + 0.5 * h * h * G, v0 - h * G
    integrator = BDF2(h, StepHistory(xp, vp, h))
    x_new = integrator.predict(x0, v0, G) + integrator.force_weight * G
    np.testing.assert_allclose(integrator.local_error(x_new, x0, v0), 0.0, atol=1e-15)
    e = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    assert error_norm(e, 2.0) == pytest.approx(math.sqrt(26 / 3) / 2)
    assert error_norm(e, 2.0, free=[True, False, False]) == pytest.approx(2.5)


def test_damping_scale_is_the_originals_at_the_scenes_step():
    k, h = 0.3, 0.025
    for integrator in (BackwardEuler(h), Newmark(h)):
        assert damping_scale(integrator, k, h) == pytest.approx(Damping.of(k, h).scale,
                                                                rel=1e-15)
    history = StepHistory(np.zeros((1, 3)), np.zeros((1, 3)), h)
    assert damping_scale(BDF2(h, history), k, h) == pytest.approx(2 / 3 * k / h, rel=1e-15)
    assert damping_scale(BackwardEuler(h / 2), k, h) == pytest.approx(0.5 * k / h)
