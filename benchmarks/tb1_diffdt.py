"""The IPC paper's time-step table (its Table 1), rerun with the paper's own scripts.

    python -m benchmarks.tb1_diffdt [--h 0.002 0.005 ...] [--out DIR] [--steps N] [--smoke]

Runs ``paperExamples/tb1_diffDt/rodsTwist_E1e4_dt<h>.txt`` of the original program's
examples (four twisted rods, 2,520 vertices, 6,888 tets, 6 s simulated) with
``ipcsim run`` into DIR/dt<h>, checks every frame with the exact checker, and prints
ipcsim's figures next to the paper's: average and largest active contacts per step,
seconds and Newton iterations per step, and the totals. An output folder that already
holds a finished run is read instead of run again (delete it to rerun). Seconds are the
steps' wall times from steps.csv, so numba compilation at start-up is excluded.
``--smoke`` runs h = 0.1 for three steps into a temporary folder (CI).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from ipcsim.cli import main as ipcsim_main
from ipcsim.io.csv_log import read_csv

from .scene_table import summarise

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


def _finished(out: Path) -> bool:
    info = out / "run.json"
    if not info.is_file():
        return False
    run = json.loads(info.read_text())
    return run.get("status") == "ok" and run.get("steps_done") == run.get("steps_planned")


def measure(h: str, out: Path, steps: int | None = None) -> dict:
    """Run (or read) the script for step size ``h`` in ``out`` and summarise it."""
    if not _finished(out):
        cmd = ["run", str(script_for(h)), "-o", str(out), "-q"]
        cmd += ["--resume"] if (out / "checkpoint.npz").is_file() else ["--overwrite"]
        if steps:
            cmd += ["--steps", str(steps)]
        status = ipcsim_main(cmd)
        if status != 0:
            raise SystemExit(f"ipcsim run {script_for(h).name} failed with status {status}")
    row = summarise(out, f"dt{h}")
    logged = read_csv(out / "steps.csv")
    row.update(h=h, total_seconds=float(np.sum(logged["wall_s"])),
               total_iterations=int(np.sum(logged["newton_iterations"])))
    return row


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
    args = ap.parse_args(argv)
    if not SCRIPTS.is_dir():
        print(f"the original program's examples are not installed ({SCRIPTS.name} missing)",
              file=sys.stderr)
        return 2
    if args.smoke:
        with tempfile.TemporaryDirectory() as tmp:
            rows = [measure("0.1", Path(tmp) / "dt0.1", steps=3)]
            print(markdown(rows))
        return 0
    rows = [measure(h, args.out / f"dt{h}", args.steps) for h in args.h]
    print(markdown(rows))
    if args.csv:
        write_csv(rows, args.csv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
