"""Per-scene statistics in the style of the IPC paper's table.

    python -m benchmarks.scene_table SCENE_OR_OUTPUT [SCENE_OR_OUTPUT ...] [--steps N]

Each argument is either a scene file, which is run (into a temporary folder, ``--steps``
to cut it short), or the output folder of a finished run, which is read. Prints one
markdown row per scene: vertices, tets, steps, average and maximum active contacts per
step, Newton iterations per step, seconds per step (wall time of the steps as logged in
steps.csv, so numba compilation at start-up is excluded), and whether every frame passed
``ipcsim check --frames``.
"""

from __future__ import annotations

import argparse
import io
import json
import tempfile
from pathlib import Path

import meshio
import numpy as np

from ipcsim.cli import main as ipcsim_main
from ipcsim.contact.frame_check import check_frames
from ipcsim.io.csv_log import read_csv


def summarise(out: Path, name: str) -> dict:
    steps = read_csv(out / "steps.csv")
    first = sorted((out / "frames").glob("frame_*.vtu"))[0]
    mesh = meshio.read(first)
    tets = len(mesh.cells_dict.get("tetra", []))
    report = io.StringIO()
    counts = {}
    clean = check_frames(out, report, counts) == 0
    run = json.loads((out / "run.json").read_text())
    contacts = steps["contacts_total"]
    return {
        "scene": name, "vertices": len(mesh.points), "tets": tets,
        "steps": len(steps["step"]), "planned": run.get("steps_planned"),
        "contacts_avg": float(np.mean(contacts)), "contacts_max": int(np.max(contacts)),
        "iterations": float(np.mean(steps["newton_iterations"])),
        "capped": int(np.sum(steps["hit_iteration_cap"])),
        "seconds": float(np.mean(steps["wall_s"])), "clean": clean, **counts,
    }


def markdown(rows: list[dict]) -> str:
    lines = ["| scene | vertices | tets | steps | contacts avg (max) | Newton it./step "
             "| s/step | capped steps | frames clean |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['vertices']} | {r['tets']} | {r['steps']} "
            f"| {r['contacts_avg']:.0f} ({r['contacts_max']}) | {r['iterations']:.2f} "
            f"| {r['seconds']:.3f} | {r['capped']} | {'yes' if r['clean'] else 'NO'} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", type=Path)
    ap.add_argument("--steps", type=int, default=None)
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in args.paths:
            if path.is_dir():
                rows.append(summarise(path, path.name))
                continue
            out = Path(tmp) / path.stem
            cmd = ["run", str(path), "-o", str(out), "-q"]
            if args.steps:
                cmd += ["--steps", str(args.steps)]
            ipcsim_main(cmd)
            rows.append(summarise(out, path.stem))
    print(markdown(rows))


if __name__ == "__main__":
    main()
