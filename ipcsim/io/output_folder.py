"""The output folder of a run: where it goes by default, and preparing it safely.

A run never mixes its files with an earlier run's: an existing, non-empty folder is
refused unless the user asks to overwrite, and overwriting removes only the files
ipcsim itself writes there, never anything else the user keeps in that folder.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..errors import IpcsimError
from ..atomic import is_temporary_name
from .checkpoint import CHECKPOINT_NAME
from .csv_log import NewtonLog, StepLog
from .run_info import RUN_INFO_NAME
from .vtk import FRAMES_DIR, SERIES_NAME

__all__ = [
    "OUTPUT_ROOT",
    "OWN_FILES",
    "OutputFolderError",
    "default_output_folder",
    "prepare_output_folder",
]

OUTPUT_ROOT = "output"

# Top-level entries a run writes; with overwrite, exactly these are removed.
OWN_FILES: tuple[str, ...] = (
    FRAMES_DIR,
    StepLog.FILE_NAME,
    NewtonLog.FILE_NAME,
    RUN_INFO_NAME,
    "scene.toml",
    CHECKPOINT_NAME,
)


class OutputFolderError(IpcsimError):
    """The output folder cannot be used (exists with content, or is not a folder)."""


def default_output_folder(scene_path: str | os.PathLike) -> Path:
    """``output/<scene-stem>``, relative to the current directory."""
    return Path(OUTPUT_ROOT) / Path(scene_path).stem


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink()


def _clear_frames(frames: Path) -> None:
    # Only frame files, the series and leftover temporaries: the folder may hold a
    # user's own files (a ParaView state, say), which stay.
    if frames.is_symlink() or not frames.is_dir():
        _remove(frames)
        return
    for entry in frames.iterdir():
        name = entry.name
        ours = (
            (name.startswith("frame_") and name.endswith(".vtu"))
            or name == SERIES_NAME
            or is_temporary_name(name)
        )
        if ours and not entry.is_dir():
            entry.unlink()


def prepare_output_folder(path: str | os.PathLike, overwrite: bool) -> Path:
    """Create ``path`` and ``path/frames`` for a new run and return ``path``.

    An existing folder that is not empty is refused with :class:`OutputFolderError`
    unless ``overwrite`` is true; then ipcsim's own files (``frames/`` contents,
    ``steps.csv``, ``newton.csv``, ``run.json``, ``scene.toml``, ``checkpoint.npz``, leftover temporary
    files) are removed and everything else is left alone.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputFolderError(f"output folder {path} exists and is not a folder")
    if path.is_dir() and any(path.iterdir()):
        if not overwrite:
            raise OutputFolderError(f"output folder {path} exists; pass --overwrite")
        for entry in path.iterdir():
            if entry.name == FRAMES_DIR:
                _clear_frames(entry)
            elif entry.name in OWN_FILES or is_temporary_name(entry.name):
                _remove(entry)
    try:
        (path / FRAMES_DIR).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputFolderError(f"cannot create output folder {path}: {exc.strerror}") from exc
    return path
