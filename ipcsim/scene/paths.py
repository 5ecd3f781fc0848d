"""Where the files a scene names are looked for, and how a writer names them again.

A relative path in a scene (shape meshes, ``meshSeq`` folders, ``meshCO`` meshes,
``restart`` files) is tried, in this order:

1. as written, if it is absolute;
2. relative to the folder of the scene file;
3. relative to each ancestor of that folder, nearest first (the original's scripts write
   paths like ``input/tetMeshes/cube.msh`` relative to the program's root, so a scene in
   ``<root>/input/tutorialExamples/`` finds its meshes from ``<root>``);
4. relative to the current working directory.

The first candidate that exists (a file, or a folder for ``meshSeq``) wins. Paths are
normalised lexically (``a/b/../c`` -> ``a/c``) and not resolved through symlinks, so the
file's extension (which decides the mesh kind) stays the one written.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

__all__ = [
    "absolute",
    "search_folders",
    "resolve",
    "is_file",
    "is_dir",
    "is_tetgen",
    "not_found_message",
    "relative_for_writing",
]


def absolute(path: str | os.PathLike) -> Path:
    """Absolute, lexically normalised path (no symlink resolution)."""
    return Path(os.path.normpath(os.path.abspath(path)))


def search_folders(scene_path: str | os.PathLike | None) -> list[Path]:
    """The folders a relative path is tried against, in order (steps 2-4 above)."""
    folders: list[Path] = []
    if scene_path is not None:
        scene_dir = absolute(scene_path).parent
        folders.append(scene_dir)
        folders.extend(scene_dir.parents)
    cwd = absolute(os.getcwd())
    if cwd not in folders:
        folders.append(cwd)
    return folders


def is_file(path: Path) -> bool:
    return path.is_file()


def is_dir(path: Path) -> bool:
    return path.is_dir()


def is_tetgen(path: Path) -> bool:
    """A TetGen mesh named as ``base`` or ``base.ele``: needs ``base.node`` and ``base.ele``."""
    base = path.with_suffix("") if path.suffix.lower() == ".ele" else path
    return (base.parent / (base.name + ".node")).is_file() and (
        base.parent / (base.name + ".ele")
    ).is_file()


def resolve(
    written: str,
    scene_path: str | os.PathLike | None,
    exists: Callable[[Path], bool] = is_file,
) -> Path | None:
    """The first existing candidate for ``written`` (absolute, normalised), or None."""
    if not written:
        return None
    p = Path(written)
    if p.is_absolute():
        cand = absolute(p)
        return cand if exists(cand) else None
    for folder in search_folders(scene_path):
        cand = Path(os.path.normpath(folder / p))
        if exists(cand):
            return cand
    return None


def not_found_message(what: str, written: str, scene_path) -> str:
    if Path(written).is_absolute():
        return f"{what} '{written}' does not exist"
    where = "the scene's folder, its parent folders" if scene_path is not None else ""
    where = f"{where} or the current directory" if where else "the current directory"
    return f"{what} '{written}' not found (looked relative to {where})"


def relative_for_writing(target: Path, folder: Path) -> str:
    """How a writer names ``target`` in a file that lives in ``folder``: relative to that
    folder when possible (POSIX separators, so scenes move between machines), else absolute.
    """
    target, folder = absolute(target), absolute(folder)
    try:
        common = Path(os.path.commonpath([target, folder]))
        rel = os.path.relpath(target, folder)
    except ValueError:  # another drive on Windows: no relative path exists
        return target.as_posix()
    if common == Path(common.anchor):
        return target.as_posix()  # nothing shared but the root: a relative path says less
    return Path(rel).as_posix()
