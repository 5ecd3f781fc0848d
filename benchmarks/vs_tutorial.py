"""ipcsim against the simulator of the lecture it teaches from: lessons 3, 4 and 7 of
phys-sim-book/solid-sim-tutorial, side by side.

    python -m benchmarks.vs_tutorial [--lessons 3_contact,4_friction,7_self_contact]
        [--steps N | --duration S] [--out DIR]

The tutorial's half: each lesson runs headless from
``../shared/solid-sim-tutorial/<lesson>/``, never copied into this repository and never
imported by ipcsim. Its ``simulator.py`` sets the lesson up and then draws with pygame
in a loop; the set-up part (everything before ``# simulation with visualization``, less
the pygame lines) is executed as written, with the lesson's folder first on
``sys.path``, and the loop's own call ``[x, v] = time_integrator.step_forward(...)``,
read from the same file, is executed once per step. pygame is not needed. The lesson's
printing goes to a null stream.

Per step (at its end): the centre of mass of the bodies' nodes (the node that carries a
moving ceiling is not one of them), the kinetic energy ½ Σ m|v|², the lesson's own
potential energies (elasticity, gravity, barrier: its modules' ``val`` functions, read
where the lesson computes them) and their total, and the wall time of the step.
``run_tutorial_lesson`` returns them as arrays (``TutorialRun``), for the comparison
with ipcsim's run of the same set-up; ``main`` writes them as CSV rows,
``tutorial_<lesson>.csv`` in ``--out``.

ipcsim's half: the lesson's scene, ``input/tutorial/<lesson>.toml`` (the same set-up
with the tutorial's conventions), stepped by ``ipcsim.Simulation`` with the same
quantities per step (``run_ipcsim_lesson``). ``compare`` gives the largest distance
between the two centre-of-mass trajectories over the run as a fraction of the scene's
size (the bodies' largest extent at the start) and the median wall time per step of
each; ``main`` prints them, writes ``ipcsim_<lesson>.csv`` beside the tutorial's and
draws ``vs_tutorial.png`` (centre-of-mass heights and wall time per step).

When the tutorial's folder is absent, ``main`` says so and exits 0.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = REPO_ROOT.parent / "shared" / "solid-sim-tutorial"
DEFAULT_OUT = REPO_ROOT / "output" / "vs_tutorial"
LESSONS = ("3_contact", "4_friction", "7_self_contact")

# where simulator.py's set-up ends and its drawing loop begins
_SETUP_END = "# simulation with visualization"
_STEP_CALL = re.compile(r"^\s*(\[x, v\] = time_integrator\.step_forward\(.*\))\s*$", re.M)


@dataclass(frozen=True)
class LessonEnergies:
    """The lesson's potential energies as expressions in its simulator's names (its
    time integrator's ``IP_val`` sums the same calls), and how many of its nodes belong
    to the bodies (the rest carry a kinematic ceiling)."""

    elastic: str
    barrier: str
    body_nodes: str


ENERGIES = {
    "3_contact": LessonEnergies(
        "MassSpringEnergy.val(x, e, l2, k)",
        "BarrierEnergy.val(x, y_ground, contact_area)", "len(x)"),
    "4_friction": LessonEnergies(
        "MassSpringEnergy.val(x, e, l2, k)",
        "BarrierEnergy.val(x, ground_n, ground_o, contact_area)", "len(x)"),
    "7_self_contact": LessonEnergies(
        "NeoHookeanEnergy.val(x, e, vol, IB, mu_lame, lam)",
        "BarrierEnergy.val(x, ground_n, ground_o, bp, be, contact_area)", "len(x) - 1"),
}

COLUMNS = ("lesson", "step", "time", "com_x", "com_y", "kinetic", "gravity", "elastic",
           "barrier", "total", "wall_s")


class TutorialMissing(RuntimeError):
    """The tutorial's folder (or one lesson of it) is not there."""


@dataclass(frozen=True)
class TutorialRun:
    """One lesson's run in the tutorial's simulator: row i is the state after step i + 1
    (row 0 of ``com`` and the energies is the start, before any step: they have one row
    more than ``wall_s``). ``h`` is the lesson's time step, ``x``/``v`` the final nodes."""

    lesson: str
    h: float
    com: np.ndarray  # (steps + 1, 2)
    kinetic: np.ndarray  # (steps + 1,)
    gravity: np.ndarray
    elastic: np.ndarray
    barrier: np.ndarray
    wall_s: np.ndarray  # (steps,)
    x: np.ndarray
    v: np.ndarray

    @property
    def total(self) -> np.ndarray:
        return self.kinetic + self.gravity + self.elastic + self.barrier

    @property
    def times(self) -> np.ndarray:
        return self.h * np.arange(self.com.shape[0])


def lesson_folder(lesson: str, root: Path = TUTORIAL) -> Path:
    folder = root / lesson
    if not (folder / "simulator.py").is_file():
        raise TutorialMissing(f"{folder}: no simulator.py (the tutorial is not there)")
    return folder


def setup_source(simulator: Path) -> tuple[str, str]:
    """(set-up code, step statement) of a lesson's simulator.py: the lines before its
    drawing loop without the pygame ones, and the loop's call of step_forward."""
    text = simulator.read_text()
    head, found, _ = text.partition(_SETUP_END)
    if not found:
        raise ValueError(f"{simulator}: no '{_SETUP_END}' line to end the set-up at")
    call = _STEP_CALL.search(text)
    if call is None:
        raise ValueError(f"{simulator}: no '[x, v] = time_integrator.step_forward(...)' line")
    setup = "\n".join(line for line in head.splitlines() if "pygame" not in line)
    return setup, call.group(1)


@contextlib.contextmanager
def _lesson_imports(folder: Path):
    """The lesson's folder first on sys.path, and none of another lesson's modules (they
    share names: time_integrator, BarrierEnergy, ...) in sys.modules, before and after."""
    def forget():
        for name, module in list(sys.modules.items()):
            where = getattr(module, "__file__", None) or ""
            if where.startswith(str(folder.parent)):
                del sys.modules[name]

    forget()
    sys.path.insert(0, str(folder))
    try:
        yield
    finally:
        sys.path.remove(str(folder))
        forget()


def _energies(ns: dict, spec: LessonEnergies, nb: int) -> tuple[float, float, float, float]:
    x, v, m = ns["x"], ns["v"], np.asarray(ns["m"], dtype=float)
    kinetic = 0.5 * float(np.sum(m[:nb] * np.sum(v[:nb] ** 2, axis=1)))
    gravity = float(ns["GravityEnergy"].val(x[:nb], m[:nb]))
    return kinetic, gravity, float(eval(spec.elastic, ns)), float(eval(spec.barrier, ns))


def _centre_of_mass(ns: dict, nb: int) -> np.ndarray:
    m = np.asarray(ns["m"], dtype=float)[:nb]
    return (m[:, None] * ns["x"][:nb]).sum(axis=0) / m.sum()


@contextlib.contextmanager
def tutorial_setup(lesson: str, root: Path = TUTORIAL):
    """The lesson set up as its simulator.py does it (the namespace its set-up code
    leaves, with its energy modules imported), while its modules are importable; and the
    compiled step statement. Within the block the lesson's printing goes to a sink."""
    folder = lesson_folder(lesson, root)
    setup, step = setup_source(folder / "simulator.py")
    with _lesson_imports(folder), contextlib.redirect_stdout(io.StringIO()) as sink:
        ns: dict = {"__name__": f"tutorial_{lesson}", "__sink__": sink}
        exec(compile(setup, str(folder / "simulator.py"), "exec"), ns)
        for module in ("GravityEnergy", "BarrierEnergy", "MassSpringEnergy", "NeoHookeanEnergy"):
            if (folder / f"{module}.py").is_file():
                exec(f"import {module}", ns)
        yield ns, compile(step, str(folder / "simulator.py"), "exec")


def run_tutorial_lesson(lesson: str, steps: int | None = None, duration: float | None = None,
                        root: Path = TUTORIAL) -> TutorialRun:
    """Run ``steps`` steps of a lesson (or as many as ``duration`` seconds of simulated
    time take at the lesson's h; 100 steps without either) in the tutorial's own code."""
    spec = ENERGIES[lesson]
    with tutorial_setup(lesson, root) as (ns, step_code):
        h = float(ns["h"])
        n = steps if steps is not None else (
            int(round(duration / h)) if duration is not None else 100)
        nb = int(eval(spec.body_nodes, ns))
        rows = [(_centre_of_mass(ns, nb), _energies(ns, spec, nb))]
        wall = np.empty(n)
        sink = ns["__sink__"]
        for i in range(n):
            t0 = time.perf_counter()
            exec(step_code, ns)
            wall[i] = time.perf_counter() - t0
            sink.seek(0)
            sink.truncate()
            rows.append((_centre_of_mass(ns, nb), _energies(ns, spec, nb)))
    energies = np.array([r[1] for r in rows])
    return TutorialRun(lesson, h, np.array([r[0] for r in rows]), energies[:, 0],
                       energies[:, 1], energies[:, 2], energies[:, 3], wall,
                       np.array(ns["x"], dtype=float), np.array(ns["v"], dtype=float))


def run_ipcsim_lesson(lesson: str, steps: int | None = None,
                      duration: float | None = None) -> TutorialRun:
    """The lesson's scene run by ipcsim, as ``run_tutorial_lesson`` runs the tutorial:
    the centre of mass and wall time per step (the energies: ipcsim's kinetic energy and
    its terms' values, where the step reports them; NaN for the others)."""
    import ipcsim

    model = ipcsim.build_model(ipcsim.load_scene(REPO_ROOT / "input" / "tutorial"
                                                 / f"{lesson}.toml"))
    sim = ipcsim.Simulation(model)
    h = model.dt
    n = steps if steps is not None else (
        int(round(duration / h)) if duration is not None else 100)
    mass = np.asarray(model.mass)

    def com(x):
        return (mass[:, None] * x[:, :2]).sum(axis=0) / mass.sum()

    coms, kinetic, elastic, wall = [com(sim.state.x)], [0.0], [0.0], np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        report = sim.step()
        wall[i] = time.perf_counter() - t0
        coms.append(com(sim.state.x))
        kinetic.append(report.row["kinetic_energy"])
        elastic.append(report.row["elastic_energy"])
    nan = np.full(n + 1, np.nan)
    return TutorialRun(lesson, h, np.array(coms), np.array(kinetic), nan, np.array(elastic),
                       nan, wall, sim.state.x[:, :2].copy(), sim.state.v[:, :2].copy())


@dataclass(frozen=True)
class Comparison:
    """A lesson in both: the largest centre-of-mass distance over the run, as a fraction
    of the scene's size, and the median wall time per step of each (s)."""

    lesson: str
    com_error: float
    tutorial_step_s: float
    ipcsim_step_s: float

    @property
    def speed_ratio(self) -> float:
        """ipcsim's median step time over the tutorial's."""
        return self.ipcsim_step_s / self.tutorial_step_s


def scene_size(lesson: str) -> float:
    """The bodies' largest extent at the start of the lesson's scene (m)."""
    import ipcsim

    model = ipcsim.build_model(ipcsim.load_scene(REPO_ROOT / "input" / "tutorial"
                                                 / f"{lesson}.toml"))
    x = model.initial_positions[:, :2]
    return float((x.max(axis=0) - x.min(axis=0)).max())


def compare(tutorial: TutorialRun, ours: TutorialRun) -> Comparison:
    steps = min(tutorial.com.shape[0], ours.com.shape[0])
    gap = np.linalg.norm(tutorial.com[:steps] - ours.com[:steps], axis=1).max()
    return Comparison(tutorial.lesson, float(gap) / scene_size(tutorial.lesson),
                      float(np.median(tutorial.wall_s)), float(np.median(ours.wall_s)))


def chart(pairs: list[tuple[TutorialRun, TutorialRun]], path: Path) -> Path:
    """Centre-of-mass heights of both runs, and their wall times per step, by lesson."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(pairs), figsize=(4.5 * len(pairs), 6), squeeze=False)
    for j, (tut, ours) in enumerate(pairs):
        top, bottom = axes[0, j], axes[1, j]
        top.plot(tut.times, tut.com[:, 1], label="tutorial", lw=2.5, alpha=0.6)
        top.plot(ours.times, ours.com[:, 1], label="ipcsim", lw=1.0)
        top.set_title(tut.lesson)
        top.set_xlabel("t (s)")
        top.set_ylabel("centre of mass y (m)")
        top.legend()
        bottom.semilogy(tut.times[1:], tut.wall_s * 1e3, label="tutorial")
        bottom.semilogy(ours.times[1:], ours.wall_s * 1e3, label="ipcsim")
        bottom.set_xlabel("t (s)")
        bottom.set_ylabel("wall time per step (ms)")
        bottom.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def csv_rows(run: TutorialRun) -> list[dict]:
    """One row per state (step 0: the start, with no wall time)."""
    rows = []
    for i in range(run.com.shape[0]):
        rows.append({
            "lesson": run.lesson, "step": i, "time": f"{i * run.h:.6g}",
            "com_x": f"{run.com[i, 0]:.17g}", "com_y": f"{run.com[i, 1]:.17g}",
            "kinetic": f"{run.kinetic[i]:.17g}", "gravity": f"{run.gravity[i]:.17g}",
            "elastic": f"{run.elastic[i]:.17g}", "barrier": f"{run.barrier[i]:.17g}",
            "total": f"{run.total[i]:.17g}",
            "wall_s": "" if i == 0 else f"{run.wall_s[i - 1]:.6g}",
        })
    return rows


def write_csv(run: TutorialRun, out: Path, side: str = "tutorial") -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{side}_{run.lesson}.csv"
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(csv_rows(run))
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.vs_tutorial",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--lessons", default=",".join(LESSONS),
                    help="comma-separated lesson folders (default: %(default)s)")
    length = ap.add_mutually_exclusive_group()
    length.add_argument("--steps", type=int, help="steps per lesson (default 100)")
    length.add_argument("--duration", type=float, help="simulated seconds per lesson")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT,
                    help="CSV folder (default: %(default)s)")
    args = ap.parse_args(argv)
    lessons = [s for s in args.lessons.split(",") if s]
    unknown = [s for s in lessons if s not in ENERGIES]
    if unknown:
        ap.error(f"unknown lesson {unknown[0]!r}; known: {', '.join(ENERGIES)}")
    if not TUTORIAL.is_dir():
        print(f"skipped: {TUTORIAL} is not there (the tutorial's code is never part of "
              "this repository)")
        return 0
    pairs = []
    for lesson in lessons:
        run = run_tutorial_lesson(lesson, args.steps, args.duration)
        write_csv(run, args.out)
        ours = run_ipcsim_lesson(lesson, args.steps, args.duration)
        write_csv(ours, args.out, "ipcsim")
        pairs.append((run, ours))
        c = compare(run, ours)
        print(f"{lesson}: {run.wall_s.size} steps of h = {run.h:g} s; centre of mass apart "
              f"by at most {c.com_error:.2e} of the scene's size; median step "
              f"{c.tutorial_step_s * 1e3:.2f} ms (tutorial), {c.ipcsim_step_s * 1e3:.2f} ms "
              f"(ipcsim): {c.speed_ratio:.3f} of the tutorial's")
    print(f"chart: {chart(pairs, args.out / 'vs_tutorial.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
