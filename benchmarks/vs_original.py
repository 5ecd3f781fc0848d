"""ipcsim against the original IPC program: the same scripts, one after the other.

    python -m benchmarks.vs_original [--only SUBSTRING] [--repeats N] [--out DIR]
        [--work DIR] [--ipc-lib-path DIRS] [--threads N] [--timeout S] [--duration S]
        [--compare-rtol R] [--via-run-ipc] [--no-warmup] [--smoke]

Runs every scene of :data:`SCENES` through the original program (the command
``../shared/ipc-original/run-ipc.sh SCRIPT OUTDIR THREADS`` runs, made the way it makes it,
so that the program's own process is timed; ``--via-run-ipc`` runs the script itself) and
through ``ipcsim run SCRIPT -o OUTDIR`` (a subprocess, as a user runs it), alternately, from a
working folder whose ``input/`` holds the original's example meshes
(``../shared/ipc-examples/input``) and this repository's ``input/meshes``, so that the
example scripts and the hello world both find their meshes. A scene with a shortening in
the table runs a copy of its script with a ``time DURATION DT`` line added: both programs
take the last ``time`` line, and both skip everything after a ``section`` that is not
closed, so the line goes before the first ``section`` line, else at the end.

Per scene and program: whole-process wall time, the process's CPU time (user + system,
from ``wait4``: steadier than the wall time on a host whose other tenants come and go),
wall time of the steps (ipcsim: the sum
of steps.csv ``wall_s``; the original: its time stamps, as ``ipc_stats.py`` reads them),
Newton iterations per step, contacts per step (ipcsim: steps.csv ``contacts_total``; the
original: the last ``# constraint = N`` of each step in its stdout.txt, which may count
differently), peak resident memory of the program's process (its VmHWM, read every
20 ms while it runs: ``ru_maxrss`` would also count this process's memory, which a child
holds between fork and exec) and the exit status. Times are medians over the repeats;
each repeat runs the two programs in turn, the order swapped every repeat, so that the
machine's load falls on both alike; the whole-process ratio is also taken repeat by
repeat (its median and range, and in how many repeats ipcsim was the faster), which a
load that drifts over minutes disturbs less than the ratio of the medians. Afterwards
the trajectories are compared as ``ipcsim compare --rtol R IPCSIM_OUT ORIGINAL_OUT``
compares them (in-process): the step where the two part by more than R of the scene
size, and their largest difference. The table's header names the file system the
outputs go to (``--work``): tiny scenes' times depend on what a file costs to create.

Before measuring, ipcsim runs a few scenes untimed so that numba's cache is warm
(``--no-warmup`` to measure a cold start). Both programs run on ``--threads`` threads
(default 1; ipcsim through ``IPCSIM_THREADS``). ``--ipc-lib-path`` (default
``$IPC_LIB_PATH``) names folders with the original's runtime libraries; they are put on
``LD_LIBRARY_PATH`` of the original's process only, never of ipcsim's (a TBB library
that numba can see changes its threading). The libraries come with
``apt-get install -y libcholmod3 libtbb12 libopenblas0-pthread``.

Prints the table with the machine, the date and the load average before and after, and
writes ``vs_original.csv``, ``vs_original_table.md`` and ``vs_original.png`` into
``--out`` (default docs/benchmarks/). ``--smoke`` runs one tiny scene once into a
temporary folder and writes files only with ``--out``. When the original program or its
examples are missing, or the program cannot run here, it says why and exits 0.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime
import json
import math
import os
import platform
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED = REPO_ROOT.parent / "shared"
ORIGINAL = SHARED / "ipc-original"
EXAMPLES_INPUT = SHARED / "ipc-examples" / "input"
DEFAULT_OUT = REPO_ROOT / "docs" / "benchmarks"
DEFAULT_WORK = REPO_ROOT / "output" / "vs_original"
TIMEOUT_EXIT = 124  # exit status recorded for a run stopped by --timeout, as timeout(1)


@dataclass(frozen=True)
class Scene:
    """One row of the benchmark. ``script`` is relative to the original's examples'
    ``input/`` (a glob pattern expands to one scene per file), or to this repository when
    ``root`` is "repo". ``shorten`` = (duration, dt) of the ``time`` line added to a copy
    of the script; dt is always the script's own."""

    name: str
    script: str
    shorten: tuple[float, float] | None = None
    repeats: int = 1
    root: str = "examples"


# a tiny scene's whole run is a quarter to one second and moves by up to 40 % on a busy
# host: its median wants many repeats (they cost a few minutes of the list's half hour)
TINY_REPEATS = 15

# name ("" : the script's path), script, shortened to (duration s, dt s), repeats, root
SCENES = (
    Scene("", "tutorialExamples/**/*.txt", None, TINY_REPEATS),
    Scene("paperExamples/10_cubeStack", "paperExamples/10_cubeStack.txt", None,
          TINY_REPEATS),
    Scene("paperExamples/2_matKnives", "paperExamples/2_matKnives.txt"),
    Scene("otherExamples/barTwist_noCollisions",
          "otherExamples/barTwist_noCollisions.txt", (2.0, 0.025)),
    Scene("mat40x40_twist", "paperExamples/21_scalability/mat40x40_twist.txt",
          (2.0, 0.04)),
    Scene("tb1 rodsTwist h = 0.002",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.002.txt", (1.0, 0.002)),
    Scene("tb1 rodsTwist h = 0.005",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.005.txt", (1.0, 0.005)),
    Scene("tb1 rodsTwist h = 0.01",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.01.txt", (1.0, 0.01)),
    Scene("tb1 rodsTwist h = 0.025",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.025.txt", (3.0, 0.025)),
    Scene("tb1 rodsTwist h = 0.05",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.05.txt", (3.0, 0.05)),
    Scene("tb1 rodsTwist h = 0.1",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.1.txt", (3.0, 0.1)),
    Scene("tb1 rodsTwist h = 0.2",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.2.txt", (3.0, 0.2)),
    Scene("tb1 rodsTwist h = 0.5",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt0.5.txt", (3.0, 0.5)),
    Scene("tb1 rodsTwist h = 1",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt1.txt", (3.0, 1.0)),
    Scene("tb1 rodsTwist h = 2, 6 s",
          "paperExamples/tb1_diffDt/rodsTwist_E1e4_dt2.txt"),
    Scene("paperExamples/20_pencilStickSlip",
          "paperExamples/20_pencilStickSlip.txt", (0.5, 0.001)),
    Scene("hello world (input/two_cubes_fall.txt)", "input/two_cubes_fall.txt", root="repo"),
)

# run untimed, in full, before measuring (with each measured scene's first step), so that
# numba's cache holds what the scenes use: contact and friction, FCR, half spaces
WARMUP = ("tutorialExamples/2cubesFall.txt", "paperExamples/10_cubeStack.txt")

# --smoke: a few seconds of simulation; the hello world when the examples are absent
SMOKE = Scene("tutorialExamples/2cubesFall", "tutorialExamples/2cubesFall.txt",
              (0.5, 0.025))
SMOKE_REPO = Scene("hello world", "input/two_cubes_fall.txt", (0.05, 0.025),
                   root="repo")
PROGRAMS = ("original", "ipcsim")


@dataclass(frozen=True)
class Settings:
    work: Path
    threads: int = 1
    timeout: float = 1800.0
    lib_path: str = ""
    compare_rtol: float = 1e-3
    via_script: bool = False  # the original through run-ipc.sh (its start-up timed too)
    say: object = print  # progress messages
    checkout: bool = False  # ipcsim from this checkout (python -m ipcsim.cli), not the install


@dataclass
class Run:
    """One run of one program on one scene."""

    rc: int
    wall_s: float
    peak_mb: float | None
    cpu_s: float | None = None  # user + system time of its process
    steps: int | None = None
    steps_wall_s: float | None = None
    newton_per_step: float | None = None
    contacts_mean: float | None = None
    vertices: int | None = None
    own_peak_mb: float | None = None  # the program's own figure (info.txt, run.json)


@dataclass
class Staged:
    """A scene ready to run: its copy of the script in the working folder."""

    scene: Scene
    source: Path
    script: Path
    name: str
    runs: dict = field(default_factory=lambda: {p: [] for p in PROGRAMS})


# ------------------------------------------------------------------------ the scenes


def _root(scene: Scene) -> Path:
    return REPO_ROOT if scene.root == "repo" else EXAMPLES_INPUT


def expand(scenes=SCENES) -> list[tuple[Scene, Path]]:
    """Each scene with its script; glob patterns become one scene per file found (sorted),
    scripts that are not here are left out."""
    out = []
    for scene in scenes:
        root = _root(scene)
        if any(c in scene.script for c in "*?["):
            for path in sorted(root.glob(scene.script)):
                name = str(path.relative_to(root).with_suffix(""))
                out.append((Scene(name, scene.script, scene.shorten, scene.repeats,
                                  scene.root), path))
        elif (root / scene.script).is_file():
            out.append((scene, root / scene.script))
    return out


def label(scene: Scene) -> str:
    """The scene's name in the table: its name or script, and the shortened duration."""
    name = scene.name or scene.script.removesuffix(".txt")
    return f"{name}, {scene.shorten[0]:g} s" if scene.shorten else name


def cut_to(scene: Scene, source: Path, duration: float) -> Scene:
    """The scene shortened to at most ``duration`` seconds at its own dt (``--duration``)."""
    from ipcsim.scene import load_scene

    spec = load_scene(source)
    if duration >= (scene.shorten[0] if scene.shorten else spec.duration):
        return scene
    return dataclasses.replace(scene, shorten=(duration, spec.dt))


def shortened(text: str, duration: float, dt: float, extra: tuple[str, ...] = ()) -> str:
    """The script with ``time DURATION DT`` as its last effective ``time`` line: before
    the first ``section`` line (both programs skip what follows a ``section`` that is
    not closed by ``section end``), else at the end; a ``time`` line inside a closed
    section (``section SQP QP ... section end``: what the SQP / QP solvers read instead)
    becomes the same line. ``extra`` lines (``timeIntegration NM``, say) go in with the
    ``time`` line, as the last of their kind."""
    # every digit of both (a ladder of halved steps reaches h = 0.05 / 2**9 = 9.765625e-05)
    line = f"time {float(duration)!r} {float(dt)!r}  # added by benchmarks.vs_original\n"
    line += "".join(f"{x}\n" for x in extra)
    rows = text.splitlines(keepends=True)
    opened = None  # the row of the open section's first line
    for k, row in enumerate(rows):
        words = row.split()
        if words[:2] == ["section", "end"] and opened is not None:
            rows[opened:k] = [line if r.split()[:1] == ["time"] else r
                              for r in rows[opened:k]]
            opened = None
        elif words[:1] == ["section"]:
            opened = k + 1
    for k, row in enumerate(rows):
        if row.split()[:1] == ["section"]:
            return "".join(rows[:k]) + line + "".join(rows[k:])
    if rows and not rows[-1].endswith("\n"):
        rows[-1] += "\n"
    return "".join(rows) + line


def stage_input(work: Path, examples_input: Path = EXAMPLES_INPUT) -> Path:
    """``work/stage`` whose ``input/`` links every entry of the examples' ``input/`` and
    this repository's ``input/meshes``; the folder both programs run in."""
    stage = work / "stage"
    inp = stage / "input"
    if inp.exists() or inp.is_symlink():
        shutil.rmtree(inp) if inp.is_dir() and not inp.is_symlink() else inp.unlink()
    inp.mkdir(parents=True)
    entries = sorted(examples_input.iterdir()) if examples_input.is_dir() else []
    entries += [p for p in (REPO_ROOT / "input").iterdir() if p.is_dir()]
    for src in entries:
        if not (inp / src.name).exists():
            (inp / src.name).symlink_to(src.resolve(), target_is_directory=src.is_dir())
    (stage / "scripts").mkdir(exist_ok=True)
    return stage


def stage_scene(scene: Scene, source: Path, stage: Path) -> Staged:
    """Copy (and shorten) the scene's script into ``stage/scripts``."""
    name = label(scene)
    text = source.read_text(encoding="utf-8", errors="replace")
    if scene.shorten:
        text = shortened(text, *scene.shorten)
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_")
    script = stage / "scripts" / f"{slug}.txt"
    script.write_text(text, encoding="utf-8")
    return Staged(scene, source, script, name)


# ------------------------------------------------------------------------ running


def _kill_group(pid: int, flag: list) -> None:
    flag.append(True)
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def _watch_high_water(pid: int, seen: list, stop: threading.Event) -> None:
    """Read the process's VmHWM (kB) every 20 ms until it ends: the high-water mark of its
    own address space, unlike ``ru_maxrss``, which also counts the memory of this (the
    parent) process that the child held between fork and exec."""
    path = f"/proc/{pid}/status"
    while True:  # Popen returns after the exec: the first reading is the program's own
        try:
            with open(path, encoding="ascii", errors="replace") as f:
                for line in f:
                    if line.startswith("VmHWM:"):
                        seen.append(int(line.split()[1]))
        except (OSError, ValueError, IndexError):
            return
        if stop.wait(0.02):
            return


def run_timed(cmd: list, cwd: Path, env: dict, log: Path, timeout: float) -> tuple:
    """Run ``cmd`` in its own process group: (exit status, wall seconds, peak resident MB
    of its process: the last VmHWM read while it ran, None for a process too short to
    be read twice, CPU seconds of its process: user + system, which a busy host's
    other tenants move less than the wall time). Past ``timeout`` the group is killed
    and the status is :data:`TIMEOUT_EXIT`."""
    killed: list = []
    seen: list = []
    stop = threading.Event()
    with open(log, "wb") as f:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=subprocess.DEVNULL, stdout=f,
                                stderr=subprocess.STDOUT, start_new_session=True)
        timer = threading.Timer(timeout, _kill_group, (proc.pid, killed))
        watcher = threading.Thread(target=_watch_high_water, args=(proc.pid, seen, stop),
                                   daemon=True)
        timer.start()
        watcher.start()
        try:
            _, status, usage = os.wait4(proc.pid, 0)
        finally:
            timer.cancel()
            stop.set()
        wall = time.perf_counter() - start
    watcher.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    rc = TIMEOUT_EXIT if killed else proc.returncode
    # a process that ended before a second reading was not watched long enough to tell
    peak = max(seen) / 1024.0 if len(seen) > 1 else None  # kilobytes
    return rc, wall, peak, usage.ru_utime + usage.ru_stime


def original_env(lib_path: str, threads: int) -> dict:
    env = dict(os.environ)
    if lib_path:
        env["LD_LIBRARY_PATH"] = ":".join(p for p in (lib_path, env.get("LD_LIBRARY_PATH"))
                                          if p)
    env["OMP_NUM_THREADS"] = env["OPENBLAS_NUM_THREADS"] = str(threads)
    return env


def ipcsim_env(threads: int, own_install: bool = True) -> dict:
    """The user's environment (no library path of the original's) with the thread count
    fixed. With ``own_install`` (an ``ipcsim`` console script is run) without
    ``PYTHONPATH``: a path to a checkout would make every install import that checkout's
    sources instead of its own (a before/after of two installs then times one code)."""
    env = dict(os.environ)
    env["IPCSIM_THREADS"] = str(threads)
    if own_install:
        env.pop("PYTHONPATH", None)
    return env


def ipcsim_command() -> list:
    exe = Path(sys.executable).with_name("ipcsim")
    return [str(exe)] if exe.is_file() else [sys.executable, "-m", "ipcsim.cli"]


def _fresh(folder: Path) -> Path:
    if folder.exists():
        shutil.rmtree(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    return folder


def original_invocation(script: Path, out: Path, cwd: Path, s: Settings) -> tuple:
    """(command, folder to run it in, log file) for the original on ``script``.

    Through run-ipc.sh with ``via_script``; otherwise the command run-ipc.sh runs, made
    the same way (a scratch folder whose ``input`` is ``cwd``'s, a copy of the script,
    stdout.txt in OUTDIR), so that the time and memory measured are the program's alone:
    run-ipc.sh's own timing includes a bash and a python3 start, which takes as long as
    the whole of a tiny scene where python3 is a version manager's shim."""
    out.mkdir(parents=True)
    if s.via_script:
        return (["bash", str(ORIGINAL / "run-ipc.sh"), str(script), str(out), str(s.threads)],
                cwd, out.with_name("original.log"))
    scratch = _fresh(out.with_name("original_cwd"))
    scratch.mkdir()
    (scratch / "input").symlink_to((cwd / "input").resolve(), target_is_directory=True)
    shutil.copyfile(script, scratch / "scene.txt")
    cmd = [str(ORIGINAL / "IPC_bin"), "100", str(scratch / "scene.txt"), "--output",
           str(out.resolve()), "--numThreads", str(s.threads), "--logLevel", "info",
           "--noProgressBar"]
    return cmd, scratch, out / "stdout.txt"


def run_original(script: Path, out: Path, cwd: Path, s: Settings) -> Run:
    cmd, where, log = original_invocation(script, _fresh(out), cwd, s)
    rc, wall, peak, cpu = run_timed(cmd, where, original_env(s.lib_path, s.threads), log,
                                    s.timeout)
    run = Run(rc, wall, peak, cpu)
    read_original(out, run)
    return run


def run_ipcsim(script: Path, out: Path, cwd: Path, s: Settings, steps: int | None = None) -> Run:
    """``ipcsim run SCRIPT -o OUT -q``: the ``ipcsim`` installed beside this Python, or
    with ``s.checkout`` this checkout's sources (``python -m ipcsim.cli`` with the
    checkout first on ``PYTHONPATH``; numba then compiles what an install compiled)."""
    cmd = ([sys.executable, "-m", "ipcsim.cli"] if s.checkout else ipcsim_command()) \
        + ["run", str(script), "-o", str(_fresh(out)), "-q"]
    if steps:
        cmd += ["--steps", str(steps)]
    # a console script runs its own install; "python -m ipcsim.cli" may need the path
    env = ipcsim_env(s.threads, own_install=cmd[0] != sys.executable)
    if s.checkout:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO_ROOT), env.get("PYTHONPATH"))
                                            if p)
    rc, wall, peak, cpu = run_timed(cmd, cwd, env, out.with_name("ipcsim.log"), s.timeout)
    run = Run(rc, wall, peak, cpu)
    read_ipcsim(out, run)
    return run


# ------------------------------------------------------------------------ reading runs


def read_ipcsim(out: Path, run: Run) -> None:
    """Steps, step wall time, Newton iterations and contacts from steps.csv; vertices from
    the first frame."""
    import meshio
    import numpy as np

    from ipcsim.io.csv_log import read_csv

    try:
        log = read_csv(out / "steps.csv")
    except (OSError, ValueError):
        return
    if len(log["step"]):
        run.steps = len(log["step"])
        run.steps_wall_s = float(np.sum(log["wall_s"]))
        run.newton_per_step = float(np.mean(log["newton_iterations"]))
        run.contacts_mean = float(np.mean(log["contacts_total"]))
    first = out / "frames" / "frame_000000.vtu"
    if first.is_file():
        run.vertices = len(meshio.read(first).points)
    try:
        run.own_peak_mb = json.loads((out / "run.json").read_text())["peak_memory_mb"]
    except (OSError, ValueError, KeyError, TypeError):
        pass


_STAMP = r"\[(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d+)\] \[\w+\] "


def original_contacts(stdout: Path) -> float | None:
    """Mean over steps of the last ``# constraint = N`` the original logs in each step."""
    last: dict[int, int] = {}
    step = None
    with open(stdout, encoding="utf-8", errors="replace") as f:
        for line in f:
            if m := re.match(_STAMP + r"Timestep (\d+):", line):
                step = int(m.group(2))
            elif step is not None and (m := re.match(_STAMP + r"# constraint = (\d+)", line)):
                last[step] = int(m.group(2))
    return statistics.fmean(last.values()) if last else None


def read_original(out: Path, run: Run) -> None:
    """Steps, Newton iterations per step and the steps' wall time from ``ipc_stats.py``;
    vertices from info.txt; contacts from stdout.txt."""
    if not (out / "log.txt").is_file():
        return
    res = subprocess.run([sys.executable, str(ORIGINAL / "ipc_stats.py"), str(out)],
                         capture_output=True, text=True)
    text = res.stdout
    if m := re.search(r"steps=(\d+) newton_total=\d+ newton_per_step=([\d.]+)", text):
        run.steps, run.newton_per_step = int(m.group(1)), float(m.group(2))
    if m := re.search(r"stepping_wall_s=([\d.]+)", text):
        run.steps_wall_s = float(m.group(1))
    info = out / "info.txt"
    if info.is_file():
        text = info.read_text(errors="replace")
        head = text.split()
        run.vertices = int(head[0]) if head and head[0].isdigit() else None
        if m := re.search(r"peak (\d+) KB", text):
            run.own_peak_mb = int(m.group(1)) / 1024.0
    if (out / "stdout.txt").is_file():
        run.contacts_mean = original_contacts(out / "stdout.txt")


def compare(ipcsim_out: Path, original_out: Path, rtol: float) -> dict:
    """What ``ipcsim compare --rtol RTOL IPCSIM_OUT ORIGINAL_OUT`` finds: verdict "same",
    "different" (with the first step beyond the tolerance) or "cannot" (why), and the
    largest difference over the frames, as a fraction of the scene size."""
    from ipcsim.io.compare import CompareError, compare_runs

    def short(text: str) -> str:  # no folder of this machine in the table
        return text.replace(str(ipcsim_out), "ipcsim's output").replace(
            str(original_out), "the original's output")

    try:
        res = compare_runs(ipcsim_out, original_out, rtol=rtol)
    except CompareError as exc:
        return {"verdict": "cannot", "message": short(str(exc))}
    except Exception as exc:  # a damaged or missing frame of a failed run
        return {"verdict": "cannot", "message": short(f"{type(exc).__name__}: {exc}")}
    out = {"verdict": "same" if res.first_frame_diff is None else "different",
           "frames": len(res.steps), "message": short(res.first_frame_diff or "")}
    if res.steps:
        k = max(range(len(res.steps)), key=res.max_rel.__getitem__)
        out.update(max_rel=res.max_rel[k], max_step=res.steps[k])
    if res.first_frame_step is not None:
        j = res.steps.index(res.first_frame_step)
        out.update(first_step=res.first_frame_step, first_time=res.times[j])
    return out


# ------------------------------------------------------------------------ the benchmark


def can_run_original(stage: Path, s: Settings) -> str | None:
    """None when the original program runs here, else why not: tried once through
    run-ipc.sh on two steps of the hello world; on failure, what ``ldd`` says is
    missing."""
    if not (ORIGINAL / "run-ipc.sh").is_file() or not (ORIGINAL / "IPC_bin").is_file():
        return f"the original program is not installed ({ORIGINAL} is missing)"
    probe = stage_scene(SMOKE_REPO, REPO_ROOT / SMOKE_REPO.script, stage)
    run = run_original(probe.script, s.work / "probe" / "original", stage,
                       dataclasses.replace(s, timeout=120.0, via_script=True))
    if run.rc == 0 and run.steps:
        return None
    why = f"the original program does not run here (exit status {run.rc})"
    try:
        ldd = subprocess.run(["ldd", str(ORIGINAL / "IPC_bin")], capture_output=True,
                             text=True, env=original_env(s.lib_path, s.threads)).stdout
    except OSError:
        return why
    missing = [ln.split()[0] for ln in ldd.splitlines() if "not found" in ln]
    if missing:
        why += (f"; ldd: {', '.join(missing)} not found. Install them with `apt-get install"
                " -y libcholmod3 libtbb12 libopenblas0-pthread`, or name a folder that"
                " holds them with --ipc-lib-path")
    return why


def warm_up(staged: list[Staged], stage: Path, s: Settings) -> None:
    """ipcsim, untimed: the :data:`WARMUP` scenes in full, then each scene's first step."""
    found = [EXAMPLES_INPUT / w for w in WARMUP if (EXAMPLES_INPUT / w).is_file()]
    s.say(f"warming numba's cache ({len(found)} scenes in full, then one step of each)")
    for k, path in enumerate(found):
        warm = stage_scene(Scene(f"warmup {k}", path.name), path, stage)
        run_ipcsim(warm.script, s.work / "warmup" / "ipcsim", stage, s)
    for st in staged:
        run_ipcsim(st.script, s.work / "warmup" / "ipcsim", stage, s, steps=1)


def measure(st: Staged, stage: Path, s: Settings, repeats: int) -> dict:
    """Run the scene ``repeats`` times with both programs (the order swapped each time)
    and summarise the runs and the comparison of the last pair."""
    folder = s.work / "runs" / st.script.stem
    for r in range(repeats):
        for program in (PROGRAMS if r % 2 == 0 else PROGRAMS[::-1]):
            runner = run_original if program == "original" else run_ipcsim
            run = runner(st.script, folder / program, stage, s)
            st.runs[program].append(run)
            s.say(f"  {st.name}: {program} {run.wall_s:.2f} s, exit {run.rc}"
                  f" (repeat {r + 1}/{repeats})")
    verdict = compare(folder / "ipcsim", folder / "original", s.compare_rtol)
    return summarise(st, verdict)


def _median(runs: list[Run], attr: str) -> float | None:
    values = [getattr(r, attr) for r in runs if getattr(r, attr) is not None]
    return statistics.median(values) if values else None


def summarise(st: Staged, verdict: dict) -> dict:
    """One row: medians of the times and memory, counts of the last run of each program."""
    row = {"scene": st.name, "script": str(st.source.relative_to(_root(st.scene))),
           "shortened": f"{st.scene.shorten[0]:g} s" if st.scene.shorten else "",
           "repeats": len(st.runs["ipcsim"])}
    for program, runs in st.runs.items():
        if not runs:
            continue
        last = runs[-1]
        row.update({f"{program}_{k}": getattr(last, k) for k in
                    ("rc", "steps", "newton_per_step", "contacts_mean", "vertices")})
        row.update({f"{program}_{k}": _median(runs, k) for k in
                    ("wall_s", "steps_wall_s", "peak_mb", "own_peak_mb", "cpu_s")})
        row[f"{program}_wall_all"] = " ".join(f"{r.wall_s:.3f}" for r in runs)
        if any(r.rc != 0 for r in runs):
            row[f"{program}_rc"] = next(r.rc for r in runs if r.rc != 0)
    # a failed run's time is no measure of the scene (the original fails at once on the
    # scripts whose meshes its build cannot find): no ratio then, in the table or chart
    both_ok = row.get("ipcsim_rc") == 0 and row.get("original_rc") == 0
    row["ratio"] = (_ratio(row.get("ipcsim_wall_s"), row.get("original_wall_s"))
                    if both_ok else None)
    row["steps_ratio"] = (_ratio(row.get("ipcsim_steps_wall_s"),
                                 row.get("original_steps_wall_s")) if both_ok else None)
    row["cpu_time_ratio"] = (_ratio(row.get("ipcsim_cpu_s"), row.get("original_cpu_s"))
                             if both_ok else None)
    if both_ok:
        row.update(paired_ratios(st.runs["original"], st.runs["ipcsim"]))
    row.update({f"compare_{k}": v for k, v in verdict.items()})
    return row


def paired_ratios(original: list[Run], ipcsim: list[Run]) -> dict:
    """The whole-process ratio repeat by repeat: the two runs of a repeat follow each
    other, so a machine whose load drifts over minutes slows both alike, and the ratio
    of the two medians hides how often each program was the faster. Their median, the
    smallest and largest, and in how many repeats ipcsim took less time."""
    paired = [i.wall_s / o.wall_s for o, i in zip(original, ipcsim) if o.wall_s > 0]
    if not paired:
        return {}
    return {"paired_ratio": statistics.median(paired), "paired_ratio_min": min(paired),
            "paired_ratio_max": max(paired),
            "ipcsim_faster_repeats": sum(r < 1.0 for r in paired)}


def _ratio(a, b) -> float | None:
    return a / b if a is not None and b else None


# ------------------------------------------------------------------------ machine


def machine() -> dict:
    """CPU model and cores, memory, Python and ipcsim versions, date, load average."""
    cpu = platform.processor() or platform.machine()
    mem = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        kb = re.search(r"MemTotal:\s+(\d+)", Path("/proc/meminfo").read_text())
        mem = f"{int(kb.group(1)) / 2**20:.0f} GiB" if kb else ""
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO_ROOT,
                                capture_output=True, text=True).stdout.strip()
    except OSError:
        commit = ""
    from ipcsim import __version__
    return {"cpu": cpu, "cores": os.cpu_count(), "memory": mem,
            "python": platform.python_version(), "ipcsim": __version__, "commit": commit,
            "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "load_before": _load()}


def file_system(folder: Path) -> str:
    """The type of the file system that holds ``folder`` (its longest mount point in
    /proc/mounts; "" where unknown). Tiny scenes' times depend on it: the original
    creates three files a step and ipcsim one, and creating a file costs 10–20 µs on
    tmpfs, hundreds on an ext4 without a journal that has just deleted many."""
    folder = str(Path(folder).resolve())
    best, kind = "", ""
    try:
        for line in Path("/proc/mounts").read_text().splitlines():
            fields = line.split()
            if len(fields) < 3:
                continue
            point = fields[1].replace("\\040", " ")
            inside = folder == point or folder.startswith(point.rstrip("/") + "/")
            if inside and len(point) >= len(best):
                best, kind = point, fields[2]
    except OSError:
        pass
    return kind


def _load() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return ""


def describe(info: dict, s: Settings) -> str:
    """The lines above the table: machine, date, load, threads."""
    # the ipcsim measured is the command installed beside this Python, which need not be
    # the checkout's own code (a release install of another commit, say)
    commit = (f"; the benchmark's checkout is at commit {info['commit']}"
              if info.get("commit") else "")
    return (f"Machine: {info['cpu']}, {info['cores']} cores, {info['memory']}; Python "
            f"{info['python']}, ipcsim {info['ipcsim']} (the `ipcsim` installed for the "
            f"Python that ran this benchmark{commit}).  \n"
            f"Date: {info['date']}; load average (1, 5, 15 min) {info['load_before']} before,"
            f" {info.get('load_after', '')} after.  \n"
            f"{s.threads} thread(s) per program; outputs written to "
            f"{info.get('output_fs') or 'a file system of unknown type'}; times are "
            f"medians over the repeats; trajectories compared with rtol "
            f"{s.compare_rtol:g} of the scene size.")


# ------------------------------------------------------------------------ output


def _f(x, fmt: str = ".2f") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return format(x, fmt)


def _sec(x) -> str:
    return _f(x, ".0f" if x is not None and x >= 100 else ".2f")


def _pair(a, b, fmt: str = ".2f") -> str:
    return f"{_f(a, fmt)} / {_f(b, fmt)}"


def _steps(r: dict) -> str:
    a, b = r.get("original_steps"), r.get("ipcsim_steps")
    return _f(a if a is not None else b, "d") if a == b or None in (a, b) else f"{a} / {b}"


def _paired(r: dict) -> str:
    if r.get("paired_ratio") is None:
        return "–"
    return (f"{r['paired_ratio']:.2f} ({r['paired_ratio_min']:.2f}–"
            f"{r['paired_ratio_max']:.2f}), {r['ipcsim_faster_repeats']} of {r['repeats']}")


def verdict_text(r: dict) -> str:
    v = r.get("compare_verdict")
    if v in (None, "cannot"):
        return "not compared" if v is None else f"cannot: {r.get('compare_message', '')}"
    largest = (f"largest {r['compare_max_rel']:.2g} at step {r['compare_max_step']}"
               if r.get("compare_max_rel") is not None else "")
    if v == "same":
        return f"same; {largest}"
    return f"part at step {r['compare_first_step']} (t = {r['compare_first_time']:g} s); " \
           f"{largest}"


HEADER = ("| scene | vertices | steps | original s | ipcsim s | ipcsim / original "
          "| repeat by repeat: median (range), ipcsim faster "
          "| CPU s, original / ipcsim | steps only s, original / ipcsim "
          "| Newton it./step, original / ipcsim "
          "| contacts/step, original / ipcsim | peak MB, original / ipcsim "
          "| exit, original / ipcsim | trajectories (ipcsim compare) |")


def markdown(rows: list[dict]) -> str:
    lines = [HEADER, "|" + "---|" * HEADER.count(" | ") + "---|"]
    for r in rows:
        vertices = r.get("ipcsim_vertices") or r.get("original_vertices")
        lines.append(
            f"| {r['scene']} | {_f(vertices, ',d')} | {_steps(r)} "
            f"| {_sec(r.get('original_wall_s'))} | {_sec(r.get('ipcsim_wall_s'))} "
            f"| {_f(r.get('ratio'))} | {_paired(r)} "
            f"| {_sec(r.get('original_cpu_s'))} / {_sec(r.get('ipcsim_cpu_s'))} "
            f"| {_sec(r.get('original_steps_wall_s'))} / {_sec(r.get('ipcsim_steps_wall_s'))} "
            f"| {_pair(r.get('original_newton_per_step'), r.get('ipcsim_newton_per_step'), '.1f')} "
            f"| {_pair(r.get('original_contacts_mean'), r.get('ipcsim_contacts_mean'), '.0f')} "
            f"| {_pair(r.get('original_peak_mb'), r.get('ipcsim_peak_mb'), '.0f')} "
            f"| {_pair(r.get('original_rc'), r.get('ipcsim_rc'), 'd')} "
            f"| {verdict_text(r)} |")
    return "\n".join(lines)


CSV_FIELDS = (
    "scene", "script", "shortened", "repeats", "original_vertices", "ipcsim_vertices",
    "original_steps", "ipcsim_steps", "original_wall_s", "ipcsim_wall_s", "ratio",
    "original_steps_wall_s", "ipcsim_steps_wall_s", "steps_ratio",
    "original_newton_per_step", "ipcsim_newton_per_step", "original_contacts_mean",
    "ipcsim_contacts_mean", "original_peak_mb", "ipcsim_peak_mb", "original_own_peak_mb",
    "original_rc", "ipcsim_rc",
    "original_wall_all", "ipcsim_wall_all", "compare_verdict", "compare_first_step",
    "compare_first_time", "compare_max_rel", "compare_max_step", "compare_message",
    "date", "cpu", "cores", "load_before", "load_after", "output_fs", "threads",
    "original_cpu_s", "ipcsim_cpu_s", "cpu_time_ratio", "paired_ratio", "paired_ratio_min",
    "paired_ratio_max", "ipcsim_faster_repeats")


def write_csv(rows: list[dict], info: dict, s: Settings, path: Path) -> None:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({**r, **{k: info.get(k) for k in
                                ("date", "cpu", "cores", "load_before", "load_after",
                                 "output_fs")},
                        "threads": s.threads})


def chart(rows: list[dict], info: dict, path: Path) -> Path:
    """ipcsim / original wall time per scene (whole process and steps only), log axis."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = [r for r in rows if r.get("ratio") or r.get("steps_ratio")]
    fig, ax = plt.subplots(figsize=(8, 0.32 * len(shown) + 1.6))
    y = list(range(len(shown)))[::-1]
    for key, style, text in (("ratio", {"marker": "o", "color": "C0"}, "whole process"),
                             ("steps_ratio", {"marker": "s", "facecolors": "none",
                                              "edgecolors": "C1"}, "steps only")):
        pts = [(r[key], yy) for r, yy in zip(shown, y) if r.get(key)]
        ax.scatter([p[0] for p in pts], [p[1] for p in pts], label=text, **style)
    ax.axvline(1.0, color="black", linewidth=1)
    ax.set_xscale("log")
    ax.set_yticks(y, [r["scene"] for r in shown], fontsize=7)
    ax.set_ylim(-0.7, len(shown) - 0.3)
    ax.set_title(f"ipcsim against the original program, {info['date'][:10]}, "
                 f"{info['cores']} cores, load {info['load_before'].split(' ')[0]}", fontsize=9)
    ax.set_xlabel("ipcsim wall time / original wall time (below 1: ipcsim faster)")
    ax.legend(fontsize=8, loc="best")
    ax.grid(True, axis="x", which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_outputs(rows: list[dict], info: dict, s: Settings, out: Path) -> list[Path]:
    """vs_original.csv, vs_original_table.md and vs_original.png in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "vs_original.csv", out / "vs_original_table.md", out / "vs_original.png"]
    write_csv(rows, info, s, paths[0])
    paths[1].write_text("<!-- written by `python -m benchmarks.vs_original` -->\n\n"
                        + describe(info, s) + "\n\n" + markdown(rows) + "\n", encoding="utf-8")
    chart(rows, info, paths[2])
    return paths


# ------------------------------------------------------------------------ main


def select(args) -> list[tuple[Scene, Path]]:
    """The scenes to run: --smoke's, or the table's matching --only, cut to --duration."""
    if args.smoke:
        return expand((SMOKE,)) or expand((SMOKE_REPO,))
    found = expand()
    if args.only:
        found = [(sc, p) for sc, p in found
                 if any(o in label(sc) or o in str(p) for o in args.only)]
    if args.duration:
        found = [(cut_to(sc, p, args.duration), p) for sc, p in found]
    return found


def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", action="append", metavar="SUBSTRING",
                    help="run the scenes whose name or script contains it (repeatable)")
    ap.add_argument("--repeats", type=int, help="runs per scene and program (default: the "
                    "table's, 15 for the tiny scenes, else 1)")
    ap.add_argument("--out", type=Path, help="where the CSV, table and chart go (default "
                    "docs/benchmarks; with --smoke: nowhere unless given)")
    ap.add_argument("--work", type=Path, help="folder for the runs (default output/"
                    "vs_original; with --smoke a temporary one)")
    ap.add_argument("--ipc-lib-path", default=os.environ.get("IPC_LIB_PATH", ""),
                    metavar="DIRS", help="folders (':'-separated) with the original's "
                    "runtime libraries, put on LD_LIBRARY_PATH for the original's process "
                    "only (default: $IPC_LIB_PATH)")
    ap.add_argument("--threads", type=int, default=1, help="threads per program (default 1)")
    ap.add_argument("--timeout", type=float, default=1800.0, metavar="S",
                    help="seconds allowed per run (default 1800)")
    ap.add_argument("--compare-rtol", type=float, default=1e-3, metavar="R",
                    help="trajectories part where a vertex differs by more than R of the "
                    "scene size (default 1e-3)")
    ap.add_argument("--duration", type=float, metavar="S",
                    help="cut every scene to at most S seconds of simulated time, at its "
                    "own dt (a quick look; the table's shortenings otherwise)")
    ap.add_argument("--via-run-ipc", action="store_true",
                    help="run the original through run-ipc.sh (default: its command, "
                    "made the same way, so that the program alone is timed)")
    ap.add_argument("--no-warmup", action="store_true",
                    help="no untimed ipcsim runs first (measures numba compiling too)")
    ap.add_argument("--keep-rows", action="store_true",
                    help="reuse the rows a former run saved in WORK/rows instead of "
                    "measuring those scenes again (to finish an interrupted benchmark)")
    ap.add_argument("--smoke", action="store_true",
                    help="one tiny scene, once, into a temporary folder")
    args = ap.parse_args(argv)
    for name in ("repeats", "threads", "timeout", "duration"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            ap.error(f"--{name} must be positive")
    return args


def run_benchmark(args, work: Path) -> tuple[list[dict], dict, Settings] | None:
    """Stage, check the original, warm up, measure. None when skipped (said why)."""
    s = Settings(work, args.threads, args.timeout, args.ipc_lib_path, args.compare_rtol,
                 args.via_run_ipc)
    found = select(args)
    if not found:
        print("vs_original: no scene matches (are ../shared/ipc-examples there?)")
        return None
    stage = stage_input(work)
    why = can_run_original(stage, s)
    if why:
        print(f"vs_original: skipped: {why}")
        return None
    staged = [stage_scene(sc, path, stage) for sc, path in found]
    info = machine() | {"output_fs": file_system(s.work)}
    if not (args.smoke or args.no_warmup):
        warm_up(staged, stage, s)
    info["load_before"] = _load()
    rows = []
    for k, st in enumerate(staged, start=1):
        saved = s.work / "rows" / f"{st.script.stem}.json"
        if args.keep_rows and saved.is_file():
            s.say(f"[{k}/{len(staged)}] {st.name}: measured before, row kept")
            rows.append(json.loads(saved.read_text(encoding="utf-8")))
            continue
        s.say(f"[{k}/{len(staged)}] {st.name}")
        rows.append(measure(st, stage, s, args.repeats or (1 if args.smoke else
                                                           st.scene.repeats)))
        # each row as soon as it is measured: an interrupted benchmark keeps its hours
        saved.parent.mkdir(parents=True, exist_ok=True)
        saved.write_text(json.dumps(rows[-1], indent=1), encoding="utf-8")
    info["load_after"] = _load()
    return rows, info, s


def main(argv=None) -> int:
    args = parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="vs_original_") as tmp:
        work = args.work or (Path(tmp) if args.smoke else DEFAULT_WORK)
        done = run_benchmark(args, work)
        if done is None:
            return 0
        rows, info, s = done
        print(describe(info, s) + "\n\n" + markdown(rows))
        out = args.out or (None if args.smoke else DEFAULT_OUT)
        if out is not None:
            for path in write_outputs(rows, info, s, out):
                print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
