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

from ..errors import excerpt

__all__ = [
    "absolute",
    "search_folders",
    "resolve",
    "candidates",
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
    try:
        return path.is_file()
    except (OSError, ValueError):  # a name too long for the file system, a NUL in it
        return False


def is_dir(path: Path) -> bool:
    try:
        return path.is_dir()
    except (OSError, ValueError):
        return False


def is_tetgen(path: Path) -> bool:
    """A TetGen mesh named as ``base`` or ``base.ele``: needs ``base.node`` and ``base.ele``."""
    base = path.with_suffix("") if path.suffix.lower() == ".ele" else path
    return is_file(base.parent / (base.name + ".node")) and is_file(
        base.parent / (base.name + ".ele"))


def resolve(
    written: str,
    scene_path: str | os.PathLike | None,
    exists: Callable[[Path], bool] = is_file,
) -> Path | None:
    """The first existing candidate for ``written`` (absolute, normalised), or None."""
    for cand in candidates(written, scene_path):
        if exists(cand):
            return cand
    return None


def candidates(written: str, scene_path) -> list[Path]:
    """Where ``written`` is looked for, in order (absolute, normalised)."""
    if not written or "\0" in written:
        return []
    p = Path(written)
    if p.is_absolute():
        return [absolute(p)]
    return [Path(os.path.normpath(folder / p)) for folder in search_folders(scene_path)]


def _kind_of(path: Path) -> str | None:
    """'a folder', 'a file' or 'not a regular file' for something that exists, else None."""
    try:
        if path.is_dir():
            return "a folder"
        if path.is_file():
            return "a file"
        return "not a regular file" if path.exists() else None
    except (OSError, ValueError):  # a name too long for the file system, say
        return None


def not_found_message(what: str, written: str, scene_path, exists=is_file) -> str:
    """Why ``written`` was not found: it exists with the wrong kind (a folder where a file
    belongs, a device), or it exists nowhere."""
    if exists in (is_file, is_dir):
        for cand in candidates(written, scene_path):
            kind = _kind_of(cand)
            if kind is not None and not exists(cand):
                want = "a folder" if exists is is_dir else "a file"
                found = (f"is {kind}, not {want}" if kind != "not a regular file" else
                         "is not a regular file (a device, a pipe or a socket)")
                return f"{what} '{excerpt(written, 80)}' {found} ({cand})"
    if Path(written).is_absolute():
        return f"{what} '{excerpt(written, 80)}' does not exist"
    where = "the scene's folder, its parent folders" if scene_path is not None else ""
    where = f"{where} or the current directory" if where else "the current directory"
    return f"{what} '{excerpt(written, 80)}' not found (looked relative to {where})"


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
