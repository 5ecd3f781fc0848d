"""ipcsim on a busy machine: alone, beside a CPU-bound process, and two runs at once.

    python -m benchmarks.busy_machine [--scene SCRIPT] [--steps N] [--repeats N]
        [--tbb-lib-path DIR] [--out DIR]

Runs ``ipcsim run SCENE --steps N`` (a subprocess, as a user runs it) in three situations:

* quiet: alone;
* beside a busy process: a Python loop that keeps one core busy, started a few seconds
  earlier;
* two runs at once: two ``ipcsim run`` started together (both are timed).

Each situation runs with the TBB library out of numba's sight and, with
``--tbb-lib-path DIR`` (a folder holding ``libtbb.so.12``, put on ``LD_LIBRARY_PATH``),
with it in sight: numba picks TBB as its threading layer whenever it can load it, which
is what ipcsim's own choice (``compiler/threads.py``) is there to prevent. Prints the
median whole-process wall time of each situation and its ratio to the quiet one, and
writes ``busy_machine.csv`` and ``busy_machine_table.md`` into ``--out`` (default
docs/benchmarks/) unless ``--smoke``.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import vs_original as vs

DEFAULT_SCENE = "tutorialExamples/2cubesFall.txt"
BUSY_LOOP = "while True:\n    pass\n"


def _env(tbb: str) -> dict:
    env = dict(os.environ)
    env.pop("IPCSIM_THREADS", None)  # ipcsim chooses, as for a user
    env.pop("NUMBA_THREADING_LAYER", None)
    if tbb:
        env["LD_LIBRARY_PATH"] = ":".join(p for p in (tbb, env.get("LD_LIBRARY_PATH")) if p)
    else:
        env.pop("LD_LIBRARY_PATH", None)
    return env


def _command(scene: Path, out: Path, steps: int) -> list:
    return vs.ipcsim_command() + ["run", str(scene), "-o", str(out), "--overwrite", "-q",
                                 "--steps", str(steps)]


def _start(scene, out, steps, env, cwd):
    return subprocess.Popen(_command(scene, out, steps), env=env, cwd=cwd,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def timed_runs(scene: Path, work: Path, steps: int, env: dict, together: int) -> list:
    """Wall seconds of ``together`` runs started at once."""
    t0 = time.perf_counter()
    procs = [_start(scene, work / f"run{k}", steps, env, scene.parent) for k in range(together)]
    walls = []
    for p in procs:
        if p.wait() != 0:
            raise RuntimeError(f"ipcsim run exited with status {p.returncode}")
        walls.append(time.perf_counter() - t0)
    return walls


def situation(name: str, scene: Path, work: Path, steps: int, env: dict,
              repeats: int) -> list:
    """Every run's wall time over the repeats of one situation."""
    walls = []
    for _ in range(repeats):
        busy = None
        if name == "beside a busy process":
            busy = subprocess.Popen([sys.executable, "-c", BUSY_LOOP])
            time.sleep(3.0)
        try:
            walls += timed_runs(scene, work, steps, env, 2 if name == "two runs at once" else 1)
        finally:
            if busy is not None:
                busy.kill()
                busy.wait()
    return walls


SITUATIONS = ("quiet", "beside a busy process", "two runs at once")


def measure(scene: Path, steps: int, repeats: int, tbb: str, say=print) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for label, lib in (("no TBB", ""), ("TBB in sight", tbb)):
            if label != "no TBB" and not lib:
                continue
            env = _env(lib)
            timed_runs(scene, work, steps, env, 1)  # warm numba's cache for this layer
            quiet = None
            for name in SITUATIONS:
                walls = situation(name, scene, work, steps, env, repeats)
                med = statistics.median(walls)
                quiet = quiet or med
                rows.append({"library": label, "situation": name, "runs": len(walls),
                             "median_s": med, "ratio": med / quiet})
                say(f"{label:13s} {name:22s} median {med:7.2f} s  x{med / quiet:.2f} "
                    f"({len(walls)} runs)")
    return rows


def markdown(rows: list[dict]) -> str:
    lines = ["| TBB | situation | runs | median wall s | / quiet |", "|---|---|---|---|---|"]
    lines += [f"| {r['library']} | {r['situation']} | {r['runs']} | {r['median_s']:.2f} | "
              f"{r['ratio']:.2f} |" for r in rows]
    return "\n".join(lines) + "\n"


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="python -m benchmarks.busy_machine",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default=DEFAULT_SCENE,
                    help=f"script under the examples' input/ (default {DEFAULT_SCENE})")
    ap.add_argument("--steps", type=int, default=120)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--tbb-lib-path", default="", metavar="DIR",
                    help="a folder with libtbb.so.12, to measure with TBB in numba's sight")
    ap.add_argument("--out", type=Path, default=vs.DEFAULT_OUT)
    ap.add_argument("--smoke", action="store_true", help="few steps, one repeat, no files")
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    work = Path(tempfile.mkdtemp())
    stage = vs.stage_input(work)
    scene = stage / "input" / args.scene
    if not scene.is_file():
        print(f"benchmarks.busy_machine: skipped: {args.scene} is not under the examples")
        return 0
    steps, repeats = (5, 1) if args.smoke else (args.steps, args.repeats)
    info = vs.machine()
    rows = measure(scene, steps, repeats, args.tbb_lib_path)
    info["load_after"] = vs._load()
    text = (f"{args.scene}, {steps} steps; machine {info['cpu']}, {info['cores']} cores; "
            f"{info['date']}; load {info['load_before']} before, {info['load_after']} after")
    print(text + "\n" + markdown(rows))
    if not args.smoke:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "busy_machine_table.md").write_text(text + "\n\n" + markdown(rows))
        with open(args.out / "busy_machine.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
