"""Newton's DOF masks of a kinematic vertex mask: made once per mask value."""

import numpy as np

from ipcsim.solver.newton import NewtonSolver


def _solver():
    return NewtonSolver(settings=None, linear_solver=object())


def test_masks_of_a_mask():
    kinematic = np.array([False, True, False])
    dofs = _solver()._dofs(kinematic)
    assert dofs.prescribed.tolist() == [False] * 3 + [True] * 3 + [False] * 3
    assert (dofs.free == ~dofs.prescribed).all()
    assert dofs.index.tolist() == [0, 1, 2, -1, -1, -1, 3, 4, 5]
    assert dofs.n_free == 6


def test_an_equal_mask_gets_the_same_arrays_and_is_then_known_by_identity():
    solver = _solver()
    first = solver._dofs(np.array([True, False]))
    later = np.array([True, False])  # the next step's mask: a new, equal array
    again = solver._dofs(later)
    assert again.index is first.index and again.free is first.free
    assert again.kinematic is later  # adopted: the next lookups compare no values
    assert solver._dofs(later) is again


def test_two_masks_alternate_without_being_made_again_and_a_third_pushes_out_the_oldest():
    solver = _solver()
    a, b, c = (np.array(m) for m in ([True, False], [False, True], [True, True]))
    da, db = solver._dofs(a), solver._dofs(b)
    assert solver._dofs(a.copy()).index is da.index
    assert solver._dofs(b.copy()).index is db.index
    solver._dofs(c)
    assert solver._dofs(b.copy()).index is db.index  # the two most recent stay
    assert solver._dofs(a.copy()).index is not da.index  # the oldest was made again
