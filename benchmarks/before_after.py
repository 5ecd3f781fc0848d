"""Two builds of ipcsim on the same scenes, run alternately: before against after.

    python -m benchmarks.before_after --before OLD_VENV/bin/ipcsim [--after ipcsim]
        [--repeats N] [--steps N] [--threads N] [--out DIR] SCENE [SCENE ...]

Each repeat runs every scene once with ``--before`` and once with ``--after`` (each an
``ipcsim`` command, e.g. the console script of another checkout's virtual environment),
one right after the other, so that a busy machine slows both alike. Prints per scene
and build the median whole-process wall time (the range in parentheses), the process's
CPU time (user + system, from ``wait4``: steadier than the wall time where other
tenants come and go), the steps' own time (steps.csv), Newton iterations and peak
memory (run.json), after/before of the medians, and the median of after/before taken
repeat by repeat (the two runs of a repeat side by side); ``--out`` also writes the rows
as ``before_after.csv``. Scenes are run from
their own folder's parent (where an original script's ``input/...`` meshes resolve),
into a temporary folder, on ``--threads`` threads (``IPCSIM_THREADS``, default 1), and
without ``PYTHONPATH``, so that each command runs its own install.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.vs_original import ipcsim_env

FIELDS = ("scene", "build", "runs", "wall_s", "wall_min_s", "wall_max_s", "cpu_s",
          "paired_wall_ratio", "steps_s", "newton_iterations", "peak_memory_mb")


def _scene_root(scene: Path) -> Path:
    """The folder an original script's ``input/...`` paths are relative to (the one
    holding ``input``), else the scene's own folder."""
    for parent in scene.parents:
        if parent.name == "input":
            return parent.parent
    return scene.parent


def run_once(command: str, scene: Path, out: Path, steps: int | None, threads: int) -> dict:
    """One ``ipcsim run`` of ``scene`` into ``out``: wall time and the run's own figures."""
    args = [command, "run", str(scene), "-o", str(out), "-q", "--overwrite"]
    if steps is not None:
        args += ["--steps", str(steps)]
    start = time.perf_counter()
    with subprocess.Popen(args, cwd=_scene_root(scene), env=ipcsim_env(threads),
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True) as proc:
        stderr = proc.stderr.read()
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{command} on {scene} exited {proc.returncode}: "
                           f"{stderr.strip()[-300:]}")
    with open(out / "steps.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    info = json.loads((out / "run.json").read_text())
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime,
            "steps_s": sum(float(r["wall_s"]) for r in rows),
            "newton_iterations": sum(int(r["newton_iterations"]) for r in rows),
            "peak_memory_mb": info.get("peak_memory_mb")}


def measure(scenes: list[Path], builds: dict[str, str], repeats: int, steps: int | None,
            threads: int, work: Path) -> list[dict]:
    """Median figures per (scene, build), the builds alternating within each repeat."""
    runs = {(s, b): [] for s in scenes for b in builds}
    for _ in range(repeats):
        for scene in scenes:
            for build, command in builds.items():
                runs[scene, build].append(run_once(command, scene, work / build, steps,
                                                   threads))
    rows = []
    for (scene, build), figures in runs.items():
        walls = [r["wall_s"] for r in figures]
        before = runs[scene, next(iter(builds))]  # this build's partner in each repeat
        rows.append({"scene": str(scene), "build": build, "runs": len(figures),
                     "wall_s": statistics.median(walls), "wall_min_s": min(walls),
                     "wall_max_s": max(walls),
                     "cpu_s": statistics.median(r["cpu_s"] for r in figures),
                     "paired_wall_ratio": statistics.median(
                         r["wall_s"] / b["wall_s"] for r, b in zip(figures, before)),
                     "steps_s": statistics.median(r["steps_s"] for r in figures),
                     "newton_iterations": statistics.median(r["newton_iterations"]
                                                            for r in figures),
                     "peak_memory_mb": figures[-1]["peak_memory_mb"]})
    return rows


def table(rows: list[dict]) -> str:
    """The rows as a markdown table, before and after side by side per scene."""
    by = {(r["scene"], r["build"]): r for r in rows}
    lines = ["| scene | whole s, before / after (after/before) | repeat by repeat | "
             "CPU s, before / after (after/before) | steps s, before / after | "
             "Newton it., before / after | peak MB, before / after |",
             "|---|---|---|---|---|---|---|"]
    for scene in dict.fromkeys(r["scene"] for r in rows):
        b, a = by[scene, "before"], by[scene, "after"]
        lines.append(
            f"| {Path(scene).stem} | {b['wall_s']:.3f} ({b['wall_min_s']:.2f}–"
            f"{b['wall_max_s']:.2f}) / {a['wall_s']:.3f} ({a['wall_min_s']:.2f}–"
            f"{a['wall_max_s']:.2f}) ({a['wall_s'] / b['wall_s']:.2f}) | "
            f"{a['paired_wall_ratio']:.2f} | {b['cpu_s']:.3f} / {a['cpu_s']:.3f} "
            f"({a['cpu_s'] / b['cpu_s']:.2f}) | "
            f"{b['steps_s']:.3f} / {a['steps_s']:.3f} | {b['newton_iterations']:g} / "
            f"{a['newton_iterations']:g} | {b['peak_memory_mb']:.0f} / "
            f"{a['peak_memory_mb']:.0f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", type=Path, metavar="SCENE")
    ap.add_argument("--before", required=True, help="the ipcsim command of the old build")
    ap.add_argument("--after", default="ipcsim", help="the ipcsim command of the new build "
                    "(default: ipcsim on the PATH)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=None, help="stop each run after step N")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="write before_after.csv here")
    args = ap.parse_args(argv)
    scenes = [s.resolve() for s in args.scenes]
    missing = [str(s) for s in scenes if not s.is_file()]
    if missing:
        print(f"before_after: no such scene: {', '.join(missing)}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as work:
        try:
            rows = measure(scenes, {"before": args.before, "after": args.after},
                           args.repeats, args.steps, args.threads, Path(work))
        except (OSError, RuntimeError) as exc:
            print(f"before_after: {exc}", file=sys.stderr)
            return 2
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())} after the runs; "
          f"{args.repeats} repeats, {args.threads} thread(s)")
    print(table(rows))
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        with open(args.out / "before_after.csv", "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=FIELDS)
            writer.writeheader()
            writer.writerows(rows)
        print(f"wrote {args.out / 'before_after.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
