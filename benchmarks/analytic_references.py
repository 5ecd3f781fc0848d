"""Analytic references: runs whose exact answer is known, and how far ipcsim is from it.

    python -m benchmarks.analytic_references [--smoke] [--out DIR]

Cases (generated tet meshes, scenes written to a temporary folder, run with Simulation):

a. free fall, backward Euler and Newmark: centre-of-mass drop against the discrete
   solution of the integrator and the continuous one, ½ g t²;
b. a block on an incline tan θ = ½: μ = 0.3 slides at g (sin θ − μ cos θ); μ = 0.6 sticks
   but for the smoothed friction's creep, ε_v (1 − √(1 − tan θ/μ)) < ε_v;
c. total linear momentum Σ m v across a head-on collision of two bodies in free space,
   frictionless and frictional (off centre, sliding sideways);
d. a cube resting on the ground: rest gap against d̂ and against the gap at which the
   barrier carries the weight, drift of the centre of mass;
e. a contact-free vibration (a bar set moving in its first elastic mode, no gravity):
   energy per step of backward Euler against its exact decay 1/(1 + ω²h²), and of
   Newmark (β = ¼, γ = ½), which conserves it.

Prints a markdown table, writes every row to ``analytic_references.csv`` and case e's
energy history to ``energy_oscillation.png`` in ``--out`` (default docs/benchmarks/).
``--smoke`` runs each case for a few steps only (the CI test does this). Wall seconds
are those of the measured steps (building the model and loading kernels excluded).
"""

from __future__ import annotations

import argparse
import csv
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import msgspec
import numpy as np
import scipy.linalg
from scipy.optimize import brentq

from ipcsim.kernels.contact.barrier import barrier_first_derivative
from ipcsim.model.build import build_model
from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.scene import load_scene
from ipcsim.model.model import GRAVITY
from ipcsim.simulation import Simulation

G = -GRAVITY[1]
DEFAULT_OUT = Path(__file__).resolve().parents[1] / "docs" / "benchmarks"

# run lengths (steps) of the full benchmark and of the CI smoke version
FULL = dict(fall=50, incline_settle=20, slide=100, stick_settle=30, stick=100,
            collision=40, rest_settle=100, rest=200, oscillation=300)
SMOKE = dict(fall=5, incline_settle=10, slide=10, stick_settle=30, stick=10,
             collision=12, rest_settle=25, rest=10, oscillation=12)


@dataclass
class Row:
    """One measured quantity against its analytic value. ``bound`` is the acceptance the
    physics or the discretisation implies (NaN where the answer is a plain value)."""

    case: str
    quantity: str
    measured: float
    analytic: float
    error: float
    error_kind: str  # "relative" or "absolute" (in the quantity's unit)
    bound: float
    steps: int
    h: float
    wall_s: float


def _rel(measured, analytic) -> float:
    return abs(measured - analytic) / abs(analytic)


def _simulation(folder: Path, name: str, text: str) -> Simulation:
    scene = folder / f"{name}.txt"
    scene.write_text(text)
    return Simulation(build_model(load_scene(scene)))


def _mesh(folder: Path, name: str, cells, size, origin) -> Path:
    return write_msh(folder / f"{name}.msh", *box_tet_mesh(*cells, size=size, origin=origin))


def _run(sim: Simulation, steps: int, each=None) -> float:
    """Takes ``steps`` steps (calling ``each(sim, row)`` after each); returns wall seconds."""
    t0 = time.perf_counter()
    for _ in range(steps):
        row = sim.step().row
        if not row["converged"]:
            raise RuntimeError(f"step {row['step']} did not converge")
        if each is not None:
            each(sim, row)
    return time.perf_counter() - t0


def _centre_of_mass(sim: Simulation) -> np.ndarray:
    m = sim.model.mass
    return (m[:, None] * sim.state.x).sum(axis=0) / m.sum()


# -- a. free fall ---------------------------------------------------------------------
def free_fall(folder: Path, steps: int) -> list[Row]:
    """A cube falls for n steps of h = 0.02 s. Backward Euler's discrete solution is
    vₖ₊₁ = vₖ + h g, xₖ₊₁ = xₖ + h vₖ₊₁ ⇒ drop h² g n(n+1)/2, which exceeds ½ g t² by
    ½ g h t. Newmark with γ = ½ integrates constant acceleration exactly: both are ½ g t²."""
    mesh = _mesh(folder, "cube", (2, 2, 2), (0.2, 0.2, 0.2), (-0.1, -0.1, -0.1))
    h, n = 0.02, steps
    rows = []
    for integrator, discrete in (("BE", h * h * G * n * (n + 1) / 2), ("NM", 0.5 * G * (n * h) ** 2)):
        sim = _simulation(folder, f"fall_{integrator}",
                          f"shapes input 1\n{mesh} 0 0.3 0  0 0 0  1 1 1\nselfCollisionOff\n"
                          f"stiffness 1e5 0.4\ntime 5 {h}\ntimeIntegration {integrator}\n")
        y0 = _centre_of_mass(sim)[1]
        wall = _run(sim, n)
        drop = y0 - _centre_of_mass(sim)[1]
        continuous = 0.5 * G * (n * h) ** 2
        for label, exact in (("discrete", discrete), ("continuous ½gt²", continuous)):
            rows.append(Row(f"a. free fall, {integrator}", f"drop (m) vs {label}", drop, exact,
                            _rel(drop, exact), "relative", np.nan, n, h, wall))
    return rows


# -- b. incline -----------------------------------------------------------------------
SLOPE_NORMAL = np.array([1.0, 2.0, 0.0]) / np.sqrt(5.0)  # tan θ = ½
SLOPE_DOWN = np.array([2.0, -1.0, 0.0]) / np.sqrt(5.0)
SIN, COS = 1.0 / np.sqrt(5.0), 2.0 / np.sqrt(5.0)


def _incline(folder: Path, mu: float) -> Simulation:
    """A block lying flat on a half space through the origin tilted by θ, 0.5 mm above it.
    Newton's tolerance is 1e-4 (as in the original's friction scripts): the default 1e-2
    allows 3e-5 m per step (tol·l·h), over ten times the creep per step measured here and
    a sixth of the sliding block's a·h²."""
    mesh = _mesh(folder, "block", (2, 1, 2), (0.2, 0.1, 0.2), (-0.1, 0.0, -0.1))
    lift = 5e-4 * SLOPE_NORMAL
    theta = np.degrees(np.arctan(0.5))
    return _simulation(folder, f"incline_{mu}",
                       f"shapes input 1\n{mesh} {lift[0]} {lift[1]} 0  0 0 {-theta}  1 1 1\n"
                       f"halfSpace 0 0 0  1 2 0  50 {mu}\nselfCollisionOff\n"
                       "stiffness 1e7 0.3\ntime 5 0.01\ntol 1\n1e-4\n")


def incline_sliding(folder: Path, settle: int, steps: int) -> list[Row]:
    """μ = 0.3 < tan θ: after landing, the mean velocity along the slope grows linearly at
    a = g (sin θ − μ cos θ); measured by a least-squares line through (t, v)."""
    mu = 0.3
    sim = _incline(folder, mu)
    _run(sim, settle)
    times, speeds = [], []

    def record(sim, row):
        times.append(row["time"])
        speeds.append(sim.state.v.mean(axis=0) @ SLOPE_DOWN)

    wall = _run(sim, steps, record)
    accel = np.polyfit(times, speeds, 1)[0]
    exact = G * (SIN - mu * COS)
    return [Row("b. incline, μ = 0.3 (slides)", "acceleration along the slope (m/s²)", accel,
                exact, _rel(accel, exact), "relative", np.nan, steps, sim.h, wall)]


def incline_sticking(folder: Path, settle: int, steps: int) -> list[Row]:
    """μ = 0.6 > tan θ: static friction holds the block; the exact answer is no motion.
    Smoothed friction lets it creep instead, at the slip rate where μ λ f₁ balances the
    pull m g sin θ (λ = m g cos θ): f₁ = 2y/ε − y²/ε² = tan θ/μ, y/ε = v/ε_v, so
    v = ε_v (1 − √(1 − tan θ/μ)) < ε_v. Measured by a least-squares line through (t, s)."""
    mu = 0.6
    sim = _incline(folder, mu)
    _run(sim, settle)
    x0 = _centre_of_mass(sim)
    times, slides = [], []

    def record(sim, row):
        times.append(row["time"])
        slides.append((_centre_of_mass(sim) - x0) @ SLOPE_DOWN)

    wall = _run(sim, steps, record)
    creep = np.polyfit(times, slides, 1)[0]
    epsv = sim.model.epsv
    exact = epsv * (1.0 - np.sqrt(1.0 - (SIN / COS) / mu))
    case = "b. incline, μ = 0.6 (sticks)"
    return [Row(case, "creep speed along the slope (m/s) vs smoothed friction", creep, exact,
                _rel(creep, exact), "relative", epsv, steps, sim.h, wall),
            Row(case, f"slide in {steps * sim.h:g} s (m) vs Coulomb", slides[-1], 0.0,
                abs(slides[-1]), "absolute", epsv * steps * sim.h, steps, sim.h, wall)]


# -- c. momentum ----------------------------------------------------------------------
def _collision(folder: Path, name: str, steps: int, mu: float, offset: float,
               sideways: float) -> list[Row]:
    """Two blocks meet head on along x in free space (no gravity, no planes): contact and
    friction are internal forces, so Σ m v must not change, in any step."""
    mesh = _mesh(folder, "block", (2, 1, 2), (0.2, 0.1, 0.2), (-0.1, 0.0, -0.1))
    fric = f"selfFric {mu}\n" if mu > 0 else ""
    sim = _simulation(folder, name,
                      "shapes input 2\n"
                      f"{mesh} 0 0 0  0 0 0  1 1 1  initVel 1 0 {sideways}  0 0 0\n"
                      f"{mesh} 0.215 {offset} 0  0 0 0  1 1 1  initVel -0.5 0 {-sideways}  0 0 0\n"
                      f"turnOffGravity\n{fric}stiffness 1e6 0.3\ntime 1 0.01\ntol 1\n1e-6\n")
    mass = sim.model.mass
    p0 = (mass[:, None] * sim.state.v).sum(axis=0)
    history = [p0]
    touched = frictional = 0

    def record(sim, row):
        nonlocal touched, frictional
        history.append((mass[:, None] * sim.state.v).sum(axis=0))
        touched += row["contacts_total"] > 0
        frictional += bool(row["friction_contacts"])

    wall = _run(sim, steps, record)
    if not touched or (mu > 0 and not frictional):
        raise RuntimeError(f"{name}: no {'frictional ' if mu > 0 else ''}contact happened")
    p = np.array(history)
    scale = np.linalg.norm(p0)
    per_step = np.linalg.norm(np.diff(p, axis=0), axis=1).max() / scale
    overall = np.linalg.norm(p[-1] - p0) / scale
    label = f"c. collision, {'μ = %g, off centre' % mu if mu > 0 else 'frictionless'}"
    return [Row(label, "max ‖Δp‖ in one step / ‖p₀‖", per_step, 0.0, per_step, "relative",
                np.nan, steps, sim.h, wall),
            Row(label, "‖p_end − p₀‖ / ‖p₀‖", overall, 0.0, overall, "relative", np.nan,
                steps, sim.h, wall)]


def collision_frictionless(folder: Path, steps: int) -> list[Row]:
    return _collision(folder, "collide", steps, mu=0.0, offset=0.0, sideways=0.0)


def collision_frictional(folder: Path, steps: int) -> list[Row]:
    """Off centre by half a block height and sliding sideways at 1 m/s relative, so the
    contact is frictional and the impact also makes the blocks turn."""
    return _collision(folder, "collide_fric", steps, mu=0.4, offset=0.05, sideways=0.5)


# -- d. resting contact ---------------------------------------------------------------
def _weight_gap(sim: Simulation, n_contacts: int) -> float:
    """The gap d at which n equal plane contacts carry the weight. At rest x = xₙ = x̃, so
    the step's optimality is h²(∇Ψ − M g) + κ ∇B = 0; summed over vertices (∇Ψ sums to 0):
    n κ (−∂b(d², d̂²)/∂d) = h² M g, with ∂b/∂d = 2 d b'(d²)."""
    dhat2, kappa = sim.model.dhat ** 2, sim.state.kappa
    weight = sim.h ** 2 * sim.model.mass.sum() * G

    def balance(d):
        return -n_contacts * kappa * 2.0 * d * barrier_first_derivative(d * d, dhat2) - weight

    return brentq(balance, 1e-30 * sim.model.dhat, sim.model.dhat * (1 - 1e-12), xtol=1e-16)


def resting_cube(folder: Path, settle: int, steps: int) -> list[Row]:
    """A stiff cube (E = 1e7, so its bottom stays flat) set down 1 mm above the ground
    settles and must then stay put: every gap in (0, d̂), the bottom's mean gap near the
    gap of equal contacts carrying the weight, no drift. Newton tolerance 1e-5·l·h
    (7e-8 m), well below d̂ (3.5e-4 m), so the rest state is resolved."""
    mesh = _mesh(folder, "rest_cube", (2, 2, 2), (0.2, 0.2, 0.2), (-0.1, 0.0, -0.1))
    h = 0.02
    sim = _simulation(folder, "rest", f"shapes input 1\n{mesh} 0 0.001 0  0 0 0  1 1 1\n"
                      f"ground 0 0\nselfCollisionOff\nstiffness 1e7 0.4\ntime 10 {h}\n"
                      "tol 1\n1e-5\n")
    _run(sim, settle)
    rest = sim.model.rest_positions[:, 1]
    bottom = np.flatnonzero(rest == rest.min())
    c0 = _centre_of_mass(sim)
    lowest, highest = np.inf, 0.0

    def record(sim, row):
        nonlocal lowest, highest
        lowest = min(lowest, sim.state.x[:, 1].min())
        highest = max(highest, sim.state.x[bottom, 1].max())

    wall = _run(sim, steps, record)
    dhat = sim.model.dhat
    carried = _weight_gap(sim, len(bottom))
    gap = float(sim.state.x[bottom, 1].mean())
    drift = float(np.linalg.norm(_centre_of_mass(sim) - c0))
    case = "d. cube resting on the ground"
    return [Row(case, "mean bottom gap (m) vs equal contacts carrying the weight", gap, carried,
                _rel(gap, carried), "relative", dhat, steps, h, wall),
            Row(case, "smallest gap while resting / d̂, in (0, 1)", lowest / dhat,
                carried / dhat, _rel(lowest, carried), "relative", 1.0, steps, h, wall),
            Row(case, "largest bottom gap while resting / d̂, in (0, 1)", highest / dhat,
                carried / dhat, _rel(highest, carried), "relative", 1.0, steps, h, wall),
            Row(case, "centre-of-mass drift (m)", drift, 0.0, drift, "absolute", np.nan,
                steps, h, wall)]


# -- e. energy in a contact-free vibration --------------------------------------------
def _first_mode(sim: Simulation) -> tuple[float, np.ndarray]:
    """(ω, φ) of the lowest elastic mode at rest: K φ = ω² M φ, the six rigid modes skipped.
    φ is M-orthogonal to the rigid modes, so it carries no momentum."""
    x = sim.state.x
    K = sim.potential.term("elasticity").hessian(x).tocsr(x.size).toarray()
    M = np.repeat(sim.model.mass, 3)
    w2, modes = scipy.linalg.eigh(K, np.diag(M))
    return float(np.sqrt(w2[6])), modes[:, 6].reshape(-1, 3)


def oscillation(folder: Path, steps: int, amplitude: float = 1e-3) -> tuple[list[Row], dict]:
    """A free bar (0.6 × 0.1 × 0.1 m, E = 1e5) starts at rest shape with velocity ω a φ
    (amplitude a = 1 mm, small enough to be linear). For the linearised system the energy
    E = ½vᵀMv + ½uᵀKu after each backward Euler step is 1/(1 + ω²h²) of the one before
    (the step is a rotation scaled by √(1 + ω²h²) in (ω u, v)); the trapezoidal rule
    (Newmark β = ¼, γ = ½) keeps it exactly."""
    mesh = _mesh(folder, "bar", (6, 2, 2), (0.6, 0.1, 0.1), (-0.3, -0.05, -0.05))
    h = 0.01
    rows, history = [], {"h": h}
    for integrator in ("BE", "NM"):
        sim = _simulation(folder, f"osc_{integrator}",
                          f"shapes input 1\n{mesh} 0 0 0  0 0 0  1 1 1\nturnOffGravity\n"
                          "selfCollisionOff\nstiffness 1e5 0.3\ntime 10 0.01\n"
                          f"timeIntegration {integrator}\ntol 1\n1e-7\n")
        omega, phi = _first_mode(sim)
        v0 = omega * amplitude / np.abs(phi).max() * phi  # rest shape: a₀ = 0 holds
        sim.state = msgspec.structs.replace(sim.state, v=v0)
        energy = [0.5 * float(np.einsum("i,ij,ij->", sim.model.mass, sim.state.v, sim.state.v))]
        wall = _run(sim, steps, lambda s, row: energy.append(row["kinetic_energy"]
                                                              + row["elastic_energy"]))
        energy = np.array(energy)
        history[integrator] = energy
        history["omega"] = omega
        period_steps = 2.0 * np.pi / (omega * h)
        if integrator == "BE":
            # least-squares decay rate per step of ln E, then the loss over one period 2π/ω
            ratio = np.exp(np.polyfit(np.arange(len(energy)), np.log(energy), 1)[0])
            exact = 1.0 / (1.0 + (omega * h) ** 2)
            lost, lost_exact = 1 - ratio ** period_steps, 1 - exact ** period_steps
            rows += [Row("e. vibration, BE", "energy ratio per step", ratio, exact,
                         _rel(ratio, exact), "relative", np.nan, steps, h, wall),
                     Row("e. vibration, BE", "fraction of energy lost per period", lost,
                         lost_exact, _rel(lost, lost_exact), "relative", np.nan, steps, h, wall)]
        else:
            drift = np.abs(energy - energy[0]).max() / energy[0]
            rows.append(Row("e. vibration, NM β=¼ γ=½", "largest energy change / E₀", drift, 0.0, drift,
                            "relative", np.nan, steps, h, wall))
    return rows, history


# -- output ---------------------------------------------------------------------------
def run_all(folder: Path, settings: dict) -> tuple[list[Row], dict]:
    s = settings
    rows = free_fall(folder, s["fall"])
    rows += incline_sliding(folder, s["incline_settle"], s["slide"])
    rows += incline_sticking(folder, s["stick_settle"], s["stick"])
    rows += collision_frictionless(folder, s["collision"])
    rows += collision_frictional(folder, s["collision"])
    rows += resting_cube(folder, s["rest_settle"], s["rest"])
    osc_rows, history = oscillation(folder, s["oscillation"])
    return rows + osc_rows, history


def _number(x: float) -> str:
    if not np.isfinite(x):
        return "–"
    return "0" if x == 0 else f"{x:.4g}" if 1e-3 <= abs(x) < 1e4 else f"{x:.2e}"


def markdown(rows: list[Row]) -> str:
    lines = ["| case | quantity | measured | analytic | error | wall s |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        analytic = _number(r.analytic)
        if np.isfinite(r.bound):
            analytic += f" (bound {_number(r.bound)})"
        error = _number(r.error) + (" rel." if r.error_kind == "relative" else "")
        lines.append(f"| {r.case} | {r.quantity} | {_number(r.measured)} | {analytic} "
                     f"| {error} | {r.wall_s:.2f} |")
    return "\n".join(lines)


def write_csv(rows: list[Row], path: Path) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(asdict(rows[0])))
        writer.writeheader()
        for r in rows:
            writer.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v)
                             for k, v in asdict(r).items()})


def plot_energy(history: dict, path: Path) -> None:
    """Left: E/E₀ of both integrators (log scale) with the exact BE decay; right: Newmark's
    small deviation from E₀."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h, omega = history["h"], history["omega"]
    be, nm = history["BE"], history["NM"]
    n = np.arange(len(be))
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    left.semilogy(h * n, be / be[0], "o", ms=2.5, label="backward Euler")
    left.semilogy(h * n, (1 + (omega * h) ** 2) ** -n, "-", lw=1,
                  label="exact BE: (1 + ω²h²)⁻ⁿ")
    left.semilogy(h * np.arange(len(nm)), nm / nm[0], "s", ms=2.5, label="Newmark β = ¼, γ = ½")
    left.set_xlabel("time (s)")
    left.set_ylabel("total energy / initial")
    left.legend(fontsize=8)
    right.plot(h * np.arange(len(nm)), nm / nm[0] - 1, "-", lw=1, color="C2")
    right.axhline(0.0, color="k", lw=0.8, ls="--")
    right.set_xlabel("time (s)")
    right.set_ylabel("Newmark: E / E₀ − 1")
    fig.suptitle(f"Free bar vibrating in its first elastic mode "
                 f"(ω = {omega:.2f} rad/s, h = {h} s, no gravity)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(smoke: bool, out: Path) -> list[Row]:
    """Runs every case, writes the CSV and the chart into ``out``, returns the rows."""
    with tempfile.TemporaryDirectory() as tmp:
        rows, history = run_all(Path(tmp), SMOKE if smoke else FULL)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(rows, out / "analytic_references.csv")
    plot_energy(history, out / "energy_oscillation.png")
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="a few steps per case (CI)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    print(markdown(run(args.smoke, args.out)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
