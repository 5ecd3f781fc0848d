"""The first run after installing: install into a fresh virtual environment, then time
the README's first scene, once with the kernels compiled at install and once without.

    python -m benchmarks.first_run [--steps N] [--work DIR] [--keep] [--only aot|jit]

For each way of installing, in a new ``venv`` under ``--work`` (default a temporary
folder): ``pip install .`` of this checkout (``IPCSIM_AOT=0`` for "jit", which leaves the
kernels to numba), then ``ipcsim run input/two_cubes_fall.txt --steps N`` twice, from the
repository root with the environment's own ``ipcsim``. Prints, per way: the install's wall
time; for the first and the second run the whole command's wall time, the first step's
``wall_s`` (steps.csv), the start of the command to the end of the first step, numba's
compile seconds and the peak memory (run.json). pip's cache makes the installs' downloads
cheap; run at a quiet moment, since every figure is one measurement.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = "input/two_cubes_fall.txt"


def _timed(cmd, env, cwd=ROOT) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def _run_figures(venv: Path, out: Path, steps: int, env: dict) -> dict:
    wall = _timed([str(venv / "bin" / "ipcsim"), "run", SCENE, "--steps", str(steps), "-o",
                   str(out), "--overwrite", "-q"], env)
    info = json.loads((out / "run.json").read_text())
    with open(out / "steps.csv", newline="") as f:
        step_walls = [float(r["wall_s"]) for r in csv.DictReader(f)]
    # the first step ended at most the steps after it before the command did
    return {"wall_s": wall, "first_step_s": step_walls[0],
            "to_first_step_done_s": wall - sum(step_walls[1:]),
            "numba_compile_s": info["kernels"]["numba_compile_s"],
            "run_by_numba": len(info["kernels"]["run_by_numba"]),
            "peak_memory_mb": info["peak_memory_mb"]}


def measure(way: str, work: Path, steps: int) -> dict:
    venv = work / f"venv-{way}"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("IPCSIM_AOT", "IPCSIM_THREADS",
                                                            "NUMBA_CACHE_DIR", "PYTHONPATH")}
    if way == "jit":
        env["IPCSIM_AOT"] = "0"
    install = _timed([str(venv / "bin" / "pip"), "install", "-q", str(ROOT)], env)
    row = {"way": way, "install_s": install}
    for k in (1, 2):
        figures = _run_figures(venv, work / f"out-{way}", steps, env)
        row.update({f"run{k}_{key}": value for key, value in figures.items()})
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.first_run",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=1)
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--keep", action="store_true", help="keep the environments")
    ap.add_argument("--only", choices=("aot", "jit"), action="append")
    args = ap.parse_args(argv)
    work = args.work or Path(tempfile.mkdtemp(prefix="ipcsim-first-run-"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    rows = []
    try:
        for way in args.only or ("aot", "jit"):
            rows.append(measure(way, work, args.steps))
            r = rows[-1]
            print(f"{way}: install {r['install_s']:.1f} s")
            for k in (1, 2):
                print(f"  run {k}: {r[f'run{k}_wall_s']:.2f} s whole command, first step "
                      f"{r[f'run{k}_first_step_s']:.2f} s, done "
                      f"{r[f'run{k}_to_first_step_done_s']:.2f} s after the start (at most), "
                      f"compiling {r[f'run{k}_numba_compile_s']:.1f} s, "
                      f"{r[f'run{k}_run_by_numba']} kernels by numba, "
                      f"peak {r[f'run{k}_peak_memory_mb']:.0f} MB")
    finally:
        if not args.keep and args.work is None:
            shutil.rmtree(work, ignore_errors=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
