"""The incremental potential's sums: term values read only when asked for, the same sums."""

from __future__ import annotations

import numpy as np

from ipcsim.potentials.base import StepContext, Triplets
from ipcsim.potentials.incremental import IncrementalPotential, WeightedTerm


class Spring:
    """½ k ‖x − a‖², counting its value calls."""

    name = "spring"
    constant_pattern = True

    def __init__(self, k: float, anchor: np.ndarray):
        self.k, self.anchor, self.value_calls = k, anchor, 0

    def value(self, x, ctx):
        self.value_calls += 1
        return 0.5 * self.k * float(np.sum((x - self.anchor) ** 2))

    def gradient(self, x, ctx):
        return (self.k * (x - self.anchor)).reshape(-1)

    def hessian(self, x, ctx):
        dofs = np.arange(x.size, dtype=np.int32)
        return Triplets(dofs, dofs, np.full(x.size, self.k))


def potential():
    rng = np.random.default_rng(0)
    a, b = Spring(2.0, rng.random((4, 3))), Spring(3.0, rng.random((4, 3)))
    return IncrementalPotential((WeightedTerm(a, 0.5), WeightedTerm(b, 1.0, barrier=True))), a, b


def test_values_are_evaluated_when_first_read_and_once():
    pot, a, b = potential()
    x = np.random.default_rng(1).random((4, 3))
    ctx = StepContext()
    values = pot.evaluate(x, ctx, 2)
    assert a.value_calls == b.value_calls == 0  # a Newton iterate's E comes from its line search
    assert values.gradients is not None and values.hessians is not None
    kappa = 7.0
    expected = 0.5 * a.value(x, ctx) + kappa * b.value(x, ctx)
    a.value_calls = b.value_calls = 0
    assert values.energy(kappa) == expected == pot.value(x, ctx, kappa)
    assert values.value_of("spring") == values.values[0]
    values.energy(1.0)
    assert a.value_calls == b.value_calls == 2  # once for the sums above, once in pot.value


def test_the_values_are_those_of_the_x_evaluated_even_if_read_later():
    pot, a, _ = potential()
    x = np.random.default_rng(2).random((4, 3))
    values = pot.evaluate(x, StepContext(), 1)
    expected = a.value(x, None)
    later = pot.evaluate(x + 1.0, StepContext(), 1)  # another point evaluated in between
    assert values.values[0] == expected and later.values[0] != expected
