"""The identity of a run's inputs: one SHA-256 over the resolved scene and the bytes of
every file it reads.

The resolved scene is :func:`~ipcsim.scene.toml_writer.scene_to_dict` (every value, every
default) with each file named by the digest of its content instead of its path, so the
same scene read from another working directory, or with its meshes moved, has the same
digest, and a mesh whose coordinates changed has another one. A TetGen mesh is its
``.node`` and ``.ele`` files; a ``meshSeq`` folder is the names and contents of its files.
A checkpoint carries the digest, and ``--resume`` continues only a run of the same inputs.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..errors import SceneError
from ..files import open_regular
from .spec import SceneSpec
from .toml_writer import scene_to_dict

__all__ = ["inputs_digest", "file_digest"]

_CHUNK = 1 << 20


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes, read in chunks."""
    h = hashlib.sha256()
    with open_regular(path) as f:  # a FIFO or a device is refused, not read for ever
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def _content_name(path: Path) -> str:
    """``sha256:<hex>`` of what ``path`` stands for in a scene."""
    path = Path(path)
    if path.is_dir():  # a mesh sequence: every file by name and content
        parts = [f"{p.name}={file_digest(p)}" for p in sorted(path.iterdir()) if p.is_file()]
        return "sha256:" + hashlib.sha256("\n".join(parts).encode()).hexdigest()
    if path.suffix.lower() in ("", ".ele"):  # TetGen: <base>.node + <base>.ele
        base = path.with_suffix("") if path.suffix.lower() == ".ele" else path
        parts = [file_digest(base.with_name(base.name + ext)) for ext in (".node", ".ele")]
        return "sha256:" + hashlib.sha256(" ".join(parts).encode()).hexdigest()
    return "sha256:" + file_digest(path)


def inputs_digest(spec: SceneSpec) -> str:
    """Hex SHA-256 of the resolved scene with every file named by its content."""
    current = [None]

    def name(path: Path) -> str:
        current[0] = path
        return _content_name(path)

    try:
        doc = scene_to_dict(spec, Path("."), name_path=name)
    except OSError as exc:
        raise SceneError(current[0], None, f"cannot read ({exc.strerror or exc})") from None
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()
