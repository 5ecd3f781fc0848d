"""The output folder of a run: where it goes by default, checking it before anything is
written (:func:`resolve_output_folder`), and preparing it (:func:`prepare_output_folder`).

A run never mixes its files with an earlier run's or with the user's own: the folder is
made absolute and normalised first, so ``missing/../old_run`` is recognised as the
existing ``old_run``; an existing, non-empty folder is refused unless the user asks to
overwrite (or resume); the current directory and the scene's own folder are refused for
a new run; and overwriting removes only the files ipcsim itself writes there, never
anything else the user keeps in that folder, and only once the new run has been built.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..atomic import is_temporary_name
from ..errors import IpcsimError, excerpt
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
    "resolve_output_folder",
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


def default_output_folder(scene_path: str | os.PathLike, append_str: str = "") -> Path:
    """``output/<scene-stem>`` (``output/<scene-stem>_<appendStr>`` when the scene says
    ``appendStr``), relative to the current directory."""
    stem = Path(scene_path).stem
    if stem in ("", ".", "..") or stem.strip(".") == "":
        raise OutputFolderError(f"cannot name an output folder after the scene file "
                                f"'{excerpt(Path(scene_path).name)}'; pass -o DIR")
    return Path(OUTPUT_ROOT) / (f"{stem}_{append_str}" if append_str else stem)


def _same_or_inside(folder: Path, other: Path) -> bool:
    """True when ``other`` is ``folder`` or lies inside it (lexically or through links)."""
    pairs = [(folder, other), (Path(os.path.realpath(folder)), Path(os.path.realpath(other)))]
    return any(b == a or a in b.parents for a, b in pairs)


def resolve_output_folder(requested, scene_path, *, mode: str) -> Path:
    """The output folder a run will write, absolute and normalised (``missing/../run`` is
    ``run``), checked before anything is written; ``mode`` is ``"new"``, ``"overwrite"``
    or ``"resume"``.

    Refused with :class:`OutputFolderError`: a file in the way; for a new or overwriting
    run, the current directory, the scene's own folder or a folder above either (a run
    there would mix its files with the user's); for a new run, an existing folder that
    is not empty (pass --overwrite or --resume); for a resume, a folder that does not
    exist; a folder that cannot be created or written.
    """
    path = Path(os.path.normpath(os.path.abspath(requested)))
    if path.exists() and not path.is_dir():
        raise OutputFolderError(f"output folder {path} exists and is not a folder")
    if mode == "resume":
        if not path.is_dir():
            raise OutputFolderError(f"{path}: no such output folder to resume")
        _check_writable(path)
        return path
    for what, where in (("the current directory", Path.cwd()),
                        ("the scene's folder", Path(os.path.abspath(scene_path)).parent)):
        if _same_or_inside(path, where):
            here = "is" if path == where else "contains"
            raise OutputFolderError(f"output folder {path} {here} {what}; a run writes "
                                    "frames/, steps.csv and more there: pass -o with a "
                                    "folder of its own")
    if path.is_dir() and any(path.iterdir()):
        if mode != "overwrite":
            raise OutputFolderError(f"output folder {path} exists; pass --overwrite "
                                    "(or --resume)")
        _check_writable(path)
    else:
        existing = next(p for p in (path, *path.parents) if p.exists())
        if not existing.is_dir():
            raise OutputFolderError(f"cannot create output folder {path}: {existing} is "
                                    "not a folder")
        _check_writable(existing)
    return path


def _check_writable(folder: Path) -> None:
    for f in (folder, folder / FRAMES_DIR):
        if f.is_dir() and not os.access(f, os.W_OK | os.X_OK):
            raise OutputFolderError(f"cannot write in {f} (permission denied)")


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
    try:
        if path.is_dir() and any(path.iterdir()):
            if not overwrite:
                raise OutputFolderError(f"output folder {path} exists; pass --overwrite")
            for entry in path.iterdir():
                if entry.name == FRAMES_DIR:
                    _clear_frames(entry)
                elif entry.name in OWN_FILES or is_temporary_name(entry.name):
                    _remove(entry)
        (path / FRAMES_DIR).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputFolderError(f"cannot prepare output folder {path}: "
                                f"{exc.strerror or exc}") from None
    return path
