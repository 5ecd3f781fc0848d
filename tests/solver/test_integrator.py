"""The integrators' updates and the prescribed vertices' rates."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.solver.integrator import BackwardEuler, Newmark, fix_kinematic_velocities


@pytest.mark.parametrize("integrator", [BackwardEuler(0.025), Newmark(0.025)],
                         ids=["BE", "NM"])
def test_kinematic_rates_says_whether_the_update_already_gives_the_prescribed_rates(
        integrator):
    """``Simulation.advance`` leaves out ``fix_kinematic_velocities`` where the
    integrator's ``kinematic_rates`` holds: it must then change no bit."""
    rng = np.random.default_rng(3)
    x, v, a = rng.normal(size=(3, 16, 3))
    x_new = x + 0.025 * rng.normal(size=(16, 3))
    kinematic = np.zeros(16, dtype=bool)
    kinematic[[1, 4, 5, 11]] = True
    v_new, a_new = integrator.update(x_new, x, v, a)
    fixed_v, fixed_a = fix_kinematic_velocities(v_new, a_new, kinematic, x_new, x, v,
                                                integrator.h)
    same = (fixed_v.tobytes() == v_new.tobytes() and fixed_a.tobytes() == a_new.tobytes())
    assert same == integrator.kinematic_rates
    # the free vertices keep the integrator's rates either way
    np.testing.assert_array_equal(fixed_v[~kinematic], v_new[~kinematic])
