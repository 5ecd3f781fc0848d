"""Speed against accuracy: sweep one setting at a time, plot wall time against error.

    python -m benchmarks.speed_accuracy [--smoke] [--scene NAME] [--out DIR]

For each scene (``two_cubes``, ``stack``, ``twisted_bar``) the Newton tolerance, d̂, the
time step h and the mesh resolution are swept one at a time around the defaults, and every
run is compared with one reference run per scene that uses the finest value of all four
at once. Writes ``speed_accuracy.csv`` (one row per run) and one chart per scene,
``speed_accuracy_<scene>.png`` (wall time against error, log-log, Pareto front as a step
line, defaults circled), into ``docs/benchmarks/`` or ``--out``.

Error. Vertex sets differ between resolutions, so every run is measured at the same
material points whatever the mesh: per body a lattice of points (corners, edge and face
midpoints and more; interpolated linearly inside their rest tet) and its centre of mass.
With y(t) these points at the sample times t = 0.05 s, 0.1 s, … (every h swept divides
0.05 s) and l the diagonal of the scene's rest bounding box,

    error = sqrt(mean over t, landmarks of |y(t) − y_ref(t)|²) / l.

Wall time is the sum of the steps' wall times (``wall_s`` of steps.csv), so numba
compilation is excluded; one warm-up run precedes the measurements, and each sweep run is
timed up to three times, the fastest kept. ``--smoke`` runs one
scene with two settings for a few steps into a temporary folder (for CI).

Not a study (``ipcsim sweep``): the mesh resolution it sweeps is a new mesh per value,
not a value of one scene; its error is taken at material points inside the rest tets,
sampled every 0.05 s while the run steps in this process, not from frames of equal meshes;
and it times each run up to three times, keeping the fastest. A study would carry all of
that as code of its own beside the study machinery.
"""

from __future__ import annotations

import argparse
import csv
import math
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ipcsim.model.build import build_model
from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO_ROOT / "docs" / "benchmarks"
SAMPLE_DT = 0.05  # s between compared samples; every swept h divides it
SMOKE_DURATION = 0.3  # s: long enough for the two cubes to touch the ground


@dataclass(frozen=True)
class Settings:
    """The four swept settings: Newton tol and d̂ relative to l (tol also × h), h in s,
    and the resolution r (cells per cube edge; the bar has 5r × r × r cells)."""

    tol: float = 1e-2
    dhat: float = 1e-3
    dt: float = 0.025
    res: int = 2


DEFAULTS = Settings()
REFERENCE = Settings(tol=1e-5, dhat=1e-4, dt=0.003125, res=5)
SWEEPS = {
    "tol": [1e-1, 1e-2, 1e-3, 1e-4],
    "dhat": [1e-2, 3e-3, 1e-3, 3e-4],
    "dt": [0.05, 0.025, 0.0125, 0.00625],
    "res": [1, 2, 3, 4],
    # one setting alone cannot go below the error the other three leave: refine together
    "combined": [Settings(1e-1, 3e-3, 0.05, 1), DEFAULTS, Settings(1e-3, 1e-3, 0.0125, 3),
                 Settings(1e-4, 3e-4, 0.00625, 4)],
}
LABELS = {"tol": "Newton tol", "dhat": "d̂", "dt": "time step h", "res": "cells per edge",
          "combined": "all four refined together"}
REPEATS = 3  # each sweep run is timed up to this many times, the fastest kept
REPEAT_BUDGET_S = 10.0  # no further repeats once a setting has used this much wall time


# ------------------------------------------------------------------------------ scenes
@dataclass
class Body:
    """One box-shaped body: its cells, size and placement (translation of its min corner)."""

    cells: tuple[int, int, int]
    size: tuple[float, float, float]
    origin: tuple[float, float, float]
    extras: str = ""  # DBC entries of the shape line


@dataclass
class SceneDef:
    """A benchmark scene: its bodies at resolution r and the keywords that do not vary."""

    name: str
    duration: float  # s
    bodies: Callable[[int], list[Body]]
    header: str  # scene keywords besides shapes, time, tol, dHat


def _two_cubes(res):
    """Two 1 m cubes, 0.2 m above the ground and 0.2 m apart, fall onto it and each other."""
    return [Body((res,) * 3, (1.0, 1.0, 1.0), (0.0, 0.2, 0.0)),
            Body((res,) * 3, (1.0, 1.0, 1.0), (0.1, 1.4, 0.1))]


def _stack(res):
    """Three 0.5 m cubes, 0.05 m apart in a column, drop and settle into a stack."""
    return [Body((res,) * 3, (0.5, 0.5, 0.5), (0.0, 0.05 + 0.55 * i, 0.0)) for i in range(3)]


def _twisted_bar(res):
    """A 1 × 0.1 × 0.1 m bar without gravity; its end faces turn in opposite senses about
    the bar's axis (360°/s each) and approach each other (0.35 m/s each): the bar buckles
    and coils onto itself from about t = 0.7 s."""
    ends = ("DBC -0.1 -0.1 -0.1  0.02 1.1 1.1   0.35 0 0   360 0 0 "
            "DBC  0.98 -0.1 -0.1  1.1 1.1 1.1  -0.35 0 0  -360 0 0")
    return [Body((5 * res, res, res), (1.0, 0.1, 0.1), (0.0, 0.0, 0.0), ends)]


SCENES = {
    "two_cubes": SceneDef("two_cubes", 1.0, _two_cubes,
                          "density 1000\nstiffness 1e5 0.4\nground 0 0\n"),
    "stack": SceneDef("stack", 1.5, _stack,  # without friction the column squirts apart
                      "density 1000\nstiffness 1e6 0.4\nground 0.5 0\nselfFric 0.5\n"),
    "twisted_bar": SceneDef("twisted_bar", 1.0, _twisted_bar,
                            "density 1000\nstiffness 1e5 0.4\nturnOffGravity\n"
                            "selfCollisionOn\n"),
}


def write_meshes(scene: SceneDef, res: int, folder: Path) -> list[Path]:
    """Write the scene's body meshes at resolution ``res`` into ``folder``."""
    out = []
    for i, b in enumerate(scene.bodies(res)):
        points, tets = box_tet_mesh(*b.cells, size=b.size)
        out.append(write_msh(folder / f"body{i}.msh", points, tets))
    return out


def scene_text(scene: SceneDef, s: Settings, duration: float, meshes: list[str]) -> str:
    """The text scene for settings ``s``, its bodies' meshes named as ``meshes`` says."""
    bodies = scene.bodies(s.res)
    lines = [f"shapes input {len(bodies)}"]
    for mesh, b in zip(meshes, bodies, strict=True):
        ox, oy, oz = b.origin
        lines.append(f"{mesh} {ox} {oy} {oz}  0 0 0  1 1 1 {b.extras}".rstrip())
    lines += [f"time {duration} {s.dt}", "tol 1", f"{s.tol}", f"dHat {s.dhat}", scene.header]
    return "\n".join(lines) + "\n"


def write_scene(scene: SceneDef, s: Settings, folder: Path, duration: float) -> tuple[Path, list]:
    """Write the meshes and the text scene for settings ``s``; returns (path, bodies)."""
    folder.mkdir(parents=True, exist_ok=True)
    meshes = write_meshes(scene, s.res, folder)
    path = folder / "scene.txt"
    path.write_text(scene_text(scene, s, duration, [m.name for m in meshes]))
    return path, scene.bodies(s.res)


def material_points(scene: SceneDef, model) -> tuple[np.ndarray, np.ndarray]:
    """The same material points on any mesh: per body a lattice with twice the cells of
    the coarsest mesh (3×3×3 points on a cube, 11×3×3 on the bar), each given as the 4
    vertices of the rest tet that contains it and its barycentric weights there."""
    x, tets = model.rest_positions, model.tets
    verts, weights = [], []
    for b, body in enumerate(scene.bodies(1)):
        axes = [np.linspace(o, o + w, 2 * c + 1)
                for o, w, c in zip(body.origin, body.size, body.cells)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        own = tets[model.vertex_shape[tets[:, 0]] == b]
        x0 = x[own[:, 0]]
        edges = np.stack([x[own[:, k]] - x0 for k in (1, 2, 3)], axis=-1)  # (m, 3, 3)
        # p = x0 + E λ  =>  λ = E⁻¹ (p − x0); inside when λ ≥ 0 and Σλ ≤ 1
        lam = np.einsum("mij,mqj->mqi", np.linalg.inv(edges), pts[None] - x0[:, None])
        bary = np.concatenate([1.0 - lam.sum(axis=-1, keepdims=True), lam], axis=-1)
        inside = np.argmax(bary.min(axis=-1), axis=0)  # the tet each point is most inside
        q = np.arange(len(pts))
        if np.any(bary[inside, q].min(axis=-1) < -1e-9):
            raise ValueError(f"{scene.name}: a lattice point lies outside body {b}")
        verts.append(own[inside])
        weights.append(bary[inside, q])
    return np.concatenate(verts), np.concatenate(weights)


# ------------------------------------------------------------------------------ runs
@dataclass
class RunResult:
    """What a run leaves for the comparison: sampled material points, cost, final gap."""

    times: np.ndarray  # (samples,)
    landmarks: np.ndarray  # (samples, points, 3): material points, then centres of mass
    wall_s: float
    iterations: int
    steps: int
    rest_gap: float  # min distance at the end, m
    dhat: float  # absolute d̂, m
    diagonal: float  # l, m
    capped: int


def simulate(scene: SceneDef, s: Settings, folder: Path, duration: float) -> RunResult:
    """Run the scene with ``s``; record landmarks every SAMPLE_DT (and at t = 0)."""
    path, bodies = write_scene(scene, s, folder, duration)
    model = build_model(load_scene(path))
    sim = Simulation(model)
    verts, weights = material_points(scene, model)
    mass, n_bodies = model.mass, len(bodies)
    body_of = model.vertex_shape

    def sample(x):
        """Lattice points Σ λₖ xₖ over their rest tets, then each body's centre of mass."""
        points = np.einsum("qk,qkd->qd", weights, x[verts])
        com = [(mass[body_of == b, None] * x[body_of == b]).sum(axis=0)
               / mass[body_of == b].sum() for b in range(n_bodies)]
        return np.vstack([points, com])

    every = round(SAMPLE_DT / s.dt)
    if not math.isclose(every * s.dt, SAMPLE_DT):
        raise ValueError(f"h = {s.dt} does not divide {SAMPLE_DT}")
    times, marks = [0.0], [sample(sim.state.x)]
    wall = iterations = capped = 0
    row = {"min_distance": np.inf}
    n_steps = round(duration / s.dt)
    for k in range(1, n_steps + 1):
        row = sim.step().row
        wall += row["wall_s"]
        iterations += row["newton_iterations"]
        capped += row["hit_iteration_cap"]
        if k % every == 0:
            times.append(k * s.dt)
            marks.append(sample(sim.state.x))
    return RunResult(np.array(times), np.array(marks), wall, iterations, n_steps,
                     float(row["min_distance"]), model.dhat, model.bbox_diagonal, capped)


def landmark_error(run: RunResult, ref: RunResult) -> float:
    """sqrt(mean |y − y_ref|²) over common sample times and landmarks, divided by l."""
    n = min(len(run.times), len(ref.times))
    if not np.allclose(run.times[:n], ref.times[:n]):
        raise ValueError("sample times differ")
    d2 = np.sum((run.landmarks[:n] - ref.landmarks[:n]) ** 2, axis=-1)
    return float(np.sqrt(d2.mean()) / ref.diagonal)


# ------------------------------------------------------------------------------ sweep
def measure(scene: SceneDef, s: Settings, folder: Path, duration: float,
            repeats: int) -> RunResult:
    """Run up to ``repeats`` times (fewer once REPEAT_BUDGET_S of wall time is spent) and
    keep the smallest wall time: other jobs on the machine only ever add time."""
    run = simulate(scene, s, folder, duration)
    spent, n = run.wall_s, 1
    while n < repeats and spent < REPEAT_BUDGET_S:
        again = simulate(scene, s, folder, duration)
        spent, n = spent + again.wall_s, n + 1
        run.wall_s = min(run.wall_s, again.wall_s)
    return run


def sweep(scene: SceneDef, sweeps: dict, reference: Settings, work: Path,
          duration: float, base: Settings = DEFAULTS, repeats: int = 1,
          say=print) -> list[dict]:
    """The reference, then every swept value (others at ``base``), as CSV rows.

    ``sweeps`` maps a parameter to its values, or ``"combined"`` to a list of Settings
    (all four refined together). A setting met twice (the base in every sweep) runs once;
    the reference always runs on its own, so a sweep point with its settings checks that
    runs are deterministic."""
    ref = simulate(scene, reference, work / "reference", duration)
    runs, done = [("reference", None, reference, ref)], {}
    for param, values in sweeps.items():
        for value in values:
            s = value if param == "combined" else replace(base, **{param: value})
            if s not in done:
                done[s] = measure(scene, s, work / f"run{len(done)}", duration, repeats)
                say(f"  {scene.name} {param}={value}: {done[s].wall_s:.2f} s")
            runs.append((param, value, s, done[s]))
    rows = []
    for param, value, s, run in runs:
        if param == "combined":
            value = f"r{s.res} h{s.dt:g} tol{s.tol:g} dhat{s.dhat:g}"
        rows.append({
            "scene": scene.name, "parameter": param,
            "value": "" if value is None else value,
            "tol": s.tol, "dhat": s.dhat, "dt": s.dt, "res": s.res,
            "is_default": int(s == base and param != "reference"),
            "wall_s": run.wall_s, "error": landmark_error(run, ref),
            "newton_iterations": run.iterations, "steps": run.steps,
            "capped_steps": run.capped,
            "rest_gap_m": run.rest_gap, "dhat_m": run.dhat,
            "rest_gap_over_dhat": run.rest_gap / run.dhat,
        })
    return rows


def pareto(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats in both wall time and error, by time."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def plot(rows: list[dict], path: Path, title: str) -> None:
    """Wall time (x, log) against error (y, log): one marker per swept parameter, the
    Pareto front as a step line, the default settings circled."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = [r for r in rows if r["parameter"] != "reference" and r["error"] > 0]
    fig, ax = plt.subplots(figsize=(7, 5))
    markers = {"tol": ("o", "tab:blue"), "dhat": ("s", "tab:orange"),
               "dt": ("^", "tab:green"), "res": ("D", "tab:red"),
               "combined": ("*", "tab:purple")}
    for param, (marker, colour) in markers.items():
        sel = [r for r in pts if r["parameter"] == param]
        if not sel:
            continue
        ax.plot([r["wall_s"] for r in sel], [r["error"] for r in sel], marker=marker,
                color=colour, linestyle=":", label=LABELS[param])
        for r in sel:
            if r["is_default"]:
                continue  # circled, and named in the title
            text = (f"r{r['res']} h{r['dt']:g}" if param == "combined"
                    else f"{r['value']:g}")
            ax.annotate(text, (r["wall_s"], r["error"]), fontsize=7,
                        xytext=(4, 3), textcoords="offset points", color=colour)
    front = [pts[i] for i in pareto([(r["wall_s"], r["error"]) for r in pts])]
    if front:
        ax.step([r["wall_s"] for r in front], [r["error"] for r in front], where="post",
                color="black", linewidth=1.0, label="Pareto front")
    default = [r for r in pts if r["is_default"]]
    if default:
        d = default[0]
        ax.plot([d["wall_s"]], [d["error"]], "o", markersize=14, markerfacecolor="none",
                markeredgecolor="black", label="defaults")
        title += (f"\ndefaults: tol {d['tol']:g}, d̂ {d['dhat']:g}, h {d['dt']:g} s, "
                  f"{d['res']} cells per edge")
    ref = [r for r in rows if r["parameter"] == "reference"]
    if ref:
        ax.axvline(ref[0]["wall_s"], color="grey", linewidth=0.8, linestyle="--",
                   label=f"reference run ({ref[0]['wall_s']:.1f} s)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the steps (s)")
    ax.set_ylabel("position RMS error / scene diagonal")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_csv(rows: list[dict], path: Path) -> None:
    """Write ``rows``, keeping the rows of other scenes already in the file."""
    scenes = {r["scene"] for r in rows}
    kept = [r for r in read_csv_rows(path) if r["scene"] not in scenes] if path.exists() else []
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(kept + rows)


def read_csv_rows(path: Path) -> list[dict]:
    """The CSV's rows with numbers as numbers (a ``combined`` value stays text)."""
    ints = {"res", "is_default", "newton_iterations", "steps", "capped_steps"}
    rows = []
    with open(path, newline="") as f:
        for raw in csv.DictReader(f):
            row = {}
            for key, text in raw.items():
                if key in ("scene", "parameter") or (key == "value" and raw["parameter"]
                                                     in ("reference", "combined")):
                    row[key] = text
                else:
                    row[key] = int(text) if key in ints else float(text)
            rows.append(row)
    return rows


def warm_up(work: Path) -> None:
    """Compile the kernels (numba) on a tiny run so no measured step pays for it."""
    for scene in SCENES.values():
        simulate(scene, replace(DEFAULTS, res=1, dt=0.05), work / f"warmup_{scene.name}", 0.1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true",
                    help="one scene, two settings, a few steps, into a temporary folder")
    ap.add_argument("--scene", choices=sorted(SCENES), action="append",
                    help="only this scene (repeatable); default all")
    ap.add_argument("--out", type=Path, default=None, help=f"default {DEFAULT_OUT.name}/")
    ap.add_argument("--replot", action="store_true",
                    help="only redraw the charts from the CSV in --out")
    args = ap.parse_args(argv)

    if args.replot:
        out = args.out or DEFAULT_OUT
        rows = read_csv_rows(out / "speed_accuracy.csv")
        for name in args.scene or sorted({r["scene"] for r in rows}):
            plot([r for r in rows if r["scene"] == name],
                 out / f"speed_accuracy_{name}.png", f"{name}: wall time against error")
        return 0

    names = args.scene or (["two_cubes"] if args.smoke else list(SCENES))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        out = args.out or (work / "out" if args.smoke else DEFAULT_OUT)
        out.mkdir(parents=True, exist_ok=True)
        if args.smoke:  # the second setting repeats the reference: its error must be 0
            base, sweeps, reference = Settings(res=1), {"dt": [0.05, 0.025]}, Settings(res=1)
        else:
            base, sweeps, reference = DEFAULTS, SWEEPS, REFERENCE
        warm_up(work)
        rows = []
        for name in names:
            scene = SCENES[name]
            duration = SMOKE_DURATION if args.smoke else scene.duration
            t0 = time.perf_counter()
            scene_rows = sweep(scene, sweeps, reference, work / name, duration, base,
                               repeats=1 if args.smoke else REPEATS,
                               say=(lambda *a: None) if args.smoke else print)
            rows += scene_rows
            plot(scene_rows, out / f"speed_accuracy_{name}.png",
                 f"{name}: wall time against error")
            print(f"{name}: {len(scene_rows)} runs in {time.perf_counter() - t0:.0f} s")
        write_csv(rows, out / "speed_accuracy.csv")
        print(f"wrote {out / 'speed_accuracy.csv'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
