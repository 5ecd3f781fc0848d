"""Newmark and impacts: how much energy a cube dropped flat onto the ground has after
its first impacts, in ipcsim and (where it runs here) the original program.

    python -m benchmarks.newmark_impacts [--heights N] [--steps N] [--no-original]
        [--ipc-lib-path DIR] [--work DIR]

A unit cube (the original's ``cube.msh``, else a generated box) starts at rest with its
bottom at heights 1.0000, 1.0037, ... m over a ground plane, E = 1e6 Pa, ν = 0.4,
h = 0.005 s, ``timeIntegration NM`` (β = 1/4, γ = 1/2: energy-conserving in free
flight) and no damping, for ``--steps`` steps (default 200; the first impact is near
step 90). Per height it prints the mean total energy (kinetic + elastic + gravity's)
over steps 130–170 divided by step 10's: 1 would be an elastic bounce conserved, above
1 energy the time stepping added at the impacts. ipcsim's energy comes from steps.csv
and its frames, the original's from its ``sysE.txt`` (the per-body sums). The heights
shift where in a time step each impact falls, on which the trapezoidal rule's error at
a one- or two-step contact depends.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchmarks import vs_original as vo

SCENE = """shapes input 1
{mesh} 0 {height:.4f} 0  0 0 0  1 1 1

ground 0 0

stiffness 1e6 0.4

time {duration} 0.005

timeIntegration NM
"""
FIRST, LAST, REFERENCE = 130, 170, 10  # steps: after the first impacts; before them


def _mesh(stage: Path) -> str:
    """The original's unit cube where the examples are staged, else a generated one."""
    if (stage / "input" / "tetMeshes" / "cube.msh").is_file():
        return "input/tetMeshes/cube.msh"
    from ipcsim.model.generate import box_tet_mesh, write_msh

    points, tets = box_tet_mesh(2, 2, 2)
    write_msh(stage / "cube_generated.msh", points - points.min(axis=0), tets)
    return "cube_generated.msh"


def ipcsim_energy(out: Path, script: Path, cwd: Path) -> dict[int, float]:
    """Total energy at each framed step of an ipcsim run: kinetic and elastic from
    steps.csv, gravity's (−Σ m g·x, zero without gravity) from the frame's positions and
    the model's masses. With adaptive steps a step's rows are its attempts and the
    accepted ones, the last of which lands on the frame's time."""
    import meshio

    import ipcsim

    with contextlib.chdir(cwd):  # where the script's input/... paths resolve, as for the run
        model = ipcsim.build_model(ipcsim.load_scene(script))
    mass, gravity = np.asarray(model.mass), np.asarray(model.gravity)
    with open(out / "steps.csv", newline="") as f:
        rows = {int(r["step"]): r for r in csv.DictReader(f) if r.get("accepted") != "0"}
    energy = {}
    for frame in sorted((out / "frames").glob("frame_*.vtu")):
        k = int(frame.stem.split("_")[1])
        if k in rows:
            x = np.asarray(meshio.read(frame).points, dtype=float)
            energy[k] = (float(rows[k]["kinetic_energy"]) + float(rows[k]["elastic_energy"])
                         - float(mass @ (x @ gravity)))
    return energy


def original_energy(out: Path) -> dict[int, float]:
    """The original's total energy per step: the sum of each line of sysE.txt."""
    lines = (out / "sysE.txt").read_text().split("\n")
    return {k: sum(map(float, line.split())) for k, line in enumerate(lines) if line.strip()}


def after_impacts(energy: dict[int, float]) -> float:
    """Mean energy over steps FIRST..LAST against step REFERENCE's."""
    late = [e for k, e in energy.items() if FIRST <= k <= LAST]
    return statistics.fmean(late) / energy[REFERENCE]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--heights", type=int, default=10)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--no-original", action="store_true")
    ap.add_argument("--ipc-lib-path", default="")
    ap.add_argument("--work", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.steps < LAST:
        print(f"newmark_impacts: --steps must be at least {LAST}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        work = (args.work or Path(tmp)).resolve()
        settings = vo.Settings(work=work, lib_path=args.ipc_lib_path, say=lambda m: None)
        stage = vo.stage_input(work)
        why = "--no-original" if args.no_original else vo.can_run_original(stage, settings)
        mesh = _mesh(stage)
        rows = []
        for i in range(args.heights):
            height = 1.0 + 0.0037 * i
            script = stage / "scripts" / f"drop_{height:.4f}.txt"
            script.write_text(SCENE.format(mesh=mesh, height=height,
                                           duration=args.steps * 0.005))
            run = vo.run_ipcsim(script, work / "ipcsim" / script.stem, stage, settings)
            if run.rc != 0:
                print(f"newmark_impacts: ipcsim failed on {script.name}", file=sys.stderr)
                return 1
            ipc = after_impacts(ipcsim_energy(work / "ipcsim" / script.stem, script, stage))
            orig = None
            if why is None:
                out = work / "original" / script.stem
                if vo.run_original(script, out, stage, settings).rc == 0:
                    orig = after_impacts(original_energy(out))
            rows.append((height, orig, ipc))
            print(f"bottom at {height:.4f} m: energy after the first impacts / before: "
                  f"original {'–' if orig is None else f'{orig:.3f}'}, ipcsim {ipc:.3f}",
                  flush=True)
    ipc_all = [r[2] for r in rows]
    line = f"median over {len(rows)} heights: ipcsim {statistics.median(ipc_all):.3f} " \
           f"({min(ipc_all):.2f}–{max(ipc_all):.2f})"
    orig_all = [r[1] for r in rows if r[1] is not None]
    if orig_all:
        line += f", original {statistics.median(orig_all):.3f} " \
                f"({min(orig_all):.2f}–{max(orig_all):.2f})"
    else:
        line += f"; the original not run ({why})"
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
