"""Before ``--resume`` changes anything: does the checkpoint fit the folder and the scene?

:func:`check_resume` reads and changes nothing; it raises :class:`CheckpointError` when

* the checkpoint was written for other inputs (its digest of the resolved scene and the
  mesh files differs from the scene's now) or another vertex count;
* its step lies beyond the scene's last step;
* a file the resumed run rewrites is not a regular file (``steps.csv`` a folder, say);
* ``steps.csv`` lacks a row of a step up to the checkpoint's, or has a damaged row;
  ``newton.csv`` likewise (iterations of every step up to it);
* a frame the run wrote up to the checkpoint is missing (``frame_000000.vtu`` and every
  frame interval), or the frame of the checkpoint's own step shows another state.

Only when all of that holds does the run command drop what was written after the
checkpoint (:func:`remove_temporaries`, ``FrameWriter.resume`` and the logs' ``keep_rows``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..atomic import is_temporary_name
from .checkpoint import CHECKPOINT_NAME, CheckpointError
from .csv_log import NEWTON_COLUMNS, STEP_COLUMNS, NewtonLog, StepLog
from .run_info import RUN_INFO_NAME
from .vtk import FRAMES_DIR, SERIES_NAME, FrameError, frame_file_name, read_frame

__all__ = ["check_resume", "remove_temporaries"]

_STEP_CELL = re.compile(r"\d{1,12}\Z", re.ASCII)
_FRAME_NAME = re.compile(r"frame_(\d+)\.vtu\Z", re.ASCII)


def check_resume(folder, checkpoint: dict, *, inputs_sha256: str, n_vertices: int,
                 scene_steps: int, frame_every: int, scene="the scene",
                 adaptive: bool = False) -> None:
    """Raise :class:`CheckpointError` unless the run in ``folder`` can continue from
    ``checkpoint`` (as :func:`~ipcsim.io.checkpoint.read_checkpoint` returns it);
    ``scene`` names the scene in messages; ``adaptive``: the run's steps.csv has a row
    per attempted step, several for a step of dt."""
    folder = Path(folder)
    k = checkpoint["step"]
    if checkpoint["inputs_sha256"] != inputs_sha256:
        raise CheckpointError(f"{scene} is not the scene the run in {folder} was started "
                              "with (a setting or the content of a mesh file differs); "
                              "resume with that scene, or start again with --overwrite")
    if len(checkpoint["x"]) != n_vertices:
        raise CheckpointError(f"{folder}: the checkpoint has {len(checkpoint['x'])} vertices, "
                              f"the scene {n_vertices}")
    if k > scene_steps:
        raise CheckpointError(f"{folder}: the checkpoint is at step {k}, after the scene's "
                              f"last step {scene_steps}")
    _check_own_files(folder)
    _check_log(folder / StepLog.FILE_NAME, STEP_COLUMNS, k, every_step_once=not adaptive)
    _check_log(folder / NewtonLog.FILE_NAME, NEWTON_COLUMNS, k, every_step_once=False)
    _check_frames(folder / FRAMES_DIR, k, frame_every, checkpoint)


def _check_own_files(folder: Path) -> None:
    for name in (StepLog.FILE_NAME, NewtonLog.FILE_NAME, RUN_INFO_NAME, CHECKPOINT_NAME,
                 f"{FRAMES_DIR}/{SERIES_NAME}"):
        p = folder / name
        if p.exists() and not p.is_file():
            raise CheckpointError(f"{p} is not a file; a resumed run rewrites it")
    if not (folder / FRAMES_DIR).is_dir():
        raise CheckpointError(f"{folder}: no {FRAMES_DIR}/ folder; not a run folder")


def _read_log(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8").split("\n")
    except (OSError, UnicodeDecodeError) as exc:
        raise CheckpointError(f"{path}: cannot read ({exc})") from None


def _check_log(path: Path, columns, k: int, *, every_step_once: bool) -> None:
    """Every complete row well formed; the steps 1..k all there (``steps.csv``: as its
    first k rows, one each; ``newton.csv``: in order, at least one row each)."""
    if not path.exists():
        if k == 0:
            return
        raise CheckpointError(f"{path} is missing; the checkpoint is at step {k}")
    lines = _read_log(path)
    if lines[0] != ",".join(columns):
        raise CheckpointError(f"{path}: not this version's columns; run again with "
                              "--overwrite")
    steps = []
    for number, row in enumerate(lines[1:-1], start=2):  # after the last \n: unfinished
        cells = row.split(",")
        if len(cells) != len(columns) or not _STEP_CELL.match(cells[0]):
            raise CheckpointError(f"{path}:{number}: damaged row")
        steps.append(int(cells[0]))
    upto = [s for s in steps if s <= k]
    if every_step_once:
        ok = steps[:k] == list(range(1, k + 1))
    else:
        ok = upto == sorted(upto) and set(upto) == set(range(1, k + 1))
    if not ok:
        raise CheckpointError(f"{path} does not hold the rows of steps 1..{k} that the "
                              f"checkpoint (at step {k}) was written after")


def _check_frames(frames: Path, k: int, every: int, checkpoint: dict) -> None:
    present = {}
    for p in frames.iterdir():
        m = _FRAME_NAME.match(p.name)
        if m and p.is_file():
            present[int(m.group(1))] = p
    missing = [j for j in range(0, k + 1, every) if j not in present]
    if missing:
        raise CheckpointError(f"{frames / frame_file_name(missing[0])} is missing; the "
                              f"checkpoint is at step {k}")
    if k not in present:
        return  # a checkpoint written on Ctrl-C between two frames
    try:
        mesh = read_frame(present[k])
    except FrameError as exc:
        raise CheckpointError(f"{exc}; the checkpoint is at its step") from None
    x = np.asarray(mesh.points, dtype=np.float64)
    v = mesh.point_data.get("velocity")
    same = x.shape == checkpoint["x"].shape and np.array_equal(x, checkpoint["x"])
    if same and v is not None:
        same = np.shape(v) == checkpoint["v"].shape and np.array_equal(v, checkpoint["v"])
    if not same:
        raise CheckpointError(f"{present[k]} does not show the checkpoint's state (step {k}); "
                              "the checkpoint belongs to another run")


def remove_temporaries(folder) -> list[Path]:
    """Delete the temporary files a killed writer left in ``folder`` and its frames
    folder (``.<name>.tmp-<pid>``); returns what was removed."""
    removed = []
    for where in (Path(folder), Path(folder) / FRAMES_DIR):
        if not where.is_dir():
            continue
        for p in where.iterdir():
            if is_temporary_name(p.name) and p.is_file():
                p.unlink()
                removed.append(p)
    return removed
