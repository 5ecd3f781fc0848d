"""Where one ``ipcsim run`` spends its wall time, phase by phase: a small scene's fixed costs.

    python -m benchmarks.run_phases SCENE [--python PATH] [--repeats N] [--steps N]
        [--out DIR]

Each repeat starts a fresh process of PATH's Python (default: this one; give another
environment's ``bin/python`` to time its install) that runs ``ipcsim run SCENE`` as the
``ipcsim`` command does, with a clock around each function that makes up a run; the
parent times the process from start to exit. Prints, per phase, the median over the
repeats in milliseconds and its share of the whole process; ``--out`` also writes the
medians as ``run_phases.csv``.

The phases, nested as they run:

    interpreter start and exit   the whole process less the child's own clock
    imports                      every module loaded, before the run or during it (numpy,
                                 ipcsim's, the standard library's); of which: making
                                 dataclasses (an install whose records were dataclasses;
                                 ipcsim's are msgspec Structs now, and a run makes none)
    main                         ``cli.main``:
      build                        scene, model and simulation (``runner._build``)
      output                       the folder, logs, frame 0, checkpoint 0 (``_open_output``)
      step loop                    ``runner._step_loop``:
        steps                        ``Simulation.step``: the step's problem
                                     (``Simulation.problem``), Newton's line searches
                                     (``StepProblem.line_search``), its final
                                     evaluation (``NewtonSolver._finish``)
        frames, logs, checkpoints    ``_write_frame``, ``CsvLog.append_rows``, ``_checkpoint``
      run.json                     ``runner._run_info``
    cycle collector              its passes (``gc.callbacks``), inside the phases above;
                                 paused while an install that pauses it starts
                                 (``ipcsim/start_up.py``), as its ``console`` does

A phase's "rest" is its time outside the phases listed under it; a module first loaded
inside a phase counts under "imports", not there. Times are wall clock
of one thread (``IPCSIM_THREADS=1``), without ``PYTHONPATH`` so that PATH's Python
imports its own install. The clocks cost about a microsecond a call (a few thousand
calls a run). The function names are ipcsim's own: a rename there shows here as a
phase that is missing (its smoke test runs it).
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.before_after import _scene_root
from benchmarks.vs_original import ipcsim_env

# (phase, module, attribute): the functions clocked in the child, in the order shown
CLOCKED = (
    ("build", "ipcsim.runner", "_build"),
    ("output", "ipcsim.runner", "_open_output"),
    ("step loop", "ipcsim.runner", "_step_loop"),
    ("steps", "ipcsim.simulation", "Simulation.step"),
    ("the step's problem", "ipcsim.simulation", "Simulation.problem"),
    ("line searches", "ipcsim.potentials.step_problem", "StepProblem.line_search"),
    ("final evaluation", "ipcsim.solver.newton", "NewtonSolver._finish"),
    ("frames", "ipcsim.runner", "_write_frame"),
    ("logs", "ipcsim.io.csv_log", "CsvLog.append_rows"),
    ("checkpoints", "ipcsim.runner", "_checkpoint"),
    ("run.json", "ipcsim.runner", "_run_info"),
)
ORDER = {phase: i for i, (phase, _, _) in enumerate(CLOCKED)}

# The child: clocks the imports and the functions above (a call is counted under the
# phase it is made in, e.g. frame 0 under "output"), runs ``ipcsim.cli.console`` and
# writes {phase path: seconds} as JSON to argv[1] once ``main`` returns.
CHILD = r'''
import sys, time
t0 = time.perf_counter()
import builtins, dataclasses, functools, gc, importlib, json
clocks_file, clocked_functions, ipcsim_args = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3:]
clocks, stack, importing, in_main = {}, [], [], []
def add(path, dt):
    clocks[path] = clocks.get(path, 0.0) + dt
collecting = []
def on_collection(phase, info):  # the cycle collector's passes, wherever they fall
    if phase == "start":
        collecting.append(time.perf_counter())
    elif collecting:
        add("collector", time.perf_counter() - collecting.pop())
gc.callbacks.append(on_collection)
try:  # an install that pauses the collector while it starts: as its console does
    from ipcsim.start_up import pause_collector
    pause_collector()
except ImportError:
    pass
make_class = getattr(dataclasses, "_process_class", None)  # the work of @dataclass
if make_class is not None:
    def timed_class(*args, **kwargs):
        t = time.perf_counter()
        try:
            return make_class(*args, **kwargs)
        finally:
            add("imports/dataclasses", time.perf_counter() - t)
    dataclasses._process_class = timed_class
real_import = builtins.__import__
def timed_import(*args, **kwargs):
    # a module first loaded inside a clocked phase: its time goes to "imports" instead
    if importing or not in_main:
        return real_import(*args, **kwargs)
    loaded, t = len(sys.modules), time.perf_counter()
    importing.append(True)
    try:
        return real_import(*args, **kwargs)
    finally:
        importing.pop()
        if len(sys.modules) != loaded:
            dt = time.perf_counter() - t
            add("imports", dt)
            for depth in range(len(stack) + 1):
                add("/".join(["main"] + stack[:depth]), -dt)
builtins.__import__ = timed_import
import ipcsim.cli
t_imports = time.perf_counter()
def clock(leaf, module, attribute):
    owner = importlib.import_module(module)
    *outer, name = attribute.split(".")
    for part in outer:
        owner = getattr(owner, part)
    inner = getattr(owner, name)
    def clocked(*args, **kwargs):
        stack.append(leaf)
        t = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            add("/".join(["main"] + stack), time.perf_counter() - t)
            stack.pop()
    functools.update_wrapper(clocked, inner)
    setattr(owner, name, clocked)
t_clocks = time.perf_counter()
for leaf, module, attribute in clocked_functions:
    clock(leaf, module, attribute)  # imports the modules the run uses
add("imports", time.perf_counter() - t_clocks)
main = ipcsim.cli.main
def timed_main(argv=None):
    in_main.append(True)
    t = time.perf_counter()
    try:
        return main(argv)
    finally:
        t_end = time.perf_counter()
        in_main.pop()
        add("main", t_end - t)
        add("imports", t_imports - t0)
        clocks["child"] = t_end - t0
        with open(clocks_file, "w") as f:
            json.dump(clocks, f)
ipcsim.cli.main = timed_main
sys.argv = ["ipcsim"] + ipcsim_args
ipcsim.cli.console()
'''


def run_once(python: str, scene: Path, out: Path, steps: int | None) -> dict[str, float]:
    """One run in a fresh process: {phase path: seconds}, "whole" the process's wall time
    and "interpreter start and exit" what the child's own clock did not see."""
    if out.exists():  # a new folder, as a first run writes: clearing an old one is not timed
        shutil.rmtree(out)
    args = ["run", str(scene), "-o", str(out), "-q"]
    if steps is not None:
        args += ["--steps", str(steps)]
    clocks_file = out.with_suffix(".json")
    start = time.perf_counter()
    done = subprocess.run([python, "-c", CHILD, str(clocks_file), json.dumps(CLOCKED), *args],
                          cwd=_scene_root(scene), env=ipcsim_env(1), capture_output=True,
                          text=True)
    whole = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"ipcsim run {scene} exited {done.returncode}: "
                           f"{done.stderr.strip()[-300:]}")
    clocks = json.loads(clocks_file.read_text())
    clocks["whole"] = whole
    clocks["interpreter start and exit"] = whole - clocks.pop("child")
    return clocks


def measure(python: str, scene: Path, repeats: int, steps: int | None,
            work: Path) -> dict[str, float]:
    """The median over ``repeats`` runs of each phase (0 where a run did not enter it)."""
    runs = [run_once(python, scene, work / "out", steps) for _ in range(repeats)]
    phases = dict.fromkeys(p for run in runs for p in run)
    return {p: statistics.median(run.get(p, 0.0) for run in runs) for p in phases}


def _children(medians: dict[str, float], parent: str) -> list[str]:
    """The phases directly under ``parent``, in the order of ``CLOCKED``."""
    depth = parent.count("/") + 1
    found = [p for p in medians if p.count("/") == depth and p.startswith(parent + "/")]
    return sorted(found, key=lambda p: ORDER.get(p.rsplit("/", 1)[-1], len(ORDER)))


def rows(medians: dict[str, float]) -> list[tuple[str, int, float]]:
    """(phase, depth, seconds) in the order of the module docstring, each phase with the
    time it spent outside the phases under it as "rest"."""
    out = [("whole process", 0, medians["whole"]),
           ("interpreter start and exit", 1, medians["interpreter start and exit"]),
           ("imports", 1, medians["imports"])]
    if "imports/dataclasses" in medians:
        out.append(("of which making the dataclasses", 2, medians["imports/dataclasses"]))

    def walk(path: str, depth: int) -> None:
        out.append((path.rsplit("/", 1)[-1], depth, medians[path]))
        children = _children(medians, path)
        for child in children:
            walk(child, depth + 1)
        if children:
            rest = medians[path] - sum(medians[c] for c in children)
            out.append(("rest (Python)" if path.endswith("/steps") else "rest", depth + 1,
                        rest))

    walk("main", 1)
    out.append(("cycle collector (inside the phases above)", 1, medians.get("collector", 0.0)))
    return out


def table(medians: dict[str, float], scene: Path, repeats: int) -> str:
    whole = medians["whole"]
    lines = [f"{scene.name}: medians of {repeats} runs", "",
             "| phase | ms | share |", "|---|---|---|"]
    for name, depth, seconds in rows(medians):
        lines.append(f"| {'· ' * depth}{name} | {1e3 * seconds:.1f} | {seconds / whole:.0%} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", type=Path)
    ap.add_argument("--python", default=sys.executable,
                    help="the Python whose ipcsim install is timed (default: this one)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--steps", type=int, default=None, help="stop each run after step N")
    ap.add_argument("--out", type=Path, default=None, help="write run_phases.csv here")
    args = ap.parse_args(argv)
    scene = args.scene.resolve()
    if not scene.is_file():
        print(f"run_phases: no such scene: {scene}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as work:
        medians = measure(args.python, scene, args.repeats, args.steps, Path(work))
    print(table(medians, scene, args.repeats))
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        with open(args.out / "run_phases.csv", "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["phase", "depth", "seconds"])
            writer.writerows(rows(medians))
    return 0


if __name__ == "__main__":
    sys.exit(main())
