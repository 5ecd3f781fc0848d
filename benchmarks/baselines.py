"""The SQP and QP baselines (``constraintSolver SQP|QP``, ipcsim/baselines/) on the
original program's tutorial scripts and its ``failures/`` scripts, each run labelled as
the paper's supplement labels its SQP runs: Pass, Intersecting, Blow-up, Timeout (and
"QP failure" where OSQP reports an infeasible QP twice in a row); the same scenes solved
by IPC (ipcsim's barrier) for reference.

    python -m benchmarks.baselines [--steps N] [--budget S] [--only SUBSTRING] [--out DIR]
                                   [--methods IPC,SQP,QP] [--merge]

Scripts that name SQP or QP themselves (the ``failures/`` ones) run with their own
settings. The others run with the settings of the original's SQP sections: ``warmStart 1``,
``constraintType graphics`` (the gap function), ``useActiveSetConvergence`` and an offset
of d̂ (the distance IPC's barrier starts acting at, 1e-3 of the scene's size by default).
Every frame is checked afterwards (``ipcsim check --frames``); a run whose frames
intersect is "Intersecting" even when no step noticed. ``--budget`` is wall seconds per
run: a run still going then is "Timeout".

The table goes to docs/benchmarks/baselines_table.md and the rows to baselines.json (not
with ``--only``, unless ``--merge``: then only this run's rows replace the saved ones).
"""

from __future__ import annotations

import argparse
import io
import json
import signal
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from msgspec.structs import replace

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO.parent / "shared" / "ipc-examples-full" / "input"
DOCS = REPO / "docs" / "benchmarks"
METHODS = ("IPC", "SQP", "QP")  # IPC: the scene solved with ipcsim's barrier, for reference
DEFAULT_STEPS = 40
DEFAULT_BUDGET = 120.0


def baseline_scene(scene: Path, method: str, out: Path) -> Path:
    """``scene`` with contact by ``method`` (SQP or QP), written as TOML to ``out``. A
    scene that already names SQP or QP keeps its constraint settings; others get the
    settings of the original's SQP sections with offset d̂."""
    from ipcsim.model.build import build_model
    from ipcsim.scene import load_scene, save_scene

    spec = load_scene(scene)
    if method == "IPC":
        spec = replace(spec, constraint_solver="interiorPoint")
    elif spec.constraint_solver in METHODS:
        spec = replace(spec, constraint_solver=method)
    else:
        dhat = build_model(spec).dhat
        spec = replace(spec, constraint_solver=method, constraint_type="graphics",
                       constraint_offset=dhat, active_set_convergence=True,
                       warm_start=max(spec.warm_start, 1))
    out.mkdir(parents=True, exist_ok=True)
    return save_scene(spec, out / f"{scene.stem}_{method}.toml")


@contextmanager
def wall_budget(seconds: float):
    """Interrupt the run after ``seconds`` of wall time, as Ctrl-C would: ``ipcsim run``
    then stops cleanly with its frames written (exit status 130)."""
    def stop(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGALRM, stop)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def run_labelled(scene: Path, out: Path, steps: int | None, budget: float) -> dict:
    """``ipcsim run`` the scene within the wall budget and label the outcome: Pass,
    Intersecting (a step noticed it, or a frame fails the exact check), Blow-up,
    QP failure, Timeout; "failed: ..." for anything else."""
    from ipcsim.cli import main as ipcsim_main
    from ipcsim.contact.frame_check import check_frames

    cmd = ["run", str(scene), "-o", str(out), "--overwrite", "-q"]
    if steps:
        cmd += ["--steps", str(steps)]
    t0 = time.perf_counter()
    timed_out, error = False, ""
    try:
        with wall_budget(budget):
            status = ipcsim_main(cmd)
    except KeyboardInterrupt:
        status, timed_out = 130, True
    except Exception as exc:  # a crash is a result too
        status, error = 1, f"{type(exc).__name__}: {exc}"
    wall = time.perf_counter() - t0
    info = json.loads((out / "run.json").read_text()) if (out / "run.json").is_file() else {}
    timed_out = timed_out or status == 130 or (bool(error) and wall >= budget)
    clean = None
    if (out / "frames" / "series.pvd").is_file():
        clean = check_frames(out, io.StringIO()) == 0
    outcome = info.get("outcome")
    if timed_out:
        label = "Timeout"
    elif outcome in ("Blow-up", "QP failure"):
        label = outcome
    elif outcome == "Intersecting" or clean is False:
        label = "Intersecting"
    elif status == 0:
        label = "Pass"
    else:
        label = f"failed: {error or info.get('status') or f'exit status {status}'}"
    logged_steps, logged_qps = _logged(out)  # where the budget stopped it before run.json
    return {"label": label, "status": status, "wall_s": wall, "frames_clean": clean,
            "steps_done": info.get("steps_done") or logged_steps,
            "steps_planned": info.get("steps_planned") or steps or _planned(scene),
            "reason": info.get("status", error),
            "qp_solves": info.get("newton_iterations") or logged_qps}


def _logged(out: Path) -> tuple[int, int]:
    """(steps, QPs) in steps.csv."""
    from ipcsim.io.csv_log import read_csv

    log = out / "steps.csv"
    if not log.is_file() or not log.stat().st_size:
        return 0, 0
    qps = read_csv(log).get("newton_iterations", [])
    return len(qps), int(sum(qps))


def _planned(scene: Path) -> int:
    from ipcsim.scene import load_scene

    return load_scene(scene).n_steps


def scripts(only: str | None = None) -> list[Path]:
    """The tutorial scripts and the failures/ scripts of the example tree."""
    if not EXAMPLES.is_dir():
        return []
    found = sorted(EXAMPLES.joinpath("tutorialExamples").rglob("*.txt"))
    found += sorted(EXAMPLES.joinpath("failures").glob("*.txt"))
    return [p for p in found if only is None or only in str(p)]


def run_all(steps=DEFAULT_STEPS, budget=DEFAULT_BUDGET, only=None, root=None,
            say=print, methods=METHODS[1:]) -> list[dict]:
    root = Path(root or REPO / "output" / "baselines")
    rows = []
    for path in scripts(only):
        name = str(path.relative_to(EXAMPLES).with_suffix(""))
        for method in methods:
            folder = root / name.replace("/", "_") / method
            scene = baseline_scene(path, method, folder / "scene")
            row = {"script": name, "method": method,
                   **run_labelled(scene, folder / "out", steps, budget)}
            rows.append(row)
            say(f"{name:48s} {method:4s} {row['label']:14s} steps {row['steps_done']:>4} "
                f"QPs {row['qp_solves']:>5}  {row['wall_s']:.1f} s")
            sys.stdout.flush()
    return rows


def markdown(rows) -> str:
    lines = ["| script | method | steps done / planned | QPs (IPC: Newton iterations) "
             "| outcome | wall (s) |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['script']} | {r['method']} | {r['steps_done']} / "
                     f"{r['steps_planned']} | {r['qp_solves']} | {r['label']} "
                     f"| {r['wall_s']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=DEFAULT_STEPS,
                    help="steps per run (0: the scene's whole duration)")
    ap.add_argument("--budget", type=float, default=DEFAULT_BUDGET,
                    help="wall seconds per run before it is a Timeout")
    ap.add_argument("--only", help="run only scripts whose path contains this")
    ap.add_argument("--out", type=Path, help="folder for the runs (default output/baselines)")
    ap.add_argument("--methods", default=",".join(METHODS),
                    help="comma-separated, of IPC, SQP, QP (default all three)")
    ap.add_argument("--merge", action="store_true",
                    help="replace only this run's (script, method) rows of the saved results")
    args = ap.parse_args(argv)
    methods = tuple(m for m in args.methods.split(",") if m)
    rows = run_all(args.steps, args.budget, args.only, args.out, methods=methods)
    saved = DOCS / "baselines.json"
    if args.merge and saved.is_file():
        new = {(r["script"], r["method"]): r for r in rows}
        old = json.loads(saved.read_text())
        rows = [new.pop((r["script"], r["method"]), r) for r in old] + list(new.values())
    order = {m: i for i, m in enumerate(METHODS)}
    rows.sort(key=lambda r: (_script_order(r["script"]), order[r["method"]]))
    table = markdown(rows)
    if not args.only or args.merge:
        DOCS.mkdir(parents=True, exist_ok=True)
        saved.write_text(json.dumps(rows, indent=1) + "\n")
        (DOCS / "baselines_table.md").write_text(table + "\n")
    print(table)
    return 0


def _script_order(name: str) -> tuple[int, str]:
    """Tutorial scripts first, then failures/, each alphabetically."""
    return (0 if name.startswith("tutorial") else 1, name)


if __name__ == "__main__":
    sys.exit(main())
