"""Time integrators: what x̃ is, how the potential terms are weighted, and how velocities
follow from the minimiser x of the step.

Backward Euler (BE):
    x̃ = xₙ + h vₙ,   E = ½‖x − x̃‖²_M + h² (Ψ − Σ m a·x) + contact,   vₙ₊₁ = (x − xₙ)/h
Newmark (NM, β, γ):
    x̃ = xₙ + h vₙ + h² (½ − β) aₙ,   E = ½‖x − x̃‖²_M + β h² (Ψ − Σ m a·x) + contact,
    aₙ₊₁ = (x − x̃)/(β h²),   vₙ₊₁ = vₙ + h ((1 − γ) aₙ + γ aₙ₊₁)
Kinematic vertices take their prescribed positions; their velocity is (x − xₙ)/h.
"""

from __future__ import annotations

import numpy as np


class BackwardEuler:
    name = "BE"
    # its update is v = Δx/h, a = Δv/h for every vertex: the prescribed vertices' rates
    # already (``fix_kinematic_velocities`` would compute them again, bit for bit)
    kinematic_rates = True

    def __init__(self, h: float):
        self.h = h

    @property
    def force_weight(self) -> float:
        """Weight of Ψ and body forces in the incremental potential."""
        return self.h * self.h

    def predict(self, x, v, a):
        return x + self.h * v

    def update(self, x_new, x, v, a):
        v_new = (x_new - x) / self.h
        return v_new, (v_new - v) / self.h


class Newmark:
    name = "NM"
    kinematic_rates = False  # its update gives the prescribed vertices Newmark's rates

    def __init__(self, h: float, beta: float = 0.25, gamma: float = 0.5):
        if not 0.0 < beta <= 0.5 or not 0.0 < gamma <= 1.0:
            raise ValueError(f"Newmark needs 0 < β ≤ 0.5 and 0 < γ ≤ 1 (got {beta}, {gamma})")
        self.h, self.beta, self.gamma = h, beta, gamma

    @property
    def force_weight(self) -> float:
        return self.beta * self.h * self.h

    def predict(self, x, v, a):
        return x + self.h * v + self.h * self.h * (0.5 - self.beta) * a

    def update(self, x_new, x, v, a):
        x_tilde = self.predict(x, v, a)
        a_new = (x_new - x_tilde) / self.force_weight
        v_new = v + self.h * ((1.0 - self.gamma) * a + self.gamma * a_new)
        return v_new, a_new


def make_integrator(time):
    """The integrator of a model's ``TimeSettings``."""
    if time.integrator == "BE":
        return BackwardEuler(time.dt)
    if time.integrator == "NM":
        return Newmark(time.dt, time.newmark_beta, time.newmark_gamma)
    raise ValueError(f"unknown integrator {time.integrator!r}")


def fix_kinematic_velocities(v_new, a_new, kinematic, x_new, x, v, h):
    """Kinematic vertices move by prescription: v = Δx/h, a = Δv/h (computed for every
    vertex and kept for the kinematic ones: on a small scene half the time of indexing
    by the mask four times)."""
    if kinematic.any():
        rows = kinematic[:, None]
        v_new = np.where(rows, (x_new - x) / h, v_new)
        a_new = np.where(rows, (v_new - v) / h, a_new)
    return v_new, a_new


def kinetic_energy(mass, v) -> float:
    return 0.5 * float(np.einsum("i,ij,ij->", mass, v, v))
