"""The example sweep: every script of the original program's example tree, a few steps each.

    python -m benchmarks.examples [--only SUBSTRING] [--steps N] [--timeout S]
        [--ipc-lib-path DIRS] [--no-original] [--out DIR] [--work DIR]

Every ``*.txt`` under ``../shared/ipc-examples-full/input`` is a script. Each one is cut to
a bounded number of steps (:data:`STEPS`: the default, or its own entry; a ``time
DURATION DT`` line at the script's own dt, as ``benchmarks.vs_original`` adds it) and run
through ``ipcsim run`` and, where ``../shared/ipc-original`` runs, through the original
program. ipcsim's frames are then checked with ``ipcsim check --frames``'s exact
predicates: a run is clean when no surface edge crosses a surface triangle between two
bodies or a body and an obstacle, no vertex is below a plane, and, for neo-Hookean
scenes, no tet is inverted (fixed-corotated elements may invert: the method promises
nothing there). Scripts whose meshes are not in the tree are listed as such.

Writes ``examples.csv`` and ``examples_table.md`` (script, vertices, tets, steps,
s/step, Newton it./step, clean, the original's s/step and it./step, both programs'
whole-process wall time and peak memory) into ``--out`` (default docs/benchmarks/), with
the machine, the date and the load.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

from benchmarks import vs_original as vs

FULL_INPUT = vs.SHARED / "ipc-examples-full" / "input"
DEFAULT_WORK = vs.REPO_ROOT / "output" / "examples"

DEFAULT_STEPS = 5
# scripts (by a part of their path) that get fewer steps: the paper's large scenes, whose
# steps take tens of seconds each; and steps of 1e-4 s or less, which move nothing in 5
STEPS = {
    "1_squeezeOut": 2, "4_rodsTwist": 2, "mat100x100": 2, "armadillo13K": 2,
    "15_trashComp": 3, "16_armaRoller": 3, "13_dolphinFunnel": 3, "17_pinCushion": 3,
    "12_sphereOnMat": 3, "videoExamples": 3, "segBedSquash": 3,
}


@dataclass
class Row:
    script: str
    status: str = ""  # ok | no meshes | refused | failed (exit N) | timeout
    vertices: int | None = None
    tets: int | None = None
    energy: str = ""
    steps: int | None = None
    s_per_step: float | None = None
    newton_per_step: float | None = None
    clean: str = ""  # yes | no (what) | -
    original_status: str = ""
    original_s_per_step: float | None = None
    original_newton_per_step: float | None = None
    wall_s: float | None = None  # whole process, ipcsim
    original_wall_s: float | None = None
    peak_mb: float | None = None  # peak resident memory of the process, ipcsim
    original_peak_mb: float | None = None


def scripts(only: str | None) -> list[Path]:
    found = sorted(FULL_INPUT.rglob("*.txt")) if FULL_INPUT.is_dir() else []
    return [p for p in found if only is None or only in str(p)]


def steps_for(path: Path, default: int) -> int:
    rel = str(path.relative_to(FULL_INPUT))
    return min([n for key, n in STEPS.items() if key in rel], default=default)


def _read_scene(path: Path, row: Row):
    """The scene and its model's counts, or None (the row says why)."""
    from ipcsim.errors import IpcsimError
    from ipcsim.model.build import build_model
    from ipcsim.scene import load_scene

    try:
        spec = load_scene(path)
        model = build_model(spec)
    except IpcsimError as exc:
        what = str(exc)
        missing = "not found" in what and ("mesh" in what or "folder" in what)
        row.status = "no meshes" if missing else f"refused: {what.split(': ', 1)[-1][:70]}"
        return None
    row.vertices, row.tets, row.energy = model.n_vertices, model.n_tets, spec.energy
    return spec


def _clean(out: Path, energy: str) -> str:
    from ipcsim.contact.frame_check import check_frames

    totals: dict = {}
    try:
        check_frames(out, out=io.StringIO(), totals=totals)
    except Exception as exc:  # a run that wrote no readable frame
        return f"- ({type(exc).__name__})"
    bad = [f"{totals[k]} {k.replace('_', ' ')}" for k in ("intersections", "below_plane")
           if totals.get(k)]
    if energy == "NH" and totals.get("inverted_tets"):
        bad.append(f"{totals['inverted_tets']} inverted tets")
    return "yes" if not bad else "no (" + ", ".join(bad) + ")"


def _per_step(run: vs.Run) -> tuple[float | None, float | None]:
    if not run.steps or run.steps_wall_s is None:
        return None, run.newton_per_step
    return run.steps_wall_s / run.steps, run.newton_per_step


def _status(run: vs.Run) -> str:
    if run.rc == vs.TIMEOUT_EXIT:
        return "timeout"
    return "ok" if run.rc == 0 and run.steps else f"failed (exit {run.rc})"


def sweep_one(path: Path, stage: Path, s: vs.Settings, default_steps: int,
              with_original: bool) -> Row:
    """Run one script with both programs for its bounded steps; check ipcsim's frames."""
    row = Row(str(path.relative_to(FULL_INPUT)))
    spec = _read_scene(path, row)
    if spec is None:
        return row
    n = min(steps_for(path, default_steps), spec.n_steps)
    staged = vs.stage_scene(vs.Scene(row.script, row.script, (n * spec.dt, spec.dt)), path,
                            stage)
    folder = s.work / "runs" / staged.script.stem
    run = vs.run_ipcsim(staged.script, folder / "ipcsim", stage, s)
    row.status, row.steps = _status(run), run.steps
    row.s_per_step, row.newton_per_step = _per_step(run)
    row.wall_s, row.peak_mb = run.wall_s, run.peak_mb
    row.clean = _clean(folder / "ipcsim", spec.energy) if run.steps else "-"
    if with_original:
        orig = vs.run_original(staged.script, folder / "original", stage, s)
        row.original_status = _status(orig)
        row.original_s_per_step, row.original_newton_per_step = _per_step(orig)
        row.original_wall_s, row.original_peak_mb = orig.wall_s, orig.peak_mb
    s.say(f"{row.script}: {row.status}, {row.steps} steps, {_g(row.s_per_step)} s/step, "
          f"clean {row.clean}; original {row.original_status or '-'}")
    return row


def _g(x, fmt=".3g") -> str:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


HEADER = ("| script | vertices | tets | steps | s/step | Newton it./step | clean | "
          "original s/step | original it./step | wall s, original / ipcsim "
          "| peak MB, original / ipcsim | status |")


def markdown(rows: list[Row]) -> str:
    lines = [HEADER, "|" + "---|" * 12]
    for r in rows:
        status = r.status + (f"; original {r.original_status}"
                             if r.original_status and r.original_status != "ok" else "")
        lines.append(f"| {r.script} | {_g(r.vertices, 'd')} | {_g(r.tets, 'd')} | "
                     f"{_g(r.steps, 'd')} | {_g(r.s_per_step)} | {_g(r.newton_per_step)} | "
                     f"{r.clean} | {_g(r.original_s_per_step)} | "
                     f"{_g(r.original_newton_per_step)} | "
                     f"{_g(r.original_wall_s)} / {_g(r.wall_s)} | "
                     f"{_g(r.original_peak_mb, '.0f')} / {_g(r.peak_mb, '.0f')} | {status} |")
    return "\n".join(lines) + "\n"


def summary(rows: list[Row]) -> str:
    ran = [r for r in rows if r.steps]
    clean = [r for r in ran if r.clean == "yes"]
    missing = [r for r in rows if r.status == "no meshes"]
    refused = [r for r in rows if r.status.startswith("refused")]
    return (f"{len(rows)} scripts: {len(ran)} ran ({len(clean)} with every frame clean), "
            f"{len(missing)} without their meshes in the tree, {len(refused)} refused.")


def write_outputs(rows: list[Row], text: str, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    table = out / "examples_table.md"
    table.write_text(text + "\n\n" + markdown(rows), encoding="utf-8")
    path = out / "examples.csv"
    fields = list(Row.__dataclass_fields__)
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: getattr(r, k) for k in fields})
    return [table, path]


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="python -m benchmarks.examples",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", metavar="SUBSTRING", help="only scripts whose path has it")
    ap.add_argument("--steps", type=int, default=DEFAULT_STEPS, metavar="N",
                    help=f"steps per script unless STEPS says fewer (default {DEFAULT_STEPS})")
    ap.add_argument("--timeout", type=float, default=900.0, metavar="S",
                    help="wall seconds per run (default 900)")
    ap.add_argument("--ipc-lib-path", default=vs.os.environ.get("IPC_LIB_PATH", ""),
                    metavar="DIRS", help="the original's runtime libraries (its process only)")
    ap.add_argument("--no-original", action="store_true", help="run ipcsim only")
    ap.add_argument("--out", type=Path, default=vs.DEFAULT_OUT, metavar="DIR")
    ap.add_argument("--work", type=Path, default=DEFAULT_WORK, metavar="DIR")
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    paths = scripts(args.only)
    if not paths:
        print(f"benchmarks.examples: skipped: no scripts under {FULL_INPUT}")
        return 0
    s = vs.Settings(work=args.work, timeout=args.timeout, lib_path=args.ipc_lib_path,
                    say=lambda *a: print(*a, flush=True))
    stage = vs.stage_input(args.work, FULL_INPUT)
    why = None if args.no_original else vs.can_run_original(stage, replace(
        s, say=lambda *a: None))
    if why:
        print(f"benchmarks.examples: the original is not run: {why}")
    info = vs.machine()
    rows = [sweep_one(p, stage, s, args.steps, why is None and not args.no_original)
            for p in paths]
    info["load_after"] = vs._load()
    text = "  \n".join(vs.describe(info, s).split("  \n")[:2]) + "  \n" + (
        f"One thread per program, {args.steps} steps per script unless STEPS says fewer. "
        + summary(rows))
    print(text)
    print(markdown(rows))
    for path in write_outputs(rows, text, args.out):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
