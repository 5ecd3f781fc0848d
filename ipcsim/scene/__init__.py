"""Scene files: the original IPC script format (``.txt`` / ``.ipc``) and TOML (``.toml``).

``load_scene(path)`` reads either into a ``SceneSpec``; ``save_scene(spec, path)`` writes
either, chosen by the extension. Every mistake in a scene is a ``SceneError`` that prints
as ``path:line: what is wrong``; warnings are collected in ``SceneSpec.warnings``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from ..errors import ArgumentError, OutputError, SceneError
from ..atomic import atomic_write_text
from ..files import NotRegularFileError, read_regular_file
from .spec import (DirichletSpec, InitialVelocitySpec, MaterialSpec, MeshObstacleSpec,
                   NeumannSpec, PlaneSpec, SceneSpec, ShapeSpec)
from .overrides import apply_overrides, parse_assignment
from .toml_reader import parse_toml
from .toml_writer import format_toml
from .txt_reader import parse_txt
from .txt_writer import format_txt
from .validate import validate_scene

__all__ = [
    "load_scene",
    "apply_overrides",
    "parse_assignment",
    "save_scene",
    "read_scene_text",
    "scene_text",
    "scene_format",
    "MAX_SCENE_BYTES",
    "parse_txt",
    "parse_toml",
    "format_txt",
    "format_toml",
    "validate_scene",
    "SceneSpec",
    "ShapeSpec",
    "MaterialSpec",
    "DirichletSpec",
    "NeumannSpec",
    "InitialVelocitySpec",
    "PlaneSpec",
    "MeshObstacleSpec",
]

TEXT_EXTENSIONS = (".txt", ".ipc")
# Scene files are written by hand or by small scripts: a few KB. Anything beyond this is a
# mistake (a mesh or a log named as the scene), refused before it is parsed.
MAX_SCENE_BYTES = 1 << 20
TOML_EXTENSIONS = (".toml",)


def scene_format(path) -> str:
    """"txt" or "toml" by the file's extension; anything else is a SceneError."""
    ext = Path(path).suffix.lower()
    if ext in TEXT_EXTENSIONS:
        return "txt"
    if ext in TOML_EXTENSIONS:
        return "toml"
    raise SceneError(path, None, f"unknown scene file extension '{ext}': use .txt or .ipc "
                                 "(IPC script) or .toml")


def read_scene_text(path, kind: str = "scene file") -> str:
    """The file's text (UTF-8, a BOM allowed); a SceneError when it cannot be read, is not
    a regular file, is larger than :data:`MAX_SCENE_BYTES` or is not text. ``kind`` names
    the file in messages (a study file is read by the same rules)."""
    try:
        data = read_regular_file(path, MAX_SCENE_BYTES + 1)
    except FileNotFoundError:
        raise SceneError(path, None, f"{kind} not found") from None
    except IsADirectoryError:
        raise SceneError(path, None, f"is a folder, not a {kind}") from None
    except NotRegularFileError:
        raise SceneError(path, None, "is not a regular file (a device, a pipe or a "
                                     f"socket), so it cannot be a {kind}") from None
    except OSError as exc:
        raise SceneError(path, None, f"cannot read {kind} ({exc.strerror or exc})") from None
    _check_size(path, len(data), kind)
    return scene_text(data, path, kind)


def scene_text(data: bytes, path, kind: str = "scene file") -> str:
    """The text of a scene file's bytes: UTF-8 (a BOM allowed) without NUL bytes, else a
    SceneError at the line of the first bad byte."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise SceneError(path, line, "not UTF-8 text (byte "
                                     f"0x{data[exc.start]:02x})") from None
    nul = text.find("\0")
    if nul >= 0:
        raise SceneError(path, text.count("\n", 0, nul) + 1,
                         f"holds a NUL byte: a binary file, not a {kind}")
    return text


def _check_size(path, size: int, kind: str = "scene file") -> None:
    if size > MAX_SCENE_BYTES:
        why = ("a hand-written scene is a few KB; `shapeMatrix` or a [[shapes]] matrix makes "
               "many copies of a shape" if kind == "scene file" else f"a {kind} is a few KB")
        raise SceneError(path, None, f"is {size / 2**20:.3g} MiB; ipcsim reads {kind}s of "
                                     f"at most {MAX_SCENE_BYTES // 2**20} MiB ({why})")


def load_scene(path, overrides=None) -> SceneSpec:
    """Read a scene file (.txt/.ipc or .toml) into a validated ``SceneSpec``; with
    ``overrides`` (dotted TOML key -> value, :mod:`ipcsim.scene.overrides`) those values
    replace the file's, checked as the file's are."""
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ArgumentError("overrides must be a mapping of dotted TOML keys to values "
                            f"({{'time.dt': 0.01}}), got {type(overrides).__name__}")
    fmt = scene_format(path)
    text = read_scene_text(path)
    spec = parse_txt(text, path) if fmt == "txt" else parse_toml(text, path)
    return apply_overrides(spec, overrides)


def save_scene(spec: SceneSpec, path) -> Path:
    """Write ``spec`` as .toml or .txt/.ipc (by extension), atomically: the text goes to a
    temporary file in the same folder, which then replaces ``path`` (os.replace), so a
    failure never leaves a half-written scene. Returns ``path``."""
    path = Path(path)
    fmt = scene_format(path)
    text = format_txt(spec, path) if fmt == "txt" else format_toml(spec, path)
    if not path.parent.is_dir() and str(path.parent) != "":
        raise SceneError(path, None, f"cannot write: folder '{path.parent}' does not exist")
    try:
        atomic_write_text(path, text)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    return path
