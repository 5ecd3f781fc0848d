"""Time integrators: what x̃ is, how the potential terms are weighted, and how velocities
follow from the minimiser x of the step.

Backward Euler (BE):
    x̃ = xₙ + h vₙ,   E = ½‖x − x̃‖²_M + h² (Ψ − Σ m a·x) + contact,   vₙ₊₁ = (x − xₙ)/h
Newmark (NM, β, γ):
    x̃ = xₙ + h vₙ + h² (½ − β) aₙ,   E = ½‖x − x̃‖²_M + β h² (Ψ − Σ m a·x) + contact,
    aₙ₊₁ = (x − x̃)/(β h²),   vₙ₊₁ = vₙ + h ((1 − γ) aₙ + γ aₙ₊₁)
Kinematic vertices take their prescribed positions; their velocity is (x − xₙ)/h.

BDF2, the two-step backward differentiation formula, with variable steps. The step
h = tₙ₊₁ − tₙ follows the step hₚ = tₙ − tₙ₋₁; ω = h / hₚ. For y' = f(y) the formula is

    (1 + 2ω)/(1 + ω) yₙ₊₁ − (1 + ω) yₙ + ω²/(1 + ω) yₙ₋₁ = h f(yₙ₊₁),

that is yₙ₊₁ = ŷ + βh f(yₙ₊₁) with the base ŷ = c₁ yₙ + c₂ yₙ₋₁ and (``bdf2_coefficients``)

    c₁ = (1 + ω)² / (1 + 2ω),   c₂ = −ω² / (1 + 2ω),   β = (1 + ω) / (1 + 2ω)

(c₁ + c₂ = 1; constant steps, ω = 1: c₁ = 4/3, c₂ = −1/3, β = 2/3). Applied to x' = v,
M v' = f(x) (f = −∇Ψ + body forces; contact enters through its potential as Ψ does):

    xₙ₊₁ = x̂ + βh vₙ₊₁,   vₙ₊₁ = v̂ + βh M⁻¹f(xₙ₊₁),   x̂ = c₁xₙ + c₂xₙ₋₁,  v̂ = c₁vₙ + c₂vₙ₋₁.

Eliminating vₙ₊₁ = (xₙ₊₁ − x̂)/(βh) from the second: M(xₙ₊₁ − x̃) = (βh)² f(xₙ₊₁) with
x̃ = x̂ + βh v̂, the stationarity condition of the incremental potential

    E(x) = ½‖x − x̃‖²_M + (βh)² (Ψ(x) − Σ m a·x) + contact:

BE's potential with x̃ = x̂ + βh v̂ and the weight w = (βh)² in place of h² (constant
steps: x̃ = (4/3)xₙ − (1/3)xₙ₋₁ + (8/9)h vₙ − (2/9)h vₙ₋₁, w = (2h/3)²). The minimiser x
gives vₙ₊₁ = (x − x̂)/(βh) and aₙ₊₁ = (vₙ₊₁ − v̂)/(βh) = (x − x̃)/(βh)², the acceleration
M⁻¹f(x) itself. Without a step before (the first step, or a history dropped) BDF2 is BE:
c₁ = 1, c₂ = 0, β = 1. Since vₙ₊₁ = (x − x̂)/(βh) exactly, what depends on the
end-of-step velocity is written with x̂ and βh where BE has xₙ and h: friction's slip is
x − x̂ with the threshold ε_v·βh, Rayleigh damping ½(x − x̂)ᵀD(x − x̂) with D = βh·αK (α
the physical coefficient k / h_scene²; BE at the scene's h: D = (k/h)K, the original's).
``lag_origin``, ``velocity_step`` and ``damping_weight`` say so for each integrator;
Newmark keeps the original's xₙ, h and k/h. The prescribed vertices keep BDF2's rates,
exact for motion linear in time (BE's Δx/h on the first step). Variable-step BDF2 is
zero-stable for ω < 1 + √2 (Grigorieff 1983).

Local error (``local_error``, for adaptive steps). With exact data a step of BDF2 errs by
x(tₙ₊₁) − xₙ₊₁ = C h³ x⁽³⁾ + O(h⁴) with C = −(1 + ω)² / (6ω(1 + 2ω)) (−2/9 at ω = 1; the
error of vₙ₊₁ enters x only as βh·O(h³)). The explicit predictor through xₙ₋₁ and xₙ with
slope vₙ, x̄ = xₙ + h(1 + ω)vₙ + ω²(xₙ₋₁ − xₙ), errs by P h³ x⁽³⁾ + O(h⁴) with
P = (1 + ω)/(6ω). So xₙ₊₁ − x̄ = (P − C) h³ x⁽³⁾ + O(h⁴), and (Milne's device)

    x(tₙ₊₁) − xₙ₊₁ ≈ C/(P − C) · (xₙ₊₁ − x̄) = −(1 + ω)/(2 + 3ω) · (xₙ₊₁ − x̄)

(−2/5 at ω = 1): an estimate of order 3 that costs no solve. A BE step (BDF2's first)
errs by −½h² x'' + O(h³) and its predictor x̄ = xₙ + h vₙ by +½h² x'', so its error is
−½(xₙ₊₁ − x̄), of order 2. ``error_norm`` measures it as a position RMS over the free
vertices, relative to the scene size; ``solver/step_size.py`` turns it into steps.
"""

from __future__ import annotations

import numpy as np
from msgspec import Struct


class StepHistory(Struct, frozen=True, eq=False):
    """What a two-step integrator keeps of the step before the current one: the positions
    xₙ₋₁ and velocities vₙ₋₁ (n, 3) it started from and its length hₙ₋₁ = tₙ − tₙ₋₁ (s).
    A value: the step core carries it in its State, checkpoints save its three fields."""

    x: np.ndarray
    v: np.ndarray
    h: float


def bdf2_coefficients(h: float, h_previous: float) -> tuple[float, float, float]:
    """(c₁, c₂, β) of the variable-step BDF2 step h after a step h_previous (module
    docstring): xₙ₊₁ = c₁xₙ + c₂xₙ₋₁ + βh vₙ₊₁."""
    omega = h / h_previous
    return ((1.0 + omega) ** 2 / (1.0 + 2.0 * omega), -omega * omega / (1.0 + 2.0 * omega),
            (1.0 + omega) / (1.0 + 2.0 * omega))


def local_error(x_new, x, v, h: float, history: StepHistory | None):
    """The estimated local position error x(tₙ₊₁) − xₙ₊₁ (n, 3) of a step from (x, v)
    that ended at x_new: BDF2's after ``history``, BE's without (module docstring)."""
    if history is None:
        return -0.5 * (x_new - (x + h * v))
    omega = h / history.h
    predicted = x + (h * (1.0 + omega)) * v + (omega * omega) * (history.x - x)
    return (-(1.0 + omega) / (2.0 + 3.0 * omega)) * (x_new - predicted)


def error_norm(error, size: float, free=None) -> float:
    """RMS over the free vertices (all where ``free`` is None) of the error's length,
    divided by the scene size l: the measure of the benchmark's errors and of τ."""
    e = np.asarray(error, dtype=float).reshape(-1, 3)
    if free is not None:
        e = e[np.asarray(free, dtype=bool)]
    if not len(e):
        return 0.0
    return float(np.sqrt(np.mean(np.einsum("ij,ij->i", e, e)))) / size


def damping_scale(integrator, stiffness: float, h_scene: float) -> float:
    """The scale of lagged Rayleigh damping's matrix D = scale·∇²Ψ(xₙ) in a step of
    ``integrator``: its ``damping_weight`` times α = k / h_scene², the damping
    coefficient the scene's ``dampingStiff`` k means at the scene's own step (BE and
    Newmark at h_scene: k / h, the original's ``computeDampingMtr``, to the bit: the
    ratio of the steps is exactly 1 there)."""
    return stiffness / h_scene * (integrator.damping_weight / h_scene)


class _OneStep:
    """What the one-step integrators (BE, Newmark) share: no history, friction's slip
    and damping's displacement x − xₙ over the step's h, as the original has them."""

    uses_history = False  # reads no step before the current one
    h: float

    @property
    def velocity_step(self) -> float:
        """h: friction's slip and damping's displacement are x − xₙ (for Newmark the
        original's friction, threshold ε_v h, not Newmark's own velocity)."""
        return self.h

    @property
    def damping_weight(self) -> float:
        """h: the original's damping, (k/h)·K on x − xₙ at the scene's h."""
        return self.h

    def lag_origin(self, x):
        return x

    def after(self, x, v) -> StepHistory:
        return StepHistory(x, v, self.h)


class BackwardEuler(_OneStep):
    name = "BE"
    order = 1  # of its local error estimate's step: err ∝ h^(order + 1)
    # its update is v = Δx/h, a = Δv/h for every vertex: the prescribed vertices' rates
    # already (``fix_kinematic_velocities`` would compute them again, bit for bit)
    kinematic_rates = True

    def __init__(self, h: float):
        self.h = h

    @property
    def force_weight(self) -> float:
        """Weight of Ψ and body forces in the incremental potential."""
        return self.h * self.h

    def at(self, h: float, history: StepHistory | None = None) -> BackwardEuler:
        """This integrator for a step of length h (BE reads no history)."""
        return BackwardEuler(h)

    def predict(self, x, v, a):
        return x + self.h * v

    def update(self, x_new, x, v, a):
        v_new = (x_new - x) / self.h
        return v_new, (v_new - v) / self.h

    def local_error(self, x_new, x, v):
        return local_error(x_new, x, v, self.h, None)


class BDF2:
    """Variable-step BDF2 (module docstring); without ``history`` its step is BE's."""

    name = "BDF2"
    uses_history = True  # x̃ and the rates read the step before (``StepHistory``)
    # its update gives the prescribed vertices BDF2's rates (exact for motion linear in
    # time), which ``fix_kinematic_velocities`` must not replace by Δx/h
    kinematic_rates = True

    def __init__(self, h: float, history: StepHistory | None = None):
        self.h, self.history = h, history
        self.c1, self.c2, self.beta = ((1.0, 0.0, 1.0) if history is None
                                       else bdf2_coefficients(h, history.h))

    @property
    def order(self) -> int:
        """2; 1 for the BE step that starts it (no history)."""
        return 1 if self.history is None else 2

    @property
    def velocity_step(self) -> float:
        """βh: vₙ₊₁ = (x − x̂)/(βh)."""
        return self.beta * self.h

    @property
    def force_weight(self) -> float:
        return self.velocity_step * self.velocity_step

    @property
    def damping_weight(self) -> float:
        return self.velocity_step

    def lag_origin(self, x):
        """x̂ = c₁xₙ + c₂xₙ₋₁, from which friction's slip and damping's displacement are
        measured."""
        return x if self.history is None else self.c1 * x + self.c2 * self.history.x

    def _base_velocity(self, v):
        return v if self.history is None else self.c1 * v + self.c2 * self.history.v

    def at(self, h: float, history: StepHistory | None) -> BDF2:
        return BDF2(h, history)

    def after(self, x, v) -> StepHistory:
        """The history of the next step, once this one started from (x, v) succeeded."""
        return StepHistory(x, v, self.h)

    def predict(self, x, v, a):
        return self.lag_origin(x) + self.velocity_step * self._base_velocity(v)

    def update(self, x_new, x, v, a):
        hv = self.velocity_step
        v_new = (x_new - self.lag_origin(x)) / hv
        return v_new, (v_new - self._base_velocity(v)) / hv

    def local_error(self, x_new, x, v):
        return local_error(x_new, x, v, self.h, self.history)


class Newmark(_OneStep):
    name = "NM"
    kinematic_rates = False  # its update gives the prescribed vertices Newmark's rates

    def __init__(self, h: float, beta: float = 0.25, gamma: float = 0.5):
        if not 0.0 < beta <= 0.5 or not 0.0 < gamma <= 1.0:
            raise ValueError(f"Newmark needs 0 < β ≤ 0.5 and 0 < γ ≤ 1 (got {beta}, {gamma})")
        self.h, self.beta, self.gamma = h, beta, gamma

    @property
    def force_weight(self) -> float:
        return self.beta * self.h * self.h

    def at(self, h: float, history: StepHistory | None = None) -> Newmark:
        return Newmark(h, self.beta, self.gamma)

    def predict(self, x, v, a):
        return x + self.h * v + self.h * self.h * (0.5 - self.beta) * a

    def update(self, x_new, x, v, a):
        x_tilde = self.predict(x, v, a)
        a_new = (x_new - x_tilde) / self.force_weight
        v_new = v + self.h * ((1.0 - self.gamma) * a + self.gamma * a_new)
        return v_new, a_new


def make_integrator(time):
    """The integrator of a model's ``TimeSettings`` (BDF2's first step has no history)."""
    if time.integrator == "BE":
        return BackwardEuler(time.dt)
    if time.integrator == "NM":
        return Newmark(time.dt, time.newmark_beta, time.newmark_gamma)
    if time.integrator == "BDF2":
        return BDF2(time.dt)
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
