"""Adaptive barrier stiffness against the IPC Toolkit: κ_min, κ_max and the balanced κ."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.contact.stiffness import balanced_kappa, kappa_bounds, should_double

ipctk = pytest.importorskip("ipctk")


@pytest.mark.parametrize("bbox, dhat, mass", [
    (1.0, 1e-3, 1.0), (3.7, 2e-2, 0.05), (0.01, 1e-6, 1e-4),
    (1.0, 1e-8, 1.0), (1.0, 1e-9, 2.0), (250.0, 1e-7, 10.0),  # d̂ at or below 1e-8·l
])
def test_bounds_and_balance_match_ipctk(bbox, dhat, mass):
    rng = np.random.default_rng(7)
    g_b, g_e = rng.normal(size=30), rng.normal(size=30)
    g_e -= 3.0 * g_b  # a force the barrier must balance: the clamp is not always active
    want_kappa, want_max = ipctk.initial_barrier_stiffness(
        bbox, ipctk.ClampedLogBarrier(), dhat, mass, g_e, g_b)
    kmin, kmax = kappa_bounds(bbox, dhat, mass)
    assert np.isfinite(kmin) and kmax == pytest.approx(want_max, rel=1e-12)
    assert kmin == pytest.approx(want_max / 100.0, rel=1e-12)
    assert balanced_kappa(g_b, g_e, kmin, kmax) == pytest.approx(want_kappa, rel=1e-12)


def test_balance_without_barrier_force_is_kappa_min_and_doubling_rule():
    assert balanced_kappa(np.zeros(3), np.ones(3), 5.0, 500.0) == 5.0
    eps_sq = 1e-6
    assert should_double(5e-7, 4e-7, eps_sq)  # close and closing
    assert not should_double(5e-7, 6e-7, eps_sq)  # opening
    assert not should_double(2e-6, 4e-7, eps_sq)  # was not close yet
