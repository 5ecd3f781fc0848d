"""The backtracking line search (kernels/terms/line_search.py) gives up once its step is
within round-off of x, and otherwise returns what halving to the cap returns."""

import math

import numpy as np

from ipcsim.kernels.terms import all_terms as kt
from ipcsim.kernels.terms.line_search import line_search
from ipcsim.potentials.kernel_data import NO_TERMS

EPS = np.finfo(float).eps
HALVINGS = 40
NO_MESH = (np.zeros((0, 1), dtype=np.int64), np.zeros((0, 2), dtype=np.int64),
           np.zeros((0, 3), dtype=np.int64), (np.zeros((0, 2), dtype=np.int64),) * 3, False,
           np.zeros((0, 3)), False, False)


def _energy(x, x_min):
    """The quadratic the search runs on: ½ Σ ‖y − x_min‖² (inertia with unit masses,
    summed in the kernel's order)."""
    total = 0.0
    for d in (x - x_min).reshape(-1).tolist():
        total += 1.0 * d * d
    return 0.5 * total


def search(x, p, x_min):
    """(α, gave up, E) of the line search on ``_energy`` from x along p, complete motion."""
    n = len(x)
    present = np.zeros(kt.N_KINDS, dtype=np.bool_)
    present[kt.INERTIA] = True
    terms = list(NO_TERMS)
    terms[kt.INERTIA] = (np.ones(n), np.ascontiguousarray(x_min, dtype=float))
    weighing = (np.array([kt.INERTIA], dtype=np.int64), np.ones(1), np.zeros(1, np.bool_))
    out = line_search(np.ascontiguousarray(x), np.ascontiguousarray(p), present, weighing,
                      1.0, tuple(terms), NO_MESH, (False, 0.0, 0.1),
                      (np.zeros(n, np.bool_), np.zeros((n, 3)), 0.0),
                      (0.0, 1.0, True, 0.1, 10), (math.nan, True, HALVINGS))
    return float(out[1]), bool(out[3]), float(out[2])


def halving_to_the_cap(x, p, x_min):
    """The search without the round-off stop: (α, gave up, E)."""
    e0 = _energy(x, x_min)
    alpha = 1.0
    for _ in range(HALVINGS):
        e = _energy(x + alpha * p, x_min)
        if e < e0:
            return alpha, False, e
        alpha *= 0.5
    return 0.0, True, e0


def test_roundoff_direction_gives_up_at_once():
    # a converged direction of free flight (1e-16) with a coordinate at 0, where
    # x + αp never rounds back to x: the search halved 40 times before the stop
    x = np.array([[0.0, 1.7, 2.9], [0.55, 0.9, 1.25]])
    p = np.full_like(x, 1.1e-16)
    e0 = _energy(x, x)
    assert search(x, p, x_min=x) == (0.0, True, e0)  # x is the minimum: no step lowers E
    assert halving_to_the_cap(x, p, x) == (0.0, True, e0)


def test_steps_above_roundoff_are_searched_as_before():
    """The search returns what the search without the stop returns, but where that one
    accepted a step within round-off of x: there it stays at x."""
    rng = np.random.default_rng(3)
    same = stopped = 0
    for _ in range(400):
        x = rng.uniform(-2, 2, (4, 3))
        p = rng.standard_normal((4, 3)) * 10.0 ** rng.uniform(-17, 0)
        x_min = x + rng.uniform(-0.2, 1.2) * p + rng.standard_normal((4, 3)) * 1e-17
        got = search(x, p, x_min)
        ref = halving_to_the_cap(x, p, x_min)
        if got == ref:
            same += 1
        else:
            assert got == (0.0, True, _energy(x, x_min))
            assert not ref[1] and ref[0] * np.abs(p).max() <= EPS * np.abs(x).max()
            stopped += 1
    assert same > 200 and stopped > 5
