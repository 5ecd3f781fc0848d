"""A linear spring of unit mass for the integrators' tests: its exact motion, and one
step of an integrator with the incremental potential minimised exactly."""

from __future__ import annotations

import math

import numpy as np

OMEGA0 = 2.0 * math.pi  # angular frequency: a period of 1 s
K = OMEGA0 ** 2  # stiffness (unit mass)


def exact(t: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity (1, 3) of x'' = −K x from x = 1, v = 0."""
    return (np.array([[math.cos(OMEGA0 * t), 0.0, 0.0]]),
            np.array([[-OMEGA0 * math.sin(OMEGA0 * t), 0.0, 0.0]]))


def spring_step(integrator, x, v, a):
    """One step: E(x) = ½|x − x̃|² + w·½K|x|² minimised exactly, then the update."""
    x_new = integrator.predict(x, v, a) / (1.0 + integrator.force_weight * K)
    return (x_new, *integrator.update(x_new, x, v, a))
