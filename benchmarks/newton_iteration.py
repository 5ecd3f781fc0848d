"""Time per Newton iteration and its split by phase, on twisted bars.

    python -m benchmarks.newton_iteration [--steps N] [--cells NX NY NZ] [--solver NAME]

Scenes:
* ``barTwist``: the original's ``otherExamples/barTwist_noCollisions.txt`` (2,523 tets,
  E = 1e9, one end rotating at 270°/s), when ``../shared/ipc-examples`` is present;
* ``bar50k``: a generated bar of about 50,000 tets (60×12×12 cells, 6 tets each), both
  end slabs rotating in opposite directions about the bar's axis, neo-Hookean, E = 1e5.

For each scene it runs N steps (the first step, which includes numba compilation, is
excluded) and prints the median over steps of (phase time / Newton iterations) for every
phase logged in steps.csv, plus the median time per iteration.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from ipcsim.model.build import build_model
from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

EXAMPLES = Path(__file__).resolve().parents[1].parent / "shared" / "ipc-examples"
PHASES = ("energy", "assembly", "solve", "ccd_line_search", "contact_set")


def bar_scene(folder: Path, cells=(60, 12, 12)) -> Path:
    nx, ny, nz = cells
    points, tets = box_tet_mesh(nx, ny, nz, size=(5.0, 1.0, 1.0))
    write_msh(folder / "bar.msh", points, tets)
    scene = folder / "bar50k.txt"
    scene.write_text(
        "shapes input 1\n"
        "bar.msh 0 0 0  0 0 0  1 1 1 "
        "DBC -0.01 -0.01 -0.01  0.01 1.01 1.01  0 0 0  -72 0 0 "
        "DBC 0.99 -0.01 -0.01  1.01 1.01 1.01  0 0 0  72 0 0\n"
        "energy NH\nstiffness 1e5 0.4\ndensity 1000\nturnOffGravity\nselfCollisionOff\n"
        "time 1 0.04\n")
    return scene


def measure(name: str, scene_path: Path, steps: int, solver: str | None) -> dict:
    model = build_model(load_scene(scene_path))
    sim = Simulation(model, linear_solver=solver)
    per_phase = {p: [] for p in PHASES}
    per_iteration, iterations = [], []
    for k in range(steps + 1):
        row = sim.step().row
        its = max(1, row["newton_iterations"])
        if k == 0:
            continue  # includes compilation
        iterations.append(row["newton_iterations"])
        per_iteration.append(row["wall_s"] / its)
        for p in PHASES:
            per_phase[p].append(row[f"wall_{p}_s"] / its)
    med = {p: statistics.median(v) for p, v in per_phase.items()}
    return {"scene": name, "tets": len(model.tets), "dofs": 3 * len(model.mass),
            "solver": sim.linear_solver.name, "steps": steps,
            "iterations_per_step": statistics.mean(iterations),
            "per_iteration": statistics.median(per_iteration), **med}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--cells", type=int, nargs=3, default=(60, 12, 12))
    ap.add_argument("--solver", default=None, help="cholmod | scipy (default: fastest)")
    args = ap.parse_args(argv)
    results = []
    bar_twist = EXAMPLES / "input/otherExamples/barTwist_noCollisions.txt"
    if bar_twist.is_file():
        results.append(measure("barTwist", bar_twist, args.steps, args.solver))
    with tempfile.TemporaryDirectory() as tmp:
        results.append(measure("bar50k", bar_scene(Path(tmp), args.cells), args.steps,
                               args.solver))
    print(f"median ms per Newton iteration ({time.strftime('%Y-%m-%d')})")
    head = ["scene", "tets", "dofs", "solver", "it/step", "total"] + list(PHASES)
    print(" | ".join(head))
    for r in results:
        cells = [r["scene"], str(r["tets"]), str(r["dofs"]), r["solver"],
                 f"{r['iterations_per_step']:.2f}", f"{1e3 * r['per_iteration']:.1f}"]
        cells += [f"{1e3 * r[p]:.1f}" for p in PHASES]
        print(" | ".join(cells))


if __name__ == "__main__":
    main()
