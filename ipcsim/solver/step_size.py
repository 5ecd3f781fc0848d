"""Step sizes from a target error (adaptive time steps), and steps that land on output
times.

A step of length h is accepted when its estimated local error (``integrator.local_error``
measured by ``integrator.error_norm``: a position RMS over the free vertices, relative to
the scene size l) is within the error allowed per unit of simulated time:

    err ≤ allowed(h) = τ · h / T      (τ relative to l, like d̂; T the scene's duration)

Summed over a run the allowed local errors make τ, so the global error stays near τ and
shrinks in proportion to it (error per unit step); err ≤ τ per step would let the global
error grow with the number of steps. Steps shorter than h_floor (10⁻⁴ dt) may make the
error of a step of h_floor, allowed(h) = τ·max(h, h_floor)/T: an impact deep in the
barrier reverses a velocity within nanoseconds, the estimate of a step across it is
about h·Δv, and err / (τh/T) does not fall as h shrinks, so error per unit step could
never be met there; such a step adds at most τ·h_floor/T (10⁻⁴·τ·dt/T) to the run's
error. With err ≈ C h^(p+1) (p = 2 for BDF2, 1 for the
BE step that starts it), err / allowed ∝ h^p, and the next step is

    h' = h · clamp(safety · (allowed / err)^(1/p), shrink, grow)

with safety 0.9, grow 2 (variable-step BDF2 is zero-stable for step ratios below
1 + √2), shrink 0.2, no growth right after a rejected step and never above the scene's
dt. Newton's own error must not count as the integrator's: its ‖p‖∞ tolerance is at
most ``solve_share`` of the allowed error (``solve_tolerance``). A rejected step is
tried again at h'. A step whose Newton solve stalls (the
iteration cap, a failed line search, α ever smaller under CCD) is tried again at
``stall_factor``·h; so is one whose Newton solve needs more than ``iteration_budget``
iterations (a crawl of ever smaller α under CCD ends there, not at the scene's cap of
thousands: a shorter step costs less than a crawl). Below ``h_min`` the run fails
instead.

The barrier stiffness κ is κ_max throughout a run with adaptive steps, unless the scene
fixes κ (``simulation._initial_stiffness``): a κ adapted per step (balanced, doubled)
changes the contact model with h, the estimate then compares different models, and the
steps shrink without the error converging.
"""

from __future__ import annotations

import math

from msgspec import Struct


class StepSizeControl(Struct, frozen=True):
    """The controller of one run (module docstring)."""

    tolerance: float  # τ, relative to l
    duration: float  # T (s): the run's simulated time
    h_max: float  # s: the scene's dt, the first and largest step
    safety: float = 0.9
    grow: float = 2.0
    shrink: float = 0.2
    stall_factor: float = 0.25
    h_min_ratio: float = 1e-8  # h_min = this · h_max
    h_floor_ratio: float = 1e-4  # h_floor = this · h_max (module docstring)
    solve_share: float = 0.1  # of the allowed error, at most Newton's tolerance
    iteration_budget: int = 100  # Newton iterations of a step before it is tried shorter

    @property
    def h_min(self) -> float:
        return self.h_min_ratio * self.h_max

    @property
    def h_floor(self) -> float:
        return self.h_floor_ratio * self.h_max

    def allowed(self, h: float) -> float:
        """The local error (relative to l) a step of length h may make."""
        return self.tolerance * max(h, self.h_floor) / self.duration

    def solve_tolerance(self, h: float) -> float:
        """Newton's ‖p‖∞ tolerance (relative to l) in a step of length h at most."""
        return self.solve_share * self.allowed(h)

    def judge(self, h: float, error: float, order: int,
              after_rejection: bool = False) -> tuple[bool, float]:
        """(accepted, the next step's length) for a step of length h whose estimated
        error is ``error`` (relative to l) and whose integrator has order ``order``."""
        allowed = self.allowed(h)
        accepted = error <= allowed
        factor = self.grow if error <= 0.0 else self.safety * (allowed / error) ** (1 / order)
        top = 1.0 if after_rejection or not accepted else self.grow
        return accepted, min(h * min(max(factor, self.shrink), top), self.h_max)

    def stalled(self, h: float) -> float:
        """The length to try again after a step whose Newton solve stalled."""
        return h * self.stall_factor


def landing_step(t: float, h: float, t_next: float) -> float:
    """The step from t towards the output time t_next: the rest t_next − t in the fewest
    equal parts no longer than h (so no sliver of a step comes before an output time;
    the step that ends there is the one that lands on it exactly)."""
    rest = t_next - t
    if not rest > 0.0:
        raise ValueError(f"output time {t_next!r} is not after t = {t!r}")
    return rest / max(1, math.ceil(rest / h * (1.0 - 1e-12)))
