"""Accuracy per second: position error against wall time, ipcsim beside the original.

    python -m benchmarks.accuracy [--only NAME] [--duration S] [--levels N] [--repeats N]
        [--ipc-lib-path DIRS] [--work DIR] [--out DIR] [--threads N] [--timeout S]
        [--no-original] [--checkout] [--keep-runs] [--smoke] [--tolerances T,T,...]

Each scene of :data:`SCENES` is run by both programs over a ladder of time steps
h0, h0/2, ..., h0/2^(levels-1), once per integrator of :data:`VARIANTS` (backward Euler
and Newmark in both programs, BDF2 in ipcsim), and twice more per program at much
smaller steps, its references (2^ref_gap and 2^(ref_gap+1) times finer than the
ladder's finest h, with :data:`REFERENCE_INTEGRATOR`: the original's Newmark, ipcsim's
BDF2, or Newmark on a contact-free scene). A run's error is

    error = sqrt(mean over sample times t and surface vertices i of |x_i(t) − x_ref,i(t)|²) / l

against the finer reference of its own model (its program's), so that small differences
between the models do not count; l is the scene size (ipcsim's rest bounding-box
diagonal of the tet shapes, the l of d̂ and τ). The sample times are the multiples of
h0 up to the duration (t = 0 left out); the vertices are those of the original's
``<n>.obj`` frames, the vertices of the surface triangles in global order, which ipcsim
compares by the same index (``ipcsim.io.compare``). Steps land on the sample times;
so do both programs' frames (about every 0.01 s, every step above; a run whose frames
would miss them gets a ``playBackSpeed`` line that makes them denser, the same line in
both programs). ipcsim's frames are its ``.vtu`` files, the original's its ``<n>.obj``.

Convergence of the references: the two references are compared like any run; the
scene's check passes when their difference is at most 10 % of the smallest error
reported for that program. Errors below 10× that difference are marked unresolved
(``*``) and left out of the observed orders (the least-squares slope of log error
against log h over the resolved runs of a ladder).

Wall time is the whole process (``benchmarks.vs_original.run_timed``: the original's
own command without its wrapper, ``ipcsim run`` as a user runs it), the median over
``--repeats``; ipcsim runs each scene's first steps untimed first (numba's cache). The
time-to-accuracy table gives, per scene and target error, each program's fastest run
within it (its error plus its references' difference at most the target) and the
ratio of the two wall times. Energy over time (kinetic + elastic + gravity's) at the
scene's own h, and of the adaptive runs, for the scenes marked ``energy``: ipcsim's from
steps.csv and its frames (``benchmarks.newmark_impacts.ipcsim_energy``), the original's
from its ``sysE.txt`` (its own per-body sums, as newmark_impacts reads them).

Prints the tables with the command, machine, date and load; a full run writes
``accuracy.csv``, ``accuracy_table.md``, ``accuracy_<scene>.png`` (error against wall
time, unresolved runs crossed out) and ``accuracy_energy_<scene>.png`` into ``--out``
(default docs/benchmarks/).
``--smoke`` runs two coarse steps and two references of a small scene into a temporary
folder (well under a minute). A partial run (``--smoke``, ``--only``, ``--duration``,
``--levels``) writes files only where ``--out`` says. Without the original
(not installed, its libraries not found: ``--ipc-lib-path``, default ``$IPC_LIB_PATH``)
or with ``--no-original``, ipcsim's half runs alone.

Adding an integrator is one line of :data:`VARIANTS` (``Variant("ipcsim", "BDF2")``).
``--tolerances 1e-2,1e-3`` adds ipcsim's adaptive BDF2 over that τ ladder: a variant
with a tolerance runs once, at the scene's own h (its first and largest step). They are
not in the default list: on scenes with impacts their steps resolve the barrier's
bounce and take long (docs/numerics.md, "BDF2 and adaptive time steps"). On a scene
with contact they solve another model than the fixed steps do: their barrier has the
stiffness of the scene's dt at every step (κ = κ_max), a fixed step's has κ/h² (a
stiffer barrier at a finer h), so their error is taken against references of their
own model, adaptive BDF2 at τ_min / 30 and τ_min / 300 (:data:`ADAPTIVE_REFERENCE`,
τ_min the smallest τ asked), checked like the others (:func:`model_of`). Without
contact the two models are one, and every run has the fixed-step references.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import hashlib
import json
import math
import statistics
import sys
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from benchmarks import speed_accuracy as sa
from benchmarks import vs_original as vo
from benchmarks.newmark_impacts import ipcsim_energy, original_energy

REPO_ROOT = vo.REPO_ROOT
DEFAULT_OUT = REPO_ROOT / "docs" / "benchmarks"
DEFAULT_WORK = REPO_ROOT / "output" / "accuracy"
TARGETS = (1e-2, 1e-3, 1e-4)  # errors of the time-to-accuracy table, / l
TOLERANCES = (1e-2, 1e-3, 1e-4)  # τ of adaptive variants, / l
ADAPTIVE_REFERENCE = (30.0, 300.0)  # adaptive references at the smallest τ / these
RESOLVED = 10.0  # an error is resolved when ≥ this × its references' difference
FRAME_DT = 0.01  # s: both programs' frame spacing at playBackSpeed 1
PLAYBACK_FRAME_DT = 0.03  # s: frame spacing per unit playBackSpeed below 1 (both programs)


@dataclass(frozen=True)
class Variant:
    """One kind of run: a program and its integrator (a ``timeIntegration`` line);
    ``tolerance`` τ makes it adaptive (a ``timeTolerance`` line, ipcsim's extension of
    the format), run once at the scene's own h, its first and largest step."""

    program: str  # "original" | "ipcsim"
    integrator: str  # "BE" | "NM" | "BDF2"
    tolerance: float | None = None

    @property
    def name(self) -> str:
        tau = "" if self.tolerance is None else f" τ={self.tolerance:g}"
        return f"{self.program} {self.integrator}{tau}"

    @property
    def slug(self) -> str:
        return self.integrator + ("" if self.tolerance is None else f"_tau{self.tolerance:g}")

    def lines(self) -> tuple[str, ...]:
        tau = () if self.tolerance is None else (f"timeTolerance {self.tolerance:g}",)
        return (f"timeIntegration {self.integrator}", *tau)


# Every kind of run measured, one line each (module docstring).
VARIANTS = (
    Variant("original", "BE"),
    Variant("original", "NM"),
    Variant("ipcsim", "BE"),
    Variant("ipcsim", "NM"),
    Variant("ipcsim", "BDF2"),
)
# each program's references: the original's Newmark (it has no BDF2); ipcsim's BDF2, not
# Newmark, which gains energy at impacts, so that its references of contact scenes converge;
# without contact (Scene.contact_free) Newmark, as the original's: it is the more accurate
# there (its error is a quarter of BDF2's at every h of the spinning bar)
REFERENCE_INTEGRATOR = {"original": "NM", "ipcsim": "BDF2"}
PROGRAMS = ("original", "ipcsim")


# ------------------------------------------------------------------------ the scenes


def _repo_script(rel: str) -> Callable[[Path], str]:
    return lambda stage: (REPO_ROOT / rel).read_text(encoding="utf-8")


def _example_script(rel: str) -> Callable[[Path], str]:
    """A script of the original's examples (FileNotFoundError where they are absent)."""
    return lambda stage: (vo.EXAMPLES_INPUT / rel).read_text(encoding="utf-8")


def _generated(name: str, res: int) -> Callable[[Path], str]:
    """A scene of benchmarks/speed_accuracy at ``res`` cells per edge: its meshes written
    under the stage's ``input/accuracy/<name>/``, where both programs find them."""
    def make(stage: Path) -> str:
        folder = stage / "input" / "accuracy" / f"{name}_r{res}"
        folder.mkdir(parents=True, exist_ok=True)
        meshes = sa.write_meshes(sa.SCENES[name], res, folder)
        names = [f"input/{m.relative_to(stage / 'input').as_posix()}" for m in meshes]
        return sa.scene_text(sa.SCENES[name], sa.Settings(res=res), 1.0, names)
    return make


@dataclass(frozen=True)
class Scene:
    """A scene of the benchmark: its script (``make(stage)`` writes what it needs under
    the stage and returns the text), how long, and its ladder of time steps."""

    name: str
    title: str
    duration: float  # s simulated (the sample times run to it)
    h0: float  # the ladder's largest h, and the spacing of the sample times
    levels: int  # the ladder: h0, h0/2, ..., h0/2^(levels-1)
    default_h: float  # the scene's own h: the energy chart's runs, adaptive runs' first h
    make: Callable[[Path], str] = field(compare=False)
    ref_gap: int = 3  # references 2^ref_gap and 2^(ref_gap+1) times finer than the finest
    energy: bool = False  # chart the energy over time (undamped scenes)
    contact_free: bool = False  # no contact: ipcsim's references by Newmark too
    programs: tuple[str, ...] = PROGRAMS

    def ladder(self) -> tuple[float, ...]:
        return tuple(self.h0 / 2 ** k for k in range(self.levels))

    def reference_integrator(self, program: str) -> str:
        return "NM" if self.contact_free else REFERENCE_INTEGRATOR[program]

    def references(self) -> tuple[float, float]:
        finest = self.h0 / 2 ** (self.levels - 1)
        return finest / 2 ** self.ref_gap, finest / 2 ** (self.ref_gap + 1)

    def sample_times(self) -> np.ndarray:
        return self.h0 * np.arange(1, round(self.duration / self.h0) + 1)


_TB1 = "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.025.txt"
SCENES = (
    Scene("spinning_bar", "a soft bar released spinning, no gravity, no contact "
          "(input/spinning_bar.txt)", 1.0, 0.05, 7, 0.025,
          _repo_script("input/spinning_bar.txt"), energy=True, contact_free=True,
          ref_gap=2),  # at 2^3 and 2^4 ipcsim's finer reference drifts by round-off
    Scene("two_cubes", "two soft cubes fall onto frictionless ground and each other "
          "(speed_accuracy two_cubes, 2 cells per edge)", 1.0, 0.05, 7, 0.025,
          _generated("two_cubes", 2), energy=True),
    Scene("stack", "three cubes drop and settle with friction (speed_accuracy stack, "
          "2 cells per edge)", 1.5, 0.05, 7, 0.025, _generated("stack", 2)),
    Scene("twisted_bar", "a bar twisted until it coils onto itself, self contact "
          "(speed_accuracy twisted_bar, 2 cells across)", 1.0, 0.05, 7, 0.025,
          _generated("twisted_bar", 2)),
    Scene("tb1_rods_twist", f"four rods twisted into each other, 3 s ({_TB1})", 3.0, 0.2,
          6, 0.025, _example_script(_TB1), ref_gap=2),
)
# run only when named by --only: the 6 s tb1 rods of the adaptive-step criterion
EXTRA = (
    Scene("tb1_rods_twist_6s", f"four rods twisted into each other, 6 s ({_TB1})", 6.0,
          0.2, 6, 0.025, _example_script(_TB1), ref_gap=2, programs=("ipcsim",)),
)
SMOKE = Scene("two_cubes_smoke", "two cubes, 1 cell per edge, 0.3 s", 0.3, 0.05, 2, 0.025,
              _generated("two_cubes", 1), ref_gap=1, energy=True)


def frame_lines(h: float, sample_dt: float) -> tuple[str, ...]:
    """A ``playBackSpeed`` line where the frames of a run at ``h`` would miss the sample
    times: both programs write a frame every round(0.01 / h) steps (every step above
    0.01 s), or every round(0.03 p / h) with ``playBackSpeed p`` below 1; p is chosen
    so that the frames fall every sample_dt / 2^j, the largest such spacing ≤ 0.01 s."""
    every = max(1, round(FRAME_DT / h))
    if round(sample_dt / h) % every == 0:
        return ()
    spacing = sample_dt
    while spacing > FRAME_DT * (1 + 1e-9):
        spacing /= 2
    if round(sample_dt / h) % max(1, round(spacing / h)) != 0:
        raise ValueError(f"h = {h:g} s does not divide the sample spacing {sample_dt:g} s")
    return (f"playBackSpeed {spacing / PLAYBACK_FRAME_DT!r}",)


# ------------------------------------------------------------------------ the runs


@dataclass
class Measured:
    """One run (its repeats) of one variant at one h."""

    scene: str
    variant: Variant
    h: float
    role: str  # "ladder" | "reference"
    folder: Path
    script: Path
    runs: list = field(default_factory=list)  # vo.Run per repeat
    error: float | None = None
    resolved: bool | None = None
    reference_difference: float | None = None  # its program's two references' difference

    @property
    def last(self):
        return self.runs[-1] if self.runs else None

    @property
    def ok(self) -> bool:
        return bool(self.runs) and self.last.rc == 0

    @property
    def wall_s(self) -> float | None:
        walls = [r.wall_s for r in self.runs if r.rc == 0]
        return statistics.median(walls) if walls else None


def stage_run(scene: Scene, text: str, variant: Variant, h: float, role: str,
              stage: Path, work: Path) -> Measured:
    """The run's copy of the script (its ``time``, integrator and frame lines) and its
    output folder."""
    lines = variant.lines() + frame_lines(h, scene.h0)
    script = stage / "scripts" / f"acc_{scene.name}_{variant.program}_{variant.slug}_h{h:g}.txt"
    script.write_text(vo.shortened(text, scene.duration, h, lines), encoding="utf-8")
    folder = work / "runs" / scene.name / variant.program / variant.slug / f"h{h:g}"
    return Measured(scene.name, variant, h, role, folder, script)


def execute(m: Measured, stage: Path, s: vo.Settings, keep: bool) -> None:
    """Run ``m`` once more (or, with ``keep``, take the run a former benchmark saved for
    the same script)."""
    saved = m.folder.with_name(m.folder.name + ".json")
    digest = hashlib.sha256(m.script.read_bytes()).hexdigest()
    if keep and not m.runs and saved.is_file():
        data = json.loads(saved.read_text(encoding="utf-8"))
        if data.get("script_sha256") == digest:
            m.runs = [vo.Run(**r) for r in data["runs"]]
            return
    runner = vo.run_original if m.variant.program == "original" else vo.run_ipcsim
    m.runs.append(runner(m.script, m.folder, stage, s))
    saved.write_text(json.dumps({"script_sha256": digest,
                                 "runs": [asdict(r) for r in m.runs]}), encoding="utf-8")


def model_of(scene: Scene, v: Variant) -> str:
    """The contact model a run solves, whose references score it: each program's
    fixed-step model (its barrier κ/h², as in the original), and ipcsim's adaptive one
    (the barrier of the scene's dt at every step, κ = κ_max: docs/numerics.md) where
    the scene has contact; without contact the two are the same model."""
    adaptive = v.tolerance is not None and not scene.contact_free
    return f"{v.program} adaptive" if adaptive else v.program


def references(scene: Scene, variants) -> list[tuple[Variant, float]]:
    """(variant, h) of each model's two references: fixed steps 2^ref_gap and
    2^(ref_gap+1) times finer than the ladder's finest h; adaptive BDF2 at τ_min / 30
    and τ_min / 300 (the smallest τ asked) from the scene's own h."""
    out = []
    for program in scene.programs:
        if any(v.program == program for v in variants):
            ref = Variant(program, scene.reference_integrator(program))
            out += [(ref, h) for h in scene.references()]
    adaptive = [v.tolerance for v in variants
                if v.program in scene.programs and model_of(scene, v).endswith("adaptive")]
    if adaptive:
        out += [(Variant("ipcsim", "BDF2", min(adaptive) / f), scene.default_h)
                for f in ADAPTIVE_REFERENCE]
    return out


def plan(scene: Scene, text: str, variants, stage: Path, work: Path) -> list[Measured]:
    """Every run of the scene: each model's two references, then each variant over the
    ladder (an adaptive variant at the scene's own h)."""
    runs = [stage_run(scene, text, ref, h, "reference", stage, work)
            for ref, h in references(scene, variants)]
    for v in variants:
        if v.program in scene.programs:
            hs = scene.ladder() if v.tolerance is None else (scene.default_h,)
            runs += [stage_run(scene, text, v, h, "ladder", stage, work) for h in hs]
    return runs


def warm_up(scene: Scene, runs: list[Measured], stage: Path, s: vo.Settings) -> None:
    """ipcsim, untimed: two steps of each ipcsim variant, so numba's cache is warm."""
    seen = set()
    for m in runs:
        if m.variant.program == "ipcsim" and m.variant not in seen:
            seen.add(m.variant)
            vo.run_ipcsim(m.script, s.work / "warmup" / scene.name, stage, s, steps=2)


def measure(runs: list[Measured], stage: Path, s: vo.Settings, repeats: int,
            keep: bool) -> None:
    """The references once, the ladder runs ``repeats`` times (the variants' order
    reversed every other repeat, so that a drifting load falls on all alike)."""
    for m in runs:
        if m.role == "reference":
            execute(m, stage, s, keep)
            s.say(f"  {m.scene} {m.variant.name} reference h = {m.h:g}: "
                  f"{m.last.wall_s:.2f} s, exit {m.last.rc}")
    ladder = [m for m in runs if m.role == "ladder"]
    for r in range(repeats):
        for m in (ladder if r % 2 == 0 else ladder[::-1]):
            if len(m.runs) > r:
                continue  # kept from a former benchmark
            execute(m, stage, s, keep)
            s.say(f"  {m.scene} {m.variant.name} h = {m.h:g}: {m.last.wall_s:.2f} s, "
                  f"exit {m.last.rc} (repeat {r + 1}/{repeats})")


# ------------------------------------------------------------------------ errors


def _at(times: np.ndarray, t: float, tol: float) -> int | None:
    k = int(np.argmin(np.abs(times - t))) if len(times) else -1
    return k if k >= 0 and abs(times[k] - t) <= tol else None


def trajectory(m: Measured, times: np.ndarray) -> np.ndarray | None:
    """Surface positions (len(times), n, 3) of the run at the sample times; None when a
    sample time has no frame (a failed run)."""
    from ipcsim.io.compare import read_obj_vertices, surface_vertices
    from ipcsim.io.render import RenderError, load_run_frames
    from ipcsim.io.vtk import read_frame

    tol = 1e-6 * m.h
    if m.variant.program == "original":
        paths = [m.folder / f"{round(t / m.h)}.obj" for t in times]
        if any(not p.is_file() or abs(round(t / m.h) * m.h - t) > tol
               for p, t in zip(paths, times)):
            return None
        return np.stack([read_obj_vertices(p) for p in paths])
    try:
        run = load_run_frames(m.folder)
    except RenderError:
        return None
    found = [_at(np.asarray(run.times, dtype=float), t, tol) for t in times]
    if None in found:
        return None
    index = surface_vertices(read_frame(run.paths[0]))
    return np.stack([np.asarray(read_frame(run.paths[k]).points)[index] for k in found])


def rms_error(x: np.ndarray | None, ref: np.ndarray | None, size: float) -> float | None:
    """sqrt(mean over times and vertices of |x − x_ref|²) / l."""
    if x is None or ref is None or x.shape != ref.shape:
        return None
    return float(np.sqrt(np.mean(np.sum((x - ref) ** 2, axis=-1))) / size)


@dataclass
class Check:
    """A model's references on a scene: their difference against the smallest error
    reported for its runs."""

    references: str  # whose and which, e.g. "ipcsim's references h = 0.001 and 0.0005 s"
    difference: float | None
    smallest: float | None

    @property
    def passed(self) -> bool | None:
        if self.difference is None or self.smallest is None:
            return None
        return self.difference <= 0.1 * self.smallest


def _references_named(refs: list[Measured]) -> str:
    program, tau = refs[0].variant.program, refs[0].variant.tolerance
    named = (f"{program}'s references h = {refs[0].h:g} and {refs[1].h:g} s" if tau is None
             else f"{program}'s adaptive references τ = {tau:g} and "
             f"{refs[1].variant.tolerance:g}")
    failed = [f"{m.variant.name} h = {m.h:g}: exit {m.last.rc if m.last else '?'}"
              for m in refs if not m.ok]
    return named + (f" (failed: {'; '.join(failed)})" if failed else "")


def score(scene: Scene, runs: list[Measured], size: float) -> list[Check]:
    """Each run's error against the finer reference of its model; the references' check."""
    times = scene.sample_times()
    checks = []
    for model in dict.fromkeys(model_of(scene, m.variant) for m in runs):
        ours = [m for m in runs if model_of(scene, m.variant) == model]
        refs = [m for m in ours if m.role == "reference"]
        if len(refs) != 2:
            continue
        coarse, fine = (trajectory(m, times) for m in refs)
        difference = rms_error(coarse, fine, size)
        for m in ours:
            if m.role == "ladder" and m.ok:
                m.error = rms_error(trajectory(m, times), fine, size)
                m.reference_difference = difference
                if m.error is not None and difference is not None:
                    m.resolved = m.error >= RESOLVED * difference
        errors = [m.error for m in ours if m.role == "ladder" and m.error is not None]
        checks.append(Check(_references_named(refs), difference,
                            min(errors) if errors else None))
    return checks


class Result(NamedTuple):
    """A scene's runs, its references' checks and its size l (m)."""

    scene: Scene
    runs: list[Measured]
    checks: list[Check]
    size: float


def observed_order(points: list[tuple[float, float]]) -> float | None:
    """Least-squares slope of log error against log h (None below two points)."""
    pts = [(h, e) for h, e in points if e and e > 0]
    if len(pts) < 2:
        return None
    return float(np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)[0])


def orders(runs: list[Measured]) -> dict[str, float | None]:
    """Each fixed-step variant's observed order over its resolved ladder runs."""
    out = {}
    for v in dict.fromkeys(m.variant for m in runs if m.role == "ladder"):
        if v.tolerance is None:
            out[v.name] = observed_order([(m.h, m.error) for m in runs if m.variant == v
                                          and m.role == "ladder" and m.resolved])
    return out


def fastest_within(runs: list[Measured], program: str, target: float) -> Measured | None:
    """The program's fastest run (of every variant) whose error is within ``target``
    even if its reference were off by the two references' difference."""
    within = [m for m in runs if m.role == "ladder" and m.variant.program == program
              and m.error is not None and m.reference_difference is not None
              and m.error + m.reference_difference <= target and m.wall_s is not None]
    return min(within, key=lambda m: m.wall_s) if within else None


def scene_size(scene: Scene, text: str, stage: Path) -> float:
    """l of the scene: ipcsim's rest bounding-box diagonal of its tet shapes."""
    from ipcsim.model.build import build_model
    from ipcsim.scene import load_scene

    script = stage / "scripts" / f"acc_{scene.name}_size.txt"
    script.write_text(vo.shortened(text, scene.default_h, scene.default_h), encoding="utf-8")
    with contextlib.chdir(stage):  # where the script's input/... paths resolve
        return float(build_model(load_scene(script)).bbox_diagonal)


# ------------------------------------------------------------------------ energy


def energy_series(m: Measured, stage: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """(times, total energy) of a finished run from its first step on (ipcsim logs no
    step 0): ipcsim's at its frames (steps.csv and the frames), the original's at every
    step (sysE.txt)."""
    if not m.ok:
        return None
    try:
        if m.variant.program == "original":
            by_step = original_energy(m.folder)
            steps = sorted(k for k in by_step if k > 0)
            return np.array(steps) * m.h, np.array([by_step[k] for k in steps])
        from ipcsim.io.csv_log import read_csv

        by_step = ipcsim_energy(m.folder, m.script, stage)
        log = read_csv(m.folder / "steps.csv")
        time_of = dict(zip(log["step"].tolist(), log["time"].tolist()))
        steps = sorted(k for k in by_step if k in time_of)
        return np.array([time_of[k] for k in steps]), np.array([by_step[k] for k in steps])
    except (OSError, ValueError, KeyError):
        return None


# ------------------------------------------------------------------------ tables


def _e(x) -> str:
    return "–" if x is None else f"{x:.2e}"


def _s(x) -> str:
    return "–" if x is None else (f"{x:.0f}" if x >= 100 else f"{x:.2f}")


def _cell(m: Measured | None) -> str:
    if m is None or not m.runs:
        return ""
    if not m.ok:
        return f"exit {m.last.rc}"
    mark = "*" if m.resolved is False else ""
    return f"{_e(m.error)}{mark} ({_s(m.wall_s)} s)"


def error_table(runs: list[Measured]) -> str:
    """Rows h, columns variants: error (wall s); ``*`` unresolved."""
    variants = list(dict.fromkeys(m.variant for m in runs if m.role == "ladder"))
    hs = sorted({m.h for m in runs if m.role == "ladder"}, reverse=True)
    lines = ["| h (s) | " + " | ".join(v.name for v in variants) + " |",
             "|---|" + "---|" * len(variants)]
    for h in hs:
        cells = [_cell(next((m for m in runs if m.variant == v and m.h == h
                             and m.role == "ladder"), None)) for v in variants]
        lines.append(f"| {h:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def check_lines(checks: list[Check]) -> list[str]:
    out = []
    for c in checks:
        verdict = {True: "converged", False: "NOT converged: finer references needed",
                   None: "cannot tell"}[c.passed]
        ratio = (f" = {c.difference / c.smallest:.2g} of it" if c.difference is not None
                 and c.smallest else "")
        out.append(f"{c.references} differ by "
                   f"{_e(c.difference)}; the smallest error reported {_e(c.smallest)}"
                   f"{ratio}: {verdict} (passes at ≤ 10 %)")
    return out


TOLERANCE_FACTOR = 3.0  # an adaptive run meets its τ when its error is at most this × τ


def tolerance_lines(runs: list[Measured]) -> list[str]:
    """Each adaptive run's error against its τ (met when ≤ 3τ and resolved)."""
    out = []
    for m in runs:
        tau = m.variant.tolerance
        if m.role != "ladder" or tau is None:
            continue
        if m.error is None:
            why = f"exit {m.last.rc}" if m.last and not m.ok else "no finished reference"
            out.append(f"{m.variant.name}: no error ({why})")
            continue
        verdict = ("unresolved: the references differ by more than a tenth of it"
                   if not m.resolved else "met" if m.error <= TOLERANCE_FACTOR * tau
                   else "NOT met")
        out.append(f"{m.variant.name}: error {_e(m.error)} = {m.error / tau:.2f} τ "
                   f"(≤ {TOLERANCE_FACTOR:g} τ: {verdict})")
    return out


def accuracy_table(results: list[Result]) -> str:
    """Per scene and target: each program's fastest run within it, and the ratio."""
    lines = [("| scene | target error | original: fastest run within it | ipcsim: fastest "
              "run within it | ipcsim / original wall time |"), "|---|---|---|---|---|"]
    for scene, runs, _, _ in results:
        for target in TARGETS:
            best = {p: fastest_within(runs, p, target) for p in PROGRAMS}
            text = {p: "none" if b is None else f"{b.variant.integrator}"
                    f"{'' if b.variant.tolerance is None else f' τ={b.variant.tolerance:g}'}"
                    f", h = {b.h:g}: {_e(b.error)} in {_s(b.wall_s)} s"
                    for p, b in best.items()}
            ratio = (f"{best['ipcsim'].wall_s / best['original'].wall_s:.3f}"
                     if best["ipcsim"] and best["original"] else "–")
            lines.append(f"| {scene.name} | {target:g} | {text['original']} | "
                         f"{text['ipcsim']} | {ratio} |")
    return "\n".join(lines)


def header(info: dict, s: vo.Settings, command: str) -> str:
    """The command, the machine, the date and the load, and what the numbers are."""
    return (f"Command: `{command}`  \n"
            f"Machine: {info['cpu']}, {info['cores']} cores, {info['memory']}; Python "
            f"{info['python']}, ipcsim {info['ipcsim']} (commit {info.get('commit') or '?'})"
            f"  \nDate: {info['date']}; load average (1, 5, 15 min) {info['load_before']} "
            f"before, {info.get('load_after', '')} after; {s.threads} thread(s) per "
            f"program; outputs on {info.get('output_fs') or 'an unknown file system'}.  \n"
            "Error: position RMS over the sample times and surface vertices against the "
            "finer reference of its own model, / l; in brackets the whole process's wall "
            "time (median of the repeats); * below 10× the references' difference.")


def report(results, info: dict, s: vo.Settings, command: str) -> str:
    """The whole report: header, then per scene its errors, check and orders, then the
    time to accuracy."""
    parts = [header(info, s, command)]
    for scene, runs, checks, size in results:
        order = orders(runs)
        parts.append(f"### {scene.name}: {scene.title}\n\n"
                     f"{scene.duration:g} s, sample times every {scene.h0:g} s, l = "
                     f"{size:.4g} m\n\n"
                     + error_table(runs) + "\n\n"
                     + "\n".join(f"* {line}" for line in check_lines(checks)
                                 + tolerance_lines(runs)) + "\n"
                     + "* observed orders (resolved runs): " + ", ".join(
                         f"{k} {'–' if v is None else f'{v:.2f}'}" for k, v in order.items()))
    parts.append("### Time to accuracy\n\n" + accuracy_table(results))
    return "\n\n".join(parts)


CSV_FIELDS = ("scene", "program", "integrator", "tolerance", "role", "h", "rc", "error",
              "resolved", "wall_s", "wall_all", "steps", "newton_per_step", "cpu_s",
              "peak_mb", "date", "cpu", "cores", "load_before", "load_after", "threads")


def csv_rows(results, info: dict, s: vo.Settings) -> list[dict]:
    rows = []
    for result in results:
        for m in result.runs:
            last = m.last
            rows.append({
                "scene": m.scene, "program": m.variant.program,
                "integrator": m.variant.integrator, "tolerance": m.variant.tolerance,
                "role": m.role, "h": m.h, "rc": None if last is None else last.rc,
                "error": m.error, "resolved": m.resolved, "wall_s": m.wall_s,
                "wall_all": " ".join(f"{r.wall_s:.3f}" for r in m.runs),
                **({k: getattr(last, k) for k in ("steps", "newton_per_step", "cpu_s",
                                                  "peak_mb")} if last else {}),
                **{k: info.get(k) for k in ("date", "cpu", "cores", "load_before",
                                            "load_after")}, "threads": s.threads})
    return rows


# ------------------------------------------------------------------------ charts


def _style(v: Variant) -> dict:
    colours = {"BE": "C0", "NM": "C1", "BDF2": "C2"}
    return {"color": colours.get(v.integrator, "C3"),
            "linestyle": "--" if v.program == "original" else "-",
            "marker": "s" if v.program == "original" else "o",
            "markerfacecolor": "none" if v.tolerance is not None else None}


def error_chart(scene: Scene, runs: list[Measured], info: dict, path: Path) -> None:
    """Error against whole-process wall time, one line per variant, log-log."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5))
    for v in dict.fromkeys(m.variant for m in runs if m.role == "ladder"):
        pts = sorted((m.wall_s, m.error, m.h) for m in runs if m.variant == v
                     and m.role == "ladder" and m.error and m.wall_s)
        if not pts:
            continue
        ax.plot([p[0] for p in pts], [p[1] for p in pts], label=v.name, **_style(v))
        for w, e, h in pts:
            ax.annotate(f"{h:g}", (w, e), fontsize=6, xytext=(3, 2), textcoords="offset points")
    unresolved = [(m.wall_s, m.error) for m in runs if m.role == "ladder" and m.error
                  and m.wall_s and m.resolved is False]
    if unresolved:  # crossed out: below 10× their references' difference
        ax.plot(*zip(*unresolved), "x", color="grey", markersize=9, linestyle="none",
                label="unresolved (below 10× the references' difference)")
    for target in TARGETS:
        ax.axhline(target, color="grey", linewidth=0.6, linestyle=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the whole process (s)")
    ax.set_ylabel("position RMS error / scene size")
    ax.set_title(f"{scene.name}: error against wall time (labels: h in s)\n"
                 f"{info['date'][:10]}, {info['cores']} cores, load "
                 f"{info['load_before'].split(' ')[0]}", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def energy_chart(scene: Scene, runs: list[Measured], stage: Path, path: Path) -> bool:
    """Total energy over time, relative to the first value, of every fixed-step variant
    at the scene's own h and of every adaptive run (dotted, one colour per τ); False
    when there is nothing to draw."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    drawn = False
    taus = sorted({m.variant.tolerance for m in runs if m.variant.tolerance is not None},
                  reverse=True)
    for m in runs:
        if m.role != "ladder" or not math.isclose(m.h, scene.default_h):
            continue
        series = energy_series(m, stage)
        if series is None or not len(series[0]) or series[1][0] == 0:
            continue
        style = _style(m.variant) | {"marker": None}
        if m.variant.tolerance is not None:
            style |= {"linestyle": ":", "color": f"C{3 + taus.index(m.variant.tolerance)}"}
        ax.plot(series[0], series[1] / series[1][0], label=m.variant.name, **style)
        drawn = True
    ax.set_xlabel("time (s)")
    ax.set_ylabel("total energy / its value after the first step")
    ax.set_title(f"{scene.name}: kinetic + elastic + gravity's energy, h = "
                 f"{scene.default_h:g} s, no damping", fontsize=9)
    ax.grid(True, alpha=0.3)
    if drawn:
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
    plt.close(fig)
    return drawn


def write_outputs(results, info: dict, s: vo.Settings, text: str, stage: Path,
                  out: Path) -> list[Path]:
    """accuracy.csv, accuracy_table.md and the charts in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "accuracy.csv", out / "accuracy_table.md"]
    with open(paths[0], "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(csv_rows(results, info, s))
    paths[1].write_text("<!-- written by `python -m benchmarks.accuracy` -->\n\n" + text
                        + "\n", encoding="utf-8")
    for scene, runs, _, _ in results:
        paths.append(out / f"accuracy_{scene.name}.png")
        error_chart(scene, runs, info, paths[-1])
        if scene.energy and energy_chart(scene, runs, stage,
                                         out / f"accuracy_energy_{scene.name}.png"):
            paths.append(out / f"accuracy_energy_{scene.name}.png")
    return paths


# ------------------------------------------------------------------------ main


def select(args) -> list[Scene]:
    """--smoke's scene, or the list's (and the extras') named by --only, cut to
    --duration and --levels."""
    if args.smoke:
        return [SMOKE]
    scenes = list(SCENES)
    if args.only:
        scenes = [sc for sc in SCENES if any(o in sc.name for o in args.only)] \
            + [sc for sc in EXTRA if sc.name in args.only]
    if args.duration:
        scenes = [replace(sc, duration=max(sc.h0, sc.h0 * math.floor(
            min(args.duration, sc.duration) / sc.h0 + 1e-9))) for sc in scenes]
    if args.levels:
        scenes = [replace(sc, levels=min(args.levels, sc.levels)) for sc in scenes]
    return scenes


def _tolerances(text: str) -> tuple[float, ...]:
    try:
        taus = tuple(float(t) for t in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of numbers: {text!r}") from None
    if not all(0 < t < 1 for t in taus):
        raise argparse.ArgumentTypeError(f"each τ must lie in (0, 1): {text!r}")
    return taus


def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", action="append", metavar="NAME",
                    help="the scenes whose name contains it (an extra scene by its full "
                    "name: tb1_rods_twist_6s); repeatable")
    ap.add_argument("--duration", type=float, metavar="S",
                    help="cut every scene to at most S s (a multiple of its h0)")
    ap.add_argument("--levels", type=int, metavar="N",
                    help="only the N coarsest h of each ladder (the references follow)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per ladder point "
                    "(median; default 3, --smoke 1)")
    ap.add_argument("--ipc-lib-path", default=vo.os.environ.get("IPC_LIB_PATH", ""),
                    metavar="DIRS", help="folders (':'-separated) with the original's "
                    "runtime libraries, for its process only (default: $IPC_LIB_PATH)")
    ap.add_argument("--work", type=Path, help="folder for the runs (default output/"
                    "accuracy; with --smoke a temporary one)")
    ap.add_argument("--out", type=Path, help="where the CSV, table and charts go (default "
                    "docs/benchmarks; with --smoke nowhere unless given)")
    ap.add_argument("--threads", type=int, default=1, help="threads per program (default 1)")
    ap.add_argument("--timeout", type=float, default=3600.0, metavar="S",
                    help="seconds allowed per run (default 3600)")
    ap.add_argument("--no-original", action="store_true", help="ipcsim's runs only")
    ap.add_argument("--checkout", action="store_true", help="run this checkout's ipcsim "
                    "(python -m ipcsim.cli) instead of the one installed beside this Python")
    ap.add_argument("--keep-runs", action="store_true", help="reuse the runs a former "
                    "benchmark left in WORK for the same scripts (to finish an interrupted one)")
    ap.add_argument("--smoke", action="store_true", help="a small scene, two coarse steps "
                    "and two references, into a temporary folder")
    ap.add_argument("--tolerances", type=_tolerances, default=(), metavar="T,T,...",
                    help="add ipcsim's adaptive BDF2 at these τ (timeTolerance), each run "
                    "once from the scene's own h")
    args = ap.parse_args(argv)
    for name in ("repeats", "threads", "timeout", "duration", "levels"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            ap.error(f"--{name.replace('_', '-')} must be positive")
    return args


def run_scene(scene: Scene, stage: Path, s: vo.Settings, args, variants) -> Result | None:
    """Stage, warm up, measure and score one scene; None when its script is not here."""
    try:
        text = scene.make(stage)
    except FileNotFoundError as exc:
        s.say(f"{scene.name}: skipped ({exc.filename} is not here)")
        return None
    s.say(f"{scene.name}: ladder {', '.join(f'{h:g}' for h in scene.ladder())} s, "
          f"references {', '.join(f'{h:g}' for h in scene.references())} s")
    size = scene_size(scene, text, stage)
    runs = plan(scene, text, variants, stage, s.work)
    warm_up(scene, runs, stage, s)
    measure(runs, stage, s, 1 if args.smoke else args.repeats, args.keep_runs)
    return Result(scene, runs, score(scene, runs, size), size)


def run_benchmark(args, work: Path) -> tuple | None:
    s = vo.Settings(work, args.threads, args.timeout, args.ipc_lib_path, say=print,
                    checkout=args.checkout)
    stage = vo.stage_input(work)
    why = "--no-original" if args.no_original else vo.can_run_original(stage, s)
    variants = [v for v in VARIANTS if v.program == "ipcsim" or why is None]
    variants += [Variant("ipcsim", "BDF2", tau) for tau in args.tolerances]
    if why:
        print(f"accuracy: the original is not run: {why}")
    info = vo.machine() | {"output_fs": vo.file_system(work)}
    results = [r for sc in select(args) if (r := run_scene(sc, stage, s, args, variants))]
    info["load_after"] = vo._load()
    return results, info, s, stage


def main(argv=None) -> int:
    args = parse_args(argv)
    command = "python -m benchmarks.accuracy " + " ".join(argv if argv is not None
                                                          else sys.argv[1:])
    with tempfile.TemporaryDirectory(prefix="accuracy_") as tmp:
        work = (args.work or (Path(tmp) if args.smoke else DEFAULT_WORK)).resolve()
        results, info, s, stage = run_benchmark(args, work)
        if not results:
            print("accuracy: no scene to run")
            return 0
        text = report(results, info, s, command.strip())
        print(text)
        partial = args.smoke or args.only or args.duration or args.levels
        out = args.out or (None if partial else DEFAULT_OUT)
        if out is None:
            print("accuracy: a partial run writes no files unless --out names a folder")
        else:
            for path in write_outputs(results, info, s, text, stage, out):
                print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
