"""A study of 8 independent tiny runs: on two Dask workers against one after the other.

    python -m benchmarks.study_parallel [--repeats 3] [--workers 2] [--duration S]

Writes a cube-drop scene (125 vertices, 384 tets, ground contact, h = 1 ms, so that a
run computes more than it writes: a frame and a checkpoint every 10 steps) and a study
that varies its Young's modulus over 8 values, then times, as a user would see them, whole commands
in fresh processes: ``ipcsim sweep STUDY --serial`` (the runs one after the other in one
process) and ``ipcsim sweep STUDY --workers 2`` (a LocalCluster of two single-threaded
worker processes), each into a new folder, alternating, ``--repeats`` times. Both include
their start-up: the serial command loads numba's cached kernels once, the cluster starts
its workers and each loads them. Prints the medians, the ratio and the 1-minute load
average around every measurement, and before and after each pair the best ratio the
machine allows at that moment (:func:`fair_share_bound`: other busy processes take their
share of the cores). numba's cache is warmed first, so nothing compiles.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ipcsim.model.generate import box_tet_mesh, write_msh

SCENE = """\
[time]
duration = {duration}
dt = 0.001

[contact]
self_collision = false

[[shapes]]
path = "cube.msh"
translation = [0.0, 0.02, 0.0]

[[planes]]
kind = "ground"
height = 0.0
"""

STUDY = """\
[study]
scene = "drop.toml"

[[vary]]
"material.E" = {{ start = 1e5, stop = 1e6, num = {runs}, spacing = "log" }}

[record]
columns = ["newton_iterations"]
"""


def write_study(folder: Path, duration: float, runs: int = 8) -> Path:
    points, tets = box_tet_mesh(4, 4, 4, size=(0.2, 0.2, 0.2), origin=(-0.1, 0.0, -0.1))
    write_msh(folder / "cube.msh", points, tets)
    (folder / "drop.toml").write_text(SCENE.format(duration=duration))
    study = folder / "study.toml"
    study.write_text(STUDY.format(runs=runs))
    return study


def timed(study: Path, out: Path, *how: str) -> tuple[float, float, float]:
    """(wall seconds, load average before, after) of one ``ipcsim sweep``."""
    before = os.getloadavg()[0]
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "ipcsim.cli", "sweep", str(study), "-o", str(out),
                    "-q", *how], check=True)
    return time.perf_counter() - t0, before, os.getloadavg()[0]


_LOOP = "x = 0\nfor i in range(20_000_000):\n    x += i\n"


def fair_share_bound() -> float:
    """What the machine gives two processes now: the wall time of a pure-Python loop run
    twice at once over twice its time alone. On an idle 2-core machine 0.5; each other
    busy process raises it (one: about 0.67). No study on two workers can do better."""
    def loops(n: int) -> float:
        t0 = time.perf_counter()
        procs = [subprocess.Popen([sys.executable, "-c", _LOOP]) for _ in range(n)]
        for p in procs:
            p.wait()
        return time.perf_counter() - t0

    return loops(2) / (2 * loops(1))


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {len(os.sched_getaffinity(0))} cores, Python {platform.python_version()}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--duration", type=float, default=1.5,
                    help="simulated seconds per run (default 1.5: 1500 steps, several "
                         "seconds of computing, long against a cluster's start)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        study = write_study(tmp, args.duration)
        (tmp / "warm").mkdir()
        warm = write_study(tmp / "warm", 0.02, runs=1)
        timed(warm, tmp / "warm_out", "--serial")  # numba's cache, before any timing
        serial, parallel, bounds = [], [], []
        for k in range(args.repeats):
            bounds.append(fair_share_bound())
            serial.append(timed(study, tmp / f"serial{k}", "--serial"))
            parallel.append(timed(study, tmp / f"parallel{k}", "--workers",
                                  str(args.workers)))
            bounds.append(fair_share_bound())
            (ts, s0, s1), (tp, p0, p1) = serial[-1], parallel[-1]
            print(f"repeat {k + 1}: serial {ts:.1f} s (load {s0:.1f}-{s1:.1f}), "
                  f"{args.workers} workers {tp:.1f} s (load {p0:.1f}-{p1:.1f}), "
                  f"ratio {tp / ts:.2f}; fair-share bound before/after "
                  f"{bounds[-2]:.2f}/{bounds[-1]:.2f}", flush=True)
    s = statistics.median(t for t, _, _ in serial)
    p = statistics.median(t for t, _, _ in parallel)
    loads = [x for t in serial + parallel for x in t[1:]]
    print(f"\n{datetime.date.today()}, {machine()}")
    print(f"| runs | one after the other (s) | {args.workers} workers (s) | ratio "
          f"| load average (1 min) during |")
    print("|---|---|---|---|---|")
    print(f"| 8 × {round(args.duration / 0.001)} steps | {s:.1f} | {p:.1f} | {p / s:.2f} "
          f"| {min(loads):.1f} – {max(loads):.1f} |")
    ratios = sorted(tp / ts for (ts, _, _), (tp, _, _) in zip(serial, parallel))
    print(f"\nratio of each repeat's pair: {', '.join(f'{r:.2f}' for r in ratios)}; median "
          f"{statistics.median(ratios):.2f}")
    print(f"fair-share bound (two busy loops at once / twice one alone): "
          f"{', '.join(f'{b:.2f}' for b in bounds)}; median {statistics.median(bounds):.2f}")
    print("all repeats (s): serial " + ", ".join(f"{t:.1f}" for t, _, _ in serial)
          + f"; {args.workers} workers " + ", ".join(f"{t:.1f}" for t, _, _ in parallel))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
