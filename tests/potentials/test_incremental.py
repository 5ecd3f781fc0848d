"""The incremental potential's sums: term values read only when asked for, once, and the
weighted sums of the terms' own values."""

from __future__ import annotations

import numpy as np

from ipcsim.contact.planes import Planes
from ipcsim.kernels.terms import all_terms as kt
from ipcsim.potentials.base import StepContext
from ipcsim.potentials.body_force import BodyForce
from ipcsim.potentials.incremental import IncrementalPotential, WeightedTerm
from ipcsim.potentials.inertia import Inertia
from ipcsim.potentials.plane_contact import PlaneContact


def setting():
    rng = np.random.default_rng(0)
    mass = rng.random(4) + 0.5
    planes = Planes(np.arange(4, dtype=np.int64), np.zeros((1, 3)),
                    np.array([[0.0, 1.0, 0.0]]), np.zeros(1))
    pot = IncrementalPotential((WeightedTerm(Inertia(mass)), WeightedTerm(BodyForce(mass), 0.5),
                                WeightedTerm(PlaneContact(planes, 0.3), barrier=True)))
    ctx = StepContext(x_tilde=rng.random((4, 3)), acceleration=rng.random((4, 3)), dhat=0.3)
    return pot, ctx


def counting(monkeypatch) -> list:
    calls = []
    values = kt.term_values
    monkeypatch.setattr(kt, "term_values", lambda *a: (calls.append(1), values(*a))[1])
    return calls


def test_values_are_evaluated_when_first_read_and_once(monkeypatch):
    pot, ctx = setting()
    x = np.random.default_rng(1).random((4, 3)) * [1.0, 0.2, 1.0] + [0.0, 0.05, 0.0]
    calls = counting(monkeypatch)
    values = pot.evaluate(x, ctx, pot.kernel.data(ctx), 1)
    assert calls == [] and values.gradients is not None  # an iterate's E: its line search's
    kappa = 7.0
    own = [t.term.value(x, ctx) for t in pot.terms]
    assert own[2] > 0.0  # some vertex within d̂ of the plane
    expected = sum(t.factor(kappa) * v for t, v in zip(pot.terms, own))
    assert values.energy(kappa) == expected
    assert values.value_of("body force") == own[1] == values.values[1]
    values.energy(1.0)
    assert calls == [1]  # once for every sum above


def test_the_values_are_those_of_the_x_evaluated_even_if_read_later():
    pot, ctx = setting()
    x = np.random.default_rng(2).random((4, 3)) + [0.0, 0.1, 0.0]
    data = pot.kernel.data(ctx)
    values = pot.evaluate(x, ctx, data, 1)
    expected = pot.terms[0].term.value(x, ctx)
    later = pot.evaluate(x + 1.0, ctx, data, 1)  # another point evaluated in between
    assert values.values[0] == expected and later.values[0] != expected


def test_the_gradient_weighs_each_terms_own_gradient_and_splits_the_barrier():
    pot, ctx = setting()
    x = np.random.default_rng(3).random((4, 3)) * [1.0, 0.2, 1.0] + [0.0, 0.05, 0.0]
    values = pot.evaluate(x, ctx, pot.kernel.data(ctx), 1)
    own = [t.term.gradient(x, ctx) for t in pot.terms]
    assert np.abs(own[2]).max() > 0.0
    kappa = 3.0
    np.testing.assert_array_equal(values.gradient(kappa),
                                  own[0] + 0.5 * own[1] + kappa * own[2])
    barrier, rest = values.split_gradient()
    np.testing.assert_array_equal(barrier, 0.0 + own[2])
    np.testing.assert_array_equal(rest, own[0] + 0.5 * own[1])
