"""The IPC paper's time-step table (its Table 1), rerun with the paper's own scripts.

    python -m benchmarks.tb1_diffdt [--h 0.002 0.005 ...] [--out DIR] [--steps N] [--smoke]

Runs ``paperExamples/tb1_diffDt/rodsTwist_E1e4_dt<h>.txt`` of the original program's
examples (four twisted rods, 2,520 vertices, 6,888 tets, 6 s simulated; the ten scripts
differ only in h) as one study (``ipcsim.study``): the h = 0.002 script with ``time.dt``
varied, every frame checked with the exact checker, into DIR (a folder per run under
DIR/runs, DIR/study.csv), on a local Dask cluster (``--workers N``) or one run after the
other (``--serial``). Prints ipcsim's figures next to the paper's: average and largest
active contacts per step, seconds and Newton iterations per step, and the totals. A run
that already finished in DIR is read instead of run again, an interrupted one resumes.
Seconds are the steps' wall times from steps.csv, so numba compilation at start-up is
excluded. ``--smoke`` runs h = 0.1 for three steps into a temporary folder (CI).
"""

from __future__ import annotations

import argparse
import csv
import sys
import tempfile
from pathlib import Path

from ipcsim.study import Record, make_study, run_study
from ipcsim.study.executors import DaskExecutor, SerialExecutor

REPO_ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = REPO_ROOT.parent / "shared" / "ipc-examples" / "input" / "paperExamples" / "tb1_diffDt"
STEPS = ("0.002", "0.005", "0.01", "0.025", "0.05", "0.1", "0.2", "0.5", "1", "2")

# The paper's Table 1 for the same scripts, on its own machine:
# h -> (contacts avg, contacts max, s/step, iterations/step, total s, total iterations)
PAPER = {
    "0.002": (137, "430", 0.29, 2.12, 862, 6351),
    "0.005": (194, "584", 0.36, 2.37, 435, 2843),
    "0.01": (269, "707", 0.38, 2.65, 229, 1591),
    "0.025": (435, "1.0K", 0.38, 2.69, 91, 645),
    "0.05": (551, "1.2K", 0.46, 3.06, 56, 368),
    "0.1": (597, "1.3K", 0.73, 4.75, 44, 285),
    "0.2": (607, "1.2K", 1.79, 14.37, 54, 431),
    "0.5": (653, "1.4K", 11.39, 100.58, 137, 1207),
    "1": (708, "1.3K", 18.41, 188.17, 110, 1129),
    "2": (843, "1.3K", 52.02, 522.00, 156, 1566),
}


def script_for(h: str) -> Path:
    return SCRIPTS / f"rodsTwist_E1e4_dt{h}.txt"


RECORD = Record(columns=("contacts_total", "newton_iterations", "wall_s", "hit_iteration_cap"),
                summaries=("mean", "max"), check_frames=True, final_state=False)


def measure(hs, out: Path, steps: int | None = None, executor=None) -> list[dict]:
    """Run (or read) the scripts for the step sizes ``hs`` as one study in ``out`` and
    summarise each run as a row of the table."""
    study = make_study(script_for(STEPS[0]), {"time.dt": [float(h) for h in hs]},
                       steps=steps, record=RECORD)
    result = run_study(study, out, executor or SerialExecutor())
    rows = []
    for h, r in zip(hs, result.rows):
        if r["status"] != "ok":
            raise SystemExit(f"{script_for(h).name} with h = {h} failed: {r['error']}")
        n = r["steps_done"]
        rows.append({"h": h, "steps": n, "contacts_avg": r["contacts_total_mean"],
                     "contacts_max": int(r["contacts_total_max"]),
                     "seconds": r["wall_s_mean"], "iterations": r["newton_iterations_mean"],
                     "total_seconds": r["wall_s_mean"] * n,
                     "total_iterations": r["newton_iterations"],
                     "capped": round(r["hit_iteration_cap_mean"] * n),
                     "clean": r["frames_clean"], **{k: r[k] for k in (
                         "intersections", "inverted_tets", "below_plane")}})
    return rows


def _frames(row: dict) -> str:
    """The exact checker's verdict over all frames. The scripts use fixed-corotated
    elasticity, which is defined for inverted tets (only neo-Hookean has an inversion
    barrier), so inverted tets are counted apart from intersections."""
    if row["clean"]:
        return "clean"
    found = [f"{row[k]} {label}" for k, label in (("intersections", "intersections"),
                                                  ("inverted_tets", "inverted tets (FCR)"),
                                                  ("below_plane", "below a plane")) if row[k]]
    return ", ".join(found)


def markdown(rows: list[dict]) -> str:
    lines = ["| h (s) | contacts avg (max) | s/step | it./step | total s | total it. "
             "| frames (exact check) | paper: contacts avg (max) | paper s/step | paper it./step "
             "| paper total s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        p = PAPER[r["h"]]
        lines.append(
            f"| {r['h']} | {r['contacts_avg']:.0f} ({r['contacts_max']}) | {r['seconds']:.2f} "
            f"| {r['iterations']:.2f} | {r['total_seconds']:.0f} | {r['total_iterations']} "
            f"| {_frames(r)} | {p[0]} ({p[1]}) | {p[2]:.2f} | {p[3]:.2f} "
            f"| {p[4]} |")
    return "\n".join(lines)


def write_csv(rows: list[dict], path: Path) -> None:
    fields = ["h", "steps", "contacts_avg", "contacts_max", "seconds", "iterations",
              "total_seconds", "total_iterations", "capped", "clean", "intersections",
              "inverted_tets", "below_plane", "paper_contacts_avg",
              "paper_seconds", "paper_iterations", "paper_total_seconds",
              "paper_total_iterations"]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            p = PAPER[r["h"]]
            w.writerow({**r, "paper_contacts_avg": p[0], "paper_seconds": p[2],
                        "paper_iterations": p[3], "paper_total_seconds": p[4],
                        "paper_total_iterations": p[5]})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h", nargs="+", choices=STEPS, default=list(STEPS), metavar="H",
                    help="step sizes to run (default: all ten)")
    ap.add_argument("--out", type=Path, default=Path("output") / "tb1_diffDt",
                    help="folder for the runs (default output/tb1_diffDt)")
    ap.add_argument("--steps", type=int, help="stop each run after N steps")
    ap.add_argument("--csv", type=Path, help="also write the table as CSV")
    ap.add_argument("--smoke", action="store_true", help="h = 0.1, three steps (CI)")
    ap.add_argument("--workers", type=int, help="local Dask workers (default: one per core)")
    ap.add_argument("--serial", action="store_true", help="one run after the other, no Dask")
    args = ap.parse_args(argv)
    if not SCRIPTS.is_dir():
        print(f"the original program's examples are not installed ({SCRIPTS.name} missing)",
              file=sys.stderr)
        return 2
    if args.smoke:
        with tempfile.TemporaryDirectory() as tmp:
            print(markdown(measure(["0.1"], Path(tmp), steps=3)))
        return 0
    executor = SerialExecutor() if args.serial else DaskExecutor(args.workers)
    rows = measure(args.h, args.out, args.steps, executor)
    print(markdown(rows))
    if args.csv:
        write_csv(rows, args.csv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
