"""The comparison baselines of the IPC paper (Li et al. 2020, §8): contact handled as
constraints in a sequence of QPs (``constraintSolver SQP``) or one QP per time step
(``constraintSolver QP``), solved with OSQP, instead of IPC's barrier.

``active_set``: which pairs are constrained and their linearisation (the constraint
functions are numba kernels in ``ipcsim.kernels.contact.constraints``); ``qp``: one QP; ``sqp``:
the time step. The simulation picks them when the model has ``constraint_solver`` set.
"""
