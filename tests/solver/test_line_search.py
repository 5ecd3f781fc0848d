"""The backtracking line search gives up once its step is within round-off of x."""

import numpy as np

from ipcsim.model.model import SolverSettings
from ipcsim.potentials.objective import LineSearch
from ipcsim.solver.newton import NewtonSolver

EPS = np.finfo(float).eps


class _Line:
    """A line search along p from x on a quadratic E with its minimum at ``x_min``,
    counting the energies evaluated."""

    def __init__(self, x, p, x_min):
        self.x, self.p3, self.x_min = x, p, x_min
        self.evaluated = 0

    def energy(self, alpha):
        self.evaluated += 1
        y = self.x + alpha * self.p3
        return float(((y - self.x_min) ** 2).sum())

    below_roundoff = LineSearch.below_roundoff


def _solver():
    return NewtonSolver(SolverSettings(newton_tolerances=(1e-3,), max_halvings=40),
                        linear_solver=None)


def _halving_to_the_cap(line, e0):
    """The search without the round-off stop: (α, gave up, E)."""
    alpha = 1.0
    for _ in range(40):
        e = line.energy(alpha)
        if e < e0:
            return alpha, False, e
        alpha *= 0.5
    return 0.0, True, e0


def test_roundoff_direction_gives_up_after_one_energy():
    # a converged direction of free flight (1e-16) with a coordinate at 0, where
    # x + αp never rounds back to x: it used to evaluate all 40 halvings
    x = np.array([[0.0, 1.7, 2.9], [0.55, 0.9, 1.25]])
    p = np.full_like(x, 1.1e-16)
    line = _Line(x, p, x_min=x)  # x is the minimum: no step lowers E
    e0 = line.energy(0.0)
    assert _solver()._backtrack(line, 1.0, e0, it=1) == (0.0, True, e0)
    assert line.evaluated == 2  # E(x) and E(x + p)
    reference = _Line(x, p, x_min=x)
    assert _halving_to_the_cap(reference, e0) == (0.0, True, e0)
    assert reference.evaluated == 40


def test_steps_above_roundoff_are_searched_as_before():
    """The search returns what the search without the stop returns, but where that one
    accepted a step within round-off of x: there it stays at x."""
    rng = np.random.default_rng(3)
    solver = _solver()
    same = stopped = 0
    for _ in range(400):
        x = rng.uniform(-2, 2, (4, 3))
        p = rng.standard_normal((4, 3)) * 10.0 ** rng.uniform(-17, 0)
        x_min = x + rng.uniform(-0.2, 1.2) * p + rng.standard_normal((4, 3)) * 1e-17
        e0 = _Line(x, p, x_min).energy(0.0)
        got = solver._backtrack(_Line(x, p, x_min), 1.0, e0, 0)
        ref = _halving_to_the_cap(_Line(x, p, x_min), e0)
        if got == ref:
            same += 1
        else:
            assert got == (0.0, True, e0)
            assert not ref[1] and ref[0] * np.abs(p).max() <= EPS * np.abs(x).max()
            stopped += 1
    assert same > 200 and stopped > 5
