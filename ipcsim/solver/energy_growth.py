"""Stopping a run whose energy grows with no work done on it.

Without prescribed motion and prescribed forces the only work done on a scene is
gravity's, so its mechanical energy

    E = ½ vᵀMv + Ψ(x) − Σ mᵢ g·(xᵢ − xᵢ⁰)

cannot grow: friction and damping dissipate, backward Euler and BDF2 damp, contact stores
energy only while it acts. Newmark conserves it on smooth motion but can gain it at
impacts; at large h the gain feeds itself (a cube thrown onto the ground at h = 5 ms:
kinetic energy from 500 J to 7·10⁷ J in 150 steps, each at the Newton iteration cap).
Once E exceeds ``GROWTH_LIMIT`` times the reference E_ref = E₀ + M|g|l (the start's
energy plus that of a fall by the scene size l, so that a body dropped from rest has a
scale too), ``EnergyGrowth.check`` says so and the run stops. Round-off and the
ordinary wobble of an energy-conserving integrator stay orders of magnitude below it.
"""

from __future__ import annotations

from msgspec import Struct
import numpy as np

from .integrator import kinetic_energy

GROWTH_LIMIT = 1e3  # E / E_ref beyond which a run has blown up


class EnergyGrowth(Struct, frozen=True, eq=False):
    """The reference of one run's energy (module docstring)."""

    mass: np.ndarray  # (n,) lumped masses
    gravity: np.ndarray  # (3,) m/s²
    x0: np.ndarray  # (n, 3) the start's positions
    reference: float  # J: E_ref

    @staticmethod
    def of(model, x, v, elastic: float) -> EnergyGrowth | None:
        """The watch of a run that starts at (x, v) with elastic energy ``elastic``; None
        where work is done on it (prescribed motion, prescribed forces, moving planes) or
        nothing has energy (E_ref = 0)."""
        moving = any(s.moving for s in model.dbc_sets) or model.mesh_sequences
        if moving or model.nbc_sets or np.any(model.plane_velocities):
            return None
        mass = np.asarray(model.mass, dtype=float)
        gravity = np.asarray(model.gravity, dtype=float)
        fall = float(mass.sum() * np.linalg.norm(gravity) * model.bbox_diagonal)
        watch = EnergyGrowth(mass, gravity, np.array(x, dtype=float), 0.0)
        reference = watch.energy(x, v, elastic) + fall
        if not reference > 0.0:
            return None
        return EnergyGrowth(mass, gravity, watch.x0, reference)

    def energy(self, x, v, elastic: float) -> float:
        """E at (x, v) with elastic energy ``elastic`` (J)."""
        work = float(np.einsum("i,ij,j->", self.mass, x - self.x0, self.gravity))
        return kinetic_energy(self.mass, v) + elastic - work

    def check(self, x, v, elastic: float) -> float | None:
        """E / E_ref where it exceeds ``GROWTH_LIMIT``, else None."""
        ratio = self.energy(x, v, elastic) / self.reference
        return ratio if ratio > GROWTH_LIMIT else None
