"""The runs of a study: planned in the client (each run's resolved scene and its content
digest, which names its folder), executed anywhere (:func:`execute` is what a Dask
worker calls) and summarised into a study.csv row.

A run's folder is ``runs/<digest>`` under the study folder, the digest being the one a
checkpoint carries (:func:`ipcsim.scene.digest.inputs_digest`: the resolved scene and
the contents of its meshes). So a re-run of the study finds what is done by content, not
by position in the study: :func:`execute` skips a finished run, resumes an interrupted
one from its checkpoint (``ipcsim run --resume``) and starts the others.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import time
from pathlib import Path

import msgspec
from msgspec import Struct

from ..errors import IpcsimError, OutputError, RunInterrupted, SceneError, excerpt, one_line
from ..io.output_folder import RUN_DIGEST_CHARS as DIGEST_CHARS
from ..io.output_folder import STUDY_RUNS as RUNS_DIR
from .spec import Record, StudySpec

__all__ = ["RunTask", "plan", "execute", "cached_row", "refuse_replacing", "ROW_FILE",
           "RUNS_DIR"]

ROW_FILE = "study_row.json"
# a study's runs each take one thread: as many runs as cores, not threads fighting
WORKER_ENV = {"IPCSIM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
              "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class RunTask(Struct, frozen=True):
    """One run of a study, as a worker gets it (plain values: it is pickled)."""

    name: str  # "3" (its row) or "reference"
    scene: str  # the base scene, absolute
    overrides: dict  # of the base scene, study-wide ones included
    parameters: dict  # the varied keys' values (study.csv's parameter columns)
    folder: str  # absolute
    digest: str
    steps: int  # the last step
    dt: float  # s, the run's time step
    record: Record

    @property
    def cache_key(self) -> dict:
        """What a cached row must match to stand for this run."""
        return {"digest": self.digest, "steps": self.steps,
                "record": msgspec.structs.asdict(self.record)}


def plan(study: StudySpec, out: Path) -> tuple[list[RunTask], RunTask | None]:
    """Every run of the study (and the reference run), its scene read and checked here:
    a bad key or value is a SceneError naming the study file and the key."""
    from ..scene import load_scene
    from ..scene.digest import inputs_digest

    def task(name, point, overrides):
        try:
            spec = load_scene(study.scene, overrides)
        except SceneError as exc:
            raise SceneError(study.path, None, f"run {name} "
                             f"({', '.join(f'{k} = {v!r}' for k, v in point.items())}): "
                             f"{exc}") from None
        digest = inputs_digest(spec)
        steps = spec.n_steps if study.steps is None else min(study.steps, spec.n_steps)
        return RunTask(name, str(study.scene), overrides, point,
                       str(out / RUNS_DIR / digest[:DIGEST_CHARS]), digest, steps,
                       spec.dt, study.record)

    tasks = [task(str(i), p, {**study.fixed, **p}) for i, p in enumerate(study.points())]
    reference = None
    if study.reference is not None:
        reference = task("reference", study.reference, {**study.fixed, **study.reference})
    return tasks, reference


def cached_row(task: RunTask) -> dict | None:
    """The row a finished run left, if it still stands for ``task``."""
    from ..files import read_regular_text

    try:
        saved = json.loads(read_regular_text(Path(task.folder) / ROW_FILE))
    except (OSError, ValueError):  # a FIFO or a folder in its place too: no row
        return None
    if not isinstance(saved, dict) or saved.get("key") != json.loads(
            json.dumps(task.cache_key)) or saved.get("row", {}).get("status") != "ok":
        return None
    return saved["row"]


def folder_state(task: RunTask) -> str:
    """What the task's folder holds: "new" (nothing), "done" (this run, finished),
    "resume" (this run, cut short), "damaged" (no readable checkpoint: the study's own
    run, which cannot go on), "beyond" (this run gone beyond ``task.steps``) or "other"
    (the checkpoint of other inputs). The last two are never replaced silently."""
    from ..io.checkpoint import read_checkpoint
    from ..io.output_folder import holds_anything

    folder = Path(task.folder)
    if not holds_anything(folder):
        return "new"
    try:
        checkpoint = read_checkpoint(folder)
    except IpcsimError:
        return "damaged"
    if checkpoint["inputs_sha256"] != task.digest:
        return "other"
    if checkpoint["step"] > task.steps:
        return "beyond"
    if checkpoint["step"] == task.steps and _run_info(folder).get("status") == "ok":
        return "done"
    return "resume"


def _conflict(task: RunTask, state: str) -> str:
    """Why the task's folder cannot be used (``state`` "beyond" or "other")."""
    if state == "beyond":
        return (f"{describe(task)}: its folder {task.folder} holds this run gone further "
                f"than this study's {task.steps} steps")
    return f"{describe(task)}: its folder {task.folder} holds the checkpoint of another run"


def refuse_replacing(tasks) -> None:
    """An OutputError (exit status 2) when a task's folder holds a run that the study
    would have to replace (:func:`folder_state` "beyond" or "other"): a finished run is
    never lost without ``--overwrite``."""
    for task in tasks:
        state = folder_state(task)
        if state in ("beyond", "other"):
            raise OutputError(f"{_conflict(task, state)}; pass --overwrite to run the study "
                              "afresh, or -o another folder")


def _mode(task: RunTask) -> str:
    """How to go on in the run's folder: "done", "resume", "new" or "overwrite"."""
    state = folder_state(task)
    if state in ("beyond", "other"):  # a folder changed since the study was planned
        raise OutputError(f"{_conflict(task, state)}; left as it is")
    return {"damaged": "overwrite"}.get(state, state)


def _run_info(folder: Path) -> dict:
    from ..files import read_regular_text

    try:
        info = json.loads(read_regular_text(folder / "run.json"))
        return info if isinstance(info, dict) else {}
    except (OSError, ValueError):
        return {}


def _simulate(task: RunTask, spec) -> str:
    """Run (or resume) the simulation in the task's folder; returns what was done."""
    from ..io.checkpoint import CheckpointError
    from ..runner import Reporter, run

    mode = _mode(task)
    if mode == "done":
        return "skipped"
    quiet = Reporter(warn=lambda message: None)
    Path(task.folder).parent.mkdir(parents=True, exist_ok=True)
    try:
        run(spec, task.folder, steps=task.steps, mode=mode, reporter=quiet)
    except CheckpointError:  # a damaged folder of the study's own: start it again
        mode = "overwrite"
        run(spec, task.folder, steps=task.steps, mode=mode, reporter=quiet)
    return {"new": "ran", "overwrite": "ran", "resume": "resumed"}[mode]


def execute(task: RunTask) -> dict:
    """Run one study run and return its study.csv row; a failure is a row with its
    error, never an exception (so one bad run does not fail a study)."""
    from ..scene import load_scene

    # one numba thread (read when the Simulation is made), on an existing cluster's
    # workers too, whose environment ipcsim did not set
    os.environ.setdefault("IPCSIM_THREADS", WORKER_ENV["IPCSIM_THREADS"])
    row = {"run": task.name, **task.parameters, "status": "ok", "error": "",
           "folder": task.folder}
    t0, cpu0 = time.perf_counter(), _cpu()
    try:
        spec = load_scene(task.scene, task.overrides)
        row["action"] = _simulate(task, spec)
        row.update(summarise(task))
    except RunInterrupted:
        raise  # Ctrl-C of a study run in this process: the study stops
    except IpcsimError as exc:
        row.update(status="failed", error=one_line(str(exc), 300))
    except Exception as exc:  # a bug: still a row, so the study goes on
        row.update(status="failed", error=one_line(f"{type(exc).__name__}: {exc}", 300))
    if row["status"] != "ok" and Path(task.folder).is_dir():
        try:
            row.update(summarise(task, partial=True))
        except Exception:  # noqa: BLE001  (what could be read of a failed run)
            pass
    row["elapsed_s"] = time.perf_counter() - t0  # this call: the run, or what was left
    row["cpu_s"] = _cpu() - cpu0  # CPU time of the process meanwhile, all its threads
    _save_row(task, row)
    return row


def _cpu() -> float:
    t = os.times()
    return t.user + t.system


def _save_row(task: RunTask, row: dict) -> None:
    from ..atomic import atomic_write_text

    folder = Path(task.folder)
    if folder.is_dir():
        try:
            atomic_write_text(folder / ROW_FILE, json.dumps(
                {"key": task.cache_key, "row": row}, default=_plain, indent=1))
        except OSError:
            pass  # the row still reaches study.csv; only the skip on re-run is lost


def _plain(v):
    if hasattr(v, "item"):
        return v.item()
    return str(v)


def summarise(task: RunTask, partial: bool = False) -> dict:
    """The recorded quantities of a run's folder (docs/user-guide.md, "Studies")."""
    import numpy as np

    from ..io.csv_log import StepLog, read_csv

    folder = Path(task.folder)
    info = _run_info(folder)
    steps = read_csv(folder / StepLog.FILE_NAME) if (folder / StepLog.FILE_NAME).is_file() \
        else {}
    n = len(steps.get("step", ()))
    row = {"steps_done": n, "steps_planned": task.steps,
           "wall_s": info.get("wall_s"),
           "newton_iterations": int(np.sum(steps.get("newton_iterations", 0))),
           "steps_not_converged": int(np.sum(steps.get("converged", np.ones(0)) == 0)),
           "inputs_sha256": task.digest}
    rec = task.record
    for column in rec.columns:
        values = np.asarray(steps.get(column, ()), dtype=float)
        for s in rec.summaries:
            row[f"{column}_{s}"] = _summary(values, s)
    if partial:
        return row
    if rec.final_state:
        row.update(_final_state(folder, task.dt))
    if rec.check_frames:
        row.update(_frames(folder))
    return row


def _summary(values, how: str) -> float:
    import numpy as np

    values = values[np.isfinite(values)] if len(values) else values
    if not len(values):
        return math.nan
    return float({"min": np.min, "max": np.max, "mean": np.mean,
                  "final": lambda v: v[-1]}[how](values))


def _final_state(folder: Path, dt: float) -> dict:
    """From the checkpoint: the last state, and a digest of its positions' bits."""
    import numpy as np

    from ..io.checkpoint import read_checkpoint

    ck = read_checkpoint(folder)
    x = np.ascontiguousarray(ck["x"], dtype=np.float64)
    centre = x.mean(axis=0)
    return {"final_time": ck["step"] * dt,
            "final_centre_x": float(centre[0]), "final_centre_y": float(centre[1]),
            "final_centre_z": float(centre[2]),
            "final_max_speed": float(np.linalg.norm(ck["v"], axis=1).max()),
            "final_positions_sha256": hashlib.sha256(x.tobytes()).hexdigest()}


def _frames(folder: Path) -> dict:
    """``ipcsim check --frames``: every frame by the exact checker."""
    from ..contact.frame_check import check_frames

    counts: dict = {}
    clean = check_frames(folder, io.StringIO(), counts) == 0
    return {"frames_clean": clean, "intersections": counts.get("intersections", 0),
            "inverted_tets": counts.get("inverted_tets", 0),
            "below_plane": counts.get("below_plane", 0)}


def describe(task: RunTask) -> str:
    """The run as a message names it."""
    values = ", ".join(f"{k}={excerpt(repr(v))}" for k, v in task.parameters.items())
    return f"run {task.name} ({values})"
