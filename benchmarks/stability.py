"""The stability suite: scenes where contact methods break, run with ipcsim's barrier,
with a quadratic penalty baseline (benchmarks/penalty.py) at three stiffnesses, and with
the SQP and QP baselines of the IPC paper (``constraintSolver SQP|QP``, benchmarks/
baselines.py: gap-function constraints with offset d̂).

    python -m benchmarks.stability [--smoke] [--contact barrier|penalty|both|sqp|all]
                                   [--only SUBSTRING] [--budget S] [--out DIR] [--merge]
    python -m benchmarks.stability --charts-only    # redraw from stability.csv

Families: impact speed (a cube hitting the ground or a thin fixed plate at 10, 100 and
1000 m/s, with a time step in which the fast cube crosses many times its size), time step
(two cubes falling onto the ground and each other, h = 0.001 … 1 s), stiffness (the same
stack, E = 1e5 … 2e10 Pa), a tight slot (a cube falling into a U whose gap is 1e-6 of the
cube's size wider than the cube, d̂ far below the clearance), a mass ratio of 1e4 (a heavy
cube on a light one) and an interlocked chain of four links hanging from a fixed one.

Every scene is generated into the output folder (meshes from ``box_tet_mesh`` and
``benchmarks/stability_meshes.py``) and writes a frame per step. Both variants run
through ``ipcsim run``, the penalty one on the same scene with ``contact.formulation =
"penalty"``. Afterwards the exact checker (``check_frame``, as ``ipcsim check --frames``)
goes over every frame, and penetration depths are measured: below a plane, and of each
body's vertices inside another body's closed surface (winding number).

Not a study (``ipcsim sweep``): its cases are scenes of their own (meshes, shapes and
boundary conditions per case, not values of one scene), every run has a wall-clock
budget after which it is stopped as by Ctrl-C, and the analysis of each case
(penetration by winding numbers, tunnelling from centroids, energy gained) is the case's
own; a study would keep all of that and add a layer.

Without ``--smoke`` the results go to docs/benchmarks/stability.csv and
docs/benchmarks/stability_table.md, and the charts to docs/benchmarks/stability_speed.png
and stability_timestep.png.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from benchmarks.baselines import baseline_scene, wall_budget
from benchmarks.penalty import STIFFNESS_FACTORS, penalty_scene
from benchmarks.stability_meshes import chain_placements, link_mesh, slot_mesh
from ipcsim.model.generate import box_tet_mesh, write_msh

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs" / "benchmarks"
CUBE = 0.2  # cube side (m); 2 × 2 × 2 cells, 27 vertices, 48 tets
SPEEDS = (10.0, 100.0, 1000.0)
SPEED_DT = 0.01  # at 1000 m/s the cube moves 10 m = 50 sizes in a step
TIME_STEPS = (0.001, 0.01, 0.1, 1.0)
STIFFNESSES = (1e5, 1e7, 1e9, 2e10)
SLOT_CLEARANCE = 1e-6  # gap − size, relative to the size
# The clearance is 2e-7 m, 1e-7 m a side. ipcsim's κ bounds need d̂ above 1e-8·l (l the
# scene's bounding-box diagonal, 0.78 m here): d̂ = 2.5e-8 m is a quarter of the clearance
# a side; the second slot case asks for 1e-9 m to show what happens below that limit.
SLOT_DHATS = (2.5e-8, 1e-9)
DEFAULT_BUDGET = 60.0  # wall seconds per run
DBC_ALL = "DBC -0.1 -0.1 -0.1  1.1 1.1 1.1  0 0 0  0 0 0"  # every surface vertex fixed


@dataclass
class Case:
    """One scene of the suite. ``x`` is the swept parameter (speed, h or E) if any;
    ``lines`` the scene text less its shapes; ``shapes`` the shape lines (mesh names
    relative to the scene's folder); ``escaped(c0, c1)`` decides from the bodies'
    centroids at the start and end whether a body passed through something."""

    family: str
    name: str
    x: float | None
    shapes: list[str]
    lines: list[str]
    escaped: object = None
    smoke: bool = False
    meshes: dict = field(default_factory=dict)  # file name -> (points, tets)

    def write(self, folder: Path) -> Path:
        folder.mkdir(parents=True, exist_ok=True)
        for name, (points, tets) in self.meshes.items():
            write_msh(folder / name, points, tets)
        scene = folder / "scene.txt"
        scene.write_text("\n".join([f"shapes input {len(self.shapes)}", *self.shapes,
                                    *self.lines, "playBackSpeed 1e-9", ""]))
        return scene  # playBackSpeed 1e-9: a frame every step


def _cube(name="cube.msh"):
    return {name: box_tet_mesh(2, 2, 2, size=(CUBE,) * 3, origin=(-CUBE / 2, 0, -CUBE / 2))}


def _stack_case(family, name, x, h, duration, E, densities=(1000.0, 1000.0), smoke=False,
                gap=0.05, turned=True):
    """Two cubes falling onto the ground and onto each other (the upper one shifted and
    turned 20° about the vertical unless not ``turned``)."""
    lower, upper = densities
    place = "0.02 {y} 0.01  0 20 0" if turned else "0 {y} 0  0 0 0"
    return Case(family, name, x, [
        f"cube.msh 0 0.05 0  0 0 0  1 1 1  material {lower:g} {E:g} 0.4",
        f"cube.msh {place.format(y=0.05 + CUBE + gap)}  1 1 1  material {upper:g} {E:g} 0.4",
    ], [f"time {duration:g} {h:g}", "ground 0 0"], escaped=_below(0, 1), smoke=smoke,
        meshes=_cube())


def _below(lower: int, upper: int):
    """Body ``upper`` ended below body ``lower`` while still over it: it went through
    (rather than sliding off to one side)."""
    def escaped(c0, c1):
        dx, dy, dz = c1[upper] - c1[lower]
        return bool(dy < 0.0 and math.hypot(dx, dz) < CUBE / 2)
    return escaped


def cases() -> list[Case]:
    out = []
    for v in SPEEDS:
        # a cube 0.3 m above the ground, thrown down at v
        out.append(Case("speed", f"ground v={v:g}", v,
                        [f"cube.msh 0 0.3 0  0 0 0  1 1 1  initVel 0 {-v:g} 0 0 0 0"],
                        [f"time 0.1 {SPEED_DT:g}", "stiffness 1e7 0.4", "ground 0 0"],
                        escaped=lambda c0, c1: bool(c1[0][1] < 0.0), meshes=_cube()))
    plate = box_tet_mesh(3, 1, 3, size=(0.6, 0.02, 0.6), origin=(-0.3, -0.02, -0.3))
    for v in SPEEDS:
        # the same cube thrown at a fixed plate 0.02 m thick (top face at y = 0)
        out.append(Case("speed", f"plate v={v:g}", v,
                        [f"plate.msh 0 0 0  0 0 0  1 1 1  {DBC_ALL}",
                         f"cube.msh 0 0.3 0  0 0 0  1 1 1  initVel 0 {-v:g} 0 0 0 0"],
                        [f"time 0.1 {SPEED_DT:g}", "stiffness 1e7 0.4"],
                        escaped=_below(0, 1), smoke=v == 1000.0,
                        meshes={**_cube(), "plate.msh": plate}))
    for h in TIME_STEPS:
        out.append(_stack_case("time step", f"stack h={h:g}", h, h, max(0.5, 10 * h), 1e6,
                               smoke=h == 0.1))
    for E in STIFFNESSES:
        out.append(_stack_case("stiffness", f"stack E={E:.0e}", E, 0.01, 0.5, E,
                               smoke=E == 2e10))
    # a heavy cube set down square on a light one: 1e4 times the density, same size
    out.append(_stack_case("mass ratio", "heavy on light (1e4)", 1e4, 0.01, 0.5, 1e8,
                           densities=(1000.0, 1e7), smoke=True, gap=0.01, turned=False))
    depth = 0.3
    for dhat in SLOT_DHATS:
        out.append(Case(
            "slot", f"slot, d̂={dhat:g}", SLOT_CLEARANCE,
            [f"slot.msh 0 0 0  0 0 0  1 1 1  {DBC_ALL}",
             f"cube.msh 0 {depth + 0.05} 0  0 0 0  1 1 1"],
            ["time 0.5 0.01", "stiffness 1e7 0.4", f"dHatAbs {dhat:g}"],
            # left the slot sideways or went through its floor
            escaped=lambda c0, c1: bool(abs(c1[1][0]) > CUBE / 2 or c1[1][1] < 0.0),
            smoke=dhat == SLOT_DHATS[0],
            meshes={**_cube(),
                    "slot.msh": slot_mesh(CUBE, SLOT_CLEARANCE, 0.1, depth, 0.05)}))
    bar, hole_w, hole_h, thick = 0.05, 0.15, 0.3, 0.05
    links = chain_placements(4, bar, hole_w, hole_h, thick, top=1.0, gap=0.05)
    shapes = []
    for k, ((tx, ty, tz), ry) in enumerate(links):
        extra = f"  {DBC_ALL}" if k == 0 else ""
        shapes.append(f"link.msh {tx:.6g} {ty:.6g} {tz:.6g}  0 {ry:g} 0  1 1 1{extra}")
    out.append(Case(
        "chain", "chain of 4 links", None, shapes, ["time 1 0.01", "stiffness 1e7 0.4"],
        # a link that dropped out of the one above falls far (links can sag ~0.1 m)
        escaped=lambda c0, c1: bool(max(c0[b][1] - c1[b][1] for b in c0) > 0.5),
        smoke=True, meshes={"link.msh": link_mesh(bar, hole_w, hole_h, thick)}))
    return out


# -- running ---------------------------------------------------------------------------------

class WallBudget(Exception):
    pass


def run_barrier(scene: Path, out: Path, steps: int | None, budget: float) -> dict:
    from ipcsim.cli import main as ipcsim_main

    cmd = ["run", str(scene), "-o", str(out), "--overwrite", "-q"]
    if steps:
        cmd += ["--steps", str(steps)]
    t0 = time.perf_counter()
    error = ""
    try:
        with wall_budget(budget):
            status = ipcsim_main(cmd)
    except KeyboardInterrupt:
        status = 130
    except Exception as exc:  # a crash of ipcsim is a result of the suite too
        status, error = 1, f"{type(exc).__name__} ({exc}) in ipcsim"
    wall = time.perf_counter() - t0
    if error and wall >= budget:  # the alarm went off inside a compiled kernel
        status, error = 130, ""
    info = {}
    if (out / "run.json").is_file():
        info = json.loads((out / "run.json").read_text())
    reason = error or {0: "", 130: f"wall budget ({budget:g} s)"}.get(
        status, info.get("status", "") or f"exit status {status}")
    return {"status": status, "reason": reason, "wall_s": wall,
            "outcome": info.get("outcome")}


def run_penalty(scene: Path, out: Path, factor: float, steps: int | None,
                budget: float) -> dict:
    """``ipcsim run`` of the scene with penalty contact at k = c·W/d̂."""
    return run_barrier(penalty_scene(scene, factor), out, steps, budget)


# -- analysis ----------------------------------------------------------------------------------

def analyse(out: Path, case: Case, n_planned: int) -> dict:
    """Read back a run: its steps, the exact check of every frame, penetration depths,
    whether a body went through something, whether energy appeared from nowhere."""
    import meshio

    from ipcsim.contact.frame_check import check_frames
    from ipcsim.contact.intersection import check_frame
    from ipcsim.io.csv_log import read_csv
    from ipcsim.io.vtk import SERIES_NAME, read_series
    from ipcsim.kernels.contact.penalty import penetration_depths
    from ipcsim.model.build import build_model
    from ipcsim.model.surface import boundary_triangles
    from ipcsim.scene import load_scene

    res = {"steps_done": 0, "newton_mean": math.nan, "newton_max": math.nan,
           "min_distance": math.nan, "intersections": 0, "inverted": 0, "below_plane": 0,
           "bad_frames": 0, "penetration": 0.0, "escaped": False, "exploded": False,
           "checker_clean": False, "planned": n_planned, "dhat": math.nan}
    steps_file = out / "steps.csv"
    if steps_file.is_file() and steps_file.stat().st_size:
        steps = read_csv(steps_file)
        if len(steps.get("step", [])):
            it = steps["newton_iterations"]
            res.update(steps_done=len(it), newton_mean=float(np.mean(it)),
                       newton_max=int(np.max(it)),
                       min_distance=float(np.min(steps["min_distance"])),
                       max_kinetic=float(np.max(steps["kinetic_energy"])))
    pvd = out / "frames" / SERIES_NAME
    if not pvd.is_file():
        return res
    res["checker_clean"] = check_frames(out, io.StringIO()) == 0

    spec = load_scene(out / "scene.toml")
    model = build_model(spec)
    planes = [(np.array(p.origin, float), np.array(p.normal, float)) for p in spec.planes]
    tets = np.asarray(model.tets, dtype=np.int64)
    surface = boundary_triangles(tets)
    body = np.asarray(model.vertex_shape)
    tri_body = body[surface[:, 0]]
    free = ~np.asarray(model.always_kinematic, dtype=bool)
    bodies = np.unique(body[np.unique(tets)])
    centroid0 = None
    for _, vtu in read_series(pvd):
        x = np.ascontiguousarray(meshio.read(vtu).points, dtype=float)
        if not np.isfinite(x).all():
            res["bad_frames"] += 1
            continue
        check = check_frame(x, tets, surface)
        res["intersections"] += check.n_intersections
        res["inverted"] += check.n_inverted
        bad = not check.ok
        for o, n in planes:
            d = (x[free] - o) @ n / np.linalg.norm(n)
            res["below_plane"] += int(np.count_nonzero(d <= 0.0))
            res["penetration"] = max(res["penetration"], float(-d.min()))
            bad |= bool((d <= 0.0).any())
        for a in bodies:
            inside = np.flatnonzero((body == a) & free)
            for b in bodies:
                if a != b and len(inside):
                    depth = penetration_depths(x, inside, surface[tri_body == b])
                    res["penetration"] = max(res["penetration"], float(depth.max()))
        res["bad_frames"] += bad
        centroid = {int(b): x[body == b].mean(axis=0) for b in bodies}
        centroid0 = centroid0 or centroid
    if centroid0 is not None and case.escaped is not None:
        res["escaped"] = case.escaped(centroid0, centroid)
    # energy: kinetic energy may not exceed what the start had plus the work gravity can
    # do down to the lowest point of the scene (backward Euler only dissipates)
    x0 = np.asarray(model.initial_positions)
    m = np.asarray(model.mass) * free
    v0 = np.asarray(model.initial_velocities)
    floor = min([x0[:, 1].min()] + [float(o[1]) for o, _ in planes])
    available = 0.5 * float(m @ (v0 ** 2).sum(axis=1)) + 9.80665 * float(m @ (x0[:, 1] - floor))
    res["exploded"] = bool(res.get("max_kinetic", 0.0) > 1.5 * available + 1e-9)
    res["dhat"] = model.dhat
    return res


def verdict(r: dict) -> str:
    """One word for the table: what went wrong first, or 'ok'."""
    if r["reason"]:
        return "failed"
    if r["escaped"]:  # before "exploded": a body that fell through gains energy by falling
        return "tunnelled"
    if r["exploded"]:
        return "exploded"
    if r["intersections"] or r["inverted"] or r["below_plane"] or r["bad_frames"]:
        return "penetrated"
    return "ok"


def label(r: dict) -> str:
    """The run as the paper's supplement labels its SQP runs: Pass, Intersecting (frames
    that intersect or went through something), Blow-up (energy from nowhere, or the
    baselines' blow-up), Timeout (the wall budget), or "QP failure"."""
    if r["status"] == 130:
        return "Timeout"
    if r.get("outcome") in ("Blow-up", "QP failure"):
        return r["outcome"]
    if r["verdict"] in ("penetrated", "tunnelled") or r.get("outcome") == "Intersecting":
        return "Intersecting"
    if r["verdict"] == "exploded":
        return "Blow-up"
    return "Pass" if r["verdict"] == "ok" else "failed"


def run_case(case: Case, model_name: str, variant, root: Path,
             steps: int | None, budget: float) -> dict:
    """``variant``: None (IPC's barrier), a penalty stiffness factor, or "SQP" / "QP"."""
    folder = root / case.name.replace(" ", "_").replace(",", "").replace("=", "")
    scene = case.write(folder / "scene")
    out = folder / model_name.replace(" ", "_")
    if variant is None:
        run = run_barrier(scene, out, steps, budget)
    elif isinstance(variant, str):
        run = run_barrier(baseline_scene(scene, variant, scene.parent), out, steps, budget)
    else:
        run = run_penalty(scene, out, variant, steps, budget)
    from ipcsim.scene import load_scene

    planned = load_scene(scene).n_steps if steps is None else steps
    res = {"family": case.family, "case": case.name, "x": case.x, "contact": model_name,
           **run, **analyse(out, case, planned)}
    if not res["reason"] and res["steps_done"] < planned:
        res["reason"] = "stopped early"
    res["verdict"] = verdict(res)
    res["label"] = label(res)
    return res


def contact_models(which: str, smoke: bool):
    """(name, variant) of the contact models: "barrier", "penalty", "both" (the two),
    "sqp" (the SQP and QP baselines) or "all"."""
    models = []
    if which in ("barrier", "both", "all"):
        models.append(("ipcsim", None))
    if which in ("penalty", "both", "all"):
        for c in (STIFFNESS_FACTORS[1:2] if smoke else STIFFNESS_FACTORS):
            models.append((f"penalty {c:.0e}", c))
    if which in ("sqp", "all"):
        models += [("SQP", "SQP"), ("QP", "QP")]
    return models


def run_suite(smoke=False, contact="all", only=None, budget=DEFAULT_BUDGET, root=None,
              steps=None, say=print) -> list[dict]:
    root = Path(root or REPO / "output" / ("stability_smoke" if smoke else "stability"))
    steps = steps or (3 if smoke else None)
    rows = []
    for case in cases():
        if (smoke and not case.smoke) or (only and only not in case.name):
            continue
        for name, factor in contact_models(contact, smoke):
            r = run_case(case, name, factor, root, steps, budget)
            rows.append(r)
            say(f"{case.name:24s} {name:13s} {r['verdict']:10s} steps {r['steps_done']}"
                f"/{r['planned']}  it {r['newton_mean']:.1f}/{r['newton_max']}  "
                f"dmin {r['min_distance']:.3g}  pen {r['penetration']:.3g}  "
                f"wall {r['wall_s']:.1f}s {r['reason']}")
            sys.stdout.flush()
    return rows


# -- reporting ---------------------------------------------------------------------------------

CSV_COLUMNS = ("family", "case", "x", "contact", "verdict", "label", "reason", "steps_done",
               "planned", "newton_mean", "newton_max", "min_distance", "penetration",
               "dhat", "intersections", "inverted", "below_plane", "bad_frames", "escaped",
               "exploded", "checker_clean", "wall_s")


def write_csv(rows, path: Path):
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in CSV_COLUMNS})


def read_results(path: Path) -> list[dict]:
    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            for k in ("x", "newton_mean", "newton_max", "min_distance", "penetration",
                      "dhat", "wall_s"):
                r[k] = float(r[k]) if r[k] not in ("", "None") else math.nan
            for k in ("steps_done", "planned", "intersections", "inverted", "below_plane",
                      "bad_frames"):
                r[k] = int(r[k])
            for k in ("escaped", "exploded", "checker_clean"):
                r[k] = r[k] == "True"
            if not r.get("label"):  # rows saved before the label existed
                r["label"] = _saved_label(r)
            rows.append(r)
    return rows


def _saved_label(r: dict) -> str:
    """``label`` of a saved row, from its verdict and reason."""
    if "wall budget" in (r.get("reason") or ""):
        return "Timeout"
    return {"ok": "Pass", "penetrated": "Intersecting", "tunnelled": "Intersecting",
            "exploded": "Blow-up"}.get(r["verdict"], "failed")


def _g(v, fmt=".3g"):
    return "–" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, fmt)


def markdown(rows) -> str:
    lines = ["| case | contact | result | label | steps | Newton it. mean (max) "
             "| min distance (m) | max penetration (m) | intersecting pairs | inverted tets "
             "| wall (s) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        result = r["verdict"] + (f": {r['reason']}" if r["reason"] else "")
        lines.append(
            f"| {r['case']} | {r['contact']} | {result} | {r.get('label') or '–'} "
            f"| {r['steps_done']}/{r['planned']} "
            f"| {_g(r['newton_mean'], '.1f')} ({_g(r['newton_max'], '.0f')}) "
            f"| {_g(r['min_distance'])} | {_g(r['penetration'])} | {r['intersections']} "
            f"| {r['inverted']} | {r['wall_s']:.1f} |")
    return "\n".join(lines)


MARKERS = {"ok": "o", "penetrated": "s", "tunnelled": "v", "exploded": "X", "failed": "x"}
NONE_LEVEL, THROUGH_LEVEL = 1e-7, 3.0  # where "no penetration" and "went through" are drawn


def chart(rows, family: str, xlabel: str, path: Path, groups):
    """Per group of cases, against the family's parameter: penetration depth (with rows
    for "none" and "went through"), the smallest logged distance, and Newton iterations;
    one line per contact model, the marker says how each run ended."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    height = 3.9 * len(groups) + 0.5
    fig, axes = plt.subplots(len(groups), 3, figsize=(15, height), squeeze=False)
    models = list(dict.fromkeys(r["contact"] for r in rows))
    colours = dict(zip(models, plt.rcParams["axes.prop_cycle"].by_key()["color"]))

    def depth(r):
        if r["verdict"] == "tunnelled":
            return THROUGH_LEVEL
        return r["penetration"] if r["penetration"] > 0 else NONE_LEVEL

    panels = (("max penetration depth (m)", depth),
              ("smallest distance logged (m)", lambda r: r["min_distance"]),
              ("Newton iterations per step (mean)", lambda r: r["newton_mean"]))
    for (title, prefix), row_axes in zip(groups, axes):
        dhat = math.nan
        for m in models:
            sel = sorted((r for r in rows if r["family"] == family and r["contact"] == m
                          and r["case"].startswith(prefix)), key=lambda r: r["x"])
            for ax, (_, value) in zip(row_axes, panels):
                pts = [(r["x"], value(r), r["verdict"]) for r in sel
                       if not math.isnan(value(r))]
                if not pts:
                    continue
                ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", color=colours[m],
                        alpha=0.6)
                for x, y, v in pts:
                    mk = MARKERS[v]
                    ax.plot(x, y, mk, color=colours[m], ms=9,
                            mfc="none" if mk in "os" else colours[m])
            dhat = next((r["dhat"] for r in sel if not math.isnan(r["dhat"])), dhat)
        for ax, (ylabel, _) in zip(row_axes, panels):
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            ax.grid(True, which="both", alpha=0.3)
        ax_p, ax_d, ax_n = row_axes
        ax_p.set_ylim(NONE_LEVEL / 3, THROUGH_LEVEL * 3)
        for level, label in ((NONE_LEVEL, "none"), (THROUGH_LEVEL, "went through")):
            ax_p.axhline(level, color="grey", lw=0.8, ls="--")
            ax_p.text(0.99, level * 1.3, label, transform=ax_p.get_yaxis_transform(),
                      ha="right", fontsize=8, color="grey")
        for ax in (ax_p, ax_d):
            if not math.isnan(dhat):
                ax.axhline(dhat, color="grey", lw=0.8, ls=":")
                ax.text(0.01, dhat * 1.3, "d̂", transform=ax.get_yaxis_transform(),
                        fontsize=8, color="grey")
        ax_p.set_title(f"{title}: penetration")
        ax_d.set_title(f"{title}: closest approach")
        ax_n.set_title(f"{title}: Newton iterations")
    handles = [plt.Line2D([], [], color=colours[m], label=m) for m in models]
    handles += [plt.Line2D([], [], ls="", marker=mk, color="k",
                           mfc="none" if mk in "os" else "k", label=v)
                for v, mk in MARKERS.items()]
    fig.legend(handles=handles, loc="lower center", ncol=9, fontsize=9)
    fig.tight_layout(rect=(0, 0.5 / height, 1, 1))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def charts(rows, folder: Path = DOCS):
    chart(rows, "speed", "impact speed (m/s)", folder / "stability_speed.png",
          [("cube onto the ground", "ground"), ("cube onto a 2 cm plate", "plate")])
    chart(rows, "time step", "time step h (s)", folder / "stability_timestep.png",
          [("two cubes falling and stacking", "stack")])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="one case per family, 3 steps")
    ap.add_argument("--contact", choices=("barrier", "penalty", "both", "sqp", "all"),
                    default="all", help="both: barrier and penalty; sqp: the SQP and QP "
                                        "baselines; all: every model")
    ap.add_argument("--merge", action="store_true",
                    help="replace only this run's (case, contact model) rows in "
                         "docs/benchmarks/stability.csv and redraw the table and charts")
    ap.add_argument("--only", help="run only cases whose name contains this")
    ap.add_argument("--budget", type=float, default=DEFAULT_BUDGET,
                    help="wall seconds per run before it is stopped")
    ap.add_argument("--out", type=Path, help="folder for the runs (default output/stability)")
    ap.add_argument("--charts-only", action="store_true",
                    help="redraw the charts and table from docs/benchmarks/stability.csv")
    args = ap.parse_args(argv)
    if args.charts_only:
        rows = read_results(DOCS / "stability.csv")
    else:
        rows = run_suite(args.smoke, args.contact, args.only, args.budget, args.out)
        if args.merge and not args.smoke:
            new = {(r["case"], r["contact"]): r for r in rows}
            saved = read_results(DOCS / "stability.csv")
            known = {(r["case"], r["contact"]) for r in saved}
            rows = [new.get((r["case"], r["contact"]), r) for r in saved]
            rows += [r for key, r in new.items() if key not in known]
        elif args.smoke or args.only or args.contact != "all":
            print(markdown(rows))
            return 0
        write_csv(rows, DOCS / "stability.csv")
    (DOCS / "stability_table.md").write_text(markdown(rows) + "\n")
    charts(rows)
    print(markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
